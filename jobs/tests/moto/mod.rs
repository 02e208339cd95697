//! A real S3-compatible server for the object-store tests: `moto_server` (installed by `scripts/setup-tools`
//! into `.tools/venv`), one per test binary, on a free 127.0.0.1 port. The process environment gets the
//! standard `AWS_*` variables pointing at it, so the code under test (and every process a test starts)
//! configures itself exactly as it would against a real endpoint. Shared by `jobs/tests/s3.rs` and
//! `tests/tests/storage.rs` (the end-to-end crate, included there by path).
//!
//! The server dies with the test binary: it runs under a small shell watchdog that kills it once the test
//! process is gone (a `static` is never dropped, so a `Drop` impl alone would leave it running).
#![allow(dead_code)]

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// Credentials given to the server's clients; tests check they never appear in logs or errors.
pub const ACCESS_KEY: &str = "CREASETESTACCESSKEY";
pub const SECRET_KEY: &str = "crease-test-secret-7f3a9c1e5b";
pub const BUCKET: &str = "crease-test";

pub struct Moto {
    pub port: u16,
    pub endpoint: String,
    watchdog: Child,
}

impl Drop for Moto {
    fn drop(&mut self) {
        let _ = self.watchdog.kill();
        let _ = self.watchdog.wait();
    }
}

/// `moto_server` on PATH or in `<repo>/.tools/venv/bin`; a clear failure otherwise (never a skip).
pub fn moto_server_path() -> PathBuf {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let local = repo.join(".tools/venv/bin/moto_server");
    if local.is_file() {
        return local;
    }
    if let Some(path) = std::env::var_os("PATH") {
        for dir in std::env::split_paths(&path) {
            let p = dir.join("moto_server");
            if p.is_file() {
                return p;
            }
        }
    }
    panic!(
        "moto_server (the local S3-compatible server these tests need) was not found on PATH or in \
         {}: run scripts/setup-tools once (or scripts/test, which does)",
        local.display()
    );
}

/// The binary's server, started on first use; the `AWS_*` environment of this process points at it.
pub fn moto() -> &'static Moto {
    static MOTO: OnceLock<Moto> = OnceLock::new();
    MOTO.get_or_init(|| {
        let server = moto_server_path();
        let port = TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let log =
            std::env::temp_dir().join(format!("crease-moto-{}-{port}.log", std::process::id()));
        // The watchdog polls this process and takes moto down with it.
        let script = r#"
"$MOTO" -H 127.0.0.1 -p "$PORT" >"$LOG" 2>&1 &
m=$!
trap 'kill $m 2>/dev/null; exit 0' TERM INT
while kill -0 "$OWNER" 2>/dev/null && kill -0 $m 2>/dev/null; do sleep 0.3; done
kill $m 2>/dev/null
"#;
        let watchdog = Command::new("sh")
            .args(["-c", script])
            .env("MOTO", &server)
            .env("PORT", port.to_string())
            .env("LOG", &log)
            .env("OWNER", std::process::id().to_string())
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("start moto_server");
        let endpoint = format!("http://127.0.0.1:{port}");
        let moto = Moto {
            port,
            endpoint: endpoint.clone(),
            watchdog,
        };
        let start = Instant::now();
        loop {
            if http(port, "GET", "/", b"").is_ok_and(|(status, _)| status > 0) {
                break;
            }
            assert!(
                start.elapsed() < Duration::from_secs(90),
                "moto_server did not start on port {port}; its log: {}",
                std::fs::read_to_string(&log).unwrap_or_default()
            );
            std::thread::sleep(Duration::from_millis(100));
        }
        create_bucket(port, BUCKET);
        for (k, v) in [
            ("AWS_ACCESS_KEY_ID", ACCESS_KEY),
            ("AWS_SECRET_ACCESS_KEY", SECRET_KEY),
            ("AWS_REGION", "us-east-1"),
            ("AWS_ENDPOINT_URL", endpoint.as_str()),
            ("AWS_ALLOW_HTTP", "true"),
            // Small budgets: an unreachable endpoint must fail quickly in the tests.
            ("CREASE_STORAGE_TIMEOUT_SECS", "10"),
            ("CREASE_STORAGE_RETRIES", "2"),
            // Small parts, so that files of a few MiB already take the multipart path.
            ("CREASE_STORAGE_MULTIPART_MIB", "5"),
        ] {
            // Set once, before any store is built or any child process started by the caller.
            std::env::set_var(k, v);
        }
        moto
    })
}

/// Creates a bucket with an unsigned request (moto accepts it, like a default-configured server).
pub fn create_bucket(port: u16, bucket: &str) {
    let (status, body) = http(port, "PUT", &format!("/{bucket}"), b"").expect("create bucket");
    assert!(
        (200..300).contains(&status),
        "creating bucket {bucket}: HTTP {status}: {}",
        String::from_utf8_lossy(&body)
    );
}

/// One HTTP/1.1 request over a fresh connection; (status, body).
pub fn http(port: u16, method: &str, path: &str, body: &[u8]) -> std::io::Result<(u16, Vec<u8>)> {
    let addr: SocketAddr = format!("127.0.0.1:{port}").parse().unwrap();
    let mut s = TcpStream::connect_timeout(&addr, Duration::from_millis(500))?;
    s.set_read_timeout(Some(Duration::from_secs(30)))?;
    write!(
        s,
        "{method} {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
        body.len()
    )?;
    s.write_all(body)?;
    let mut out = Vec::new();
    s.read_to_end(&mut out)?;
    let text = String::from_utf8_lossy(&out);
    let status = text
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    let body = match out.windows(4).position(|w| w == b"\r\n\r\n") {
        Some(i) => out[i + 4..].to_vec(),
        None => Vec::new(),
    };
    Ok((status, body))
}

/// A loopback port nothing listens on (bound, then released).
pub fn closed_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

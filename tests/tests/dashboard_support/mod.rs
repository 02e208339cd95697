//! Setup shared by the dashboard tests: a coordinator with `--http-listen` and client/worker tokens, a worker,
//! job files on the sleeve fixture, and a minimal HTTP/1.1 client (plain or TLS) that shows status, headers
//! and body exactly as sent.
#![allow(dead_code)]

use crease_e2e::*;
use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Arc;
use std::time::Duration;

pub const CLIENT_TOKEN: &str = "dash-client-token";
pub const WORKER_TOKEN: &str = "dash-worker-token";

/// One HTTP answer.
#[derive(Debug)]
pub struct Resp {
    pub status: u16,
    pub head: String,
    pub body: Vec<u8>,
}

impl Resp {
    pub fn header(&self, name: &str) -> Option<String> {
        self.head.lines().skip(1).find_map(|l| {
            let (k, v) = l.split_once(':')?;
            k.trim()
                .eq_ignore_ascii_case(name)
                .then(|| v.trim().to_string())
        })
    }
    pub fn text(&self) -> String {
        String::from_utf8_lossy(&self.body).into_owned()
    }
    pub fn json(&self) -> serde_json::Value {
        serde_json::from_slice(&self.body)
            .unwrap_or_else(|e| panic!("not JSON ({e}): {}\n{}", self.head, self.text()))
    }
}

/// Where the dashboard is and how to reach it.
pub struct Dash {
    pub addr: String,
    /// CA to trust for HTTPS; None: plain HTTP.
    pub ca: Option<PathBuf>,
}

fn tls_stream(addr: &str, ca: &Path) -> rustls::StreamOwned<rustls::ClientConnection, TcpStream> {
    let mut roots = rustls::RootCertStore::empty();
    let pem = std::fs::read(ca).unwrap();
    use rustls::pki_types::pem::PemObject;
    for c in rustls::pki_types::CertificateDer::pem_slice_iter(&pem) {
        roots.add(c.unwrap()).unwrap();
    }
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let config = rustls::ClientConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .unwrap()
        .with_root_certificates(roots)
        .with_no_client_auth();
    // `crease certs` names the coordinator's certificate after localhost and 127.0.0.1.
    let name = rustls::pki_types::ServerName::try_from("localhost").unwrap();
    let conn = rustls::ClientConnection::new(Arc::new(config), name).unwrap();
    let tcp = TcpStream::connect(addr).unwrap();
    tcp.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    rustls::StreamOwned::new(conn, tcp)
}

impl Dash {
    /// Sends one request (`Connection: close`) and reads the whole answer.
    pub fn req(&self, method: &str, path: &str, headers: &[(&str, &str)], body: &[u8]) -> Resp {
        let mut text = format!(
            "{method} {path} HTTP/1.1\r\nHost: {}\r\nConnection: close\r\nContent-Length: {}\r\n",
            self.addr,
            body.len()
        );
        for (k, v) in headers {
            text.push_str(&format!("{k}: {v}\r\n"));
        }
        text.push_str("\r\n");
        let mut raw = Vec::new();
        let mut send = |s: &mut dyn ReadWrite| {
            s.write_all(text.as_bytes()).unwrap();
            s.write_all(body).unwrap();
            s.flush().unwrap();
            // rustls reports the peer closing without close_notify as an error after the data.
            let _ = s.read_to_end(&mut raw);
        };
        match &self.ca {
            Some(ca) => send(&mut tls_stream(&self.addr, ca)),
            None => {
                let mut s = TcpStream::connect(&self.addr).unwrap();
                s.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
                send(&mut s)
            }
        }
        parse(&raw).unwrap_or_else(|| {
            panic!(
                "no HTTP answer to {method} {path}: {:?}",
                String::from_utf8_lossy(&raw)
            )
        })
    }

    pub fn get(&self, path: &str, auth: Auth) -> Resp {
        let h = auth.header();
        let hs: Vec<(&str, &str)> = h.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect();
        self.req("GET", path, &hs, b"")
    }

    pub fn post(&self, path: &str, auth: Auth) -> Resp {
        let h = auth.header();
        let hs: Vec<(&str, &str)> = h.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect();
        self.req("POST", path, &hs, b"")
    }

    /// Opens the event stream and reads until `until` appears in it (or the deadline passes).
    pub fn events_until(&self, auth: Auth, until: &str) -> String {
        let mut text = format!(
            "GET /api/events HTTP/1.1\r\nHost: {}\r\nAccept: text/event-stream\r\n",
            self.addr
        );
        for (k, v) in auth.header() {
            text.push_str(&format!("{k}: {v}\r\n"));
        }
        text.push_str("\r\n");
        let mut s = TcpStream::connect(&self.addr).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
        s.write_all(text.as_bytes()).unwrap();
        let mut got = Vec::new();
        let mut buf = [0u8; 8192];
        let start = std::time::Instant::now();
        while start.elapsed() < DEADLINE {
            let n = match s.read(&mut buf) {
                Ok(0) | Err(_) => break,
                Ok(n) => n,
            };
            got.extend_from_slice(&buf[..n]);
            if String::from_utf8_lossy(&got).contains(until) {
                break;
            }
        }
        String::from_utf8_lossy(&got).into_owned()
    }
}

trait ReadWrite: Read + Write {}
impl<T: Read + Write> ReadWrite for T {}

fn parse(raw: &[u8]) -> Option<Resp> {
    let split = raw.windows(4).position(|w| w == b"\r\n\r\n")?;
    let head = String::from_utf8_lossy(&raw[..split]).into_owned();
    let status = head.split_whitespace().nth(1)?.parse().ok()?;
    let mut body = raw[split + 4..].to_vec();
    if head
        .to_ascii_lowercase()
        .contains("transfer-encoding: chunked")
    {
        body = dechunk(&body);
    }
    Some(Resp { status, head, body })
}

fn dechunk(mut b: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    while let Some(eol) = b.windows(2).position(|w| w == b"\r\n") {
        let n = usize::from_str_radix(std::str::from_utf8(&b[..eol]).unwrap().trim(), 16).unwrap();
        if n == 0 {
            break;
        }
        out.extend_from_slice(&b[eol + 2..eol + 2 + n]);
        b = &b[eol + 2 + n + 2..];
    }
    out
}

/// How a request authenticates.
#[derive(Clone, Copy)]
pub enum Auth<'a> {
    None,
    Bearer(&'a str),
    Cookie(&'a str),
}

impl Auth<'_> {
    fn header(&self) -> Vec<(String, String)> {
        match self {
            Auth::None => vec![],
            Auth::Bearer(t) => vec![("Authorization".into(), format!("Bearer {t}"))],
            Auth::Cookie(c) => vec![("Cookie".into(), c.to_string())],
        }
    }
}

pub fn secret_file(p: &Path, text: &str) -> PathBuf {
    std::fs::write(p, text).unwrap();
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(p, std::fs::Permissions::from_mode(0o600)).unwrap();
    }
    p.to_path_buf()
}

/// A coordinator with the dashboard on `http_port`, client and worker tokens, and `extra` flags.
pub fn start(d: &Path, http_port: u16, extra: &[&str]) -> Coordinator {
    let client = secret_file(&d.join("client-tokens"), &format!("{CLIENT_TOKEN}\n"));
    let worker = secret_file(&d.join("worker-token"), &format!("{WORKER_TOKEN}\n"));
    let listen = format!("127.0.0.1:{http_port}");
    let mut flags = vec![
        "--http-listen",
        &listen,
        "--client-tokens-file",
        client.to_str().unwrap(),
        "--worker-token-file",
        worker.to_str().unwrap(),
    ];
    flags.extend_from_slice(extra);
    let mut c = Coordinator::start(d, &flags);
    c.client_args = vec!["--token-file".into(), client.to_str().unwrap().into()];
    c.worker_args = vec![
        "--worker-token-file".into(),
        worker.to_str().unwrap().into(),
    ];
    let addr = format!("127.0.0.1:{http_port}");
    wait_until("the dashboard to listen", || {
        TcpStream::connect(&addr).is_ok()
    });
    c
}

/// A job on the sleeve fixture (4 frames, several windows and blocks) writing into `d/<name>-out`.
pub fn job(d: &Path, name: &str) -> (PathBuf, PathBuf) {
    let anchors = d.join("anchors.json");
    if !anchors.exists() {
        write_anchors(&anchors);
    }
    let out = d.join(format!("{name}-out"));
    let file = job_file(d, name, &fixture(), &anchors, &out, "per-anchor", "");
    (file, out)
}

/// The repository root (screenshots go under its `target/test-artifacts/`, the browser scripts are in it).
pub fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

/// The venv's Python with Playwright, or a failure that says how to get it.
pub fn playwright_python() -> PathBuf {
    let chromium = Path::new("/usr/bin/chromium");
    assert!(
        chromium.exists(),
        "/usr/bin/chromium is missing: run scripts/setup-tools (as root it installs Debian's chromium and \
         chromium-driver packages)"
    );
    let python = workspace().join(".tools/venv/bin/python");
    let ok = Command::new(&python)
        .args(["-c", "import playwright.sync_api"])
        .output()
        .is_ok_and(|o| o.status.success());
    assert!(
        ok,
        "{} cannot import playwright: run scripts/setup-tools",
        python.display()
    );
    python
}

/// Runs a browser script (`cmd`, a Python with Playwright on a script of tests/tests/browser/) and returns the
/// JSON summary it prints, failing the test with its output when it fails.
pub fn browser_script(mut cmd: Command) -> serde_json::Value {
    let out = cmd.output().expect("run the browser script");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "browser script failed:\n{stdout}\n{}",
        stderr(&out)
    );
    serde_json::from_str(stdout.trim())
        .unwrap_or_else(|e| panic!("browser script output is not its JSON summary ({e}): {stdout}"))
}

/// A coordinator like [`start`] serving HTTPS with a certificate from `crease certs`; returns it and the CA
/// to trust.
pub fn start_tls(d: &Path, http_port: u16) -> (Coordinator, PathBuf) {
    let certs = d.join("certs");
    let o = Command::new(bin())
        .args(["certs", "--out", certs.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.success(), "crease certs: {}", stderr(&o));
    let c = start(
        d,
        http_port,
        &[
            "--tls-cert",
            certs.join("coordinator.pem").to_str().unwrap(),
            "--tls-key",
            certs.join("coordinator.key").to_str().unwrap(),
        ],
    );
    (c, certs.join("ca.pem"))
}

//! Process helpers shared by the tests that start real coordinators and workers on 127.0.0.1: every child is
//! killed when its handle drops and every wait has a deadline, so a broken build fails instead of hanging.
#![allow(dead_code)]

use std::collections::BTreeMap;
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

pub const BIN: &str = env!("CARGO_BIN_EXE_crease");
pub const DEADLINE: Duration = Duration::from_secs(90);

/// A child process killed on drop.
pub struct Proc(pub Child);

impl Proc {
    pub fn kill(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
    pub fn pid(&self) -> u32 {
        self.0.id()
    }
}

/// Sends SIGTERM and waits (bounded) for a clean exit.
pub fn sigterm_and_wait(w: &mut Proc) {
    let pid = w.pid();
    assert!(Command::new("kill")
        .args(["-TERM", &pid.to_string()])
        .status()
        .unwrap()
        .success());
    let start = Instant::now();
    let status = loop {
        if let Some(s) = w.0.try_wait().unwrap() {
            break s;
        }
        assert!(start.elapsed() < DEADLINE, "worker did not stop on SIGTERM");
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(status.success(), "{status}");
}

impl Drop for Proc {
    fn drop(&mut self) {
        self.kill();
    }
}

pub fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

pub fn wait_until(what: &str, mut f: impl FnMut() -> bool) {
    let start = Instant::now();
    while !f() {
        assert!(start.elapsed() < DEADLINE, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// A coordinator on a fixed loopback port (so it can be restarted on the same address).
pub struct Coordinator {
    pub port: u16,
    pub db: PathBuf,
    pub proc: Option<Proc>,
    pub extra: Vec<String>,
    /// Appended to every client command (`--tls-ca`, `--token-file`, ...).
    pub client_args: Vec<String>,
    /// Appended to every worker command.
    pub worker_args: Vec<String>,
    /// URL scheme clients and workers use (`http` or `https`).
    pub scheme: &'static str,
    /// Where the coordinator's stderr goes (none: discarded).
    pub log: Option<PathBuf>,
}

impl Coordinator {
    pub fn start(dir: &Path, extra: &[&str]) -> Self {
        let mut c = Coordinator {
            port: free_port(),
            db: dir.join("queue.sqlite"),
            proc: None,
            extra: extra.iter().map(|s| s.to_string()).collect(),
            client_args: Vec::new(),
            worker_args: Vec::new(),
            scheme: "http",
            log: None,
        };
        c.spawn();
        c
    }

    pub fn spawn(&mut self) {
        let child = Command::new(BIN)
            .args([
                "coordinator",
                "--listen",
                &format!("127.0.0.1:{}", self.port),
            ])
            .arg("--db")
            .arg(&self.db)
            .args(["--heartbeat-ms", "200", "--worker-timeout-ms", "2000"])
            .args(&self.extra)
            .stdout(Stdio::null())
            .stderr(match &self.log {
                Some(log) => Stdio::from(std::fs::File::create(log).unwrap()),
                None => Stdio::null(),
            })
            .spawn()
            .expect("start coordinator");
        self.proc = Some(Proc(child));
        let addr: SocketAddr = format!("127.0.0.1:{}", self.port).parse().unwrap();
        wait_until("the coordinator to listen", || {
            TcpStream::connect_timeout(&addr, Duration::from_millis(200)).is_ok()
        });
    }

    pub fn url(&self) -> String {
        format!("{}://127.0.0.1:{}", self.scheme, self.port)
    }

    /// Starts a worker and waits until it has registered (its log says so).
    pub fn worker(&self, name: &str, env: &[(&str, &str)]) -> Proc {
        let log = self.db.with_file_name(format!("worker-{name}.log"));
        let mut cmd = Command::new(BIN);
        cmd.args(["worker", "--coordinator", &self.url(), "--name", name])
            .args(["--threads", "1", "--drain-secs", "5"])
            .args(&self.worker_args)
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&log).unwrap());
        for (k, v) in env {
            cmd.env(k, v);
        }
        let p = Proc(cmd.spawn().expect("start worker"));
        wait_until(&format!("worker {name} to register"), || {
            std::fs::read_to_string(&log).is_ok_and(|t| t.contains("registered as"))
        });
        p
    }

    pub fn cli(&self, args: &[&str]) -> Output {
        Command::new(BIN)
            .args(args)
            .args(["--coordinator", &self.url()])
            .args(&self.client_args)
            .output()
            .expect("run crease")
    }

    pub fn submit(&self, job: &Path) -> String {
        let o = self.cli(&["submit", job.to_str().unwrap()]);
        assert!(o.status.success(), "submit: {}", stderr(&o));
        String::from_utf8(o.stdout).unwrap().trim().to_string()
    }

    pub fn status(&self, job: &str) -> serde_json::Value {
        let o = self.cli(&["status", job, "--json"]);
        assert!(o.status.success(), "status: {}", stderr(&o));
        serde_json::from_slice(&o.stdout).unwrap()
    }

    pub fn wait_state(&self, job: &str, states: &[&str]) -> serde_json::Value {
        let mut last = serde_json::Value::Null;
        wait_until(&format!("job {job} to reach {states:?}"), || {
            last = self.status(job);
            states.contains(&last["state"].as_str().unwrap_or(""))
        });
        last
    }
}

pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

pub fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/sleeve")
}

/// Anchors on the sleeve fixture: 40 per frame, so per-anchor mode with 8-column blocks has 5+ blocks per
/// window.
pub fn write_anchors(path: &Path) {
    let frames: Vec<String> = (0..4)
        .map(|f| {
            let list: Vec<String> = (0..40)
                .map(|k| {
                    format!(
                        r#"{{"triangle":{},"axis":[0,0,{}],"angle":0.6}}"#,
                        6000 + 2 * k,
                        if k < 20 { 1 } else { -1 }
                    )
                })
                .collect();
            format!(r#"{{"frame":{f},"anchors":[{}]}}"#, list.join(","))
        })
        .collect();
    std::fs::write(
        path,
        format!(r#"{{"version":1,"frames":[{}]}}"#, frames.join(",")),
    )
    .unwrap();
}

/// Parameters shared by the job files and the reference `crease run`: short windows so there are several
/// windows, cross-fades and reduce tasks on four frames.
pub const MODE_ARGS: [&str; 6] = ["--window", "3", "--shift", "2", "--anchor-block", "8"];

pub fn job_file(
    dir: &Path,
    name: &str,
    input: &Path,
    anchors: &Path,
    out: &Path,
    mode: &str,
    extra: &str,
) -> PathBuf {
    let path = dir.join(format!("{name}.toml"));
    let text = format!(
        r#"name = "{name}"
input = "{}"
output = "{}"
{extra}
[folds]
kind = "anchors"
uri = "{}"

[deform]
mode = "{mode}"
window = 3
shift = 2

[partition]
anchor_block = 8
frames_per_chunk = 1

[preview]
size = 64
"#,
        input.display(),
        out.display(),
        anchors.display()
    );
    std::fs::write(&path, text).unwrap();
    path
}

/// `crease run` (local single-node mode) into `out`.
pub fn local_run(input: &Path, anchors: &Path, out: &Path, mode: &str, workers: &str) {
    let o = Command::new(BIN)
        .args(["run", "--input", input.to_str().unwrap()])
        .args(["--anchors", anchors.to_str().unwrap()])
        .args(["--out", out.to_str().unwrap(), "--mode", mode])
        .args(MODE_ARGS)
        .args([
            "--preview-size",
            "64",
            "--local-workers",
            workers,
            "--threads",
            "2",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "crease run: {}", stderr(&o));
}

/// Every file of an output (the frames, previews), except `report.json` (it holds timings) and intermediates.
pub fn output_files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut m = BTreeMap::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let e = e.unwrap();
        let name = e.file_name().to_string_lossy().into_owned();
        if name == "report.json" || name.starts_with('.') || e.path().is_dir() {
            continue;
        }
        m.insert(name, std::fs::read(e.path()).unwrap());
    }
    m
}

pub fn assert_complete_and_identical(reference: &Path, out: &Path) {
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["complete"], true, "{}", out.display());
    let a = output_files(reference);
    let b = output_files(out);
    assert!(a.len() >= 6, "reference has only {:?}", a.keys());
    assert_eq!(
        a.keys().collect::<Vec<_>>(),
        b.keys().collect::<Vec<_>>(),
        "{} vs {}",
        reference.display(),
        out.display()
    );
    for (k, v) in &a {
        assert!(
            v == &b[k],
            "{k} differs between {} and {}",
            reference.display(),
            out.display()
        );
    }
}

pub fn tasks(status: &serde_json::Value) -> Vec<serde_json::Value> {
    status["tasks"].as_array().cloned().unwrap_or_default()
}

pub fn setup() -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let anchors = dir.path().join("anchors.json");
    write_anchors(&anchors);
    (dir, anchors)
}

impl Coordinator {
    /// Like [`Coordinator::start`], with the coordinator's stderr kept in `log` (the security tests read the
    /// refusals it logs). Clients and workers use `scheme`, `client_args` and `worker_args`, set here.
    pub fn start_logged(
        dir: &Path,
        extra: &[&str],
        log: &Path,
        scheme: &'static str,
        client_args: &[&str],
        worker_args: &[&str],
    ) -> Self {
        Self::start_logged_on(
            free_port(),
            dir,
            extra,
            log,
            scheme,
            client_args,
            worker_args,
        )
    }

    /// [`Coordinator::start_logged`] on a given port (a test that starts a worker before its coordinator).
    pub fn start_logged_on(
        port: u16,
        dir: &Path,
        extra: &[&str],
        log: &Path,
        scheme: &'static str,
        client_args: &[&str],
        worker_args: &[&str],
    ) -> Self {
        let strings = |a: &[&str]| a.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        let mut c = Coordinator {
            port,
            db: dir.join("queue.sqlite"),
            proc: None,
            extra: strings(extra),
            client_args: strings(client_args),
            worker_args: strings(worker_args),
            scheme,
            log: Some(log.to_path_buf()),
        };
        c.spawn();
        c
    }
}

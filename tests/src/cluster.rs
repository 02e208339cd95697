//! A coordinator process on a fixed loopback port (so a test can kill and restart it on the same address), its
//! workers, and the client verbs a test calls against it.

use crate::binary::bin;
use crate::process::{free_port, stderr, wait_until, Proc};
use std::net::{SocketAddr, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::Duration;

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
        let child = Command::new(bin())
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
        let mut cmd = Command::new(bin());
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
        Command::new(bin())
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

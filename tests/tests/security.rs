//! Security and transport limits with real processes on 127.0.0.1: a job over TLS with tokens gives the same
//! bytes as `crease run`; every kind of refused call is refused with the right code and logged with method
//! and peer, never with a token; an over-size message is refused; a worker at capacity refuses more work and
//! the coordinator hands the task back without charging it.

use crease_e2e::*;
use crease_net::{ClientSecurity, ClientTls, Secret};
use crease_proto as pb;
use crease_proto::worker_client::WorkerClient;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::Instant;

const USER_TOKEN: &str = "ct-user-4f2a9c1e7b";
const ROTATED_TOKEN: &str = "ct-older-0d8e6b5a3c";
const WORKER_TOKEN: &str = "wt-cluster-7e1f3b9d2a";
const WRONG_TOKEN: &str = "wrong-guess-55aa33cc";
const ALL_TOKENS: [&str; 4] = [USER_TOKEN, ROTATED_TOKEN, WORKER_TOKEN, WRONG_TOKEN];

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn certs(out: &Path) {
    let o = Command::new(bin())
        .args(["certs", "--out", path(out)])
        .output()
        .unwrap();
    assert!(o.status.success(), "crease certs: {}", stderr(&o));
}

fn secret_file(p: &Path, text: &str) -> PathBuf {
    std::fs::write(p, text).unwrap();
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(p, std::fs::Permissions::from_mode(0o600)).unwrap();
    }
    p.to_path_buf()
}

/// Files of a secured cluster under `d`.
struct Files {
    certs: PathBuf,
    client_tokens: PathBuf,
    user_token: PathBuf,
    worker_token: PathBuf,
    log: PathBuf,
}

impl Files {
    fn new(d: &Path) -> Self {
        let certs_dir = d.join("certs");
        certs(&certs_dir);
        Files {
            client_tokens: secret_file(
                &d.join("client-tokens"),
                &format!("# rotation: the new token first\n{USER_TOKEN}\n\n  {ROTATED_TOKEN}  \n"),
            ),
            user_token: secret_file(&d.join("user-token"), &format!("{USER_TOKEN}\n")),
            worker_token: secret_file(&d.join("worker-token"), &format!("{WORKER_TOKEN}\n")),
            log: d.join("coordinator.log"),
            certs: certs_dir,
        }
    }

    fn cert(&self, name: &str) -> String {
        path(&self.certs.join(name)).to_string()
    }

    fn start(&self, d: &Path) -> Coordinator {
        let (ca, cert, key) = (
            self.cert("ca.pem"),
            self.cert("coordinator.pem"),
            self.cert("coordinator.key"),
        );
        let (wcert, wkey) = (self.cert("worker.pem"), self.cert("worker.key"));
        let extra = [
            "--tls-cert",
            &cert,
            "--tls-key",
            &key,
            "--tls-ca",
            &ca,
            "--client-tokens-file",
            path(&self.client_tokens),
            "--worker-token-file",
            path(&self.worker_token),
        ];
        let client = ["--tls-ca", &ca, "--token-file", path(&self.user_token)];
        let worker = [
            "--tls-ca",
            &ca,
            "--tls-cert",
            &wcert,
            "--tls-key",
            &wkey,
            "--worker-token-file",
            path(&self.worker_token),
        ];
        Coordinator::start_logged(d, &extra, &self.log, "https", &client, &worker)
    }
}

/// A client command against `url` with exactly `args` (no defaults from the coordinator handle).
fn cli_raw(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut cmd = Command::new(bin());
    cmd.args(args).env_remove("CREASE_TOKEN");
    for (k, v) in env {
        cmd.env(k, v);
    }
    cmd.output().unwrap()
}

fn assert_fails_with(o: &Output, what: &str, needles: &[&str]) {
    assert!(!o.status.success(), "{what} succeeded: {}", stderr(o));
    let e = stderr(o);
    for n in needles {
        assert!(e.contains(n), "{what}: `{n}` not in: {e}");
    }
    for t in ALL_TOKENS {
        assert!(!e.contains(t), "{what}: a token was printed: {e}");
    }
}

/// Runs a worker that must be refused by the coordinator; returns its stderr.
fn refused_worker(c: &Coordinator, d: &Path, name: &str, token_file: &Path, f: &Files) -> String {
    let log = d.join(format!("worker-{name}.log"));
    let mut p = Proc(
        Command::new(bin())
            .args(["worker", "--coordinator", &c.url(), "--name", name])
            .args(["--tls-ca", &f.cert("ca.pem")])
            .args(["--worker-token-file", path(token_file)])
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&log).unwrap())
            .spawn()
            .unwrap(),
    );
    let start = Instant::now();
    let status = loop {
        if let Some(s) = p.0.try_wait().unwrap() {
            break s;
        }
        assert!(start.elapsed() < DEADLINE, "worker {name} was not refused");
        std::thread::sleep(std::time::Duration::from_millis(50));
    };
    let text = std::fs::read_to_string(&log).unwrap();
    assert!(!status.success(), "worker {name} exited cleanly: {text}");
    assert!(text.contains("refused the registration"), "{text}");
    text
}

/// The worker's gRPC port, from its log.
fn worker_url(log: &Path, scheme: &str) -> String {
    let mut url = String::new();
    wait_until("the worker to listen", || {
        let text = std::fs::read_to_string(log).unwrap_or_default();
        match text
            .split("listening on ")
            .nth(1)
            .and_then(|r| r.split(',').next())
        {
            Some(addr) => {
                url = format!("{scheme}://{addr}");
                true
            }
            None => false,
        }
    });
    url
}

fn rt() -> tokio::runtime::Runtime {
    tokio::runtime::Runtime::new().unwrap()
}

async fn worker_client(
    url: &str,
    ca: Option<&Path>,
    token: Option<&str>,
) -> WorkerClient<crease_net::AuthChannel> {
    let net = ClientSecurity {
        tls: ca.map(|ca| ClientTls::load(ca, Some("crease-worker".into())).unwrap()),
        token: token.map(Secret::new),
        ..ClientSecurity::default()
    };
    WorkerClient::new(net.connect_lazy(url).unwrap())
}

fn cancel_req() -> pb::CancelTaskRequest {
    pb::CancelTaskRequest {
        job_id: "job-x".into(),
        task_key: "k".into(),
        attempt: 1,
    }
}

/// A weight-block task of the job in `job_toml` (valid payload; with a test delay it just waits).
fn held_task(job_toml: &Path, id: &str) -> pb::Task {
    let spec =
        crease_jobs::JobSpec::from_toml_str(&std::fs::read_to_string(job_toml).unwrap()).unwrap();
    let task = crease_jobs::TaskSpec::WeightBlock {
        job: spec,
        window: 0,
        block: 0,
    };
    pb::Task {
        job_id: id.into(),
        task_key: "held".into(),
        attempt: 1,
        kind: task.kind().into(),
        payload: task.to_payload(),
    }
}

#[test]
fn a_job_over_tls_with_tokens_matches_local_mode_and_every_refusal_is_logged_without_tokens() {
    let (dir, anchors) = setup();
    let d = dir.path();
    local_run(&fixture(), &anchors, &d.join("reference"), "fused", "1");
    let f = Files::new(d);
    let c = f.start(d);
    let _w = c.worker("secure", &[]);

    // The whole job over TLS with tokens: identical bytes.
    let job = job_file(d, "tls", &fixture(), &anchors, &d.join("out"), "fused", "");
    let id = c.submit(&job);
    let s = c.wait_state(&id, &["done", "failed"]);
    assert_eq!(s["state"], "done", "{s}");
    assert_complete_and_identical(&d.join("reference"), &d.join("out"));
    // The older token of a rotation still works (from the environment this time).
    let url = c.url();
    let ca = f.cert("ca.pem");
    let o = cli_raw(
        &["jobs", "--coordinator", &url, "--tls-ca", &ca],
        &[("CREASE_TOKEN", ROTATED_TOKEN)],
    );
    assert!(o.status.success(), "rotated token: {}", stderr(&o));

    // Refusals seen by users.
    let no_token = cli_raw(&["jobs", "--coordinator", &url, "--tls-ca", &ca], &[]);
    assert_fails_with(
        &no_token,
        "no token",
        &["needs a client bearer token", "--token-file"],
    );
    let wrong = cli_raw(
        &["jobs", "--coordinator", &url, "--tls-ca", &ca],
        &[("CREASE_TOKEN", WRONG_TOKEN)],
    );
    assert_fails_with(&wrong, "wrong token", &["not valid"]);
    let worker_as_user = cli_raw(
        &["jobs", "--coordinator", &url, "--tls-ca", &ca],
        &[("CREASE_TOKEN", WORKER_TOKEN)],
    );
    assert_fails_with(
        &worker_as_user,
        "worker token as a user",
        &["may not call it"],
    );
    let plain_url = url.replace("https://", "http://");
    let plaintext = cli_raw(
        &[
            "jobs",
            "--coordinator",
            &plain_url,
            "--token-file",
            path(&f.user_token),
        ],
        &[],
    );
    assert_fails_with(&plaintext, "plaintext client", &["https://", "--tls-ca"]);
    let other = d.join("other-ca");
    certs(&other);
    let other_ca = cli_raw(
        &[
            "jobs",
            "--coordinator",
            &url,
            "--tls-ca",
            path(&other.join("ca.pem")),
            "--token-file",
            path(&f.user_token),
        ],
        &[],
    );
    assert_fails_with(
        &other_ca,
        "client trusting another CA",
        &["not signed by the CA"],
    );

    // Refusals seen by workers: a user's token, a wrong token.
    let e = refused_worker(&c, d, "with-client-token", &f.user_token, &f);
    assert!(e.contains("may not call it"), "{e}");
    let wrong_file = secret_file(&d.join("wrong-token"), WRONG_TOKEN);
    let e = refused_worker(&c, d, "with-wrong-token", &wrong_file, &f);
    assert!(e.contains("not valid"), "{e}");

    // A worker's own server refuses Execute and Cancel without the cluster secret.
    let wurl = worker_url(&d.join("worker-secure.log"), "https");
    let ca_path = f.certs.join("ca.pem");
    rt().block_on(async {
        for token in [None, Some(USER_TOKEN), Some(WRONG_TOKEN)] {
            let mut w = worker_client(&wurl, Some(&ca_path), token).await;
            let e = w.cancel(cancel_req()).await.unwrap_err();
            assert_eq!(e.code(), tonic::Code::Unauthenticated, "{token:?}: {e}");
            let e = w.execute(held_task(&job, "job-x")).await.unwrap_err();
            assert_eq!(e.code(), tonic::Code::Unauthenticated, "{token:?}: {e}");
        }
        // With it, the same call goes through (nothing to cancel).
        let mut w = worker_client(&wurl, Some(&ca_path), Some(WORKER_TOKEN)).await;
        assert!(!w.cancel(cancel_req()).await.unwrap().into_inner().found);
    });

    // Every refusal is in the coordinator's log with method and peer, and no token is anywhere in it.
    let log = std::fs::read_to_string(&f.log).unwrap();
    let refusals: Vec<&str> = log
        .lines()
        .filter(|l| l.contains("refused gRPC call"))
        .collect();
    for (method, kind, n) in [
        ("/crease.v1.Coordinator/ListJobs", "unauthenticated", 2),
        ("/crease.v1.Coordinator/ListJobs", "permission denied", 1),
        (
            "/crease.v1.Coordinator/RegisterWorker",
            "permission denied",
            1,
        ),
        (
            "/crease.v1.Coordinator/RegisterWorker",
            "unauthenticated",
            1,
        ),
    ] {
        let found = refusals
            .iter()
            .filter(|l| {
                l.contains(method)
                    && l.contains(kind)
                    && l.contains("peer")
                    && l.contains("127.0.0.1:")
            })
            .count();
        assert!(
            found >= n,
            "{n} {kind} refusal(s) of {method} expected in:\n{log}"
        );
    }
    let wlog = std::fs::read_to_string(d.join("worker-secure.log")).unwrap();
    for method in ["/crease.v1.Worker/Execute", "/crease.v1.Worker/Cancel"] {
        assert!(
            wlog.lines().any(|l| l.contains("refused gRPC call")
                && l.contains(method)
                && l.contains("peer")
                && l.contains("127.0.0.1:")),
            "{method} refusal not in the worker log:\n{wlog}"
        );
    }
    for t in ALL_TOKENS {
        assert!(
            !log.contains(t),
            "a token is in the coordinator log:\n{log}"
        );
        assert!(!wlog.contains(t), "a token is in the worker log:\n{wlog}");
    }
}

#[test]
fn a_job_spec_over_the_message_limit_is_refused_with_a_clear_error() {
    let (dir, anchors) = setup();
    let d = dir.path();
    let c = Coordinator::start(d, &["--max-message-mib", "1"]);
    let job = job_file(d, "big", &fixture(), &anchors, &d.join("out"), "fused", "");
    let mut text = std::fs::read_to_string(&job).unwrap();
    text.push_str(&format!("# {}\n", "x".repeat(1536 * 1024)));
    let big = d.join("big-spec.toml");
    std::fs::write(&big, text).unwrap();
    let o = c.cli(&["submit", path(&big)]);
    assert!(!o.status.success(), "an over-size spec was accepted");
    let e = stderr(&o);
    assert!(
        e.contains("--max-message-mib") && e.contains("too large"),
        "{e}"
    );
    // The limit is a limit, not a refusal of everything.
    let ok = c.cli(&["submit", path(&job)]);
    assert!(ok.status.success(), "{}", stderr(&ok));
}

#[test]
fn a_worker_at_capacity_refuses_execute_and_the_coordinator_hands_the_task_back_uncharged() {
    let (dir, anchors) = setup();
    let d = dir.path();
    local_run(&fixture(), &anchors, &d.join("reference"), "fused", "1");
    let c = Coordinator::start(d, &[]);
    // Fused jobs have no weight-block task: only the test's own held task waits.
    let _w = c.worker("busy", &[("CREASE_TEST_TASK_DELAY", "weight-block=60000")]);
    let wurl = worker_url(&d.join("worker-busy.log"), "http");
    // Every counted failure would fail this job at once.
    let job = job_file(
        d,
        "cap",
        &fixture(),
        &anchors,
        &d.join("out"),
        "fused",
        "max_task_attempts = 1",
    );
    let rt = rt();
    let mut w = rt.block_on(worker_client(&wurl, None, None));
    let held = rt.block_on(w.execute(held_task(&job, "held"))).unwrap();
    let e = rt
        .block_on(w.execute(held_task(&job, "second")))
        .unwrap_err();
    assert_eq!(e.code(), tonic::Code::ResourceExhausted, "{e}");

    let id = c.submit(&job);
    wait_until("the coordinator to meet the full worker", || {
        tasks(&c.status(&id)).iter().any(|t| {
            t["last_error"]
                .as_str()
                .is_some_and(|e| e.contains("at capacity"))
        })
    });
    let found = rt
        .block_on(w.cancel(pb::CancelTaskRequest {
            job_id: "held".into(),
            task_key: "held".into(),
            attempt: 1,
        }))
        .unwrap()
        .into_inner()
        .found;
    assert!(found);
    drop(held);
    let s = c.wait_state(&id, &["done", "failed"]);
    assert_eq!(s["state"], "done", "{s}");
    assert_eq!(s["tasks_failed"], 0, "{s}");
    assert_complete_and_identical(&d.join("reference"), &d.join("out"));
    // The worker stayed registered: the refusal was not taken for a lost worker.
    let wlog = std::fs::read_to_string(d.join("worker-busy.log")).unwrap();
    assert_eq!(wlog.matches("registered as").count(), 1, "{wlog}");
}

/// Runs a command that must exit by itself (a misconfiguration), killing it at the deadline.
fn must_exit(args: &[&str]) -> (bool, String) {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("stderr");
    let mut p = Proc(
        Command::new(bin())
            .args(args)
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&log).unwrap())
            .spawn()
            .unwrap(),
    );
    let start = Instant::now();
    let status = loop {
        if let Some(s) = p.0.try_wait().unwrap() {
            break s;
        }
        assert!(start.elapsed() < DEADLINE, "{args:?} did not exit");
        std::thread::sleep(std::time::Duration::from_millis(20));
    };
    (status.success(), std::fs::read_to_string(&log).unwrap())
}

#[test]
fn misconfigurations_are_named_and_half_secured_clusters_warned_about() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let f = Files::new(d);
    #[cfg(unix)]
    for key in ["coordinator.key", "worker.key"] {
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(f.certs.join(key))
            .unwrap()
            .permissions()
            .mode();
        assert_eq!(mode & 0o777, 0o600, "{key}");
    }
    let empty = secret_file(&d.join("empty-tokens"), "# none yet\n\n");
    let listen = format!("127.0.0.1:{}", free_port());
    let db = d.join("q.sqlite");
    let base = ["coordinator", "--listen", &listen, "--db", path(&db)];
    let (cert, key, ca) = (
        f.cert("coordinator.pem"),
        f.cert("coordinator.key"),
        f.cert("ca.pem"),
    );
    for (extra, needles) in [
        (
            vec!["--client-tokens-file", "/nonexistent/crease-client-tokens"],
            vec!["--client-tokens-file", "/nonexistent/crease-client-tokens"],
        ),
        (
            vec!["--worker-token-file", path(&empty)],
            vec!["--worker-token-file", "empty-tokens", "no token"],
        ),
        (vec!["--tls-cert", cert.as_str()], vec!["--tls-key"]),
        (
            vec!["--tls-cert", ca.as_str(), "--tls-key", ca.as_str()],
            vec!["--tls-key", "ca.pem", "private key"],
        ),
        (vec!["--max-message-mib", "0"], vec!["--max-message-mib"]),
    ] {
        let args: Vec<&str> = base.iter().copied().chain(extra.iter().copied()).collect();
        let (ok, err) = must_exit(&args);
        assert!(!ok, "{extra:?} was accepted");
        for n in needles {
            assert!(err.contains(n), "{extra:?}: `{n}` not in: {err}");
        }
    }
    let (ok, err) = must_exit(&["jobs", "--token-file", path(&empty)]);
    assert!(
        !ok && err.contains("--token-file") && err.contains("empty-tokens"),
        "{err}"
    );

    // TLS without tokens runs, with a warning that anyone may call it.
    let log = d.join("tls-only.log");
    let c = Coordinator::start_logged(
        d,
        &["--tls-cert", &cert, "--tls-key", &key],
        &log,
        "https",
        &["--tls-ca", &ca],
        &[],
    );
    wait_until("the unauthenticated warning", || {
        std::fs::read_to_string(&log).is_ok_and(|t| t.contains("encrypted but unauthenticated"))
    });
    let o = c.cli(&["jobs"]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn a_task_over_the_workers_message_limit_fails_its_job_clearly_instead_of_looping() {
    let (dir, anchors) = setup();
    let d = dir.path();
    let mut c = Coordinator::start(d, &[]);
    c.worker_args = vec!["--max-message-mib".into(), "1".into()];
    let _w = c.worker("small", &[]);
    // The job name travels in every task's payload: 1.5 MiB of it does not fit a 1 MiB worker.
    let job = job_file(d, "huge", &fixture(), &anchors, &d.join("out"), "fused", "");
    let text = std::fs::read_to_string(&job).unwrap().replacen(
        "name = \"huge\"",
        &format!("name = \"{}\"", "n".repeat(1536 * 1024)),
        1,
    );
    std::fs::write(&job, text).unwrap();
    let id = c.submit(&job);
    let s = c.wait_state(&id, &["done", "failed"]);
    assert_eq!(s["state"], "failed", "{}", s["message"]);
    let msg = s["message"].as_str().unwrap();
    assert!(msg.contains("--max-message-mib"), "{msg}");
}

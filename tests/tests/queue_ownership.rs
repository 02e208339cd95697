//! Who owns a queue and its jobs, with real processes on 127.0.0.1: one coordinator per queue file (a second
//! one refuses, naming the first); a client token stands for one submission (same spec: the same job; another
//! spec: refused, naming the job); one live job per output location; and a coordinator restart that does not
//! redo the work its workers finished or were still running.

use crease_e2e::*;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

#[test]
fn a_second_coordinator_on_the_same_queue_refuses_naming_the_first() {
    let dir = tempfile::tempdir().unwrap();
    let first = Coordinator::start(dir.path(), &[]);
    let port = free_port();
    let log = dir.path().join("second.log");
    let mut second = Proc(
        Command::new(bin())
            .args(["coordinator", "--listen", &format!("127.0.0.1:{port}")])
            .arg("--db")
            .arg(&first.db)
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&log).unwrap())
            .spawn()
            .unwrap(),
    );
    let started = Instant::now();
    let status = loop {
        if let Some(s) = second.0.try_wait().unwrap() {
            break s;
        }
        // Still running: it took the queue (and would requeue the first one's running tasks).
        assert!(
            started.elapsed() < Duration::from_secs(20),
            "a second coordinator started on the same queue and is serving"
        );
        std::thread::sleep(Duration::from_millis(50));
    };
    let err = std::fs::read_to_string(&log).unwrap();
    assert!(!status.success(), "a second coordinator started: {err}");
    let holder = first.proc.as_ref().unwrap().pid();
    assert!(
        err.contains(&format!("pid {holder}"))
            && err.contains(&format!("127.0.0.1:{}", first.port))
            && err.contains(&first.db.display().to_string()),
        "{err}"
    );
    // The first one is untouched and still serves.
    let o = first.cli(&["jobs", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn the_lock_dies_with_its_coordinator_so_a_restart_after_a_crash_starts() {
    let dir = tempfile::tempdir().unwrap();
    let mut c = Coordinator::start(dir.path(), &[]);
    c.proc.as_mut().unwrap().kill();
    // spawn() waits until the new process listens: it would time out if the old lock were still held.
    c.spawn();
    let o = c.cli(&["jobs", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn a_reused_client_token_and_a_busy_output_are_refused_naming_the_job() {
    let (dir, anchors) = setup();
    let d = dir.path();
    // No worker: the first job stays live (waiting) for the whole test.
    let c = Coordinator::start(d, &["--grace-secs", "600"]);
    let out = d.join("out");
    let token = "client_token = \"tok-1\"";
    let job = job_file(d, "first", &fixture(), &anchors, &out, "fused", token);
    let id = c.submit(&job);
    // The same spec under the same token: the same job, exit 0.
    assert_eq!(c.submit(&job), id);
    // Another spec (another mode) under the same token: refused, naming the job.
    let other = job_file(
        d,
        "first-b",
        &fixture(),
        &anchors,
        &out,
        "per-anchor",
        token,
    );
    let o = c.cli(&["submit", other.to_str().unwrap()]);
    let err = stderr(&o);
    assert!(!o.status.success(), "{err}");
    assert!(err.contains(&id) && err.contains("tok-1"), "{err}");
    // Another job (no token) writing where the live one writes: refused, naming it.
    let busy = job_file(d, "second", &fixture(), &anchors, &out, "fused", "");
    let o = c.cli(&["submit", busy.to_str().unwrap()]);
    let err = stderr(&o);
    assert!(!o.status.success(), "{err}");
    assert!(
        err.contains(&id) && err.contains(&out.display().to_string()),
        "{err}"
    );
    // Once the live job is cancelled, the output is free.
    let o = c.cli(&["cancel", &id]);
    assert!(o.status.success(), "{}", stderr(&o));
    let second = c.submit(&busy);
    assert_ne!(second, id);
}

#[test]
fn a_coordinator_restart_keeps_the_running_task_and_its_result_without_a_second_attempt() {
    let (dir, anchors) = setup();
    let d = dir.path();
    local_run(&fixture(), &anchors, &d.join("reference"), "fused", "1");
    let mut c = Coordinator::start(d, &[]);
    // Long enough that the coordinator is killed and back while the first window runs.
    let _w = c.worker(
        "steady",
        &[("CREASE_TEST_TASK_DELAY", "weight-window=4000")],
    );
    let job = job_file(d, "keep", &fixture(), &anchors, &d.join("out"), "fused", "");
    let id = c.submit(&job);
    wait_until("a weight window to run", || {
        tasks(&c.status(&id))
            .iter()
            .any(|t| t["kind"] == "weight-window" && t["state"] == "running")
    });
    // Crash the coordinator mid-task; the worker keeps running it.
    c.proc.as_mut().unwrap().kill();
    std::thread::sleep(Duration::from_millis(500));
    c.spawn();
    let after = c.wait_state(&id, &["done", "failed"]);
    assert_eq!(after["state"], "done", "{after}");
    for t in tasks(&after) {
        assert_eq!(t["attempts"], 1, "ran twice: {t}");
    }
    assert_complete_and_identical(&d.join("reference"), &d.join("out"));
    // The queue says how: the attempt was adopted, not re-run.
    let o = c.cli(&["logs", &id]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("reported by") && text.contains("after a coordinator restart"),
        "{text}"
    );
}

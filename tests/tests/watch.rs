//! `crease watch` against real coordinator and worker processes: it rides out a coordinator restart (same
//! queue file) and ends 0 when the job completes; its exit status tells a failed job (3), a cancelled one (4)
//! and a lost coordinator (5) apart; a failed or cancelled watch never says "done".

use crease_e2e::*;
use std::fs::File;
use std::path::Path;
use std::process::{Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

/// Starts `crease watch JOB` with its stderr in `log`.
fn start_watch(c: &Coordinator, id: &str, log: &Path, reconnect_secs: &str) -> Proc {
    Proc(
        Command::new(bin())
            .args(["watch", id, "--coordinator", &c.url()])
            .args(["--reconnect-secs", reconnect_secs])
            .stdout(Stdio::null())
            .stderr(File::create(log).unwrap())
            .spawn()
            .expect("start crease watch"),
    )
}

fn wait_exit(p: &mut Proc, what: &str) -> ExitStatus {
    let start = Instant::now();
    loop {
        if let Some(s) = p.0.try_wait().unwrap() {
            return s;
        }
        assert!(start.elapsed() < DEADLINE, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

fn read(p: &Path) -> String {
    std::fs::read_to_string(p).unwrap_or_default()
}

#[test]
fn watch_rides_out_a_coordinator_restart() {
    let (dir, anchors) = setup();
    let d = dir.path();
    let mut c = Coordinator::start(d, &[]);
    // Slow tasks, so the job is still running when the coordinator goes down and comes back.
    let _w = c.worker("w", &[("CREASE_TEST_TASK_DELAY", "*=400")]);
    let out = d.join("out");
    let job = job_file(d, "restart", &fixture(), &anchors, &out, "fused", "");
    let id = c.submit(&job);
    let log = d.join("watch.log");
    let mut watch = start_watch(&c, &id, &log, "60");
    wait_until("a task to be done", || {
        c.status(&id)["tasks_done"].as_u64().unwrap_or(0) >= 1
    });
    let mut old = c.proc.take().unwrap();
    old.kill();
    assert!(
        watch.0.try_wait().unwrap().is_none(),
        "the watch ended with the coordinator: {}",
        read(&log)
    );
    std::thread::sleep(Duration::from_millis(1500));
    c.spawn();
    let status = wait_exit(&mut watch, "the watch to end");
    let text = read(&log);
    assert_eq!(status.code(), Some(0), "watch: {text}");
    assert!(text.contains("lost the coordinator"), "{text}");
    assert!(text.contains("reconnected to the coordinator"), "{text}");
    assert!(text.contains(&format!("{id} done")), "{text}");
    assert_eq!(c.status(&id)["state"], "done");
    let report = std::fs::read_to_string(out.join("report.json")).unwrap();
    assert!(report.contains("\"complete\": true"));
}

#[test]
fn exit_status_tells_failed_cancelled_and_lost_apart() {
    let (dir, anchors) = setup();
    let d = dir.path();
    let mut c = Coordinator::start(d, &[]);
    let _w = c.worker("w", &[("CREASE_TEST_TASK_DELAY", "position=60000")]);

    // Failed: one CG iteration cannot converge; the message names a flag that exists.
    let failing = job_file(d, "cg", &fixture(), &anchors, &d.join("o1"), "fused", "");
    let text = std::fs::read_to_string(&failing)
        .unwrap()
        .replace("shift = 2\n", "shift = 2\ncg_max_iter = 1\n");
    std::fs::write(&failing, text).unwrap();
    let o = c.cli(&["submit", failing.to_str().unwrap(), "--watch"]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(3), "{err}");
    assert!(err.contains("failed") && !err.contains(" done:"), "{err}");
    assert!(err.contains("deform.cg_max_iterations"), "{err}");
    let keys = Command::new(bin())
        .args(["tuning", "deform.cg"])
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&keys.stdout).contains("deform.cg_max_iterations = "));

    // Cancelled.
    let slow = job_file(d, "slow", &fixture(), &anchors, &d.join("o2"), "fused", "");
    let id = c.submit(&slow);
    wait_until("a positioning task to run", || {
        c.status(&id)["tasks_running"].as_u64() == Some(1)
    });
    let log = d.join("cancel.log");
    let mut watch = start_watch(&c, &id, &log, "60");
    std::thread::sleep(Duration::from_millis(500));
    assert!(c.cli(&["cancel", &id]).status.success());
    let status = wait_exit(&mut watch, "the watch of a cancelled job");
    let text = read(&log);
    assert_eq!(status.code(), Some(4), "{text}");
    assert!(
        text.contains("cancelled") && !text.contains(" done"),
        "{text}"
    );

    // Lost: the coordinator goes away for good while a job runs.
    let lost = job_file(d, "lost", &fixture(), &anchors, &d.join("o3"), "fused", "");
    let id = c.submit(&lost);
    let log = d.join("lost.log");
    let mut watch = start_watch(&c, &id, &log, "2");
    std::thread::sleep(Duration::from_millis(500));
    c.proc.take().unwrap().kill();
    let status = wait_exit(&mut watch, "the watch to give up");
    let text = read(&log);
    assert_eq!(status.code(), Some(5), "{text}");
    assert!(text.contains("gave up reconnecting"), "{text}");
}

#[test]
fn watch_help_documents_the_exit_codes() {
    let o = Command::new(bin())
        .args(["watch", "--help"])
        .output()
        .unwrap();
    let help = String::from_utf8_lossy(&o.stdout);
    for line in [
        "0  the job is done",
        "3  the job failed",
        "4  the job was cancelled",
        "5  lost the coordinator",
    ] {
        assert!(help.contains(line), "{line}: {help}");
    }
}

//! Cluster tests with real processes on 127.0.0.1: a coordinator and workers started from the `crease`
//! binary, jobs submitted with `crease submit`, outputs compared byte for byte with `crease run` (local
//! single-node mode). Every child is killed when its handle drops and every wait has a deadline, so a broken
//! build fails instead of hanging.

use crease_e2e::*;
use std::path::PathBuf;
use std::process::Command;
use std::time::{Duration, Instant};
#[test]
fn one_worker_three_workers_and_local_mode_write_identical_bytes() {
    let (dir, anchors) = setup();
    let d = dir.path();
    let input = fixture();
    for mode in ["per-anchor", "fused"] {
        local_run(
            &input,
            &anchors,
            &d.join(format!("local-{mode}")),
            mode,
            "1",
        );
    }
    // Local mode with several workers and concurrent tasks is also identical.
    local_run(
        &input,
        &anchors,
        &d.join("local3-per-anchor"),
        "per-anchor",
        "3",
    );
    assert_complete_and_identical(&d.join("local-per-anchor"), &d.join("local3-per-anchor"));

    let c = Coordinator::start(d, &[]);
    let _w1 = c.worker("w-one", &[]);
    let job1 = job_file(d, "one", &input, &anchors, &d.join("one"), "per-anchor", "");
    let id1 = c.submit(&job1);
    let s1 = c.wait_state(&id1, &["done", "failed"]);
    assert_eq!(s1["state"], "done", "{s1}");
    let blocks = tasks(&s1)
        .iter()
        .filter(|t| t["kind"] == "weight-block")
        .count();
    assert!(
        blocks >= 10,
        "per-anchor job planned only {blocks} weight blocks"
    );

    let _w2 = c.worker("w-two", &[]);
    let _w3 = c.worker("w-three", &[]);
    for (name, mode) in [("three", "per-anchor"), ("three-fused", "fused")] {
        let job = job_file(d, name, &input, &anchors, &d.join(name), mode, "");
        let id = c.submit(&job);
        let s = c.wait_state(&id, &["done", "failed"]);
        assert_eq!(s["state"], "done", "{s}");
    }
    let s3 = c.status("job-00002");
    let workers: std::collections::BTreeSet<String> = tasks(&s3)
        .iter()
        .map(|t| t["worker"].as_str().unwrap_or("").to_string())
        .collect();
    assert!(workers.len() >= 2, "all tasks ran on {workers:?}");

    assert_complete_and_identical(&d.join("local-per-anchor"), &d.join("one"));
    assert_complete_and_identical(&d.join("local-per-anchor"), &d.join("three"));
    assert_complete_and_identical(&d.join("local-fused"), &d.join("three-fused"));
}

#[test]
fn sigkill_of_a_worker_in_a_weight_block_still_completes_identically() {
    let (dir, anchors) = setup();
    let d = dir.path();
    local_run(
        &fixture(),
        &anchors,
        &d.join("reference"),
        "per-anchor",
        "1",
    );
    let c = Coordinator::start(d, &[]);
    // This worker sits in every weight block long enough to be killed there.
    let mut victim = c.worker(
        "victim",
        &[("CREASE_TEST_TASK_DELAY", "weight-block=30000")],
    );
    let job = job_file(
        d,
        "kill",
        &fixture(),
        &anchors,
        &d.join("out"),
        "per-anchor",
        "",
    );
    let id = c.submit(&job);
    let mut killed_key = String::new();
    wait_until("a weight block to run", || {
        let s = c.status(&id);
        match tasks(&s)
            .iter()
            .find(|t| t["kind"] == "weight-block" && t["state"] == "running")
        {
            Some(t) => {
                killed_key = t["key"].as_str().unwrap().to_string();
                true
            }
            None => false,
        }
    });
    victim.kill();
    let _healthy = c.worker("healthy", &[]);
    let s = c.wait_state(&id, &["done", "failed"]);
    assert_eq!(s["state"], "done", "{s}");
    let t = tasks(&s)
        .into_iter()
        .find(|t| t["key"] == killed_key.as_str())
        .unwrap();
    assert!(t["attempts"].as_u64().unwrap() >= 2, "{t}");
    assert_complete_and_identical(&d.join("reference"), &d.join("out"));
}

#[test]
fn coordinator_restart_resumes_without_losing_or_recomputing_tasks() {
    let (dir, anchors) = setup();
    let d = dir.path();
    local_run(
        &fixture(),
        &anchors,
        &d.join("reference"),
        "per-anchor",
        "1",
    );
    let mut c = Coordinator::start(d, &[]);
    let _w = c.worker("steady", &[("CREASE_TEST_TASK_DELAY", "position=700")]);
    let job = job_file(
        d,
        "restart",
        &fixture(),
        &anchors,
        &d.join("out"),
        "per-anchor",
        "",
    );
    let id = c.submit(&job);
    // Wait until some frames are positioned but not all.
    let mut before = serde_json::Value::Null;
    wait_until("the first positioned frame", || {
        before = c.status(&id);
        tasks(&before)
            .iter()
            .any(|t| t["kind"] == "position" && t["state"] == "done")
    });
    let total = tasks(&before).len();
    let done_before: Vec<(String, u64)> = tasks(&before)
        .iter()
        .filter(|t| t["state"] == "done")
        .map(|t| {
            (
                t["key"].as_str().unwrap().to_string(),
                t["attempts"].as_u64().unwrap(),
            )
        })
        .collect();
    assert!(
        done_before.len() < total,
        "the job finished before the restart"
    );
    // Crash, then restart on the same address and queue file.
    c.proc.as_mut().unwrap().kill();
    c.spawn();
    let after = c.wait_state(&id, &["done", "failed"]);
    assert_eq!(after["state"], "done", "{after}");
    assert_eq!(tasks(&after).len(), total, "tasks were lost or added");
    for (key, attempts) in done_before {
        let t = tasks(&after)
            .into_iter()
            .find(|t| t["key"] == key.as_str())
            .unwrap();
        assert_eq!(
            t["attempts"].as_u64().unwrap(),
            attempts,
            "{key} was recomputed: {t}"
        );
    }
    assert_complete_and_identical(&d.join("reference"), &d.join("out"));
}

#[test]
fn losing_every_worker_reports_waiting_then_fails_after_the_grace_period() {
    let (dir, anchors) = setup();
    let d = dir.path();
    let c = Coordinator::start(d, &["--grace-secs", "3"]);
    let mut w = c.worker("only", &[("CREASE_TEST_TASK_DELAY", "*=30000")]);
    let job = job_file(
        d,
        "orphan",
        &fixture(),
        &anchors,
        &d.join("out"),
        "fused",
        "",
    );
    let id = c.submit(&job);
    wait_until("a task to run", || {
        c.status(&id)["tasks_running"].as_u64() == Some(1)
    });
    w.kill();
    let waiting = c.wait_state(&id, &["waiting", "failed"]);
    assert_eq!(waiting["state"], "waiting", "{waiting}");
    assert!(
        waiting["message"]
            .as_str()
            .unwrap()
            .contains("waiting for a worker"),
        "{waiting}"
    );
    let failed = c.wait_state(&id, &["failed", "done"]);
    assert_eq!(failed["state"], "failed");
    let msg = failed["message"].as_str().unwrap();
    assert!(
        msg.contains("no worker was available") && msg.contains("grace period"),
        "{msg}"
    );
    assert!(!d.join("out/report.json").exists());
}

#[test]
fn a_task_that_always_fails_is_retried_to_the_limit_then_fails_the_job() {
    let (dir, anchors) = setup();
    let d = dir.path();
    // The directory for positioned frames is blocked by a plain file: submit-time checks (the output is
    // writable) pass and the weight tasks succeed, but every attempt to store a positioned frame gets an I/O
    // error (retryable), so that task is retried up to the limit.
    let input = fixture();
    std::fs::create_dir_all(d.join("out/.crease-work")).unwrap();
    std::fs::write(d.join("out/.crease-work/positions"), b"not a directory").unwrap();
    let c = Coordinator::start(d, &["--retry-backoff-ms", "50"]);
    let _w = c.worker("one", &[]);
    let job = job_file(
        d,
        "broken",
        &input,
        &anchors,
        &d.join("out"),
        "fused",
        "max_task_attempts = 3",
    );
    let id = c.submit(&job);
    let s = c.wait_state(&id, &["failed", "done"]);
    assert_eq!(s["state"], "failed", "{s}");
    let msg = s["message"].as_str().unwrap();
    let failed: Vec<_> = tasks(&s)
        .into_iter()
        .filter(|t| t["state"] == "failed")
        .collect();
    assert_eq!(failed.len(), 1, "{s}");
    let key = failed[0]["key"].as_str().unwrap();
    assert_eq!(failed[0]["attempts"], 3, "{s}");
    assert!(
        msg.contains(&format!("task `{key}`")) && msg.contains("3 time(s)"),
        "{msg}"
    );
    assert!(key.starts_with("position"), "{msg}");
    assert!(msg.contains(".crease-work/positions"), "{msg}");
    assert!(!d.join("out/report.json").exists());

    // Bad data (a NaN in a late frame) is not retryable: the job fails at the first attempt, naming the file
    // and the vertex.
    let nan = d.join("nan");
    std::fs::create_dir(&nan).unwrap();
    for f in [
        "frame_0020.obj",
        "frame_0021.obj",
        "frame_0022.obj",
        "frame_0023.obj",
    ] {
        std::fs::copy(fixture().join(f), nan.join(f)).unwrap();
    }
    let text = std::fs::read_to_string(nan.join("frame_0023.obj")).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let idx = lines.iter().position(|l| l.starts_with("v ")).unwrap() + 10;
    lines[idx] = "v nan 0 0".into();
    std::fs::write(nan.join("frame_0023.obj"), lines.join("\n")).unwrap();
    let job = job_file(d, "nan", &nan, &anchors, &d.join("out-nan"), "fused", "");
    let id = c.submit(&job);
    let s = c.wait_state(&id, &["failed", "done"]);
    assert_eq!(s["state"], "failed", "{s}");
    let msg = s["message"].as_str().unwrap();
    assert!(
        // 1-based, as in the file: the 11th `v` line.
        msg.contains("frame_0023.obj") && msg.contains("vertex 11") && msg.contains("task `"),
        "{msg}"
    );
    assert!(!d.join("out-nan/report.json").exists());
}

#[test]
fn cancel_stops_running_tasks_promptly_and_presents_nothing_as_complete() {
    let (dir, anchors) = setup();
    let d = dir.path();
    let c = Coordinator::start(d, &[]);
    let _w = c.worker("busy", &[("CREASE_TEST_TASK_DELAY", "*=60000")]);
    let job = job_file(
        d,
        "cancel",
        &fixture(),
        &anchors,
        &d.join("out"),
        "fused",
        "",
    );
    let id = c.submit(&job);
    wait_until("a task to run", || {
        c.status(&id)["tasks_running"].as_u64() == Some(1)
    });
    let o = c.cli(&["cancel", &id]);
    assert!(o.status.success(), "{}", stderr(&o));
    // The worker stops its 60-second task: the coordinator sees it end long before the delay would.
    let start = Instant::now();
    wait_until("the cancelled task to stop", || {
        c.status(&id)["tasks_running"].as_u64() == Some(0)
    });
    assert!(start.elapsed() < Duration::from_secs(30));
    let s = c.status(&id);
    assert_eq!(s["state"], "cancelled");
    assert!(tasks(&s)
        .iter()
        .all(|t| t["state"] != "running" && t["state"] != "queued"));
    assert!(!d.join("out/report.json").exists());
    // Watching a cancelled job ends with a non-zero status naming the state.
    let o = c.cli(&["watch", &id]);
    assert!(
        !o.status.success() && stderr(&o).contains("cancelled"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn bad_specs_and_unreachable_inputs_are_rejected_at_submit() {
    let (dir, anchors) = setup();
    let d = dir.path();
    let c = Coordinator::start(d, &[]);
    let missing = d.join("no-such-input");
    let cases: Vec<(PathBuf, Vec<String>)> = vec![
        (
            job_file(d, "missing", &missing, &anchors, &d.join("o1"), "fused", ""),
            vec![missing.display().to_string()],
        ),
        (
            job_file(
                d,
                "anchors",
                &fixture(),
                &d.join("nope.json"),
                &d.join("o2"),
                "fused",
                "",
            ),
            vec!["nope.json".into()],
        ),
        (
            job_file(d, "mode", &fixture(), &anchors, &d.join("o3"), "magic", ""),
            vec!["magic".into()],
        ),
        (
            job_file(
                d,
                "field",
                &fixture(),
                &anchors,
                &d.join("o4"),
                "fused",
                "colour = 3",
            ),
            vec!["colour".into()],
        ),
        (
            job_file(
                d,
                "attempts",
                &fixture(),
                &anchors,
                &d.join("o5"),
                "fused",
                "max_task_attempts = 0",
            ),
            vec!["max_task_attempts".into()],
        ),
    ];
    for (job, want) in cases {
        let o = c.cli(&["submit", job.to_str().unwrap()]);
        let err = stderr(&o);
        assert!(!o.status.success(), "{} was accepted", job.display());
        for w in want {
            assert!(err.contains(&w), "{}: {err}", job.display());
        }
    }
    let o = c.cli(&["jobs", "--json"]);
    let jobs: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(jobs, serde_json::json!([]), "rejected jobs were queued");

    // Idempotent submit: the same client token names the same job.
    let job = job_file(
        d,
        "token",
        &fixture(),
        &anchors,
        &d.join("o6"),
        "fused",
        r#"client_token = "abc""#,
    );
    let a = c.submit(&job);
    let b = c.submit(&job);
    assert_eq!(a, b);
    let o = c.cli(&["jobs", "--json"]);
    let jobs: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(jobs.as_array().unwrap().len(), 1);
}

#[test]
fn a_worker_of_another_protocol_version_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let c = Coordinator::start(dir.path(), &[]);
    let o = Command::new(bin())
        .args([
            "worker",
            "--coordinator",
            &c.url(),
            "--protocol-version",
            "999",
        ])
        .output()
        .unwrap();
    let err = stderr(&o);
    assert!(!o.status.success(), "{err}");
    assert!(
        err.contains("refused") && err.contains("protocol version 999"),
        "{err}"
    );
}

#[test]
fn sigterm_drains_a_worker_that_finishes_its_task() {
    let (dir, anchors) = setup();
    let d = dir.path();
    let c = Coordinator::start(d, &[]);
    let mut w = c.worker(
        "drained",
        &[("CREASE_TEST_TASK_DELAY", "weight-window=1500")],
    );
    let job = job_file(
        d,
        "drain",
        &fixture(),
        &anchors,
        &d.join("out"),
        "fused",
        "",
    );
    let id = c.submit(&job);
    wait_until("a weight window to run", || {
        tasks(&c.status(&id))
            .iter()
            .any(|t| t["kind"] == "weight-window" && t["state"] == "running")
    });
    sigterm_and_wait(&mut w);
    // The task it was running finished there (first attempt), and a new worker completes the job.
    let s = c.status(&id);
    let first = tasks(&s)
        .into_iter()
        .find(|t| t["kind"] == "weight-window" && t["attempts"] == 1 && t["state"] == "done");
    assert!(first.is_some(), "{s}");
    let _w2 = c.worker("after", &[]);
    let s = c.wait_state(&id, &["done", "failed"]);
    assert_eq!(s["state"], "done", "{s}");
}

#[test]
fn sigterm_hands_back_a_task_that_outlasts_the_drain_timeout() {
    let (dir, anchors) = setup();
    let d = dir.path();
    local_run(&fixture(), &anchors, &d.join("reference"), "fused", "1");
    let c = Coordinator::start(d, &[]);
    // The worker's drain timeout is 5 s (see `Coordinator::worker`); its weight windows would take 60 s.
    let mut w = c.worker("slow", &[("CREASE_TEST_TASK_DELAY", "weight-window=60000")]);
    let job = job_file(
        d,
        "handback",
        &fixture(),
        &anchors,
        &d.join("out"),
        "fused",
        "",
    );
    let id = c.submit(&job);
    let mut key = String::new();
    wait_until("a weight window to run", || {
        match tasks(&c.status(&id))
            .into_iter()
            .find(|t| t["kind"] == "weight-window" && t["state"] == "running")
        {
            Some(t) => {
                key = t["key"].as_str().unwrap().to_string();
                true
            }
            None => false,
        }
    });
    sigterm_and_wait(&mut w);
    // Handed back: queued again, not failed.
    let s = c.status(&id);
    let t = tasks(&s)
        .into_iter()
        .find(|t| t["key"] == key.as_str())
        .unwrap();
    assert_eq!(t["state"], "queued", "{s}");
    let _w2 = c.worker("fast", &[]);
    let s = c.wait_state(&id, &["done", "failed"]);
    assert_eq!(s["state"], "done", "{s}");
    assert_complete_and_identical(&d.join("reference"), &d.join("out"));
}

//! The queue's state machine, without gRPC: ordering, stale reports, the retry policy, cancel, recovery, logs,
//! idempotent submit.

use super::*;
use crease_jobs::FailureKind;
use std::sync::atomic::{AtomicUsize, Ordering};

static NEXT_OUTPUT: AtomicUsize = AtomicUsize::new(0);
use rusqlite::Connection;
use std::path::Path;

fn task(key: &str, deps: &[&str]) -> NewTask {
    NewTask {
        key: key.into(),
        kind: "test".into(),
        payload: "{}".into(),
        deps: deps.iter().map(|d| d.to_string()).collect(),
        expands: false,
    }
}

fn job(priority: i32, tasks: Vec<NewTask>) -> NewJob {
    NewJob {
        name: "j".into(),
        spec_json: "{}".into(),
        info_json: "{}".into(),
        // Each job its own output: two live jobs may not share one.
        output: format!("/tmp/x{}", NEXT_OUTPUT.fetch_add(1, Ordering::Relaxed)),
        priority,
        client_token: None,
        max_task_attempts: 3,
        max_failures: 10,
        tasks,
    }
}

fn err(retryable: bool) -> Failure {
    let kind = if retryable {
        FailureKind::Transient
    } else {
        FailureKind::InvalidInput
    };
    Failure::new(kind, "boom")
}

fn keys(store: &Store) -> Vec<String> {
    store
        .ready_tasks(100)
        .unwrap()
        .into_iter()
        .map(|t| format!("{}:{}", t.job_id, t.key))
        .collect()
}

#[test]
fn priority_first_then_fifo_then_dependencies() {
    let mut s = Store::in_memory().unwrap();
    let (a, _) = s
        .insert_job(&job(0, vec![task("x", &[]), task("y", &["x"])]))
        .unwrap();
    let (b, _) = s.insert_job(&job(5, vec![task("x", &[])])).unwrap();
    let (c, _) = s.insert_job(&job(0, vec![task("x", &[])])).unwrap();
    assert_eq!(
        keys(&s),
        vec![format!("{b}:x"), format!("{a}:x"), format!("{c}:x")]
    );
    let cl = s.claim(&a, "x", "w1").unwrap().unwrap();
    assert_eq!(cl.attempt, 1);
    assert!(!keys(&s).contains(&format!("{a}:y")), "y waits for x");
    let out = s.complete(&a, "x", 1, "{}", 0.5, &[]).unwrap();
    assert_eq!(out, Outcome::Done { job_done: false });
    assert!(keys(&s).contains(&format!("{a}:y")));
}

#[test]
fn stale_reports_are_ignored() {
    let mut s = Store::in_memory().unwrap();
    let (a, _) = s.insert_job(&job(0, vec![task("x", &[])])).unwrap();
    s.claim(&a, "x", "w1").unwrap().unwrap();
    // The coordinator gave up on attempt 1 (worker lost) and re-queued it.
    assert_eq!(
        s.fail(&a, "x", 1, "w1", &err(true), 0.0).unwrap(),
        Outcome::Retry { attempt: 1 }
    );
    let cl = s.claim(&a, "x", "w2").unwrap().unwrap();
    assert_eq!(cl.attempt, 2);
    // The late report of attempt 1 changes nothing.
    assert_eq!(
        s.complete(&a, "x", 1, "{}", 1.0, &[]).unwrap(),
        Outcome::Stale
    );
    assert_eq!(s.tasks(&a).unwrap()[0].state, TaskState::Running);
    assert_eq!(
        s.complete(&a, "x", 2, "{}", 1.0, &[]).unwrap(),
        Outcome::Done { job_done: true }
    );
    assert!(s.finish_job(&a).unwrap());
    assert_eq!(s.job(&a).unwrap().state, JobState::Done);
}

#[test]
fn retries_up_to_the_limit_then_the_job_fails_naming_the_task() {
    let mut s = Store::in_memory().unwrap();
    let (a, _) = s.insert_job(&job(0, vec![task("pos/f0003", &[])])).unwrap();
    for attempt in 1..=2 {
        s.claim(&a, "pos/f0003", "w1").unwrap().unwrap();
        assert_eq!(
            s.fail(&a, "pos/f0003", attempt, "w1", &err(true), 0.0)
                .unwrap(),
            Outcome::Retry { attempt }
        );
    }
    s.claim(&a, "pos/f0003", "w1").unwrap().unwrap();
    match s.fail(&a, "pos/f0003", 3, "w1", &err(true), 0.0).unwrap() {
        Outcome::JobFailed { message } => {
            assert!(
                message.contains("pos/f0003") && message.contains("boom"),
                "{message}"
            )
        }
        o => panic!("{o:?}"),
    }
    assert_eq!(s.job(&a).unwrap().state, JobState::Failed);
    assert_eq!(s.worker_failures(&a, "w1").unwrap(), 3);
}

#[test]
fn non_retryable_failures_fail_at_once_and_hand_backs_do_not_count() {
    let mut s = Store::in_memory().unwrap();
    let (a, _) = s.insert_job(&job(0, vec![task("x", &[])])).unwrap();
    // Hand-backs (drain) and restarts do not use up attempts.
    for attempt in 1..=5 {
        s.claim(&a, "x", "w1").unwrap().unwrap();
        let handed_back = Failure::new(FailureKind::Cancelled, "cancelled");
        assert_eq!(
            s.fail(&a, "x", attempt, "w1", &handed_back, 0.0).unwrap(),
            Outcome::Retry { attempt }
        );
    }
    s.claim(&a, "x", "w1").unwrap().unwrap();
    assert!(matches!(
        s.fail(&a, "x", 6, "w1", &err(false), 0.0).unwrap(),
        Outcome::JobFailed { .. }
    ));
}

#[test]
fn job_failure_limit_counts_over_all_tasks() {
    let mut s = Store::in_memory().unwrap();
    let mut j = job(0, vec![task("a", &[]), task("b", &[])]);
    j.max_failures = 2;
    let (id, _) = s.insert_job(&j).unwrap();
    s.claim(&id, "a", "w1").unwrap().unwrap();
    s.claim(&id, "b", "w1").unwrap().unwrap();
    assert!(matches!(
        s.fail(&id, "a", 1, "w1", &err(true), 0.0).unwrap(),
        Outcome::Retry { .. }
    ));
    match s.fail(&id, "b", 1, "w1", &err(true), 0.0).unwrap() {
        Outcome::JobFailed { message } => assert!(message.contains("limit of 2"), "{message}"),
        o => panic!("{o:?}"),
    }
}

#[test]
fn cancel_drops_queued_tasks_and_closes_running_ones_on_report() {
    let mut s = Store::in_memory().unwrap();
    let (a, _) = s
        .insert_job(&job(0, vec![task("x", &[]), task("y", &[])]))
        .unwrap();
    s.claim(&a, "x", "w1").unwrap().unwrap();
    assert_eq!(s.cancel_job(&a).unwrap(), JobState::Cancelled);
    assert!(s.ready_tasks(10).unwrap().is_empty());
    assert_eq!(s.running_tasks(Some(&a)).unwrap().len(), 1);
    let stopped = Failure::new(FailureKind::Cancelled, "cancelled");
    assert_eq!(
        s.fail(&a, "x", 1, "w1", &stopped, 0.0).unwrap(),
        Outcome::Cancelled
    );
    assert!(s.running_tasks(Some(&a)).unwrap().is_empty());
    assert_eq!(s.cancel_job(&a).unwrap(), JobState::Cancelled);
}

#[test]
fn restart_recovery_keeps_running_attempts_for_adoption_and_keeps_done_ones() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("q.sqlite");
    let a = {
        let mut s = Store::open(&path).unwrap();
        let (a, _) = s
            .insert_job(&job(0, vec![task("x", &[]), task("y", &[])]))
            .unwrap();
        s.claim(&a, "x", "w1").unwrap().unwrap();
        s.complete(&a, "x", 1, "{}", 0.1, &[]).unwrap();
        s.claim(&a, "y", "w1").unwrap().unwrap();
        a
    };
    let mut s = Store::open(&path).unwrap();
    let orphans = s.recover().unwrap();
    assert_eq!(
        orphans,
        vec![(a.clone(), "y".to_string(), 1, "w1".to_string())]
    );
    let tasks = s.tasks(&a).unwrap();
    assert_eq!(tasks[0].state, TaskState::Done);
    assert_eq!(tasks[0].attempts, 1);
    // Still running under attempt 1: its worker (registered again as w2) adopts it and reports it.
    assert_eq!(tasks[1].state, TaskState::Running);
    assert!(s.adopt(&a, "y", 1, "w2").unwrap());
    let (claim, worker, _) = s.current_claim(&a, "y", 1).unwrap().unwrap();
    assert_eq!((claim.attempt, worker.as_str()), (1, "w2"));
    assert_eq!(
        s.complete(&a, "y", 1, "{}", 0.1, &[]).unwrap(),
        Outcome::Done { job_done: true }
    );
    assert!(s.current_claim(&a, "y", 1).unwrap().is_none());
}

#[test]
fn an_attempt_nobody_adopts_is_queued_again_uncharged_and_its_late_report_is_stale() {
    let mut s = Store::in_memory().unwrap();
    let (a, _) = s.insert_job(&job(0, vec![task("y", &[])])).unwrap();
    s.claim(&a, "y", "w1").unwrap().unwrap();
    assert_eq!(s.recover().unwrap().len(), 1);
    let restart = Failure::new(FailureKind::CoordinatorRestart, "nobody reported it");
    assert_eq!(
        s.fail(&a, "y", 1, "w1", &restart, 0.0).unwrap(),
        Outcome::Retry { attempt: 1 }
    );
    let cl = s.claim(&a, "y", "w3").unwrap().unwrap();
    assert_eq!(cl.attempt, 2);
    assert_eq!(s.job(&a).unwrap().failures, 0);
    // Attempt 1 turns up late: attempt 2 belongs to w3 now, so it is not adopted and its result is stale.
    assert!(!s.adopt(&a, "y", 1, "w2").unwrap());
    assert!(s.current_claim(&a, "y", 1).unwrap().is_none());
    assert_eq!(
        s.complete(&a, "y", 1, "{}", 0.1, &[]).unwrap(),
        Outcome::Stale
    );
}

#[test]
fn task_logs_are_kept_per_attempt_and_old_queue_files_gain_the_table() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("old.sqlite");
    {
        // A queue file from before the task_logs table existed.
        let conn = Connection::open(&path).unwrap();
        conn.execute_batch(
            super::schema::BASELINE
                .split("CREATE TABLE IF NOT EXISTS task_logs")
                .next()
                .unwrap(),
        )
        .unwrap();
    }
    let mut s = Store::open(&path).unwrap();
    let (a, _) = s
        .insert_job(&job(0, vec![task("x", &[]), task("y", &["x"])]))
        .unwrap();
    s.claim(&a, "x", "w1").unwrap().unwrap();
    s.append_task_log(&a, "x", 1, &["one".into(), "two".into()])
        .unwrap();
    s.fail(&a, "x", 1, "w1", &err(true), 0.0).unwrap();
    s.claim(&a, "x", "w2").unwrap().unwrap();
    s.append_task_log(&a, "x", 2, &["three".into()]).unwrap();
    let logs = s.task_logs(&a, None).unwrap();
    assert_eq!(logs.len(), 2);
    assert_eq!((logs[0].attempt, logs[0].worker.as_str()), (1, "w1"));
    assert_eq!(logs[0].outcome, "failed");
    assert_eq!(logs[0].error, "boom");
    assert_eq!(logs[0].lines, vec!["one", "two"]);
    assert_eq!((logs[1].attempt, logs[1].outcome.as_str()), (2, "running"));
    assert_eq!(logs[1].lines, vec!["three"]);
    assert!(s.task_logs(&a, Some("y")).unwrap().is_empty());
    assert!(s.has_task(&a, "y").unwrap() && !s.has_task(&a, "z").unwrap());
    let g = s.gauges().unwrap();
    assert_eq!((g.queue_depth, g.tasks_running), (0, 1));
    assert_eq!(g.jobs, vec![("running".to_string(), 1)]);
}

#[test]
fn client_token_makes_submit_idempotent_and_expansion_is_atomic() {
    let mut s = Store::in_memory().unwrap();
    let mut j = job(0, vec![task("merge", &[])]);
    j.client_token = Some("tok".into());
    let (a, created) = s.insert_job(&j).unwrap();
    assert!(created);
    let (b, created) = s.insert_job(&j).unwrap();
    assert_eq!((a.clone(), false), (b, created));
    s.claim(&a, "merge", "w1").unwrap().unwrap();
    let more = vec![task("w/0", &["merge"]), task("fin", &["w/0"])];
    assert_eq!(
        s.complete(&a, "merge", 1, "{}", 0.0, &more).unwrap(),
        Outcome::Done { job_done: false }
    );
    assert_eq!(keys(&s), vec![format!("{a}:w/0")]);
}

/// The committed fixture: a queue file written by the crease of commit 546d6d9 (before schema versions), after
/// one job was submitted to its coordinator. See `coordinator/tests/fixtures/README.md`.
fn old_queue_file(dir: &Path) -> std::path::PathBuf {
    let fixture =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/queue-before-versions.sqlite");
    let copy = dir.join("queue.sqlite");
    std::fs::copy(&fixture, &copy).unwrap();
    copy
}

fn columns(path: &Path, table: &str) -> Vec<String> {
    let conn = Connection::open(path).unwrap();
    let mut stmt = conn
        .prepare(&format!("SELECT name FROM pragma_table_info('{table}')"))
        .unwrap();
    stmt.query_map([], |r| r.get(0))
        .unwrap()
        .collect::<rusqlite::Result<Vec<String>>>()
        .unwrap()
}

fn user_version(path: &Path) -> u32 {
    Connection::open(path)
        .unwrap()
        .pragma_query_value(None, "user_version", |r| r.get(0))
        .unwrap()
}

#[test]
fn a_queue_file_from_before_schema_versions_is_migrated_and_keeps_its_jobs() {
    let dir = tempfile::tempdir().unwrap();
    let path = old_queue_file(dir.path());
    assert_eq!(user_version(&path), 0, "the fixture predates versions");
    assert!(!columns(&path, "jobs").contains(&"spec_hash".to_string()));

    let mut s = Store::open(&path).unwrap();
    assert_eq!(user_version(&path), SCHEMA_VERSION);
    assert!(columns(&path, "jobs").contains(&"spec_hash".to_string()));
    let jobs = s.list_jobs().unwrap();
    assert_eq!(jobs.len(), 1, "{jobs:?}");
    let job = &jobs[0];
    assert_eq!(
        (job.id.as_str(), job.name.as_str()),
        ("job-00001", "fixture")
    );
    let tasks = s.tasks(&job.id).unwrap();
    assert!(tasks.len() >= 2, "{tasks:?}");
    assert!(s
        .ready_tasks(100)
        .unwrap()
        .iter()
        .any(|t| t.job_id == job.id));
    // The old file keeps working: a new job goes in beside the old one, with the new column filled.
    let (b, created) = s.insert_job(&job_with_token("t", "{\"a\":1}")).unwrap();
    assert!(created && b == "job-00002", "{b}");
    drop(s);
    // Opening it again applies nothing twice.
    let s = Store::open(&path).unwrap();
    assert_eq!(s.list_jobs().unwrap().len(), 2);
    assert_eq!(user_version(&path), SCHEMA_VERSION);
}

#[test]
fn a_queue_file_from_a_newer_crease_is_refused_naming_the_file_and_versions() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("future.sqlite");
    Connection::open(&path)
        .unwrap()
        .pragma_update(None, "user_version", 99)
        .unwrap();
    let e = Store::open(&path).err().expect("refused").to_string();
    assert!(
        e.contains(&path.display().to_string())
            && e.contains("99")
            && e.contains(&SCHEMA_VERSION.to_string()),
        "{e}"
    );
}

fn job_with_token(token: &str, spec_json: &str) -> NewJob {
    NewJob {
        client_token: Some(token.into()),
        spec_json: spec_json.into(),
        ..job(0, vec![task("x", &[])])
    }
}

#[test]
fn the_retry_policy_follows_the_failure_kind_not_the_message() {
    let mut s = Store::in_memory().unwrap();
    // A message that reads like a transient error does not make a full output volume retryable ...
    let (a, _) = s.insert_job(&job(0, vec![task("x", &[])])).unwrap();
    s.claim(&a, "x", "w1").unwrap().unwrap();
    let full = Failure::new(
        FailureKind::StorageFullRemote,
        "retryable? timed out, cancelled",
    );
    match s.fail(&a, "x", 1, "w1", &full, 0.0).unwrap() {
        Outcome::JobFailed { message } => {
            assert!(message.contains("storage-full-remote"), "{message}")
        }
        o => panic!("{o:?}"),
    }
    // ... and one that reads like a fatal one does not stop a full worker cache from moving elsewhere.
    let (b, _) = s.insert_job(&job(0, vec![task("x", &[])])).unwrap();
    s.claim(&b, "x", "w1").unwrap().unwrap();
    let local = Failure::new(FailureKind::StorageFullLocal, "not retryable: bad data");
    assert_eq!(
        s.fail(&b, "x", 1, "w1", &local, 0.0).unwrap(),
        Outcome::Retry { attempt: 1 }
    );
    assert_eq!(
        s.worker_failures(&b, "w1").unwrap(),
        1,
        "a full cache counts"
    );
    // A worker that did not take the task, and a coordinator restart, are not charged to anyone.
    for (attempt, kind) in [
        (2, FailureKind::HandedBack),
        (3, FailureKind::CoordinatorRestart),
    ] {
        s.claim(&b, "x", "w2").unwrap().unwrap();
        let f = Failure::new(kind, "the worker was busy");
        assert_eq!(
            s.fail(&b, "x", attempt, "w2", &f, 0.0).unwrap(),
            Outcome::Retry { attempt }
        );
    }
    assert_eq!(s.worker_failures(&b, "w2").unwrap(), 0);
    assert_eq!(s.job(&b).unwrap().failures, 1);
    // Each closed attempt keeps its kind (`crease logs`).
    let kinds: Vec<(String, String)> = s
        .task_logs(&b, None)
        .unwrap()
        .into_iter()
        .map(|l| (l.outcome, l.kind))
        .collect();
    let pair = |o: &str, k: &str| (o.to_string(), k.to_string());
    assert_eq!(
        kinds,
        vec![
            pair("failed", "storage-full-local"),
            pair("handed-back", "handed-back"),
            pair("coordinator-restart", "coordinator-restart"),
        ]
    );
}

#[test]
fn a_reused_token_with_another_spec_and_a_busy_output_are_refused_naming_the_job() {
    let mut s = Store::in_memory().unwrap();
    let (a, _) = s.insert_job(&job_with_token("tok", "{\"x\":1}")).unwrap();
    // The same spec again: the same job.
    let (again, created) = s.insert_job(&job_with_token("tok", "{\"x\":1}")).unwrap();
    assert_eq!((again.as_str(), created), (a.as_str(), false));
    // Another spec under the token: refused, naming the job.
    let e = s
        .insert_job(&job_with_token("tok", "{\"x\":2}"))
        .unwrap_err()
        .to_string();
    assert!(e.contains(&a) && e.contains("`tok`"), "{e}");
    // Another job writing to the live job's output (with a trailing slash): refused, naming it.
    let output = s.job(&a).unwrap().output;
    let busy = NewJob {
        output: format!("{output}/"),
        ..job(0, vec![task("x", &[])])
    };
    let e = s.insert_job(&busy).unwrap_err().to_string();
    assert!(e.contains(&a) && e.contains(&output), "{e}");
    // Once that job has ended, its output is free again.
    s.cancel_job(&a).unwrap();
    s.insert_job(&busy).unwrap();
}

#[test]
fn the_blocklist_names_each_excluded_worker_with_its_failures_and_can_be_cleared() {
    let mut s = Store::in_memory().unwrap();
    let (a, _) = s
        .insert_job(&job(0, vec![task("x", &[]), task("y", &[])]))
        .unwrap();
    let boom = |why: &str| Failure::new(FailureKind::Transient, why);
    // w1 fails twice (x, then y), w2 once, and a hand-back by w2 is not held against it.
    s.claim(&a, "x", "w1").unwrap().unwrap();
    s.fail(&a, "x", 1, "w1", &boom("disk hiccup"), 0.0).unwrap();
    s.claim(&a, "y", "w1").unwrap().unwrap();
    s.fail(&a, "y", 1, "w1", &boom("frame 3 unreadable"), 0.0)
        .unwrap();
    s.claim(&a, "x", "w2").unwrap().unwrap();
    s.fail(&a, "x", 2, "w2", &boom("flaky"), 0.0).unwrap();
    s.claim(&a, "y", "w2").unwrap().unwrap();
    let back = Failure::new(FailureKind::HandedBack, "at capacity");
    s.fail(&a, "y", 2, "w2", &back, 0.0).unwrap();

    let b = s.blocklist(&a, 2).unwrap();
    assert_eq!(b.len(), 1, "{b:?}");
    assert_eq!((b[0].worker.as_str(), b[0].failures), ("w1", 2));
    assert_eq!(b[0].reasons.len(), 2, "{b:?}");
    assert!(
        b[0].reasons
            .iter()
            .any(|r| r.contains("task `y` attempt 1 (transient): frame 3 unreadable")),
        "{b:?}"
    );
    assert_eq!(s.blocklist(&a, 1).unwrap().len(), 2);
    assert_eq!(s.blocklist_sizes(2).unwrap(), vec![(a.clone(), 1)]);

    assert_eq!(s.unblock(&a, Some("w9")).unwrap(), Vec::<String>::new());
    assert_eq!(s.unblock(&a, Some("w1")).unwrap(), vec!["w1"]);
    assert!(s.blocklist(&a, 2).unwrap().is_empty());
    assert_eq!(
        s.worker_failures(&a, "w1").unwrap(),
        0,
        "w1 gets the job's tasks again"
    );
    assert_eq!(s.unblock(&a, None).unwrap(), vec!["w2"]);
    assert!(s.blocklist(&a, 1).unwrap().is_empty());
}

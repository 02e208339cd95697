//! Progress a user can see: every fold detection task (step chunks, the phase pass over the whole sequence,
//! tracing chunks) reports its frames (not a task bar standing at 0/N), and `crease status` shows a running
//! task's worker and its latest progress.

use crease_e2e::*;
use std::process::Command;
use std::time::{Duration, Instant};

fn demo(dir: &std::path::Path, triangles: &str, frames: &str) -> String {
    let root = dir.join("demo");
    let o = Command::new(bin())
        .args(["demo", "--out", root.to_str().unwrap()])
        .args(["--triangles", triangles, "--frames", frames])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    root.join("input").display().to_string()
}

#[test]
fn fold_detection_reports_its_frames() {
    let dir = tempfile::tempdir().unwrap();
    let input = demo(dir.path(), "2000", "6");
    let out = dir.path().join("out");
    // stderr is a file here, so progress comes as plain log lines.
    let o = Command::new(bin())
        .args(["run", "--input", &input, "--folds", "stretch"])
        .args(["--out", out.to_str().unwrap(), "--preview-size", "64"])
        .output()
        .unwrap();
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    // The step records of the six frames in two chunks of half the sequence each.
    for first in ["f000000", "f000003"] {
        assert!(
            err.contains(&format!("[folds/steps/{first}] started: 3 steps")),
            "{err}"
        );
        assert!(err.contains(&format!("[folds/steps/{first}] 3/3")), "{err}");
    }
    // The phase task: two passes over the six frames, five frame steps each.
    assert!(err.contains("[folds/phases] started: 10 steps"), "{err}");
    assert!(err.contains("[folds/phases] 10/10"), "{err}");
    // Tracing in chunks of half the sequence; without the seed memory (the default) a frame's folds are its
    // own, so the second chunk traces just its three frames, with no warm-up.
    assert!(err.contains("[folds/f000000] started: 3 steps"), "{err}");
    assert!(err.contains("[folds/f000003] started: 3 steps"), "{err}");
    assert!(err.contains("[folds/f000003] 3/3"), "{err}");
    assert!(err.contains("[folds/f000003] done"), "{err}");
}

#[test]
fn status_shows_the_running_task_its_worker_and_progress() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let input = demo(d, "30000", "16");
    let c = Coordinator::start(d, &[]);
    let _w = c.worker("w-progress", &[]);
    let job = d.join("job.toml");
    std::fs::write(
        &job,
        format!(
            "input = \"{input}\"\noutput = \"{}\"\n[folds]\nkind = \"stretch\"\n[preview]\nsize = 64\n",
            d.join("out").display()
        ),
    )
    .unwrap();
    let id = c.submit(&job);
    let start = Instant::now();
    let seen = loop {
        let s = c.status(&id);
        let running = s["running"].as_array().cloned().unwrap_or_default();
        if let Some(r) = running
            .iter()
            .find(|r| r["total"].as_u64().unwrap_or(0) > 0)
        {
            break r.clone();
        }
        assert!(
            s["state"] != "done" && start.elapsed() < DEADLINE,
            "never saw a running task's progress: {s}"
        );
        std::thread::sleep(Duration::from_millis(30));
    };
    // Detection runs first, so the first task seen with progress is one of its tasks.
    let key = seen["key"].as_str().unwrap_or("").to_string();
    assert!(key.starts_with("folds/"), "{seen}");
    let worker = seen["worker"].as_str().unwrap_or("").to_string();
    assert!(!worker.is_empty(), "no worker named: {seen}");
    let total = seen["total"].as_u64().unwrap_or(0);
    match key.as_str() {
        "folds/phases" => assert_eq!(total, 30, "two passes over 16 frames: {seen}"),
        k if k.starts_with("folds/steps/f") || k.starts_with("folds/f") => {
            assert!((1..=16).contains(&total), "a frame chunk's frames: {seen}")
        }
        k => panic!("{k} is not a fold detection task: {seen}"),
    }
    // The plain-text status names a running task and its worker as the JSON status does. Tasks come and go
    // between the two reads, so it is read again until both show the same task (the job runs for seconds).
    let start = Instant::now();
    loop {
        let state = c.status(&id);
        let o = c.cli(&["status", &id]);
        let text = String::from_utf8_lossy(&o.stdout).into_owned();
        let running = state["running"].as_array().cloned().unwrap_or_default();
        let named = running.iter().any(|r| {
            let (k, w) = (
                r["key"].as_str().unwrap_or(""),
                r["worker"].as_str().unwrap_or(""),
            );
            !k.is_empty() && !w.is_empty() && text.contains(&format!("running {k} on {w}"))
        });
        if named {
            break;
        }
        assert!(
            state["state"] != "done" && start.elapsed() < DEADLINE,
            "the status text never named a running task and its worker: {text}"
        );
        std::thread::sleep(Duration::from_millis(30));
    }
    c.wait_state(&id, &["done"]);
}

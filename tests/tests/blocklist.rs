//! The per-job worker blocklist (`--blacklist-after`) seen from outside, with real processes: `crease status`
//! (text and JSON) names the excluded worker and the failures that put it there, the coordinator's metrics
//! count it per job, and `crease unblock` clears it.

use crease_e2e::*;

#[test]
fn status_and_metrics_show_a_blocklisted_worker_with_its_failures_and_unblock_clears_it() {
    let (dir, anchors) = setup();
    let d = dir.path();
    // Positioned frames cannot be stored (a plain file blocks their directory): every position attempt fails
    // with an I/O error, a retryable failure charged to the worker that ran it.
    std::fs::create_dir_all(d.join("out/.crease-work")).unwrap();
    std::fs::write(d.join("out/.crease-work/positions"), b"not a directory").unwrap();
    let extra = [
        "--metrics-listen",
        "127.0.0.1:0",
        // Two failures are needed to blocklist again: far longer apart than `unblock` then `status` take.
        "--retry-backoff-ms",
        "300",
        "--blacklist-after",
        "2",
    ];
    let clog = d.join("coordinator.log");
    let c = Coordinator::start_logged(d, &extra, &clog, "http", &[], &[]);
    let maddr = metrics_addr(&clog);
    // The only worker: blocklisted, it still gets the job's tasks (no other worker could), so the job lives on.
    let _w = c.worker("flaky", &[]);
    let limits = "max_task_attempts = 40\nmax_task_failures_per_job = 40";
    let job = job_file(
        d,
        "blocked",
        &fixture(),
        &anchors,
        &d.join("out"),
        "fused",
        limits,
    );
    let id = c.submit(&job);

    let mut s = serde_json::Value::Null;
    wait_until("the worker to be blocklisted", || {
        s = c.status(&id);
        s["blocked_workers"]
            .as_array()
            .is_some_and(|b| !b.is_empty())
    });
    let b = &s["blocked_workers"][0];
    let worker = b["worker"].as_str().unwrap().to_string();
    assert!(worker.starts_with('w'), "{s}");
    assert!(b["failures"].as_u64().unwrap() >= 2, "{s}");
    let reasons = b["reasons"].as_array().unwrap();
    assert!(!reasons.is_empty(), "{s}");
    assert!(
        reasons
            .iter()
            .all(|r| r.as_str().unwrap().contains("task `position")),
        "{s}"
    );
    // The text status says it too, with the command that clears it.
    let o = c.cli(&["status", &id]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains(&format!("blocklisted: worker {worker}"))
            && text.contains(&format!("crease unblock {id} --worker {worker}")),
        "{text}"
    );
    // The metric counts it for this job.
    let (code, m) = get(&maddr, "/metrics");
    assert_eq!(code, 200);
    let series = format!("crease_job_blocklisted_workers{{job=\"{id}\"}} 1");
    assert!(m.lines().any(|l| l == series), "no `{series}` in\n{m}");

    // An operator clears it.
    let o = c.cli(&["unblock", &id, "--worker", &worker]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        String::from_utf8_lossy(&o.stdout).trim(),
        format!("{id}: cleared {worker}")
    );
    let after = c.status(&id);
    let still: Vec<_> = after["blocked_workers"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|b| b["worker"] == worker.as_str())
        .cloned()
        .collect();
    assert!(still.is_empty(), "{after}");
    // Unknown jobs are named.
    let o = c.cli(&["unblock", "job-99999"]);
    assert!(!o.status.success() && stderr(&o).contains("job-99999"));
    let o = c.cli(&["cancel", &id]);
    assert!(o.status.success(), "{}", stderr(&o));
}

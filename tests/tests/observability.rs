//! Observability with real processes on 127.0.0.1: Prometheus metrics and health probes on the coordinator
//! and the worker (scraped with a plain HTTP/1.1 GET), JSON logs carrying job and task ids, and the per-task
//! log tail through `crease logs`.

use crease_e2e::*;
use std::collections::BTreeMap;
use std::path::Path;
use std::process::{Command, Stdio};

/// One sample: metric name and labels.
type Sample = (String, BTreeMap<String, String>);

/// Parses the text exposition format into samples.
fn parse_metrics(text: &str) -> Vec<(Sample, f64)> {
    let mut out = Vec::new();
    for line in text.lines() {
        if line.starts_with('#') || line.trim().is_empty() {
            continue;
        }
        let (series, value) = line.rsplit_once(' ').expect("sample line");
        let value: f64 = value.parse().unwrap_or_else(|_| panic!("value in {line}"));
        let (name, labels) = match series.split_once('{') {
            Some((n, rest)) => (n, rest.trim_end_matches('}')),
            None => (series, ""),
        };
        let mut map = BTreeMap::new();
        for pair in labels.split(',').filter(|p| !p.is_empty()) {
            let (k, v) = pair.split_once('=').expect("label");
            map.insert(k.to_string(), v.trim_matches('"').to_string());
        }
        out.push(((name.to_string(), map), value));
    }
    out
}

/// The value of `name` with exactly `labels` (0 when absent).
fn value(samples: &[(Sample, f64)], name: &str, labels: &[(&str, &str)]) -> f64 {
    let want: BTreeMap<String, String> = labels
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    samples
        .iter()
        .find(|((n, l), _)| n == name && *l == want)
        .map_or(0.0, |(_, v)| *v)
}

/// Sum of `name` over every label set.
fn sum(samples: &[(Sample, f64)], name: &str) -> f64 {
    samples
        .iter()
        .filter(|((n, _), _)| n == name)
        .map(|(_, v)| v)
        .sum()
}

fn json_lines(log: &Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(log)
        .unwrap()
        .lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("not JSON ({e}): {l}")))
        .collect()
}

fn kinds(status: &serde_json::Value) -> BTreeMap<String, usize> {
    let mut m = BTreeMap::new();
    for t in tasks(status) {
        *m.entry(t["kind"].as_str().unwrap().to_string())
            .or_default() += 1;
    }
    m
}

#[test]
fn metrics_json_logs_and_task_log_tails_after_a_job_and_a_failing_task() {
    let (dir, anchors) = setup();
    let d = dir.path();
    // Positioned frames cannot be stored (a plain file blocks their directory): the second job's position
    // tasks fail with an I/O error on every attempt.
    std::fs::create_dir_all(d.join("broken/.crease-work")).unwrap();
    std::fs::write(d.join("broken/.crease-work/positions"), b"not a directory").unwrap();
    let obs = ["--metrics-listen", "127.0.0.1:0", "--log-format", "json"];
    let mut extra = vec!["--retry-backoff-ms", "50"];
    extra.extend(obs);
    let clog = d.join("coordinator.log");
    let mut c = Coordinator::start_logged(d, &extra, &clog, "http", &[], &[]);
    let caddr = metrics_addr(&clog);
    assert_eq!(get(&caddr, "/healthz").0, 200);
    assert_eq!(get(&caddr, "/readyz").0, 200);
    c.worker_args = obs.iter().map(|s| s.to_string()).collect();
    let _w = c.worker("obs", &[]);
    let wlog = d.join("worker-obs.log");
    let waddr = metrics_addr(&wlog);
    assert_eq!(get(&waddr, "/healthz").0, 200);
    wait_until("the worker to be ready", || get(&waddr, "/readyz").0 == 200);

    let job = job_file(d, "obs", &fixture(), &anchors, &d.join("out"), "fused", "");
    let id = c.submit(&job);
    let s = c.wait_state(&id, &["done", "failed"]);
    assert_eq!(s["state"], "done", "{s}");
    let per_kind = kinds(&s);
    let total: usize = per_kind.values().sum();
    assert!(per_kind.len() >= 3, "{per_kind:?}");

    // Coordinator metrics, read after the job is done.
    let (code, text) = get(&caddr, "/metrics");
    assert_eq!(code, 200);
    let m = parse_metrics(&text);
    for (kind, n) in &per_kind {
        assert_eq!(
            value(&m, "crease_task_duration_seconds_count", &[("kind", kind)]),
            *n as f64,
            "{kind}\n{text}"
        );
    }
    assert_eq!(
        value(&m, "crease_workers", &[("state", "live")]),
        1.0,
        "{text}"
    );
    assert_eq!(
        value(&m, "crease_workers", &[("state", "draining")]),
        0.0,
        "{text}"
    );
    assert_eq!(value(&m, "crease_queue_depth", &[]), 0.0, "{text}");
    assert_eq!(value(&m, "crease_tasks_running", &[]), 0.0, "{text}");
    assert_eq!(
        value(&m, "crease_jobs", &[("state", "done")]),
        1.0,
        "{text}"
    );
    assert_eq!(value(&m, "crease_task_retries_total", &[]), 0.0, "{text}");
    assert_eq!(value(&m, "crease_task_failures_total", &[]), 0.0, "{text}");

    // Worker metrics: every task of the job ran there.
    let (code, text) = get(&waddr, "/metrics");
    assert_eq!(code, 200);
    let wm = parse_metrics(&text);
    assert_eq!(
        sum(&wm, "crease_worker_tasks_total"),
        total as f64,
        "{text}"
    );
    for (kind, n) in &per_kind {
        assert_eq!(
            value(
                &wm,
                "crease_worker_tasks_total",
                &[("kind", kind), ("outcome", "done")]
            ),
            *n as f64,
            "{kind}\n{text}"
        );
        assert_eq!(
            value(
                &wm,
                "crease_worker_task_duration_seconds_count",
                &[("kind", kind)]
            ),
            *n as f64,
            "{kind}\n{text}"
        );
    }
    assert_eq!(
        value(&wm, "crease_worker_tasks_running", &[]),
        0.0,
        "{text}"
    );
    assert_eq!(value(&wm, "crease_worker_capacity", &[]), 1.0, "{text}");

    // JSON logs: every line parses; every line about a task names the job and the task.
    for log in [&clog, &wlog] {
        let lines = json_lines(log);
        assert!(!lines.is_empty());
        let about_tasks: Vec<_> = lines
            .iter()
            .filter(|l| {
                let msg = l["message"].as_str().unwrap_or("");
                msg.starts_with("task ") || msg.starts_with("dispatched")
            })
            .collect();
        assert!(about_tasks.len() >= total, "{}", log.display());
        for l in about_tasks {
            assert_eq!(l["job_id"], id.as_str(), "{l}");
            assert!(l["task"].as_str().is_some_and(|t| !t.is_empty()), "{l}");
        }
    }
    let started = json_lines(&wlog)
        .iter()
        .filter(|l| l["message"] == "task started")
        .count();
    assert_eq!(started, total);

    // `crease logs JOB`: a block per task, each with the coordinator's and the worker's lines.
    let o = c.cli(&["logs", &id]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8(o.stdout).unwrap();
    for t in tasks(&s) {
        let key = t["key"].as_str().unwrap();
        let header = format!("== task `{key}` attempt 1 on w1: done");
        let block = out
            .split_once(&header)
            .unwrap_or_else(|| panic!("no {header} in\n{out}"))
            .1;
        let block = block.split("\n==").next().unwrap();
        assert!(block.contains("dispatched to worker w1"), "{key}: {block}");
        assert!(block.contains("INFO  task started"), "{key}: {block}");
        assert!(block.contains("done in"), "{key}: {block}");
    }
    let key = tasks(&s)[0]["key"].as_str().unwrap().to_string();
    let o = c.cli(&["logs", &id, &key]);
    assert!(o.status.success(), "{}", stderr(&o));
    let one = String::from_utf8(o.stdout).unwrap();
    assert_eq!(one.matches("== task `").count(), 1, "{one}");
    assert!(one.contains(&format!("== task `{key}` attempt 1")), "{one}");
    let o = c.cli(&["logs", &id, "no/such-task"]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("no task `no/such-task`"),
        "{}",
        stderr(&o)
    );
    let o = c.cli(&["logs", "job-99999"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("job-99999"), "{}", stderr(&o));

    // A task that always fails: its log shows each attempt's error, from the worker's tail too.
    let job = job_file(
        d,
        "broken",
        &fixture(),
        &anchors,
        &d.join("broken"),
        "fused",
        "max_task_attempts = 2",
    );
    let id2 = c.submit(&job);
    let s2 = c.wait_state(&id2, &["failed", "done"]);
    assert_eq!(s2["state"], "failed", "{s2}");
    let failed = tasks(&s2)
        .into_iter()
        .find(|t| t["state"] == "failed")
        .unwrap();
    let key = failed["key"].as_str().unwrap();
    let o = c.cli(&["logs", &id2, key]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8(o.stdout).unwrap();
    for attempt in 1..=2 {
        assert!(
            out.contains(&format!("== task `{key}` attempt {attempt} on w1: failed")),
            "{out}"
        );
    }
    assert!(
        out.lines().any(|l| l.contains("w1: ")
            && l.contains("WARN")
            && l.contains(".crease-work/positions")),
        "the worker's tail has no error line:\n{out}"
    );
    let m = parse_metrics(&get(&caddr, "/metrics").1);
    assert!(value(&m, "crease_task_failures_total", &[]) >= 2.0);
    assert!(value(&m, "crease_task_retries_total", &[]) >= 1.0);
    assert_eq!(value(&m, "crease_jobs", &[("state", "failed")]), 1.0);
    let wm = parse_metrics(&get(&waddr, "/metrics").1);
    assert!(
        value(
            &wm,
            "crease_worker_tasks_total",
            &[
                ("kind", failed["kind"].as_str().unwrap()),
                ("outcome", "failed")
            ]
        ) >= 2.0
    );
    if let Some(p) = c.proc.as_mut() {
        p.kill();
    }
}

#[test]
fn a_worker_is_ready_only_while_registered_and_not_draining() {
    let (dir, anchors) = setup();
    let d = dir.path();
    // The worker starts before its coordinator exists: alive, but not ready.
    let port = free_port();
    let wlog = d.join("worker.log");
    let mut w = Proc(
        Command::new(bin())
            .args([
                "worker",
                "--coordinator",
                &format!("http://127.0.0.1:{port}"),
            ])
            .args(["--name", "early", "--threads", "1", "--drain-secs", "3"])
            .args(["--metrics-listen", "127.0.0.1:0"])
            .env("CREASE_TEST_TASK_DELAY", "*=60000")
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&wlog).unwrap())
            .spawn()
            .unwrap(),
    );
    let waddr = metrics_addr(&wlog);
    assert_eq!(get(&waddr, "/healthz").0, 200);
    assert_eq!(get(&waddr, "/readyz").0, 503);
    let c =
        Coordinator::start_logged_on(port, d, &[], &d.join("coordinator.log"), "http", &[], &[]);
    wait_until("the worker to register and be ready", || {
        get(&waddr, "/readyz").0 == 200
    });
    assert!(std::fs::read_to_string(&wlog)
        .unwrap()
        .contains("registered as"));
    // With a task in flight, SIGTERM starts a drain: the worker stays alive but is not ready.
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
    wait_until("a task to run", || {
        tasks(&c.status(&id))
            .iter()
            .any(|t| t["state"] == "running")
    });
    assert!(Command::new("kill")
        .args(["-TERM", &w.pid().to_string()])
        .status()
        .unwrap()
        .success());
    wait_until("the draining worker to report not ready", || {
        get(&waddr, "/readyz").0 == 503
    });
    assert_eq!(get(&waddr, "/healthz").0, 200);
    w.kill();
}

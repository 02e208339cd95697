//! The soak test, for real: `crease-soak --secure` (this crate's harness, driving the `crease` under test) runs 50 small jobs from concurrent clients on a
//! loopback cluster of worker processes that are SIGKILLed and restarted at random, in the production
//! configuration (TLS on every connection, client tokens in rotation, a worker token), and must report every job
//! done with the bytes of a single-node run and a coordinator whose metrics agree. The test reads the harness's
//! JSON, then checks outputs itself: it runs its own `crease run` for every input and compares the harness's
//! references and several jobs' outputs with it.

use crease_e2e::*;
use std::collections::BTreeSet;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The harness has its own deadline (`--deadline-secs`); this one only catches a harness that hangs.
const SOAK_DEADLINE: Duration = Duration::from_secs(400);

#[test]
fn fifty_jobs_from_concurrent_clients_survive_random_worker_kills_over_tls_with_single_node_bytes()
{
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let keep = d.join("soak");
    let json = d.join("soak.json");
    let (out_log, err_log) = (d.join("stdout.txt"), d.join("stderr.txt"));
    let started = Instant::now();
    let mut p = Proc(
        Command::new(env!("CARGO_BIN_EXE_crease-soak"))
            .arg("--crease")
            .arg(bin())
            .args(["--secure", "--jobs", "50", "--clients", "4"])
            .args(["--workers", "3", "--kills", "6", "--kill-window-secs", "10"])
            .args(["--seed", "11", "--deadline-secs", "300"])
            .arg("--keep")
            .arg(&keep)
            .arg("--json")
            .arg(&json)
            .stdout(std::fs::File::create(&out_log).unwrap())
            .stderr(std::fs::File::create(&err_log).unwrap())
            .stdin(Stdio::null())
            .spawn()
            .unwrap(),
    );
    let status = loop {
        if let Some(s) = p.0.try_wait().unwrap() {
            break s;
        }
        assert!(
            started.elapsed() < SOAK_DEADLINE,
            "the soak did not end within {SOAK_DEADLINE:?}"
        );
        std::thread::sleep(Duration::from_millis(100));
    };
    let table = std::fs::read_to_string(&out_log).unwrap();
    let log = std::fs::read_to_string(&err_log).unwrap();
    println!("{table}\nsoak took {:.1}s", started.elapsed().as_secs_f64());
    assert!(status.success(), "soak failed ({status}):\n{table}\n{log}");

    let s: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(s["jobs"], 50, "{s}");
    assert_eq!(s["done"], 50, "{table}");
    assert_eq!(s["failed"], 0, "{table}");
    assert_eq!(s["unfinished"], 0, "{table}");
    assert_eq!(s["mismatched"], 0, "{table}");
    assert_eq!(s["secure"], true, "{s}");
    // The coordinator's own count, scraped from /metrics after the last job ended.
    let m = &s["metrics"];
    assert_eq!(m["jobs_done"], 50, "{table}");
    assert_eq!(m["jobs_done_matches"], true, "{table}");
    assert_eq!(m["queue_depth"], 0, "{table}");
    assert_eq!(m["tasks_running"], 0, "{table}");
    assert!(m["task_retries_total"].is_u64(), "{m}");
    assert!(m["task_failures_total"].is_u64(), "{m}");
    // Really secured: https everywhere, the workers registered over it, and no token in any log.
    let logs = keep.join("logs");
    let coordinator_log = std::fs::read_to_string(logs.join("coordinator.log")).unwrap();
    assert!(
        coordinator_log.contains("at https://127.0.0.1:"),
        "workers did not register with https URLs:\n{coordinator_log}"
    );
    let mut secrets = Vec::new();
    for f in ["client-tokens", "worker-token"] {
        let text = std::fs::read_to_string(keep.join("secrets").join(f)).unwrap();
        secrets.extend(
            text.lines()
                .map(str::trim)
                .filter(|l| !l.is_empty() && !l.starts_with('#'))
                .map(String::from),
        );
    }
    assert_eq!(secrets.len(), 3, "two user tokens and a worker token");
    let mut texts = vec![table.clone(), log.clone()];
    for e in std::fs::read_dir(&logs).unwrap() {
        texts.push(std::fs::read_to_string(e.unwrap().path()).unwrap());
    }
    for t in &texts {
        for secret in &secrets {
            assert!(!t.contains(secret.as_str()), "a token was printed");
        }
    }
    let kills = s["kills"].as_u64().unwrap();
    assert!((1..=6).contains(&kills), "kills: {kills}\n{log}");
    assert_eq!(s["kill_log"].as_array().unwrap().len() as u64, kills);
    // A SIGKILLed worker loses the task it was running, and that task must run again. All 50 jobs are queued
    // within the first seconds of the kill window, so the workers are busy when the kills land: kills without
    // a single retry would mean the kills (or the retry accounting) did nothing.
    let retried = s["tasks_retried"].as_u64().unwrap();
    assert!(
        retried >= 1,
        "{kills} kills but no task attempt retried\n{table}"
    );
    assert!(
        m["task_retries_total"].as_u64().unwrap() >= 1,
        "{kills} kills but the coordinator counted no retry: {m}"
    );
    println!(
        "jobs/min {:.1}, latency p50 {:.2}s p95 {:.2}s, {kills} kills, {} task attempts retried",
        s["jobs_per_minute"].as_f64().unwrap(),
        s["latency_seconds"]["p50"].as_f64().unwrap(),
        s["latency_seconds"]["p95"].as_f64().unwrap(),
        s["tasks_retried"]
    );

    let jobs = s["job_results"].as_array().unwrap();
    assert_eq!(jobs.len(), 50);
    // Every submission made a new job, and the clients really were several.
    let ids: BTreeSet<&str> = jobs.iter().map(|j| j["id"].as_str().unwrap()).collect();
    assert_eq!(ids.len(), 50, "{ids:?}");
    let clients: BTreeSet<u64> = jobs.iter().map(|j| j["client"].as_u64().unwrap()).collect();
    assert_eq!(clients.len(), 4);
    for j in jobs {
        assert_eq!(j["state"], "done", "{j}");
        assert_eq!(j["identical"], true, "{j}");
    }

    // Independent check: our own single-node run of each input, against the harness's reference, one job of
    // each positioning partition, and every job that had a task retried (a kill landed on it).
    let cases = s["cases"].as_array().unwrap();
    assert!(cases.len() >= 3, "{s}");
    let modes: BTreeSet<&str> = cases.iter().map(|c| c["mode"].as_str().unwrap()).collect();
    assert_eq!(modes.len(), 2, "both weight modes: {modes:?}");
    for c in cases {
        let name = c["name"].as_str().unwrap();
        let mine = d.join(format!("mine-{name}"));
        let args: Vec<&str> = c["run_args"]
            .as_array()
            .unwrap()
            .iter()
            .map(|a| a.as_str().unwrap())
            .collect();
        let o = Command::new(bin())
            .args(["run", "--quiet", "--input", c["input"].as_str().unwrap()])
            .args(["--anchors", c["anchors_file"].as_str().unwrap()])
            .arg("--out")
            .arg(&mine)
            .args(&args)
            .output()
            .unwrap();
        assert!(o.status.success(), "crease run {name}: {}", stderr(&o));
        assert_complete_and_identical(&mine, Path::new(c["reference"].as_str().unwrap()));
        let mut chunks = BTreeSet::new();
        for j in jobs.iter().filter(|j| j["case"] == name) {
            let new_partition = chunks.insert(j["partition"]["frames_per_chunk"].as_u64().unwrap());
            if new_partition || j["tasks_retried"].as_u64().unwrap() > 0 {
                assert_complete_and_identical(&mine, Path::new(j["output"].as_str().unwrap()));
            }
        }
        assert!(chunks.len() >= 2, "{name}: one partition only");
    }
}

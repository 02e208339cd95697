//! What the cluster benchmarks share: running one job spec on a fresh in-process cluster (coordinator and
//! gRPC workers on 127.0.0.1, as `crease run` does), in a scratch directory of its own.

use crate::local::LocalCluster;
use anyhow::{bail, Context, Result};
use crease_coordinator::JobClient;
use crease_proto as pb;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// A finished benchmark job: its status (with task rows) and wall time from submit to done.
pub struct JobRun {
    pub status: pb::JobStatus,
    pub wall: f64,
}

impl JobRun {
    /// (tasks, summed work seconds) per task kind.
    pub fn work_by_kind(&self) -> BTreeMap<String, (usize, f64)> {
        let mut out: BTreeMap<String, (usize, f64)> = BTreeMap::new();
        for t in &self.status.tasks {
            let e = out.entry(t.kind.clone()).or_default();
            e.0 += 1;
            e.1 += t.work_seconds;
        }
        out
    }
}

/// Runs `spec` (JSON) on a fresh local cluster of `workers` workers × `capacity` slots; fails unless it ends
/// done.
pub fn run_job(
    rt: &tokio::runtime::Runtime,
    spec: &serde_json::Value,
    workers: usize,
    capacity: u32,
    cache: PathBuf,
) -> Result<JobRun> {
    let (status, wall) = rt.block_on(async {
        let cluster = LocalCluster::start(workers, capacity, cache).await?;
        let result = async {
            let t0 = Instant::now();
            let (id, _) = cluster.client.submit(spec.to_string(), "json").await?;
            crate::watch::follow(&cluster.client, &id, None).await?;
            let wall = t0.elapsed().as_secs_f64();
            let s = cluster.client.status(&id, true).await?;
            anyhow::Ok((s, wall))
        }
        .await;
        cluster.stop().await;
        result
    })?;
    if status.state != "done" {
        bail!(
            "benchmark job `{}` ended {}: {}",
            spec["name"].as_str().unwrap_or("?"),
            status.state,
            status.message
        );
    }
    Ok(JobRun { status, wall })
}

/// A fresh scratch directory for one benchmark (removed by the caller).
pub fn scratch(name: &str) -> Result<PathBuf> {
    let dir = std::env::temp_dir().join(format!("crease-bench-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    Ok(dir)
}

pub fn path_str(p: &Path) -> String {
    p.display().to_string()
}

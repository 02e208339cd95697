//! Read-only views of the scheduler for the web dashboard (crease-dashboard): the live worker registry, the
//! stream of every job's events, and a job's stored spec (to resubmit it). Kept apart from the scheduling
//! logic so the dashboard needs no access to the queue or the registry themselves.

use super::{lock, Scheduler};
use crate::scheduler::ApiError;
use crease_proto as pb;
use tokio::sync::broadcast;

/// One live worker as the dashboard shows it.
#[derive(Debug, Clone, PartialEq)]
pub struct WorkerView {
    pub id: String,
    pub name: String,
    pub address: String,
    pub capacity: u32,
    pub running: u32,
    /// Seconds since its last heartbeat (or registration).
    pub last_seen_secs: f64,
    pub draining: bool,
    /// (job id, task key, attempt) of the tasks it runs now, from the queue.
    pub tasks: Vec<(String, String, u32)>,
}

impl Scheduler {
    /// Every job's events as they are published (the gRPC `WatchJob` stream is per job). A slow reader
    /// misses events (`Lagged`) rather than holding the scheduler up.
    pub fn subscribe(&self) -> broadcast::Receiver<pb::JobEvent> {
        self.events.subscribe()
    }

    /// The registered workers, by id, with the tasks each one runs now.
    pub fn workers_view(&self) -> Result<Vec<WorkerView>, ApiError> {
        let running = lock(&self.store).running_tasks(None)?;
        let workers = lock(&self.workers);
        Ok(workers
            .ids()
            .iter()
            .filter_map(|id| workers.get(id))
            .map(|w| WorkerView {
                id: w.id.clone(),
                name: w.name.clone(),
                address: w.address.clone(),
                capacity: w.capacity,
                running: w.running,
                last_seen_secs: w.last_seen.elapsed().as_secs_f64(),
                draining: w.draining,
                tasks: running
                    .iter()
                    .filter(|(_, _, _, wid)| *wid == w.id)
                    .map(|(job, key, attempt, _)| (job.clone(), key.clone(), *attempt))
                    .collect(),
            })
            .collect())
    }

    /// The spec a job was submitted with, as JSON (a job spec's own format).
    pub fn job_spec_json(&self, job_id: &str) -> Result<String, ApiError> {
        Ok(lock(&self.store).job(job_id)?.spec_json)
    }
}

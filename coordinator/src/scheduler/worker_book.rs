//! Worker bookkeeping: registration, heartbeats, workers lost or dropped (their running tasks go back to the
//! queue), and the grace period a job waits when no worker is live.

use super::{fmt_secs, lock, ApiError, Scheduler};
use crate::state::store::{Claim, Failure, JobState, Outcome, StoreError};
use crate::state::workers::WorkerEntry;
use crease_jobs::FailureKind;
use crease_proto as pb;
use crease_proto::worker_client::WorkerClient;
use std::time::{Duration, Instant};
use tracing::{info, warn};

impl Scheduler {
    /// Registers a worker; refuses other protocol versions.
    pub fn register(
        &self,
        req: &pb::RegisterWorkerRequest,
    ) -> Result<pb::RegisterWorkerResponse, ApiError> {
        if req.protocol_version != crease_proto::PROTOCOL_VERSION {
            return Err(ApiError::Invalid(format!(
                "worker `{}` speaks protocol version {} but this coordinator speaks version {}; upgrade one of them",
                req.name,
                req.protocol_version,
                crease_proto::PROTOCOL_VERSION
            )));
        }
        if req.capacity == 0 {
            return Err(ApiError::Invalid(format!(
                "worker `{}` registered with capacity 0",
                req.name
            )));
        }
        let net = &self.config.worker_channel;
        let channel = net
            .connect_lazy(&req.address)
            .map_err(|e| ApiError::Invalid(format!("worker `{}`: address {e}", req.name)))?;
        let client = WorkerClient::new(channel)
            .max_decoding_message_size(net.max_message_bytes)
            .max_encoding_message_size(net.max_message_bytes);
        let id = {
            let mut n = lock(&self.next_worker);
            *n += 1;
            format!("w{}", *n)
        };
        lock(&self.store).register_worker(&id, &req.name, &req.address, req.capacity)?;
        lock(&self.workers).insert(WorkerEntry {
            id: id.clone(),
            name: req.name.clone(),
            address: req.address.clone(),
            capacity: req.capacity,
            running: 0,
            last_seen: Instant::now(),
            draining: false,
            client,
        });
        info!(
            worker = %id,
            name = %req.name,
            address = %req.address,
            capacity = req.capacity,
            "coordinator: worker {id} `{}` at {} registered, capacity {}",
            req.name,
            req.address,
            req.capacity
        );
        self.adopt(&id, &req.attempts);
        self.wake.notify_one();
        Ok(pb::RegisterWorkerResponse {
            worker_id: id,
            heartbeat_interval_ms: self.config.heartbeat_interval.as_millis() as u32,
        })
    }

    /// Records a heartbeat; `known: false` tells a worker to register again.
    pub fn heartbeat(&self, req: &pb::HeartbeatRequest) -> pb::HeartbeatResponse {
        let mut workers = lock(&self.workers);
        match workers.get_mut(&req.worker_id) {
            Some(w) => {
                w.last_seen = Instant::now();
                if req.draining && !w.draining {
                    info!(worker = %w.id, "coordinator: worker {} is draining", w.id);
                }
                w.draining = req.draining;
                pb::HeartbeatResponse { known: true }
            }
            None => pb::HeartbeatResponse { known: false },
        }
    }

    /// Forgets a worker whose stream broke or that stopped answering; if it is still alive, its next
    /// heartbeat is answered `known: false` and it registers again.
    pub(super) fn drop_worker(&self, wid: &str, why: &str) {
        if lock(&self.workers).remove(wid).is_some() {
            warn!(
                worker = %wid,
                reason = %why,
                "coordinator: worker {wid} dropped: {why}"
            );
            let _ = lock(&self.store).set_worker_state(wid, "lost");
        }
    }

    /// Workers that missed their heartbeats are lost: their running tasks go back to the queue.
    pub(super) fn expire_workers(&self) -> Result<(), StoreError> {
        let expired = lock(&self.workers).expired(self.config.worker_timeout);
        for wid in expired {
            self.drop_worker(
                &wid,
                &format!("no heartbeat for {}", fmt_secs(self.config.worker_timeout)),
            );
            let running = lock(&self.store).running_tasks(None)?;
            for (job, key, attempt, w) in running.into_iter().filter(|r| r.3 == wid) {
                let claim = Claim::of_attempt(&job, &key, attempt);
                let f = Failure::new(
                    FailureKind::WorkerLost,
                    format!(
                        "worker {w} was lost (no heartbeat for {})",
                        fmt_secs(self.config.worker_timeout)
                    ),
                );
                if let Outcome::JobFailed { message } = self.fail(&claim, &w, &f)? {
                    self.emit(&job, "job_failed", &key, &message, 0, 0);
                }
            }
        }
        Ok(())
    }

    /// The attempts a (re-)registering worker names that were running when this coordinator started become
    /// that worker's again, keeping their attempt numbers: nothing is run twice.
    fn adopt(&self, wid: &str, attempts: &[pb::AttemptRef]) {
        for a in attempts {
            let key = (a.job_id.clone(), a.task_key.clone(), a.attempt);
            if lock(&self.orphans).remove(&key).is_none() {
                continue;
            }
            match lock(&self.store).adopt(&a.job_id, &a.task_key, a.attempt, wid) {
                Ok(true) => {
                    if let Some(w) = lock(&self.workers).get_mut(wid) {
                        w.running += 1;
                    }
                    info!(
                        job_id = %a.job_id,
                        task = %a.task_key,
                        attempt = a.attempt,
                        worker = %wid,
                        "coordinator: worker {wid} still has attempt {} of task `{}`: adopted",
                        a.attempt,
                        a.task_key
                    );
                }
                Ok(false) => {}
                Err(e) => {
                    warn!(job_id = %a.job_id, task = %a.task_key, error = %e, "cannot adopt: {e}")
                }
            }
        }
    }

    /// Once the adoption window after a restart is over, the attempts no worker adopted are queued again
    /// (not charged to anyone: the coordinator, not the task, went away).
    pub(super) fn expire_orphans(&self) -> Result<(), StoreError> {
        if Instant::now() < self.adopt_until || lock(&self.orphans).is_empty() {
            return Ok(());
        }
        let left: Vec<_> = lock(&self.orphans).drain().collect();
        for ((job, key, attempt), worker) in left {
            let claim = Claim::of_attempt(&job, &key, attempt);
            let f = Failure::new(
                FailureKind::CoordinatorRestart,
                format!(
                    "the coordinator restarted and no worker reported attempt {attempt} within {}",
                    fmt_secs(self.config.adopt_window())
                ),
            );
            if let Outcome::JobFailed { message } = self.fail(&claim, &worker, &f)? {
                self.emit(&job, "job_failed", &key, &message, 0, 0);
            }
        }
        self.wake.notify_one();
        Ok(())
    }

    /// With no live worker, jobs with work left report `waiting`; after the grace period they fail.
    pub(super) fn grace(&self) -> Result<(), StoreError> {
        let live = lock(&self.workers).live();
        let since = {
            let mut s = lock(&self.no_workers_since);
            if live > 0 {
                *s = None;
            } else if s.is_none() {
                *s = Some(Instant::now());
            }
            *s
        };
        let jobs = lock(&self.store).active_jobs()?;
        let grace = self.config.no_worker_grace;
        for job in jobs {
            match since {
                None => {
                    if job.state == JobState::Waiting {
                        lock(&self.store).set_waiting(&job.id, false, "")?;
                        self.emit(&job.id, "job_resumed", "", "a worker is available", 0, 0);
                    }
                }
                Some(since) => {
                    // The clock starts when the farm emptied or when the job was submitted, whichever is later.
                    let age = Duration::from_secs_f64(
                        (crate::state::store::now() - job.submitted).max(0.0),
                    );
                    let waited = since.elapsed().min(age);
                    if waited >= grace {
                        let c = lock(&self.store).counts(&job.id)?;
                        let msg = format!(
                            "no worker was available for {} (the grace period); {} of {} task(s) could not run",
                            fmt_secs(grace),
                            c.total - c.done,
                            c.total
                        );
                        if lock(&self.store).fail_job(&job.id, &msg)? {
                            self.emit(&job.id, "job_failed", "", &msg, 0, 0);
                        }
                    } else if job.state != JobState::Waiting {
                        let msg = format!(
                            "waiting for a worker: none is registered; the job fails if none comes within {}",
                            fmt_secs(grace)
                        );
                        lock(&self.store).set_waiting(&job.id, true, &msg)?;
                        self.emit(&job.id, "job_waiting", "", &msg, 0, 0);
                    }
                }
            }
        }
        Ok(())
    }
}

//! Task dispatch: ready tasks to workers with free capacity (the per-job blocklist permitting), one attempt
//! followed to its end, and its outcome applied to the queue with the retry policy.

use super::{expand, lock, missing_outputs, ApiError, Scheduler};
use crate::state::store::{Claim, Failure, JobState, Outcome, StoreError};
use crease_jobs::{FailureKind, Storage, TaskOutput};
use crease_proto as pb;
use crease_proto::worker_client::WorkerClient;
use std::collections::HashSet;
use std::sync::Arc;
use std::time::Instant;
use tracing::{info, warn};

/// How one attempt ended, as seen from the coordinator.
enum Reported {
    Done(Vec<u8>),
    Failed(Failure),
}

impl Scheduler {
    pub(super) fn dispatch(self: &Arc<Self>) -> Result<(), StoreError> {
        let free = lock(&self.workers).total_free();
        if free == 0 {
            return Ok(());
        }
        let ready = lock(&self.store).ready_tasks(free as usize * 4 + 8)?;
        for t in ready {
            let ids = lock(&self.workers).ids();
            let banned: HashSet<String> = {
                let store = lock(&self.store);
                ids.iter()
                    .filter(|w| {
                        store
                            .worker_failures(&t.job_id, w)
                            .is_ok_and(|n| n >= self.config.blacklist_after)
                    })
                    .cloned()
                    .collect()
            };
            let chosen = {
                let workers = lock(&self.workers);
                let any_allowed = ids
                    .iter()
                    .any(|w| !banned.contains(w) && workers.get(w).is_some_and(|w| !w.draining));
                // A worker that failed this job repeatedly gets its tasks only when no other worker could.
                workers.pick(|w| !any_allowed || !banned.contains(&w.id))
            };
            let Some(wid) = chosen else { continue };
            let Some(claim) = lock(&self.store).claim(&t.job_id, &t.key, &wid)? else {
                continue;
            };
            let (client, name) = {
                let mut workers = lock(&self.workers);
                match workers.get_mut(&wid) {
                    Some(w) => {
                        w.running += 1;
                        (w.client.clone(), w.name.clone())
                    }
                    None => continue,
                }
            };
            info!(
                job_id = %claim.job_id,
                task = %claim.key,
                attempt = claim.attempt,
                worker = %wid,
                kind = %claim.kind,
                "dispatched to worker {wid} `{name}`"
            );
            self.task_log(&claim, &format!("dispatched to worker {wid} `{name}`"));
            self.emit(
                &claim.job_id,
                "task_started",
                &claim.key,
                &format!("attempt {} on {wid}", claim.attempt),
                0,
                0,
            );
            let this = Arc::clone(self);
            tokio::spawn(async move { this.run_attempt(claim, wid, client).await });
        }
        Ok(())
    }

    /// Sends one attempt to a worker and follows its stream to the end.
    async fn run_attempt(
        self: Arc<Self>,
        claim: Claim,
        wid: String,
        mut client: WorkerClient<crease_net::AuthChannel>,
    ) {
        let req = pb::Task {
            job_id: claim.job_id.clone(),
            task_key: claim.key.clone(),
            attempt: claim.attempt,
            kind: claim.kind.clone(),
            payload: claim.payload.clone().into_bytes(),
        };
        let lost = |reason: String| Reported::Failed(Failure::new(FailureKind::WorkerLost, reason));
        let started = Instant::now();
        let mut worker_tail = Vec::new();
        let reported = match client.execute(req).await {
            // A worker at its capacity (it finished a task the coordinator has not heard of yet, or another
            // coordinator shares it) stays registered; the task is handed back, not charged.
            Err(status) if status.code() == tonic::Code::ResourceExhausted => {
                Reported::Failed(Failure::new(
                    FailureKind::HandedBack,
                    format!("worker {wid} is at capacity: {}", status.message()),
                ))
            }
            // A task bigger than the gRPC message limit (here or on the worker) never fits: fail it clearly
            // instead of handing it back forever.
            Err(status) if status.code() == tonic::Code::OutOfRange => Reported::Failed(Failure::new(
                FailureKind::TooLarge,
                format!(
                    "task `{}` does not fit the gRPC message limit (--max-message-mib of the coordinator or worker {wid}): {}",
                    claim.key,
                    status.message()
                ),
            )),
            Err(status) => {
                // The worker never started the task (unreachable or draining): not the task's fault.
                self.drop_worker(
                    &wid,
                    &format!("did not take task `{}`: {}", claim.key, status.message()),
                );
                Reported::Failed(Failure::new(
                    FailureKind::HandedBack,
                    format!("worker {wid} did not take the task: {}", status.message()),
                ))
            }
            Ok(resp) => {
                let mut stream = resp.into_inner();
                loop {
                    match stream.message().await {
                        Ok(Some(pb::TaskEvent {
                            event: Some(ev),
                            log_tail,
                        })) => match ev {
                            pb::task_event::Event::Progress(p) => self.emit(
                                &claim.job_id,
                                "task_progress",
                                &claim.key,
                                if p.note.is_empty() { &p.stage } else { &p.note },
                                p.done,
                                p.total,
                            ),
                            pb::task_event::Event::Result(r) => {
                                worker_tail = log_tail;
                                break Reported::Done(r.output);
                            }
                            pb::task_event::Event::Failure(f) => {
                                worker_tail = log_tail;
                                break Reported::Failed(Failure::new(kind_of(&f), f.reason));
                            }
                        },
                        Ok(Some(_)) => {}
                        Ok(None) => {
                            self.drop_worker(&wid, "closed a task stream without a result");
                            break lost(format!(
                                "worker {wid} closed the stream of task `{}` without a result",
                                claim.key
                            ));
                        }
                        Err(status) => {
                            self.drop_worker(&wid, &format!("stream broke: {}", status.message()));
                            break lost(format!(
                                "worker {wid} was lost while running task `{}`: {}",
                                claim.key,
                                status.message()
                            ));
                        }
                    }
                }
            }
        };
        if let Some(w) = lock(&self.workers).get_mut(&wid) {
            w.running = w.running.saturating_sub(1);
        }
        if !worker_tail.is_empty() {
            let lines: Vec<String> = worker_tail.iter().map(|l| format!("{wid}: {l}")).collect();
            if let Err(e) =
                lock(&self.store).append_task_log(&claim.job_id, &claim.key, claim.attempt, &lines)
            {
                warn!(job_id = %claim.job_id, task = %claim.key, error = %e, "cannot store the task's log tail: {e}");
            }
        }
        let wall = started.elapsed().as_secs_f64();
        if let Err(e) = self.report(&claim, &wid, reported, wall).await {
            warn!(
                job_id = %claim.job_id,
                task = %claim.key,
                attempt = claim.attempt,
                worker = %wid,
                error = %e,
                "coordinator: job {} task `{}`: {e}",
                claim.job_id,
                claim.key
            );
        }
        self.wake.notify_one();
    }

    /// Applies an attempt's outcome to the queue.
    async fn report(
        &self,
        claim: &Claim,
        wid: &str,
        reported: Reported,
        wall: f64,
    ) -> Result<(), StoreError> {
        let (job_id, key) = (claim.job_id.as_str(), claim.key.as_str());
        let outcome = match reported {
            Reported::Done(bytes) => match serde_json::from_slice::<TaskOutput>(&bytes) {
                Ok(output) => {
                    let more = if claim.expands {
                        let job = lock(&self.store).job(job_id)?;
                        match expand(&job, key, &output) {
                            Ok(more) => more,
                            Err(msg) => {
                                lock(&self.store).fail_job(job_id, &msg)?;
                                self.emit(job_id, "job_failed", key, &msg, 0, 0);
                                self.stop_running(job_id);
                                return Ok(());
                            }
                        }
                    } else {
                        Vec::new()
                    };
                    let out_json = serde_json::to_string(&output).unwrap_or_default();
                    lock(&self.store).complete(
                        job_id,
                        key,
                        claim.attempt,
                        &out_json,
                        output.work_seconds,
                        &more,
                    )?
                }
                Err(e) => self.fail(
                    claim,
                    wid,
                    &Failure::new(
                        FailureKind::Internal,
                        format!("worker {wid} sent a malformed task output: {e}"),
                    ),
                )?,
            },
            Reported::Failed(f) => self.fail(claim, wid, &f)?,
        };
        match outcome {
            Outcome::Stale => {}
            Outcome::Done { job_done } => {
                self.metrics.task_done(&claim.kind, wall);
                info!(
                    job_id = %job_id,
                    task = %key,
                    attempt = claim.attempt,
                    worker = %wid,
                    kind = %claim.kind,
                    wall_seconds = wall,
                    "task done in {wall:.2}s"
                );
                self.task_log(claim, &format!("done in {wall:.2}s on {wid}"));
                let (done, total) = self.progress_of(job_id);
                self.emit(job_id, "task_done", key, "", done, total);
                if job_done {
                    self.finish(job_id).await?;
                }
            }
            Outcome::Retry { attempt } => self.emit(
                job_id,
                "task_retry",
                key,
                &format!("attempt {attempt} failed"),
                0,
                0,
            ),
            Outcome::JobFailed { message } => {
                self.emit(job_id, "job_failed", key, &message, 0, 0);
                self.stop_running(job_id);
            }
            Outcome::Cancelled => {}
        }
        // A finalize that raced with a cancel or a failure must not leave a report vouching for the output.
        let job = lock(&self.store).job(job_id)?;
        if key == crease_jobs::storage::keys::FINALIZE_TASK
            && matches!(job.state, JobState::Cancelled | JobState::Failed)
        {
            if let Ok(out) = Storage::open(&job.output) {
                let _ = out.delete(crease_jobs::storage::keys::REPORT).await;
            }
        }
        Ok(())
    }

    pub(super) fn fail(
        &self,
        claim: &Claim,
        wid: &str,
        f: &Failure,
    ) -> Result<Outcome, StoreError> {
        let backoff = self.config.backoff(claim.attempt).as_secs_f64();
        let outcome =
            lock(&self.store).fail(&claim.job_id, &claim.key, claim.attempt, wid, f, backoff)?;
        if f.counts() && !matches!(outcome, Outcome::Stale | Outcome::Cancelled) {
            self.metrics.failure();
        }
        let line = match &outcome {
            Outcome::Retry { .. } => {
                self.metrics.retry();
                warn!(
                    job_id = %claim.job_id,
                    task = %claim.key,
                    attempt = claim.attempt,
                    worker = %wid,
                    error = %f.reason,
                    "coordinator: job {} task `{}` attempt {} failed on {wid}: {}",
                    claim.job_id,
                    claim.key,
                    claim.attempt,
                    f.reason
                );
                if f.counts() {
                    format!("failed on {wid} ({}): {}; queued again", f.kind, f.reason)
                } else {
                    format!("handed back by {wid}: {}; queued again", f.reason)
                }
            }
            Outcome::JobFailed { message } => {
                warn!(
                    job_id = %claim.job_id,
                    task = %claim.key,
                    attempt = claim.attempt,
                    worker = %wid,
                    error = %f.reason,
                    "job failed: {message}"
                );
                format!("failed on {wid} ({}): {}; the job failed", f.kind, f.reason)
            }
            Outcome::Cancelled => format!("stopped on {wid}: the job ended"),
            Outcome::Stale | Outcome::Done { .. } => return Ok(outcome),
        };
        self.task_log(claim, &line);
        Ok(outcome)
    }

    /// Every task is done: the job is done once every final output exists.
    async fn finish(&self, job_id: &str) -> Result<(), StoreError> {
        let job = lock(&self.store).job(job_id)?;
        let missing = match missing_outputs(&job).await {
            Ok(m) => m,
            Err(msg) => vec![msg],
        };
        if missing.is_empty() {
            if lock(&self.store).finish_job(job_id)? {
                let (done, total) = self.progress_of(job_id);
                self.emit(job_id, "job_done", "", "", done, total);
            }
        } else {
            let msg = format!(
                "every task finished but these outputs are missing from {}: {}",
                job.output,
                missing.join(", ")
            );
            if lock(&self.store).fail_job(job_id, &msg)? {
                self.emit(job_id, "job_failed", "", &msg, 0, 0);
            }
        }
        Ok(())
    }

    /// Tells workers to stop the running tasks of a job that ended (cancelled or failed).
    pub(super) fn stop_running(&self, job_id: &str) {
        let running = lock(&self.store)
            .running_tasks(Some(job_id))
            .unwrap_or_default();
        for (job, key, attempt, wid) in running {
            let client = lock(&self.workers).get(&wid).map(|w| w.client.clone());
            if let Some(mut client) = client {
                tokio::spawn(async move {
                    let _ = client
                        .cancel(pb::CancelTaskRequest {
                            job_id: job,
                            task_key: key,
                            attempt,
                        })
                        .await;
                });
            }
        }
    }
}

impl Scheduler {
    /// `ReportTask`: the end of an attempt whose stream broke (the coordinator restarted while it ran). It is
    /// applied like a streamed one while it is still the task's current attempt; otherwise it is stale (the
    /// task ran again elsewhere) and dropped.
    pub async fn report_task(
        &self,
        req: pb::TaskReport,
    ) -> Result<pb::ReportTaskResponse, ApiError> {
        let a = req
            .attempt
            .ok_or_else(|| ApiError::Invalid("ReportTask without an attempt".into()))?;
        let ev = req.event.unwrap_or_default();
        let reported = match ev.event {
            Some(pb::task_event::Event::Result(r)) => Reported::Done(r.output),
            Some(pb::task_event::Event::Failure(f)) => {
                Reported::Failed(Failure::new(kind_of(&f), f.reason))
            }
            _ => {
                return Err(ApiError::Invalid(format!(
                    "ReportTask for task `{}` attempt {} carries no result or failure",
                    a.task_key, a.attempt
                )))
            }
        };
        let current = lock(&self.store).current_claim(&a.job_id, &a.task_key, a.attempt)?;
        let Some((claim, owner, started)) = current else {
            let msg = format!(
                "attempt {} reported by {} after it was given up: ignored",
                a.attempt, req.worker_id
            );
            lock(&self.store).note(&a.job_id, "stale_report", &a.task_key, &msg)?;
            return Ok(pb::ReportTaskResponse { accepted: false });
        };
        lock(&self.orphans).remove(&(a.job_id.clone(), a.task_key.clone(), a.attempt));
        if let Some(w) = lock(&self.workers).get_mut(&owner) {
            w.running = w.running.saturating_sub(1);
        }
        if !ev.log_tail.is_empty() {
            let lines: Vec<String> = ev
                .log_tail
                .iter()
                .map(|l| format!("{owner}: {l}"))
                .collect();
            lock(&self.store).append_task_log(&claim.job_id, &claim.key, claim.attempt, &lines)?;
        }
        let line = format!("reported by {} after a coordinator restart", req.worker_id);
        self.task_log(&claim, &line);
        let wall = (crate::state::store::now() - started).max(0.0);
        self.report(&claim, &owner, reported, wall).await?;
        self.wake.notify_one();
        Ok(pb::ReportTaskResponse { accepted: true })
    }
}

/// The kind a worker reported; a worker older than the `kind` field (or one naming a kind this coordinator
/// does not know) is read by its flags, as before kinds existed.
fn kind_of(f: &pb::TaskFailure) -> FailureKind {
    FailureKind::parse(&f.kind).unwrap_or(if f.cancelled {
        FailureKind::Cancelled
    } else if f.retryable {
        FailureKind::Transient
    } else {
        FailureKind::InvalidInput
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_workers_kind_is_read_and_an_older_worker_is_read_by_its_flags() {
        let f = |kind: &str, retryable, cancelled| pb::TaskFailure {
            kind: kind.into(),
            retryable,
            cancelled,
            reason: String::new(),
        };
        assert_eq!(
            kind_of(&f("solver-failure", true, false)),
            FailureKind::Solver
        );
        assert_eq!(kind_of(&f("", false, false)), FailureKind::InvalidInput);
        assert_eq!(kind_of(&f("", true, false)), FailureKind::Transient);
        assert_eq!(
            kind_of(&f("from-the-future", true, true)),
            FailureKind::Cancelled
        );
    }
}

//! The scheduler: turns submitted jobs into queued tasks, hands ready tasks to workers by free capacity,
//! follows each attempt's progress stream, applies the retry policy, watches heartbeats and the no-worker
//! grace period, and publishes job events. Everything the gRPC face ([`crate::server`]) and the in-process
//! client ([`crate::client::LocalClient`]) do goes through here.

use crate::config::CoordinatorConfig;
use crate::metrics::{CoordinatorMetrics, Snapshot};
use crate::state::store::{
    Claim, Failure, JobRow, JobState, NewJob, NewTask, Outcome, Store, StoreError,
};
use crate::state::workers::{WorkerEntry, Workers};
use crease_jobs::{InputInfo, JobSpec, Storage, TaskOutput};
use crease_proto as pb;
use crease_proto::worker_client::WorkerClient;
use std::collections::HashSet;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};
use tokio::sync::{broadcast, mpsc, Notify};
use tracing::{info, warn};

/// Errors of client and worker requests, mapped to gRPC codes by the server.
#[derive(Debug, thiserror::Error)]
pub enum ApiError {
    /// The request is wrong (bad job spec, unreachable input, wrong protocol version).
    #[error("{0}")]
    Invalid(String),
    #[error("{0}")]
    NotFound(String),
    #[error("{0}")]
    Internal(String),
}

impl From<StoreError> for ApiError {
    fn from(e: StoreError) -> Self {
        match e {
            StoreError::NoSuchJob(id) => ApiError::NotFound(format!("job {id} not found")),
            e => ApiError::Internal(e.to_string()),
        }
    }
}

/// How one attempt ended, as seen from the coordinator.
enum Reported {
    Done(Vec<u8>),
    Failed(Failure),
}

/// The coordinator's state and scheduling logic.
pub struct Scheduler {
    config: CoordinatorConfig,
    store: Mutex<Store>,
    workers: Mutex<Workers>,
    events: broadcast::Sender<pb::JobEvent>,
    wake: Notify,
    /// When the farm last became empty (coordinator start counts as empty).
    no_workers_since: Mutex<Option<Instant>>,
    next_worker: Mutex<u32>,
    metrics: CoordinatorMetrics,
    live: crate::live::LiveProgress,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    // A panic while holding the lock leaves the data as consistent as SQLite left it; keep serving.
    m.lock().unwrap_or_else(|p| p.into_inner())
}

fn fmt_secs(d: Duration) -> String {
    format!("{:.1}s", d.as_secs_f64())
}

impl Scheduler {
    /// Opens the queue (recovering it after a restart) and returns the scheduler; call [`Scheduler::run`] to
    /// start dispatching.
    pub fn open(config: CoordinatorConfig) -> Result<Arc<Self>, StoreError> {
        let mut store = match &config.db {
            Some(p) => Store::open(p)?,
            None => Store::in_memory()?,
        };
        let requeued = store.recover()?;
        if requeued > 0 {
            info!(
                requeued,
                "coordinator: recovered the queue, {requeued} task(s) that were running are queued again"
            );
        }
        let next = store.worker_count()?;
        let (events, _) = broadcast::channel(4096);
        Ok(Arc::new(Scheduler {
            config,
            store: Mutex::new(store),
            workers: Mutex::new(Workers::default()),
            events,
            wake: Notify::new(),
            no_workers_since: Mutex::new(Some(Instant::now())),
            next_worker: Mutex::new(next),
            metrics: CoordinatorMetrics::default(),
            live: Default::default(),
        }))
    }

    pub fn config(&self) -> &CoordinatorConfig {
        &self.config
    }

    /// The dispatch loop: runs until the process ends.
    pub async fn run(self: Arc<Self>) {
        let tick = self
            .config
            .heartbeat_interval
            .min(Duration::from_millis(200));
        loop {
            tokio::select! {
                _ = self.wake.notified() => {}
                _ = tokio::time::sleep(tick) => {}
            }
            if let Err(e) = self.tick() {
                warn!(error = %e, "coordinator: {e}");
            }
        }
    }

    fn tick(self: &Arc<Self>) -> Result<(), StoreError> {
        self.expire_workers()?;
        self.grace()?;
        self.dispatch()
    }

    // ------------------------------------------------------------------ client requests

    /// Validates, inspects and plans a job, then queues it. A client token that names an earlier job returns
    /// that job instead (idempotent submit).
    pub async fn submit(&self, text: &str, format: &str) -> Result<(String, bool), ApiError> {
        let spec = match format {
            "json" => JobSpec::from_json_str(text),
            _ => JobSpec::from_toml_str(text),
        }
        .map_err(|e| ApiError::Invalid(format!("rejected: {e}")))?;
        if let Some(token) = &spec.client_token {
            if let Some(id) = lock(&self.store).job_by_token(token)? {
                return Ok((id, false));
            }
        }
        let info =
            crease_jobs::limits::admit(&spec, &self.config.storage_roots, &self.config.limits)
                .await
                .map_err(|e| ApiError::Invalid(format!("rejected: {e}")))?;
        let defs = crease_jobs::plan(&spec, &info)
            .map_err(|e| ApiError::Invalid(format!("rejected: {e}")))?;
        // A report left by an earlier run must not vouch for this job while it runs, and files only an earlier
        // run wrote must not stand beside this one's result (crease_jobs::stale).
        let out =
            Storage::open(&spec.output).map_err(|e| ApiError::Invalid(format!("rejected: {e}")))?;
        crease_jobs::stale::claim_output(&out, &spec, &info)
            .await
            .map_err(|e| ApiError::Invalid(format!("rejected: {e}")))?;
        let name = if spec.name.is_empty() {
            spec.input
                .trim_end_matches('/')
                .rsplit('/')
                .next()
                .unwrap_or("job")
                .to_string()
        } else {
            spec.name.clone()
        };
        let job = NewJob {
            name,
            spec_json: serde_json::to_string(&spec)
                .map_err(|e| ApiError::Internal(e.to_string()))?,
            info_json: serde_json::to_string(&info)
                .map_err(|e| ApiError::Internal(e.to_string()))?,
            output: spec.output.clone(),
            priority: spec.priority,
            client_token: spec.client_token.clone(),
            max_task_attempts: spec.max_task_attempts,
            max_failures: spec.max_task_failures_per_job,
            tasks: defs.into_iter().map(new_task).collect(),
        };
        let (id, created) = lock(&self.store).insert_job(&job)?;
        if created {
            self.emit(&id, "job_submitted", "", &job.name, 0, 0);
        }
        self.wake.notify_one();
        Ok((id, created))
    }

    /// A job's status, optionally with one row per task.
    pub fn status(&self, job_id: &str, with_tasks: bool) -> Result<pb::JobStatus, ApiError> {
        let store = lock(&self.store);
        let job = store.job(job_id)?;
        self.status_with_running(&store, &job, with_tasks)
    }

    /// [`status_of`] plus the running tasks' workers and latest progress ([`crate::live`]).
    fn status_with_running(
        &self,
        store: &Store,
        job: &JobRow,
        with_tasks: bool,
    ) -> Result<pb::JobStatus, ApiError> {
        let mut status = status_of(store, job, with_tasks)?;
        if status.tasks_running > 0 {
            if !with_tasks {
                status.tasks = status_of(store, job, true)?.tasks;
            }
            self.live.fill(&mut status);
            if !with_tasks {
                status.tasks.clear();
            }
        }
        Ok(status)
    }

    /// All jobs, newest first.
    pub fn list(&self) -> Result<Vec<pb::JobStatus>, ApiError> {
        let store = lock(&self.store);
        let jobs = store.list_jobs()?;
        jobs.iter()
            .map(|j| self.status_with_running(&store, j, false))
            .collect()
    }

    /// Cancels a job: queued tasks are dropped and workers are told to stop its running tasks.
    pub fn cancel(&self, job_id: &str) -> Result<JobState, ApiError> {
        let state = lock(&self.store).cancel_job(job_id)?;
        if state == JobState::Cancelled {
            self.emit(job_id, "job_cancelled", "", "cancelled by the user", 0, 0);
            self.stop_running(job_id);
        }
        Ok(state)
    }

    /// Progress events of one job: a snapshot first, then live events, then a final snapshot once the job has
    /// ended (the stream then closes).
    pub fn watch(self: &Arc<Self>, job_id: &str) -> Result<mpsc::Receiver<pb::JobEvent>, ApiError> {
        let mut rx = self.events.subscribe();
        let first = self.status(job_id, false)?;
        let (tx, out) = mpsc::channel(256);
        let id = job_id.to_string();
        let this = Arc::downgrade(self);
        tokio::spawn(async move {
            let snapshot = |s: pb::JobStatus| pb::JobEvent {
                job_id: s.job_id.clone(),
                kind: "snapshot".into(),
                done: s.tasks_done as u64,
                total: s.tasks_total as u64,
                message: s.message.clone(),
                status: Some(s),
                ..Default::default()
            };
            let terminal = |s: &pb::JobStatus| JobState::parse(&s.state).is_terminal();
            let done = terminal(&first);
            if tx.send(snapshot(first)).await.is_err() || done {
                return;
            }
            let mut poll = tokio::time::interval(Duration::from_millis(250));
            loop {
                tokio::select! {
                    ev = rx.recv() => match ev {
                        Ok(ev) if ev.job_id == id => {
                            if tx.send(ev).await.is_err() { return; }
                        }
                        Ok(_) | Err(broadcast::error::RecvError::Lagged(_)) => {}
                        Err(broadcast::error::RecvError::Closed) => return,
                    },
                    _ = poll.tick() => {}
                }
                let Some(sched) = this.upgrade() else { return };
                let Ok(s) = sched.status(&id, false) else {
                    return;
                };
                if terminal(&s) {
                    let _ = tx.send(snapshot(s)).await;
                    return;
                }
            }
        });
        Ok(out)
    }

    // ------------------------------------------------------------------ worker requests

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

    // ------------------------------------------------------------------ scheduling

    fn dispatch(self: &Arc<Self>) -> Result<(), StoreError> {
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
        let lost = |reason: String| {
            Reported::Failed(Failure {
                retryable: true,
                counts: true,
                cancelled: false,
                reason,
            })
        };
        let started = Instant::now();
        let mut worker_tail = Vec::new();
        let reported = match client.execute(req).await {
            // A worker at its capacity (it finished a task the coordinator has not heard of yet, or another
            // coordinator shares it) stays registered; the task is handed back, not charged.
            Err(status) if status.code() == tonic::Code::ResourceExhausted => {
                Reported::Failed(Failure {
                    retryable: true,
                    counts: false,
                    cancelled: true,
                    reason: format!("worker {wid} is at capacity: {}", status.message()),
                })
            }
            // A task bigger than the gRPC message limit (here or on the worker) never fits: fail it clearly
            // instead of handing it back forever.
            Err(status) if status.code() == tonic::Code::OutOfRange => Reported::Failed(Failure {
                retryable: false,
                counts: true,
                cancelled: false,
                reason: format!(
                    "task `{}` does not fit the gRPC message limit (--max-message-mib of the coordinator or worker {wid}): {}",
                    claim.key,
                    status.message()
                ),
            }),
            Err(status) => {
                // The worker never started the task (unreachable or draining): not the task's fault.
                self.drop_worker(
                    &wid,
                    &format!("did not take task `{}`: {}", claim.key, status.message()),
                );
                Reported::Failed(Failure {
                    retryable: true,
                    counts: false,
                    cancelled: true,
                    reason: format!("worker {wid} did not take the task: {}", status.message()),
                })
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
                                break Reported::Failed(Failure {
                                    retryable: f.retryable,
                                    counts: !f.cancelled,
                                    cancelled: f.cancelled,
                                    reason: f.reason,
                                });
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
                    &Failure {
                        retryable: false,
                        counts: true,
                        cancelled: false,
                        reason: format!("worker {wid} sent a malformed task output: {e}"),
                    },
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
        if key == crease_jobs::keys::FINALIZE_TASK
            && matches!(job.state, JobState::Cancelled | JobState::Failed)
        {
            if let Ok(out) = Storage::open(&job.output) {
                let _ = out.delete(crease_jobs::keys::REPORT).await;
            }
        }
        Ok(())
    }

    fn fail(&self, claim: &Claim, wid: &str, f: &Failure) -> Result<Outcome, StoreError> {
        let backoff = self.config.backoff(claim.attempt).as_secs_f64();
        let outcome =
            lock(&self.store).fail(&claim.job_id, &claim.key, claim.attempt, wid, f, backoff)?;
        if f.counts && !matches!(outcome, Outcome::Stale | Outcome::Cancelled) {
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
                if f.counts {
                    format!("failed on {wid}: {}; queued again", f.reason)
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
                format!("failed on {wid}: {}; the job failed", f.reason)
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
    fn stop_running(&self, job_id: &str) {
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

    /// Forgets a worker whose stream broke or that stopped answering; if it is still alive, its next
    /// heartbeat is answered `known: false` and it registers again.
    fn drop_worker(&self, wid: &str, why: &str) {
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
    fn expire_workers(&self) -> Result<(), StoreError> {
        let expired = lock(&self.workers).expired(self.config.worker_timeout);
        for wid in expired {
            self.drop_worker(
                &wid,
                &format!("no heartbeat for {}", fmt_secs(self.config.worker_timeout)),
            );
            let running = lock(&self.store).running_tasks(None)?;
            for (job, key, attempt, w) in running.into_iter().filter(|r| r.3 == wid) {
                let claim = Claim {
                    job_id: job.clone(),
                    key: key.clone(),
                    kind: String::new(),
                    payload: String::new(),
                    attempt,
                    expands: false,
                };
                let f = Failure {
                    retryable: true,
                    counts: true,
                    cancelled: false,
                    reason: format!(
                        "worker {w} was lost (no heartbeat for {})",
                        fmt_secs(self.config.worker_timeout)
                    ),
                };
                if let Outcome::JobFailed { message } = self.fail(&claim, &w, &f)? {
                    self.emit(&job, "job_failed", &key, &message, 0, 0);
                }
            }
        }
        Ok(())
    }

    /// With no live worker, jobs with work left report `waiting`; after the grace period they fail.
    fn grace(&self) -> Result<(), StoreError> {
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

    fn progress_of(&self, job_id: &str) -> (u64, u64) {
        lock(&self.store)
            .counts(job_id)
            .map(|c| (c.done as u64, c.total as u64))
            .unwrap_or((0, 0))
    }

    /// Appends one of the coordinator's own lines to an attempt's log (`crease logs`).
    fn task_log(&self, claim: &Claim, message: &str) {
        let line = crease_telemetry::tail::stamp("coordinator", message);
        if let Err(e) =
            lock(&self.store).append_task_log(&claim.job_id, &claim.key, claim.attempt, &[line])
        {
            warn!(job_id = %claim.job_id, task = %claim.key, error = %e, "cannot store a task log line: {e}");
        }
    }

    /// The log of a job's task attempts (one task, or all); unknown jobs and tasks are named in the error.
    pub fn task_logs(
        &self,
        job_id: &str,
        task_key: Option<&str>,
    ) -> Result<pb::GetTaskLogsResponse, ApiError> {
        let store = lock(&self.store);
        store.job(job_id)?;
        if let Some(key) = task_key {
            if !store.has_task(job_id, key)? {
                return Err(ApiError::NotFound(format!(
                    "job {job_id} has no task `{key}`"
                )));
            }
        }
        let attempts = store
            .task_logs(job_id, task_key)?
            .into_iter()
            .map(|a| pb::TaskAttemptLog {
                task_key: a.task_key,
                attempt: a.attempt,
                worker: a.worker,
                outcome: a.outcome,
                error: a.error,
                started_unix: a.started,
                finished_unix: a.finished,
                lines: a.lines,
            })
            .collect();
        Ok(pb::GetTaskLogsResponse { attempts })
    }

    /// The metrics text for a scrape: gauges read from the queue and the worker registry now.
    pub fn metrics_text(&self) -> String {
        let queue = match lock(&self.store).gauges() {
            Ok(g) => g,
            Err(e) => {
                warn!(error = %e, "metrics: cannot read the queue: {e}");
                Default::default()
            }
        };
        let (live, total) = {
            let w = lock(&self.workers);
            (w.live() as i64, w.ids().len() as i64)
        };
        self.metrics.render(&Snapshot {
            queue,
            workers_live: live,
            workers_draining: total - live,
        })
    }

    fn emit(&self, job_id: &str, kind: &str, key: &str, message: &str, done: u64, total: u64) {
        let ev = pb::JobEvent {
            job_id: job_id.to_string(),
            kind: kind.to_string(),
            task_key: key.to_string(),
            message: message.to_string(),
            done,
            total,
            status: None,
        };
        self.live.observe(&ev);
        let _ = self.events.send(ev);
    }
}

fn new_task(d: crease_jobs::TaskDef) -> NewTask {
    NewTask {
        kind: d.spec.kind().to_string(),
        payload: String::from_utf8(d.spec.to_payload()).unwrap_or_default(),
        key: d.key,
        deps: d.deps,
        expands: d.expands,
    }
}

fn job_parts(job: &JobRow) -> Result<(JobSpec, InputInfo), String> {
    let spec: JobSpec = serde_json::from_str(&job.spec_json)
        .map_err(|e| format!("job {}: stored spec is unreadable: {e}", job.id))?;
    let info: InputInfo = serde_json::from_str(&job.info_json)
        .map_err(|e| format!("job {}: stored input info is unreadable: {e}", job.id))?;
    Ok((spec, info))
}

fn expand(job: &JobRow, key: &str, output: &TaskOutput) -> Result<Vec<NewTask>, String> {
    let (spec, info) = job_parts(job)?;
    crease_jobs::expand(&spec, &info, key, output)
        .map(|defs| defs.into_iter().map(new_task).collect())
        .map_err(|e| format!("task `{key}` succeeded but its results cannot be planned on: {e}"))
}

async fn missing_outputs(job: &JobRow) -> Result<Vec<String>, String> {
    let (spec, info) = job_parts(job)?;
    let out = Storage::open(&job.output).map_err(|e| e.to_string())?;
    let mut missing = Vec::new();
    for key in crease_jobs::final_outputs(&spec, &info) {
        if !out.exists(&key).await.map_err(|e| e.to_string())? {
            missing.push(key);
        }
    }
    Ok(missing)
}

fn status_of(store: &Store, job: &JobRow, with_tasks: bool) -> Result<pb::JobStatus, ApiError> {
    let c = store.counts(&job.id)?;
    let tasks = if with_tasks {
        store
            .tasks(&job.id)?
            .into_iter()
            .map(|t| pb::TaskRow {
                key: t.key,
                kind: t.kind,
                state: t.state.as_str().to_string(),
                attempts: t.attempts,
                last_error: t.last_error,
                worker: t.worker,
                work_seconds: t.work_seconds,
                wall_seconds: t.wall_seconds,
            })
            .collect()
    } else {
        Vec::new()
    };
    Ok(pb::JobStatus {
        job_id: job.id.clone(),
        name: job.name.clone(),
        state: job.state.as_str().to_string(),
        priority: job.priority,
        tasks_total: c.total,
        tasks_done: c.done,
        tasks_running: c.running,
        tasks_failed: c.failed,
        message: job.message.clone(),
        output: job.output.clone(),
        submitted_unix: job.submitted,
        finished_unix: job.finished,
        tasks,
        work_seconds: c.work_seconds,
        running: Vec::new(),
    })
}

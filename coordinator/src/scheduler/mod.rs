//! The scheduler: turns submitted jobs into queued tasks, hands ready tasks to workers by free capacity,
//! follows each attempt's progress stream, applies the retry policy, watches heartbeats and the no-worker
//! grace period, and publishes job events. Everything the gRPC face ([`crate::server`]) and the in-process
//! client ([`crate::client::LocalClient`]) do goes through here.
//!
//! Split by concern: [`dispatch`] hands tasks to workers and applies each attempt's outcome; [`worker_book`]
//! keeps the registry of workers (registration, heartbeats, loss) and the no-worker grace period; this module
//! holds the client requests and the shared state.
mod dispatch;
mod views;
pub use views::WorkerView;
mod worker_book;

use crate::config::CoordinatorConfig;
use crate::metrics::{CoordinatorMetrics, Snapshot};
use crate::state::store::{Claim, JobRow, JobState, NewJob, NewTask, Store, StoreError};
use crate::state::workers::Workers;
use crease_jobs::{InputInfo, JobSpec, Storage, TaskOutput};
use crease_proto as pb;
use std::collections::HashMap;
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
            e @ (StoreError::TokenReused { .. } | StoreError::OutputBusy { .. }) => {
                ApiError::Invalid(format!("rejected: {e}"))
            }
            e => ApiError::Internal(e.to_string()),
        }
    }
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
    /// Attempts that were running when this coordinator started (job, key, attempt) and the worker id they
    /// ran under; their workers adopt them by registering again, until `adopt_until`.
    orphans: Mutex<HashMap<(String, String, u32), String>>,
    adopt_until: Instant,
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
        let running = store.recover()?;
        let window = config.adopt_window();
        if !running.is_empty() {
            info!(
                running = running.len(),
                "coordinator: recovered the queue; {} task(s) were running: their workers may report them within {}, then they are queued again",
                running.len(),
                fmt_secs(window)
            );
        }
        let adopt_until = Instant::now() + window;
        let orphans = running
            .into_iter()
            .map(|(job, key, attempt, worker)| ((job, key, attempt), worker))
            .collect();
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
            orphans: Mutex::new(orphans),
            adopt_until,
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
        self.expire_orphans()?;
        self.grace()?;
        self.dispatch()
    }

    /// Validates, inspects and plans a job, then queues it. A client token that names an earlier job with the
    /// same spec returns that job instead (idempotent submit); with another spec it is refused, naming the job.
    /// So is a job whose output a live job is writing.
    pub async fn submit(&self, text: &str, format: &str) -> Result<(String, bool), ApiError> {
        let spec = match format {
            "json" => JobSpec::from_json_str(text),
            _ => JobSpec::from_toml_str(text),
        }
        .map_err(|e| ApiError::Invalid(format!("rejected: {e}")))?;
        let spec_json =
            serde_json::to_string(&spec).map_err(|e| ApiError::Internal(e.to_string()))?;
        // Before admission touches the output (it removes a stale report): a resubmit gets its job back, and a
        // live job's output is not anyone else's.
        {
            let store = lock(&self.store);
            if let Some(token) = &spec.client_token {
                if let Some(id) = store.job_by_token(token, &spec_json)? {
                    return Ok((id, false));
                }
            }
            if let Some((job, state)) = store.live_job_writing(&spec.output)? {
                return Err(StoreError::OutputBusy {
                    output: spec.output.clone(),
                    job,
                    state: state.as_str().to_string(),
                }
                .into());
            }
        }
        let info = crease_jobs::plan::limits::admit(
            &spec,
            &self.config.storage_roots,
            &self.config.limits,
        )
        .await
        .map_err(|e| ApiError::Invalid(format!("rejected: {e}")))?;
        let defs = crease_jobs::plan(&spec, &info)
            .map_err(|e| ApiError::Invalid(format!("rejected: {e}")))?;
        // A report left by an earlier run must not vouch for this job while it runs, and files only an earlier
        // run wrote must not stand beside this one's result (crease_jobs::plan::stale).
        let out =
            Storage::open(&spec.output).map_err(|e| ApiError::Invalid(format!("rejected: {e}")))?;
        crease_jobs::plan::stale::claim_output(&out, &spec, &info)
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
            spec_json,
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
        let mut status = status_of(store, job, with_tasks, self.config.blacklist_after)?;
        if status.tasks_running > 0 {
            if !with_tasks {
                status.tasks = status_of(store, job, true, self.config.blacklist_after)?.tasks;
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

    /// Clears a job's worker blocklist (one worker, or all); returns the workers cleared.
    pub fn unblock(&self, job_id: &str, worker: Option<&str>) -> Result<Vec<String>, ApiError> {
        let mut store = lock(&self.store);
        store.job(job_id)?;
        let cleared = store.unblock(job_id, worker)?;
        drop(store);
        if !cleared.is_empty() {
            info!(job_id = %job_id, "blocklist of job {job_id} cleared for {}", cleared.join(", "));
            self.emit(job_id, "blocklist_cleared", "", &cleared.join(", "), 0, 0);
            self.wake.notify_one();
        }
        Ok(cleared)
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
                kind: a.kind,
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
        let blocklisted = lock(&self.store)
            .blocklist_sizes(self.config.blacklist_after)
            .unwrap_or_default();
        self.metrics.render(&Snapshot {
            queue,
            blocklisted,
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

fn status_of(
    store: &Store,
    job: &JobRow,
    with_tasks: bool,
    blacklist_after: u32,
) -> Result<pb::JobStatus, ApiError> {
    let blocked_workers = store
        .blocklist(&job.id, blacklist_after)?
        .into_iter()
        .map(|b| pb::BlockedWorker {
            worker: b.worker,
            failures: b.failures,
            reasons: b.reasons,
        })
        .collect();
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
        blocked_workers,
        running: Vec::new(),
    })
}

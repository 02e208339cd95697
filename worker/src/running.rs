//! Running tasks: the table of tasks in flight (so `Cancel` and the drain can stop them), the progress sink
//! that turns crease-core progress into stream events, and the run of one task.
//!
//! A task keeps running when its coordinator goes away (a restart): outputs are deterministic and the work is
//! as good as any rerun. Its final event, which has no stream to go to any more, is held here until the
//! reporter has registered again and hands it over with `ReportTask`.

use crate::metrics::WorkerMetrics;
use crease_core::progress::Progress;
use crease_jobs::{ExecContext, TaskError, TaskSpec};
use crease_proto as pb;
use crease_telemetry::tail::LogTail;
use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};
use tokio::sync::{mpsc, Notify, OwnedSemaphorePermit};
use tracing::{info, warn, Instrument};

/// Identifies one attempt of one task.
pub type AttemptId = (String, String, u32);

type Sender = mpsc::UnboundedSender<Result<pb::TaskEvent, tonic::Status>>;

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// Tasks in flight on this worker.
pub struct Tasks {
    cache_dir: PathBuf,
    in_flight: Mutex<HashMap<AttemptId, Arc<AtomicBool>>>,
    /// Final events of attempts whose stream had closed (the coordinator restarted), not yet reported.
    held: Mutex<Vec<(AttemptId, pb::TaskEvent)>>,
    draining: AtomicBool,
    idle: Notify,
    pub metrics: Arc<WorkerMetrics>,
}

impl Tasks {
    pub fn new(cache_dir: PathBuf, metrics: Arc<WorkerMetrics>) -> Self {
        Tasks {
            cache_dir,
            in_flight: Mutex::new(HashMap::new()),
            held: Mutex::new(Vec::new()),
            draining: AtomicBool::new(false),
            idle: Notify::new(),
            metrics,
        }
    }

    pub fn running(&self) -> usize {
        lock(&self.in_flight).len()
    }

    /// Attempts running here or held: what a new registration tells the coordinator to adopt.
    pub fn attempts(&self) -> Vec<AttemptId> {
        let mut ids: Vec<AttemptId> = lock(&self.in_flight).keys().cloned().collect();
        ids.extend(lock(&self.held).iter().map(|(id, _)| id.clone()));
        ids
    }

    /// Takes the held final events (to report them); give back with [`Tasks::hold`] what could not be sent.
    pub fn take_held(&self) -> Vec<(AttemptId, pb::TaskEvent)> {
        std::mem::take(&mut *lock(&self.held))
    }

    pub fn hold(&self, id: AttemptId, event: pb::TaskEvent) {
        lock(&self.held).push((id, event));
    }

    pub fn draining(&self) -> bool {
        self.draining.load(Ordering::SeqCst)
    }

    pub fn set_draining(&self) {
        self.draining.store(true, Ordering::SeqCst);
    }

    /// Asks one attempt to stop; false when it is not running here.
    pub fn cancel(&self, id: &AttemptId) -> bool {
        match lock(&self.in_flight).get(id) {
            Some(flag) => {
                flag.store(true, Ordering::SeqCst);
                true
            }
            None => false,
        }
    }

    /// Asks every running attempt to stop (drain timeout); returns how many.
    pub fn cancel_all(&self) -> usize {
        let map = lock(&self.in_flight);
        for flag in map.values() {
            flag.store(true, Ordering::SeqCst);
        }
        map.len()
    }

    /// Waits until no task runs, at most `timeout`; true when idle.
    pub async fn wait_idle(&self, timeout: Duration) -> bool {
        let deadline = tokio::time::Instant::now() + timeout;
        loop {
            let notified = self.idle.notified();
            if self.running() == 0 {
                return true;
            }
            if tokio::time::timeout_at(deadline, notified).await.is_err() {
                return self.running() == 0;
            }
        }
    }

    /// Starts one attempt; its events (progress, then one result or failure with the attempt's log tail) go
    /// to `tx`, or are held when `tx` has closed. Log events inside the attempt's span are captured into that
    /// tail. `slot` is the attempt's share of the worker's capacity, freed just before its final event.
    pub fn start(self: &Arc<Self>, task: pb::Task, tx: Sender, slot: OwnedSemaphorePermit) {
        let id: AttemptId = (task.job_id.clone(), task.task_key.clone(), task.attempt);
        let cancel = Arc::new(AtomicBool::new(false));
        lock(&self.in_flight).insert(id.clone(), Arc::clone(&cancel));
        let this = Arc::clone(self);
        let tail = Arc::new(LogTail::default());
        let span = tracing::info_span!(
            crease_telemetry::tail::TASK_SPAN,
            job_id = %task.job_id,
            task = %task.task_key,
            attempt = task.attempt
        );
        let capture = crease_telemetry::tail::capture(&span, Arc::clone(&tail));
        let fut = async move {
            let (job_id, key, attempt) = (&task.job_id, &task.task_key, task.attempt);
            info!(job_id = %job_id, task = %key, attempt, kind = %task.kind, "task started");
            let started = Instant::now();
            let progress = Arc::new(StreamProgress {
                tx: tx.clone(),
                cancel: Arc::clone(&cancel),
                last_sent: Mutex::new(HashMap::new()),
                tail: Arc::clone(&tail),
            });
            let result = run_one(&task, &this.cache_dir, progress).await;
            let secs = started.elapsed().as_secs_f64();
            let (event, outcome) = match result {
                Ok(output) => {
                    info!(job_id = %job_id, task = %key, attempt, seconds = secs, "task done in {secs:.2}s");
                    let ev = pb::task_event::Event::Result(pb::TaskResult {
                        output: serde_json::to_vec(&output).unwrap_or_default(),
                    });
                    (ev, "done")
                }
                Err(e) => {
                    let cancelled = e.is_cancelled();
                    if cancelled {
                        info!(job_id = %job_id, task = %key, attempt, "task stopped: {}", e.reason);
                    } else {
                        warn!(
                            job_id = %job_id,
                            task = %key,
                            attempt,
                            kind = %e.kind,
                            "task failed: {}",
                            e.reason
                        );
                    }
                    let ev = pb::task_event::Event::Failure(pb::TaskFailure {
                        retryable: e.retryable(),
                        cancelled,
                        reason: e.reason,
                        kind: e.kind.as_str().to_string(),
                    });
                    (ev, if cancelled { "cancelled" } else { "failed" })
                }
            };
            this.metrics.task_finished(&task.kind, outcome, secs);
            drop(capture);
            drop(slot);
            let last = pb::TaskEvent {
                event: Some(event),
                log_tail: tail.lines(),
            };
            if let Err(unsent) = tx.send(Ok(last)) {
                if let Ok(last) = unsent.0 {
                    info!(
                        job_id = %job_id,
                        task = %key,
                        attempt,
                        "the coordinator stopped listening; holding the attempt's end ({outcome}) until it is back"
                    );
                    this.hold(id.clone(), last);
                }
            }
            lock(&this.in_flight).remove(&id);
            this.idle.notify_waiters();
        };
        tokio::spawn(fut.instrument(span));
    }
}

async fn run_one(
    task: &pb::Task,
    cache_dir: &std::path::Path,
    progress: Arc<StreamProgress>,
) -> Result<crease_jobs::TaskOutput, TaskError> {
    let spec = TaskSpec::from_payload(&task.kind, &task.payload)
        .map_err(|e| TaskError::fatal(format!("task `{}`: {}", task.task_key, e.reason)))?;
    if let Some(ms) = test_delay(&task.kind) {
        let end = Instant::now() + Duration::from_millis(ms);
        while Instant::now() < end {
            if progress.cancelled() {
                return Err(TaskError::cancelled());
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    }
    let ctx = ExecContext {
        progress: progress.clone(),
        cache_dir: cache_dir.to_path_buf(),
    };
    let out = crease_jobs::execute(&spec, &ctx).await;
    // A task that finished after it was told to stop still reports its result: outputs are deterministic, so
    // a completed task is as good as any other run of it.
    out.map_err(|mut e| {
        if !e.is_cancelled() && !e.reason.contains(&task.task_key) {
            e.reason = format!("task `{}`: {}", task.task_key, e.reason);
        }
        e
    })
}

/// The `CREASE_TEST_TASK_DELAY` hook (see the crate docs).
fn test_delay(kind: &str) -> Option<u64> {
    let v = std::env::var("CREASE_TEST_TASK_DELAY").ok()?;
    v.split(',').find_map(|part| {
        let (k, ms) = part.split_once('=')?;
        (k.trim() == kind || k.trim() == "*")
            .then(|| ms.trim().parse().ok())
            .flatten()
    })
}

/// Progress of one task as stream events, at most ten per second per stage; `cancelled()` is true once the
/// task was cancelled (a coordinator that stopped listening does not cancel it: see the module docs).
struct StreamProgress {
    tx: Sender,
    cancel: Arc<AtomicBool>,
    last_sent: Mutex<HashMap<String, (Instant, u64, u64)>>,
    /// Stage starts and ends and notes also go to the attempt's log tail (throttled progress does not).
    tail: Arc<LogTail>,
}

impl StreamProgress {
    fn send(&self, stage: &str, done: u64, total: u64, note: &str) {
        let _ = self.tx.send(Ok(pb::TaskEvent {
            event: Some(pb::task_event::Event::Progress(pb::TaskProgress {
                stage: stage.to_string(),
                done,
                total,
                note: note.to_string(),
            })),
            log_tail: Vec::new(),
        }));
    }
}

impl Progress for StreamProgress {
    fn begin(&self, stage: &str, total: u64) {
        lock(&self.last_sent).insert(stage.to_string(), (Instant::now(), 0, total));
        self.tail
            .record("INFO", &format!("stage `{stage}` started ({total} units)"));
        self.send(stage, 0, total, "");
    }

    fn advance(&self, stage: &str, n: u64) {
        let mut map = lock(&self.last_sent);
        let entry = map
            .entry(stage.to_string())
            .or_insert((Instant::now(), 0, 0));
        entry.1 += n;
        let finished = entry.2 > 0 && entry.1 >= entry.2;
        if finished || entry.0.elapsed() >= Duration::from_millis(100) {
            entry.0 = Instant::now();
            let (done, total) = (entry.1, entry.2);
            drop(map);
            if finished {
                self.tail
                    .record("INFO", &format!("stage `{stage}` done ({done}/{total})"));
            }
            self.send(stage, done, total, "");
        }
    }

    fn note(&self, msg: &str) {
        self.tail.record("INFO", msg);
        self.send("note", 0, 0, msg);
    }

    fn cancelled(&self) -> bool {
        self.cancel.load(Ordering::SeqCst)
    }
}

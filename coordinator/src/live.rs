//! The latest progress of each running task, as its worker streams it, so that `crease status` can show what
//! a long task (a whole-sequence fold detection) is doing and on which worker. Kept in memory only: it is stale
//! the moment the task ends, and after a coordinator restart the next progress event fills it again.

use crease_proto as pb;
use std::collections::HashMap;
use std::sync::Mutex;

/// (job, task key) → (stage, done, total).
type Table = HashMap<(String, String), (String, u64, u64)>;

#[derive(Default)]
pub struct LiveProgress {
    tasks: Mutex<Table>,
}

impl LiveProgress {
    fn lock(&self) -> std::sync::MutexGuard<'_, Table> {
        self.tasks.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Follows the scheduler's events: progress is recorded, and forgotten when the task or the job ends.
    pub fn observe(&self, ev: &pb::JobEvent) {
        match ev.kind.as_str() {
            "task_progress" if ev.total > 0 => {
                self.lock().insert(
                    (ev.job_id.clone(), ev.task_key.clone()),
                    (ev.message.clone(), ev.done, ev.total),
                );
            }
            "task_done" | "task_retry" | "task_started" => {
                self.lock()
                    .remove(&(ev.job_id.clone(), ev.task_key.clone()));
            }
            "job_done" | "job_failed" | "job_cancelled" => {
                self.lock().retain(|(job, _), _| *job != ev.job_id);
            }
            _ => {}
        }
    }

    /// Fills `status.running` from its task rows (state `running`) and the recorded progress.
    pub fn fill(&self, status: &mut pb::JobStatus) {
        let tasks = self.lock();
        status.running = status
            .tasks
            .iter()
            .filter(|t| t.state == "running")
            .map(|t| {
                let (stage, done, total) = tasks
                    .get(&(status.job_id.clone(), t.key.clone()))
                    .cloned()
                    .unwrap_or_default();
                pb::RunningTask {
                    key: t.key.clone(),
                    kind: t.kind.clone(),
                    worker: t.worker.clone(),
                    stage,
                    done,
                    total,
                }
            })
            .collect();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ev(kind: &str, key: &str, msg: &str, done: u64, total: u64) -> pb::JobEvent {
        pb::JobEvent {
            job_id: "job-1".into(),
            kind: kind.into(),
            task_key: key.into(),
            message: msg.into(),
            done,
            total,
            status: None,
        }
    }

    #[test]
    fn running_tasks_carry_their_latest_progress_until_they_end() {
        let live = LiveProgress::default();
        live.observe(&ev(
            "task_progress",
            "folds/f000000",
            "stretch folds",
            3,
            12,
        ));
        live.observe(&ev(
            "task_progress",
            "folds/f000000",
            "stretch folds",
            7,
            12,
        ));
        let row = |key: &str, state: &str| pb::TaskRow {
            key: key.into(),
            kind: "fold-detect".into(),
            state: state.into(),
            worker: "w1".into(),
            ..Default::default()
        };
        let mut s = pb::JobStatus {
            job_id: "job-1".into(),
            tasks: vec![row("folds/f000000", "running"), row("finalize", "queued")],
            ..Default::default()
        };
        live.fill(&mut s);
        assert_eq!(s.running.len(), 1);
        let r = &s.running[0];
        assert_eq!((r.key.as_str(), r.worker.as_str()), ("folds/f000000", "w1"));
        assert_eq!(
            (r.stage.as_str(), r.done, r.total),
            ("stretch folds", 7, 12)
        );
        live.observe(&ev("task_done", "folds/f000000", "", 1, 2));
        live.fill(&mut s);
        assert_eq!((s.running[0].done, s.running[0].total), (0, 0));
    }
}

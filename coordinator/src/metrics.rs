//! The coordinator's Prometheus metrics. Gauges (queue depth, running tasks, workers, jobs) are read from the
//! queue and the worker registry at scrape time, so they can never drift from the state they describe;
//! counters and the duration histogram are updated on task transitions.

use crate::state::store::QueueGauges;
use prometheus_client::metrics::counter::Counter;
use prometheus_client::metrics::family::Family;
use prometheus_client::metrics::gauge::Gauge;
use prometheus_client::metrics::histogram::{exponential_buckets, Histogram};
use prometheus_client::registry::Registry;

type Labels = Vec<(String, String)>;

/// Job states exported even when no job is in them (so a dashboard sees 0, not a missing series).
const JOB_STATES: [&str; 6] = [
    "queued",
    "running",
    "waiting",
    "done",
    "failed",
    "cancelled",
];

/// Task durations span tens of milliseconds (a preview) to many minutes (a weight window on a real mesh).
pub fn duration_histogram() -> Histogram {
    Histogram::new(exponential_buckets(0.01, 2.5, 14))
}

/// What the scheduler reads at scrape time.
#[derive(Debug, Clone, Default)]
pub struct Snapshot {
    pub queue: QueueGauges,
    pub workers_live: i64,
    pub workers_draining: i64,
    /// Per active job: how many workers it excludes.
    pub blocklisted: Vec<(String, i64)>,
}

pub struct CoordinatorMetrics {
    registry: Registry,
    queue_depth: Gauge,
    tasks_running: Gauge,
    workers: Family<Labels, Gauge>,
    jobs: Family<Labels, Gauge>,
    blocklisted: Family<Labels, Gauge>,
    task_duration: Family<Labels, Histogram, fn() -> Histogram>,
    retries: Counter,
    failures: Counter,
}

impl Default for CoordinatorMetrics {
    fn default() -> Self {
        let mut registry = Registry::default();
        let queue_depth = Gauge::default();
        let tasks_running = Gauge::default();
        let workers = Family::<Labels, Gauge>::default();
        let jobs = Family::<Labels, Gauge>::default();
        let blocklisted = Family::<Labels, Gauge>::default();
        let task_duration = Family::<Labels, Histogram, fn() -> Histogram>::new_with_constructor(
            duration_histogram,
        );
        let retries = Counter::default();
        let failures = Counter::default();
        registry.register(
            "crease_queue_depth",
            "Tasks queued and runnable now (dependencies done, retry backoff over)",
            queue_depth.clone(),
        );
        registry.register(
            "crease_tasks_running",
            "Task attempts running on workers",
            tasks_running.clone(),
        );
        registry.register(
            "crease_workers",
            "Registered workers by state (live takes work, draining finishes its tasks)",
            workers.clone(),
        );
        registry.register("crease_jobs", "Jobs by state", jobs.clone());
        registry.register(
            "crease_job_blocklisted_workers",
            "Workers an active job gives no more tasks to (--blacklist-after failures there), by job",
            blocklisted.clone(),
        );
        registry.register(
            "crease_task_duration_seconds",
            "Wall time of successful task attempts, dispatch to result, by task kind",
            task_duration.clone(),
        );
        registry.register(
            "crease_task_retries",
            "Task attempts that failed or were handed back and were queued again",
            retries.clone(),
        );
        registry.register(
            "crease_task_failures",
            "Task attempts that failed (not counting hand-backs, cancellations and restarts)",
            failures.clone(),
        );
        CoordinatorMetrics {
            registry,
            queue_depth,
            tasks_running,
            workers,
            jobs,
            blocklisted,
            task_duration,
            retries,
            failures,
        }
    }
}

fn label(k: &str, v: &str) -> Labels {
    vec![(k.to_string(), v.to_string())]
}

impl CoordinatorMetrics {
    /// A task attempt succeeded after `seconds` of wall time.
    pub fn task_done(&self, kind: &str, seconds: f64) {
        self.task_duration
            .get_or_create(&label("kind", kind))
            .observe(seconds);
    }

    pub fn retry(&self) {
        self.retries.inc();
    }

    pub fn failure(&self) {
        self.failures.inc();
    }

    /// Sets the gauges from `s` and encodes every metric (OpenMetrics text).
    pub fn render(&self, s: &Snapshot) -> String {
        self.queue_depth.set(s.queue.queue_depth);
        self.tasks_running.set(s.queue.tasks_running);
        self.workers
            .get_or_create(&label("state", "live"))
            .set(s.workers_live);
        self.workers
            .get_or_create(&label("state", "draining"))
            .set(s.workers_draining);
        for state in JOB_STATES {
            let n = s
                .queue
                .jobs
                .iter()
                .find(|(k, _)| k == state)
                .map_or(0, |(_, n)| *n);
            self.jobs.get_or_create(&label("state", state)).set(n);
        }
        // Only jobs still running have a series: an ended job's blocklist no longer means anything.
        self.blocklisted.clear();
        for (job, n) in &s.blocklisted {
            self.blocklisted.get_or_create(&label("job", job)).set(*n);
        }
        crease_telemetry::render(&self.registry)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gauges_come_from_the_snapshot_and_every_job_state_is_exported() {
        let m = CoordinatorMetrics::default();
        m.task_done("position", 0.5);
        m.task_done("position", 2.0);
        m.retry();
        m.failure();
        let text = m.render(&Snapshot {
            queue: QueueGauges {
                queue_depth: 7,
                tasks_running: 3,
                jobs: vec![("running".into(), 2)],
            },
            workers_live: 2,
            workers_draining: 1,
            blocklisted: vec![("job-00007".into(), 1)],
        });
        for line in [
            "crease_queue_depth 7",
            "crease_tasks_running 3",
            "crease_workers{state=\"live\"} 2",
            "crease_workers{state=\"draining\"} 1",
            "crease_jobs{state=\"running\"} 2",
            "crease_jobs{state=\"cancelled\"} 0",
            "crease_task_duration_seconds_count{kind=\"position\"} 2",
            "crease_task_retries_total 1",
            "crease_task_failures_total 1",
            "crease_job_blocklisted_workers{job=\"job-00007\"} 1",
        ] {
            assert!(text.lines().any(|l| l == line), "no `{line}` in\n{text}");
        }
        // A later scrape reflects the state then, not a running total.
        let text = m.render(&Snapshot::default());
        assert!(text.lines().any(|l| l == "crease_queue_depth 0"), "{text}");
        assert!(
            text.lines()
                .any(|l| l == "crease_jobs{state=\"running\"} 0"),
            "{text}"
        );
    }
}

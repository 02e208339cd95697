//! What a worker shows the farm's monitoring: Prometheus metrics about the tasks it ran, and its readiness
//! (registered with the coordinator and not draining) for the Kubernetes probe.

use prometheus_client::metrics::counter::Counter;
use prometheus_client::metrics::family::Family;
use prometheus_client::metrics::gauge::Gauge;
use prometheus_client::metrics::histogram::{exponential_buckets, Histogram};
use prometheus_client::registry::Registry;
use std::sync::atomic::{AtomicBool, Ordering};

type Labels = Vec<(String, String)>;

/// Same buckets as the coordinator's task histogram, so the two can be compared.
fn duration_histogram() -> Histogram {
    Histogram::new(exponential_buckets(0.01, 2.5, 14))
}

pub struct WorkerMetrics {
    registry: Registry,
    running: Gauge,
    tasks: Family<Labels, Counter>,
    duration: Family<Labels, Histogram, fn() -> Histogram>,
    registered: AtomicBool,
}

impl WorkerMetrics {
    pub fn new(capacity: u32) -> Self {
        let mut registry = Registry::default();
        let running = Gauge::default();
        let cap: Gauge = Gauge::default();
        cap.set(i64::from(capacity));
        let tasks = Family::<Labels, Counter>::default();
        let duration = Family::<Labels, Histogram, fn() -> Histogram>::new_with_constructor(
            duration_histogram,
        );
        registry.register(
            "crease_worker_tasks_running",
            "Tasks running on this worker",
            running.clone(),
        );
        registry.register(
            "crease_worker_capacity",
            "Tasks this worker runs at the same time",
            cap,
        );
        registry.register(
            "crease_worker_tasks",
            "Task attempts this worker finished, by kind and outcome (done, failed, cancelled)",
            tasks.clone(),
        );
        registry.register(
            "crease_worker_task_duration_seconds",
            "Time this worker spent on task attempts, by kind",
            duration.clone(),
        );
        WorkerMetrics {
            registry,
            running,
            tasks,
            duration,
            registered: AtomicBool::new(false),
        }
    }

    /// One attempt ended with `outcome` after `seconds`.
    pub fn task_finished(&self, kind: &str, outcome: &str, seconds: f64) {
        self.tasks
            .get_or_create(&vec![
                ("kind".to_string(), kind.to_string()),
                ("outcome".to_string(), outcome.to_string()),
            ])
            .inc();
        self.duration
            .get_or_create(&vec![("kind".to_string(), kind.to_string())])
            .observe(seconds);
    }

    /// Whether the coordinator currently knows this worker.
    pub fn set_registered(&self, yes: bool) {
        self.registered.store(yes, Ordering::SeqCst);
    }

    pub fn registered(&self) -> bool {
        self.registered.load(Ordering::SeqCst)
    }

    /// Encodes every metric (OpenMetrics text) with `running` tasks in flight now.
    pub fn render(&self, running: usize) -> String {
        self.running.set(running as i64);
        crease_telemetry::render(&self.registry)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_attempts_by_kind_and_outcome_and_reports_readiness() {
        let m = WorkerMetrics::new(4);
        assert!(!m.registered());
        m.set_registered(true);
        assert!(m.registered());
        m.task_finished("position", "done", 0.2);
        m.task_finished("position", "done", 0.3);
        m.task_finished("position", "failed", 0.1);
        let text = m.render(2);
        for line in [
            "crease_worker_tasks_running 2",
            "crease_worker_capacity 4",
            "crease_worker_tasks_total{kind=\"position\",outcome=\"done\"} 2",
            "crease_worker_tasks_total{kind=\"position\",outcome=\"failed\"} 1",
            "crease_worker_task_duration_seconds_count{kind=\"position\"} 3",
        ] {
            assert!(text.lines().any(|l| l == line), "no `{line}` in\n{text}");
        }
    }
}

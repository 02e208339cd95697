//! What the coordinator and the workers share to be observed on a farm: the small HTTP server for
//! Prometheus scrapes and Kubernetes probes ([`http`]) and the bounded per-task log tail that a worker
//! sends back with a task's result ([`tail`]). Kept out of crease-core, which knows nothing of processes.

pub mod http;
pub mod tail;

/// A registry as OpenMetrics text, the body of `GET /metrics`. Encoding into a `String` cannot fail on I/O; a
/// failure would be a metric that cannot be written, so the scrape says so instead of serving half a page.
pub fn render(registry: &prometheus_client::registry::Registry) -> String {
    let mut out = String::new();
    if prometheus_client::encoding::text::encode(&mut out, registry).is_err() {
        out = "# metrics could not be encoded\n".to_string();
    }
    out
}

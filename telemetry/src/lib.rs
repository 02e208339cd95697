//! What the coordinator and the workers share to be observed on a farm: the small HTTP server for
//! Prometheus scrapes and Kubernetes probes ([`http`]) and the bounded per-task log tail that a worker
//! sends back with a task's result ([`tail`]). Kept out of crease-core, which knows nothing of processes.

pub mod http;
pub mod tail;

//! gRPC protocol of the crease cluster, generated from `proto/crease.proto` at build time with protox
//! (no system protoc).

/// Bumped on every incompatible change of `crease.proto` or of the task payloads it carries; the
/// coordinator refuses workers that speak another version.
pub const PROTOCOL_VERSION: u32 = 1;

#[allow(clippy::all, clippy::pedantic)]
mod generated {
    tonic::include_proto!("crease.v1");
}

pub use generated::*;
pub use generated::{coordinator_client, coordinator_server, worker_client, worker_server};

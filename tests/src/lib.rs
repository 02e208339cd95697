//! The one process-helper kit of crease's end-to-end tests and of the soak harness (`crease-soak`): they start
//! real coordinators and workers on 127.0.0.1, so every child is killed when its handle drops and every wait
//! has a deadline, and a broken build fails instead of hanging.
//!
//! The tests live in this crate (not in `cli/`) because they exercise the whole cluster, not the CLI package;
//! the `crease` executable they drive is found (and brought up to date) by [`binary`].

pub mod binary;
pub mod cluster;
pub mod http;
pub mod outputs;
pub mod process;
pub mod tools;

pub use binary::bin;
pub use cluster::Coordinator;
pub use http::{get, http_get, metrics_addr};
pub use outputs::*;
pub use process::*;

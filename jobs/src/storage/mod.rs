//! Storage: where a job's input, intermediates and outputs live, and how they are read and written.
//!
//! - [`location`] — a URI as a local path or a remote location, and the object store serving it;
//! - [`store`] — [`Storage`], a directory-like root addressed by keys, with atomic puts, and the worker's
//!   cache of remote inputs;
//! - [`keys`] — the deterministic names of tasks and of everything they write;
//! - [`confine`] — keeping a job inside the storage its coordinator was given;
//! - [`errors`] — telling a full or unreachable store from other failures;
//! - [`s3`] — S3-compatible stores configured from the `AWS_*` environment.

pub mod confine;
pub mod errors;
pub mod keys;
pub mod location;
pub mod s3;
pub mod store;

pub use location::{parse_location, register_store, remote_store, Location};
pub use store::{fetch_input_to_cache, input_size, Storage};

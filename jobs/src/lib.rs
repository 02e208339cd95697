//! crease-jobs: job specs, planning (job → task graph), storage and task execution on top of crease-core.
//!
//! This crate holds everything about a job that does not depend on the transport: the coordinator calls
//! [`inspect_input`] at submit, [`plan`] / [`expand`] to build the task graph and [`final_outputs`] before marking
//! a job done; workers call [`execute`]. No gRPC here, so the same code runs in-process in tests.

pub mod detect;
pub mod error;
pub mod execute;
pub mod inspect;
pub mod keys;
pub mod plan;
pub mod spec;
pub mod storage;
pub mod task;

pub use error::{JobError, TaskError};
pub use execute::{execute, ExecContext};
pub use inspect::{inspect_input, InputInfo};
pub use plan::{expand, final_outputs, plan};
pub use spec::{FoldSpec, JobSpec, Partition, PreviewOptions};
pub use storage::{fetch_input_to_cache, Storage};
pub use task::{TaskDef, TaskOutput, TaskSpec};

//! Running one task on a worker: fetch what it needs from storage, run crease-core on a blocking thread, write
//! its results under deterministic keys.

use crate::error::TaskError;
use crate::task::{TaskOutput, TaskSpec};
use crease_core::progress::Progress;
use std::path::PathBuf;
use std::sync::Arc;

/// What a worker provides to every task.
#[derive(Clone)]
pub struct ExecContext {
    /// Progress of the task; `cancelled()` returning true stops the task with [`TaskError::cancelled`].
    pub progress: Arc<dyn Progress + Send + Sync>,
    /// Local directory where remote inputs are cached between tasks.
    pub cache_dir: PathBuf,
}

/// Executes `task`. Deterministic: what it writes depends only on the task, not on the worker or the attempt.
pub async fn execute(task: &TaskSpec, ctx: &ExecContext) -> Result<TaskOutput, TaskError> {
    let _ = (task, ctx);
    Err(TaskError::fatal("not implemented yet"))
}

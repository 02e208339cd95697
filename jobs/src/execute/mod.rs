//! Running one task on a worker: crease-core on a blocking thread, inputs and results through storage.
//!
//! Each task kind has its own module named after what it computes: `folds` (detection and merge), `frame_cache` (parsed input frames kept per process), `settle`
//! (temporal coherence of a frame range), `weights` (a fused window, an anchor block, the reduce of a window),
//! `relief` (the fold relief of captured frames), `position` (cross-fade, positioning, stretch passes and
//! shape ending of a frame chunk), `finalize` (output sequence, previews, report). They share
//! `env::TaskEnv`: the job's storage, input and anchors, opened the same way by every task.
//!
//! Determinism: a task reads only what its dependencies wrote under deterministic keys and calls the
//! [`crease_core::spacetime::stages`] functions in a fixed order, so what it writes does not depend on the
//! worker, the number of workers, or how many times it ran.

mod capture_trace;
#[cfg(feature = "deep")]
mod deep;
mod env;
mod exact;
mod export;
mod finalize;
mod fold_chunks;
mod folds;
pub mod frame_cache;
mod partial_file;
pub mod phase_times;
mod position;
mod relief;
mod settle;
mod stretch;
mod weights;
pub mod window_cache;

use crate::error::TaskError;
use crate::failure::FailureKind;
use crate::plan::task::{TaskOutput, TaskSpec};
use crease_core::progress::Progress;
use env::TaskEnv;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

/// The refusal of a deep task by a worker built without the learning stack: the same on every such worker,
/// so it is not retried; the job fails with the way to a worker that runs it.
#[cfg(not(feature = "deep"))]
fn without_deep(task: &TaskSpec) -> TaskError {
    TaskError::new(
        FailureKind::InvalidInput,
        format!(
            "{}: this worker was built without DeepWrinkles (the `deep` feature); run deep jobs on workers \
             built with `cargo build --release --features deep`",
            task.kind()
        ),
    )
}

/// What a worker provides to every task.
#[derive(Clone)]
pub struct ExecContext {
    /// Progress of the task; `cancelled()` returning true stops the task with [`TaskError::cancelled`].
    pub progress: Arc<dyn Progress + Send + Sync>,
    /// Local directory where remote inputs are cached between tasks (and finalize stages remote outputs).
    pub cache_dir: PathBuf,
}

/// Executes `task` on a blocking thread of the current tokio runtime. Deterministic: what it writes depends only
/// on the task, not on the worker or the attempt.
pub async fn execute(task: &TaskSpec, ctx: &ExecContext) -> Result<TaskOutput, TaskError> {
    let task = task.clone();
    let ctx = ctx.clone();
    let handle = tokio::runtime::Handle::current();
    let kind = task.kind();
    tokio::task::spawn_blocking(move || run(&task, &ctx, handle))
        .await
        .map_err(|e| TaskError::fatal(format!("{kind} task panicked: {e}")))?
}

fn run(
    task: &TaskSpec,
    ctx: &ExecContext,
    handle: tokio::runtime::Handle,
) -> Result<TaskOutput, TaskError> {
    if ctx.progress.cancelled() {
        return Err(TaskError::cancelled());
    }
    let clock = Instant::now();
    run_kind(task, ctx, handle, clock).map_err(|e| local_full_is_retryable(e, ctx))
}

/// Full storage fails a job at once, except the worker's own disk (cache, staging): another worker may have
/// room, so that failure is retryable (and the coordinator moves the task elsewhere).
fn local_full_is_retryable(mut e: TaskError, ctx: &ExecContext) -> TaskError {
    let in_cache = e
        .location
        .as_deref()
        .is_some_and(|at| std::path::Path::new(at).starts_with(&ctx.cache_dir));
    if e.kind == FailureKind::StorageFullRemote && in_cache {
        e.kind = FailureKind::StorageFullLocal;
    }
    e
}

fn run_kind(
    task: &TaskSpec,
    ctx: &ExecContext,
    handle: tokio::runtime::Handle,
    clock: Instant,
) -> Result<TaskOutput, TaskError> {
    let env = TaskEnv::new(task.job(), ctx, handle)?;
    let (summary, written) = match task {
        TaskSpec::FoldDetect { frames, .. } => folds::detect(&env, frames.clone())?,
        TaskSpec::FoldSteps { frames, .. } => stretch::steps(&env, frames.clone())?,
        TaskSpec::FoldPhases { .. } => stretch::phases(&env)?,
        TaskSpec::FoldSettle { frames, .. } => settle::settle(&env, frames.clone())?,
        TaskSpec::FoldMerge { .. } => folds::merge(&env)?,
        TaskSpec::FoldFiles { .. } => folds::files(&env)?,
        TaskSpec::FoldPlot { .. } => stretch::plot(&env)?,
        TaskSpec::WeightWindow { window, .. } => weights::fused_window(&env, *window)?,
        TaskSpec::WeightBlock { window, block, .. } => {
            weights::anchor_block(&env, *window, *block)?
        }
        TaskSpec::Reduce { window, .. } => weights::reduce(&env, *window)?,
        TaskSpec::Relief { frames, .. } => relief::relief(&env, frames.clone())?,
        TaskSpec::Position { frames, .. } => position::position(&env, frames.clone())?,
        TaskSpec::Finalize { .. } => finalize::finalize(&env)?,
        #[cfg(feature = "deep")]
        TaskSpec::DeepTrain { .. } => deep::train(&env)?,
        #[cfg(feature = "deep")]
        TaskSpec::DeepApply { frames, .. } => deep::apply(&env, frames.clone())?,
        #[cfg(feature = "deep")]
        TaskSpec::DeepFinish { frames, .. } => deep::finish(&env, *frames)?,
        #[cfg(not(feature = "deep"))]
        TaskSpec::DeepTrain { .. } | TaskSpec::DeepApply { .. } | TaskSpec::DeepFinish { .. } => {
            return Err(without_deep(task));
        }
    };
    Ok(TaskOutput {
        summary,
        work_seconds: clock.elapsed().as_secs_f64(),
        written,
    })
}

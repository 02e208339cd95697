//! One task of a job, run on a farm node with no coordinator: `crease task run --job job.toml --task KEY`.
//!
//! The task is looked up in the planner's own graph (re-planned from the job file and the input, which is
//! deterministic), so a farm runs exactly the tasks a coordinator would, and they write the same keys. Tasks
//! after fold detection are found by expanding the graph with the anchors `fold-merge` stored; a block slot
//! (see [`super::graph`]) runs the blocks it stands for, in order.

use super::graph::{farm_graph, parse_slot_key, Stage};
use crate::error::{JobError, TaskError};
use crate::execute::{execute, ExecContext};
use crate::plan::graph::{expand, plan};
use crate::plan::input::InputInfo;
use crate::plan::inspect::inspect_input;
use crate::plan::task::{TaskDef, TaskOutput, TaskSpec};
use crate::spec::JobSpec;
use crate::storage::keys;
use crate::storage::store::Storage;
use crease_core::folds::AnchorSet;
use serde_json::json;

/// Which task to run: a key of the graph, or the `index`-th task of a stage.
#[derive(Debug, Clone, PartialEq)]
pub enum TaskRef {
    Key(String),
    Index {
        stage: String,
        index: usize,
        block_slots: usize,
    },
}

/// What running one farm task did: the planner tasks it ran, with their outputs.
#[derive(Debug)]
pub struct FarmRun {
    pub key: String,
    pub ran: Vec<(String, TaskOutput)>,
}

/// Why a farm task failed: bad job or key (do not retry), or the task's own error (retry when it says so).
#[derive(Debug, thiserror::Error)]
pub enum FarmRunError {
    #[error("{0}")]
    Job(#[from] JobError),
    #[error("task `{key}`: {error}")]
    Task { key: String, error: TaskError },
}

impl FarmRunError {
    /// Whether the farm should retry: storage or I/O trouble, never a bad job, key or input data.
    pub fn retryable(&self) -> bool {
        match self {
            // A key that is not in the graph or a bad job file fails the same way on every attempt.
            FarmRunError::Job(JobError::Plan(_) | JobError::Spec { .. }) => false,
            FarmRunError::Job(e) => TaskError::from_job(e).retryable(),
            FarmRunError::Task { error, .. } => error.retryable(),
        }
    }
}

/// Resolves `task` in `job`'s graph and runs it (and only it) against the job's storage.
pub async fn run_farm_task(
    job: &JobSpec,
    task: &TaskRef,
    ctx: &ExecContext,
) -> Result<FarmRun, FarmRunError> {
    let info = inspect_input(job).await?;
    let key = match task {
        TaskRef::Key(k) => k.clone(),
        TaskRef::Index {
            stage,
            index,
            block_slots,
        } => {
            let st = Stage::parse(stage).ok_or_else(|| {
                JobError::Plan(format!(
                    "unknown stage `{stage}`; expected one of fold-steps, fold-phases, fold-detect, \
                     fold-settle, fold-merge, fold-files, fold-plot, relief, weights, reduce, position, finalize"
                ))
            })?;
            farm_graph(job, &info, *block_slots)?
                .task_at(st, *index)?
                .key
                .clone()
        }
    };
    let specs = resolve(job, &info, &key).await?;
    let mut ran = Vec::with_capacity(specs.len());
    for def in specs {
        let out = execute(&def.spec, ctx)
            .await
            .map_err(|error| FarmRunError::Task {
                key: def.key.clone(),
                error,
            })?;
        ran.push((def.key, out));
    }
    Ok(FarmRun { key, ran })
}

/// The planner tasks farm task `key` stands for (one, or a slot's blocks: possibly none).
pub async fn resolve(job: &JobSpec, info: &InputInfo, key: &str) -> Result<Vec<TaskDef>, JobError> {
    let initial = plan(job, info)?;
    if let Some(t) = initial.iter().find(|t| t.key == key) {
        return Ok(vec![t.clone()]);
    }
    let Some(merge) = initial.iter().find(|t| t.expands) else {
        return Err(unknown_key(key, &initial));
    };
    // After detection: the graph as the coordinator would expand it, from the anchors fold-merge stored.
    let counts = detected_counts(job, info).await.map_err(|e| {
        JobError::Plan(format!(
            "task `{key}` comes after fold detection, but the detected anchors cannot be read (has `{}` run?): {e}",
            merge.key
        ))
    })?;
    let out = TaskOutput {
        summary: json!({ "anchors_per_frame": counts }),
        ..Default::default()
    };
    let rest = expand(job, info, &merge.key, &out)?;
    if let Some(t) = rest.iter().find(|t| t.key == key) {
        return Ok(vec![t.clone()]);
    }
    if let Some((window, slot, slots)) = parse_slot_key(key) {
        let blocks: Vec<TaskDef> = rest
            .iter()
            .filter(|t| {
                matches!(t.spec, TaskSpec::WeightBlock { window: w, block, .. }
                    if w == window && block % slots == slot)
            })
            .cloned()
            .collect();
        if blocks.is_empty() && !rest.iter().any(|t| t.key == keys::reduce_task(window)) {
            return Err(JobError::Plan(format!(
                "task `{key}`: window {window} does not exist or is not a per-anchor window"
            )));
        }
        return Ok(blocks);
    }
    let mut all = initial;
    all.extend(rest);
    Err(unknown_key(key, &all))
}

fn unknown_key(key: &str, tasks: &[TaskDef]) -> JobError {
    let shown: Vec<&str> = tasks.iter().take(6).map(|t| t.key.as_str()).collect();
    JobError::Plan(format!(
        "task `{key}` is not in this job's graph ({} tasks: {}{}); `crease export-job` lists them",
        tasks.len(),
        shown.join(", "),
        if tasks.len() > shown.len() {
            ", …"
        } else {
            ""
        }
    ))
}

/// Anchors per frame from the detected anchors that `fold-merge` stored, read as the weight tasks read them.
async fn detected_counts(job: &JobSpec, info: &InputInfo) -> Result<Vec<usize>, JobError> {
    let out = Storage::open(&job.output)?;
    let bytes = out.get(keys::ANCHORS_BIN).await?;
    let label = std::path::PathBuf::from(out.describe(keys::ANCHORS_BIN));
    let set = AnchorSet::from_binary(&bytes, &label, info.n_frames, info.n_triangles)
        .map_err(|e| JobError::storage(out.describe(keys::ANCHORS_BIN), e))?;
    Ok((0..info.n_frames).map(|t| set.frame(t).len()).collect())
}

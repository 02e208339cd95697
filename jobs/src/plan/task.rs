//! Tasks: the self-contained units the coordinator schedules and workers execute.
//!
//! A [`TaskSpec`] carries everything a worker needs (the job spec with its URIs and parameters, and the
//! window, block or frame range), so a worker keeps no state between tasks and any worker can run any task.
//! Over gRPC a task travels as its [`TaskSpec::kind`] plus [`TaskSpec::to_payload`] (JSON).

use crate::error::TaskError;
use crate::spec::JobSpec;
use serde::{Deserialize, Serialize};
use std::ops::Range;

/// One unit of work of a job.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum TaskSpec {
    /// Detect the folds of `frames` (per-frame detectors: one task per chunk; whole-sequence detectors: one
    /// task over all frames).
    FoldDetect { job: JobSpec, frames: Range<usize> },
    /// Stretch detector: the step records of `frames` (both directions of time), before the phase test.
    FoldSteps { job: JobSpec, frames: Range<usize> },
    /// Stretch detector: the phase test over the whole sequence from the step records (the tracing chunks are
    /// `FoldDetect` tasks after it).
    FoldPhases { job: JobSpec },
    /// Temporal coherence of the detected anchors of `frames` (the detector's settle, split by frame range: it
    /// reads the detected anchors of `frames` widened by the settle radius).
    FoldSettle { job: JobSpec, frames: Range<usize> },
    /// Gather the detected anchors into their binary form (`anchors.bin`, what the later tasks read); its
    /// success expands the graph with the weight tasks.
    FoldMerge { job: JobSpec },
    /// Write the user-facing `anchors.json` and `folds/control_lines.obj` from `anchors.bin`: no deformation
    /// task needs them, so they are written beside the weight tasks, off the job's critical path; finalize
    /// (and with it `report.json`) waits for them.
    FoldFiles { job: JobSpec },
    /// Stretch detector: draw `folds.png` (the overlay frames' fold signal) from the tracing chunks and phase
    /// codes. It needs neither the settled anchors nor `anchors.bin`, so it runs beside the settle, merge and
    /// deformation tasks; only finalize waits for it.
    FoldPlot { job: JobSpec },
    /// Per-anchor mode: the anchor columns of block `block` of window `window` → partial blend.
    WeightBlock {
        job: JobSpec,
        window: usize,
        block: usize,
    },
    /// Fused mode: the whole 3-right-hand-side solve of window `window` → the window's field.
    WeightWindow { job: JobSpec, window: usize },
    /// Per-anchor mode: sum the partial blends of window `window` in block order → the window's field.
    Reduce { job: JobSpec, window: usize },
    /// The fold relief of captured `frames` (what a generic deconvolution adds along the normal), which the
    /// positioning of each frame averages over its neighbours in time.
    Relief { job: JobSpec, frames: Range<usize> },
    /// Cross-fade, position and stretch-reduce `frames`.
    Position { job: JobSpec, frames: Range<usize> },
    /// Write the output sequence, previews and `report.json` (last).
    Finalize { job: JobSpec },
    /// Train a DeepWrinkles model and publish it under `model/` ([`crate::deep`]).
    DeepTrain { job: JobSpec },
    /// Apply a DeepWrinkles model to `frames`.
    DeepApply { job: JobSpec, frames: Range<usize> },
    /// Write `done.json` and `report.json` once all `frames` frames of a deep apply are stored.
    DeepFinish { job: JobSpec, frames: usize },
}

impl TaskSpec {
    /// Short kind name (`weight-block`, `position`, …), as sent over gRPC next to the payload.
    pub fn kind(&self) -> &'static str {
        match self {
            TaskSpec::FoldDetect { .. } => "fold-detect",
            TaskSpec::FoldSteps { .. } => "fold-steps",
            TaskSpec::FoldPhases { .. } => "fold-phases",
            TaskSpec::FoldSettle { .. } => "fold-settle",
            TaskSpec::FoldMerge { .. } => "fold-merge",
            TaskSpec::FoldFiles { .. } => "fold-files",
            TaskSpec::FoldPlot { .. } => "fold-plot",
            TaskSpec::WeightBlock { .. } => "weight-block",
            TaskSpec::WeightWindow { .. } => "weight-window",
            TaskSpec::Reduce { .. } => "reduce",
            TaskSpec::Relief { .. } => "relief",
            TaskSpec::Position { .. } => "position",
            TaskSpec::Finalize { .. } => "finalize",
            TaskSpec::DeepTrain { .. } => "deep-train",
            TaskSpec::DeepApply { .. } => "deep-apply",
            TaskSpec::DeepFinish { .. } => "deep-finish",
        }
    }

    /// The job this task belongs to.
    pub fn job(&self) -> &JobSpec {
        match self {
            TaskSpec::FoldDetect { job, .. }
            | TaskSpec::FoldSteps { job, .. }
            | TaskSpec::FoldPhases { job }
            | TaskSpec::FoldSettle { job, .. }
            | TaskSpec::FoldMerge { job }
            | TaskSpec::FoldFiles { job }
            | TaskSpec::FoldPlot { job }
            | TaskSpec::WeightBlock { job, .. }
            | TaskSpec::WeightWindow { job, .. }
            | TaskSpec::Reduce { job, .. }
            | TaskSpec::Relief { job, .. }
            | TaskSpec::Position { job, .. }
            | TaskSpec::Finalize { job }
            | TaskSpec::DeepTrain { job }
            | TaskSpec::DeepApply { job, .. }
            | TaskSpec::DeepFinish { job, .. } => job,
        }
    }

    /// JSON encoding sent over the wire.
    pub fn to_payload(&self) -> Vec<u8> {
        serde_json::to_vec(self).unwrap_or_default()
    }

    /// Decodes a payload received over the wire, checking it against the announced `kind`. A malformed task is
    /// not retryable: it would be malformed on every worker.
    pub fn from_payload(kind: &str, payload: &[u8]) -> Result<Self, TaskError> {
        let spec: TaskSpec = serde_json::from_slice(payload)
            .map_err(|e| TaskError::fatal(format!("malformed `{kind}` task payload: {e}")))?;
        if spec.kind() != kind {
            return Err(TaskError::fatal(format!(
                "task payload is a `{}` task but was sent as `{kind}`",
                spec.kind()
            )));
        }
        Ok(spec)
    }
}

/// What a successful task reports back (small: stats, timings, anchor counts; bulk results are in storage).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct TaskOutput {
    pub summary: serde_json::Value,
    /// Seconds of computation (excluding waiting for storage), for throughput and efficiency figures.
    pub work_seconds: f64,
    /// Storage keys (relative to the job's output) the task wrote.
    pub written: Vec<String>,
}

/// One node of a job's task graph.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TaskDef {
    /// Unique within the job and deterministic (`weights/w0003/b0007`), so a re-plan names the same tasks.
    pub key: String,
    pub spec: TaskSpec,
    /// Keys of the tasks that must succeed first.
    pub deps: Vec<String>,
    /// When true, the coordinator calls [`crate::plan::graph::expand`] after this task succeeds and inserts the returned
    /// tasks in the same transaction that marks this one done.
    pub expands: bool,
}

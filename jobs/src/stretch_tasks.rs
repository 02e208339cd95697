//! The stretch detector's part of the task graph: step chunks → one phase task → tracing chunks →
//! settle ranges ([`crate::settle_tasks`]: temporal coherence) → the usual `fold-merge`, which reconciles the
//! tracing chunks' seed memories ([`crease_core::folds::stretch::split`]).
//!
//! ```text
//!   fold-steps (4·k frames each) ─► fold-phases ─► fold-detect (tracing, k frames each)
//!       ─► fold-settle (k frames each) ─► fold-merge
//!       ─► fold-plot (folds.png; only finalize waits for it)
//! ```
//!
//! Tracing dominates (it flattens a patch per seed), so the chunk size `k` is set from the triangle count for
//! tasks of some seconds each; step chunks do about a quarter of the work per frame, so they take four times
//! as many frames (at most half the sequence, so that two workers share them).

use crate::inspect::InputInfo;
use crate::keys;
use crate::plan::chunk_ranges;
use crate::spec::JobSpec;
use crate::task::{TaskDef, TaskSpec};
use std::ops::Range;

/// Frames each tracing task traces ahead of its chunk by default.
pub const DEFAULT_WARM_UP: usize = 3;

/// Triangle-frames per tracing task when the job does not say: about 20 frames at 100K triangles.
const TRIANGLE_FRAMES_PER_TASK: usize = 2_000_000;

/// Frames per tracing chunk: the job's `partition.stretch_frames_per_chunk`, or (0) from the triangle count
/// (4..=64 frames), no more than half the sequence so that two workers share even a short one.
pub fn trace_frames_per_chunk(job: &JobSpec, n_frames: usize, n_triangles: usize) -> usize {
    match job.partition.stretch_frames_per_chunk {
        0 => (TRIANGLE_FRAMES_PER_TASK / n_triangles.max(1))
            .clamp(4, 64)
            .min(n_frames.div_ceil(2))
            .max(1),
        k => k,
    }
}

/// The tracing chunks of the job.
pub fn trace_chunks(job: &JobSpec, n_frames: usize, n_triangles: usize) -> Vec<Range<usize>> {
    chunk_ranges(n_frames, trace_frames_per_chunk(job, n_frames, n_triangles))
}

/// The step chunks of the job: four tracing chunks' worth of frames each, but no more than half the sequence.
/// Every later task of the job waits for the steps, so a short sequence in one step chunk kept all workers but
/// one idle at the start of the job; split in two, two workers share them. Any chunking gives the same bits.
pub fn step_chunks(job: &JobSpec, n_frames: usize, n_triangles: usize) -> Vec<Range<usize>> {
    let per_chunk = 4 * trace_frames_per_chunk(job, n_frames, n_triangles);
    chunk_ranges(n_frames, per_chunk.min(n_frames.div_ceil(2)).max(1))
}

/// The detection tasks and the merge (marked `expands`) of a stretch job. `n_triangles` is the traced
/// (input) mesh's, whatever the subdivision.
pub fn tasks(job: &JobSpec, info: &InputInfo) -> Vec<TaskDef> {
    let n = info.n_frames;
    let nt = traced_triangles(job, info);
    let mut tasks: Vec<TaskDef> = step_chunks(job, n, nt)
        .into_iter()
        .map(|r| TaskDef {
            key: keys::fold_steps_task(r.start),
            spec: TaskSpec::FoldSteps {
                job: job.clone(),
                frames: r,
            },
            deps: vec![],
            expands: false,
        })
        .collect();
    tasks.push(TaskDef {
        key: keys::FOLD_PHASES_TASK.to_string(),
        spec: TaskSpec::FoldPhases { job: job.clone() },
        deps: tasks.iter().map(|t| t.key.clone()).collect(),
        expands: false,
    });
    let trace: Vec<TaskDef> = trace_chunks(job, n, nt)
        .into_iter()
        .map(|r| TaskDef {
            key: keys::fold_detect_task(r.start),
            spec: TaskSpec::FoldDetect {
                job: job.clone(),
                frames: r,
            },
            deps: vec![keys::FOLD_PHASES_TASK.to_string()],
            expands: false,
        })
        .collect();
    let traced: Vec<(Range<usize>, String)> = trace
        .iter()
        .map(|t| match &t.spec {
            TaskSpec::FoldDetect { frames, .. } => (frames.clone(), t.key.clone()),
            _ => unreachable!("tracing tasks are fold-detect tasks"),
        })
        .collect();
    let settle = crate::settle_tasks::tasks(job, n, nt, &traced);
    // The merge reads the tracing chunks (it reconciles them) and the settled ranges.
    let merge = TaskDef {
        key: keys::FOLD_MERGE_TASK.to_string(),
        spec: TaskSpec::FoldMerge { job: job.clone() },
        deps: trace.iter().chain(&settle).map(|t| t.key.clone()).collect(),
        expands: true,
    };
    // `folds.png` needs only the tracing chunks (and the phase codes before them). Listed after the settle
    // ranges and the merge, so that a free worker takes a settle range first (the coordinator dispatches ready
    // tasks in list order): the settle ranges and the merge are on the chain every deformation task waits on,
    // the drawing is not (only finalize waits for it).
    let plot = draws_plot(job, n).then(|| TaskDef {
        key: keys::FOLD_PLOT_TASK.to_string(),
        spec: TaskSpec::FoldPlot { job: job.clone() },
        deps: trace.iter().map(|t| t.key.clone()).collect(),
        expands: false,
    });
    tasks.extend(trace);
    tasks.extend(settle);
    tasks.push(merge);
    tasks.extend(plot);
    tasks
}

/// Whether a stretch job over `n_frames` frames draws `folds.png` (and so has a `fold-plot` task): it has
/// frames to show at a nonzero size (a valid job always has; the planner and the task ask the same question).
pub fn draws_plot(job: &JobSpec, n_frames: usize) -> bool {
    crate::detect::stretch_detector(job, n_frames)
        .is_some_and(|d| d.overlay_size > 0 && !d.overlay_frames.is_empty())
}

/// Triangles of the mesh the detector traces: the input's (subdivision multiplies by 4 per level).
pub fn traced_triangles(job: &JobSpec, info: &InputInfo) -> usize {
    info.n_triangles >> (2 * job.folds.subdivide().min(8))
}

//! The planner: a job becomes a graph of tasks.
//!
//! ```text
//!   fold-detect (per frame chunk, or one) ─► fold-settle ─► fold-merge ─┐   (only when folds are detected;
//!                                                                      │    stretch: see `stretch_tasks`;
//!                                                                      │    settle: see `settle_tasks`)
//!                                                                      ▼ expand
//!   fold-files (anchors.json, control lines) ─────────────────────────────────────────────► finalize
//!   fold-plot (stretch: folds.png, from the tracing chunks, planned with them) ────────────► finalize
//!   weight-block (window, anchor block) ─► reduce (window) ─┐          (per-anchor mode)
//!   weight-window (window) ─────────────────────────────────┤          (fused mode)
//!                                                           ▼
//!   relief (frame chunk, from the input alone) ─────────────┤          (jobs that add folds)
//!                                                           ▼
//!   position (frame chunk; depends on every window covering its frames, and on the reliefs of its frames
//!             widened by the relief's temporal span) ─► finalize
//! ```
//!
//! When the anchors are known at submit (an anchors file, or none), [`plan`] returns the whole graph. When
//! they are detected, the anchor count of each window — and with it the number of weight blocks — is only
//! known once detection is done, so [`plan`] returns the detection tasks and a `fold-merge` task marked
//! `expands`, and [`expand`] returns the rest once `fold-merge` has succeeded: the deformation tasks and a
//! `fold-files` task that writes the user-facing anchor files. Nothing but finalize waits for `fold-files`,
//! so it runs beside the weight tasks instead of lengthening the chain every deformation task waits on.

use crate::error::JobError;
use crate::plan::chunks::{blocks_per_window, chunk_ranges, job_windows, position_chunks};
use crate::plan::detect;
use crate::plan::input::InputInfo;
use crate::plan::task::{TaskDef, TaskOutput, TaskSpec};
use crate::spec::JobSpec;
use crate::storage::keys;
use crease_core::spacetime::WeightMode;

/// The initial task graph of a job.
pub fn plan(job: &JobSpec, info: &InputInfo) -> Result<Vec<TaskDef>, JobError> {
    job.validate()?;
    if let Some(deep) = &job.deep {
        return Ok(crate::deep::plan::plan(job, deep, info));
    }
    let n = info.n_frames;
    if n == 0 {
        return Err(JobError::Plan("the input has no frames".into()));
    }
    let relief = relief_tasks(job, n);
    if let Some(counts) = &info.anchors_per_frame {
        if counts.len() != n {
            return Err(JobError::Plan(format!(
                "anchor counts cover {} frames but the input has {n}",
                counts.len()
            )));
        }
        let mut tasks = relief;
        tasks.extend(deformation_tasks(job, n, counts, &[]));
        return Ok(tasks);
    }
    let granularity = detect::granularity(&job.folds).ok_or_else(|| {
        JobError::Plan(format!(
            "folds of kind `{}` are neither known at submit nor detected",
            job.folds.kind()
        ))
    })?;
    if matches!(job.folds, crate::spec::FoldSpec::Stretch { .. }) {
        let mut tasks = crate::plan::stretch::tasks(job, info);
        tasks.extend(relief);
        return Ok(tasks);
    }
    let chunks = detect::detection_chunks(granularity, n, job.partition.fold_frames_per_chunk);
    let mut tasks: Vec<TaskDef> = chunks
        .iter()
        .map(|r| TaskDef {
            key: keys::fold_detect_task(r.start),
            spec: TaskSpec::FoldDetect {
                job: job.clone(),
                frames: r.clone(),
            },
            deps: vec![],
            expands: false,
        })
        .collect();
    let detected: Vec<(std::ops::Range<usize>, String)> = chunks
        .iter()
        .cloned()
        .zip(tasks.iter().map(|t| t.key.clone()))
        .collect();
    tasks.extend(crate::plan::settle::tasks(
        job,
        n,
        info.n_triangles,
        &detected,
    ));
    // A video job that joins the geometry's folds asks first whether the capture erased them, which the
    // reliefs say (`execute::capture_trace`): its merge waits for them, so they are listed before it.
    if matches!(&job.folds, crate::spec::FoldSpec::Video { params, .. } if params.geometry_folds) {
        tasks.extend(relief);
        push_merge(job, &mut tasks);
    } else {
        push_merge(job, &mut tasks);
        tasks.extend(relief);
    }
    Ok(tasks)
}

/// The fold merge of a detecting job, after every task listed so far.
fn push_merge(job: &JobSpec, tasks: &mut Vec<TaskDef>) {
    let deps = tasks.iter().map(|t| t.key.clone()).collect();
    tasks.push(TaskDef {
        key: keys::FOLD_MERGE_TASK.to_string(),
        spec: TaskSpec::FoldMerge { job: job.clone() },
        deps,
        expands: true,
    });
}

/// Whether a job's positioning adds the fold relief: every job that adds folds (from a file or a detector),
/// when the relief is on. A job without folds gives its input back.
pub fn has_relief(job: &JobSpec) -> bool {
    !matches!(job.folds, crate::spec::FoldSpec::None) && job.params().relief.is_active()
}

/// The relief chunks: `[0, n)` in ranges of `partition.frames_per_chunk` frames.
fn relief_chunks(job: &JobSpec, n: usize) -> Vec<std::ops::Range<usize>> {
    chunk_ranges(n, job.partition.frames_per_chunk)
}

/// The relief tasks of a job (none without relief): they read the input alone, so they are planned at submit
/// and run beside fold detection.
fn relief_tasks(job: &JobSpec, n: usize) -> Vec<TaskDef> {
    if !has_relief(job) {
        return Vec::new();
    }
    relief_chunks(job, n)
        .into_iter()
        .map(|r| TaskDef {
            key: keys::relief_task(r.start),
            spec: TaskSpec::Relief {
                job: job.clone(),
                frames: r,
            },
            deps: vec![],
            expands: false,
        })
        .collect()
}

/// The tasks to add after task `done_key` (marked `expands`) succeeded with `output`.
pub fn expand(
    job: &JobSpec,
    info: &InputInfo,
    done_key: &str,
    output: &TaskOutput,
) -> Result<Vec<TaskDef>, JobError> {
    if done_key != keys::FOLD_MERGE_TASK {
        return Err(JobError::Plan(format!(
            "task `{done_key}` does not expand the graph"
        )));
    }
    let counts: Vec<usize> = output
        .summary
        .get("anchors_per_frame")
        .and_then(|v| serde_json::from_value(v.clone()).ok())
        .ok_or_else(|| {
            JobError::Plan(format!(
                "task `{done_key}` reported no `anchors_per_frame` in its summary"
            ))
        })?;
    if counts.len() != info.n_frames {
        return Err(JobError::Plan(format!(
            "task `{done_key}` reported anchors for {} frames but the input has {}",
            counts.len(),
            info.n_frames
        )));
    }
    let merge = [keys::FOLD_MERGE_TASK.to_string()];
    let mut tasks = deformation_tasks(job, info.n_frames, &counts, &merge);
    // Second in the list (the coordinator dispatches ready tasks in list order): the first weight task, which
    // starts the chain every positioning task waits on, goes to the first free worker, and `fold-files` to
    // the next one at once rather than after all the weight tasks.
    tasks.insert(
        1.min(tasks.len()),
        TaskDef {
            key: keys::FOLD_FILES_TASK.to_string(),
            spec: TaskSpec::FoldFiles { job: job.clone() },
            deps: merge.to_vec(),
            expands: false,
        },
    );
    // A stretch job's `fold-plot` (planned with the detection tasks) is waited for by finalize only.
    let plot = matches!(job.folds, crate::spec::FoldSpec::Stretch { .. })
        && crate::plan::stretch::draws_plot(job, info.n_frames);
    if let Some(finalize) = tasks
        .iter_mut()
        .find(|t| matches!(t.spec, TaskSpec::Finalize { .. }))
    {
        finalize.deps.push(keys::FOLD_FILES_TASK.to_string());
        if plot {
            finalize.deps.push(keys::FOLD_PLOT_TASK.to_string());
        }
    }
    Ok(tasks)
}

/// Storage keys (relative to the job's output) that must all exist before the job may be marked done.
pub fn final_outputs(job: &JobSpec, info: &InputInfo) -> Vec<String> {
    if job.deep.is_some() {
        return crate::deep::plan::final_outputs(info);
    }
    let mut out = info.output_files.clone();
    if info.anchors_per_frame.is_none() {
        out.push(keys::ANCHORS.to_string());
        out.push(keys::CONTROL_LINES.to_string());
    }
    out.push(keys::PREVIEW.to_string());
    out.push(keys::STRETCH_PLOT.to_string());
    for &f in &job.export.formats {
        out.push(crate::export_spec::export_key(&job.display_name(), f));
    }
    out.push(keys::REPORT.to_string());
    out
}

/// Weights, reduce, positioning and finalize tasks, each also depending on `extra_deps`.
///
/// Listed window by window, each positioning chunk right after the last window it needs: the coordinator
/// dispatches ready tasks in list order, so a chunk whose fields are done runs beside the next windows' weight
/// tasks instead of waiting behind all of them, and the job does not end with every positioning chunk at once
/// (a tail where a lone chunk leaves workers idle). The tasks and their dependencies are the same in any
/// order, and so are the outputs.
fn deformation_tasks(
    job: &JobSpec,
    n: usize,
    counts: &[usize],
    extra_deps: &[String],
) -> Vec<TaskDef> {
    let params = job.params();
    let windows = job_windows(job, n);
    // Each window's weight tasks (its field task last) and the key of the task that produces its field.
    let mut window_tasks: Vec<Vec<TaskDef>> = Vec::with_capacity(windows.len());
    let mut field_task = Vec::with_capacity(windows.len());
    match params.mode {
        WeightMode::Fused => {
            for k in 0..windows.len() {
                let key = keys::weight_window_task(k);
                window_tasks.push(vec![TaskDef {
                    key: key.clone(),
                    spec: TaskSpec::WeightWindow {
                        job: job.clone(),
                        window: k,
                    },
                    deps: extra_deps.to_vec(),
                    expands: false,
                }]);
                field_task.push(key);
            }
        }
        WeightMode::PerAnchor => {
            for (k, &blocks) in blocks_per_window(job, counts).iter().enumerate() {
                let mut tasks = Vec::with_capacity(blocks + 1);
                for b in 0..blocks {
                    tasks.push(TaskDef {
                        key: keys::weight_block_task(k, b),
                        spec: TaskSpec::WeightBlock {
                            job: job.clone(),
                            window: k,
                            block: b,
                        },
                        deps: extra_deps.to_vec(),
                        expands: false,
                    });
                }
                let key = keys::reduce_task(k);
                let mut deps = extra_deps.to_vec();
                deps.extend(tasks.iter().map(|t| t.key.clone()));
                tasks.push(TaskDef {
                    key: key.clone(),
                    spec: TaskSpec::Reduce {
                        job: job.clone(),
                        window: k,
                    },
                    deps,
                    expands: false,
                });
                window_tasks.push(tasks);
                field_task.push(key);
            }
        }
    }
    // Positioning chunks, grouped by the last window they need (windows are in frame order, so the groups are
    // too, and the chunks stay in frame order overall).
    let mut after_window: Vec<Vec<TaskDef>> = vec![Vec::new(); windows.len()];
    let mut unplaced = Vec::new();
    let mut position_keys = Vec::new();
    for r in position_chunks(n, &windows, job.partition.frames_per_chunk) {
        let key = keys::position_task(r.start);
        let mut deps = extra_deps.to_vec();
        if has_relief(job) {
            // The reliefs of the chunk's frames widened by the temporal span each frame's heights read.
            let (lo, hi) = (
                params.relief.span(r.start, n).start,
                params.relief.span(r.end - 1, n).end,
            );
            deps.extend(
                relief_chunks(job, n)
                    .into_iter()
                    .filter(|c| c.start < hi && lo < c.end)
                    .map(|c| keys::relief_task(c.start)),
            );
        }
        let mut last = None;
        for (k, w) in windows.iter().enumerate() {
            if w.start < r.end && r.start < w.end() {
                deps.push(field_task[k].clone());
                last = Some(k);
            }
        }
        let task = TaskDef {
            key: key.clone(),
            spec: TaskSpec::Position {
                job: job.clone(),
                frames: r,
            },
            deps,
            expands: false,
        };
        match last {
            Some(k) => after_window[k].push(task),
            None => unplaced.push(task),
        }
        position_keys.push(key);
    }
    let mut tasks = Vec::new();
    for (weights, positions) in window_tasks.into_iter().zip(after_window) {
        tasks.extend(weights);
        tasks.extend(positions);
    }
    tasks.extend(unplaced);
    let mut deps = extra_deps.to_vec();
    deps.extend(position_keys);
    tasks.push(TaskDef {
        key: keys::FINALIZE_TASK.to_string(),
        spec: TaskSpec::Finalize { job: job.clone() },
        deps,
        expands: false,
    });
    tasks
}

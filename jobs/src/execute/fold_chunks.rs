//! The fold intermediates that tasks hand each other, read back and checked: detection chunks and their
//! timings, a stretch job's tracing chunks, and the settle ranges (for the merge, in frame order, settled again
//! where the reconcile traced a frame again).

use super::env::TaskEnv;
use crate::error::TaskError;
use crate::plan::chunks::trace_chunks;
use crate::plan::detect::{detection_chunks, granularity};
use crate::plan::settle::{job_settle_chunks, settle_radius};
use crate::spec::FoldSpec;
use crate::storage::keys;
use crease_core::folds::anchors::binary;
use crease_core::folds::stretch::split::{self, TracedChunk};
use crease_core::folds::temporal::{settle_input, settle_range};
use crease_core::folds::FrameAnchors;
use crease_core::mesh::io::OpenedSequence;
use crease_core::mesh::FrameSource;
use serde_json::Value;
use std::ops::Range;
use std::path::Path;

/// The job's detection chunks over `n` frames.
pub(super) fn chunks(env: &TaskEnv, n: usize) -> Vec<Range<usize>> {
    granularity(&env.job.folds)
        .map(|g| detection_chunks(g, n, env.job.partition.fold_frames_per_chunk))
        .unwrap_or_default()
}

/// The detection seconds a chunk starting at frame `first` recorded beside its anchors.
pub(super) fn chunk_seconds(env: &TaskEnv, first: usize) -> Result<f64, TaskError> {
    let key = keys::fold_chunk_timing(first);
    let timing: Value = env.get_json(&key)?;
    timing
        .get("seconds")
        .and_then(Value::as_f64)
        .ok_or_else(|| TaskError::fatal(format!("{}: no `seconds`", env.out.describe(&key))))
}

/// Frames and triangles of the traced (input) mesh.
pub(super) fn traced_size(opened: &OpenedSequence) -> (usize, usize) {
    let (source, _) = split::traced_source(opened.source.as_ref());
    (source.n_frames(), source.topology().n_triangles())
}

/// The tracing chunk `r` as its `fold-detect` task stored it, checked to hold exactly the frames `r`.
pub(super) fn read_trace_chunk(env: &TaskEnv, r: &Range<usize>) -> Result<TracedChunk, TaskError> {
    env.check_cancelled()?;
    let key = keys::fold_trace_chunk(r.start);
    let bytes = env.get(&key)?;
    let chunk = TracedChunk::from_binary(&bytes, Path::new(&env.out.describe(&key)))
        .map_err(|e| TaskError::fatal(e.to_string()))?;
    let frames: Vec<usize> = chunk.frames.iter().map(|f| f.anchors.frame).collect();
    if chunk.first != r.start || frames != r.clone().collect::<Vec<_>>() {
        return Err(TaskError::fatal(format!(
            "{}: holds {} frames from {}, expected frames {}..{}",
            env.out.describe(&key),
            chunk.frames.len(),
            chunk.first,
            r.start,
            r.end
        )));
    }
    Ok(chunk)
}

/// The stretch job's tracing chunks and frame count as its settle tasks see them.
pub(super) fn traced_chunks(env: &TaskEnv, opened: &OpenedSequence) -> (Vec<Range<usize>>, usize) {
    let (n, nt) = traced_size(opened);
    (trace_chunks(env.job, n, nt), nt)
}

pub(super) fn is_stretch(env: &TaskEnv) -> bool {
    matches!(env.job.folds, FoldSpec::Stretch { .. })
}

/// The job's detection chunks (tracing chunks for stretch folds) and settle ranges over the input's frames.
pub(super) fn ranges(
    env: &TaskEnv,
    opened: &OpenedSequence,
) -> (Vec<Range<usize>>, Vec<Range<usize>>) {
    let n = opened.source.n_frames();
    if is_stretch(env) {
        let (chunks, nt) = traced_chunks(env, opened);
        (chunks, job_settle_chunks(env.job, n, nt))
    } else {
        (chunks(env, n), job_settle_chunks(env.job, n, 0))
    }
}

/// The detected anchors of detection chunk `r`, as its task stored them (a stretch tracing chunk's frames as
/// traced, before the merge reconciles them).
pub(super) fn read_detected(
    env: &TaskEnv,
    r: &Range<usize>,
) -> Result<Vec<FrameAnchors>, TaskError> {
    if is_stretch(env) {
        let chunk = read_trace_chunk(env, r)?;
        return Ok(chunk.frames.into_iter().map(|f| f.anchors).collect());
    }
    env.check_cancelled()?;
    let key = keys::fold_chunk(r.start);
    let bytes = env.get(&key)?;
    let frames = binary::frames_from_binary(&bytes, Path::new(&env.out.describe(&key)))
        .map_err(|e| TaskError::fatal(e.to_string()))?;
    check_frames(env, &key, &frames, r)?;
    Ok(frames)
}

/// `frames` read from `key` must be exactly the frames `r`, in order.
fn check_frames(
    env: &TaskEnv,
    key: &str,
    frames: &[FrameAnchors],
    r: &Range<usize>,
) -> Result<(), TaskError> {
    let got: Vec<usize> = frames.iter().map(|f| f.frame).collect();
    if got != r.clone().collect::<Vec<_>>() {
        return Err(TaskError::fatal(format!(
            "{}: holds frames {got:?}, expected frames {}..{}",
            env.out.describe(key),
            r.start,
            r.end
        )));
    }
    Ok(())
}

/// The settled anchors of every frame, in order, for the merge. `detected`: all frames as the whole-sequence
/// settle would get them (a stretch job's reconciled tracing chunks); `again`: the frames whose anchors differ
/// from what the tracing chunks stored (traced again by the reconcile), whose settle ranges were settled from
/// the wrong input and are settled again here. Without settle tasks (see [`settle_radius`]) the settle changes
/// nothing and `detected` is returned as it is.
pub(super) fn settled(
    env: &TaskEnv,
    opened: &OpenedSequence,
    detected: Vec<FrameAnchors>,
    again: &[usize],
    label: &str,
) -> Result<Vec<FrameAnchors>, TaskError> {
    let n = detected.len();
    let Some(radius) = settle_radius(env.job, n) else {
        return Ok(detected);
    };
    let source: &dyn FrameSource = opened.source.as_ref();
    let (_, ranges) = ranges(env, opened);
    let mut out = Vec::with_capacity(n);
    for r in ranges {
        let need = settle_input(r.clone(), n, radius);
        if again.iter().any(|t| need.contains(t)) {
            out.extend(
                settle_range(source, &detected, 0, n, r, radius)
                    .map_err(|e| TaskError::from_core(label, e))?,
            );
            continue;
        }
        out.extend(read_settled(env, &r)?);
    }
    covers(out, n, label)
}

/// The settled anchors of every frame, in order, as the job's `fold-settle` tasks stored them (for a job that
/// has settle tasks and whose detected frames are all as its detection tasks stored them).
pub(super) fn stored_settled(
    env: &TaskEnv,
    opened: &OpenedSequence,
    n: usize,
    label: &str,
) -> Result<Vec<FrameAnchors>, TaskError> {
    let (_, ranges) = ranges(env, opened);
    let mut out = Vec::with_capacity(n);
    for r in ranges {
        out.extend(read_settled(env, &r)?);
    }
    covers(out, n, label)
}

/// The settled range `r` as its `fold-settle` task stored it.
fn read_settled(env: &TaskEnv, r: &Range<usize>) -> Result<Vec<FrameAnchors>, TaskError> {
    env.check_cancelled()?;
    let key = keys::fold_settled(r.start);
    let bytes = env.get(&key)?;
    let frames = binary::frames_from_binary(&bytes, Path::new(&env.out.describe(&key)))
        .map_err(|e| TaskError::fatal(e.to_string()))?;
    check_frames(env, &key, &frames, r)?;
    Ok(frames)
}

/// `out` if it holds all `n` frames.
fn covers(out: Vec<FrameAnchors>, n: usize, label: &str) -> Result<Vec<FrameAnchors>, TaskError> {
    if out.len() != n {
        return Err(TaskError::fatal(format!(
            "{label}: the settle ranges cover {} of {n} frames",
            out.len()
        )));
    }
    Ok(out)
}

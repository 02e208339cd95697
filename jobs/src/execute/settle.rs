//! `fold-settle` tasks ([`crate::settle_tasks`]): the temporal coherence of one frame range, from the detected
//! anchors of that range widened by the settle radius, stored under [`keys::fold_settled`] in the binary anchors
//! form; and [`settled`], the merge's side: the settled ranges in frame order.

use super::env::TaskEnv;
use super::phase_times::Lap;
use crate::error::TaskError;
use crate::keys;
use crate::settle_tasks::{inputs_of, job_settle_chunks, settle_radius};
use crate::spec::FoldSpec;
use crease_core::folds::anchors::binary;
use crease_core::folds::temporal::{settle_input, settle_range};
use crease_core::folds::FrameAnchors;
use crease_core::mesh::io::OpenedSequence;
use crease_core::mesh::FrameSource;
use serde_json::{json, Value};
use std::ops::Range;
use std::path::Path;

fn is_stretch(env: &TaskEnv) -> bool {
    matches!(env.job.folds, FoldSpec::Stretch { .. })
}

/// The job's detection chunks (tracing chunks for stretch folds) and settle ranges over the input's frames.
fn plan(env: &TaskEnv, opened: &OpenedSequence) -> (Vec<Range<usize>>, Vec<Range<usize>>) {
    let n = opened.source.n_frames();
    if is_stretch(env) {
        let (chunks, nt) = super::stretch::traced_chunks(env, opened);
        (chunks, job_settle_chunks(env.job, n, nt))
    } else {
        (
            super::folds::chunks(env, n),
            job_settle_chunks(env.job, n, 0),
        )
    }
}

/// The detected anchors of detection chunk `r`, as its task stored them (a stretch tracing chunk's frames as
/// traced, before the merge reconciles them).
fn read_detected(env: &TaskEnv, r: &Range<usize>) -> Result<Vec<FrameAnchors>, TaskError> {
    if is_stretch(env) {
        let chunk = super::stretch::read_trace_chunk(env, r)?;
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

/// A `fold-settle` task: settles `frames` from the detection chunks its input window overlaps.
pub fn settle(env: &TaskEnv, frames: Range<usize>) -> Result<(Value, Vec<String>), TaskError> {
    let mut lap = Lap::start();
    let opened = env.open_input()?;
    let n = opened.source.n_frames();
    let label = format!(
        "temporal coherence, frames {}..{}",
        frames.start, frames.end
    );
    let radius = settle_radius(env.job, n).ok_or_else(|| {
        TaskError::fatal(format!(
            "{label}: folds of kind `{}` over {n} frames have no settle tasks",
            env.job.folds.kind()
        ))
    })?;
    let (detected, ranges) = plan(env, &opened);
    if !ranges.contains(&frames) {
        return Err(TaskError::fatal(format!(
            "{label}: not one of the job's settle ranges over {n} frames"
        )));
    }
    let need = settle_input(frames.clone(), n, radius);
    let mut input: Vec<FrameAnchors> = Vec::with_capacity(need.len());
    for c in inputs_of(&frames, n, radius, &detected) {
        input.extend(
            read_detected(env, &c)?
                .into_iter()
                .filter(|f| need.contains(&f.frame)),
        );
    }
    lap.lap("fold-settle: open input, read detected chunks");
    env.check_cancelled()?;
    let out = settle_range(
        opened.source.as_ref(),
        &input,
        need.start,
        n,
        frames.clone(),
        radius,
    )
    .map_err(|e| TaskError::from_core(&label, e))?;
    lap.lap("fold-settle: settle_range (reads its window's meshes)");
    let key = keys::fold_settled(frames.start);
    env.put(&key, binary::frames_to_binary(&out))?;
    lap.lap("fold-settle: write settled anchors");
    let counts: Vec<usize> = out.iter().map(|f| f.anchors.len()).collect();
    Ok((json!({ "anchors_per_frame": counts }), vec![key]))
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
    let (_, ranges) = plan(env, opened);
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
    let (_, ranges) = plan(env, opened);
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

//! Fold-detection tasks, generic over [`crease_core::folds::FoldDetector`]: `detect` runs the job's detector on
//! a frame chunk (or the whole sequence), stores its anchors and writes the inspection files the detector drew
//! for those frames (overlays); `merge` assembles the anchors into `anchors.json` (and its binary form, which
//! the later tasks read) and the control lines into `folds/control_lines.obj`, whose per-frame anchor counts let the planner size the weight blocks.

use super::env::TaskEnv;
use crate::detect::{detection_chunks, detector, granularity};
use crate::error::TaskError;
use crate::keys;
use crate::spec::FoldSpec;
use crease_core::folds::anchors::binary;
use crease_core::folds::{AnchorSet, FoldDetector, FrameAnchors};
use crease_core::mesh::io::OpenedSequence;
use serde_json::{json, Value};
use std::ops::Range;
use std::path::Path;

fn job_detector(
    env: &TaskEnv,
    opened: &OpenedSequence,
) -> Result<Box<dyn FoldDetector>, TaskError> {
    let inputs = env.fold_inputs()?;
    detector(env.job, &opened.layout, opened.source.n_frames(), &inputs)
        .map_err(|e| TaskError::fatal(e.to_string()))?
        .ok_or_else(|| {
            TaskError::fatal(format!(
                "folds of kind `{}` are not detected; this job has no fold tasks",
                env.job.folds.kind()
            ))
        })
}

/// The job's detection chunks over `n` frames.
fn chunks(env: &TaskEnv, n: usize) -> Vec<Range<usize>> {
    granularity(&env.job.folds)
        .map(|g| detection_chunks(g, n, env.job.partition.fold_frames_per_chunk))
        .unwrap_or_default()
}

pub fn detect(env: &TaskEnv, frames: Range<usize>) -> Result<(Value, Vec<String>), TaskError> {
    if matches!(env.job.folds, FoldSpec::Stretch { .. }) {
        return super::stretch::trace(env, frames);
    }
    let opened = env.open_input()?;
    let d = job_detector(env, &opened)?;
    let n = opened.source.n_frames();
    let label = format!(
        "{} fold detection, frames {}..{}",
        d.name(),
        frames.start,
        frames.end
    );
    if !chunks(env, n).contains(&frames) {
        return Err(TaskError::fatal(format!(
            "{label}: not one of the job's detection chunks over {n} frames"
        )));
    }
    env.check_cancelled()?;
    let clock = std::time::Instant::now();
    let (found, artifacts) = d
        .detect_with_artifacts(opened.source.as_ref(), frames.clone(), env.progress())
        .map_err(|e| TaskError::from_core(&label, e))?;
    let expected: Vec<usize> = frames.clone().collect();
    let got: Vec<usize> = found.iter().map(|f| f.frame).collect();
    if got != expected {
        return Err(TaskError::fatal(format!(
            "{label}: the detector returned frames {got:?}, expected {expected:?}"
        )));
    }
    let seconds = clock.elapsed().as_secs_f64();
    let key = keys::fold_chunk(frames.start);
    env.put(&key, binary::frames_to_binary(&found))?;
    let timing = keys::fold_chunk_timing(frames.start);
    env.put_json(
        &timing,
        &json!({ "seconds": seconds, "frames": frames.len() }),
    )?;
    let mut written = vec![key, timing];
    // Overlays go straight to their final keys: they depend on this chunk's frames only, and a rerun rewrites
    // the same bytes.
    for a in artifacts {
        env.put(&a.key, a.bytes)?;
        written.push(a.key);
    }
    let counts: Vec<usize> = found.iter().map(|f| f.anchors.len()).collect();
    Ok((json!({ "anchors_per_frame": counts }), written))
}

pub fn merge(env: &TaskEnv) -> Result<(Value, Vec<String>), TaskError> {
    let opened = env.open_input()?;
    let d = job_detector(env, &opened)?;
    let n = opened.source.n_frames();
    let n_tri = opened.source.topology().n_triangles();
    let mut written = Vec::new();
    let (frames, mut summary_extra) = if matches!(env.job.folds, FoldSpec::Stretch { .. }) {
        let g = super::stretch::gather(env, &opened)?;
        for a in g.artifacts {
            env.put(&a.key, a.bytes)?;
            written.push(a.key);
        }
        (
            g.frames,
            json!({ "per_frame": g.per_frame, "retraced_frames": g.retraced }),
        )
    } else {
        let (frames, per_frame) = gather_chunks(env, opened.source.as_ref(), d.as_ref(), n)?;
        (frames, json!({ "per_frame": per_frame }))
    };
    let set = AnchorSet::from_frame_anchors(frames, n_tri, None)
        .map_err(|e| TaskError::from_core(&format!("{} fold merge", d.name()), e))?;
    if set.n_frames() != n {
        return Err(TaskError::fatal(format!(
            "{} fold merge: anchors for {} frames, the input has {n}",
            d.name(),
            set.n_frames()
        )));
    }
    // The job's own tasks read the binary form; `anchors.json` is written once, for people and other tools.
    // Counts come from reading the stored form back as the weight tasks will, so planning and solving agree.
    let bin = set.to_binary();
    let back = AnchorSet::from_binary(
        &bin,
        Path::new(&env.out.describe(keys::ANCHORS_BIN)),
        n,
        n_tri,
    )
    .map_err(|e| TaskError::from_core("fold merge", e))?;
    env.put(keys::ANCHORS_BIN, bin)?;
    env.put(keys::ANCHORS, set.to_json())?;
    // In a subdirectory: an extra .obj beside the output frames would make the output unreadable as a sequence.
    env.put(keys::CONTROL_LINES, back.control_lines_obj())?;
    // What finalize puts into report.json as `fold_detection`.
    let mut summary = json!({ "source": d.name(), "anchors": back.total() });
    if let (Some(s), Some(extra)) = (summary.as_object_mut(), summary_extra.as_object_mut()) {
        s.append(extra);
    }
    let extra = d
        .summary(opened.source.as_ref())
        .map_err(|e| TaskError::from_core("fold merge: detection summary", e))?;
    if let (Some(s), Value::Object(extra)) = (summary.as_object_mut(), extra) {
        s.extend(extra);
    }
    env.put_json(keys::FOLD_SUMMARY, &summary)?;
    let counts: Vec<usize> = (0..n).map(|t| back.frame(t).len()).collect();
    written.extend([
        keys::ANCHORS_BIN.to_string(),
        keys::ANCHORS.to_string(),
        keys::CONTROL_LINES.to_string(),
        keys::FOLD_SUMMARY.to_string(),
    ]);
    Ok((
        json!({ "anchors_per_frame": counts, "anchors": back.total() }),
        written,
    ))
}

/// The anchors of every detection chunk in frame order, finished by the detector's [`FoldDetector::settle`],
/// and per frame, for report.json: anchors, control lines and detection seconds (a chunk's time spread evenly
/// over its frames).
fn gather_chunks(
    env: &TaskEnv,
    source: &dyn crease_core::mesh::FrameSource,
    d: &dyn FoldDetector,
    n: usize,
) -> Result<(Vec<FrameAnchors>, Vec<Value>), TaskError> {
    let mut frames: Vec<FrameAnchors> = Vec::with_capacity(n);
    // Per frame, for report.json: anchors, control lines, folds found, seeds tried (detectors that search seeds)
    // and detection seconds (a chunk's time spread evenly over its frames: a whole-sequence detector has one
    // chunk, so that is its mean per frame).
    let mut per_frame: Vec<Value> = Vec::with_capacity(n);
    for r in chunks(env, n) {
        env.check_cancelled()?;
        let key = keys::fold_chunk(r.start);
        let bytes = env.get(&key)?;
        let chunk = binary::frames_from_binary(&bytes, Path::new(&env.out.describe(&key)))
            .map_err(|e| TaskError::fatal(e.to_string()))?;
        let seconds = chunk_seconds(env, r.start)?;
        for f in &chunk {
            per_frame.push(json!({
                "frame": f.frame,
                "anchors": f.anchors.len(),
                "control_lines": f.control_lines.len(),
                "folds": f.detection.map(|d| d.folds),
                "seeds_tried": f.detection.and_then(|d| d.seeds_tried),
                "detection_seconds": seconds / r.len().max(1) as f64,
            }));
        }
        frames.extend(chunk);
    }
    let frames = d
        .settle(source, frames)
        .map_err(|e| TaskError::from_core(&format!("{} fold merge", d.name()), e))?;
    Ok((frames, per_frame))
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

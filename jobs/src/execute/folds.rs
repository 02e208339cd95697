//! Fold-detection tasks, generic over [`crease_core::folds::FoldDetector`]: `detect` runs the job's detector on
//! a frame chunk (or the whole sequence), stores its anchors and writes the inspection files the detector drew
//! for those frames (overlays); `merge` assembles the anchors into their binary form (`anchors.bin`, which the
//! later tasks read and whose per-frame anchor counts let the planner size the weight blocks); `files` writes
//! the user-facing `anchors.json` and `folds/control_lines.obj` from it (a stretch job's `folds.png` has its
//! own `fold-plot` task, [`super::stretch::plot`], which needs only the tracing chunks).
//! The temporal coherence between them runs in `fold-settle` tasks ([`crate::plan::settle`]).
//!
//! Why two tasks: `merge` is on every detection job's critical path (all deformation tasks wait for it), and
//! the text of the two user files (tens of MB at paper scale) was the larger part of it. No task reads them,
//! so `files` runs beside the weight tasks and only finalize (which writes `report.json`) waits for it.

use super::env::TaskEnv;
use super::fold_chunks::{self, chunk_seconds, chunks};
use super::phase_times::Lap;
use crate::error::TaskError;
use crate::plan::detect::detector;
use crate::report::FoldDetection;
use crate::spec::FoldSpec;
use crate::storage::keys;
use crease_core::folds::anchors::binary;
use crease_core::folds::fuse::fuse;
use crease_core::folds::stretch::{StretchDetector, StretchParams};
use crease_core::folds::{AnchorSet, FoldDetector, FrameAnchors};
use crease_core::mesh::io::OpenedSequence;
use serde_json::{json, Value};
use std::ops::Range;
use std::path::Path;
use std::sync::Arc;

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
    let mut lap = Lap::start();
    let d = job_detector(env, &opened)?;
    let n = opened.source.n_frames();
    let n_tri = opened.source.topology().n_triangles();
    let mut written = Vec::new();
    let (frames, mut summary_extra) = if matches!(env.job.folds, FoldSpec::Stretch { .. }) {
        let g = super::stretch::gather(env, &opened)?;
        (
            g.frames,
            json!({ "per_frame": g.per_frame, "retraced_frames": g.retraced }),
        )
    } else {
        let (frames, per_frame) = gather_chunks(env, &opened, d.as_ref(), n)?;
        (frames, json!({ "per_frame": per_frame }))
    };
    lap.lap("fold-merge: gathering, in all");
    let (frames, geometry) = with_geometry_folds(env, &opened, frames)?;
    if let (Some(g), Some(s)) = (geometry, summary_extra.as_object_mut()) {
        s.insert("geometry".into(), g);
        lap.lap("fold-merge: the geometry's folds");
    }
    let set = AnchorSet::from_frame_anchors(frames, n_tri, None)
        .map_err(|e| TaskError::from_core(&format!("{} fold merge", d.name()), e))?;
    if set.n_frames() != n {
        return Err(TaskError::fatal(format!(
            "{} fold merge: anchors for {} frames, the input has {n}",
            d.name(),
            set.n_frames()
        )));
    }
    // The job's own tasks read the binary form; `anchors.json` is written from it by the `fold-files` task, for
    // people and other tools. Counts come from reading the stored form back as the weight tasks will, so
    // planning and solving agree.
    let bin = set.to_binary();
    let back = AnchorSet::from_binary(
        &bin,
        Path::new(&env.out.describe(keys::ANCHORS_BIN)),
        n,
        n_tri,
    )
    .map_err(|e| TaskError::from_core("fold merge", e))?;
    lap.lap("fold-merge: anchor set, binary form read back");
    env.put(keys::ANCHORS_BIN, bin)?;
    lap.lap("fold-merge: write anchors.bin");
    // What finalize puts into report.json as `fold_detection` ([`FoldDetection`]).
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
    // The type finalize reads it back as; stored as a JSON value, whose keys are sorted as in the report.
    let summary: FoldDetection = serde_json::from_value(summary)
        .map_err(|e| TaskError::fatal(format!("fold merge: detection summary: {e}")))?;
    let summary = serde_json::to_value(&summary)
        .map_err(|e| TaskError::fatal(format!("fold merge: detection summary: {e}")))?;
    env.put_json(keys::FOLD_SUMMARY, &summary)?;
    let counts: Vec<usize> = (0..n).map(|t| back.frame(t).len()).collect();
    lap.lap("fold-merge: summary");
    written.extend([
        keys::ANCHORS_BIN.to_string(),
        keys::FOLD_SUMMARY.to_string(),
    ]);
    Ok((
        json!({ "anchors_per_frame": counts, "anchors": back.total() }),
        written,
    ))
}

/// A video job's anchors joined by the geometry's (`video.geometry_folds`, [`crease_core::folds::fuse`]): the
/// stretch detector runs here, on the whole sequence, with its default settings, so the fused set is made in
/// one place and every worker reads the same bytes. Not where the capture erased its folds (its trace, the
/// median share of the lost surface the relief gives back, below `video.geometry_min_trace`): the geometry
/// knows the band that lost length there, not where each crest lies, and the images alone place them better.
/// Returns the frames to store and what the report says of it.
fn with_geometry_folds(
    env: &TaskEnv,
    opened: &Arc<OpenedSequence>,
    frames: Vec<FrameAnchors>,
) -> Result<(Vec<FrameAnchors>, Option<Value>), TaskError> {
    let FoldSpec::Video { params, .. } = &env.job.folds else {
        return Ok((frames, None));
    };
    if !params.geometry_folds {
        return Ok((frames, None));
    }
    let trace = super::capture_trace::median_relief_share(env, opened)?;
    if let Some(share) = trace.filter(|&s| s < params.geometry_min_trace) {
        return Ok((
            frames,
            Some(json!({ "capture_trace": share, "skipped": "the capture erased its folds" })),
        ));
    }
    let n = opened.source.n_frames();
    let clock = std::time::Instant::now();
    let geometry = StretchDetector::new(StretchParams::default())
        .detect(opened.source.as_ref(), 0..n, env.progress())
        .map_err(|e| TaskError::from_core("fold merge: the geometry's folds", e))?;
    let seconds = clock.elapsed().as_secs_f64();
    let (fused, counts) = fuse(frames, &geometry, params.fused_gain)
        .map_err(|e| TaskError::from_core("fold merge: fusing the geometry's folds", e))?;
    Ok((
        fused,
        Some(json!({
            "images_anchors": counts.primary,
            "geometry_anchors": counts.secondary,
            "shared_triangles": counts.shared,
            "fused_gain": params.fused_gain,
            "capture_trace": trace,
            "seconds": seconds,
        })),
    ))
}

/// `anchors.json` and `folds/control_lines.obj` from the `anchors.bin` that `merge` stored: the bytes `merge`
/// used to write itself. `anchors.json` holds the stored values as they are (they were validated, and their
/// axes normalised, once, before `merge` stored them; validating again could move a normalised axis by an ulp).
pub fn files(env: &TaskEnv) -> Result<(Value, Vec<String>), TaskError> {
    let mut lap = Lap::start();
    let opened = env.open_input()?;
    let n = opened.source.n_frames();
    let n_tri = opened.source.topology().n_triangles();
    env.check_cancelled()?;
    let bytes = env.get(keys::ANCHORS_BIN)?;
    let label = env.out.describe(keys::ANCHORS_BIN);
    let path = Path::new(&label);
    let bad = |e: crease_core::Error| TaskError::fatal(format!("fold files: {e}"));
    let stored = {
        let mut r = binary::Reader::open(path, &bytes, binary::Kind::AnchorSet).map_err(bad)?;
        let frames = binary::read_frames(&mut r).map_err(bad)?;
        r.end().map_err(bad)?;
        frames
    };
    drop(bytes);
    lap.lap("fold-files: read anchors.bin");
    env.check_cancelled()?;
    // anchors.json from the values as stored; then the same frames validated as the weight tasks read them
    // (`AnchorSet::from_binary`: checked against the input, axes normalised), which gives the control lines,
    // without parsing the bytes a second time.
    let json = anchors_json(&stored);
    lap.lap("fold-files: format anchors.json");
    let set = AnchorSet::from_stored_frames(stored, path, n, n_tri).map_err(bad)?;
    let total = set.total();
    lap.lap("fold-files: validate the anchors");
    env.put(keys::ANCHORS, json)?;
    lap.lap("fold-files: write anchors.json");
    // In a subdirectory: an extra .obj beside the output frames would make the output unreadable as a sequence.
    let obj = set.control_lines_obj();
    lap.lap("fold-files: format control_lines.obj");
    env.put(keys::CONTROL_LINES, obj)?;
    lap.lap("fold-files: write control_lines.obj");
    let written = vec![keys::ANCHORS.to_string(), keys::CONTROL_LINES.to_string()];
    Ok((json!({ "anchors": total }), written))
}

/// The anchors file (`AnchorSet::to_json`'s format: version 1, frames without anchors or lines left out) of
/// frames as they were stored, without validating them again.
fn anchors_json(frames: &[FrameAnchors]) -> String {
    #[derive(serde::Serialize)]
    struct File<'a> {
        version: u32,
        frames: Vec<&'a FrameAnchors>,
    }
    let file = File {
        version: 1,
        frames: frames
            .iter()
            .filter(|f| !f.anchors.is_empty() || !f.control_lines.is_empty())
            .collect(),
    };
    serde_json::to_string(&file).expect("anchors serialise")
}

/// The anchors of every detection chunk in frame order, finished by the detector's [`FoldDetector::settle`]
/// (as the job's `fold-settle` tasks stored it, when it has them), and per frame, for report.json: anchors,
/// control lines and detection seconds (a chunk's time spread evenly over its frames).
fn gather_chunks(
    env: &TaskEnv,
    opened: &OpenedSequence,
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
    let label = format!("{} fold merge", d.name());
    let frames = if crate::plan::settle::settle_radius(env.job, n).is_some() {
        // Settled by the job's `fold-settle` tasks, range by range, as `d.settle` would.
        fold_chunks::settled(env, opened, frames, &[], &label)?
    } else {
        d.settle(opened.source.as_ref(), frames)
            .map_err(|e| TaskError::from_core(&label, e))?
    };
    Ok((frames, per_frame))
}

#[cfg(test)]
mod tests {
    use super::anchors_json;
    use crease_core::folds::anchors::binary;
    use crease_core::folds::{Anchor, AnchorSet, FrameAnchors};
    use std::path::Path;

    /// `fold-files` writes what `AnchorSet::to_json` wrote in `merge` before: same format, same values (read
    /// from the binary form as stored, not validated again).
    #[test]
    fn anchors_json_from_the_binary_form_is_the_sets_json() {
        let axis = |i: usize| {
            let v = [0.3 + i as f64 * 0.01, -0.7, 0.2 * i as f64 + 0.1];
            let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            [v[0] / n, v[1] / n, v[2] / n]
        };
        let frames: Vec<FrameAnchors> = (0..5)
            .map(|f| FrameAnchors {
                frame: f,
                anchors: if f == 1 {
                    vec![]
                } else {
                    (0..f + 1)
                        .map(|i| Anchor {
                            triangle: (7 * i + f) as u32,
                            axis: axis(i + f),
                            angle: 0.1 * i as f64 - 0.33,
                        })
                        .collect()
                },
                control_lines: if f == 3 {
                    vec![]
                } else {
                    vec![vec![[0.1, 0.2 * f as f64, 1e-17]; f + 1]]
                },
                detection: None,
            })
            .chain(std::iter::once(FrameAnchors {
                frame: 5,
                ..Default::default()
            }))
            .collect();
        let set = AnchorSet::from_frame_anchors(frames, 100, None).unwrap();
        let bin = set.to_binary();
        let mut r =
            binary::Reader::open(Path::new("a.bin"), &bin, binary::Kind::AnchorSet).unwrap();
        let stored = binary::read_frames(&mut r).unwrap();
        r.end().unwrap();
        assert_eq!(anchors_json(&stored), set.to_json());
    }
}

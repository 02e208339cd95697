//! The stretch detector's tasks ([`crate::stretch_tasks`]): step records and phase codes go through storage as
//! `.npy`, traced chunks in the binary anchors form, under [`keys`]; the computation is
//! [`crease_core::folds::stretch::split`], so these functions only move data and name what is missing.

use super::env::TaskEnv;
use super::phase_times::Lap;
use crate::error::TaskError;
use crate::keys;
use crate::stretch_tasks::{step_chunks, trace_chunks};
use crease_core::folds::stretch::split::{
    self, ChunkTracer, Pass, PhaseCode, Phases, StepRecord, TracedChunk,
};
use crease_core::folds::stretch::StretchDetector;
use crease_core::folds::{Artifact, FrameAnchors};
use crease_core::mesh::io::OpenedSequence;
use crease_core::mesh::FrameSource;
use serde_json::{json, Value};
use std::cell::RefCell;
use std::ops::Range;
use std::path::Path;

fn detector(env: &TaskEnv, n: usize) -> Result<StretchDetector, TaskError> {
    crate::detect::stretch_detector(env.job, n).ok_or_else(|| {
        TaskError::fatal(format!(
            "folds of kind `{}` have no stretch detection tasks",
            env.job.folds.kind()
        ))
    })
}

/// Frames and triangles of the traced (input) mesh.
fn traced_size(opened: &OpenedSequence) -> (usize, usize) {
    let (source, _) = split::traced_source(opened.source.as_ref());
    (source.n_frames(), source.topology().n_triangles())
}

/// Storage reads inside core's callbacks: the first storage error is kept here (core sees a cancellation and
/// stops) and returned instead of core's error.
struct Carry(RefCell<Option<TaskError>>);

impl Carry {
    fn new() -> Self {
        Carry(RefCell::new(None))
    }

    fn wrap<T>(&self, r: Result<T, TaskError>) -> crease_core::Result<T> {
        r.map_err(|e| {
            self.0.borrow_mut().get_or_insert(e);
            crease_core::Error::Cancelled
        })
    }

    fn finish<T>(self, label: &str, r: crease_core::Result<T>) -> Result<T, TaskError> {
        match (self.0.into_inner(), r) {
            (Some(e), _) => Err(e),
            (None, r) => r.map_err(|e| TaskError::from_core(label, e)),
        }
    }
}

pub fn steps(env: &TaskEnv, frames: Range<usize>) -> Result<(Value, Vec<String>), TaskError> {
    let opened = env.open_input()?;
    let (n, nt) = traced_size(&opened);
    let label = format!("stretch steps, frames {}..{}", frames.start, frames.end);
    if !step_chunks(env.job, n, nt).contains(&frames) {
        return Err(TaskError::fatal(format!(
            "{label}: not one of the job's step chunks over {n} frames"
        )));
    }
    let det = detector(env, n)?;
    let records = split::steps(
        opened.source.as_ref(),
        frames.clone(),
        &det.params,
        env.progress(),
    )
    .map_err(|e| TaskError::from_core(&label, e))?;
    let mut written = Vec::with_capacity(records.len());
    for (t, rec) in frames.zip(records) {
        let key = keys::fold_steps(t);
        env.put_npy(&key, &[nt, 4], rec.as_flattened())?;
        written.push(key);
    }
    Ok((json!({}), written))
}

fn pass_name(pass: Pass) -> &'static str {
    match pass {
        Pass::Forward => "fwd",
        Pass::Backward => "bwd",
    }
}

fn read_steps(env: &TaskEnv, t: usize, nt: usize) -> Result<Vec<StepRecord>, TaskError> {
    let key = keys::fold_steps(t);
    let (shape, data) = env.get_npy::<f64>(&key)?;
    if shape != [nt, 4] {
        return Err(TaskError::fatal(format!(
            "{}: shape {shape:?}, expected [{nt}, 4]",
            env.out.describe(&key)
        )));
    }
    Ok(data
        .chunks_exact(4)
        .map(|c| [c[0], c[1], c[2], c[3]])
        .collect())
}

pub fn phases(env: &TaskEnv) -> Result<(Value, Vec<String>), TaskError> {
    let opened = env.open_input()?;
    let (n, nt) = traced_size(&opened);
    let det = detector(env, n)?;
    let carry = Carry::new();
    let written = RefCell::new(Vec::with_capacity(2 * n));
    let r = Phases {
        n_frames: n,
        n_triangles: nt,
        params: &det.params,
    }
    .run(
        |t| carry.wrap(read_steps(env, t, nt)),
        |t, pass, codes| {
            let key = keys::fold_phases(pass_name(pass), t);
            carry.wrap(env.put_npy(&key, &[nt], &codes))?;
            written.borrow_mut().push(key);
            Ok(())
        },
        env.progress(),
    );
    carry.finish("stretch phases", r)?;
    Ok((json!({}), written.into_inner()))
}

type Codes = (Option<Vec<PhaseCode>>, Option<Vec<PhaseCode>>);

/// Frame `t`'s phase codes: forward except at frame 0, backward except at the last frame.
fn read_codes(env: &TaskEnv, t: usize, n: usize, nt: usize) -> Result<Codes, TaskError> {
    let read = |pass: Pass| -> Result<Vec<PhaseCode>, TaskError> {
        let key = keys::fold_phases(pass_name(pass), t);
        let (shape, data) = env.get_npy::<u32>(&key)?;
        if shape != [nt] {
            return Err(TaskError::fatal(format!(
                "{}: shape {shape:?}, expected [{nt}]",
                env.out.describe(&key)
            )));
        }
        Ok(data)
    };
    Ok((
        if t > 0 {
            Some(read(Pass::Forward)?)
        } else {
            None
        },
        if t + 1 < n {
            Some(read(Pass::Backward)?)
        } else {
            None
        },
    ))
}

/// A tracing chunk (a `fold-detect` task of a stretch job).
pub fn trace(env: &TaskEnv, frames: Range<usize>) -> Result<(Value, Vec<String>), TaskError> {
    let opened = env.open_input()?;
    let (n, nt) = traced_size(&opened);
    let label = format!("stretch tracing, frames {}..{}", frames.start, frames.end);
    if !trace_chunks(env.job, n, nt).contains(&frames) {
        return Err(TaskError::fatal(format!(
            "{label}: not one of the job's tracing chunks over {n} frames"
        )));
    }
    let det = detector(env, n)?;
    let clock = std::time::Instant::now();
    let carry = Carry::new();
    let r = ChunkTracer::new(&det, opened.source.as_ref()).and_then(|mut tracer| {
        split::trace_chunk(
            &mut tracer,
            frames.clone(),
            env.job.partition.stretch_warm_up,
            |t| carry.wrap(read_codes(env, t, n, nt)),
            env.progress(),
        )
    });
    let chunk = carry.finish(&label, r)?;
    let seconds = clock.elapsed().as_secs_f64();
    let key = keys::fold_trace_chunk(frames.start);
    env.put(&key, chunk.to_binary())?;
    let timing = keys::fold_chunk_timing(frames.start);
    env.put_json(
        &timing,
        &json!({ "seconds": seconds, "frames": frames.len() }),
    )?;
    let counts: Vec<usize> = chunk
        .frames
        .iter()
        .map(|f| f.anchors.anchors.len())
        .collect();
    Ok((json!({ "anchors_per_frame": counts }), vec![key, timing]))
}

/// What `fold-merge` needs of a stretch job: the settled frames, the per-frame report lines, `folds.png`, and
/// how many frames the reconcile traced again.
pub struct Gathered {
    pub frames: Vec<FrameAnchors>,
    pub per_frame: Vec<Value>,
    pub artifacts: Vec<Artifact>,
    pub retraced: usize,
}

pub fn gather(env: &TaskEnv, opened: &OpenedSequence) -> Result<Gathered, TaskError> {
    let lap = RefCell::new(Lap::start());
    let (n, nt) = traced_size(opened);
    let det = detector(env, n)?;
    let source: &dyn FrameSource = opened.source.as_ref();
    let label = "stretch fold merge";
    let chunks = trace_chunks(env.job, n, nt);
    let mut per_frame_seconds: Vec<f64> = Vec::with_capacity(n);
    let carry = Carry::new();
    let r = ChunkTracer::new(&det, source).and_then(|tracer| {
        let tracer = RefCell::new(tracer);
        let mut read_chunk = |r: &Range<usize>| -> Result<TracedChunk, TaskError> {
            env.check_cancelled()?;
            let key = keys::fold_trace_chunk(r.start);
            let bytes = env.get(&key)?;
            let chunk = TracedChunk::from_binary(&bytes, Path::new(&env.out.describe(&key)))
                .map_err(|e| TaskError::fatal(e.to_string()))?;
            let seconds = super::folds::chunk_seconds(env, r.start)?;
            if chunk.first != r.start || chunk.frames.len() != r.len() {
                return Err(TaskError::fatal(format!(
                    "{}: holds {} frames from {}, expected frames {}..{}",
                    env.out.describe(&keys::fold_trace_chunk(r.start)),
                    chunk.frames.len(),
                    chunk.first,
                    r.start,
                    r.end
                )));
            }
            per_frame_seconds.extend(std::iter::repeat_n(
                seconds / r.len().max(1) as f64,
                r.len(),
            ));
            Ok(chunk)
        };
        let (frames, retraced) = split::reconcile(
            chunks.iter().map(|r| carry.wrap(read_chunk(r))),
            n,
            |t, seeds| {
                let (f, b) = carry.wrap(read_codes(env, t, n, nt))?;
                let mut tracer = tracer.borrow_mut();
                tracer.set_seeds(seeds);
                tracer.trace(t, f.as_deref(), b.as_deref())
            },
        )?;
        lap.borrow_mut()
            .lap("fold-merge: read and reconcile chunks");
        let mut shown = Vec::new();
        for f in &frames {
            if f.overlay.is_some() {
                let (a, b) = carry.wrap(read_codes(env, f.anchors.frame, n, nt))?;
                let o =
                    split::overlay_frame(&mut tracer.borrow_mut(), f, a.as_deref(), b.as_deref())?;
                shown.extend(o);
            }
        }
        lap.borrow_mut().lap("fold-merge: overlay frames' signals");
        let (frames, artifacts) = det.finish(
            source,
            frames.into_iter().map(|f| f.anchors).collect(),
            &shown,
        )?;
        lap.borrow_mut()
            .lap("fold-merge: temporal coherence, folds.png");
        Ok((frames, artifacts, retraced))
    });
    let (frames, artifacts, retraced) = carry.finish(label, r)?;
    // As the single detection task reported them: settled anchors, the tracing time spread over its frames.
    let per_frame = frames
        .iter()
        .zip(&per_frame_seconds)
        .map(|(f, s)| {
            json!({
                "frame": f.frame,
                "anchors": f.anchors.len(),
                "control_lines": f.control_lines.len(),
                "folds": f.detection.map(|d| d.folds),
                "seeds_tried": f.detection.and_then(|d| d.seeds_tried),
                "detection_seconds": s,
            })
        })
        .collect();
    Ok(Gathered {
        frames,
        per_frame,
        artifacts,
        retraced,
    })
}

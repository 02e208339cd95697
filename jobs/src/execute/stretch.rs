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
    let mut lap = Lap::start();
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
    lap.lap("fold-steps: step records (meshes parsed, tensors, smoothing)");
    let mut written = Vec::with_capacity(records.len());
    for (t, rec) in frames.zip(records) {
        let key = keys::fold_steps(t);
        env.put_npy(&key, &[nt, 4], rec.as_flattened())?;
        written.push(key);
    }
    lap.lap("fold-steps: write step records");
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
    let mut lap = Lap::start();
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
    let codes_seconds = std::cell::Cell::new(0.0);
    let r = ChunkTracer::new(&det, opened.source.as_ref()).and_then(|mut tracer| {
        split::trace_chunk(
            &mut tracer,
            frames.clone(),
            env.job.partition.stretch_warm_up,
            |t| {
                let c = std::time::Instant::now();
                let codes = read_codes(env, t, n, nt);
                codes_seconds.set(codes_seconds.get() + c.elapsed().as_secs_f64());
                carry.wrap(codes)
            },
            env.progress(),
        )
    });
    let chunk = carry.finish(&label, r)?;
    let seconds = clock.elapsed().as_secs_f64();
    lap.lap("fold-detect: trace (meshes parsed, signals, tracing; codes read)");
    super::phase_times::add(
        "fold-detect: of which phase codes read",
        codes_seconds.get(),
    );
    let key = keys::fold_trace_chunk(frames.start);
    env.put(&key, chunk.to_binary())?;
    lap.lap("fold-detect: write chunk");
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

/// The frames of every tracing chunk as the whole-sequence detector traced them: the chunks reconciled
/// ([`split::reconcile`]), tracing again (with a tracer made on first need) the frames whose chunk's warm-up
/// missed the true seed memory. Also returns the frames traced again, in order.
fn reconciled(
    env: &TaskEnv,
    opened: &OpenedSequence,
    det: &StretchDetector,
    label: &str,
    mut each_chunk: impl FnMut(&Range<usize>) -> Result<(), TaskError>,
) -> Result<(Vec<split::ChunkFrame>, Vec<usize>), TaskError> {
    let (n, nt) = traced_size(opened);
    let source: &dyn FrameSource = opened.source.as_ref();
    let chunks = trace_chunks(env.job, n, nt);
    let carry = Carry::new();
    let tracer: RefCell<Option<ChunkTracer>> = RefCell::new(None);
    let again = RefCell::new(Vec::new());
    let r = split::reconcile(
        chunks.iter().map(|r| {
            carry.wrap(read_trace_chunk(env, r).and_then(|c| {
                each_chunk(r)?;
                Ok(c)
            }))
        }),
        n,
        |t, seeds| {
            let (f, b) = carry.wrap(read_codes(env, t, n, nt))?;
            let mut tracer = tracer.borrow_mut();
            if tracer.is_none() {
                *tracer = Some(ChunkTracer::new(det, source)?);
            }
            let tracer = tracer.as_mut().expect("made above");
            tracer.set_seeds(seeds);
            again.borrow_mut().push(t);
            tracer.trace(t, f.as_deref(), b.as_deref())
        },
    );
    let (frames, _) = carry.finish(label, r)?;
    Ok((frames, again.into_inner()))
}

/// What `fold-merge` needs of a stretch job: the settled frames, the per-frame report lines and how many frames
/// the reconcile traced again. (`folds.png` is drawn by its own `fold-plot` task, off the job's critical
/// path: [`plot`].)
pub struct Gathered {
    pub frames: Vec<FrameAnchors>,
    pub per_frame: Vec<Value>,
    pub retraced: usize,
}

pub fn gather(env: &TaskEnv, opened: &OpenedSequence) -> Result<Gathered, TaskError> {
    let mut lap = Lap::start();
    let (n, _) = traced_size(opened);
    let det = detector(env, n)?;
    let label = "stretch fold merge";
    let mut per_frame_seconds: Vec<f64> = Vec::with_capacity(n);
    let (frames, again) = reconciled(env, opened, &det, label, |r| {
        let seconds = super::folds::chunk_seconds(env, r.start)?;
        per_frame_seconds.extend(std::iter::repeat_n(
            seconds / r.len().max(1) as f64,
            r.len(),
        ));
        Ok(())
    })?;
    lap.lap("fold-merge: read and reconcile chunks");
    let frames: Vec<FrameAnchors> = frames.into_iter().map(|f| f.anchors).collect();
    let frames = super::settle::settled(env, opened, frames, &again, label)?;
    lap.lap("fold-merge: settled ranges (read, or settled again where traced again)");
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
        retraced: again.len(),
    })
}

/// A `fold-plot` task: `folds.png` of a stretch job (see [`folds_png`]), stored under its final key.
pub fn plot(env: &TaskEnv) -> Result<(Value, Vec<String>), TaskError> {
    let opened = env.open_input()?;
    let mut written = Vec::new();
    for a in folds_png(env, &opened)? {
        env.put(&a.key, a.bytes)?;
        written.push(a.key);
    }
    Ok((json!({ "images": written.len() }), written))
}

/// `folds.png` of a stretch job (empty when it draws none): the overlay frames' fold signal and anchors as the
/// whole-sequence detector drew them. It needs only the tracing chunks (reconciled, as the merge reconciles
/// them) and the phase codes, not the settled anchors: its own `fold-plot` task runs beside the settle ranges,
/// the merge and the deformation, off the chain every deformation task waits on.
pub fn folds_png(env: &TaskEnv, opened: &OpenedSequence) -> Result<Vec<Artifact>, TaskError> {
    let mut lap = Lap::start();
    let (n, nt) = traced_size(opened);
    let det = detector(env, n)?;
    if det.overlay_size == 0 || det.overlay_frames.is_empty() {
        return Ok(Vec::new());
    }
    let label = "stretch folds.png";
    let (frames, _) = reconciled(env, opened, &det, label, |_| Ok(()))?;
    lap.lap("fold-plot: read and reconcile chunks");
    let source: &dyn FrameSource = opened.source.as_ref();
    let carry = Carry::new();
    let r = ChunkTracer::new(&det, source).and_then(|mut tracer| {
        let mut shown = Vec::new();
        for f in &frames {
            if f.overlay.is_some() {
                let (a, b) = carry.wrap(read_codes(env, f.anchors.frame, n, nt))?;
                shown.extend(split::overlay_frame(
                    &mut tracer,
                    f,
                    a.as_deref(),
                    b.as_deref(),
                )?);
            }
        }
        // Nothing to settle here (no frames): only the drawing of `finish`.
        Ok(det.finish(source, Vec::new(), &shown)?.1)
    });
    let artifacts = carry.finish(label, r)?;
    lap.lap("fold-plot: overlay frames' signals, folds.png");
    Ok(artifacts)
}

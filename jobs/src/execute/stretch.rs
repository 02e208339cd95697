//! The stretch detector's tasks ([`crate::plan::stretch`]): step records and phase codes go through storage as
//! `.npy`, traced chunks in the binary anchors form, under [`keys`]; the computation is
//! [`crease_core::folds::stretch::split`], so these functions only move data and name what is missing.

use super::env::TaskEnv;
use super::fold_chunks::{self, chunk_seconds, read_trace_chunk, traced_chunks, traced_size};
use super::phase_times::Lap;
use crate::error::TaskError;
use crate::plan::chunks::{step_chunks, trace_chunks};
use crate::storage::keys;
use crease_core::folds::stretch::overlay::OverlayFrame;
use crease_core::folds::stretch::split::{
    self, ChunkTracer, Pass, PhaseCode, Phases, StepRecord, TracedChunk,
};
use crease_core::folds::stretch::StretchDetector;
use crease_core::folds::{Anchor, Artifact, FrameAnchors};
use crease_core::mesh::io::OpenedSequence;
use crease_core::mesh::FrameSource;
use crease_core::progress::Progress;
use serde_json::{json, Value};
use std::cell::RefCell;
use std::ops::Range;

fn detector(env: &TaskEnv, n: usize) -> Result<StretchDetector, TaskError> {
    crate::plan::detect::stretch_detector(env.job, n).ok_or_else(|| {
        TaskError::fatal(format!(
            "folds of kind `{}` have no stretch detection tasks",
            env.job.folds.kind()
        ))
    })
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
    // The overlay frames of this chunk whose drawing data the task keeps for `fold-plot` (see `chunks_are_exact`).
    let overlays: Vec<usize> = if chunks_are_exact(&det) {
        frames
            .clone()
            .filter(|t| det.overlay_frames.contains(t))
            .collect()
    } else {
        Vec::new()
    };
    let clock = std::time::Instant::now();
    let carry = Carry::new();
    let codes_seconds = std::cell::Cell::new(0.0);
    let codes = |t: usize| {
        let c = std::time::Instant::now();
        let codes = read_codes(env, t, n, nt);
        codes_seconds.set(codes_seconds.get() + c.elapsed().as_secs_f64());
        carry.wrap(codes)
    };
    let mut shown = Vec::with_capacity(overlays.len());
    // Several pieces report as one stage over the chunk's frames (exact chunks: no warm-up), so the task's bar
    // counts its frames once instead of restarting at every overlay frame.
    let pieces = PiecesProgress(env.progress());
    let progress: &dyn Progress = if overlays.is_empty() {
        env.progress()
    } else {
        env.progress()
            .begin(TRACING_STAGE, (frames.end - frames.start) as u64);
        &pieces
    };
    let r = ChunkTracer::new(&det, opened.source.as_ref()).and_then(|mut tracer| {
        // Traced in pieces that end at the overlay frames, so that each overlay frame's signal is taken right
        // after its tracing, from the meshes its tracing holds. Without the seed memory (the only case with
        // overlay frames here) a frame's tracing depends on that frame alone, so the pieces give the frames one
        // piece gives.
        let mut chunk: Option<TracedChunk> = None;
        let mut start = frames.start;
        for end in overlays.iter().map(|&t| t + 1).chain([frames.end]) {
            if end <= start {
                continue;
            }
            let piece = split::trace_chunk(
                &mut tracer,
                start..end,
                env.job.partition.stretch_warm_up,
                codes,
                progress,
            )?;
            match chunk.as_mut() {
                None => chunk = Some(piece),
                Some(c) => c.frames.extend(piece.frames),
            }
            if overlays.contains(&(end - 1)) {
                let (f, b) = codes(end - 1)?;
                let last = chunk
                    .as_ref()
                    .and_then(|c| c.frames.last())
                    .expect("a piece traces at least one frame");
                shown.extend(split::overlay_frame(
                    &mut tracer,
                    last,
                    f.as_deref(),
                    b.as_deref(),
                )?);
            }
            start = end;
        }
        Ok(chunk.expect("a tracing chunk has frames"))
    });
    if !overlays.is_empty() {
        env.progress().end(TRACING_STAGE);
    }
    let chunk = carry.finish(&label, r)?;
    let seconds = clock.elapsed().as_secs_f64();
    lap.lap("fold-detect: trace (meshes parsed, signals, tracing; codes read)");
    super::phase_times::add(
        "fold-detect: of which phase codes read",
        codes_seconds.get(),
    );
    let key = keys::fold_trace_chunk(frames.start);
    env.put(&key, chunk.to_binary())?;
    let mut written = vec![key];
    for o in &shown {
        let (shape, data) = overlay_to_npy(o);
        let key = keys::fold_overlay(o.frame);
        env.put_npy(&key, &shape, &data)?;
        written.push(key);
    }
    lap.lap("fold-detect: write chunk (and overlay frames)");
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
    written.push(timing);
    Ok((json!({ "anchors_per_frame": counts }), written))
}

/// Whether the tracing chunks are exact as traced: without the seed memory a frame's folds depend on that frame
/// alone, so the reconcile never traces a frame again ([`split::reconcile`]; the `stretch_split` tests check
/// it). Then the tracing tasks keep the overlay frames' drawing data for `fold-plot`, and neither `fold-plot`
/// nor `fold-merge` reads the chunks back (the settle tasks read them). With the seed memory both reconcile
/// the chunks, and `fold-plot` computes the overlay frames' signals again.
fn chunks_are_exact(det: &StretchDetector) -> bool {
    !det.params.seed_memory
}

/// An overlay frame as one flat f64 array (every value exact: counts and triangle indices are far below 2^53):
/// `[frame, vertices, triangles, anchors, folds]`, the positions (3 per vertex), the shrinkage (1 per triangle),
/// then per anchor its triangle, axis and angle.
fn overlay_to_npy(o: &OverlayFrame) -> ([usize; 1], Vec<f64>) {
    let mut v =
        Vec::with_capacity(5 + 3 * o.positions.len() + o.shrink.len() + 5 * o.anchors.len());
    v.extend([
        o.frame as f64,
        o.positions.len() as f64,
        o.shrink.len() as f64,
        o.anchors.len() as f64,
        o.n_folds as f64,
    ]);
    v.extend(o.positions.iter().flatten());
    v.extend(&o.shrink);
    for a in &o.anchors {
        v.extend([a.triangle as f64, a.axis[0], a.axis[1], a.axis[2], a.angle]);
    }
    ([v.len()], v)
}

/// The overlay frame `t` a tracing task stored, checked against the traced mesh (`nv` vertices, `nt` triangles).
fn read_overlay(env: &TaskEnv, t: usize, nv: usize, nt: usize) -> Result<OverlayFrame, TaskError> {
    let key = keys::fold_overlay(t);
    let (_, v) = env.get_npy::<f64>(&key)?;
    let bad = |what: &str| {
        TaskError::fatal(format!(
            "{}: {what} (expected overlay frame {t} of a mesh of {nv} vertices and {nt} triangles)",
            env.out.describe(&key)
        ))
    };
    let head = v.get(..5).ok_or_else(|| bad("shorter than its header"))?;
    let k = head[3] as usize;
    if head[0] != t as f64 || head[1] != nv as f64 || head[2] != nt as f64 || head[3] != k as f64 {
        return Err(bad(&format!("header {head:?}")));
    }
    if v.len() != 5 + 3 * nv + nt + 5 * k {
        return Err(bad(&format!("{} values", v.len())));
    }
    let (p, rest) = v[5..].split_at(3 * nv);
    let (shrink, anchors) = rest.split_at(nt);
    let anchors = anchors
        .chunks_exact(5)
        .map(|a| {
            if a[0] < 0.0 || a[0] >= nt as f64 || a[0].fract() != 0.0 {
                return Err(bad(&format!("an anchor on triangle {}", a[0])));
            }
            Ok(Anchor {
                triangle: a[0] as u32,
                axis: [a[1], a[2], a[3]],
                angle: a[4],
            })
        })
        .collect::<Result<_, _>>()?;
    Ok(OverlayFrame {
        frame: t,
        positions: p.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
        shrink: shrink.to_vec(),
        anchors,
        n_folds: head[4] as usize,
    })
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
    let mut spread = |r: &Range<usize>| -> Result<(), TaskError> {
        let seconds = chunk_seconds(env, r.start)?;
        per_frame_seconds.extend(std::iter::repeat_n(
            seconds / r.len().max(1) as f64,
            r.len(),
        ));
        Ok(())
    };
    let (frames, retraced) =
        if chunks_are_exact(&det) && crate::plan::settle::settle_radius(env.job, n).is_some() {
            // The settled ranges are final as stored: no chunk to read back on the job's critical path (at 100K
            // triangles they are some 4 MB per frame, read here once more after the settle tasks read them).
            for r in &traced_chunks(env, opened).0 {
                spread(r)?;
            }
            let frames = fold_chunks::stored_settled(env, opened, n, label)?;
            lap.lap("fold-merge: settled ranges read (chunks exact, not read)");
            (frames, 0)
        } else {
            let (frames, again) = reconciled(env, opened, &det, label, spread)?;
            lap.lap("fold-merge: read and reconcile chunks");
            let frames: Vec<FrameAnchors> = frames.into_iter().map(|f| f.anchors).collect();
            let frames = fold_chunks::settled(env, opened, frames, &again, label)?;
            lap.lap("fold-merge: settled ranges (read, or settled again where traced again)");
            (frames, again.len())
        };
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
        retraced,
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
    let source: &dyn FrameSource = opened.source.as_ref();
    if chunks_are_exact(&det) {
        // Drawn from what the tracing tasks kept: the frames as traced are the final ones.
        let traced = split::traced_source(source).0.topology();
        let shown = (0..n)
            .filter(|t| det.overlay_frames.contains(t))
            .map(|t| read_overlay(env, t, traced.n_vertices(), nt))
            .collect::<Result<Vec<_>, _>>()?;
        lap.lap("fold-plot: read the overlay frames");
        let (_, artifacts) = det
            .finish(source, Vec::new(), &shown)
            .map_err(|e| TaskError::from_core(label, e))?;
        lap.lap("fold-plot: folds.png");
        return Ok(artifacts);
    }
    let (frames, _) = reconciled(env, opened, &det, label, |_| Ok(()))?;
    lap.lap("fold-plot: read and reconcile chunks");
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

/// The stage name `split::trace_chunk` reports its frames under.
const TRACING_STAGE: &str = "stretch tracing";

/// Forwards a piece's frame counts and cancellation but not its begin and end: the caller reports the whole
/// chunk as one stage, so pieces traced for the overlay frames do not show as separate bars.
struct PiecesProgress<'a>(&'a dyn Progress);

impl Progress for PiecesProgress<'_> {
    fn advance(&self, stage: &str, n: u64) {
        self.0.advance(stage, n);
    }
    fn note(&self, msg: &str) {
        self.0.note(msg);
    }
    fn cancelled(&self) -> bool {
        self.0.cancelled()
    }
}

//! Positioning tasks (Popa et al. 2009 §5.4–5.5): for each frame of a chunk, cross-fade the fields of the
//! windows covering it, position the vertices, run the stretch passes, and store the positions, the stretch
//! measured after each step and the frame's "shape kept" figures (finalize merges them in frame order).

use super::env::TaskEnv;
use super::exact;
use super::phase_times::Lap;
use crate::error::TaskError;
use crate::plan::detect::image_numbers;
use crate::plan::inspect::{output_files, output_sink, writes_frames};
use crate::spec::FoldSpec;
use crate::storage::keys;
use crease_core::folds::video::CameraRig;
use crease_core::heat::{self, SurfaceOperator};
use crease_core::mesh::io::OpenedSequence;
use crease_core::mesh::{FrameSink, FrameSource};
use crease_core::shading_refine::{ImageRefiner, ShadingRefineParams};
use crease_core::shape::ShapeAccumulator;
use crease_core::spacetime::params::Scales;
use crease_core::spacetime::position::strain_limit::{StrainLimiter, StrainReference};
use crease_core::spacetime::position::{Pinning, PositionSystem};
use crease_core::spacetime::shape::lost_area::RestAreas;
use crease_core::spacetime::shape::relief;
use crease_core::spacetime::stages::{self, FrameRefiner, PositionedFrame};
use crease_core::spacetime::windows::Window;
use crease_core::vec3::V3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use serde_json::{json, Value};
use std::ops::Range;
use std::sync::{Arc, Mutex};

/// Seconds each step of one frame took (sidecar; the only intermediate whose bytes differ between runs).
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub(crate) struct FrameTimings {
    #[serde(with = "exact")]
    pub read: f64,
    #[serde(with = "exact")]
    pub blend: f64,
    #[serde(with = "exact")]
    pub factor: f64,
    #[serde(with = "exact")]
    pub position: f64,
    pub passes: Vec<f64>,
    #[serde(with = "exact")]
    pub metrics: f64,
    #[serde(with = "exact")]
    pub symbolic: f64,
}

/// What one positioned frame hands back to the task: the storage keys it wrote and its last stretch figures.
type FrameDone = (Vec<String>, Option<Value>);

/// Positions `frames`.
pub fn position(env: &TaskEnv, frames: Range<usize>) -> Result<(Value, Vec<String>), TaskError> {
    let mut lap = Lap::start();
    let label = format!("position frames {}..{}", frames.start, frames.end);
    let opened = env.open_input()?;
    let source: &dyn FrameSource = opened.source.as_ref();
    let n = source.n_frames();
    if frames.start >= frames.end || frames.end > n {
        return Err(TaskError::fatal(format!(
            "{label}: not a frame range of the {n}-frame input"
        )));
    }
    let topo = source.topology().clone();
    let n_tri = topo.n_triangles();
    let scales = sequence_scales(env, &opened, &label)?;
    let (system, symbolic) = position_system(env, &opened, &scales, &label)?;
    let system = system.as_ref();
    let limiter = strain_limiter(env, &opened, &label)?;
    let limiter = limiter.as_deref();
    let windows = env.windows(n);
    let passes = env.params.stretch_passes;
    let reliefs = load_reliefs(env, &frames, n)?;
    let lost_area = if env.params.lost_area_bound {
        Some(rest_areas(&opened, &label)?)
    } else {
        None
    };
    let refiner = image_refiner(env, &opened, scales.detail, &label)?;
    lap.lap("position: input, system, strain limiter, reliefs");
    env.progress().begin("position", frames.len() as u64);
    let mut written = Vec::new();
    // Frame files go straight to the output through the layout's sink (the same writer `crease run` uses), one
    // sink per parallel slot of a batch, so that each frame's file is formatted and written beside the next
    // frame's positioning instead of one after the other after it. A sink of one-file-per-frame layouts holds no
    // state across frames that changes what it writes (see `writes_frames`), so the files are the same.
    let out_dir = env.output_dir(&format!("position-{}", frames.start))?;
    let batch = rayon::current_num_threads().max(1);
    let sinks: Vec<Mutex<Box<dyn FrameSink>>> = if writes_frames(env.job, &opened.layout) {
        (0..batch.min(frames.len()))
            .map(|_| {
                output_sink(env.job, &opened.layout, &topo, n, &out_dir.path)
                    .map(Mutex::new)
                    .map_err(|e| TaskError::from_core(&label, e))
            })
            .collect::<Result<_, _>>()?
    } else {
        Vec::new()
    };
    let names = output_files(env.job, &opened.layout, n);
    let mut stretch_final = Vec::new();
    // Frames in parallel, in batches of the pool size so memory stays bounded by a few frames. Each frame's
    // fields are read, the frame positioned and measured, and its intermediates and output file written inside
    // the parallel part; only the lists of keys and figures are gathered in frame order afterwards.
    let all: Vec<usize> = frames.clone().collect();
    for chunk in all.chunks(batch) {
        env.check_cancelled()?;
        let done: Vec<Result<FrameDone, TaskError>> = chunk
            .par_iter()
            .enumerate()
            .map(|(slot, &t)| {
                if env.ctx.progress.cancelled() {
                    return Err(TaskError::cancelled());
                }
                let phi = load_faded(env, &windows, t, n_tri)?;
                let heights = match &reliefs {
                    Some((first, r)) => {
                        let span = env.params.relief.span(t, n);
                        let slices: Vec<&[f64]> = r[span.start - first..span.end - first]
                            .iter()
                            .map(|v| v.as_slice())
                            .collect();
                        Some(
                            relief::heights(&topo, &env.params.relief, &slices, span.start, t)
                                .map_err(|e| TaskError::from_core(&label, e))?,
                        )
                    }
                    None => None,
                };
                let p = stages::position_frame(
                    system,
                    source,
                    t,
                    &phi,
                    passes,
                    env.params.stretch_rotation,
                    &scales.ending,
                    heights.as_deref(),
                    lost_area.as_deref(),
                    limiter,
                    refiner.as_ref().map(|r| r as &dyn FrameRefiner),
                )
                .map_err(|e| TaskError::from_core(&label, e))?;
                drop(phi);
                // The frame's "shape kept" figures (docs/fidelity.md), here where the frame is, rather than in
                // finalize, which would filter every frame again one after the other at the end of the job. The
                // drift is what crease's own low-pass at the shape scale keeps of the displacement.
                let clock = std::time::Instant::now();
                let mut shape = ShapeAccumulator::default();
                let op = SurfaceOperator::with_rims_along_themselves(&topo, &p.rest);
                let low = heat::low_pass(&op, scales.ending.shape_scale);
                shape.add_frame(&topo, &|d: &[V3]| op.apply(&low, d), &p.rest, &p.out);
                let shape_seconds = clock.elapsed().as_secs_f64();
                let keys = store_frame(env, &p, &shape, shape_seconds, frames.start, symbolic)?;
                let mut keys = keys.to_vec();
                if let Some(sink) = sinks.get(slot) {
                    sink.lock()
                        .unwrap_or_else(|e| e.into_inner())
                        .write_frame(t, &p.out)
                        .map_err(|e| TaskError::from_core(&label, e))?;
                    if let Some(name) = names.get(t) {
                        keys.push(name.clone());
                    }
                }
                env.progress().advance("position", 1);
                let last = p
                    .stretch
                    .last()
                    .map(|(_, st)| json!({"frame": t, "l2": st.l2, "max": st.max}));
                Ok((keys, last))
            })
            .collect();
        // In frame order: the first failing frame's error, else every frame's keys and figures.
        for r in done {
            let (keys, last) = r?;
            written.extend(keys);
            stretch_final.extend(last);
        }
        lap.lap("position: frames (fields, positioning, passes, shape, files)");
    }
    out_dir.upload(env)?;
    env.progress().end("position");
    Ok((
        json!({ "frames": [frames.start, frames.end], "stretch_final": stretch_final }),
        written,
    ))
}

/// The shading refinement of a video job's frames from their own images (`folds.params.refine_rounds` > 0),
/// read on whichever machine positions them, at the sequence's detail scale `detail`.
fn image_refiner(
    env: &TaskEnv,
    opened: &OpenedSequence,
    detail: f64,
    label: &str,
) -> Result<Option<ImageRefiner>, TaskError> {
    let FoldSpec::Video {
        params,
        first_image_number,
        ..
    } = &env.job.folds
    else {
        return Ok(None);
    };
    if params.refine_rounds == 0 {
        return Ok(None);
    }
    let inputs = env.fold_inputs()?;
    let path = inputs.cameras.as_deref().ok_or_else(|| {
        TaskError::fatal(format!(
            "{label}: the cameras file was not fetched for the shading refinement"
        ))
    })?;
    let rig = CameraRig::read(path, inputs.images.as_deref())
        .map_err(|e| TaskError::from_core(label, e))?;
    let n = opened.source.n_frames();
    Ok(Some(ImageRefiner {
        rig,
        numbers: image_numbers(&opened.layout, n, *first_image_number),
        params: ShadingRefineParams {
            detail_scale: detail,
            ..params.refine_params()
        },
    }))
}

/// Stores frame `p.t`'s positions, its stretch and shape words and its timings (the intermediates finalize
/// reads); returns their keys. `first` is the chunk's first frame, which carries the system's `symbolic` time.
fn store_frame(
    env: &TaskEnv,
    p: &PositionedFrame,
    shape: &ShapeAccumulator,
    shape_seconds: f64,
    first: usize,
    symbolic: f64,
) -> Result<[String; 3], TaskError> {
    let t = p.t;
    let mut words: Vec<u64> = p
        .stretch
        .iter()
        .flat_map(|(acc, _)| acc.to_words())
        .collect();
    words.extend(shape.to_words());
    // The lost-area bound's judgement of the frame, as the bits of an f64 (NaN: the bound did not run).
    words.push(p.lost_share.unwrap_or(f64::NAN).to_bits());
    // What the relief gives back of the surface the capture lost, likewise.
    words.push(p.relief_share.unwrap_or(f64::NAN).to_bits());
    let timings = FrameTimings {
        read: p.read,
        blend: p.blend,
        factor: p.factor,
        position: p.position,
        passes: p.passes.clone(),
        metrics: p.metrics + shape_seconds,
        symbolic: if t == first { symbolic } else { 0.0 },
    };
    let (kp, ks, kt) = (
        keys::positions(t),
        keys::frame_stretch(t),
        keys::frame_timings(t),
    );
    env.put_npy(&kp, &[p.out.len(), 3], p.out.as_flattened())?;
    env.put_npy(&ks, &[words.len()], &words)?;
    env.put_json(&kt, &timings)?;
    Ok([kp, ks, kt])
}

/// A positioning system this process built: (input, pinning, screen bits, system).
type BuiltSystem = (
    Arc<OpenedSequence>,
    Pinning,
    Option<u64>,
    Arc<PositionSystem>,
);

/// Positioning systems built by this process, most recent first.
static SYSTEMS: Mutex<Vec<BuiltSystem>> = Mutex::new(Vec::new());

/// The input's positioning system (its sparsity pattern and symbolic Cholesky analysis, AMD ordering included)
/// and the seconds spent building it (0 when it was already built). `crease run` in one process builds it once
/// per sequence; a job's positioning chunks each needed it again, so a worker now keeps the last two it built,
/// keyed by the very same opened input (an input changed on disk is reopened, see `TaskEnv::open_input`, and
/// then misses) and the parameters the system depends on. The system is immutable once built, so sharing it
/// cannot change what a task computes.
fn position_system(
    env: &TaskEnv,
    opened: &Arc<OpenedSequence>,
    scales: &Scales,
    label: &str,
) -> Result<(Arc<PositionSystem>, f64), TaskError> {
    let (pinning, screen) = (env.params.pinning, scales.screen);
    let screen_bits = screen.map(f64::to_bits);
    let found = |systems: &[BuiltSystem]| {
        systems
            .iter()
            .find(|(o, p, s, _)| Arc::ptr_eq(o, opened) && *p == pinning && *s == screen_bits)
            .map(|(_, _, _, sys)| Arc::clone(sys))
    };
    if let Some(sys) = found(&SYSTEMS.lock().unwrap_or_else(|p| p.into_inner())) {
        return Ok((sys, 0.0));
    }
    // Built outside the lock; two tasks that miss together both build, and the second insert wins (equal).
    let clock = std::time::Instant::now();
    let topo = opened.source.topology().clone();
    let sys = Arc::new(
        PositionSystem::new(topo, pinning, screen).map_err(|e| TaskError::from_core(label, e))?,
    );
    let seconds = clock.elapsed().as_secs_f64();
    let mut systems = SYSTEMS.lock().unwrap_or_else(|p| p.into_inner());
    if found(&systems).is_none() {
        systems.insert(
            0,
            (Arc::clone(opened), pinning, screen_bits, Arc::clone(&sys)),
        );
        systems.truncate(2);
    }
    Ok((sys, seconds))
}

/// The lengths of the job's deformation on this input ([`crease_core::spacetime::DeformParams::scales`]): the
/// detail scale (by default from the mean edge length of the input's first frame), the shape screen's cutoff,
/// the ending's shape scale. The same for every task of the job, being a function of frame 0 and the parameters.
pub(super) fn sequence_scales(
    env: &TaskEnv,
    opened: &Arc<OpenedSequence>,
    label: &str,
) -> Result<Scales, TaskError> {
    Ok(first_edge_and_scales(env, opened, label)?.1)
}

/// [`sequence_scales`] with the first frame's mean edge length they were measured by.
pub(super) fn first_edge_and_scales(
    env: &TaskEnv,
    opened: &Arc<OpenedSequence>,
    label: &str,
) -> Result<(f64, Scales), TaskError> {
    let source = &opened.source;
    let first = source
        .read_frame(0)
        .map_err(|e| TaskError::from_core(label, e))?;
    let edge = crease_core::shape::mean_edge_length(source.topology(), &first);
    if !(edge.is_finite() && edge > 0.0) {
        return Err(TaskError::fatal(format!(
            "{label}: the first frame ({}) has mean edge length {edge}: no length to measure the folds by",
            source.describe_frame(0)
        )));
    }
    Ok((edge, env.params.scales(edge)))
}

/// The reliefs the heights of `frames` read (their spans), as (first frame, reliefs), or None when the job has
/// no relief.
#[allow(clippy::type_complexity)]
fn load_reliefs(
    env: &TaskEnv,
    frames: &Range<usize>,
    n: usize,
) -> Result<Option<(usize, Vec<Vec<f64>>)>, TaskError> {
    if !crate::plan::graph::has_relief(env.job) {
        return Ok(None);
    }
    let p = &env.params.relief;
    let (lo, hi) = (p.span(frames.start, n).start, p.span(frames.end - 1, n).end);
    let reliefs = (lo..hi)
        .into_par_iter()
        .map(|k| env.get_npy::<f64>(&keys::relief(k)).map(|(_, v)| v))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Some((lo, reliefs)))
}

/// A strain limiter this process built: (input, cap bits, sweeps, reference, limiter).
type BuiltLimiter = (
    Arc<OpenedSequence>,
    u64,
    usize,
    StrainReference,
    Arc<StrainLimiter>,
);

/// Strain limiters built by this process, most recent first.
static LIMITERS: Mutex<Vec<BuiltLimiter>> = Mutex::new(Vec::new());

/// The job's strain limiter (None when off). Its sequence reference, each edge's longest captured length,
/// needs every input frame, which a positioning chunk does not otherwise read; a worker builds it once per
/// opened input and settings and keeps the last two, like [`position_system`]. The lengths are a maximum, exact
/// in any reading order, so every task (and `crease_core::spacetime::deform`) limits against the same bits.
fn strain_limiter(
    env: &TaskEnv,
    opened: &Arc<OpenedSequence>,
    label: &str,
) -> Result<Option<Arc<StrainLimiter>>, TaskError> {
    let p = &env.params;
    if p.strain_limit == 0.0 {
        return Ok(None);
    }
    let key = (
        p.strain_limit.to_bits(),
        p.strain_limit_sweeps,
        p.strain_reference,
    );
    let found = |built: &[BuiltLimiter]| {
        built
            .iter()
            .find(|(o, c, s, r, _)| Arc::ptr_eq(o, opened) && (*c, *s, *r) == key)
            .map(|(.., l)| Arc::clone(l))
    };
    if let Some(l) = found(&LIMITERS.lock().unwrap_or_else(|p| p.into_inner())) {
        return Ok(Some(l));
    }
    let Some(limiter) = p
        .strain_limiter(opened.source.as_ref())
        .map_err(|e| TaskError::from_core(&format!("{label}: strain limit"), e))?
    else {
        return Ok(None);
    };
    let limiter = Arc::new(limiter);
    let mut built = LIMITERS.lock().unwrap_or_else(|p| p.into_inner());
    if found(&built).is_none() {
        built.insert(
            0,
            (
                Arc::clone(opened),
                key.0,
                key.1,
                key.2,
                Arc::clone(&limiter),
            ),
        );
        built.truncate(2);
    }
    Ok(Some(limiter))
}

/// The bound of what the deformation adds for `opened` (the surface each neighbourhood shows at its largest over the sequence),
/// built once per process and input like the strain limiter: it reads every frame.
pub(super) fn rest_areas(
    opened: &Arc<OpenedSequence>,
    label: &str,
) -> Result<Arc<RestAreas>, TaskError> {
    type Built = (Arc<OpenedSequence>, Arc<RestAreas>);
    static BUILT: Mutex<Vec<Built>> = Mutex::new(Vec::new());
    let found = |built: &[Built]| {
        built
            .iter()
            .find(|(o, _)| Arc::ptr_eq(o, opened))
            .map(|(_, a)| Arc::clone(a))
    };
    if let Some(a) = found(&BUILT.lock().unwrap_or_else(|p| p.into_inner())) {
        return Ok(a);
    }
    let areas = Arc::new(
        RestAreas::of_sequence(opened.source.as_ref())
            .map_err(|e| TaskError::from_core(&format!("{label}: rest areas"), e))?,
    );
    let mut built = BUILT.lock().unwrap_or_else(|p| p.into_inner());
    if found(&built).is_none() {
        built.insert(0, (Arc::clone(opened), Arc::clone(&areas)));
        built.truncate(2);
    }
    Ok(areas)
}

/// The cross-faded rotation-vector field of frame `t`, from the stored fields of the windows covering it.
fn load_faded(
    env: &TaskEnv,
    windows: &[Window],
    t: usize,
    n_tri: usize,
) -> Result<Vec<V3>, TaskError> {
    let mut slices: Vec<(usize, Vec<V3>)> = Vec::new();
    for k in stages::windows_covering(windows, t) {
        let key = keys::window_field(k, t);
        let (shape, data) = env.get_npy::<f64>(&key)?;
        if shape != [n_tri, 3] {
            return Err(TaskError::fatal(format!(
                "{}: shape {shape:?}, expected ({n_tri}, 3)",
                env.out.describe(&key)
            )));
        }
        slices.push((
            k,
            data.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
        ));
    }
    stages::crossfade_frame(windows, t, n_tri, |k| {
        slices
            .iter()
            .find(|(j, _)| *j == k)
            .map(|(_, v)| v.as_slice())
            .ok_or_else(|| {
                crease_core::Error::param(
                    "window field",
                    format!("window {k} missing for frame {t}"),
                )
            })
    })
    .map_err(|e| TaskError::fatal(format!("frame {t}: {e}")))
}

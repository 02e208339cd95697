//! `crease deep apply`: a trained model run on a pose sequence or on coarse meshes, writing the
//! output contract. Every frame depends only on the inputs (pose history included) and the model, never on
//! which other frames were computed in the same run, so a frame range gives the same bytes as the full run:
//! that is what lets the job system split apply into frame chunks.

use crate::contract;
pub use crate::detail::relief::CoarseDetail;
use crate::detail::relief::{blend, in_part, CoarseRelief};
use crate::detail::{Prediction, SurfaceGate};
use crate::model::{Model, RegressorKind};
use crate::normal_maps::raster::TexelMap;
use crate::normal_maps::{convert_space, world_from_vertex_normals, NormalMap, Space};
use crate::regression::pose::read_pose_file;
use crease_core::mesh::io::open_sequence;
use crease_core::mesh::{geometry, Frame, FrameSource};
use crease_core::progress::Progress;
use crease_core::vec3::V3;
use crease_core::{Error, Result};
use std::ops::Range;
use std::path::{Path, PathBuf};

/// Frames whose relief is computed together (their maps then run in parallel).
const RELIEF_CHUNK: usize = 32;

#[derive(Debug, Clone)]
pub enum ApplyInput {
    /// A pose file: shapes come from the regression.
    Pose(PathBuf),
    /// A coarse mesh sequence in the model's topology (e.g. a capture).
    Coarse(PathBuf),
}

#[derive(Debug, Clone)]
pub struct ApplyParams {
    pub space: Space,
    /// Overrides the model's regressor for `--pose`.
    pub regressor: Option<RegressorKind>,
    /// Frames to write (0-based, end exclusive); all when `None`.
    pub frames: Option<Range<usize>>,
    /// Skip the cGAN and write the coarse maps (for comparisons).
    pub no_cgan: bool,
    /// Where a capture's detail comes from (`--coarse` only); `None`: where the model's training decided
    /// ([`Model::coarse_detail`]).
    pub coarse_detail: Option<CoarseDetail>,
}

impl Default for ApplyParams {
    fn default() -> Self {
        ApplyParams {
            space: Space::World,
            regressor: None,
            frames: None,
            no_cgan: false,
            coarse_detail: None,
        }
    }
}

/// The coarse shapes of every input frame: the regression's (from poses) or the given meshes.
pub enum CoarseShapes {
    Frames(Vec<Frame>),
    Source(Box<dyn FrameSource>),
}

impl CoarseShapes {
    pub fn n_frames(&self) -> usize {
        match self {
            CoarseShapes::Frames(f) => f.len(),
            CoarseShapes::Source(s) => s.n_frames(),
        }
    }
    pub fn frame(&self, t: usize) -> Result<Frame> {
        match self {
            CoarseShapes::Frames(f) => Ok(f[t].clone()),
            CoarseShapes::Source(s) => s.read_frame(t),
        }
    }
}

/// Shapes predicted from a pose file: the regression's reconstruction of [`coefficients_from_poses`], as it is
/// (`apply --pose` smooths it first when the model says so: [`pose_shapes`]).
pub fn shapes_from_poses(
    model: &Model,
    pose_path: &Path,
    regressor: RegressorKind,
) -> Result<Vec<Frame>> {
    Ok(coefficients_from_poses(model, pose_path, regressor)?
        .iter()
        .map(|c| model.subspace.reconstruct(c))
        .collect())
}

/// The shapes `apply --pose` writes for the frames in `range`: the regression's coefficients, reconstructed
/// and low-passed as the model's `pose_lowpass` says ([`crate::regression::pose_lowpass`]). Frames outside
/// `range` stay empty (a chunk smooths only its own frames).
pub fn pose_shapes(
    model: &Model,
    pose_path: &Path,
    regressor: RegressorKind,
    range: Option<Range<usize>>,
) -> Result<Vec<Frame>> {
    let coeffs = coefficients_from_poses(model, pose_path, regressor)?;
    let range = range.unwrap_or(0..coeffs.len());
    let lowpass = model.manifest.pose_lowpass;
    Ok(coeffs
        .iter()
        .enumerate()
        .map(|(t, c)| {
            if range.contains(&t) {
                lowpass.shape(&model.topology, &model.subspace, c)
            } else {
                Vec::new()
            }
        })
        .collect())
}

/// Subspace coefficients predicted from a pose file (the whole file: controls need the history, and the
/// autoregressive regressor is rolled out from the first frame on its own predictions, so every frame range of
/// a chunked apply recomputes the same rollout: a linear map per frame, cheap next to the maps).
pub fn coefficients_from_poses(
    model: &Model,
    pose_path: &Path,
    regressor: RegressorKind,
) -> Result<Vec<Vec<f64>>> {
    let poses = read_pose_file(pose_path, None)?;
    if poses[0].len() != model.manifest.control.pose_dim() {
        return Err(Error::format(
            pose_path,
            None,
            format!(
                "pose vectors have {} numbers; the model was trained on {}",
                poses[0].len(),
                model.manifest.control.pose_dim()
            ),
        ));
    }
    let controls = model.manifest.control.controls(&poses)?;
    let coeffs: Vec<Vec<f64>> = match regressor {
        RegressorKind::Linear => controls.iter().map(|c| model.linear.predict(c)).collect(),
        RegressorKind::Autoregressive => model
            .autoregressive
            .as_ref()
            .ok_or_else(|| model.missing_regressor(regressor))?
            .rollout(&controls),
        RegressorKind::Blend => {
            let (ar, blend) = match (&model.autoregressive, &model.manifest.blend) {
                (Some(ar), Some(b)) => (ar, b),
                _ => return Err(model.missing_regressor(regressor)),
            };
            let linear: Vec<Vec<f64>> = controls.iter().map(|c| model.linear.predict(c)).collect();
            crate::regression::blend::mix(&linear, &ar.rollout(&controls), blend.weight)
        }
        RegressorKind::Kernel => model
            .kernel
            .as_ref()
            .ok_or_else(|| model.missing_regressor(regressor))?
            .predict_sequence(&poses),
        RegressorKind::Lstm => {
            let net = model
                .lstm
                .as_ref()
                .ok_or_else(|| model.missing_regressor(regressor))?;
            // A residual network (format 7 on) adds to its base regressor's coefficients.
            let base = match net.config.residual_of {
                Some(kind) => {
                    let ar = model.autoregressive.as_ref();
                    let (ar, weight) = match (kind, ar, &model.manifest.blend) {
                        (RegressorKind::Linear, _, _) => (None, 0.0),
                        (RegressorKind::Autoregressive, Some(ar), _) => (Some(ar), 1.0),
                        (RegressorKind::Blend, Some(ar), Some(b)) => (Some(ar), b.weight),
                        _ => return Err(model.missing_regressor(kind)),
                    };
                    let lin: Vec<Vec<f64>> =
                        controls.iter().map(|c| model.linear.predict(c)).collect();
                    Some(match ar {
                        None => lin,
                        Some(ar) => {
                            crate::regression::blend::mix(&lin, &ar.rollout(&controls), weight)
                        }
                    })
                }
                None => None,
            };
            net.predict_sequence(&controls, base.as_deref())?
        }
    };
    Ok(coeffs)
}

/// Frames of a pose file whose recent poses lie further than [`crate::regression::kernel::OUTSIDE`] from every
/// training frame's, with their distance; none for the other regressors (their maps extrapolate linearly).
fn poses_outside(
    model: &Model,
    pose_path: &Path,
    regressor: RegressorKind,
) -> Result<Vec<(usize, f64)>> {
    let kernel = match (regressor, &model.kernel) {
        (RegressorKind::Kernel, Some(k)) => k,
        _ => return Ok(Vec::new()),
    };
    let poses = read_pose_file(pose_path, None)?;
    Ok(kernel
        .distances(&poses)
        .into_iter()
        .enumerate()
        .filter(|(_, d)| *d > crate::regression::kernel::OUTSIDE)
        .collect())
}

/// Opens coarse meshes and checks them against the model's topology, naming the file on a mismatch.
pub fn open_coarse(model: &Model, dir: &Path) -> Result<Box<dyn FrameSource>> {
    let opened = open_sequence(dir)?;
    let topo = opened.source.topology();
    if topo.n_vertices() != model.topology.n_vertices()
        || topo.triangles() != model.topology.triangles()
    {
        return Err(Error::Mesh {
            path: Some(dir.to_path_buf()),
            frame: None,
            msg: format!(
                "{} vertices / {} triangles do not match the model's topology ({} / {}); {}",
                topo.n_vertices(),
                topo.n_triangles(),
                model.topology.n_vertices(),
                model.topology.n_triangles(),
                opened.source.describe_frame(0)
            ),
        });
    }
    Ok(opened.source)
}

/// What an apply wrote: how many frames, and which of them got the input's own normals and why.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ApplySummary {
    pub frames: usize,
    /// (0-based frame, reason) of every frame the detail model's guard sent back to the input's normals.
    pub fallback: Vec<(usize, String)>,
    /// (0-based frame, distance) of every pose-path frame whose recent poses lie outside what the kernel
    /// regressor learned ([`crate::regression::kernel::OUTSIDE`] training standard deviations from every
    /// training frame's): its shape is little more than the mean shape.
    pub outside: Vec<(usize, f64)>,
}

/// Runs the model on `input` and writes frames (all, or `params.frames`) into `out`. A coarse frame whose scale
/// the model was not trained for is an error naming it; one the detail model's guard rejects gets the input's
/// own normals, and its OBJ says so (`# normals: …`), as does the summary.
pub fn apply(
    model: &Model,
    input: &ApplyInput,
    params: &ApplyParams,
    out: &Path,
    progress: &dyn Progress,
) -> Result<ApplySummary> {
    let shapes = match input {
        ApplyInput::Pose(p) => CoarseShapes::Frames(pose_shapes(
            model,
            p,
            params.regressor.unwrap_or(model.manifest.regressor),
            params.frames.clone(),
        )?),
        ApplyInput::Coarse(d) => CoarseShapes::Source(open_coarse(model, d)?),
    };
    let n = shapes.n_frames();
    let range = params.frames.clone().unwrap_or(0..n);
    let outside = match input {
        ApplyInput::Pose(p) => poses_outside(
            model,
            p,
            params.regressor.unwrap_or(model.manifest.regressor),
        )?,
        ApplyInput::Coarse(_) => Vec::new(),
    };
    if range.start >= range.end || range.end > n {
        return Err(Error::param(
            "frames",
            format!(
                "{}..{} is not a frame range of this {n}-frame input",
                range.start + 1,
                range.end
            ),
        ));
    }
    let res = model.manifest.resolution;
    let texels = TexelMap::new(&model.layout, res, res);
    let enhancer = if params.no_cgan {
        None
    } else {
        crate::cgan::enhance::Enhancer::for_model(model)?.filter(|e| match input {
            ApplyInput::Coarse(_) => e.spec.use_coarse,
            ApplyInput::Pose(_) => e.spec.use_pose,
        })
    };
    let capture = match input {
        ApplyInput::Coarse(d) => Some(d.as_path()),
        ApplyInput::Pose(_) => None,
    };
    let detail = params
        .coarse_detail
        .unwrap_or_else(|| model.coarse_detail());
    let mut relief = match (&shapes, capture, detail) {
        (CoarseShapes::Source(s), Some(_), CoarseDetail::Relief | CoarseDetail::Blend) => {
            Some(CoarseRelief::new(s.as_ref())?)
        }
        _ => None,
    };
    // Whether the capture lost surface is asked of all its frames, whatever the range written, so that any
    // frame range gives the whole run's bytes; they are streamed through, one at a time.
    let gate = match &shapes {
        CoarseShapes::Source(s) if capture.is_some() => {
            let mut failed = None;
            let frames = (0..s.n_frames()).map_while(|t| match s.read_frame(t) {
                Ok(f) => Some(f),
                Err(e) => {
                    failed = Some(e);
                    None
                }
            });
            let gate = model.detail.surface_gate(&model.topology, frames);
            if let Some(e) = failed {
                return Err(e);
            }
            gate
        }
        _ => SurfaceGate::OPEN,
    };
    contract::prepare(out)?;
    let writer = contract::FrameWriter::new(&model.topology, &model.layout);
    progress.begin("apply", range.len() as u64);
    let one_frame = |t: usize,
                     heights: Option<(&[f64], &CoarseRelief)>,
                     scratch: &mut contract::FrameScratch|
     -> Result<Option<String>> {
        if progress.cancelled() {
            return Err(Error::Cancelled);
        }
        let c = shapes.frame(t)?;
        let relieved = heights.map(|(h, r)| r.relieved(&model.topology, &c, h));
        let source = match (capture, relieved.as_deref()) {
            (Some(path), Some(r)) if detail == CoarseDetail::Blend => {
                Source::Blended(path, r, gate)
            }
            (Some(path), Some(r)) => Source::Relieved(path, r, gate),
            (Some(path), None) => Source::Capture(path, gate),
            (None, _) => Source::Pose,
        };
        let f = frame_map(
            model,
            &texels,
            &c,
            source,
            t,
            enhancer.as_ref(),
            params.space,
        )?;
        writer.write(out, t, &c, &f.map, &f.note, scratch)?;
        progress.advance("apply", 1);
        Ok(f.fallback)
    };
    // Frames are independent (the cGAN sees one frame's map, never another's output, and the relief of a
    // frame reads only the captured frames around it), so their files are the same bytes in any order and in
    // any frame range. The relief is computed a chunk of frames at a time, so that its memory stays bounded on
    // long sequences. Without a cGAN the chunk's frames run in parallel (each thread with its own buffers);
    // the cGAN's own loops use every core, so with one the frames run one after another. The parallel run
    // keeps every frame's outcome so that the error reported is the first failing frame's, whichever thread
    // met an error first.
    let all: Vec<usize> = range.clone().collect();
    let mut fallbacks: Vec<Option<String>> = Vec::with_capacity(all.len());
    let mut scratch = contract::FrameScratch::default();
    for chunk in all.chunks(RELIEF_CHUNK) {
        let heights = match (&mut relief, &shapes) {
            (Some(r), CoarseShapes::Source(s)) => Some(r.heights(s.as_ref(), chunk)?),
            _ => None,
        };
        let bound = relief.as_ref();
        let h = |k: usize| heights.as_ref().map(|h| h[k].as_slice()).zip(bound);
        if enhancer.is_none() && rayon::current_num_threads() > 1 {
            use rayon::prelude::*;
            let done: Vec<Result<Option<String>>> = chunk
                .par_iter()
                .enumerate()
                .map_init(contract::FrameScratch::default, |s, (k, &t)| {
                    one_frame(t, h(k), s)
                })
                .collect();
            for d in done {
                fallbacks.push(d?);
            }
        } else {
            for (k, &t) in chunk.iter().enumerate() {
                fallbacks.push(one_frame(t, h(k), &mut scratch)?);
            }
        }
    }
    contract::sync_frames(out, range.clone())?;
    progress.end("apply");
    if params.frames.is_none() {
        contract::finish(out, n, params.space, res, "crease deep apply")?;
    }
    if let Some((t, d)) = outside.iter().find(|(t, _)| range.contains(t)) {
        progress.note(&format!(
            "frame {} and {} more: the poses lie outside what the kernel regressor learned ({d:.2} training standard deviations from the nearest training frame's); those shapes are close to the mean shape",
            t + 1,
            outside.iter().filter(|(u, _)| range.contains(u)).count() - 1
        ));
    }
    Ok(ApplySummary {
        frames: range.len(),
        outside: outside
            .into_iter()
            .filter(|(t, _)| range.contains(t))
            .collect(),
        fallback: range
            .zip(fallbacks)
            .filter_map(|(t, f)| f.map(|r| (t, r)))
            .collect(),
    })
}

/// Where a frame's coarse shape came from.
#[derive(Debug, Clone, Copy)]
pub enum Source<'a> {
    /// The regression (`apply --pose`).
    Pose,
    /// A capture read from this path (`apply --coarse`): the detail model runs on it, with what the capture's
    /// lost surface lets it add.
    Capture(&'a Path, SurfaceGate),
    /// A capture read from this path, the frame with its fold relief ([`crate::detail::relief`]), and what the
    /// capture's lost surface lets the relief add.
    Relieved(&'a Path, &'a [V3], SurfaceGate),
    /// As `Relieved`, drawn as the midpoint of the relieved frame and the detail model's fine shape
    /// ([`crate::detail::relief::blend`]).
    Blended(&'a Path, &'a [V3], SurfaceGate),
}

/// One frame's map, the note its OBJ carries, and the guard's reason when it fell back.
pub struct FrameMap {
    pub map: NormalMap,
    pub note: String,
    pub fallback: Option<String>,
}

/// One frame's map: from a capture, the detail model's normals (or, past its guard, the capture's own) or those
/// of the capture with its fold relief; from the regression, the shape's own normals; then `enhancer` (the
/// cGAN, where the caller decided to use it; not on a frame that fell back), in the asked space.
pub fn frame_map(
    model: &Model,
    texels: &TexelMap,
    coarse: &[V3],
    source: Source,
    t: usize,
    enhancer: Option<&crate::cgan::enhance::Enhancer>,
    space: Space,
) -> Result<FrameMap> {
    let topo = &model.topology;
    let (normals, mut note, fallback) = match source {
        Source::Capture(path, gate) => {
            let what = format!("{} frame {}", path.display(), t + 1);
            let h = model.detail.check_scale(topo, coarse, &what)?;
            match model.detail.predict(topo, coarse, h, gate) {
                Prediction::Fine { shape, share } => (
                    geometry::vertex_normals(topo, &shape),
                    if share < 1.0 {
                        format!(
                            "the detail model's at {:.0} % (the capture lost little of the garment's surface)",
                            share * 100.0
                        )
                    } else {
                        "the detail model's".to_string()
                    },
                    None,
                ),
                Prediction::Fallback(why) => (
                    geometry::vertex_normals(topo, coarse),
                    format!("the input's own (the detail model fell back: {why})"),
                    Some(why.to_string()),
                ),
            }
        }
        Source::Relieved(path, relieved, gate) | Source::Blended(path, relieved, gate) => {
            let blended = matches!(source, Source::Blended(..));
            let what = format!("{} frame {}", path.display(), t + 1);
            // The unit check stands: the maps and the cGAN were made for the training garment's scale.
            let h = model.detail.check_scale(topo, coarse, &what)?;
            if relieved.len() != coarse.len() {
                return Err(Error::param(
                    "relief",
                    format!(
                        "{what}: {} relieved vertices for {}",
                        relieved.len(),
                        coarse.len()
                    ),
                ));
            }
            let what = if blended {
                "the midpoint of crease's fold relief and the detail model's shape"
            } else {
                "crease's fold relief"
            };
            match (gate.share, gate.fallback()) {
                (_, Some(why)) => (
                    geometry::vertex_normals(topo, coarse),
                    format!("the input's own (no relief: {why})"),
                    Some(why.to_string()),
                ),
                (share, None) => {
                    let mut shape = if share < 1.0 {
                        in_part(coarse, relieved, share)
                    } else {
                        relieved.to_vec()
                    };
                    if blended {
                        shape = blend(&shape, &model.detail.fine_or_coarse(topo, coarse, h, gate));
                    }
                    let note = if share < 1.0 {
                        format!(
                            "{what} at {:.0} % (the capture lost little of the garment's surface)",
                            share * 100.0
                        )
                    } else {
                        what.to_string()
                    };
                    (geometry::vertex_normals(topo, &shape), note, None)
                }
            }
        }
        Source::Pose => (
            geometry::vertex_normals(topo, coarse),
            "the pose regression's shape".to_string(),
            None,
        ),
    };
    let mut map = world_from_vertex_normals(texels, topo, &normals);
    if let (Some(e), None) = (enhancer, &fallback) {
        map = e.enhance(&map)?;
        note.push_str(", enhanced by the cGAN");
    }
    if space == Space::Tangent {
        map = convert_space(&map, texels, topo, coarse, &model.layout, true);
    }
    Ok(FrameMap {
        map,
        note,
        fallback,
    })
}

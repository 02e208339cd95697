//! `crease deep apply`: a trained model run on a pose sequence or on coarse meshes, writing the DESIGN §7
//! output contract. Every frame depends only on the inputs (pose history included) and the model, never on
//! which other frames were computed in the same run, so a frame range gives the same bytes as the full run:
//! that is what lets the job system split apply into frame chunks.

use crate::contract;
use crate::detail::{DetailFilter, Umbrella};
use crate::model::{Model, RegressorKind};
use crate::normal_maps::raster::TexelMap;
use crate::normal_maps::{bake_coarse, convert_space, world_from_vertex_normals, NormalMap, Space};
use crate::regression::pose::read_pose_file;
use crease_core::mesh::io::open_sequence;
use crease_core::mesh::{geometry, Frame, FrameSource, Topology};
use crease_core::progress::Progress;
use crease_core::vec3::V3;
use crease_core::{Error, Result};
use std::ops::Range;
use std::path::{Path, PathBuf};

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
}

impl Default for ApplyParams {
    fn default() -> Self {
        ApplyParams {
            space: Space::World,
            regressor: None,
            frames: None,
            no_cgan: false,
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

/// The shapes `apply --pose` writes for the frames in `range`: the regression's coefficients, made smooth by the
/// model's `pose_smoothing` (format 8 on; [`crate::regression::pose_smoothing`]), or reconstructed as they are. Frames
/// outside `range` stay empty (a chunk smooths only its own frames).
pub fn pose_shapes(
    model: &Model,
    pose_path: &Path,
    regressor: RegressorKind,
    range: Option<Range<usize>>,
) -> Result<Vec<Frame>> {
    let coeffs = coefficients_from_poses(model, pose_path, regressor)?;
    let range = range.unwrap_or(0..coeffs.len());
    let smoothing = model.manifest.pose_smoothing.as_ref();
    let filter = smoothing.and_then(|s| s.filter(&model.topology));
    Ok(coeffs
        .iter()
        .enumerate()
        .map(|(t, c)| match smoothing {
            _ if !range.contains(&t) => Vec::new(),
            Some(s) => s.shape(&model.subspace, filter.as_ref(), c),
            None => model.subspace.reconstruct(c),
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

/// Runs the model on `input` and writes frames (all, or `params.frames`) into `out`.
pub fn apply(
    model: &Model,
    input: &ApplyInput,
    params: &ApplyParams,
    out: &Path,
    progress: &dyn Progress,
) -> Result<usize> {
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
        crate::cgan::enhance::Enhancer::for_model(model)?
    };
    // The detail filter learned captured → fine; a regression's reconstruction is no capture (it sharpens the
    // mixed-in folds: docs/deepwrinkles.md, "Pose-only normals taken apart"), so poses get the map of their
    // (smoothed) shape.
    let op = crate::detail::Umbrella::new(&model.topology);
    let detail = match input {
        ApplyInput::Coarse(_) => model.detail.as_ref().map(|f| (f, &op)),
        ApplyInput::Pose(_) => None,
    };
    contract::prepare(out)?;
    let writer = contract::FrameWriter::new(&model.topology, &model.layout);
    progress.begin("apply", range.len() as u64);
    let one_frame = |t: usize, scratch: &mut ApplyScratch| -> Result<()> {
        if progress.cancelled() {
            return Err(Error::Cancelled);
        }
        let c = shapes.frame(t)?;
        let map = frame_map_with(
            model,
            &texels,
            &c,
            detail,
            enhancer.as_ref(),
            params.space,
            scratch,
        )?;
        writer.write(out, t, &c, &map, &mut scratch.files)?;
        progress.advance("apply", 1);
        Ok(())
    };
    // Each frame needs its predecessor's map only through the cGAN's input, never its output, so frames are
    // independent and their files the same bytes in any order. Without a cGAN they run in parallel (each
    // thread with its own buffers, so memory stays at a frame per thread); the cGAN's own loops use every
    // core, so with one the frames run one after another.
    if enhancer.is_none() && rayon::current_num_threads() > 1 {
        use rayon::prelude::*;
        range
            .clone()
            .into_par_iter()
            .try_for_each_init(ApplyScratch::default, |s, t| one_frame(t, s))?;
    } else {
        let mut scratch = ApplyScratch::default();
        for t in range.clone() {
            one_frame(t, &mut scratch)?;
        }
    }
    contract::sync_frames(out, range.clone())?;
    progress.end("apply");
    if params.frames.is_none() {
        contract::finish(out, n, params.space, res, "crease deep apply")?;
    }
    Ok(range.len())
}

/// Buffers one thread of `apply` reuses from frame to frame.
#[derive(Debug, Default)]
pub struct ApplyScratch {
    filter: crate::detail::FilterScratch,
    fine: Vec<V3>,
    files: contract::FrameScratch,
}

/// The map of a captured mesh's predicted fine shape: the vertex normals of `filter`'s prediction interpolated
/// over the coarse mesh's faces (the coarse mesh stays the surface the map belongs to).
pub fn detail_map(
    texels: &TexelMap,
    topo: &Topology,
    op: &Umbrella,
    filter: &DetailFilter,
    coarse: &[V3],
) -> NormalMap {
    detail_map_with(
        texels,
        topo,
        op,
        filter,
        coarse,
        &mut ApplyScratch::default(),
    )
}

/// [`detail_map`] with `scratch`'s buffers.
pub fn detail_map_with(
    texels: &TexelMap,
    topo: &Topology,
    op: &Umbrella,
    filter: &DetailFilter,
    coarse: &[V3],
    scratch: &mut ApplyScratch,
) -> NormalMap {
    filter.apply_into(op, coarse, &mut scratch.fine, &mut scratch.filter);
    world_from_vertex_normals(texels, topo, &geometry::vertex_normals(topo, &scratch.fine))
}

/// One frame's map: the coarse map (or, with a detail filter, the map of the predicted fine shape), enhanced by
/// the cGAN when the model has one, in the asked space.
pub fn frame_map(
    model: &Model,
    texels: &TexelMap,
    coarse: &[V3],
    detail: Option<(&DetailFilter, &Umbrella)>,
    enhancer: Option<&crate::cgan::enhance::Enhancer>,
    space: Space,
) -> Result<NormalMap> {
    frame_map_with(
        model,
        texels,
        coarse,
        detail,
        enhancer,
        space,
        &mut ApplyScratch::default(),
    )
}

/// [`frame_map`] with `scratch`'s buffers.
pub fn frame_map_with(
    model: &Model,
    texels: &TexelMap,
    coarse: &[V3],
    detail: Option<(&DetailFilter, &Umbrella)>,
    enhancer: Option<&crate::cgan::enhance::Enhancer>,
    space: Space,
    scratch: &mut ApplyScratch,
) -> Result<NormalMap> {
    let mut map = match detail {
        Some((f, op)) => detail_map_with(texels, &model.topology, op, f, coarse, scratch),
        None => bake_coarse(texels, &model.topology, coarse),
    };
    if let Some(e) = enhancer {
        map = e.enhance(&map)?;
    }
    if space == Space::Tangent {
        map = convert_space(&map, texels, &model.topology, coarse, &model.layout, true);
    }
    Ok(map)
}

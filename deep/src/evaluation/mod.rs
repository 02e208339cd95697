//! `crease deep eval`: how well a model does on sequences it was not trained on, by the normal error of its
//! maps and the shape error of its meshes, beside the captured input's own normal error.
//!
//! Scoring (per original vertex and frame): the map's normal, sampled at the vertex's UVs and averaged over its
//! corners, against the ground truth's area-weighted vertex normal (the map normal error); the mean distance
//! of the output mesh's vertices to the ground truth's (the shape error); and the same angle between the
//! input mesh's own vertex normals and the ground truth's (what the maps have to beat). The maps are scored
//! in memory, as `apply` would write them (16-bit PNGs differ by less than 0.01°).

pub mod loso;
pub mod strip;
pub mod table1;

use crate::apply::{frame_map, CoarseDetail, Source};
use crate::detail::relief::CoarseRelief;
use crate::model::Model;
use crate::normal_maps::bake::map_normal_error;
use crate::normal_maps::raster::TexelMap;
use crate::normal_maps::uv::UvLayout;
use crate::normal_maps::{sample_vertex_normals, world_from_vertex_normals, Space};
use crate::subspace::vertex_error;
use crease_core::mesh::{geometry, Frame, Sequence, Topology};
use crease_core::vec3::V3;
use crease_core::Result;
use rayon::prelude::*;
use serde::Serialize;
use std::path::Path;

/// Mean figures of one path on one sequence.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Score {
    pub frames: usize,
    /// Map normal error (°).
    pub map_deg: f64,
    /// Output mesh's vertex normals against the ground truth's (°).
    pub mesh_deg: f64,
    /// Input mesh's own normal error (°): the captured mesh's for a capture, 0 when there is none.
    pub input_deg: f64,
    /// The map of the input mesh's own normals, scored as the maps are (°; 0 when there is no input): what a
    /// frame the guard sends back gets, and so what the maps must never be worse than. Above `input_deg` where
    /// the input's normals vary faster than the map's texels follow.
    pub input_map_deg: f64,
    /// Shape error (mm).
    pub shape_mm: f64,
    /// Frames the detail model's guard sent back to the input's normals.
    pub fallback_frames: usize,
}

/// One frame's output: its mesh, the map's normals per vertex, and whether the guard fell back.
struct FrameScore {
    map_deg: f64,
    mesh_deg: f64,
    input_deg: f64,
    input_map_deg: f64,
    shape_mm: f64,
    fallback: bool,
}

fn mean_of(frames: &[FrameScore]) -> Score {
    let n = frames.len().max(1) as f64;
    Score {
        frames: frames.len(),
        map_deg: frames.iter().map(|f| f.map_deg).sum::<f64>() / n,
        mesh_deg: frames.iter().map(|f| f.mesh_deg).sum::<f64>() / n,
        input_deg: frames.iter().map(|f| f.input_deg).sum::<f64>() / n,
        input_map_deg: frames.iter().map(|f| f.input_map_deg).sum::<f64>() / n,
        shape_mm: frames.iter().map(|f| f.shape_mm).sum::<f64>() / n,
        fallback_frames: frames.iter().filter(|f| f.fallback).count(),
    }
}

fn angle_deg(topo: &Topology, a: &[V3], b: &[V3]) -> f64 {
    crate::normal_maps::bake::mesh_normal_error(topo, a, b)
}

/// Frames to score: every `step`-th of `range`.
pub fn frames_to_score(range: std::ops::Range<usize>, step: usize) -> Vec<usize> {
    range.step_by(step.max(1)).collect()
}

/// The model's coarse path on a capture of `gt` (same frames), with its detail from `detail`, scored on
/// `frames` (increasing).
pub fn score_capture(
    model: &Model,
    capture: &[Frame],
    capture_path: &Path,
    gt: &[Frame],
    frames: &[usize],
    detail: CoarseDetail,
) -> Result<Score> {
    let res = model.manifest.resolution;
    let texels = TexelMap::new(&model.layout, res, res);
    let topo = &model.topology;
    let relieved: Option<Vec<Frame>> = match detail {
        CoarseDetail::Relief | CoarseDetail::Blend => {
            let seq = Sequence::new(topo.clone(), capture.to_vec())?;
            let mut relief = CoarseRelief::new(&seq)?;
            let heights = relief.heights(&seq, frames)?;
            Some(
                frames
                    .iter()
                    .zip(&heights)
                    .map(|(&t, h)| relief.relieved(topo, &capture[t], h))
                    .collect(),
            )
        }
        CoarseDetail::Model => None,
    };
    let gate = model
        .detail
        .surface_gate(topo, capture.iter().map(|f| f.as_slice()));
    let scores: Vec<FrameScore> = frames
        .par_iter()
        .enumerate()
        .map(|(k, &t)| {
            let c = &capture[t];
            let source = match &relieved {
                Some(r) if detail == CoarseDetail::Blend => {
                    Source::Blended(capture_path, &r[k], gate)
                }
                Some(r) => Source::Relieved(capture_path, &r[k], gate),
                None => Source::Capture(capture_path, gate),
            };
            let f = frame_map(model, &texels, c, source, t, None, Space::World)?;
            let sampled = sample_vertex_normals(&f.map, topo, &model.layout);
            let own = world_from_vertex_normals(&texels, topo, &geometry::vertex_normals(topo, c));
            let own = sample_vertex_normals(&own, topo, &model.layout);
            Ok(FrameScore {
                map_deg: map_normal_error(&sampled, topo, &gt[t]).0,
                mesh_deg: angle_deg(topo, c, &gt[t]),
                input_deg: angle_deg(topo, c, &gt[t]),
                input_map_deg: map_normal_error(&own, topo, &gt[t]).0,
                shape_mm: 1e3 * vertex_error(c, &gt[t]).0,
                fallback: f.fallback.is_some(),
            })
        })
        .collect::<Result<_>>()?;
    Ok(mean_of(&scores))
}

/// Shapes (the pose path's, or any other) scored as `apply --pose` draws them: the map of the shape's own
/// normals.
pub fn score_shapes(
    topo: &Topology,
    layout: &UvLayout,
    resolution: usize,
    shapes: &[Frame],
    gt: &[Frame],
    frames: &[usize],
) -> Score {
    let texels = TexelMap::new(layout, resolution, resolution);
    let scores: Vec<FrameScore> = frames
        .par_iter()
        .map(|&t| {
            let s = &shapes[t];
            let map = world_from_vertex_normals(&texels, topo, &geometry::vertex_normals(topo, s));
            let sampled = sample_vertex_normals(&map, topo, layout);
            FrameScore {
                map_deg: map_normal_error(&sampled, topo, &gt[t]).0,
                mesh_deg: angle_deg(topo, s, &gt[t]),
                input_deg: 0.0,
                input_map_deg: 0.0,
                shape_mm: 1e3 * vertex_error(s, &gt[t]).0,
                fallback: false,
            }
        })
        .collect();
    mean_of(&scores)
}

//! `crease bake`: the detailed output of any mode (or gt) turned into normal maps on the coarse input, so an
//! engine can render the folds on the coarse mesh. The detailed sequence may have its own topology (a
//! subdivided output, a scan): it is only ray-cast against.

use crate::contract;
use crate::normal_maps::raster::TexelMap;
use crate::normal_maps::uv::UvLayout;
use crate::normal_maps::{bake_fine, convert_space, FineSurface, Space};
use crease_core::mesh::{geometry, FrameSource, Topology};
use crease_core::progress::Progress;
use crease_core::vec3::{self, V3};
use crease_core::{Error, Result};
use rayon::prelude::*;
use std::path::Path;

/// Options of a bake.
#[derive(Debug, Clone)]
pub struct BakeParams {
    pub resolution: usize,
    pub space: Space,
    /// How far (in mean coarse edge lengths) a texel's ray may travel to meet the detailed surface.
    pub max_dist_edges: f64,
}

impl Default for BakeParams {
    fn default() -> Self {
        BakeParams {
            resolution: super::DEFAULT_RESOLUTION,
            space: Space::World,
            max_dist_edges: 8.0,
        }
    }
}

impl BakeParams {
    pub fn validate(&self) -> Result<()> {
        if !(8..=8192).contains(&self.resolution) {
            return Err(Error::param(
                "resolution",
                format!("{} is outside 8..=8192", self.resolution),
            ));
        }
        if !(self.max_dist_edges.is_finite() && self.max_dist_edges > 0.0) {
            return Err(Error::param(
                "max-dist",
                "must be a positive number of edge lengths",
            ));
        }
        Ok(())
    }
}

pub fn mean_edge_length(topo: &Topology, p: &[V3]) -> f64 {
    let mut s = 0.0;
    let mut c = 0usize;
    for t in topo.triangles() {
        for k in 0..3 {
            s += vec3::norm(vec3::sub(p[t[k] as usize], p[t[(k + 1) % 3] as usize]));
            c += 1;
        }
    }
    s / c.max(1) as f64
}

/// Bakes every frame of `detailed` onto the same frame of `coarse` and writes the output contract into `out`.
pub fn bake_sequence(
    coarse: &dyn FrameSource,
    detailed: &dyn FrameSource,
    layout: &UvLayout,
    params: &BakeParams,
    out: &Path,
    progress: &dyn Progress,
) -> Result<()> {
    params.validate()?;
    let n = coarse.n_frames();
    if detailed.n_frames() != n {
        return Err(Error::param(
            "detailed",
            format!(
                "{} has {} frames, the coarse sequence {} has {n}",
                detailed.describe_frame(0),
                detailed.n_frames(),
                coarse.describe_frame(0)
            ),
        ));
    }
    let topo = coarse.topology().clone();
    layout.check(&topo, "coarse mesh")?;
    let texels = TexelMap::new(layout, params.resolution, params.resolution);
    contract::prepare(out)?;
    let writer = contract::FrameWriter::new(&topo, layout);
    progress.begin("bake", n as u64);
    // Frames in parallel, each one whole: memory stays at a few frames. Every frame's outcome is kept, so that
    // a bad input names its first bad frame rather than the one some thread met first.
    let outcomes: Vec<Result<()>> = (0..n)
        .into_par_iter()
        .map_init(
            contract::FrameScratch::default,
            |scratch, t| -> Result<()> {
                if progress.cancelled() {
                    return Err(Error::Cancelled);
                }
                let c = coarse.read_frame(t)?;
                let d = detailed.read_frame(t)?;
                let fine = FineSurface::new(detailed.topology(), &d)?;
                let max_dist = params.max_dist_edges * mean_edge_length(&topo, &c);
                let mut map = bake_fine(&texels, &topo, &c, &fine, max_dist);
                if params.space == Space::Tangent {
                    map = convert_space(&map, &texels, &topo, &c, layout, true);
                }
                writer.write(
                    out,
                    t,
                    &c,
                    &map,
                    "baked from the detailed sequence",
                    scratch,
                )?;
                progress.advance("bake", 1);
                Ok(())
            },
        )
        .collect();
    outcomes.into_iter().collect::<Result<()>>()?;
    contract::sync_frames(out, 0..n)?;
    progress.end("bake");
    contract::finish(out, n, params.space, params.resolution, "crease bake")
}

/// Normal error (docs/fidelity.md) of maps against a reference: per original vertex, the map normal sampled at its
/// UVs and averaged over its corners, against the reference's area-weighted vertex normal. Returns (mean
/// angle in degrees, share of vertices the map reached).
pub fn map_normal_error(
    map_normals: &[Option<V3>],
    reference_topo: &Topology,
    reference: &[V3],
) -> (f64, f64) {
    let gt = geometry::vertex_normals(reference_topo, reference);
    let (mut s, mut c) = (0.0, 0usize);
    for (m, g) in map_normals.iter().zip(&gt) {
        if let Some(m) = m {
            s += vec3::dot(*m, *g).clamp(-1.0, 1.0).acos().to_degrees();
            c += 1;
        }
    }
    (
        s / c.max(1) as f64,
        c as f64 / map_normals.len().max(1) as f64,
    )
}

/// Mean angle (degrees) between two meshes' area-weighted vertex normals (same topology).
pub fn mesh_normal_error(topo: &Topology, a: &[V3], b: &[V3]) -> f64 {
    let na = geometry::vertex_normals(topo, a);
    let nb = geometry::vertex_normals(topo, b);
    na.iter()
        .zip(&nb)
        .map(|(x, y)| vec3::dot(*x, *y).clamp(-1.0, 1.0).acos().to_degrees())
        .sum::<f64>()
        / na.len().max(1) as f64
}

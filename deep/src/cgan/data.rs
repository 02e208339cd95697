//! Training pairs for the cGAN (§4.1): per frame, the coarse map of an input shape (captured, registration,
//! subspace or regression reconstruction) and the detailed map of the fine mesh projected onto that shape,
//! with the previous frame's detailed map for the temporal term.

use crate::cgan::Sample;
use crate::normal_maps::raster::TexelMap;
use crate::normal_maps::{bake_coarse, bake_fine, FineSurface, NormalMap};
use crease_core::mesh::{Frame, Topology};
use crease_core::Result;
use rayon::prelude::*;

/// (coarse map, detailed map) of every frame of one sequence.
pub fn map_pairs(
    topo: &Topology,
    texels: &TexelMap,
    coarse: &[Frame],
    fine: &[Frame],
    max_dist_edges: f64,
) -> Result<Vec<(NormalMap, NormalMap)>> {
    coarse
        .par_iter()
        .zip(fine.par_iter())
        .map(|(c, f)| {
            let lr = bake_coarse(texels, topo, c);
            let surface = FineSurface::new(topo, f)?;
            let max_dist = max_dist_edges * crate::normal_maps::bake::mean_edge_length(topo, c);
            let hr = bake_fine(texels, topo, c, &surface, max_dist);
            Ok((lr, hr))
        })
        .collect()
}

/// Samples of one sequence; frame 0 uses its own target as the previous one.
pub fn samples(pairs: &[(NormalMap, NormalMap)]) -> Vec<Sample> {
    (0..pairs.len())
        .map(|t| Sample {
            input: pairs[t].0.clone(),
            target: pairs[t].1.clone(),
            prev_target: pairs[t.saturating_sub(1)].1.clone(),
        })
        .collect()
}

//! How much of the surface a capture lost the fold relief gives back, over the whole sequence, before the
//! deformation: the median over frames of [`Trace::share`], the figure `report.json` gives as
//! `summary.lost_area.median_relief_share` (the same frames, heights and rest areas the positioning uses, so
//! the two agree). A video job's fold merge reads it to tell a capture that blurred its folds, where the
//! geometry's folds sit on what is left of them, from one that erased them, where the geometry knows only the
//! band that lost length and its anchors would put crests in the wrong places.
//!
//! [`Trace::share`]: crease_core::spacetime::shape::lost_area::Trace::share

use super::env::TaskEnv;
use crate::error::TaskError;
use crate::storage::keys;
use crease_core::mesh::io::OpenedSequence;
use crease_core::spacetime::shape::relief;
use rayon::prelude::*;
use std::sync::Arc;

/// The median relief share of the job's input, or `None` when the job has no relief or no frame lost surface.
/// Reads every frame's relief (the relief tasks must have run).
pub fn median_relief_share(
    env: &TaskEnv,
    opened: &Arc<OpenedSequence>,
) -> Result<Option<f64>, TaskError> {
    if !crate::plan::graph::has_relief(env.job) {
        return Ok(None);
    }
    let label = "fold merge: capture trace";
    let source = opened.source.as_ref();
    let topo = source.topology();
    let n = source.n_frames();
    // Built once per process and input, shared with the positioning tasks that run here.
    let areas = super::position::rest_areas(opened, label)?;
    let reliefs = (0..n)
        .into_par_iter()
        .map(|k| env.get_npy::<f64>(&keys::relief(k)).map(|(_, v)| v))
        .collect::<Result<Vec<_>, _>>()?;
    let p = &env.params.relief;
    let shares = (0..n)
        .into_par_iter()
        .map(|t| {
            let span = p.span(t, n);
            let slices: Vec<&[f64]> = reliefs[span.clone()].iter().map(|v| v.as_slice()).collect();
            let h = relief::heights(topo, p, &slices, span.start, t)
                .map_err(|e| TaskError::from_core(label, e))?;
            let rest = source
                .read_frame(t)
                .map_err(|e| TaskError::from_core(label, e))?;
            let relieved = relief::add_heights(topo, &rest, &rest, &h);
            Ok(areas
                .trace(topo, &rest, &relieved)
                .and_then(|tr| tr.share()))
        })
        .collect::<Result<Vec<_>, TaskError>>()?;
    let mut s: Vec<f64> = shares.into_iter().flatten().collect();
    s.sort_by(f64::total_cmp);
    Ok(s.get(s.len() / 2).copied())
}

//! Realising traced folds as anchors (Chen 2011 §4.4–4.5): the triangles the control lines cross.
//!
//! Folds are traced on the input mesh, where the fold width, α and the patch radius have the sizes the thesis
//! gives them in edge lengths of the capture. When the deformation runs on a subdivided mesh (so folds narrower
//! than an input triangle can form), the same control lines are realised on it: each sample, a barycentric point
//! of an input triangle, names the subdivided triangle holding it ([`Subdivision::locate`]). The tracer samples
//! the lines densely enough for the finer triangles ([`super::trace::FoldTracer::new`]).

use super::trace::TracedFold;
use crate::folds::Anchor;
use crate::mesh::subdivide::Subdivision;
use std::collections::BTreeMap;

/// The anchors of `folds`, on the traced mesh (`sub` = `None`) or on its subdivision. A triangle crossed by
/// several lines keeps the first one's anchor (folds in tracing order, strongest first). Sorted by triangle.
pub fn anchors(folds: &[TracedFold], sub: Option<&Subdivision>) -> Vec<Anchor> {
    let mut out: BTreeMap<u32, Anchor> = BTreeMap::new();
    for s in folds.iter().flat_map(|f| &f.samples) {
        let triangle = match sub {
            None => s.triangle,
            Some(sub) => sub.locate(s.triangle as usize, s.bary).0 as u32,
        };
        out.entry(triangle).or_insert(Anchor {
            triangle,
            axis: s.axis,
            angle: s.angle,
        });
    }
    out.into_values().collect()
}

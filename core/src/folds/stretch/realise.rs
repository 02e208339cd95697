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
use crate::vec3;

/// The anchors of `folds`, on the traced mesh (`sub` = `None`) or on its subdivision. A triangle crossed by
/// several folds keeps the first fold's anchor (folds in tracing order, strongest first); several samples of one
/// fold on one triangle are averaged, so the anchor does not depend on the order the lines were walked in.
/// Sorted by triangle.
///
/// Per fold, its samples are sorted by (triangle, sample order) and summed triangle by triangle in sample
/// order; which triangles earlier folds took is a flag per triangle. This runs once per frame on the sequential
/// path after the seeds, so it avoids the ordered maps (one node per anchor) it was first written with; the
/// sums are the same additions in the same order.
pub fn anchors(folds: &[TracedFold], sub: Option<&Subdivision>) -> Vec<Anchor> {
    let mut out: Vec<Anchor> = Vec::new();
    let mut taken: Vec<bool> = Vec::new();
    // (triangle, index of the sample in its fold) of the fold at hand.
    let mut mine: Vec<(u32, u32)> = Vec::new();
    for fold in folds {
        mine.clear();
        for (k, s) in fold.samples.iter().enumerate() {
            let triangle = match sub {
                None => s.triangle,
                Some(sub) => sub.locate(s.triangle as usize, s.bary).0 as u32,
            };
            if taken.get(triangle as usize).copied().unwrap_or(false) {
                continue;
            }
            mine.push((triangle, k as u32));
        }
        mine.sort_unstable();
        for group in mine.chunk_by(|a, b| a.0 == b.0) {
            let triangle = group[0].0;
            let (mut axis, mut angle) = ([0.0; 3], 0.0);
            for &(_, k) in group {
                let s = &fold.samples[k as usize];
                axis = vec3::add(axis, s.axis);
                angle += s.angle;
            }
            let len = vec3::norm(axis);
            if len > 1e-12 {
                if taken.len() <= triangle as usize {
                    taken.resize(triangle as usize + 1, false);
                }
                taken[triangle as usize] = true;
                out.push(Anchor {
                    triangle,
                    axis: vec3::scale(axis, 1.0 / len),
                    angle: angle / group.len() as f64,
                });
            }
        }
    }
    // Unique: a triangle is taken by one fold at most.
    out.sort_unstable_by_key(|a| a.triangle);
    out
}

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
use crate::vec3::{self, V3};
use std::collections::BTreeMap;

/// The anchors of `folds`, on the traced mesh (`sub` = `None`) or on its subdivision. A triangle crossed by
/// several folds keeps the first fold's anchor (folds in tracing order, strongest first); several samples of one
/// fold on one triangle are averaged, so the anchor does not depend on the order the lines were walked in.
/// Sorted by triangle.
pub fn anchors(folds: &[TracedFold], sub: Option<&Subdivision>) -> Vec<Anchor> {
    let mut out: BTreeMap<u32, Anchor> = BTreeMap::new();
    for fold in folds {
        let mut mine: BTreeMap<u32, (V3, f64, usize)> = BTreeMap::new();
        for s in &fold.samples {
            let triangle = match sub {
                None => s.triangle,
                Some(sub) => sub.locate(s.triangle as usize, s.bary).0 as u32,
            };
            if out.contains_key(&triangle) {
                continue;
            }
            let e = mine.entry(triangle).or_insert(([0.0; 3], 0.0, 0));
            e.0 = vec3::add(e.0, s.axis);
            e.1 += s.angle;
            e.2 += 1;
        }
        for (triangle, (axis, angle, n)) in mine {
            let len = vec3::norm(axis);
            if len > 1e-12 {
                out.insert(
                    triangle,
                    Anchor {
                        triangle,
                        axis: vec3::scale(axis, 1.0 / len),
                        angle: angle / n as f64,
                    },
                );
            }
        }
    }
    out.into_values().collect()
}

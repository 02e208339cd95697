//! Realising traced folds as anchors (Chen 2011 §4.4–4.5): the triangles the control lines cross.
//!
//! Folds are traced on the input mesh, where the fold width, α and the patch radius have the sizes the thesis
//! gives them in edge lengths of the capture. When the deformation runs on a subdivided mesh (so folds narrower
//! than an input triangle can form), the same control lines are realised on it: each sample, a barycentric point
//! of an input triangle, names the subdivided triangle holding it ([`Subdivision::locate`]). The tracer samples
//! the lines densely enough for the finer triangles ([`super::tracer::FoldTracer::new`]).

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::folds::stretch::trace::LineSample;
    use crate::vec3::V3;
    use std::collections::BTreeMap;

    /// The first implementation, with ordered maps: what [`anchors`] must give bit for bit.
    fn anchors_with_maps(folds: &[TracedFold], sub: Option<&Subdivision>) -> Vec<Anchor> {
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

    fn uniform(state: &mut u64) -> f64 {
        *state ^= *state << 13;
        *state ^= *state >> 7;
        *state ^= *state << 17;
        (*state >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Folds crossing each other's triangles, several samples per triangle in no order, samples whose axes
    /// cancel (no anchor, so a later fold may take the triangle), on the traced mesh and on its subdivision:
    /// the same anchors, bit for bit, as the ordered-map implementation.
    #[test]
    fn anchors_are_those_of_the_ordered_maps() {
        let (topo, _) = crate::synth::sheet(9, 9, 0.1).unwrap();
        let sub = Subdivision::new(&topo, 1).unwrap();
        let n = topo.n_triangles() as u32;
        let mut state = 0x853c_49e6_748f_ea9bu64;
        let mut folds = Vec::new();
        for _ in 0..12 {
            let mut samples = Vec::new();
            for _ in 0..40 {
                let triangle = (uniform(&mut state) * 30.0) as u32 % n;
                let u = uniform(&mut state);
                let v = (1.0 - u) * uniform(&mut state);
                let axis = if uniform(&mut state) < 0.1 {
                    [0.0; 3]
                } else {
                    vec3::normalize([
                        uniform(&mut state) - 0.5,
                        uniform(&mut state) - 0.5,
                        uniform(&mut state) - 0.5,
                    ])
                };
                samples.push(LineSample {
                    triangle,
                    bary: [1.0 - u - v, u, v],
                    point: [0.0; 3],
                    axis,
                    angle: uniform(&mut state),
                });
            }
            // Opposite axes on the last triangle cancel in the first fold (no anchor there); the next fold
            // takes it.
            let last = LineSample {
                triangle: n - 1,
                bary: [0.2, 0.3, 0.5],
                point: [0.0; 3],
                axis: [0.0, 0.6, 0.8],
                angle: 0.25,
            };
            samples.push(last);
            if folds.is_empty() {
                samples.push(LineSample {
                    axis: [0.0, -0.6, -0.8],
                    ..last
                });
            }
            folds.push(TracedFold {
                seed: 0,
                change: 1.1,
                width: 1.0,
                axis: Vec::new(),
                direction: [1.0, 0.0, 0.0],
                lines: Vec::new(),
                samples,
            });
        }
        let mut checked = 0;
        for sub in [None, Some(&sub)] {
            let want = anchors_with_maps(&folds, sub);
            let got = anchors(&folds, sub);
            assert!(want.len() > 20, "{}", want.len());
            if sub.is_none() {
                let a = want.last().unwrap();
                assert!(
                    a.triangle == n - 1 && (a.axis[2] - 0.8).abs() < 1e-12,
                    "{a:?}"
                );
            }
            assert_eq!(format!("{got:?}"), format!("{want:?}"));
            checked += got.len();
        }
        assert!(checked > 40);
        assert!(anchors(&[], None).is_empty());
    }
}

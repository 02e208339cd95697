//! Fold restoration: give back the fold amplitude the capture smoothed away, in phase with the folds the
//! capture still shows.
//!
//! A capture system low-passes the cloth: folds a few edges wide lose most of their height, but not all of it
//! (the public data's filter keeps 46% of a fold 6 edges long and 84% at 8). What is left sits exactly where the
//! real ridges and valleys are, on the right side. The fold detectors, on the other hand, know *where* the
//! cloth folded (it shrank there, or the video shows edge pairs) but only guess the ridge positions and sides:
//! their anchors' sign agrees with the real folds on about 65–70% of the moving vertices.
//!
//! So, after positioning, each vertex is pushed along the captured normal by `gain` times the captured
//! surface's residual under the capture filter applied once more (x − C(x), along the normal: the Taubin filter
//! of [`crate::shape`], the one that defines drift), weighted by how far the deformation already tilted that
//! part of the garment. A fold the capture kept a fraction T of has residual (1 − T) of what is left, and
//! needs 1/T − 1 of it back: gain ≈ 1/T. The default gain 2 is 1/T for a fold of 6 edges on the public data's
//! meshes (T = 0.46, data/README.md), the middle of the band the capture damped without erasing; shapes the
//! capture kept whole (T = 1, 10 edges and longer: the garment's own curvature, wide pleats) have no residual
//! and are left alone, which keeps the drift low. T depends on the mesh (0.82 at 6 edges on an equilateral
//! grid), which is why the gain is a parameter.
//!
//! The weight is the deformation's tilt of the vertex normal, smoothed over two rings and divided by
//! [`REFERENCE_TILT_DEG`] (clamped to 1): restoration only happens where a detector put folds, so a sequence
//! without anchors still comes back bit for bit, and a garment at rest is not sharpened.

use crate::mesh::{geometry, Topology};
use crate::shape::TaubinFilter;
use crate::vec3::{self, V3};

/// Smoothed tilt (degrees) at which the restoration weight reaches 1: about the anchor angle of the weakest
/// fold the stretch detector makes (linear law, gain 4 × minimum shrinkage 0.02 = 4.6°), so that every
/// detected fold is restored fully and only the fading edges of the deformation partly.
pub const REFERENCE_TILT_DEG: f64 = 5.0;

/// How strongly folds are restored.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Restoration {
    /// Multiple of the captured surface's residual under the capture filter added along its normal where the
    /// weight is 1.
    pub gain: f64,
    /// Smoothed tilt (radians) of the deformed vertex normal at which the weight reaches 1.
    pub reference_tilt: f64,
}

impl Restoration {
    /// Whether this restoration changes anything.
    pub fn is_active(&self) -> bool {
        self.gain != 0.0 && self.reference_tilt > 0.0
    }

    /// The restored positions: `out` plus the captured surface's residual along its normal, where the
    /// deformation (from `rest` to `out`) tilted the surface. `out` is returned unchanged when the restoration
    /// is inactive or `out` equals `rest`.
    ///
    /// Builds the connectivity tables of [`RestoreMesh`] on every call; a caller restoring many frames of one
    /// mesh builds them once and calls [`Restoration::apply_with`] (same result, bit for bit).
    pub fn apply(&self, topo: &Topology, rest: &[V3], out: &[V3]) -> Vec<V3> {
        if !self.is_active() || out == rest {
            return out.to_vec();
        }
        self.apply_with(topo, &RestoreMesh::new(topo), rest, out)
    }

    /// [`Restoration::apply`] with the connectivity tables built beforehand (`mesh` must be `topo`'s).
    pub fn apply_with(
        &self,
        topo: &Topology,
        mesh: &RestoreMesh,
        rest: &[V3],
        out: &[V3],
    ) -> Vec<V3> {
        if !self.is_active() || out == rest {
            return out.to_vec();
        }
        let n = rest.len();
        let n_rest = geometry::vertex_normals(topo, rest);
        let n_out = geometry::vertex_normals(topo, out);
        // The capture filter applied once more: what it takes away now is the trace of what it took before.
        let smooth = mesh.filter.apply(rest);
        let mut weight: Vec<f64> = (0..n)
            // atan2 of |sin| and cos: exactly 0 where the normal did not change (acos of a rounded dot is not).
            .map(|v| {
                vec3::norm(vec3::cross(n_rest[v], n_out[v])).atan2(vec3::dot(n_rest[v], n_out[v]))
            })
            .collect();
        let mut next = vec![0.0; n];
        for _ in 0..2 {
            for (v, w) in next.iter_mut().enumerate() {
                let nb = mesh.ring(v);
                let sum: f64 = nb.iter().map(|&u| weight[u as usize]).sum::<f64>() + weight[v];
                *w = sum / (nb.len() + 1) as f64;
            }
            std::mem::swap(&mut weight, &mut next);
        }
        (0..n)
            .map(|v| {
                let w = (weight[v] / self.reference_tilt).min(1.0);
                if w.is_nan() || w <= 0.0 || vec3::norm(n_rest[v]) == 0.0 {
                    return out[v];
                }
                let height = vec3::dot(vec3::sub(rest[v], smooth[v]), n_rest[v]);
                vec3::add(out[v], vec3::scale(n_rest[v], self.gain * w * height))
            })
            .collect()
    }
}

/// What the restoration needs of the connectivity, which is the same for every frame: the capture filter
/// (its neighbour lists) and every vertex's one-ring for the tilt smoothing. Building them takes a sorted
/// neighbour list per vertex (one allocation each), about as long as the 40 filter sweeps themselves, so the
/// deformation builds them once per sequence ([`super::position::PositionSystem::restore_mesh`]).
pub struct RestoreMesh {
    filter: TaubinFilter,
    ring_offsets: Vec<u32>,
    ring: Vec<u32>,
}

impl RestoreMesh {
    pub fn new(topo: &Topology) -> Self {
        let nv = topo.n_vertices();
        let mut ring_offsets = Vec::with_capacity(nv + 1);
        let mut ring = Vec::with_capacity(6 * nv);
        ring_offsets.push(0u32);
        for v in 0..nv {
            // Sorted and unique, as `Topology::vertex_neighbors` gives them (the smoothing sums in this order).
            ring.extend(topo.vertex_neighbors(v));
            ring_offsets.push(ring.len() as u32);
        }
        RestoreMesh {
            filter: TaubinFilter::captured(topo),
            ring_offsets,
            ring,
        }
    }

    fn ring(&self, v: usize) -> &[u32] {
        &self.ring[self.ring_offsets[v] as usize..self.ring_offsets[v + 1] as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat grid of `nx` × `ny` vertices, spacing 1, with a ripple of wavelength `wl` along x of height `amp`.
    fn rippled_grid(nx: usize, ny: usize, wl: f64, amp: f64) -> (Topology, Vec<V3>) {
        let mut p = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                let x = i as f64 + 0.5 * (j % 2) as f64;
                let y = j as f64 * 0.75f64.sqrt();
                p.push([x, y, amp * (2.0 * std::f64::consts::PI * x / wl).sin()]);
            }
        }
        let mut tris = Vec::new();
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let a = (j * nx + i) as u32;
                let (b, c, d) = (a + 1, a + nx as u32, a + nx as u32 + 1);
                if j % 2 == 0 {
                    tris.push([a, b, c]);
                    tris.push([b, d, c]);
                } else {
                    tris.push([a, b, d]);
                    tris.push([a, d, c]);
                }
            }
        }
        (Topology::new(nx * ny, tris).unwrap(), p)
    }

    #[test]
    fn nothing_moved_gives_the_input_back() {
        let (topo, p) = rippled_grid(12, 10, 6.0, 0.2);
        let r = Restoration {
            gain: 2.0,
            reference_tilt: 0.1,
        };
        assert_eq!(r.apply(&topo, &p, &p), p);
    }

    /// Where the deformation tilted the surface, the captured ripple grows in place (same sign, same crest),
    /// by gain · (1 − T(ℓ)) of itself in the middle of the grid; two rings beyond the tilted part nothing moves.
    #[test]
    fn a_tilted_ripple_grows_in_phase_and_the_rest_stays() {
        let (topo, rest) = rippled_grid(24, 16, 6.0, 0.1);
        // A "deformation" that tilts the left half only: a bump of the right half keeps it still.
        let out: Vec<V3> = rest
            .iter()
            .map(|q| {
                if q[0] < 10.0 {
                    [q[0], q[1], q[2] + 0.3 * (q[0] * 0.8).sin()]
                } else {
                    *q
                }
            })
            .collect();
        let r = Restoration {
            gain: 2.0,
            reference_tilt: 1e-3,
        };
        let got = r.apply(&topo, &rest, &out);
        let mut checked = 0;
        for v in 0..rest.len() {
            let added = got[v][2] - out[v][2];
            let (x, y) = (rest[v][0], rest[v][1]);
            if x > 14.0 {
                assert_eq!(got[v], out[v], "vertex {v} far from the tilt moved");
            }
            let interior = (3.0..8.0).contains(&x) && (3.0..10.0).contains(&y);
            if interior && rest[v][2].abs() > 0.05 {
                // The captured ripple itself, amplified: same sign, gain · (1 − T) of it, T = 0.82 the capture
                // filter's gain at 6 edges on this equilateral grid ((1 − 0.5 μ)(1 + 0.53 μ))^20, μ = 0.256.
                let ratio = added / rest[v][2];
                assert!(ratio > 0.28 && ratio < 0.45, "vertex {v}: ratio {ratio}");
                checked += 1;
            }
        }
        assert!(checked > 5, "{checked}");
    }

    #[test]
    fn inactive_restoration_changes_nothing() {
        let (topo, rest) = rippled_grid(8, 8, 5.0, 0.2);
        let out: Vec<V3> = rest
            .iter()
            .map(|q| [q[0], q[1], q[2] + 0.1 * q[0]])
            .collect();
        for r in [
            Restoration {
                gain: 0.0,
                reference_tilt: 0.1,
            },
            Restoration {
                gain: 2.0,
                reference_tilt: 0.0,
            },
        ] {
            assert_eq!(r.apply(&topo, &rest, &out), out);
        }
    }
}

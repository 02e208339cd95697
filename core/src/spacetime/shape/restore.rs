//! Fold restoration: give back the fold amplitude the capture smoothed away, in phase with the folds the
//! capture still shows.
//!
//! A capture system low-passes the cloth: folds a few edges wide lose most of their height, but not all of it
//! (the public data's filter keeps 18% of a fold 5 edges long, 46% at 6 and 84% at 8). What is left sits
//! exactly where the real ridges and valleys are, on the right side. The fold detectors, on the other hand,
//! know *where* the cloth folded (it shrank there, or the video shows edge pairs) but only guess the ridge
//! positions and sides: their anchors' sign agrees with the real folds on about 65–70% of the moving vertices.
//!
//! So, after positioning, each vertex is pushed along the captured normal by what a deconvolution of the
//! capture filter C (the Taubin filter that made the public data, [`TaubinFilter::capture`]) adds
//! to the captured surface c, weighted by how far the deformation already tilted that part of the garment. The
//! deconvolution is Van Cittert's iteration g ← g + (c − C(g)) from g = c, `steps` times (a fractional part is
//! a last, partial step), evaluated as one Chebyshev series in the filter's averaging operator
//! ([`super::deconvolve`]: 74 sweeps instead of 400 at 5 steps, the same result to rounding). A component the capture kept a fraction T of comes back as 1 − (1 − T)^(steps + 1)
//! of its original height: never more than it had (no overshoot, unlike a fixed gain on c − C(c), which gives
//! T(1 + gain(1 − T)) and so exceeds 1 for every T above 1/gain), all of it where the capture kept most of it,
//! and at most `steps + 1` times the captured residue where it kept almost nothing, which bounds what noise can
//! gain. One step is the old restoration with gain 1. Shapes the capture kept whole (T = 1: wavelengths of 10
//! edges and more, the garment's own curvature, wide pleats) are fixed points and are left alone, which keeps
//! the drift low.
//!
//! The weight is the deformation's tilt of the vertex normal, smoothed over two rings and divided by
//! [`REFERENCE_TILT_DEG`] (clamped to 1): restoration only happens where a detector put folds, so a sequence
//! without anchors still comes back bit for bit, and a garment at rest is not sharpened.

use super::deconvolve::CaptureStencil;
use crate::mesh::{geometry, Topology};
use crate::shape::TaubinFilter;
use crate::vec3::{self, V3};
use std::sync::{Arc, Mutex};

/// Smoothed tilt (degrees) at which the restoration weight reaches 1: about the anchor angle of the weakest
/// fold the stretch detector makes (linear law, gain 4 × minimum shrinkage 0.02 = 4.6°), so that every
/// detected fold is restored fully and only the fading edges of the deformation partly.
pub const REFERENCE_TILT_DEG: f64 = 5.0;

/// How the positioning ends: the shape projection ([`super::projection`]), then the fold restoration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Restoration {
    /// Van Cittert steps of the deconvolution of the capture filter (fractional part: a last partial step);
    /// 0 restores nothing.
    pub steps: f64,
    /// Smoothed tilt (radians) of the deformed vertex normal at which the weight reaches 1.
    pub reference_tilt: f64,
    /// Fraction of the capture filter's low-pass of the displacement removed before restoring (0: none).
    pub projection: f64,
    /// Where the projection sits relative to the last stretch pass.
    pub order: super::projection::ProjectionOrder,
}

/// The captured surface `c` deconvolved by `filter`: `steps` Van Cittert steps g ← g + (c − filter(g)) from
/// g = c, the fractional part of `steps` as a last step of that size. The statement of the deconvolution, step
/// by step (`steps` × the filter's sweeps); the restoration evaluates the same polynomial of the filter in
/// fewer sweeps ([`super::deconvolve`]), equal to this to rounding.
pub fn deconvolve(filter: &TaubinFilter, c: &[V3], steps: f64) -> Vec<V3> {
    let mut g = c.to_vec();
    let mut left = steps;
    while left > 0.0 {
        let size = left.min(1.0);
        let smooth = filter.apply(&g);
        for ((gv, cv), sv) in g.iter_mut().zip(c).zip(&smooth) {
            *gv = vec3::add(*gv, vec3::scale(vec3::sub(*cv, *sv), size));
        }
        left -= 1.0;
    }
    g
}

impl Restoration {
    /// Whether the fold restoration adds anything.
    pub fn restores(&self) -> bool {
        self.steps > 0.0 && self.reference_tilt > 0.0
    }

    /// Whether this ending (projection or restoration) changes anything.
    pub fn is_active(&self) -> bool {
        self.restores() || self.projection > 0.0
    }

    /// The shape projection, then the fold restoration, of a positioned frame `out` of `rest` (`out` unchanged
    /// when neither is active or `out` equals `rest`).
    ///
    /// The restoration's weight (where the detectors put folds) is read off `out` as positioned, before the
    /// projection: the projection takes away what the capture would have seen of the displacement, which
    /// moves the garment, not the folds, and the tilt that drift carried must not decide where folds are
    /// restored any more than the drift itself does.
    pub fn finish(&self, topo: &Topology, mesh: &RestoreMesh, rest: &[V3], out: &[V3]) -> Vec<V3> {
        if out == rest {
            return out.to_vec();
        }
        if !self.restores() {
            return super::projection::project(
                mesh.stencil.filter(),
                rest,
                out,
                self.projection,
            );
        }
        if self.projection <= 0.0 {
            let detail = mesh.stencil.detail(&mesh.series(self.steps), rest);
            return self.restore_onto(topo, rest, out, out, &detail, mesh);
        }
        // Both: the projection's low-pass of the displacement and the restoration's detail of the captured
        // surface in one set of sweeps (the same numbers as `shape_projection::project` and
        // `CaptureStencil::detail` give separately, bit for bit).
        let d: Vec<V3> = out
            .iter()
            .zip(rest)
            .map(|(o, c)| vec3::sub(*o, *c))
            .collect();
        let (detail, low) = mesh
            .stencil
            .detail_and_low_pass(&mesh.series(self.steps), rest, &d);
        let projected: Vec<V3> = out
            .iter()
            .zip(&low)
            .map(|(o, l)| vec3::sub(*o, vec3::scale(*l, self.projection)))
            .collect();
        self.restore_onto(topo, rest, out, &projected, &detail, mesh)
    }

    /// The restored positions: `out` plus what the deconvolution adds to the captured surface, along its
    /// normal, where the deformation (from `rest` to `out`) tilted the surface. `out` is returned unchanged when the restoration
    /// is inactive or `out` equals `rest`. (The shape projection is not part of this: see [`Restoration::finish`].)
    ///
    /// Builds the connectivity tables of [`RestoreMesh`] on every call; a caller restoring many frames of one
    /// mesh builds them once and calls [`Restoration::apply_with`] (same result, bit for bit).
    pub fn apply(&self, topo: &Topology, rest: &[V3], out: &[V3]) -> Vec<V3> {
        if !self.restores() || out == rest {
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
        if !self.restores() || out == rest {
            return out.to_vec();
        }
        let detail = mesh.stencil.detail(&mesh.series(self.steps), rest);
        self.restore_onto(topo, rest, out, out, &detail, mesh)
    }

    /// The restoration with its weight read off `tilted` (the deformed frame whose tilt says where folds
    /// were put) and its heights added to `base`; `detail` is what the deconvolution of the capture filter
    /// adds to `rest` (the folds the capture damped, as far as `steps` undoes them).
    fn restore_onto(
        &self,
        topo: &Topology,
        rest: &[V3],
        tilted: &[V3],
        base: &[V3],
        detail: &[V3],
        mesh: &RestoreMesh,
    ) -> Vec<V3> {
        let n = rest.len();
        let n_rest = geometry::vertex_normals(topo, rest);
        let n_out = geometry::vertex_normals(topo, tilted);
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
                    return base[v];
                }
                let height = vec3::dot(detail[v], n_rest[v]);
                vec3::add(base[v], vec3::scale(n_rest[v], w * height))
            })
            .collect()
    }
}

/// What the restoration needs of the connectivity, which is the same for every frame: the capture filter's
/// stencil (its neighbour lists), every vertex's one-ring for the tilt smoothing, and the deconvolution's
/// series for the last step count asked for. Building the lists takes a sorted neighbour list per vertex (one
/// allocation each), as long as a good part of the deconvolution, so the deformation builds them once per
/// sequence ([`crate::spacetime::position::PositionSystem::restore_mesh`]).
pub struct RestoreMesh {
    stencil: CaptureStencil,
    ring_offsets: Vec<u32>,
    ring: Vec<u32>,
    /// (steps as bits, series): the series takes O((80 × steps)²) operations to compute, ~0.2 ms at 5 steps.
    series: Mutex<Option<(u64, Arc<Vec<f64>>)>>,
}

impl RestoreMesh {
    /// The capture filter the shape projection and the restoration use.
    pub fn capture_filter(&self) -> &TaubinFilter {
        self.stencil.filter()
    }

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
            stencil: CaptureStencil::new(topo),
            ring_offsets,
            ring,
            series: Mutex::new(None),
        }
    }

    /// The deconvolution's Chebyshev series for `steps` ([`CaptureStencil::series`]), computed once per step
    /// count and shared by the frames (a pure function of `steps`: which frame computes it changes nothing).
    fn series(&self, steps: f64) -> Arc<Vec<f64>> {
        let mut cached = self.series.lock().unwrap_or_else(|e| e.into_inner());
        match &*cached {
            Some((bits, s)) if *bits == steps.to_bits() => s.clone(),
            _ => {
                let s = Arc::new(self.stencil.series(steps));
                *cached = Some((steps.to_bits(), s.clone()));
                s
            }
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
            steps: 2.0,
            reference_tilt: 0.1,
            projection: 0.0,
            order: Default::default(),
        };
        assert_eq!(r.apply(&topo, &p, &p), p);
    }

    /// Where the deformation tilted the surface, the captured ripple grows in place (same sign, same crest),
    /// by (1 − (1 − T)^(steps + 1)) / T − 1 of itself in the middle of the grid (T the capture filter's gain at
    /// the ripple's wavelength); two rings beyond the tilted part nothing moves.
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
            steps: 2.0,
            reference_tilt: 1e-3,
            projection: 0.0,
            order: Default::default(),
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
                // The captured ripple itself, amplified: same sign, (1 − (1 − T)³) / T − 1 = 0.43 of it after two
                // steps, T = 0.68 the capture filter's gain at 6 edges on this equilateral grid
                // ((1 − 0.5 μ)(1 + 0.53 μ))^40, μ = 0.256.
                let ratio = added / rest[v][2];
                assert!(ratio > 0.33 && ratio < 0.53, "vertex {v}: ratio {ratio}");
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
                steps: 0.0,
                reference_tilt: 0.1,
                projection: 0.0,
                order: Default::default(),
            },
            Restoration {
                steps: 2.0,
                reference_tilt: 0.0,
                projection: 0.0,
                order: Default::default(),
            },
        ] {
            assert_eq!(r.apply(&topo, &rest, &out), out);
        }
    }

    /// A plane wave the capture filter kept a fraction T of comes back as 1 − (1 − T)^(steps + 1) of its
    /// height, never more; one step is the captured residue added once.
    #[test]
    fn deconvolution_recovers_what_the_filter_kept_without_overshoot() {
        let (topo, flat) = rippled_grid(60, 40, 6.0, 0.0);
        let filter = TaubinFilter::capture(&topo);
        let wave: Vec<V3> = flat
            .iter()
            .map(|q| [q[0], q[1], (2.0 * std::f64::consts::PI * q[0] / 6.0).sin()])
            .collect();
        let captured = filter.apply(&wave);
        // Interior vertices on a crest of the wave, far from the rim.
        let crest: Vec<usize> = (0..wave.len())
            .filter(|&v| {
                let q = flat[v];
                (15.0..45.0).contains(&q[0]) && (10.0..25.0).contains(&q[1]) && wave[v][2] > 0.99
            })
            .collect();
        assert!(crest.len() > 10);
        let t = captured[crest[0]][2] / wave[crest[0]][2];
        assert!(t > 0.6 && t < 0.75, "T = {t}");
        let mut last = t;
        for steps in [1.0, 2.0, 5.0] {
            let g = deconvolve(&filter, &captured, steps);
            let expect = 1.0 - (1.0 - t).powf(steps + 1.0);
            for &v in &crest {
                let got = g[v][2] / wave[v][2];
                assert!(
                    (got - expect).abs() < 0.02,
                    "{steps} steps: {got} vs {expect}"
                );
                assert!(
                    got <= 1.0 + 1e-3 && got > last - 0.02,
                    "{steps} steps: {got}"
                );
            }
            last = expect;
        }
        // One step is the captured surface plus its residue under the filter.
        let one = deconvolve(&filter, &captured, 1.0);
        let again = filter.apply(&captured);
        for v in 0..wave.len() {
            let want = vec3::add(captured[v], vec3::sub(captured[v], again[v]));
            assert!(vec3::norm(vec3::sub(one[v], want)) < 1e-12);
        }
        assert_eq!(deconvolve(&filter, &captured, 0.0), captured);
    }
}

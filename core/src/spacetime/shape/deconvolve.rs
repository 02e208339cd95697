//! The fold restoration's deconvolution of the capture filter as one Chebyshev series in the filter's
//! averaging operator: about 75 neighbour sweeps per frame instead of `steps` × 80.
//!
//! Every step of the capture filter ([`TaubinFilter::capture`]) is x ← x + f (A x − x) with one and the same
//! averaging operator A (uniform weights over the one-ring; a boundary vertex averages its boundary
//! neighbours; a vertex without neighbours keeps its value). So the filter is a polynomial in A,
//! C = Π_i (I + f_i (A − I)), and Van Cittert's iteration g ← g + s (c − C g) from g = c
//! ([`super::restore::deconvolve`]) is another one, g = q(A) c, of degree 80 × ⌈steps⌉ — 400 sweeps at the
//! default 5 steps. That many matrix-vector products are needed to apply a general polynomial of that degree,
//! but not this one: A is row-stochastic, and its boundary rows reference only boundary vertices, so it is
//! block-triangular with two diagonal blocks each similar to a symmetric matrix; its eigenvalues are real and
//! lie in [−1, 1]. As a function on [−1, 1], q is smooth (C is a bump around the eigenvalue 1 whatever its
//! degree), and its Chebyshev coefficients fall to rounding level (10⁻¹⁴ of the largest) by degree 60–70
//! for 5 steps. The series truncated there, evaluated with the three-term recurrence T_{k+1}(A) = 2 A T_k(A) −
//! T_{k−1}(A), gives the deconvolution to rounding: on the public sleeve and drape meshes (extents 0.5 and 1)
//! it differs from the step-by-step iteration by about 1e-14, the size of that iteration's own rounding
//! (`tests::the_series_is_van_cittert_to_rounding` checks 1e-12 of the extent on a mesh with a boundary).
//!
//! What the restoration needs is the detail the deconvolution adds, q(A) c − c = r(A) c with r = q − 1. r
//! vanishes on constants (r(1) = 0: a filter step keeps a constant field), so the series is applied to c minus
//! its mean: the result then does not depend on where the garment stands, to rounding.

use crate::spacetime::kernels::stencil_sweep::{self, Sweep};
use crate::mesh::Topology;
use crate::shape::TaubinFilter;
use crate::vec3::{self, V3};
use rayon::prelude::*;
use std::f64::consts::PI;

/// Coefficients below this fraction of the largest are dropped from the tail of the series (they are at the
/// rounding level of the coefficients themselves, a few 1e-16 of the largest).
const TAIL_FRACTION: f64 = 1e-14;

/// Terms kept beyond the last coefficient above [`TAIL_FRACTION`]: the true coefficients keep falling
/// geometrically past the cut, so a few more terms put the truncation error well under it.
const TAIL_MARGIN: usize = 8;

/// Vertices per parallel chunk of one sweep.
const CHUNK: usize = 4096;

/// The capture filter's averaging operator A, read from the filter's own neighbour lists (so the series
/// applies exactly the operator the filter steps with).
pub struct CaptureStencil {
    filter: TaubinFilter,
    /// 1 / (number of neighbours) of each vertex (0 for a vertex without neighbours): the same factor the
    /// filter computes in every sweep, computed once.
    inv_count: Vec<f64>,
    /// The neighbour lists for the AVX2 sweep ([`stencil_sweep`]): vertex v's neighbours are the slots at
    /// the byte offsets `slot_bytes[offsets[v] .. offsets[v + 1]]` of the swept field, in the filter's list
    /// order. `None` when a mesh is too large for 32-bit byte offsets (the scalar sweep runs).
    wide: Option<WideLists>,
}

/// [`CaptureStencil`]'s neighbour lists as byte offsets into a field of [f64; 6] slots.
struct WideLists {
    offsets: Vec<u32>,
    slot_bytes: Vec<u32>,
}

impl CaptureStencil {
    /// The stencil of [`TaubinFilter::capture`] on `topo`: interior vertices average their whole one-ring,
    /// boundary vertices their neighbours along the boundary.
    pub fn new(topo: &Topology) -> Self {
        let filter = TaubinFilter::capture(topo);
        let inv_count = (0..topo.n_vertices())
            .map(|v| match filter.neighbors(v).len() {
                0 => 0.0,
                n => 1.0 / n as f64,
            })
            .collect();
        let nv = topo.n_vertices();
        // Every neighbour index is below the vertex count (the filter's lists come from the topology): the
        // AVX2 sweep reads the slots unchecked, so this is checked here, once.
        let wide = (nv.saturating_mul(stencil_sweep::SLOT_BYTES) <= u32::MAX as usize).then(|| {
            let mut offsets = Vec::with_capacity(nv + 1);
            let mut slot_bytes = Vec::new();
            offsets.push(0u32);
            for v in 0..nv {
                for &w in filter.neighbors(v) {
                    assert!((w as usize) < nv, "vertex {v}: neighbour {w} out of range");
                    slot_bytes.push(w * stencil_sweep::SLOT_BYTES as u32);
                }
                offsets.push(slot_bytes.len() as u32);
            }
            WideLists {
                offsets,
                slot_bytes,
            }
        });
        CaptureStencil {
            filter,
            inv_count,
            wide,
        }
    }

    /// The capture filter itself (the shape projection low-passes with it).
    pub fn filter(&self) -> &TaubinFilter {
        &self.filter
    }

    /// (A x) at vertex `v`: the mean of its neighbours (summed in list order, as the filter sums), or x[v].
    #[inline]
    fn average(&self, x: &[V3], v: usize) -> V3 {
        let nb = self.filter.neighbors(v);
        if nb.is_empty() {
            return x[v];
        }
        let mut sum = [0.0; 3];
        for &w in nb {
            sum = vec3::add(sum, x[w as usize]);
        }
        vec3::scale(sum, self.inv_count[v])
    }

    /// [`Self::detail`]`(series, c)` and the capture filter's low-pass of `d` (`self.filter().apply(d)`), both
    /// bit for bit, in one set of sweeps: the shape projection and the fold restoration of a frame apply the
    /// same averaging operator, 80 filter steps and ~90 series terms, so sweeping both fields together reads
    /// each vertex's neighbour list once instead of twice, and its two 3-vectors from one 48-byte slot
    /// Every value is computed with the operations, in the order, of the two separate
    /// evaluations; the sweeps run in parallel over vertex chunks (no thread-count dependence).
    pub fn detail_and_low_pass(&self, series: &[f64], c: &[V3], d: &[V3]) -> (Vec<V3>, Vec<V3>) {
        self.detail_and_low_pass_with(series, c, d, stencil_sweep::available())
    }

    /// [`Self::detail_and_low_pass`] with the AVX2 sweep (`wide`, where the CPU has it) or the scalar one
    /// (the reference); the same bits either way.
    fn detail_and_low_pass_with(
        &self,
        series: &[f64],
        c: &[V3],
        d: &[V3],
        wide: bool,
    ) -> (Vec<V3>, Vec<V3>) {
        let n = c.len();
        assert_eq!(d.len(), n, "fields of different lengths");
        assert_eq!(
            n,
            self.inv_count.len(),
            "a field of {n} vertices on a mesh of {}",
            self.inv_count.len()
        );
        let (lambda, mu) = (self.filter.lambda, self.filter.mu);
        let filter_steps = self.filter.iterations;
        // Series sweeps: T_1 … T_{len−1}, one each.
        let series_steps = series.len().saturating_sub(1);
        if n == 0 || (series_steps == 0 && filter_steps == 0) {
            return (self.detail(series, c), d.to_vec());
        }
        let wide = self
            .wide
            .as_ref()
            .filter(|_| wide && stencil_sweep::detected());
        let mean = vec3::scale(
            c.iter().fold([0.0; 3], |s, p| vec3::add(s, *p)),
            1.0 / n as f64,
        );
        // cur[v] = [filter iterate x_j (3) | T_j u (3)]; other[v] = [scratch (3) | T_{j−1} u (3)].
        let mut cur: Vec<[f64; 6]> = d
            .iter()
            .zip(c)
            .map(|(dv, cv)| {
                let u = vec3::sub(*cv, mean);
                [dv[0], dv[1], dv[2], u[0], u[1], u[2]]
            })
            .collect();
        let mut acc: Vec<V3> = match series.first() {
            Some(&s0) => cur
                .iter()
                .map(|q| vec3::scale([q[3], q[4], q[5]], s0))
                .collect(),
            None => vec![[0.0; 3]; n],
        };
        let mut other: Vec<[f64; 6]> = vec![[0.0; 6]; n];
        for j in 0..filter_steps.max(series_steps) {
            // Sweep j of the series makes T_{j+1} = A T_0 (j = 0) or 2 A T_j − T_{j−1}, weighted series[j + 1].
            let sweep = Sweep {
                filter: (j < filter_steps).then_some(if j % 2 == 0 { lambda } else { mu }),
                term: (j < series_steps).then(|| series[j + 1]),
                first: j == 0,
            };
            let src = &cur;
            other
                .par_chunks_mut(CHUNK)
                .zip(acc.par_chunks_mut(CHUNK))
                .enumerate()
                .for_each(|(ch, (os, accs))| {
                    #[cfg(target_arch = "x86_64")]
                    if let Some(lists) = wide {
                        // SAFETY: AVX2 is present (`detected`); `offsets` has n + 1 entries and `inv_count` n
                        // (asserted above), every byte offset is that of a slot below n (checked in `new`),
                        // `src` has n slots, and the chunks of `other` and `acc` have the same length.
                        unsafe {
                            stencil_sweep::avx2::sweep(
                                &lists.offsets,
                                &lists.slot_bytes,
                                &self.inv_count,
                                src,
                                ch * CHUNK,
                                os,
                                accs,
                                sweep,
                            )
                        };
                        return;
                    }
                    #[cfg(not(target_arch = "x86_64"))]
                    let _ = wide;
                    for (k, (ov, av)) in os.iter_mut().zip(accs.iter_mut()).enumerate() {
                        self.sweep_vertex(src, ch * CHUNK + k, ov, av, sweep);
                    }
                });
            std::mem::swap(&mut cur, &mut other);
        }
        let low = cur.iter().map(|q| [q[0], q[1], q[2]]).collect();
        (acc, low)
    }

    /// One vertex of one fused sweep (the scalar reference of [`stencil_sweep::avx2::sweep`]): from the
    /// field `src`, vertex `v`'s next filter iterate and series iterate into `ov` (whose last three values
    /// are T_{j−1} u on entry), and the series term added to `av`.
    #[inline]
    fn sweep_vertex(&self, src: &[[f64; 6]], v: usize, ov: &mut [f64; 6], av: &mut V3, s: Sweep) {
        let me = src[v];
        let nb = self.filter.neighbors(v);
        // Neighbour means, summed from zero in list order (as the filter and the series do).
        let (xa, ta) = if nb.is_empty() {
            ([me[0], me[1], me[2]], [me[3], me[4], me[5]])
        } else {
            let mut s = [0.0; 6];
            for &w in nb {
                let q = &src[w as usize];
                for i in 0..6 {
                    s[i] += q[i];
                }
            }
            let inv = self.inv_count[v];
            (
                [s[0] * inv, s[1] * inv, s[2] * inv],
                [s[3] * inv, s[4] * inv, s[5] * inv],
            )
        };
        // The filter step x + f (mean − x); a vertex without neighbours keeps x.
        if let Some(f) = s.filter {
            let x = [me[0], me[1], me[2]];
            let nx = if nb.is_empty() {
                x
            } else {
                vec3::add(x, vec3::scale(vec3::sub(xa, x), f))
            };
            ov[..3].copy_from_slice(&nx);
        } else {
            ov[..3].copy_from_slice(&me[..3]);
        }
        if let Some(a) = s.term {
            let next = if s.first {
                ta
            } else {
                vec3::sub(vec3::scale(ta, 2.0), [ov[3], ov[4], ov[5]])
            };
            ov[3..].copy_from_slice(&next);
            *av = vec3::add(*av, vec3::scale(next, a));
        } else {
            ov[3..].copy_from_slice(&me[3..]);
        }
    }

    /// The Chebyshev series of the detail Van Cittert's `steps` add ([`van_cittert_series`] for this filter).
    pub fn series(&self, steps: f64) -> Vec<f64> {
        van_cittert_series(
            self.filter.lambda,
            self.filter.mu,
            self.filter.iterations,
            steps,
        )
    }

    /// Σ_k series[k] T_k(A) applied to `c` minus its mean: the detail q(A) c − c that `steps` Van Cittert
    /// steps add to `c`, for `series` = [`Self::series`]`(steps)`. Each term costs one sweep over the
    /// neighbour lists, run in parallel over vertex chunks (every vertex's value is computed the same way on
    /// any thread: the result does not depend on the thread count).
    pub fn detail(&self, series: &[f64], c: &[V3]) -> Vec<V3> {
        let n = c.len();
        if series.is_empty() || n == 0 {
            return vec![[0.0; 3]; n];
        }
        let mean = vec3::scale(
            c.iter().fold([0.0; 3], |s, p| vec3::add(s, *p)),
            1.0 / n as f64,
        );
        // T_0 u, T_1 u with u = c − mean; `acc` sums the series.
        let mut prev: Vec<V3> = c.iter().map(|p| vec3::sub(*p, mean)).collect();
        let mut acc: Vec<V3> = prev.iter().map(|p| vec3::scale(*p, series[0])).collect();
        if series.len() == 1 {
            return acc;
        }
        let mut cur: Vec<V3> = vec![[0.0; 3]; n];
        cur.par_chunks_mut(CHUNK)
            .zip(acc.par_chunks_mut(CHUNK))
            .enumerate()
            .for_each(|(ch, (cs, accs))| {
                for (k, (cv, av)) in cs.iter_mut().zip(accs.iter_mut()).enumerate() {
                    *cv = self.average(&prev, ch * CHUNK + k);
                    *av = vec3::add(*av, vec3::scale(*cv, series[1]));
                }
            });
        for &a in &series[2..] {
            // T_{k+1} u = 2 A T_k u − T_{k−1} u, written over T_{k−1} u (read only at its own vertex).
            prev.par_chunks_mut(CHUNK)
                .zip(acc.par_chunks_mut(CHUNK))
                .enumerate()
                .for_each(|(ch, (ps, accs))| {
                    for (k, (pv, av)) in ps.iter_mut().zip(accs.iter_mut()).enumerate() {
                        let next =
                            vec3::sub(vec3::scale(self.average(&cur, ch * CHUNK + k), 2.0), *pv);
                        *pv = next;
                        *av = vec3::add(*av, vec3::scale(next, a));
                    }
                });
            std::mem::swap(&mut prev, &mut cur);
        }
        acc
    }
}

/// The gain of the filter x ← x + f_i (A x − x) (f_i = λ, μ, λ, …, `iterations` steps) on an eigenvector of A
/// with eigenvalue `x`, followed by Van Cittert's `steps` (the fractional part a last, partial step) —
/// q(x) — minus 1: the detail the deconvolution adds to that eigenvector, per unit of it.
fn detail_gain(lambda: f64, mu: f64, iterations: usize, steps: f64, x: f64) -> f64 {
    let l = x - 1.0;
    let mut c = 1.0;
    for it in 0..iterations {
        let f = if it % 2 == 0 { lambda } else { mu };
        c *= 1.0 + f * l;
    }
    let mut g = 1.0;
    let mut left = steps;
    while left > 0.0 {
        let size = left.min(1.0);
        g += size * (1.0 - c * g);
        left -= 1.0;
    }
    g - 1.0
}

/// Chebyshev coefficients (on [−1, 1], the spectrum of A) of the detail r(x) = q(x) − 1 that `steps` Van
/// Cittert steps of the Taubin filter (λ, μ, `iterations` steps) add, truncated where they reach rounding
/// level. r is a polynomial of degree `iterations` × ⌈steps⌉ = D, so interpolating it at the D + 1 Chebyshev
/// points gives its coefficients exactly (up to rounding); the discrete cosine transform uses a table of
/// cos(π m / 2(D + 1)), m < 4(D + 1), so the O(D²) sums call no trigonometry. Empty when nothing is added.
pub fn van_cittert_series(lambda: f64, mu: f64, iterations: usize, steps: f64) -> Vec<f64> {
    if !(steps > 0.0 && steps.is_finite()) || iterations == 0 {
        return Vec::new();
    }
    let n = iterations * steps.ceil() as usize + 1;
    let samples: Vec<f64> = (0..n)
        .map(|j| {
            let x = (PI * (j as f64 + 0.5) / n as f64).cos();
            detail_gain(lambda, mu, iterations, steps, x)
        })
        .collect();
    let table: Vec<f64> = (0..4 * n)
        .map(|m| (PI * m as f64 / (2 * n) as f64).cos())
        .collect();
    let mut coeffs: Vec<f64> = (0..n)
        .map(|k| {
            let s: f64 = samples
                .iter()
                .enumerate()
                .map(|(j, y)| y * table[(k * (2 * j + 1)) % (4 * n)])
                .sum();
            2.0 * s / n as f64
        })
        .collect();
    coeffs[0] *= 0.5;
    let largest = coeffs.iter().fold(0.0f64, |m, a| m.max(a.abs()));
    if largest <= 0.0 {
        return Vec::new();
    }
    let last = coeffs
        .iter()
        .rposition(|a| a.abs() > TAIL_FRACTION * largest)
        .unwrap_or(0);
    coeffs.truncate((last + 1 + TAIL_MARGIN).min(n));
    coeffs
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spacetime::shape::restore::deconvolve;

    /// An irregular sheet with a boundary: a grid of `nx` × `ny` vertices whose cells are split along either
    /// diagonal by a hash, heights from a few ripples, and one corner cell missing (a notch in the boundary).
    fn sheet(nx: usize, ny: usize) -> (Topology, Vec<V3>) {
        sheet_with_diagonals(nx, ny, true)
    }

    /// A sheet whose quads are split along one diagonal everywhere (`mixed` false: interior vertices have six
    /// neighbours, the sweep's unrolled case) or along either diagonal by a pattern (valences 4 to 8).
    fn sheet_with_diagonals(nx: usize, ny: usize, mixed: bool) -> (Topology, Vec<V3>) {
        let mut p = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                let (x, y) = (
                    i as f64 + 0.3 * ((i * 7 + j * 3) % 5) as f64 / 5.0,
                    j as f64,
                );
                p.push([
                    x,
                    y,
                    0.4 * (x * 1.1).sin() * (y * 0.7).cos() + 0.05 * ((i * j) % 3) as f64,
                ]);
            }
        }
        let mut tris = Vec::new();
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                if i == 0 && j == 0 {
                    continue;
                }
                let a = (j * nx + i) as u32;
                let (b, c, d) = (a + 1, a + nx as u32, a + nx as u32 + 1);
                if mixed && (i * 31 + j * 17) % 3 == 0 {
                    tris.extend([[a, b, c], [b, d, c]]);
                } else {
                    tris.extend([[a, b, d], [a, d, c]]);
                }
            }
        }
        (Topology::new(nx * ny, tris).unwrap(), p)
    }

    /// The stencil's operator, stepped like the filter, reproduces `TaubinFilter::capture` bit for bit: the
    /// neighbour lists here are the filter's.
    #[test]
    fn the_stencil_is_the_capture_filters() {
        let (topo, p) = sheet(23, 17);
        let stencil = CaptureStencil::new(&topo);
        let mut x = p.clone();
        for it in 0..stencil.filter.iterations {
            let f = if it % 2 == 0 {
                stencil.filter.lambda
            } else {
                stencil.filter.mu
            };
            x = (0..x.len())
                .map(|v| {
                    let avg = stencil.average(&x, v);
                    vec3::add(x[v], vec3::scale(vec3::sub(avg, x[v]), f))
                })
                .collect();
        }
        let want = TaubinFilter::capture(&topo).apply(&p);
        assert!(x
            .iter()
            .zip(&want)
            .all(|(a, b)| a.map(f64::to_bits) == b.map(f64::to_bits)));
    }

    /// The fused sweeps give the restoration's detail and the shape projection's low-pass bit for bit as
    /// computed separately, for series shorter and longer than the filter's 80 steps, on a mesh with a
    /// boundary, a notch and a vertex without neighbours (the notch leaves vertex 0 without triangles).
    #[test]
    fn fused_sweeps_are_the_separate_ones_bit_for_bit() {
        let (topo, p) = sheet(31, 23);
        let stencil = CaptureStencil::new(&topo);
        assert!(stencil.filter.neighbors(0).is_empty());
        let d: Vec<V3> = p
            .iter()
            .map(|q| {
                [
                    0.1 * (q[0] * 0.9).sin(),
                    -0.05 * q[1].cos(),
                    0.02 * q[0] * q[1],
                ]
            })
            .collect();
        let bits = |v: &[V3]| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
        for steps in [0.5, 1.0, 8.0, 20.0] {
            let series = stencil.series(steps);
            let (detail, low) = stencil.detail_and_low_pass(&series, &p, &d);
            assert_eq!(bits(&detail), bits(&stencil.detail(&series, &p)), "{steps}");
            assert_eq!(bits(&low), bits(&stencil.filter.apply(&d)), "{steps}");
        }
        // No series terms: only the filter runs.
        let (detail, low) = stencil.detail_and_low_pass(&[], &p, &d);
        assert!(detail.iter().all(|v| *v == [0.0; 3]));
        assert_eq!(bits(&low), bits(&stencil.filter.apply(&d)));
        let one = [0.7];
        let (detail, _) = stencil.detail_and_low_pass(&one, &p, &d);
        assert_eq!(bits(&detail), bits(&stencil.detail(&one, &p)));
    }

    /// The AVX2 sweep gives the scalar sweep's bits: series shorter and longer than the filter's 80 steps,
    /// no series, on two sheets with boundary vertices and a vertex without neighbours: one with interior
    /// vertices of six neighbours (the unrolled case), one with valences from four to eight. (Where the CPU
    /// lacks AVX2 both calls run the scalar sweep.)
    #[test]
    fn wide_sweeps_are_the_scalar_sweeps() {
        for mixed in [true, false] {
            let (topo, p) = sheet_with_diagonals(37, 29, mixed);
            let stencil = CaptureStencil::new(&topo);
            let counts: Vec<usize> = (0..p.len())
                .map(|v| stencil.filter.neighbors(v).len())
                .collect();
            for k in [0, 2] {
                assert!(counts.contains(&k), "no vertex with {k} neighbours");
            }
            if mixed {
                assert!(counts.iter().any(|&k| k > 6), "no vertex above six");
            } else {
                assert!(counts.contains(&6), "no vertex with six neighbours");
            }
            let d: Vec<V3> = p
                .iter()
                .map(|q| [(q[0] * 1.7).cos(), 0.3 * q[1].sin(), -0.2 * q[0]])
                .collect();
            let bits = |v: &[V3]| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
            for steps in [0.5, 1.0, 8.0, 20.0] {
                let series = stencil.series(steps);
                for s in [&series[..], &series[..1], &[]] {
                    let (dw, lw) = stencil.detail_and_low_pass_with(s, &p, &d, true);
                    let (ds, ls) = stencil.detail_and_low_pass_with(s, &p, &d, false);
                    assert_eq!(
                        bits(&dw),
                        bits(&ds),
                        "detail, mixed {mixed}, steps {steps}, {} terms",
                        s.len()
                    );
                    assert_eq!(
                        bits(&lw),
                        bits(&ls),
                        "low-pass, mixed {mixed}, steps {steps}, {} terms",
                        s.len()
                    );
                }
            }
        }
    }

    /// The truncated series gives what Van Cittert's iteration adds, to 1e-12 of the extent, for whole and
    /// fractional step counts, near the origin and far from it; the series is much shorter than the
    /// iteration's 80 sweeps per step.
    #[test]
    fn the_series_is_van_cittert_to_rounding() {
        let (topo, p) = sheet(40, 30);
        let stencil = CaptureStencil::new(&topo);
        let filter = TaubinFilter::capture(&topo);
        for offset in [0.0, 250.0] {
            let c: Vec<V3> = p
                .iter()
                .map(|q| [q[0] + offset, q[1] - offset, q[2]])
                .collect();
            for steps in [0.5, 1.0, 2.5, 5.0, 8.0] {
                let series = stencil.series(steps);
                let got = stencil.detail(&series, &c);
                let reference = deconvolve(&filter, &c, steps);
                let mut worst = 0.0f64;
                let mut largest = 0.0f64;
                for ((g, r), q) in got.iter().zip(&reference).zip(&c) {
                    let want = vec3::sub(*r, *q);
                    worst = worst.max(vec3::norm(vec3::sub(*g, want)));
                    largest = largest.max(vec3::norm(want));
                }
                // Extent about 40; the reference's own rounding far from the origin is about 400 ε × 250.
                let tol = 1e-12 * 40.0 + 1e-13 * offset;
                assert!(worst < tol, "steps {steps} offset {offset}: {worst:e}");
                assert!(
                    largest > 0.01,
                    "steps {steps}: nothing restored ({largest})"
                );
                let sweeps = filter.iterations as f64 * steps.ceil();
                assert!(
                    (series.len() as f64) < 0.5 * sweeps.max(120.0),
                    "steps {steps}: {} terms for {sweeps} sweeps",
                    series.len()
                );
            }
        }
    }

    /// The default 5 steps need fewer than 100 terms (the iteration takes 400 sweeps); no steps, none.
    #[test]
    fn the_default_series_is_short() {
        let (lambda, mu, it) = (0.5, -0.53, crate::shape::CAPTURE_STEPS);
        let s = van_cittert_series(lambda, mu, it, 5.0);
        assert!(s.len() > 20 && s.len() < 100, "{}", s.len());
        // The detail of a constant (x = 1) is nothing; the highest frequencies (x = −1, the filter removed them
        // all) come back 5 times over (q = 6).
        let at = |x: f64| {
            let (mut t0, mut t1, mut sum) = (1.0, x, s[0]);
            for &a in &s[1..] {
                sum += a * t1;
                (t0, t1) = (t1, 2.0 * x * t1 - t0);
            }
            sum
        };
        assert!(at(1.0).abs() < 1e-12, "{}", at(1.0));
        assert!((at(-1.0) - 5.0).abs() < 1e-12, "{}", at(-1.0));
        assert!(van_cittert_series(lambda, mu, it, 0.0).is_empty());
        let (topo, p) = sheet(6, 5);
        let none = CaptureStencil::new(&topo).detail(&[], &p);
        assert!(none.iter().all(|d| *d == [0.0; 3]));
    }
}

//! The production kernel of the fused weight solve: the same block CG as [`super::fused::solve3`], arranged so
//! that each iteration moves as few bytes as possible.
//!
//! At paper scale a window has a million nodes and CG is bound by memory bandwidth, not arithmetic: the
//! reference solver streams about 400 bytes per node per iteration (three f64 columns for each of x, r, p, q,
//! the diagonal and its inverse, in six separate passes). Here:
//!
//! - **the stencil is implicit**: off-diagonal couplings are uniform per edge type (c_s across a mesh edge, c_t
//!   across a frame), so the matrix is the mesh adjacency plus two constants; the diagonal takes only a few
//!   distinct values (space degree × time degree × anchored), so each node stores a one-byte class into a small
//!   table of f64 diagonals and their inverses;
//! - **vectors are stored in f32, arithmetic is f64**: every product and every reduction is accumulated in f64
//!   and only the stored iterates are rounded. The rounding (6·10⁻⁸ relative) is four orders of magnitude below
//!   the solver tolerance (10⁻³); the stopping test is confirmed on the true residual ‖B − M X‖ in f64 before
//!   returning, so the result meets the tolerance by the same measure as the reference;
//! - **passes are fused**: (1) q = M p together with ⟨p, q⟩; (2) the x and r updates together with ⟨r, r⟩ and
//!   ⟨r, D⁻¹r⟩; (3) the new search direction. About 150 bytes per node per iteration instead of 400.
//!
//! Reductions are summed per fixed-size chunk and then in chunk order, so the result does not depend on the
//! thread count (cluster and single-node runs stay bit-identical).

use super::fused::CgStats;
use super::operator::{SpaceTimeOperator, CHUNK};
use crate::error::{Error, Result};
use crate::mesh::NONE;
use rayon::prelude::*;
use std::collections::HashMap;

pub(super) type V3f = [f32; 3];

/// Below this relative tolerance the f32 iterates cannot be trusted to reach it (the residual of an f32-rounded
/// solution is about 10⁻⁶ relative for this operator's condition number), so the solve runs the f64 reference
/// solver instead.
pub const F32_MIN_TOLERANCE: f64 = 1e-4;

/// The window operator reduced to what the stencil needs: per-node diagonal class, the class tables, and the
/// mesh adjacency (borrowed from the operator).
pub(super) struct LeanOperator<'a> {
    pub(super) tri_adj: &'a [[u32; 3]],
    pub(super) n_tri: usize,
    pub(super) n_frames: usize,
    pub(super) c_s: f64,
    pub(super) c_t: f64,
    pub(super) class: Vec<u8>,
    pub(super) diag: Vec<f64>,
    pub(super) inv_diag: Vec<f64>,
}

impl<'a> LeanOperator<'a> {
    /// None when the diagonal has more distinct values than a byte can index (it cannot with the operator's
    /// own construction, but the caller then falls back to the reference solver rather than assume it).
    pub(super) fn new(op: &SpaceTimeOperator<'a>) -> Option<Self> {
        let mut index: HashMap<u64, u8> = HashMap::new();
        let mut diag = Vec::new();
        let mut class = Vec::with_capacity(op.n_nodes());
        for &d in op.diag() {
            let c = match index.get(&d.to_bits()) {
                Some(&c) => c,
                None => {
                    let c = u8::try_from(diag.len()).ok()?;
                    index.insert(d.to_bits(), c);
                    diag.push(d);
                    c
                }
            };
            class.push(c);
        }
        let inv_diag = diag.iter().map(|d| 1.0 / d).collect();
        Some(LeanOperator {
            tri_adj: op.tri_adj,
            n_tri: op.n_tri,
            n_frames: op.n_frames,
            c_s: op.coeffs.c_s,
            c_t: op.coeffs.c_t,
            class,
            diag,
            inv_diag,
        })
    }

    pub(super) fn n_nodes(&self) -> usize {
        self.class.len()
    }

    /// (frame, triangle) of the first node of a chunk; callers step it with [`Self::next`] instead of dividing
    /// per node (an integer division per node costs as much as the rest of the stencil).
    pub(super) fn locate(&self, n: usize) -> (usize, usize) {
        (n / self.n_tri, n % self.n_tri)
    }

    #[inline(always)]
    pub(super) fn next(&self, (lt, i): (usize, usize)) -> (usize, usize) {
        if i + 1 == self.n_tri {
            (lt + 1, 0)
        } else {
            (lt, i + 1)
        }
    }

    /// (M v)[n] in f64 from f32 storage; n = lt · n_tri + i.
    #[inline(always)]
    pub(super) fn row(&self, v: &[V3f], n: usize, (lt, i): (usize, usize)) -> [f64; 3] {
        let base = n - i;
        let d = self.diag[self.class[n] as usize];
        let vn = v[n];
        let mut s = [0.0f64; 3];
        for &j in &self.tri_adj[i] {
            if j != NONE {
                let vm = v[base + j as usize];
                s[0] += vm[0] as f64;
                s[1] += vm[1] as f64;
                s[2] += vm[2] as f64;
            }
        }
        let mut t = [0.0f64; 3];
        if lt > 0 {
            let vm = v[n - self.n_tri];
            t = [vm[0] as f64, vm[1] as f64, vm[2] as f64];
        }
        if lt + 1 < self.n_frames {
            let vm = v[n + self.n_tri];
            t[0] += vm[0] as f64;
            t[1] += vm[1] as f64;
            t[2] += vm[2] as f64;
        }
        [
            d * vn[0] as f64 - self.c_s * s[0] - self.c_t * t[0],
            d * vn[1] as f64 - self.c_s * s[1] - self.c_t * t[1],
            d * vn[2] as f64 - self.c_s * s[2] - self.c_t * t[2],
        ]
    }
}

/// Sums per-chunk partial results in chunk order (deterministic for any thread count).
pub(super) fn in_order(parts: Vec<[f64; 2]>) -> [f64; 2] {
    parts
        .iter()
        .fold([0.0; 2], |a, b| [a[0] + b[0], a[1] + b[1]])
}

#[inline(always)]
pub(super) fn to32(v: [f64; 3]) -> V3f {
    [v[0] as f32, v[1] as f32, v[2] as f32]
}

#[inline(always)]
pub(super) fn to64(v: V3f) -> [f64; 3] {
    [v[0] as f64, v[1] as f64, v[2] as f64]
}

/// The error the kernel returns when `max_iter` iterations do not reach `tol`.
pub(super) fn no_convergence(tol: f64, max_iter: usize, reached: f64) -> Error {
    Error::numeric(
        "weights (fused CG)",
        format!(
            "did not reach relative residual {tol:e} in {max_iter} iterations (at {reached:.3e}); raise the tuning key deform.cg_max_iterations or deform.cg_tolerance"
        ),
    )
}

/// Solves M X = B (rows × 3) to ‖B − M X‖_F ≤ tol ‖B‖_F, measured in f64 on the returned X; same stopping
/// rule and error messages as [`super::fused::solve3`] (block CG on M ⊗ I₃), which it hands over to when `tol`
/// is below [`F32_MIN_TOLERANCE`]; it is also the same algorithm (Jacobi-preconditioned).
pub fn solve3_lean(
    op: &SpaceTimeOperator,
    b: &[[f64; 3]],
    tol: f64,
    max_iter: usize,
) -> Result<(Vec<[f64; 3]>, CgStats)> {
    if b.len() != op.n_nodes() {
        return Err(Error::param(
            "weights (fused CG)",
            format!(
                "right-hand side has {} rows for {} unknowns",
                b.len(),
                op.n_nodes()
            ),
        ));
    }
    if tol < F32_MIN_TOLERANCE {
        return super::fused::solve3(op, b, tol, max_iter);
    }
    let Some(lean) = LeanOperator::new(op) else {
        return super::fused::solve3(op, b, tol, max_iter);
    };
    let n = lean.n_nodes();
    let mut stats = CgStats::default();
    let bnorm2 = in_order(
        b.par_chunks(CHUNK)
            .map(|bs| {
                let s = bs
                    .iter()
                    .map(|v| v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
                    .sum::<f64>();
                [s, 0.0]
            })
            .collect(),
    )[0];
    let bnorm = bnorm2.sqrt();
    if bnorm == 0.0 {
        return Ok((vec![[0.0; 3]; n], stats));
    }
    let mut x: Vec<V3f> = vec![[0.0; 3]; n];
    let mut r: Vec<V3f> = b.par_iter().map(|&v| to32(v)).collect();
    let mut p: Vec<V3f> = vec![[0.0; 3]; n];
    let mut q: Vec<V3f> = vec![[0.0; 3]; n];
    // p = D⁻¹ r and ⟨r, D⁻¹ r⟩.
    let mut rz = in_order(
        p.par_chunks_mut(CHUNK)
            .zip(r.par_chunks(CHUNK))
            .enumerate()
            .map(|(c, (ps, rs))| {
                let mut acc = 0.0;
                for (k, (pk, rk)) in ps.iter_mut().zip(rs).enumerate() {
                    let d = lean.inv_diag[lean.class[c * CHUNK + k] as usize];
                    let rv = to64(*rk);
                    *pk = to32([rv[0] * d, rv[1] * d, rv[2] * d]);
                    acc += (rv[0] * rv[0] + rv[1] * rv[1] + rv[2] * rv[2]) * d;
                }
                [acc, 0.0]
            })
            .collect(),
    )[0];
    let mut it = 0usize;
    while it < max_iter {
        it += 1;
        // (1) q = M p, ⟨p, q⟩.
        let pq = in_order(
            q.par_chunks_mut(CHUNK)
                .enumerate()
                .map(|(c, qs)| {
                    let mut acc = 0.0;
                    let mut at = lean.locate(c * CHUNK);
                    for (k, qk) in qs.iter_mut().enumerate() {
                        let nd = c * CHUNK + k;
                        let mv = to32(lean.row(&p, nd, at));
                        at = lean.next(at);
                        let pv = p[nd];
                        acc += pv[0] as f64 * mv[0] as f64
                            + pv[1] as f64 * mv[1] as f64
                            + pv[2] as f64 * mv[2] as f64;
                        *qk = mv;
                    }
                    [acc, 0.0]
                })
                .collect(),
        )[0];
        let alpha = rz / pq;
        if !alpha.is_finite() {
            return Err(Error::numeric(
                "weights (fused CG)",
                "breakdown: non-finite step",
            ));
        }
        // (2) x += α p, r −= α q, ⟨r, r⟩, ⟨r, D⁻¹ r⟩.
        let [rr, rz_new] = in_order(
            x.par_chunks_mut(CHUNK)
                .zip(r.par_chunks_mut(CHUNK))
                .enumerate()
                .map(|(c, (xs, rs))| {
                    let base = c * CHUNK;
                    let mut acc = [0.0; 2];
                    for (k, (xk, rk)) in xs.iter_mut().zip(rs.iter_mut()).enumerate() {
                        let nd = base + k;
                        let (pv, qv) = (to64(p[nd]), to64(q[nd]));
                        let (xv, rv) = (to64(*xk), to64(*rk));
                        *xk = to32([
                            xv[0] + alpha * pv[0],
                            xv[1] + alpha * pv[1],
                            xv[2] + alpha * pv[2],
                        ]);
                        let rn = to32([
                            rv[0] - alpha * qv[0],
                            rv[1] - alpha * qv[1],
                            rv[2] - alpha * qv[2],
                        ]);
                        *rk = rn;
                        let rn = to64(rn);
                        let s = rn[0] * rn[0] + rn[1] * rn[1] + rn[2] * rn[2];
                        acc[0] += s;
                        acc[1] += s * lean.inv_diag[lean.class[nd] as usize];
                    }
                    acc
                })
                .collect(),
        );
        stats.iterations = it;
        stats.relative_residual = rr.sqrt() / bnorm;
        if stats.relative_residual <= tol {
            // Confirm on the true residual of the stored iterate (the recurrence drifts from it by f32
            // round-off); continue iterating in the rare case it is still above the tolerance.
            let true_rel = true_residual(&lean, &x, b) / bnorm;
            stats.relative_residual = true_rel;
            if true_rel <= tol {
                return Ok((x.par_iter().map(|&v| to64(v)).collect(), stats));
            }
        }
        // (3) p = D⁻¹ r + β p.
        let beta = rz_new / rz;
        rz = rz_new;
        p.par_chunks_mut(CHUNK)
            .zip(r.par_chunks(CHUNK))
            .enumerate()
            .for_each(|(c, (ps, rs))| {
                for (k, (pk, rk)) in ps.iter_mut().zip(rs).enumerate() {
                    let d = lean.inv_diag[lean.class[c * CHUNK + k] as usize];
                    let (rv, pv) = (to64(*rk), to64(*pk));
                    *pk = to32([
                        rv[0] * d + beta * pv[0],
                        rv[1] * d + beta * pv[1],
                        rv[2] * d + beta * pv[2],
                    ]);
                }
            });
    }
    Err(no_convergence(tol, max_iter, stats.relative_residual))
}

/// ‖B − M X‖_F in f64.
pub(super) fn true_residual(lean: &LeanOperator, x: &[V3f], b: &[[f64; 3]]) -> f64 {
    in_order(
        b.par_chunks(CHUNK)
            .enumerate()
            .map(|(c, bs)| {
                let mut acc = 0.0;
                let mut at = lean.locate(c * CHUNK);
                for (k, bk) in bs.iter().enumerate() {
                    let m = lean.row(x, c * CHUNK + k, at);
                    at = lean.next(at);
                    let e = [bk[0] - m[0], bk[1] - m[1], bk[2] - m[2]];
                    acc += e[0] * e[0] + e[1] * e[1] + e[2] * e[2];
                }
                [acc, 0.0]
            })
            .collect(),
    )[0]
    .sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spacetime::weights::fused::solve3;
    use crate::spacetime::weights::operator::Coefficients;
    use crate::spacetime::weights::WindowProblem;
    use crate::spacetime::windows::Window;
    use crate::synth::{self, DemoSpec};

    /// A synthetic garment and 150 random anchors per frame: the weight solvers' test problem.
    fn problem_input(
        triangles: usize,
        frames: usize,
    ) -> (crate::mesh::Sequence, crate::folds::AnchorSet) {
        let (seq, _) = synth::demo(&DemoSpec {
            triangles,
            frames,
            ..Default::default()
        })
        .unwrap();
        let anchors = synth::random_anchors(&seq.topology, &seq.frames, 150, 3).unwrap();
        (seq, anchors)
    }

    /// ‖M x − b‖ / ‖b‖ over all three columns, with the operator's own f64 product.
    fn residual(
        op: &SpaceTimeOperator,
        x: &[[f64; 3]],
        b: &[[f64; 3]],
    ) -> f64 {
        let mut q = vec![[0.0; 3]; x.len()];
        op.apply3(x, &mut q);
        let (mut num, mut den) = (0.0, 0.0);
        for (qq, bb) in q.iter().zip(b) {
            for k in 0..3 {
                num += (qq[k] - bb[k]).powi(2);
                den += bb[k] * bb[k];
            }
        }
        (num / den).sqrt()
    }

    #[test]
    fn agrees_with_the_f64_reference_within_the_tolerance() {
        let (seq, anchors) = problem_input(6000, 10);
        let window = Window { start: 0, len: 10 };
        let problem = WindowProblem::new(&seq.topology, &anchors, window, Coefficients::default());
        let b = problem.fused_rhs();
        for tol in [1e-3, 1e-4] {
            let (xr, sr) = solve3(&problem.op, &b, tol, 1000).unwrap();
            let (xl, sl) = solve3_lean(&problem.op, &b, tol, 1000).unwrap();
            let res = residual(&problem.op, &xl, &b);
            assert!(res <= tol, "tol {tol:e}: true residual {res:e}");
            assert!((res - sl.relative_residual).abs() < 1e-9 * tol.max(res));
            assert!(
                sl.iterations.abs_diff(sr.iterations) <= 1,
                "tol {tol:e}: {} vs {} iterations",
                sl.iterations,
                sr.iterations
            );
            // Same iterates up to f32 rounding: far closer than the tolerance separates solutions.
            let (mut num, mut den) = (0.0f64, 0.0f64);
            for (a, c) in xl.iter().zip(&xr) {
                for k in 0..3 {
                    num += (a[k] - c[k]).powi(2);
                    den += c[k] * c[k];
                }
            }
            let rel = (num / den).sqrt();
            assert!(
                den > 0.0 && rel < 1e-4,
                "tol {tol:e}: relative difference {rel:e}"
            );
        }
    }

    #[test]
    fn results_do_not_depend_on_the_thread_count() {
        let (seq, anchors) = problem_input(6000, 10);
        let window = Window { start: 0, len: 10 };
        let problem = WindowProblem::new(&seq.topology, &anchors, window, Coefficients::default());
        let b = problem.fused_rhs();
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| solve3_lean(&problem.op, &b, 1e-3, 1000).unwrap().0)
        };
        let bits = |x: &[[f64; 3]]| -> Vec<u64> { x.iter().flat_map(|v| v.map(f64::to_bits)).collect() };
        assert_eq!(bits(&run(1)), bits(&run(3)));
    }

    #[test]
    fn tight_tolerances_use_the_f64_solver_and_bad_input_is_named() {
        let (seq, anchors) = problem_input(6000, 10);
        let window = Window { start: 2, len: 6 };
        let problem = WindowProblem::new(&seq.topology, &anchors, window, Coefficients::default());
        let b = problem.fused_rhs();
        let (xr, _) = solve3(&problem.op, &b, 1e-8, 1000).unwrap();
        let (xl, sl) = solve3_lean(&problem.op, &b, 1e-8, 1000).unwrap();
        assert!(sl.relative_residual <= 1e-8);
        assert!(xr
            .iter()
            .zip(&xl)
            .all(|(a, c)| (0..3).all(|k| a[k].to_bits() == c[k].to_bits())));

        let zero = vec![[0.0; 3]; b.len()];
        let (x0, s0) = solve3_lean(&problem.op, &zero, 1e-3, 1000).unwrap();
        assert!(x0.iter().all(|v| *v == [0.0; 3]) && s0.iterations == 0);

        let e = solve3_lean(&problem.op, &b[1..], 1e-3, 1000).unwrap_err();
        assert!(e.to_string().contains("right-hand side"), "{e}");
        let e = solve3_lean(&problem.op, &b, 1e-3, 2).unwrap_err();
        assert!(e.to_string().contains("deform.cg_max_iterations"), "{e}");
    }
}

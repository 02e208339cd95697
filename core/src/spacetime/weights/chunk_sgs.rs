//! The fused weight solve's block CG with a chunk-local symmetric Gauss–Seidel preconditioner.
//!
//! Jacobi-preconditioned CG needs about 17 iterations on a paper-scale window and each iteration is bound by
//! instructions, not memory (docs/benchmarks.md, "issue14-weights"), so the lever is fewer iterations. The
//! preconditioner here is symmetric Gauss–Seidel on each fixed [`CHUNK`]-node chunk of the space-time
//! operator, ignoring the couplings between chunks (block Jacobi over chunks): P = (D + L) D⁻¹ (D + U) per chunk,
//! symmetric positive definite because each chunk's block of M is, so CG stays CG. It halves the iteration count
//! (9 instead of 17 on the 100K window).
//!
//! Why chunk-local: chunks are fixed by the node count, never by the thread count, and each chunk's sweeps read
//! only its own nodes, so the result is the same bits for any number of threads (and on any worker).
//!
//! Each iteration is two sweeps over the nodes:
//! - (A) per chunk, x += α p and r −= α q with ⟨r, r⟩, then z = P⁻¹ r by a forward and a backward sweep on the
//!   chunk (the chunk's r is still in cache) with ⟨r, z⟩;
//! - (B) p = z + β p and q = M z + β q (= M p, without waiting for every chunk's new p before the stencil) with
//!   ⟨p, q⟩.
//!
//! Storage and arithmetic follow [`super::lean_cg`]: f32 vectors, f64 products and reductions, per-chunk
//! partial sums added in chunk order, the stopping test confirmed on the true residual in f64.

use super::fused::CgStats;
use super::lean_cg::{in_order, no_convergence, to32, to64, true_residual, LeanOperator, V3f};
use super::operator::CHUNK;
use crate::error::{Error, Result};
use crate::mesh::NONE;
use rayon::prelude::*;

/// z = P⁻¹ r on the chunk starting at node `s` (`r` is the chunk's slice), written to `z`; returns ⟨r, z⟩ with
/// the stored (f32) z. `w` is f64 scratch of the chunk's length.
fn precondition_chunk(
    lean: &LeanOperator,
    s: usize,
    r: &[V3f],
    z: &mut [V3f],
    w: &mut Vec<[f64; 3]>,
) -> f64 {
    let len = r.len();
    w.clear();
    w.resize(len, [0.0; 3]);
    let (c_s, c_t, n_tri) = (lean.c_s, lean.c_t, lean.n_tri);
    // Forward: (D + L) y = r, L = the chunk's couplings to lower-numbered nodes.
    let mut at = lean.locate(s);
    for k in 0..len {
        let (lt, i) = at;
        at = lean.next(at);
        let n = s + k;
        let base = n - i;
        let mut acc = to64(r[k]);
        let mut add = |m: usize, c: f64| {
            // m − s < k ⇔ s ≤ m < n (unsigned wrap-around rejects m < s).
            let l = m.wrapping_sub(s);
            if l < k {
                let y = w[l];
                acc[0] += c * y[0];
                acc[1] += c * y[1];
                acc[2] += c * y[2];
            }
        };
        for &j in &lean.tri_adj[i] {
            if j != NONE {
                add(base + j as usize, c_s);
            }
        }
        if lt > 0 {
            add(n - n_tri, c_t);
        }
        let d = lean.inv_diag[lean.class[n] as usize];
        w[k] = [acc[0] * d, acc[1] * d, acc[2] * d];
    }
    // Backward: (D + U) z = D y, in place (w[k] holds y until node k is reached, z after).
    let mut rz = 0.0;
    let mut at = lean.locate(s + len - 1);
    for k in (0..len).rev() {
        let n = s + k;
        let (lt, i) = at;
        at = if i == 0 {
            (lt.wrapping_sub(1), n_tri - 1)
        } else {
            (lt, i - 1)
        };
        let base = n - i;
        let mut acc = [0.0f64; 3];
        let mut add = |m: usize, c: f64| {
            // k < m − s < len ⇔ n < m < chunk end.
            let l = m.wrapping_sub(s);
            if l > k && l < len {
                let y = w[l];
                acc[0] += c * y[0];
                acc[1] += c * y[1];
                acc[2] += c * y[2];
            }
        };
        for &j in &lean.tri_adj[i] {
            if j != NONE {
                add(base + j as usize, c_s);
            }
        }
        if lt + 1 < lean.n_frames {
            add(n + n_tri, c_t);
        }
        let d = lean.inv_diag[lean.class[n] as usize];
        let y = w[k];
        let zk = [y[0] + acc[0] * d, y[1] + acc[1] * d, y[2] + acc[2] * d];
        w[k] = zk;
        let z32 = to32(zk);
        z[k] = z32;
        let (rv, zv) = (to64(r[k]), to64(z32));
        rz += rv[0] * zv[0] + rv[1] * zv[1] + rv[2] * zv[2];
    }
    rz
}

/// Block CG with the chunk-SGS preconditioner; `bnorm` = ‖B‖_F > 0. Same stopping rule and error as the
/// Jacobi kernel.
pub(super) fn solve(
    lean: &LeanOperator,
    b: &[[f64; 3]],
    bnorm: f64,
    tol: f64,
    max_iter: usize,
) -> Result<(Vec<[f64; 3]>, CgStats)> {
    let n = lean.n_nodes();
    let mut stats = CgStats::default();
    let mut x: Vec<V3f> = vec![[0.0; 3]; n];
    let mut r: Vec<V3f> = b.par_iter().map(|&v| to32(v)).collect();
    let mut z: Vec<V3f> = vec![[0.0; 3]; n];
    let mut p: Vec<V3f> = vec![[0.0; 3]; n];
    let mut q: Vec<V3f> = vec![[0.0; 3]; n];
    let scratch = || Vec::with_capacity(CHUNK);
    // z = P⁻¹ r, ⟨r, z⟩.
    let mut rz = in_order(
        z.par_chunks_mut(CHUNK)
            .zip(r.par_chunks(CHUNK))
            .enumerate()
            .map_init(scratch, |w, (c, (zs, rs))| {
                [precondition_chunk(lean, c * CHUNK, rs, zs, w), 0.0]
            })
            .collect(),
    )[0];
    let mut beta = 0.0;
    let mut it = 0usize;
    while it < max_iter {
        it += 1;
        // (B) p = z + β p, q = M z + β q, ⟨p, q⟩. With p = q = 0 at the start, the first pass sets p = z.
        let pq = in_order(
            p.par_chunks_mut(CHUNK)
                .zip(q.par_chunks_mut(CHUNK))
                .enumerate()
                .map(|(c, (ps, qs))| {
                    let mut acc = 0.0;
                    let mut at = lean.locate(c * CHUNK);
                    for (k, (pk, qk)) in ps.iter_mut().zip(qs.iter_mut()).enumerate() {
                        let nd = c * CHUNK + k;
                        let mz = lean.row(&z, nd, at);
                        at = lean.next(at);
                        let (zv, pv, qv) = (to64(z[nd]), to64(*pk), to64(*qk));
                        let pn = to32([
                            zv[0] + beta * pv[0],
                            zv[1] + beta * pv[1],
                            zv[2] + beta * pv[2],
                        ]);
                        let qn = to32([
                            mz[0] + beta * qv[0],
                            mz[1] + beta * qv[1],
                            mz[2] + beta * qv[2],
                        ]);
                        *pk = pn;
                        *qk = qn;
                        let (pn, qn) = (to64(pn), to64(qn));
                        acc += pn[0] * qn[0] + pn[1] * qn[1] + pn[2] * qn[2];
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
        // (A) x += α p, r −= α q, ⟨r, r⟩; z = P⁻¹ r, ⟨r, z⟩.
        let [rr, rz_new] = in_order(
            x.par_chunks_mut(CHUNK)
                .zip(r.par_chunks_mut(CHUNK))
                .zip(z.par_chunks_mut(CHUNK))
                .enumerate()
                .map_init(scratch, |w, (c, ((xs, rs), zs))| {
                    let base = c * CHUNK;
                    let mut rr = 0.0;
                    for (k, (xk, rk)) in xs.iter_mut().zip(rs.iter_mut()).enumerate() {
                        let (pv, qv) = (to64(p[base + k]), to64(q[base + k]));
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
                        rr += rn[0] * rn[0] + rn[1] * rn[1] + rn[2] * rn[2];
                    }
                    [rr, precondition_chunk(lean, base, rs, zs, w)]
                })
                .collect(),
        );
        stats.iterations = it;
        stats.relative_residual = rr.sqrt() / bnorm;
        if stats.relative_residual <= tol {
            // Confirm on the true residual of the stored iterate (the recurrences drift from it by f32
            // round-off); continue iterating in the rare case it is still above the tolerance.
            let true_rel = true_residual(lean, &x, b) / bnorm;
            stats.relative_residual = true_rel;
            if true_rel <= tol {
                return Ok((x.par_iter().map(|&v| to64(v)).collect(), stats));
            }
        }
        beta = rz_new / rz;
        rz = rz_new;
    }
    Err(no_convergence(tol, max_iter, stats.relative_residual))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spacetime::weights::fused::solve3;
    use crate::spacetime::weights::lean_cg::tests::{problem_input, residual};
    use crate::spacetime::weights::lean_cg::{solve3_lean_with, Preconditioner};
    use crate::spacetime::weights::operator::Coefficients;
    use crate::spacetime::weights::WindowProblem;
    use crate::spacetime::windows::Window;

    /// The weight problem over every frame of `seq`, with the default coefficients.
    fn whole_window<'a>(
        seq: &'a crate::mesh::Sequence,
        anchors: &crate::folds::AnchorSet,
    ) -> WindowProblem<'a> {
        let window = Window {
            start: 0,
            len: seq.frames.len(),
        };
        WindowProblem::new(&seq.topology, anchors, window, Coefficients::default())
    }

    /// P z = r with P = (D + L) D⁻¹ (D + U) on each chunk, built independently of the sweeps from the
    /// operator's own neighbour list: checks that the sweeps apply exactly the intended (symmetric)
    /// preconditioner, on a mesh whose frames fit in a chunk (time couplings inside chunks) and one whose
    /// frames span several chunks.
    #[test]
    fn sweeps_invert_the_chunk_sgs_matrix() {
        for (triangles, frames) in [(3000, 6), (12000, 3)] {
            let (seq, anchors) = problem_input(triangles, frames);
            let problem = whole_window(&seq, &anchors);
            let op = &problem.op;
            let lean = LeanOperator::new(op).unwrap();
            let n = op.n_nodes();
            assert!(
                n > 2 * CHUNK,
                "{n} nodes: the case must have several chunks"
            );
            // A deterministic, irregular right-hand side exactly representable in f32.
            let r: Vec<V3f> = (0..n)
                .map(|k| {
                    let h = (k as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40;
                    let v = (h % 2001) as f32 / 1000.0 - 1.0;
                    [v, 0.5 * v + 0.25, -v]
                })
                .collect();
            let mut z = vec![[0.0f32; 3]; n];
            let mut w = Vec::new();
            let mut rz = 0.0;
            for (c, (zs, rs)) in z.chunks_mut(CHUNK).zip(r.chunks(CHUNK)).enumerate() {
                rz += precondition_chunk(&lean, c * CHUNK, rs, zs, &mut w);
            }
            let chunk = |m: usize| m / CHUNK;
            let d = op.diag();
            // u = (D + U) z, then v = (D + L) D⁻¹ u; compare with r.
            let zf: Vec<[f64; 3]> = z.iter().map(|&v| to64(v)).collect();
            let mut u = vec![[0.0f64; 3]; n];
            for nd in 0..n {
                let mut s = [d[nd] * zf[nd][0], d[nd] * zf[nd][1], d[nd] * zf[nd][2]];
                op.for_each_neighbor(nd, |m, c| {
                    if m > nd && chunk(m) == chunk(nd) {
                        (0..3).for_each(|k| s[k] -= c * zf[m][k]);
                    }
                });
                u[nd] = s;
            }
            let (mut err, mut scale) = (0.0f64, 0.0f64);
            let mut rz_check = 0.0;
            for nd in 0..n {
                let mut s = u[nd];
                op.for_each_neighbor(nd, |m, c| {
                    if m < nd && chunk(m) == chunk(nd) {
                        (0..3).for_each(|k| s[k] -= c * u[m][k] / d[m]);
                    }
                });
                for k in 0..3 {
                    err = err.max((s[k] - r[nd][k] as f64).abs());
                    scale = scale.max((r[nd][k] as f64).abs());
                    rz_check += r[nd][k] as f64 * zf[nd][k];
                }
            }
            // z is stored in f32: P z reproduces r to f32 rounding times the norm of P (≤ 4 · max diagonal).
            assert!(
                err <= 1e-5 * scale,
                "{triangles}×{frames}: |P z − r| = {err:e}"
            );
            assert!(
                (rz - rz_check).abs() <= 1e-9 * rz_check.abs(),
                "{rz} vs {rz_check}"
            );
            assert!(rz > 0.0, "P must be positive definite");
        }
    }

    /// Meets the tolerance by the true residual, in fewer iterations than Jacobi, and lands on the reference
    /// solution within what the tolerance allows.
    #[test]
    fn reaches_the_tolerance_in_fewer_iterations_than_jacobi() {
        for (triangles, frames) in [(6000, 10), (12000, 4)] {
            let (seq, anchors) = problem_input(triangles, frames);
            let problem = whole_window(&seq, &anchors);
            let b = problem.fused_rhs();
            for tol in [1e-3, 1e-4] {
                let (xr, _) = solve3(&problem.op, &b, 1e-9, 10_000).unwrap();
                let (xj, sj) =
                    solve3_lean_with(&problem.op, &b, tol, 1000, Preconditioner::Jacobi).unwrap();
                let (xs, ss) =
                    solve3_lean_with(&problem.op, &b, tol, 1000, Preconditioner::ChunkSgs).unwrap();
                let res = residual(&problem.op, &xs, &b);
                assert!(res <= tol, "tol {tol:e}: true residual {res:e}");
                assert!((res - ss.relative_residual).abs() < 1e-9 * tol.max(res));
                assert!(
                    ss.iterations < sj.iterations,
                    "{triangles}×{frames}, tol {tol:e}: SGS {} iterations, Jacobi {}",
                    ss.iterations,
                    sj.iterations
                );
                // Error against the converged solution: of the order of Jacobi's at the same tolerance.
                let err = |x: &[[f64; 3]]| {
                    let (mut num, mut den) = (0.0f64, 0.0f64);
                    for (a, c) in x.iter().zip(&xr) {
                        for k in 0..3 {
                            num += (a[k] - c[k]).powi(2);
                            den += c[k] * c[k];
                        }
                    }
                    (num / den).sqrt()
                };
                let (es, ej) = (err(&xs), err(&xj));
                eprintln!(
                    "{triangles}×{frames} tol {tol:e}: SGS {} it, error {es:.2e}; Jacobi {} it, error {ej:.2e}",
                    ss.iterations, sj.iterations
                );
                assert!(
                    es <= 3.0 * ej.max(tol * 0.1),
                    "SGS error {es:e}, Jacobi {ej:e}"
                );
            }
        }
    }
}

//! `fused` mode: the blended rotation field of a window from three right-hand sides.
//!
//! The blend exp(Σ_a w_a φ_a) needs only X = W Φ (one rotation vector per node), and because the weights
//! solve M W = c_a E, X solves M X = c_a E Φ: three right-hand sides instead of one per anchor.
//! Solved with Jacobi-preconditioned conjugate gradient on all three columns at once (see [`solve3`]), with
//! rows × 3 storage so one sweep over the mesh adjacency serves all three columns. [`solve3`] is the plain f64
//! statement of the algorithm (the reference the per-anchor solver's iterates are checked against); the
//! deformation runs the same iteration through [`super::lean_cg::solve3_lean`], which moves fewer bytes.

use super::operator::{SpaceTimeOperator, CHUNK};
use crate::error::{Error, Result};
use rayon::prelude::*;

/// Outcome of a CG solve.
#[derive(Debug, Clone, Copy, Default, serde::Serialize)]
pub struct CgStats {
    pub iterations: usize,
    /// Final relative residual ‖r‖/‖b‖ (Frobenius over the columns in fused mode; worst column in per-anchor).
    pub relative_residual: f64,
}

/// Σ over nodes of f(node) for each of 3 columns, summed chunk by chunk in a fixed order (deterministic).
fn sum3(n: usize, f: impl Fn(usize) -> [f64; 3] + Sync) -> [f64; 3] {
    let partial: Vec<[f64; 3]> = (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| {
            let mut s = [0.0; 3];
            for k in c * CHUNK..((c + 1) * CHUNK).min(n) {
                let v = f(k);
                s[0] += v[0];
                s[1] += v[1];
                s[2] += v[2];
            }
            s
        })
        .collect();
    partial
        .iter()
        .fold([0.0; 3], |a, b| [a[0] + b[0], a[1] + b[1], a[2] + b[2]])
}

/// Solves M X = B (rows × 3) to ‖B − M X‖_F ≤ tol ‖B‖_F.
///
/// The three columns share one step length and one search-direction update computed from Frobenius inner
/// products (CG on M ⊗ I₃). Unlike per-column CG this is exactly equivariant under rotations of the anchors'
/// rotation vectors (B → B Q leaves every inner product unchanged), so a rigidly moved capture with rigidly
/// moved anchors yields a rigidly moved result to round-off, not merely to the solver tolerance.
pub fn solve3(
    op: &SpaceTimeOperator,
    b: &[[f64; 3]],
    tol: f64,
    max_iter: usize,
) -> Result<(Vec<[f64; 3]>, CgStats)> {
    let n = op.n_nodes();
    assert_eq!(b.len(), n);
    let inv_d: Vec<f64> = op.diag().iter().map(|d| 1.0 / d).collect();
    let dot = |a: &[[f64; 3]], c: &[[f64; 3]]| {
        let s = sum3(n, |k| {
            [a[k][0] * c[k][0], a[k][1] * c[k][1], a[k][2] * c[k][2]]
        });
        s[0] + s[1] + s[2]
    };
    let mut x = vec![[0.0f64; 3]; n];
    let mut r = b.to_vec();
    let mut p: Vec<[f64; 3]> = r
        .iter()
        .zip(&inv_d)
        .map(|(r, d)| [r[0] * d, r[1] * d, r[2] * d])
        .collect();
    let mut q = vec![[0.0f64; 3]; n];
    let bnorm = dot(b, b).sqrt();
    let mut rz = dot(&r, &p);
    let mut stats = CgStats::default();
    if bnorm == 0.0 {
        return Ok((x, stats));
    }
    for it in 1..=max_iter {
        op.apply3(&p, &mut q);
        let alpha = rz / dot(&p, &q);
        if !alpha.is_finite() {
            return Err(Error::numeric(
                "weights (fused CG)",
                "breakdown: non-finite step",
            ));
        }
        x.par_chunks_mut(CHUNK)
            .zip(r.par_chunks_mut(CHUNK))
            .enumerate()
            .for_each(|(c, (xs, rs))| {
                let base = c * CHUNK;
                for k in 0..xs.len() {
                    for j in 0..3 {
                        xs[k][j] += alpha * p[base + k][j];
                        rs[k][j] -= alpha * q[base + k][j];
                    }
                }
            });
        let rel = dot(&r, &r).sqrt() / bnorm;
        stats.iterations = it;
        stats.relative_residual = rel;
        if rel <= tol {
            return Ok((x, stats));
        }
        let rz_new = sum3(n, |k| {
            let d = inv_d[k];
            [
                r[k][0] * r[k][0] * d,
                r[k][1] * r[k][1] * d,
                r[k][2] * r[k][2] * d,
            ]
        });
        let rz_new = rz_new[0] + rz_new[1] + rz_new[2];
        let beta = rz_new / rz;
        rz = rz_new;
        p.par_chunks_mut(CHUNK).enumerate().for_each(|(c, ps)| {
            let base = c * CHUNK;
            for (k, pk) in ps.iter_mut().enumerate() {
                let d = inv_d[base + k];
                for j in 0..3 {
                    pk[j] = r[base + k][j] * d + beta * pk[j];
                }
            }
        });
    }
    Err(Error::numeric(
        "weights (fused CG)",
        format!(
            "did not reach relative residual {tol:e} in {max_iter} iterations (at {:.3e}); raise the tuning key deform.cg_max_iterations or deform.cg_tolerance",
            stats.relative_residual
        ),
    ))
}

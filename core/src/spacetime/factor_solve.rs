//! Triangular solves with a supernodal Cholesky factor for exactly three right-hand sides (the x, y, z of the
//! positioning displacements), stored row-interleaved.
//!
//! faer's supernodal solve treats each supernode as a dense block and calls its dense triangular-solve and
//! matrix-product kernels on it. The positioning factor of a mesh Laplacian has tens of thousands of supernodes of
//! a few columns each, where that per-call overhead dominates and each right-hand-side column streams the factor
//! separately. Here one sweep over the factor serves all three columns: each factor entry is loaded once and
//! applied to three contiguous values. Same factor, same permutation, same arithmetic up to summation order.

use faer::sparse::linalg::cholesky::{SymbolicCholesky, SymbolicCholeskyRaw};
use faer::{Mat, MatMut};

/// Overwrites `rhs` (n × 3) with (L Lᵀ)⁻¹ rhs in the original ordering, for a supernodal factor `l_values` of
/// `symbolic`. Returns false (leaving `rhs` untouched) when the factor is not supernodal or `rhs` is not n × 3;
/// the caller then uses faer's general solve.
pub fn solve3_supernodal(
    symbolic: &SymbolicCholesky<usize>,
    l_values: &[f64],
    rhs: &mut Mat<f64>,
) -> bool {
    let SymbolicCholeskyRaw::Supernodal(sn) = symbolic.raw() else {
        return false;
    };
    let n = sn.nrows();
    if rhs.nrows() != n || rhs.ncols() != 3 || l_values.len() != sn.len_val() {
        return false;
    }
    // Permute into row-interleaved storage: x[i] = rhs[fwd[i]].
    let mut x: Vec<[f64; 3]> = match symbolic.perm() {
        Some(p) => p
            .arrays()
            .0
            .iter()
            .map(|&f| [rhs[(f, 0)], rhs[(f, 1)], rhs[(f, 2)]])
            .collect(),
        None => (0..n)
            .map(|i| [rhs[(i, 0)], rhs[(i, 1)], rhs[(i, 2)]])
            .collect(),
    };
    let begin = sn.supernode_begin();
    let end = sn.supernode_end();
    let val_ptr = sn.col_ptr_for_val();
    let row_ptr = sn.col_ptr_for_row_idx();
    let rows = sn.row_idx();
    let ns = sn.n_supernodes();
    // Supernode s: columns start..end, a dense column-major block of (size + |pattern|) rows; the first `size`
    // rows are the lower-triangular diagonal block, the rest the rows listed in `pattern`.
    let block = |s: usize| {
        let (start, size) = (begin[s], end[s] - begin[s]);
        let vals = &l_values[val_ptr[s]..val_ptr[s + 1]];
        let m = vals.len() / size - size;
        let pattern = &rows[row_ptr[s]..row_ptr[s] + m];
        (start, size, vals, pattern)
    };
    // Forward: L y = b.
    for s in 0..ns {
        let (start, size, vals, pattern) = block(s);
        let ld = size + pattern.len();
        for c in 0..size {
            let col = &vals[c * ld..(c + 1) * ld];
            let d = col[c];
            let yc = x[start + c];
            let yc = [yc[0] / d, yc[1] / d, yc[2] / d];
            x[start + c] = yc;
            for r in c + 1..size {
                let l = col[r];
                let xr = &mut x[start + r];
                xr[0] -= l * yc[0];
                xr[1] -= l * yc[1];
                xr[2] -= l * yc[2];
            }
            for (k, &i) in pattern.iter().enumerate() {
                let l = col[size + k];
                let xi = &mut x[i];
                xi[0] -= l * yc[0];
                xi[1] -= l * yc[1];
                xi[2] -= l * yc[2];
            }
        }
    }
    // Backward: Lᵀ x = y.
    for s in (0..ns).rev() {
        let (start, size, vals, pattern) = block(s);
        let ld = size + pattern.len();
        for c in (0..size).rev() {
            let col = &vals[c * ld..(c + 1) * ld];
            let mut acc = x[start + c];
            for r in c + 1..size {
                let l = col[r];
                let xr = x[start + r];
                acc[0] -= l * xr[0];
                acc[1] -= l * xr[1];
                acc[2] -= l * xr[2];
            }
            for (k, &i) in pattern.iter().enumerate() {
                let l = col[size + k];
                let xi = x[i];
                acc[0] -= l * xi[0];
                acc[1] -= l * xi[1];
                acc[2] -= l * xi[2];
            }
            let d = col[c];
            x[start + c] = [acc[0] / d, acc[1] / d, acc[2] / d];
        }
    }
    // Back to the original ordering: rhs[i] = x[inv[i]].
    let mut out: MatMut<'_, f64> = rhs.as_mut();
    match symbolic.perm() {
        Some(p) => {
            for (i, &v) in p.arrays().1.iter().enumerate() {
                for c in 0..3 {
                    out[(i, c)] = x[v][c];
                }
            }
        }
        None => {
            for (i, xi) in x.iter().enumerate() {
                for c in 0..3 {
                    out[(i, c)] = xi[c];
                }
            }
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spacetime::position::PositionSystem;
    use crate::spacetime::DeformParams;
    use crate::synth::{self, DemoSpec};
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, LltRef, SymmetricOrdering};
    use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
    use faer::{Conj, Par, Side};

    /// The interleaved solve must agree with faer's own supernodal solve on the positioning matrix of a real
    /// mesh (to round-off: only the summation order differs).
    #[test]
    fn matches_faer_on_a_positioning_matrix() {
        let (seq, _) = synth::demo(&DemoSpec {
            triangles: 20_000,
            frames: 2,
            ..Default::default()
        })
        .unwrap();
        let params = DeformParams::default();
        let sys =
            PositionSystem::new(seq.topology.clone(), params.pinning, params.screen()).unwrap();
        let (vals, _, _, _) = sys.assemble(&seq.frames[0]).unwrap();
        let (cp, ri) = sys.pattern();
        let n = cp.len() - 1;
        let pattern = SymbolicSparseColMatRef::new_checked(n, n, cp, None, ri);
        let symbolic = factorize_symbolic_cholesky(
            pattern,
            Side::Lower,
            SymmetricOrdering::Amd,
            Default::default(),
        )
        .unwrap();
        assert!(matches!(symbolic.raw(), SymbolicCholeskyRaw::Supernodal(_)));
        let mut l = vec![0.0; symbolic.len_val()];
        let mut buf = MemBuffer::new(
            symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
        );
        symbolic
            .factorize_numeric_llt::<f64>(
                &mut l,
                SparseColMatRef::new(pattern, &vals),
                Side::Lower,
                Default::default(),
                Par::Seq,
                MemStack::new(&mut buf),
                Default::default(),
            )
            .unwrap();
        let b = Mat::<f64>::from_fn(n, 3, |i, j| ((i * 7 + j * 13) % 17) as f64 - 8.0);
        let mut ours = b.clone();
        assert!(solve3_supernodal(&symbolic, &l, &mut ours));
        let mut theirs = b.clone();
        let mut buf = MemBuffer::new(symbolic.solve_in_place_scratch::<f64>(3, Par::Seq));
        LltRef::<usize, f64>::new(&symbolic, &l).solve_in_place_with_conj(
            Conj::No,
            theirs.as_mut(),
            Par::Seq,
            MemStack::new(&mut buf),
        );
        let scale = (0..n)
            .flat_map(|i| (0..3).map(move |j| (i, j)))
            .map(|(i, j)| theirs[(i, j)].abs())
            .fold(0.0, f64::max);
        let worst = (0..n)
            .flat_map(|i| (0..3).map(move |j| (i, j)))
            .map(|(i, j)| (ours[(i, j)] - theirs[(i, j)]).abs())
            .fold(0.0, f64::max);
        assert!(
            scale > 0.0 && worst <= 1e-10 * scale,
            "{worst} vs scale {scale}"
        );

        // Not three columns: declined, untouched (the caller falls back to faer).
        let mut two = Mat::<f64>::from_fn(n, 2, |i, j| (i + j) as f64);
        let before = two.clone();
        assert!(!solve3_supernodal(&symbolic, &l, &mut two));
        assert!(two == before);
    }
}

//! Triangular solves with a supernodal Cholesky factor for exactly three right-hand sides (the x, y, z of the
//! positioning displacements), stored row-interleaved.
//!
//! faer's supernodal solve treats each supernode as a dense block and calls its dense triangular-solve and
//! matrix-product kernels on it. The positioning factor of a mesh Laplacian has tens of thousands of supernodes of
//! a few columns each, where that per-call overhead dominates and each right-hand-side column streams the factor
//! separately. Here one sweep over the factor serves all three columns, and a supernode is applied in groups of
//! up to four columns, row by row: each row below a group's triangle is read from (backward) or written to
//! (forward) the solution once per group, with the group's columns summed in registers, instead of once per
//! column. Group widths 1–4 are compiled separately so that those sums are straight-line code. Same factor, same
//! permutation, same arithmetic up to summation order.

use faer::sparse::linalg::cholesky::{SymbolicCholesky, SymbolicCholeskyRaw};
use faer::Mat;

type Row = [f64; 3];

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
    let perm = symbolic.perm().map(|p| p.arrays());
    // Permute into row-interleaved storage: x[i] = rhs[fwd[i]].
    let mut x: Vec<Row> = {
        let (c0, c1, c2) = (
            rhs.col_as_slice(0),
            rhs.col_as_slice(1),
            rhs.col_as_slice(2),
        );
        match perm {
            Some((fwd, _)) => fwd.iter().map(|&f| [c0[f], c1[f], c2[f]]).collect(),
            None => (0..n).map(|i| [c0[i], c1[i], c2[i]]).collect(),
        }
    };
    let begin = sn.supernode_begin();
    let end = sn.supernode_end();
    let val_ptr = sn.col_ptr_for_val();
    let row_ptr = sn.col_ptr_for_row_idx();
    let rows = sn.row_idx();
    let ns = sn.n_supernodes();
    // Supernode s: columns start..start+size, a dense column-major block of (size + |pattern|) rows; the first
    // `size` rows are the lower-triangular diagonal block, the rest the rows listed in `pattern` (all of them
    // after the supernode's last column).
    let block = |s: usize| {
        let (start, size) = (begin[s], end[s] - begin[s]);
        let vals = &l_values[val_ptr[s]..val_ptr[s + 1]];
        let m = vals.len() / size - size;
        let pattern = &rows[row_ptr[s]..row_ptr[s] + m];
        (start, size, vals, pattern)
    };
    // Forward: L y = b, each supernode in groups of up to four columns.
    for s in 0..ns {
        let (start, size, vals, pattern) = block(s);
        let (head, tail) = x.split_at_mut(start + size);
        let mut b = Block {
            y: &mut head[start..],
            vals,
            ld: vals.len() / size,
            pattern,
            tail_start: start + size,
        };
        for c0 in (0..size).step_by(GROUP) {
            match size - c0 {
                1 => b.forward::<1>(c0, tail),
                2 => b.forward::<2>(c0, tail),
                3 => b.forward::<3>(c0, tail),
                _ => b.forward::<4>(c0, tail),
            }
        }
    }
    // Backward: Lᵀ x = y, the same groups in reverse order.
    for s in (0..ns).rev() {
        let (start, size, vals, pattern) = block(s);
        let (head, tail) = x.split_at_mut(start + size);
        let mut b = Block {
            y: &mut head[start..],
            vals,
            ld: vals.len() / size,
            pattern,
            tail_start: start + size,
        };
        for c0 in (0..size).step_by(GROUP).rev() {
            match size - c0 {
                1 => b.backward::<1>(c0, tail),
                2 => b.backward::<2>(c0, tail),
                3 => b.backward::<3>(c0, tail),
                _ => b.backward::<4>(c0, tail),
            }
        }
    }
    // Back to the original ordering: rhs[i] = x[inv[i]].
    for c in 0..3 {
        let col = rhs.col_as_slice_mut(c);
        match perm {
            Some((_, inv)) => {
                for (o, &v) in col.iter_mut().zip(inv) {
                    *o = x[v][c];
                }
            }
            None => {
                for (o, xi) in col.iter_mut().zip(&x) {
                    *o = xi[c];
                }
            }
        }
    }
    true
}

/// Columns handled together: their contributions to a row are summed in registers, so each row of the
/// solution is loaded (and, forward, stored) once per group instead of once per column.
const GROUP: usize = 4;

/// One supernode during a sweep: its own rows `y` of the solution, its dense column-major block `vals`
/// (leading dimension `ld`: the diagonal block's `y.len()` rows, then the rows of `pattern`), and where the rows
/// after it begin (`tail` in the sweeps holds the solution from row `tail_start` on).
struct Block<'a> {
    y: &'a mut [Row],
    vals: &'a [f64],
    ld: usize,
    pattern: &'a [usize],
    tail_start: usize,
}

impl Block<'_> {
    /// Forward step for columns c0..c0+G: solve their G×G triangle, then subtract their contribution from every
    /// row below it (the rest of the diagonal block, then the pattern rows), one row at a time.
    #[inline(always)]
    fn forward<const G: usize>(&mut self, c0: usize, tail: &mut [Row]) {
        let (size, ld, m) = (self.y.len(), self.ld, self.pattern.len());
        let cols: [&[f64]; G] =
            std::array::from_fn(|j| &self.vals[(c0 + j) * ld..(c0 + j) * ld + size + m]);
        for (j, col) in cols.iter().enumerate() {
            let d = col[c0 + j];
            let yc = self.y[c0 + j];
            let yc = [yc[0] / d, yc[1] / d, yc[2] / d];
            self.y[c0 + j] = yc;
            for (r, &l) in (j + 1..G).zip(&col[c0 + j + 1..c0 + G]) {
                let yr = &mut self.y[c0 + r];
                yr[0] -= l * yc[0];
                yr[1] -= l * yc[1];
                yr[2] -= l * yc[2];
            }
        }
        let yg: [Row; G] = std::array::from_fn(|j| self.y[c0 + j]);
        let sum = |r: usize| {
            let mut acc = [0.0; 3];
            for (col, yj) in cols.iter().zip(&yg) {
                let l = col[r];
                acc[0] += l * yj[0];
                acc[1] += l * yj[1];
                acc[2] += l * yj[2];
            }
            acc
        };
        for (r, yr) in self.y.iter_mut().enumerate().skip(c0 + G) {
            let acc = sum(r);
            yr[0] -= acc[0];
            yr[1] -= acc[1];
            yr[2] -= acc[2];
        }
        for (k, &i) in self.pattern.iter().enumerate() {
            let acc = sum(size + k);
            let xi = &mut tail[i - self.tail_start];
            xi[0] -= acc[0];
            xi[1] -= acc[1];
            xi[2] -= acc[2];
        }
    }

    /// Backward step for columns c0..c0+G (every row after them already final): subtract the rows below the
    /// G×G triangle, one row at a time for all G columns, then solve the transposed triangle.
    #[inline(always)]
    fn backward<const G: usize>(&mut self, c0: usize, tail: &[Row]) {
        let (size, ld, m) = (self.y.len(), self.ld, self.pattern.len());
        let cols: [&[f64]; G] =
            std::array::from_fn(|j| &self.vals[(c0 + j) * ld..(c0 + j) * ld + size + m]);
        let mut acc: [Row; G] = std::array::from_fn(|j| self.y[c0 + j]);
        let mut sub = |r: usize, x: Row| {
            for (col, a) in cols.iter().zip(acc.iter_mut()) {
                let l = col[r];
                a[0] -= l * x[0];
                a[1] -= l * x[1];
                a[2] -= l * x[2];
            }
        };
        for (r, &yr) in self.y.iter().enumerate().skip(c0 + G) {
            sub(r, yr);
        }
        for (k, &i) in self.pattern.iter().enumerate() {
            sub(size + k, tail[i - self.tail_start]);
        }
        for (j, (col, mut a)) in cols.iter().zip(acc).enumerate().rev() {
            for (r, &l) in (j + 1..G).zip(&col[c0 + j + 1..c0 + G]) {
                let yr = self.y[c0 + r];
                a[0] -= l * yr[0];
                a[1] -= l * yr[1];
                a[2] -= l * yr[2];
            }
            let d = col[c0 + j];
            self.y[c0 + j] = [a[0] / d, a[1] / d, a[2] / d];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spacetime::position::PositionSystem;
    use crate::spacetime::DeformParams;
    use crate::synth::{self, DemoSpec};
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::sparse::linalg::cholesky::{
        factorize_symbolic_cholesky, CholeskySymbolicParams, LltRef, SymmetricOrdering,
    };
    use faer::sparse::linalg::SymbolicSupernodalParams;
    use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
    use faer::{Conj, Par, Side};

    /// Factorises the positioning matrix of a real mesh with the given supernode relaxation, checks that the
    /// interleaved solve agrees with faer's own supernodal solve (to round-off: only the summation order
    /// differs), and returns the supernode widths the factor had.
    fn agrees_with_faer(relax: &[(usize, f64)]) -> Vec<usize> {
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
            CholeskySymbolicParams {
                supernodal_params: SymbolicSupernodalParams { relax: Some(relax) },
                ..Default::default()
            },
        )
        .unwrap();
        let SymbolicCholeskyRaw::Supernodal(sn) = symbolic.raw() else {
            panic!("the positioning factor should be supernodal");
        };
        let widths = (0..sn.n_supernodes())
            .map(|s| sn.supernode_end()[s] - sn.supernode_begin()[s])
            .collect();
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
        let cells = || (0..n).flat_map(|i| (0..3).map(move |j| (i, j)));
        let scale = cells()
            .map(|(i, j)| theirs[(i, j)].abs())
            .fold(0.0, f64::max);
        let worst = cells()
            .map(|(i, j)| (ours[(i, j)] - theirs[(i, j)]).abs())
            .fold(0.0, f64::max);
        assert!(
            scale > 0.0 && worst <= 1e-10 * scale,
            "relax {relax:?}: {worst} vs scale {scale}"
        );

        // Not three columns: declined, untouched (the caller falls back to faer).
        let mut two = Mat::<f64>::from_fn(n, 2, |i, j| (i + j) as f64);
        let before = two.clone();
        assert!(!solve3_supernodal(&symbolic, &l, &mut two));
        assert!(two == before);
        widths
    }

    /// The solve must agree with faer's on every supernode width it has a separate path for (1, 2, 3, 4 and
    /// wider): faer's default relaxation and a coarser one (wide supernodes with explicit zeros) cover them.
    #[test]
    fn matches_faer_on_a_positioning_matrix() {
        let mut widths = agrees_with_faer(&[(4, 1.0), (16, 0.8), (48, 0.1), (usize::MAX, 0.05)]);
        widths.extend(agrees_with_faer(&[
            (16, 1.0),
            (64, 0.3),
            (usize::MAX, 0.05),
        ]));
        for w in 1..=4 {
            assert!(widths.contains(&w), "no supernode of width {w}");
        }
        assert!(widths.iter().any(|&w| w > 4), "no supernode wider than 4");
    }
}

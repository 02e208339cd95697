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
//!
//! **Solve plan** ([`SolvePlan`], built once per symbolic analysis, so once per sequence). The factor's row
//! indices are kept as `u32` (half the index bytes a sweep streams next to the values), and the supernodal
//! elimination tree is cut into independent subtrees plus the "top" above them, so that the sweeps run on
//! several threads **with the sequential sweep's bits**:
//!
//! - *backward* (Lᵀ x = y): every supernode reads only rows of its ancestors. The top is solved first (it holds
//!   every subtree's ancestors), then the subtrees in parallel, each writing only its own rows: every value is
//!   computed exactly as in the sequential sweep.
//! - *forward* (L y = b): a supernode subtracts its contribution from the rows of its ancestors, so two
//!   subtrees update the same top rows, and the order of those subtractions decides the bits. Each subtree
//!   therefore applies its updates of its own rows directly and *records* its updates of top rows, in order;
//!   then one sequential walk in supernode order replays each subtree's record where the sequential sweep
//!   would have run that subtree, and solves the top supernodes in between. Every row receives the same
//!   subtractions in the same order as in the sequential sweep.
//!
//! So the result does not depend on the cut nor on the thread count (`tests::matches_faer_on_a_positioning_matrix`).
//! The cut needs the supernodes numbered in a postorder of their tree (each subtree a contiguous range), which
//! faer's analysis gives; a factor without it is solved sequentially.

use faer::sparse::linalg::cholesky::{SymbolicCholesky, SymbolicCholeskyRaw};
use faer::Mat;
use rayon::prelude::*;
use std::ops::Range;

type Row = [f64; 3];

/// Overwrites `rhs` (n × 3) with (L Lᵀ)⁻¹ rhs in the original ordering, for a supernodal factor `l_values` of
/// `symbolic`. Returns false (leaving `rhs` untouched) when the factor is not supernodal or `rhs` is not n × 3;
/// the caller then uses faer's general solve. Builds the [`SolvePlan`] on every call: a caller solving with
/// many factors of one analysis builds it once ([`SolvePlan::solve3`], same bits).
pub fn solve3_supernodal(
    symbolic: &SymbolicCholesky<usize>,
    l_values: &[f64],
    rhs: &mut Mat<f64>,
) -> bool {
    match SolvePlan::new(symbolic) {
        Some(plan) => plan.solve3(symbolic, l_values, rhs),
        None => false,
    }
}

/// One supernode: columns `start..start + size`, its dense column-major block at `val` in the factor's values
/// (leading dimension `size + m`: the diagonal block's rows, then its `m` pattern rows, listed at `pat` in
/// [`SolvePlan::pats`]). The first `n_own` pattern rows are rows of the supernode's own part (its subtree, or
/// the whole matrix for a top supernode), as offsets from that part's first column; the rest are indices into
/// the top rows ([`SolvePlan::top_rows`]).
#[derive(Debug, Clone, Copy)]
struct Super {
    start: usize,
    size: usize,
    val: usize,
    pat: usize,
    m: usize,
    n_own: usize,
}

/// A subtree of the cut: supernodes `sns` (a contiguous range in postorder) covering columns `cols`.
#[derive(Debug, Clone)]
struct Subtree {
    sns: Range<usize>,
    cols: Range<usize>,
}

/// The sweeps' view of a factor's structure, built once per symbolic analysis (see the module documentation).
#[derive(Debug, Clone)]
pub struct SolvePlan {
    n: usize,
    len_val: usize,
    supers: Vec<Super>,
    pats: Vec<u32>,
    /// Independent subtrees in supernode order (empty: one sequential sweep over the whole factor).
    subtrees: Vec<Subtree>,
    /// Rows (columns) of the supernodes outside every subtree, ascending.
    top_rows: Vec<u32>,
}

/// The cut stops once every subtree holds at most this fraction of the factor's entries...
const SUBTREE_SHARE: usize = 16;
/// ...or when moving one more supernode to the top would make the top (solved on one thread) hold more than
/// 1/TOP_SHARE of them.
const TOP_SHARE: usize = 4;

impl SolvePlan {
    /// The plan of a supernodal analysis (None for a simplicial one), cut into subtrees where the supernodes
    /// are numbered in postorder.
    pub fn new(symbolic: &SymbolicCholesky<usize>) -> Option<Self> {
        Self::with_cut(symbolic, true)
    }

    /// [`SolvePlan::new`], with the tree cut into subtrees (`cut`) or not (one sequential sweep): the two give
    /// the same bits; tests compare them.
    pub fn with_cut(symbolic: &SymbolicCholesky<usize>, cut: bool) -> Option<Self> {
        let SymbolicCholeskyRaw::Supernodal(sn) = symbolic.raw() else {
            return None;
        };
        let n = sn.nrows();
        if n >= u32::MAX as usize {
            return None;
        }
        let (begin, end) = (sn.supernode_begin(), sn.supernode_end());
        let (val_ptr, row_ptr, rows) =
            (sn.col_ptr_for_val(), sn.col_ptr_for_row_idx(), sn.row_idx());
        let ns = sn.n_supernodes();
        let mut supers = Vec::with_capacity(ns);
        for s in 0..ns {
            let (start, size) = (begin[s], end[s] - begin[s]);
            let len = val_ptr[s + 1] - val_ptr[s];
            let m = len / size - size;
            supers.push(Super {
                start,
                size,
                val: val_ptr[s],
                pat: row_ptr[s],
                m,
                n_own: m,
            });
        }
        let global = |s: &Super| &rows[s.pat..s.pat + s.m];
        let (subtrees, top_rows) = if cut {
            cut_tree(&supers, global, n)
        } else {
            (Vec::new(), Vec::new())
        };
        // Patterns as u32: global rows for top supernodes, own-part offsets then top indices for subtrees.
        let mut top_index = vec![u32::MAX; if subtrees.is_empty() { 0 } else { n }];
        for (k, &r) in top_rows.iter().enumerate() {
            top_index[r as usize] = k as u32;
        }
        let mut pats = Vec::with_capacity(supers.iter().map(|s| s.m).sum());
        let mut owner = vec![usize::MAX; ns];
        for (k, st) in subtrees.iter().enumerate() {
            owner[st.sns.clone()].fill(k);
        }
        for (s, sup) in supers.iter_mut().enumerate() {
            let pattern = &rows[sup.pat..sup.pat + sup.m];
            sup.pat = pats.len();
            match subtrees.get(owner[s]) {
                None => pats.extend(pattern.iter().map(|&r| r as u32)),
                Some(st) => {
                    let own = pattern.partition_point(|&r| r < st.cols.end);
                    sup.n_own = own;
                    pats.extend(pattern[..own].iter().map(|&r| (r - st.cols.start) as u32));
                    for &r in &pattern[own..] {
                        let t = top_index[r];
                        if t == u32::MAX {
                            // A pattern row neither in the subtree nor in the top: not an elimination tree's
                            // structure after all. Solve sequentially.
                            return Self::with_cut(symbolic, false);
                        }
                        pats.push(t);
                    }
                }
            }
        }
        Some(SolvePlan {
            n,
            len_val: sn.len_val(),
            supers,
            pats,
            subtrees,
            top_rows,
        })
    }

    /// Independent subtrees the sweeps run in parallel (0: sequential).
    pub fn n_subtrees(&self) -> usize {
        self.subtrees.len()
    }

    /// [`solve3_supernodal`] with this plan (`symbolic` must be the analysis the plan was built from).
    pub fn solve3(
        &self,
        symbolic: &SymbolicCholesky<usize>,
        l_values: &[f64],
        rhs: &mut Mat<f64>,
    ) -> bool {
        let n = self.n;
        if rhs.nrows() != n || rhs.ncols() != 3 || l_values.len() != self.len_val {
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
        self.forward(l_values, &mut x);
        self.backward(l_values, &mut x);
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

    /// The block of supernode `s` over `own` (the rows of its part, starting at column `base`).
    fn block<'a>(&'a self, l: &'a [f64], s: usize, own: &'a mut [Row], base: usize) -> Block<'a> {
        let sup = self.supers[s];
        let ld = sup.size + sup.m;
        let local = sup.start - base;
        let (head, tail) = own.split_at_mut(local + sup.size);
        Block {
            y: &mut head[local..],
            tail,
            tail_start: local + sup.size,
            vals: &l[sup.val..sup.val + sup.size * ld],
            ld,
            pattern: &self.pats[sup.pat..sup.pat + sup.m],
            n_own: sup.n_own,
        }
    }

    /// Forward step of supernode `s` over its part `own` (first column `base`); updates of top rows go to `emit`.
    fn forward_super(
        &self,
        l: &[f64],
        s: usize,
        own: &mut [Row],
        base: usize,
        emit: &mut impl FnMut(u32, Row),
    ) {
        let mut b = self.block(l, s, own, base);
        let size = b.y.len();
        for c0 in (0..size).step_by(GROUP) {
            match size - c0 {
                1 => b.forward::<1>(c0, emit),
                2 => b.forward::<2>(c0, emit),
                3 => b.forward::<3>(c0, emit),
                _ => b.forward::<4>(c0, emit),
            }
        }
    }

    /// Backward step of supernode `s` over its part `own` (first column `base`); `top` holds the top rows.
    fn backward_super(&self, l: &[f64], s: usize, own: &mut [Row], base: usize, top: &[Row]) {
        let mut b = self.block(l, s, own, base);
        let size = b.y.len();
        for c0 in (0..size).step_by(GROUP).rev() {
            match size - c0 {
                1 => b.backward::<1>(c0, top),
                2 => b.backward::<2>(c0, top),
                3 => b.backward::<3>(c0, top),
                _ => b.backward::<4>(c0, top),
            }
        }
    }

    /// `x` split into the subtrees' own rows (mutable, disjoint).
    fn split<'a>(&self, x: &'a mut [Row]) -> Vec<&'a mut [Row]> {
        let mut parts = Vec::with_capacity(self.subtrees.len());
        let mut rest = x;
        let mut at = 0;
        for st in &self.subtrees {
            let (_, r) = rest.split_at_mut(st.cols.start - at);
            let (mine, r) = r.split_at_mut(st.cols.len());
            parts.push(mine);
            rest = r;
            at = st.cols.end;
        }
        parts
    }

    /// L y = b in place (permuted, interleaved).
    fn forward(&self, l: &[f64], x: &mut [Row]) {
        let ns = self.supers.len();
        let mut no_top =
            |_: u32, _: Row| unreachable!("a top supernode has no top rows outside its part");
        if self.subtrees.is_empty() {
            for s in 0..ns {
                self.forward_super(l, s, x, 0, &mut no_top);
            }
            return;
        }
        // The subtrees in parallel, each recording its updates of top rows in order...
        let records: Vec<Vec<(u32, Row)>> = self
            .split(x)
            .into_par_iter()
            .zip(self.subtrees.par_iter())
            .map(|(own, st)| {
                let mut record = Vec::new();
                for s in st.sns.clone() {
                    self.forward_super(l, s, own, st.cols.start, &mut |t, acc| {
                        record.push((t, acc))
                    });
                }
                record
            })
            .collect();
        // ...then, in supernode order, each subtree's record where the sequential sweep ran it, and the top.
        let mut s = 0;
        let mut k = 0;
        while s < ns {
            match self.subtrees.get(k) {
                Some(st) if st.sns.start == s => {
                    for &(t, acc) in &records[k] {
                        let xi = &mut x[self.top_rows[t as usize] as usize];
                        xi[0] -= acc[0];
                        xi[1] -= acc[1];
                        xi[2] -= acc[2];
                    }
                    s = st.sns.end;
                    k += 1;
                }
                _ => {
                    self.forward_super(l, s, x, 0, &mut no_top);
                    s += 1;
                }
            }
        }
    }

    /// Lᵀ x = y in place: the top (every subtree's ancestors) first, then the subtrees in parallel.
    fn backward(&self, l: &[f64], x: &mut [Row]) {
        let ns = self.supers.len();
        if self.subtrees.is_empty() {
            for s in (0..ns).rev() {
                self.backward_super(l, s, x, 0, &[]);
            }
            return;
        }
        let mut k = self.subtrees.len();
        let mut s = ns;
        while s > 0 {
            match k.checked_sub(1).map(|j| &self.subtrees[j]) {
                Some(st) if st.sns.end == s => {
                    s = st.sns.start;
                    k -= 1;
                }
                _ => {
                    s -= 1;
                    self.backward_super(l, s, x, 0, &[]);
                }
            }
        }
        let top: Vec<Row> = self.top_rows.iter().map(|&r| x[r as usize]).collect();
        self.split(x)
            .into_par_iter()
            .zip(self.subtrees.par_iter())
            .for_each(|(own, st)| {
                for s in st.sns.clone().rev() {
                    self.backward_super(l, s, own, st.cols.start, &top);
                }
            });
    }
}

/// Cuts the supernodal elimination tree (parent of a supernode: the one holding its first pattern row) into
/// independent subtrees and the top above them: starting from the roots, the heaviest subtree (by factor
/// entries) is split into its children while it holds more than 1/[`SUBTREE_SHARE`] of the entries and the top
/// stays under 1/[`TOP_SHARE`]. Returns the subtrees in supernode order and the top's rows, or nothing when
/// the supernodes are not numbered in postorder or fewer than two subtrees come out.
fn cut_tree<'a>(
    supers: &[Super],
    pattern: impl Fn(&Super) -> &'a [usize],
    n: usize,
) -> (Vec<Subtree>, Vec<u32>) {
    let ns = supers.len();
    let none = (Vec::new(), Vec::new());
    if ns < 2 {
        return none;
    }
    let mut sn_of_col = vec![0usize; n];
    for (s, sup) in supers.iter().enumerate() {
        sn_of_col[sup.start..sup.start + sup.size].fill(s);
    }
    let parent: Vec<Option<usize>> = supers
        .iter()
        .map(|sup| pattern(sup).first().map(|&r| sn_of_col[r]))
        .collect();
    // Subtree weights and first supernodes; postorder means every subtree is the range first..=s.
    let mut weight: Vec<usize> = supers.iter().map(|s| s.size * (s.size + s.m)).collect();
    let mut first: Vec<usize> = (0..ns).collect();
    let mut count = vec![1usize; ns];
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); ns];
    for s in 0..ns {
        if let Some(p) = parent[s] {
            if p <= s {
                return none;
            }
            weight[p] += weight[s];
            first[p] = first[p].min(first[s]);
            count[p] += count[s];
            children[p].push(s);
        }
    }
    if (0..ns).any(|s| s + 1 - first[s] != count[s]) {
        return none;
    }
    let total: usize = (0..ns)
        .filter(|&s| parent[s].is_none())
        .map(|s| weight[s])
        .sum();
    let own = |s: usize| supers[s].size * (supers[s].size + supers[s].m);
    let mut frontier: Vec<usize> = (0..ns).filter(|&s| parent[s].is_none()).collect();
    let mut top = vec![false; ns];
    let mut top_weight = 0;
    while let Some((i, &h)) = frontier.iter().enumerate().max_by_key(|(_, &s)| weight[s]) {
        if weight[h] * SUBTREE_SHARE <= total
            || children[h].is_empty()
            || (top_weight + own(h)) * TOP_SHARE > total
        {
            break;
        }
        frontier.swap_remove(i);
        top[h] = true;
        top_weight += own(h);
        frontier.extend(&children[h]);
    }
    if frontier.len() < 2 {
        return none;
    }
    frontier.sort_unstable_by_key(|&s| first[s]);
    let subtrees = frontier
        .iter()
        .map(|&r| Subtree {
            sns: first[r]..r + 1,
            cols: supers[first[r]].start..supers[r].start + supers[r].size,
        })
        .collect();
    let top_rows = (0..ns)
        .filter(|&s| top[s])
        .flat_map(|s| (supers[s].start..supers[s].start + supers[s].size).map(|c| c as u32))
        .collect();
    (subtrees, top_rows)
}

/// Columns handled together: their contributions to a row are summed in registers, so each row of the
/// solution is loaded (and, forward, stored) once per group instead of once per column.
const GROUP: usize = 4;

/// One supernode during a sweep: its own rows `y` of the solution, the rows of its part after it (`tail`, the
/// part's rows from offset `tail_start` on), its dense column-major block `vals` (leading dimension `ld`: the
/// diagonal block's `y.len()` rows, then the rows of `pattern`), and how many pattern rows lie in the part
/// (`n_own`, as offsets in the part; the rest are top rows, as indices into the top).
struct Block<'a> {
    y: &'a mut [Row],
    tail: &'a mut [Row],
    tail_start: usize,
    vals: &'a [f64],
    ld: usize,
    pattern: &'a [u32],
    n_own: usize,
}

impl Block<'_> {
    /// Forward step for columns c0..c0+G: solve their G×G triangle, then subtract their contribution from every
    /// row below it (the rest of the diagonal block, then the pattern rows), one row at a time; a top row's
    /// contribution goes to `emit` instead.
    #[inline(always)]
    fn forward<const G: usize>(&mut self, c0: usize, emit: &mut impl FnMut(u32, Row)) {
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
        let (own, top) = self.pattern.split_at(self.n_own);
        for (k, &i) in own.iter().enumerate() {
            let acc = sum(size + k);
            let xi = &mut self.tail[i as usize - self.tail_start];
            xi[0] -= acc[0];
            xi[1] -= acc[1];
            xi[2] -= acc[2];
        }
        for (k, &t) in top.iter().enumerate() {
            emit(t, sum(size + self.n_own + k));
        }
    }

    /// Backward step for columns c0..c0+G (every row after them already final; `top` holds the top rows):
    /// subtract the rows below the G×G triangle, one row at a time for all G columns, then solve the transposed
    /// triangle.
    #[inline(always)]
    fn backward<const G: usize>(&mut self, c0: usize, top: &[Row]) {
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
        let (own, top_rows) = self.pattern.split_at(self.n_own);
        for (k, &i) in own.iter().enumerate() {
            sub(size + k, self.tail[i as usize - self.tail_start]);
        }
        for (k, &t) in top_rows.iter().enumerate() {
            sub(size + self.n_own + k, top[t as usize]);
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
        let edge = crate::shape::mean_edge_length(&seq.topology, &seq.frames[0]);
        let sys = PositionSystem::new(
            seq.topology.clone(),
            params.pinning,
            params.scales(edge).screen,
        )
        .unwrap();
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
        // The plan cut into subtrees (solved in parallel) and the plain sequential sweep: the same bits, on 1
        // and 3 threads.
        let cut = SolvePlan::new(&symbolic).unwrap();
        let whole = SolvePlan::with_cut(&symbolic, false).unwrap();
        assert_eq!(whole.n_subtrees(), 0);
        assert!(cut.n_subtrees() >= 2, "{} subtrees", cut.n_subtrees());
        let bits = |m: &Mat<f64>| -> Vec<u64> {
            (0..n)
                .flat_map(|i| (0..3).map(move |j| (i, j)))
                .map(|(i, j)| m[(i, j)].to_bits())
                .collect()
        };
        for threads in [1, 3] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            for plan in [&cut, &whole] {
                let mut x = b.clone();
                assert!(pool.install(|| plan.solve3(&symbolic, &l, &mut x)));
                assert_eq!(bits(&x), bits(&ours), "{threads} threads");
            }
        }
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
    /// On both, the plan cut into subtrees gives the sequential sweep's bits on any thread count.
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

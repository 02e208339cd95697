//! The Gauss–Newton normal equations of registration (`register.rs`), assembled in parallel and solved with a
//! Cholesky factorisation whose analysis and buffers are made once per template.
//!
//! Every step of every scan has the same block pattern (node pairs that share a vertex, the pairs the
//! smoothness term links), so the plan below lists once, for each lower 12 × 12 block and for each node, which
//! vertices and graph edges contribute to it. A step then fills each block (and each node's part of the
//! right-hand side) on its own thread, adding the rows' contributions **in the order of the rows** — temporal,
//! data (vertex by vertex: point rows, then the point-to-plane row), boundary, rigidity, smoothness — and
//! computing each product as `(w · a) · b`, as a row-by-row accumulation does. Floating-point sums depend on
//! their order; with this one the system, and so the registration, is the same to the bit whatever the thread
//! count (and the same as the row-by-row assembly this replaces, which hashed its blocks and allocated per row).
//! The numeric factorisation reuses its value buffer and scratch memory: fresh ones cost page faults on every
//! step.

use crease_core::{Error, Result};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{self, SymbolicCholesky};
use faer::sparse::{SparseColMat, SparseColMatRef, SymbolicSparseColMat};
use faer::{Conj, Mat, Par, Side};
use rayon::prelude::*;
use std::collections::HashMap;

/// Unknowns per graph node: A (row-major 3 × 3) then t.
pub(crate) const NV: usize = 12;
const BLOCK: usize = NV * NV;

/// Index of coordinate `c`'s Jacobian entry `q` (0..3: A's row c times the offset; 3: t_c) in a node's 12.
#[inline]
fn loc(c: usize, q: usize) -> usize {
    if q < 3 {
        3 * c + q
    } else {
        9 + c
    }
}

/// The fixed part: block pattern, who contributes to each block and node, the symbolic Cholesky factor and the
/// reusable numeric buffers.
pub(crate) struct Plan {
    n: usize,
    /// Lower blocks (row block ≥ column block), sorted.
    blocks: Vec<(u32, u32)>,
    /// Per block: (vertex, position of the row node in its influence list, of the column node), by vertex.
    block_vertices: Vec<Vec<(u32, u32, u32)>>,
    /// Per block: the graph edges whose smoothness rows touch it, in edge order.
    block_edges: Vec<Vec<u32>>,
    /// Per node: (vertex, position of the node in its influence list), by vertex.
    node_vertices: Vec<Vec<(u32, u32)>>,
    /// Per node: the graph edges touching it, in edge order.
    node_edges: Vec<Vec<u32>>,
    symbolic: SymbolicSparseColMat<usize>,
    /// Per stored (lower-triangle, column-major) value: its index in the flat block values.
    csc_from_block: Vec<usize>,
    /// Stored values on the diagonal (they get the damping).
    csc_diagonal: Vec<usize>,
    llt: SymbolicCholesky<usize>,
    par: Par,
    // Reused every step.
    block_vals: Vec<f64>,
    csc_vals: Vec<f64>,
    l_vals: Vec<f64>,
    scratch: MemBuffer,
}

fn numeric(msg: String) -> Error {
    Error::Numeric {
        stage: "registration".into(),
        msg,
    }
}

/// What one Gauss–Newton step adds, beside the plan: the per-vertex Jacobian coefficients and every row's
/// residual (computed by the caller in row order, with the energy).
pub(crate) struct Rows<'a> {
    /// Per vertex: start of its influence entries in `coef`.
    pub infl_start: &'a [usize],
    /// Per influence entry: (w·d₀, w·d₁, w·d₂, w), the Jacobian of each coordinate w.r.t. that node's A row
    /// and t component.
    pub coef: &'a [[f64; 4]],
    /// Per vertex with a data pair: the point rows' residuals and (normal, point-to-plane residual).
    pub data: &'a [Option<DataRows>],
    /// Per vertex with a boundary pair: the boundary point rows' residuals.
    pub bound: &'a [Option<[f64; 3]>],
    pub w_point: f64,
    pub w_plane: f64,
    pub w_bound: f64,
    /// Temporal rows (single entries on the diagonal): weight, per unknown (coefficient, residual); empty
    /// when off.
    pub w_temporal: f64,
    pub temporal: &'a [(f64, f64)],
    /// Rigidity rows per node: 6 rows of 6 (local index, coefficient) entries (the last 3 rows use the first
    /// 3 entries) and their residuals.
    pub w_rigid: f64,
    pub rigid: &'a [RigidRows],
    /// Smoothness rows per edge (j, k): A_j's row-c coefficients (the offset to node k) and the residuals of
    /// the 3 rows; entries are (j: 3c+dd ← d[dd], 9+c ← 1), (k: 9+c ← −1).
    pub w_smooth: f64,
    pub edges: &'a [(u32, u32)],
    pub smooth: &'a [SmoothRows],
}

#[derive(Clone, Copy, Debug)]
pub(crate) struct DataRows {
    pub point_r: [f64; 3],
    pub normal: [f64; 3],
    pub plane_r: f64,
}

#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct RigidRows {
    /// 3 orthogonality rows of 6 entries, then 3 unit-length rows of 3 entries.
    pub entries: [[(usize, f64); 6]; 6],
    pub len: [usize; 6],
    pub r: [f64; 6],
}

#[derive(Clone, Copy, Debug)]
pub(crate) struct SmoothRows {
    pub d: [f64; 3],
    pub r: [f64; 3],
}

impl Plan {
    /// `influence[v]`: the (node, weight) pairs of vertex v; `edges`: the smoothness graph, both directions.
    pub(crate) fn new(
        n_nodes: usize,
        influence: &[Vec<(u32, f64)>],
        edges: &[(u32, u32)],
    ) -> Result<Self> {
        let mut blocks: Vec<(u32, u32)> = (0..n_nodes as u32).map(|j| (j, j)).collect();
        blocks.extend(edges.iter().copied().filter(|(a, b)| a > b));
        blocks.sort_unstable();
        blocks.dedup();
        let index: HashMap<(u32, u32), usize> =
            blocks.iter().enumerate().map(|(i, b)| (*b, i)).collect();
        let block_of = |a: u32, b: u32| -> Result<usize> {
            index
                .get(&(a.max(b), a.min(b)))
                .copied()
                .ok_or_else(|| numeric(format!("node pair ({a}, {b}) outside the block pattern")))
        };
        let mut block_vertices = vec![Vec::new(); blocks.len()];
        let mut node_vertices = vec![Vec::new(); n_nodes];
        for (v, inf) in influence.iter().enumerate() {
            for (pj, &(j, _)) in inf.iter().enumerate() {
                node_vertices[j as usize].push((v as u32, pj as u32));
                for (pk, &(k, _)) in inf.iter().enumerate() {
                    if j >= k && (j != k || pj == pk) {
                        block_vertices[block_of(j, k)?].push((v as u32, pj as u32, pk as u32));
                    }
                }
            }
        }
        let mut block_edges = vec![Vec::new(); blocks.len()];
        let mut node_edges = vec![Vec::new(); n_nodes];
        for (e, &(j, k)) in edges.iter().enumerate() {
            let e = e as u32;
            node_edges[j as usize].push(e);
            node_edges[k as usize].push(e);
            block_edges[block_of(j, j)?].push(e);
            block_edges[block_of(k, k)?].push(e);
            block_edges[block_of(j, k)?].push(e);
        }
        // Stored entries: the lower triangle, block by block; their order in the column-major matrix comes from
        // building it once with each entry's own flat index as its value (exact in f64).
        let mut idx = Vec::new();
        let mut flat = Vec::new();
        for (bi, &(rb, cb)) in blocks.iter().enumerate() {
            for a in 0..NV {
                for b in 0..NV {
                    let (i, j) = (rb as usize * NV + a, cb as usize * NV + b);
                    if i >= j {
                        idx.push(faer::sparse::Pair { row: i, col: j });
                        flat.push(bi * BLOCK + a * NV + b);
                    }
                }
            }
        }
        let n = n_nodes * NV;
        let (symbolic, argsort) = SymbolicSparseColMat::try_new_from_indices(n, n, &idx)
            .map_err(|e| numeric(format!("{e:?}")))?;
        let as_values: Vec<f64> = flat.iter().map(|&f| f as f64).collect();
        let order =
            SparseColMat::<usize, f64>::new_from_argsort(symbolic.clone(), &argsort, &as_values)
                .map_err(|e| numeric(format!("{e:?}")))?;
        let csc_from_block: Vec<usize> = order.val().iter().map(|&f| f as usize).collect();
        let mut csc_diagonal = Vec::with_capacity(n);
        for col in 0..n {
            for p in symbolic.col_range(col) {
                if symbolic.row_idx()[p] == col {
                    csc_diagonal.push(p);
                }
            }
        }
        let llt = cholesky::factorize_symbolic_cholesky(
            symbolic.as_ref(),
            Side::Lower,
            Default::default(),
            Default::default(),
        )
        .map_err(|e| numeric(format!("Cholesky analysis: {e:?}")))?;
        let par = faer::get_global_parallelism();
        let scratch = MemBuffer::try_new(
            llt.factorize_numeric_llt_scratch::<f64>(par, Default::default())
                .or(llt.solve_in_place_scratch::<f64>(1, par)),
        )
        .map_err(|e| numeric(format!("Cholesky scratch: {e:?}")))?;
        Ok(Plan {
            n,
            block_vals: vec![0.0; blocks.len() * BLOCK],
            csc_vals: vec![0.0; csc_from_block.len()],
            l_vals: vec![0.0; llt.len_val()],
            blocks,
            block_vertices,
            block_edges,
            node_vertices,
            node_edges,
            symbolic,
            csc_from_block,
            csc_diagonal,
            llt,
            par,
            scratch,
        })
    }

    /// Assembles JᵀWJ (+ `damping` · (1 + |diagonal|) on its diagonal) and JᵀW r from `rows` and solves.
    pub(crate) fn solve(&mut self, rows: &Rows<'_>, damping: f64) -> Result<Vec<f64>> {
        let blocks = &self.blocks;
        let (bv, be) = (&self.block_vertices, &self.block_edges);
        self.block_vals
            .par_chunks_mut(BLOCK)
            .enumerate()
            .for_each(|(b, acc)| {
                let (rb, cb) = blocks[b];
                fill_block(acc, rb, cb, &bv[b], &be[b], rows);
            });
        let mut rhs = vec![[0.0; NV]; self.n / NV];
        let (nv, ne) = (&self.node_vertices, &self.node_edges);
        rhs.par_iter_mut()
            .enumerate()
            .for_each(|(j, acc)| fill_rhs(acc, j as u32, &nv[j], &ne[j], rows));
        let block_vals = &self.block_vals;
        self.csc_vals
            .par_iter_mut()
            .zip(&self.csc_from_block)
            .for_each(|(v, &f)| *v = block_vals[f]);
        for &p in &self.csc_diagonal {
            let v = &mut self.csc_vals[p];
            *v += damping * (1.0 + v.abs());
        }
        let mat = SparseColMatRef::new(self.symbolic.as_ref(), &self.csc_vals);
        self.l_vals.fill(0.0);
        let stack = MemStack::new(&mut self.scratch);
        let llt = self
            .llt
            .factorize_numeric_llt::<f64>(
                &mut self.l_vals,
                mat,
                Side::Lower,
                Default::default(),
                self.par,
                stack,
                Default::default(),
            )
            .map_err(|e| numeric(format!("Cholesky: {e:?}")))?;
        let mut sol = Mat::<f64>::from_fn(self.n, 1, |i, _| rhs[i / NV][i % NV]);
        let stack = MemStack::new(&mut self.scratch);
        llt.solve_in_place_with_conj(Conj::No, sol.as_mut(), self.par, stack);
        Ok((0..self.n).map(|i| sol[(i, 0)]).collect())
    }
}

/// One lower block (row node `rb`, column node `cb`), its rows' contributions in row order.
fn fill_block(
    acc: &mut [f64],
    rb: u32,
    cb: u32,
    vertices: &[(u32, u32, u32)],
    edges: &[u32],
    rows: &Rows<'_>,
) {
    acc.fill(0.0);
    let diag = rb == cb;
    if diag && !rows.temporal.is_empty() {
        let base = rb as usize * NV;
        for l in 0..NV {
            let a = rows.temporal[base + l].0;
            acc[l * NV + l] += rows.w_temporal * a * a;
        }
    }
    let coef = |v: u32, p: u32| rows.coef[rows.infl_start[v as usize] + p as usize];
    for &(v, pj, pk) in vertices {
        let Some(d) = rows.data[v as usize] else {
            continue;
        };
        let (cj, ck) = (coef(v, pj), coef(v, pk));
        if rows.w_point > 0.0 {
            for c in 0..3 {
                for (q, a) in cj.iter().enumerate() {
                    let wa = rows.w_point * a;
                    let row = loc(c, q) * NV;
                    for (q2, b) in ck.iter().enumerate() {
                        acc[row + loc(c, q2)] += wa * b;
                    }
                }
            }
        }
        if rows.w_plane > 0.0 {
            let n = d.normal;
            for c in 0..3 {
                for (q, a) in cj.iter().enumerate() {
                    let wa = rows.w_plane * (a * n[c]);
                    let row = loc(c, q) * NV;
                    for (c2, nc2) in n.iter().enumerate() {
                        for (q2, b) in ck.iter().enumerate() {
                            acc[row + loc(c2, q2)] += wa * (b * nc2);
                        }
                    }
                }
            }
        }
    }
    for &(v, pj, pk) in vertices {
        if rows.bound[v as usize].is_none() {
            continue;
        }
        let (cj, ck) = (coef(v, pj), coef(v, pk));
        for c in 0..3 {
            for (q, a) in cj.iter().enumerate() {
                let wa = rows.w_bound * a;
                let row = loc(c, q) * NV;
                for (q2, b) in ck.iter().enumerate() {
                    acc[row + loc(c, q2)] += wa * b;
                }
            }
        }
    }
    if diag {
        let rg = &rows.rigid[rb as usize];
        for (entries, &len) in rg.entries.iter().zip(&rg.len) {
            for &(i, a) in &entries[..len] {
                let wa = rows.w_rigid * a;
                for &(j, b) in &entries[..len] {
                    acc[i * NV + j] += wa * b;
                }
            }
        }
    }
    for &e in edges {
        let (j, k) = rows.edges[e as usize];
        let d = rows.smooth[e as usize].d;
        for c in 0..3 {
            // The row's entries on node `node`: (local index, coefficient).
            let part = |node: u32| -> ([(usize, f64); 4], usize) {
                let mut out = [(0, 0.0); 4];
                let mut len = 0;
                if node == j {
                    for (dd, dv) in d.iter().enumerate() {
                        out[len] = (3 * c + dd, *dv);
                        len += 1;
                    }
                    out[len] = (9 + c, 1.0);
                    len += 1;
                }
                if node == k {
                    out[len] = (9 + c, -1.0);
                    len += 1;
                }
                (out, len)
            };
            let ((ra, rl), (ca, cl)) = (part(rb), part(cb));
            for &(i, a) in &ra[..rl] {
                let wa = rows.w_smooth * a;
                for &(jj, b) in &ca[..cl] {
                    acc[i * NV + jj] += wa * b;
                }
            }
        }
    }
}

/// Node `j`'s 12 entries of JᵀW r, its rows' contributions in row order.
fn fill_rhs(acc: &mut [f64; NV], j: u32, vertices: &[(u32, u32)], edges: &[u32], rows: &Rows<'_>) {
    let base = j as usize * NV;
    if !rows.temporal.is_empty() {
        for (l, a) in acc.iter_mut().enumerate() {
            let (c, r) = rows.temporal[base + l];
            *a += rows.w_temporal * c * r;
        }
    }
    let coef = |v: u32, p: u32| rows.coef[rows.infl_start[v as usize] + p as usize];
    for &(v, p) in vertices {
        let Some(d) = rows.data[v as usize] else {
            continue;
        };
        let cj = coef(v, p);
        if rows.w_point > 0.0 {
            for c in 0..3 {
                for q in 0..4 {
                    acc[loc(c, q)] += rows.w_point * cj[q] * d.point_r[c];
                }
            }
        }
        if rows.w_plane > 0.0 {
            for c in 0..3 {
                for q in 0..4 {
                    acc[loc(c, q)] += rows.w_plane * (cj[q] * d.normal[c]) * d.plane_r;
                }
            }
        }
    }
    for &(v, p) in vertices {
        let Some(r) = rows.bound[v as usize] else {
            continue;
        };
        let cj = coef(v, p);
        for c in 0..3 {
            for q in 0..4 {
                acc[loc(c, q)] += rows.w_bound * cj[q] * r[c];
            }
        }
    }
    let rg = &rows.rigid[j as usize];
    for ((entries, &len), &r) in rg.entries.iter().zip(&rg.len).zip(&rg.r) {
        for &(i, a) in &entries[..len] {
            acc[i] += rows.w_rigid * a * r;
        }
    }
    for &e in edges {
        let (ej, ek) = rows.edges[e as usize];
        let s = rows.smooth[e as usize];
        for c in 0..3 {
            let r = s.r[c];
            if j == ej {
                for dd in 0..3 {
                    acc[3 * c + dd] += rows.w_smooth * s.d[dd] * r;
                }
                acc[9 + c] += rows.w_smooth * 1.0 * r;
            }
            if j == ek {
                acc[9 + c] += -rows.w_smooth * r;
            }
        }
    }
}

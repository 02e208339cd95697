//! The space-time weight matrix M of one window, applied matrix-free.
//!
//! Unknowns are the weights of every (frame, triangle) node of the window, ordered frame-major
//! (node = local_frame · n_triangles + triangle). From Popa et al. 2009 §5.3:
//!
//! ```text
//!   M = c_s L_space + c_t L_time + c_i D_free + c_a D_anchor
//! ```
//!
//! with L_space the graph Laplacian of the triangle dual graph (uniform weights) replicated per frame, L_time
//! the path-graph Laplacian over the window's frames per triangle, and the diagonal mitigation (c_i) or anchor
//! (c_a) term. The connectivity is the mesh's own adjacency, so the operator stores only its diagonal: about
//! six non-zeros per row are recomputed on the fly from `tri_adj`, which is cheaper than streaming a CSR matrix.

use crate::mesh::{Topology, NONE};

/// Coefficients of the weight functional.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Coefficients {
    pub c_s: f64,
    pub c_t: f64,
    pub c_i: f64,
    pub c_a: f64,
}

impl Default for Coefficients {
    fn default() -> Self {
        Coefficients {
            c_s: 0.9,
            c_t: 0.5,
            c_i: 0.1,
            c_a: 10.0,
        }
    }
}

/// Matrix-free M for one window.
pub struct SpaceTimeOperator<'a> {
    pub tri_adj: &'a [[u32; 3]],
    pub n_tri: usize,
    pub n_frames: usize,
    pub coeffs: Coefficients,
    diag: Vec<f64>,
}

impl<'a> SpaceTimeOperator<'a> {
    /// `anchored_nodes` lists the window nodes that carry an anchor (any order).
    pub fn new(
        topo: &'a Topology,
        n_frames: usize,
        coeffs: Coefficients,
        anchored_nodes: &[u32],
    ) -> Self {
        let n_tri = topo.n_triangles();
        let tri_adj = topo.tri_adj();
        let mut diag = Vec::with_capacity(n_tri * n_frames);
        for lt in 0..n_frames {
            let time_deg = (lt > 0) as usize + (lt + 1 < n_frames) as usize;
            for adj in tri_adj {
                let space_deg = adj.iter().filter(|&&j| j != NONE).count();
                diag.push(
                    coeffs.c_s * space_deg as f64 + coeffs.c_t * time_deg as f64 + coeffs.c_i,
                );
            }
        }
        for &n in anchored_nodes {
            diag[n as usize] += coeffs.c_a - coeffs.c_i;
        }
        SpaceTimeOperator {
            tri_adj,
            n_tri,
            n_frames,
            coeffs,
            diag,
        }
    }

    pub fn n_nodes(&self) -> usize {
        self.diag.len()
    }

    pub fn diag(&self) -> &[f64] {
        &self.diag
    }

    /// Calls `f(neighbour_node, coupling)` for every off-diagonal entry of row `node`; the matrix entry is
    /// `-coupling`.
    #[inline(always)]
    pub fn for_each_neighbor(&self, node: usize, mut f: impl FnMut(usize, f64)) {
        let lt = node / self.n_tri;
        let i = node - lt * self.n_tri;
        let base = lt * self.n_tri;
        for &j in &self.tri_adj[i] {
            if j != NONE {
                f(base + j as usize, self.coeffs.c_s);
            }
        }
        if lt > 0 {
            f(node - self.n_tri, self.coeffs.c_t);
        }
        if lt + 1 < self.n_frames {
            f(node + self.n_tri, self.coeffs.c_t);
        }
    }

    /// The five neighbour slots of row `node`: slots 0–2 are the triangles across edges 0–2 in the same frame,
    /// slot 3 the same triangle one frame earlier, slot 4 one frame later; `usize::MAX` where there is none.
    /// Slots 0–2 couple with `c_s`, slots 3–4 with `c_t`.
    #[inline]
    pub fn neighbor_slots(&self, node: usize) -> [usize; 5] {
        let lt = node / self.n_tri;
        let i = node - lt * self.n_tri;
        let base = lt * self.n_tri;
        let adj = self.tri_adj[i];
        let sp = |j: u32| {
            if j == NONE {
                usize::MAX
            } else {
                base + j as usize
            }
        };
        [
            sp(adj[0]),
            sp(adj[1]),
            sp(adj[2]),
            if lt > 0 {
                node - self.n_tri
            } else {
                usize::MAX
            },
            if lt + 1 < self.n_frames {
                node + self.n_tri
            } else {
                usize::MAX
            },
        ]
    }

    /// The slot of `node` in the neighbour list of its neighbour in slot `slot` (the link seen from the other
    /// side).
    #[inline]
    pub fn reverse_slot(&self, node: usize, slot: usize, neighbor: usize) -> usize {
        match slot {
            3 => 4,
            4 => 3,
            _ => {
                let i = (node % self.n_tri) as u32;
                let j = neighbor % self.n_tri;
                self.tri_adj[j].iter().position(|&k| k == i).unwrap_or(0)
            }
        }
    }

    /// y = M p for three right-hand sides stored row-wise, parallel over node chunks (each output row is
    /// written by exactly one task, so the result does not depend on the thread count).
    pub fn apply3(&self, p: &[[f64; 3]], y: &mut [[f64; 3]]) {
        use rayon::prelude::*;
        y.par_chunks_mut(CHUNK).enumerate().for_each(|(c, ys)| {
            let base = c * CHUNK;
            for (k, yk) in ys.iter_mut().enumerate() {
                let n = base + k;
                let d = self.diag[n];
                let pn = p[n];
                let mut s = [d * pn[0], d * pn[1], d * pn[2]];
                self.for_each_neighbor(n, |m, w| {
                    let pm = p[m];
                    s[0] -= w * pm[0];
                    s[1] -= w * pm[1];
                    s[2] -= w * pm[2];
                });
                *yk = s;
            }
        });
    }

    /// Writes the operator as a symmetric CSR matrix (full, both triangles) for comparison with reference
    /// solvers: returns (row_ptr, col_idx, values).
    pub fn to_csr(&self) -> (Vec<u64>, Vec<u32>, Vec<f64>) {
        let mut row_ptr = Vec::with_capacity(self.n_nodes() + 1);
        let mut cols = Vec::new();
        let mut vals = Vec::new();
        row_ptr.push(0u64);
        for n in 0..self.n_nodes() {
            let mut row: Vec<(u32, f64)> = vec![(n as u32, self.diag[n])];
            self.for_each_neighbor(n, |m, w| row.push((m as u32, -w)));
            row.sort_by_key(|e| e.0);
            for (c, v) in row {
                cols.push(c);
                vals.push(v);
            }
            row_ptr.push(cols.len() as u64);
        }
        (row_ptr, cols, vals)
    }
}

/// Rows per parallel task; fixed so that reductions are summed in the same order on any machine.
pub const CHUNK: usize = 8192;

//! `per-anchor` mode: the paper's formulation, one weight column per anchor (Popa et al. 2009 §5.3), split
//! into anchor-column blocks that each return their partial blend Σ_{a∈block} w_a φ_a. Blocks are the unit the
//! cluster distributes; their partial sums add up to the full blend.
//!
//! Locality: a column's right-hand side c_a e_a is a single node, and Jacobi-preconditioned CG started from
//! zero keeps its k-th iterate inside the k-ring of that node in the space-time graph (M has a one-ring
//! stencil). [`LocalCg`] therefore runs CG on an active set that grows by one ring per iteration. Its iterates
//! are *exactly* those of CG on the whole window (every entry outside the active set is exactly zero, so
//! inner products and matrix products agree), but each column costs a few thousand node updates instead of a
//! pass over the million nodes of the window.

use super::fused::CgStats;
use super::operator::SpaceTimeOperator;
use crate::error::{Error, Result};
use crate::mesh::NONE;
use crate::vec3::V3;
use std::ops::Range;

/// One anchor of a window: its node (local_frame · n_tri + triangle) and rotation vector.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WindowAnchor {
    pub node: u32,
    pub phi: V3,
}

/// Partial blend of one anchor block: Σ_{a∈block} w_a φ_a on the nodes the block reaches, in the order the
/// block first reached them (deterministic: it depends only on the block's anchors).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PartialBlend {
    pub nodes: Vec<u32>,
    pub values: Vec<V3>,
    /// Sum of CG iterations over the block's columns and the worst relative residual.
    pub iterations: usize,
    pub max_relative_residual: f64,
    /// Total number of node updates (Σ over iterations of the active-set size): the work the block did.
    pub node_updates: u64,
}

/// Splits `n_anchors` anchor columns into as few consecutive blocks of at most `block_size` as possible, sized
/// from the window's anchor count so that they differ by at most one column: each block is a task with a fixed
/// cost, and a ragged last block (a few columns) would pay that cost for little work and finish early.
pub fn plan_blocks(n_anchors: usize, block_size: usize) -> Vec<Range<usize>> {
    let n_blocks = n_anchors.div_ceil(block_size.max(1));
    (0..n_blocks)
        .map(|b| b * n_anchors / n_blocks..(b + 1) * n_anchors / n_blocks)
        .collect()
}

/// Conjugate gradient for one column with a growing active set (see module docs). Reusable across columns:
/// only the touched entries of the global-to-local map are reset.
///
/// The active nodes keep their own adjacency in local indices (`links`), filled in as nodes join, so an
/// iteration touches only the compact local arrays. Local index 0 is a sentinel whose value is always zero; it
/// stands for "no neighbour or not yet active", which keeps the inner loop free of branches.
pub struct LocalCg {
    local_of: Vec<u32>,
    nodes: Vec<u32>,
    links: Vec<[u32; 5]>,
    diag: Vec<f64>,
    x: Vec<f64>,
    r: Vec<f64>,
    p: Vec<f64>,
    q: Vec<f64>,
}

impl LocalCg {
    pub fn new(n_nodes: usize) -> Self {
        let mut cg = LocalCg {
            local_of: vec![NONE; n_nodes],
            nodes: Vec::new(),
            links: Vec::new(),
            diag: Vec::new(),
            x: Vec::new(),
            r: Vec::new(),
            p: Vec::new(),
            q: Vec::new(),
        };
        cg.clear();
        cg
    }

    /// The last solved column: (window node, weight) for every node of its support.
    pub fn column(&self) -> impl Iterator<Item = (u32, f64)> + '_ {
        self.nodes[1..]
            .iter()
            .copied()
            .zip(self.x[1..].iter().copied())
    }

    fn clear(&mut self) {
        for &g in self.nodes.iter().skip(1) {
            self.local_of[g as usize] = NONE;
        }
        for v in [
            &mut self.diag,
            &mut self.x,
            &mut self.r,
            &mut self.p,
            &mut self.q,
        ] {
            v.clear();
            v.push(0.0);
        }
        self.nodes.clear();
        self.nodes.push(NONE);
        self.links.clear();
        self.links.push([0; 5]);
    }

    fn push(&mut self, op: &SpaceTimeOperator, g: usize) {
        let l = self.nodes.len() as u32;
        self.local_of[g] = l;
        self.nodes.push(g as u32);
        self.diag.push(op.diag()[g]);
        self.x.push(0.0);
        self.r.push(0.0);
        self.p.push(0.0);
        self.q.push(0.0);
        let mut own = [0u32; 5];
        for (slot, &m) in op.neighbor_slots(g).iter().enumerate() {
            if m == usize::MAX {
                continue;
            }
            let lm = self.local_of[m];
            if lm != NONE {
                own[slot] = lm;
                self.links[lm as usize][op.reverse_slot(g, slot, m)] = l;
            }
        }
        self.links.push(own);
    }

    /// Solves M w = rhs · e_node to relative residual `tol`; afterwards [`LocalCg::column`] yields the column's
    /// support and values. Returns (iterations, relative residual, node updates).
    pub fn solve(
        &mut self,
        op: &SpaceTimeOperator,
        node: u32,
        rhs: f64,
        tol: f64,
        max_iter: usize,
    ) -> Result<(usize, f64, u64)> {
        self.clear();
        self.push(op, node as usize);
        self.r[1] = rhs;
        self.p[1] = rhs / self.diag[1];
        let mut rz = rhs * self.p[1];
        let bnorm = rhs.abs();
        let (c_s, c_t) = (op.coeffs.c_s, op.coeffs.c_t);
        let mut frontier = 1..2usize;
        let mut updates = 0u64;
        for it in 1..=max_iter {
            // Grow the active set by the ring that M p can reach.
            let before = self.nodes.len();
            for l in frontier.clone() {
                let g = self.nodes[l] as usize;
                for m in op.neighbor_slots(g) {
                    if m != usize::MAX && self.local_of[m] == NONE {
                        self.push(op, m);
                    }
                }
            }
            frontier = before..self.nodes.len();
            let n = self.nodes.len();
            updates += (n - 1) as u64;
            // q = M p on the active set.
            let mut pq = 0.0;
            for l in 1..n {
                let k = self.links[l];
                let p = &self.p;
                let s = self.diag[l] * p[l]
                    - c_s * (p[k[0] as usize] + p[k[1] as usize] + p[k[2] as usize])
                    - c_t * (p[k[3] as usize] + p[k[4] as usize]);
                self.q[l] = s;
                pq += p[l] * s;
            }
            let alpha = rz / pq;
            if !alpha.is_finite() {
                return Err(Error::numeric(
                    "weights (per-anchor CG)",
                    "breakdown: non-finite step",
                ));
            }
            let mut rr = 0.0;
            for l in 1..n {
                self.x[l] += alpha * self.p[l];
                self.r[l] -= alpha * self.q[l];
                rr += self.r[l] * self.r[l];
            }
            let rel = rr.sqrt() / bnorm;
            if rel <= tol {
                return Ok((it, rel, updates));
            }
            let mut rz_new = 0.0;
            for l in 1..n {
                rz_new += self.r[l] * self.r[l] / self.diag[l];
            }
            let beta = rz_new / rz;
            rz = rz_new;
            for l in 1..n {
                self.p[l] = self.r[l] / self.diag[l] + beta * self.p[l];
            }
        }
        Err(Error::numeric(
            "weights (per-anchor CG)",
            format!(
                "anchor node {node}: no convergence to {tol:e} in {max_iter} iterations; raise the tuning key deform.cg_max_iterations or deform.cg_tolerance"
            ),
        ))
    }
}

/// Scratch for one block: a dense accumulator over the window's nodes plus the list of touched nodes.
pub struct BlockWorkspace {
    cg: LocalCg,
    acc: Vec<V3>,
    touched: Vec<u32>,
    is_touched: Vec<bool>,
}

impl BlockWorkspace {
    pub fn new(n_nodes: usize) -> Self {
        BlockWorkspace {
            cg: LocalCg::new(n_nodes),
            acc: vec![[0.0; 3]; n_nodes],
            touched: Vec::new(),
            is_touched: vec![false; n_nodes],
        }
    }
}

/// Solves the anchor columns `anchors` (one block) and returns their partial blend. Columns are accumulated in
/// the given order, so the result is bit-identical wherever the block runs.
pub fn solve_block(
    op: &SpaceTimeOperator,
    anchors: &[WindowAnchor],
    tol: f64,
    max_iter: usize,
    ws: &mut BlockWorkspace,
) -> Result<PartialBlend> {
    let c_a = op.coeffs.c_a;
    let mut out = PartialBlend::default();
    for a in anchors {
        let (it, rel, upd) = ws.cg.solve(op, a.node, c_a, tol, max_iter)?;
        out.iterations += it;
        out.max_relative_residual = out.max_relative_residual.max(rel);
        out.node_updates += upd;
        for (g, w) in ws.cg.column() {
            let gi = g as usize;
            if !ws.is_touched[gi] {
                ws.is_touched[gi] = true;
                ws.touched.push(g);
            }
            let acc = &mut ws.acc[gi];
            acc[0] += w * a.phi[0];
            acc[1] += w * a.phi[1];
            acc[2] += w * a.phi[2];
        }
    }
    out.nodes = std::mem::take(&mut ws.touched);
    out.values = out
        .nodes
        .iter()
        .map(|&g| {
            let gi = g as usize;
            ws.is_touched[gi] = false;
            std::mem::replace(&mut ws.acc[gi], [0.0; 3])
        })
        .collect();
    Ok(out)
}

/// Adds partial blends into a dense window field, in the order given (callers pass blocks in block order so the
/// sum is deterministic).
pub fn accumulate(field: &mut [V3], partial: &PartialBlend) {
    for (&g, v) in partial.nodes.iter().zip(&partial.values) {
        let f = &mut field[g as usize];
        f[0] += v[0];
        f[1] += v[1];
        f[2] += v[2];
    }
}

/// Stats of a whole per-anchor window solve.
pub fn merge_stats(stats: &mut CgStats, p: &PartialBlend) {
    stats.iterations += p.iterations;
    stats.relative_residual = stats.relative_residual.max(p.max_relative_residual);
}

#[cfg(test)]
mod tests {
    use super::plan_blocks;

    #[test]
    fn blocks_cover_the_anchors_in_order_with_even_sizes() {
        for n in 0..120 {
            for bs in 1..30 {
                let blocks = plan_blocks(n, bs);
                assert_eq!(blocks.len(), n.div_ceil(bs), "n {n} bs {bs}: block count");
                let mut next = 0;
                for b in &blocks {
                    assert_eq!(b.start, next, "n {n} bs {bs}: contiguous");
                    assert!(!b.is_empty() && b.len() <= bs, "n {n} bs {bs}: size {b:?}");
                    next = b.end;
                }
                assert_eq!(next, n, "n {n} bs {bs}: every anchor");
                let (lo, hi) = blocks.iter().fold((usize::MAX, 0), |(lo, hi), b| {
                    (lo.min(b.len()), hi.max(b.len()))
                });
                assert!(
                    blocks.is_empty() || hi - lo <= 1,
                    "n {n} bs {bs}: sizes {lo}..{hi}"
                );
            }
        }
    }
}

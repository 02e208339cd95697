//! The weight solve of one time window in either mode, returning the window's blended rotation-vector field
//! X = Σ_a w_a φ_a (one 3-vector per node): whole ([`solve_window`], the single-machine driver), or as the
//! stages a cluster task runs — fused: [`fused_window_field`]; per-anchor: [`anchor_block`] for each block of
//! [`anchor_blocks`], summed in block order by [`reduce_blocks`]. Both paths run the same functions, so a
//! window's field has the same bits wherever it was solved.

use super::fused::CgStats;
use super::lean_cg;
use super::operator::{Coefficients, SpaceTimeOperator};
use super::per_anchor::{self, BlockWorkspace, PartialBlend, WindowAnchor};
use crate::error::{Error, Result};
use crate::spacetime::params::{DeformParams, WeightMode};
use crate::spacetime::windows::Window;
use crate::folds::AnchorSet;
use crate::mesh::Topology;
use crate::progress::Progress;
use crate::vec3::V3;
use rayon::prelude::*;
use std::ops::Range;

/// The linear system of one window: operator and anchors (sorted by node).
pub struct WindowProblem<'a> {
    pub window: Window,
    pub op: SpaceTimeOperator<'a>,
    pub anchors: Vec<WindowAnchor>,
}

impl<'a> WindowProblem<'a> {
    pub fn new(
        topo: &'a Topology,
        anchors: &AnchorSet,
        window: Window,
        coeffs: Coefficients,
    ) -> Self {
        let n_tri = topo.n_triangles();
        let mut list = Vec::new();
        for lt in 0..window.len {
            for a in anchors.frame(window.start + lt) {
                list.push(WindowAnchor {
                    node: (lt * n_tri + a.triangle as usize) as u32,
                    phi: a.rotation_vector(),
                });
            }
        }
        let nodes: Vec<u32> = list.iter().map(|a| a.node).collect();
        let op = SpaceTimeOperator::new(topo, window.len, coeffs, &nodes);
        WindowProblem {
            window,
            op,
            anchors: list,
        }
    }

    /// Right-hand side c_a E Φ of the fused solve.
    pub fn fused_rhs(&self) -> Vec<V3> {
        let mut b = vec![[0.0; 3]; self.op.n_nodes()];
        let c_a = self.op.coeffs.c_a;
        for a in &self.anchors {
            b[a.node as usize] = [c_a * a.phi[0], c_a * a.phi[1], c_a * a.phi[2]];
        }
        b
    }
}

/// What one window's solve did.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct WindowStats {
    pub start: usize,
    pub len: usize,
    pub anchors: usize,
    pub blocks: usize,
    /// Fused: CG iterations of the 3-RHS solve; per-anchor: summed over all columns.
    pub cg_iterations: usize,
    pub max_relative_residual: f64,
    /// Per-anchor mode: total node updates over all columns (work measure).
    pub node_updates: u64,
    pub seconds: f64,
}

/// Solves one window in the configured mode.
pub fn solve_window(
    problem: &WindowProblem,
    params: &DeformParams,
    progress: &dyn Progress,
) -> Result<(Vec<V3>, WindowStats)> {
    let t0 = std::time::Instant::now();
    let mut stats = WindowStats {
        start: problem.window.start,
        len: problem.window.len,
        anchors: problem.anchors.len(),
        ..Default::default()
    };
    let field = match params.mode {
        WeightMode::Fused => {
            let (x, cg) = fused_window_field(problem, params)?;
            stats.cg_iterations = cg.iterations;
            stats.max_relative_residual = cg.relative_residual;
            x
        }
        WeightMode::PerAnchor => {
            let blocks = anchor_blocks(problem, params);
            stats.blocks = blocks.len();
            let mut field = vec![[0.0; 3]; problem.op.n_nodes()];
            let mut cg = CgStats::default();
            // Blocks run in parallel in batches and are summed in block order: deterministic, bounded memory.
            // One workspace per pool thread, allocated once per window (each holds window-sized scratch).
            let threads = rayon::current_num_threads().max(1);
            let pool: Vec<std::sync::Mutex<BlockWorkspace>> = (0..threads)
                .map(|_| std::sync::Mutex::new(BlockWorkspace::new(problem.op.n_nodes())))
                .collect();
            let batch = 2 * threads;
            for chunk in blocks.chunks(batch) {
                if progress.cancelled() {
                    return Err(Error::Cancelled);
                }
                let partials: Vec<Result<PartialBlend>> = chunk
                    .par_iter()
                    .map(|range| {
                        let slot = rayon::current_thread_index().unwrap_or(0) % threads;
                        let mut ws = pool[slot].lock().map_err(|_| {
                            Error::numeric("weights (per-anchor)", "a worker thread panicked")
                        })?;
                        anchor_block(problem, range.clone(), params, &mut ws)
                    })
                    .collect();
                for p in partials {
                    reduce_into(&mut field, &mut cg, &mut stats.node_updates, &p?);
                }
            }
            stats.cg_iterations = cg.iterations;
            stats.max_relative_residual = cg.relative_residual;
            field
        }
    };
    stats.seconds = t0.elapsed().as_secs_f64();
    Ok((field, stats))
}

/// Fused mode: the window's blended rotation-vector field X (one 3-vector per node, frame-major) from the
/// 3-right-hand-side solve M X = c_a E Φ (the bandwidth-lean kernel, [`lean_cg`]).
pub fn fused_window_field(
    problem: &WindowProblem,
    params: &DeformParams,
) -> Result<(Vec<V3>, CgStats)> {
    let b = problem.fused_rhs();
    lean_cg::solve3_lean(
        &problem.op,
        &b,
        params.cg_tolerance,
        params.cg_max_iterations,
    )
}

/// Per-anchor mode: the anchor-column ranges of a window's blocks (`params.anchor_block` columns each, in
/// anchor order).
pub fn anchor_blocks(problem: &WindowProblem, params: &DeformParams) -> Vec<Range<usize>> {
    per_anchor::plan_blocks(problem.anchors.len(), params.anchor_block)
}

/// Per-anchor mode: solves the anchor columns `range` of the window (one CG column each) and returns their
/// partial blend Σ_{a∈range} w_a φ_a — the unit of work a cluster worker runs.
pub fn anchor_block(
    problem: &WindowProblem,
    range: Range<usize>,
    params: &DeformParams,
    ws: &mut BlockWorkspace,
) -> Result<PartialBlend> {
    let anchors = problem.anchors.get(range.clone()).ok_or_else(|| {
        Error::param(
            "anchor block",
            format!(
                "columns {range:?} are outside the window's {} anchors",
                problem.anchors.len()
            ),
        )
    })?;
    per_anchor::solve_block(
        &problem.op,
        anchors,
        params.cg_tolerance,
        params.cg_max_iterations,
        ws,
    )
}

/// Per-anchor mode: the window field as the sum of its blocks' partial blends, added in the order given (pass
/// them in block order), starting from zero. Also returns the merged CG statistics.
pub fn reduce_blocks<'a>(
    n_nodes: usize,
    partials: impl IntoIterator<Item = &'a PartialBlend>,
) -> Result<(Vec<V3>, CgStats, u64)> {
    let mut field = vec![[0.0; 3]; n_nodes];
    let mut cg = CgStats::default();
    let mut updates = 0u64;
    for p in partials {
        if let Some(&bad) = p.nodes.iter().find(|&&g| g as usize >= n_nodes) {
            return Err(Error::param(
                "partial blend",
                format!("node {bad} is outside the window's {n_nodes} nodes"),
            ));
        }
        reduce_into(&mut field, &mut cg, &mut updates, p);
    }
    Ok((field, cg, updates))
}

/// Adds one partial blend (the next in block order) into a window field and its statistics.
pub fn reduce_into(field: &mut [V3], cg: &mut CgStats, updates: &mut u64, p: &PartialBlend) {
    per_anchor::accumulate(field, p);
    per_anchor::merge_stats(cg, p);
    *updates += p.node_updates;
}

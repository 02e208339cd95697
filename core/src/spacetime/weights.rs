//! The weight solve of one time window in either mode, returning the window's blended rotation-vector field
//! X = Σ_a w_a φ_a (one 3-vector per node).

use super::fused::CgStats;
use super::operator::{Coefficients, SpaceTimeOperator};
use super::params::{DeformParams, WeightMode};
use super::per_anchor::{BlockWorkspace, PartialBlend, WindowAnchor};
use super::stages;
use super::windows::Window;
use crate::error::{Error, Result};
use crate::folds::AnchorSet;
use crate::mesh::Topology;
use crate::progress::Progress;
use crate::vec3::V3;
use rayon::prelude::*;

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
            let (x, cg) = stages::fused_window_field(problem, params)?;
            stats.cg_iterations = cg.iterations;
            stats.max_relative_residual = cg.relative_residual;
            x
        }
        WeightMode::PerAnchor => {
            let blocks = stages::anchor_blocks(problem, params);
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
                        stages::anchor_block(problem, range.clone(), params, &mut ws)
                    })
                    .collect();
                for p in partials {
                    stages::reduce_into(&mut field, &mut cg, &mut stats.node_updates, &p?);
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

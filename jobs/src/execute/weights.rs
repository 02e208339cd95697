//! Weight tasks (Popa et al. 2009 §5.3): a fused window, one anchor block of a window, and the reduce that sums
//! a window's blocks. Each window's field is stored frame by frame, so a positioning task reads only the frames
//! it positions.

use super::env::TaskEnv;
use super::exact;
use super::partial_file::{self, BlockStats};
use super::phase_times::Lap;
use super::window_cache::{self, WindowEntry};
use crate::error::TaskError;
use crate::keys;
use crease_core::spacetime::weights::fused::CgStats;
use crease_core::spacetime::weights::per_anchor::plan_blocks;
use crease_core::spacetime::weights;
use crease_core::spacetime::weights::{WindowProblem, WindowStats};
use crease_core::spacetime::windows::Window;
use crease_core::vec3::V3;
use serde::{Deserialize, Serialize};
use serde_json::{json, Value};
use std::time::Instant;

/// [`WindowStats`] with exact floats, as stored next to a window's field.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct WindowRecord {
    pub start: usize,
    pub len: usize,
    pub anchors: usize,
    pub blocks: usize,
    pub cg_iterations: usize,
    #[serde(with = "exact")]
    pub max_relative_residual: f64,
    pub node_updates: u64,
    #[serde(with = "exact")]
    pub seconds: f64,
}

impl From<WindowRecord> for WindowStats {
    fn from(r: WindowRecord) -> Self {
        WindowStats {
            start: r.start,
            len: r.len,
            anchors: r.anchors,
            blocks: r.blocks,
            cg_iterations: r.cg_iterations,
            max_relative_residual: r.max_relative_residual,
            node_updates: r.node_updates,
            seconds: r.seconds,
        }
    }
}

fn label(k: usize, w: &Window) -> String {
    format!("window {k} (frames {}..{})", w.start, w.end())
}

/// Fused mode: the 3-right-hand-side solve of window `k`.
pub fn fused_window(env: &TaskEnv, k: usize) -> Result<(Value, Vec<String>), TaskError> {
    let opened = env.open_input()?;
    let topo = opened.source.topology().clone();
    let n = opened.source.n_frames();
    let anchors = env.anchors(n, topo.n_triangles())?;
    let (_, w) = env.window(n, k)?;
    env.check_cancelled()?;
    let clock = Instant::now();
    let problem = WindowProblem::new(&topo, &anchors, w, env.params.coefficients);
    let (field, cg) = weights::fused_window_field(&problem, &env.params)
        .map_err(|e| TaskError::from_core(&label(k, &w), e))?;
    let record = WindowRecord {
        start: w.start,
        len: w.len,
        anchors: problem.anchors.len(),
        blocks: 0,
        cg_iterations: cg.iterations,
        max_relative_residual: cg.relative_residual,
        node_updates: 0,
        seconds: clock.elapsed().as_secs_f64(),
    };
    drop(problem);
    write_window(env, k, w, topo.n_triangles(), &field, &record)
}

/// Per-anchor mode: block `b` of window `k` → its partial blend. The window's problem and block workspaces
/// come from the worker's [`window_cache`] when an earlier block of the same window left them there.
pub fn anchor_block(env: &TaskEnv, k: usize, b: usize) -> Result<(Value, Vec<String>), TaskError> {
    let mut lap = Lap::start();
    let opened = env.open_input()?;
    let n = opened.source.n_frames();
    let n_tri = opened.source.topology().n_triangles();
    let (_, w) = env.window(n, k)?;
    let spec = serde_json::to_vec(env.job).unwrap_or_default();
    let key = window_cache::fingerprint(&[
        &spec,
        &env.anchors_fingerprint()?.to_le_bytes(),
        &(k as u64).to_le_bytes(),
    ]);
    env.check_cancelled()?;
    lap.lap("weight-block: open input, cache key");
    let clock = Instant::now();
    let (entry, hit) = window_cache::get_or_build(key, &opened, || {
        let anchors = env.anchors(n, n_tri)?;
        WindowEntry::build(opened.clone(), |topo| {
            Ok::<_, TaskError>(WindowProblem::new(
                topo,
                &anchors,
                w,
                env.params.coefficients,
            ))
        })
    })?;
    let problem = entry.problem();
    let blocks = weights::anchor_blocks(problem, &env.params);
    let range = blocks.get(b).cloned().ok_or_else(|| {
        TaskError::fatal(format!(
            "{}: block {b} does not exist ({} anchors make {} blocks of {})",
            label(k, &w),
            problem.anchors.len(),
            blocks.len(),
            env.params.anchor_block
        ))
    })?;
    let mut ws = entry.take_workspace();
    lap.lap("weight-block: window (cache hit, or build)");
    let partial =
        on_compute_pool(|| weights::anchor_block(problem, range.clone(), &env.params, &mut ws))
            .map_err(|e| TaskError::from_core(&format!("{} block {b}", label(k, &w)), e))?;
    entry.give_back(ws);
    let seconds = clock.elapsed().as_secs_f64();
    lap.lap("weight-block: solve");
    let stats = BlockStats {
        columns: range.len(),
        iterations: partial.iterations,
        max_relative_residual: partial.max_relative_residual,
        node_updates: partial.node_updates,
        seconds,
    };
    let bytes = partial_file::encode(&partial, &stats);
    drop(partial);
    lap.lap("weight-block: encode");
    let key = keys::block_partial(k, b);
    env.put(&key, bytes)?;
    lap.lap("weight-block: write");
    // Floats as their shortest round-trip text, as the JSON sidecars write them (see `exact`).
    let summary = json!({
        "columns": stats.columns,
        "iterations": stats.iterations,
        "max_relative_residual": format!("{:?}", stats.max_relative_residual),
        "node_updates": stats.node_updates,
        "seconds": format!("{:?}", stats.seconds),
        "window_cache": if hit { "hit" } else { "miss" },
    });
    Ok((summary, vec![key]))
}

/// Runs `f` on one of the process's compute (rayon) threads, the caller waiting.
///
/// Why: a block's solve is single-threaded, and a task runs on a blocking thread of its own. When several
/// workers share a process (`crease run`'s local cluster, `crease bench --cluster`), a block beside a
/// positioning task (which fills the whole pool) made one more busy compute thread than cores; under `perf`
/// the blocks' solve took ~13 % more CPU samples in the cluster run than the same blocks in
/// `crease_core::spacetime::deform`. In the pool, the process never runs more compute threads than the pool
/// has (`--threads`, default: the cores). The result does not depend on the thread it ran on.
fn on_compute_pool<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    if rayon::current_thread_index().is_none() {
        rayon::scope(|_| f())
    } else {
        f()
    }
}

/// Per-anchor mode: window `k`'s field as the sum of its blocks' partial blends, in block order.
pub fn reduce(env: &TaskEnv, k: usize) -> Result<(Value, Vec<String>), TaskError> {
    let mut lap = Lap::start();
    let opened = env.open_input()?;
    let topo = opened.source.topology().clone();
    let n = opened.source.n_frames();
    let n_tri = topo.n_triangles();
    let anchors = env.anchors(n, n_tri)?;
    let (_, w) = env.window(n, k)?;
    let n_anchors: usize = (w.start..w.end()).map(|t| anchors.frame(t).len()).sum();
    let n_blocks = plan_blocks(n_anchors, env.params.anchor_block).len();
    let n_nodes = w.len * n_tri;
    let mut field = vec![[0.0; 3]; n_nodes];
    let mut cg = CgStats::default();
    let mut record = WindowRecord {
        start: w.start,
        len: w.len,
        anchors: n_anchors,
        blocks: n_blocks,
        cg_iterations: 0,
        max_relative_residual: 0.0,
        node_updates: 0,
        seconds: 0.0,
    };
    env.progress().begin("reduce", n_blocks as u64);
    lap.lap("reduce: open input, anchors");
    for b in 0..n_blocks {
        env.check_cancelled()?;
        let key = keys::block_partial(k, b);
        let bytes = env.get(&key)?;
        lap.lap("reduce: read partials");
        let stats = partial_file::add_into(&bytes, &mut field, &mut cg, &mut record.node_updates)
            .map_err(|e| TaskError::fatal(format!("{}: {e}", env.out.describe(&key))))?;
        drop(bytes);
        record.seconds += stats.seconds;
        env.progress().advance("reduce", 1);
        lap.lap("reduce: decode and sum");
    }
    env.progress().end("reduce");
    record.cg_iterations = cg.iterations;
    record.max_relative_residual = cg.relative_residual;
    let written = write_window(env, k, w, n_tri, &field, &record);
    lap.lap("reduce: write field");
    written
}

/// Stores a window's field frame by frame plus its statistics.
fn write_window(
    env: &TaskEnv,
    k: usize,
    w: Window,
    n_tri: usize,
    field: &[V3],
    record: &WindowRecord,
) -> Result<(Value, Vec<String>), TaskError> {
    let mut written = Vec::with_capacity(w.len + 1);
    for lt in 0..w.len {
        env.check_cancelled()?;
        let key = keys::window_field(k, w.start + lt);
        // The frame's rows as one flat slice, encoded once (no intermediate copy of 2.4 MB per frame).
        env.put_npy(
            &key,
            &[n_tri, 3],
            field[lt * n_tri..(lt + 1) * n_tri].as_flattened(),
        )?;
        written.push(key);
    }
    let key = keys::window_stats(k);
    env.put_json(&key, record)?;
    written.push(key);
    Ok((serde_json::to_value(record).unwrap_or_default(), written))
}

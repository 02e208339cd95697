//! What a weight-block task costs beyond its own solve, with and without the worker's window cache: the blocks
//! of one paper-scale window run as tasks (`execute`, as a worker runs them) with the cache off and on, and the
//! same blocks solved directly on one prebuilt problem and workspace (the single-process cost). The three are
//! interleaved round by round in one process, so their ratios hold on a loaded machine.
//!
//! `cargo run --release -p crease-research --example block_overhead -- [triangles] [anchors/frame] [blocks] [rounds]`

use crease_core::folds::AnchorSet;
use crease_core::mesh::io::open_sequence;
use crease_core::progress::NoProgress;
use crease_core::spacetime::weights::per_anchor::BlockWorkspace;
use crease_core::spacetime::weights;
use crease_core::spacetime::weights::WindowProblem;
use crease_core::spacetime::windows::Window;
use crease_core::synth::{self, DemoSpec};
use crease_jobs::{execute, inspect_input, plan, window_cache, ExecContext, JobSpec, TaskSpec};
use std::sync::Arc;
use std::time::Instant;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

#[tokio::main]
async fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg = |i: usize, d: usize| args.get(i).and_then(|a| a.parse().ok()).unwrap_or(d);
    let (triangles, per_frame, n_blocks, rounds) =
        (arg(1, 100_000), arg(2, 2000), arg(3, 8), arg(4, 3));
    let frames = 10;
    let root = tempfile::tempdir().unwrap();
    let (seq, _) = synth::demo(&DemoSpec {
        triangles,
        frames,
        ..Default::default()
    })
    .unwrap();
    let anchors = synth::random_anchors(&seq.topology, &seq.frames, per_frame, 7).unwrap();
    let (input, anchors_path) = synth::write_demo(root.path(), &seq, &anchors).unwrap();
    drop(seq);
    let spec = JobSpec::from_toml_str(&format!(
        "input = {:?}\noutput = {:?}\n[folds]\nkind = \"anchors\"\nuri = {:?}\n[deform]\nmode = \"per-anchor\"\n",
        input.display().to_string(),
        root.path().join("out").display().to_string(),
        anchors_path.display().to_string()
    ))
    .unwrap();
    let info = inspect_input(&spec).await.unwrap();
    let blocks: Vec<TaskSpec> = plan(&spec, &info)
        .unwrap()
        .into_iter()
        .map(|t| t.spec)
        .filter(|s| matches!(s, TaskSpec::WeightBlock { window: 0, .. }))
        .take(n_blocks)
        .collect();
    let ctx = ExecContext {
        progress: Arc::new(NoProgress),
        cache_dir: root.path().join("cache"),
    };
    // The single-process reference: one problem, one workspace, the same block ranges.
    let opened = open_sequence(&input).unwrap();
    let topo = opened.source.topology().clone();
    let set = AnchorSet::read(&anchors_path, frames, topo.n_triangles()).unwrap();
    let problem = WindowProblem::new(
        &topo,
        &set,
        Window {
            start: 0,
            len: frames,
        },
        spec.params().coefficients,
    );
    let ranges = weights::anchor_blocks(&problem, &spec.params());
    let mut ws = BlockWorkspace::new(problem.op.n_nodes());
    println!(
        "{} triangles, one {frames}-frame window, {} anchors in {} blocks of <= {}; {} blocks per mode, {rounds} rounds",
        topo.n_triangles(),
        problem.anchors.len(),
        ranges.len(),
        spec.params().anchor_block,
        blocks.len()
    );
    let (mut off, mut on, mut direct) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..rounds {
        window_cache::set_budget(0);
        for b in &blocks {
            let t = Instant::now();
            execute(b, &ctx).await.unwrap();
            off.push(t.elapsed().as_secs_f64());
        }
        window_cache::set_budget(window_cache::DEFAULT_BUDGET_BYTES);
        execute(&blocks[0], &ctx).await.unwrap(); // the window's first block builds the entry
        for b in &blocks {
            let t = Instant::now();
            let out = execute(b, &ctx).await.unwrap();
            assert_eq!(out.summary["window_cache"], "hit");
            on.push(t.elapsed().as_secs_f64());
        }
        for r in ranges.iter().take(blocks.len()) {
            let t = Instant::now();
            weights::anchor_block(&problem, r.clone(), &spec.params(), &mut ws).unwrap();
            direct.push(t.elapsed().as_secs_f64());
        }
    }
    let (off, on, direct) = (median(off), median(on), median(direct));
    println!("median seconds per block: task, cache off {off:.4}; task, cache on {on:.4}; direct solve {direct:.4}");
    println!(
        "per-task overhead over the direct solve: cache off {:.1} ms ({:.2}x), cache on {:.1} ms ({:.2}x)",
        (off - direct) * 1e3,
        off / direct,
        (on - direct) * 1e3,
        on / direct
    );
    println!(
        "machine load: {}",
        std::fs::read_to_string("/proc/loadavg")
            .unwrap_or_default()
            .trim()
    );
}

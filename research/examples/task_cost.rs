//! Where a task's time goes at a given scale: runs every task of a per-anchor job in process and prints the
//! seconds per task kind, next to the fixed cost every task pays (opening the input, reading the anchors,
//! building the window's operator).
//!
//! `cargo run --release -p crease-research --example task_cost -- [triangles] [frames] [fold_scale]`

use crease_core::folds::AnchorSet;
use crease_core::mesh::io::open_sequence;
use crease_core::progress::NoProgress;
use crease_core::spacetime::weights::WindowProblem;
use crease_core::spacetime::windows::Window;
use crease_core::synth::{demo, DemoSpec};
use crease_jobs::{execute, inspect_input, plan, ExecContext, JobSpec};
use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Instant;

#[tokio::main]
async fn main() {
    let args: Vec<String> = std::env::args().collect();
    let triangles: usize = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(100_000);
    let frames: usize = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(10);
    let fold_scale: f64 = args.get(3).and_then(|a| a.parse().ok()).unwrap_or(1.0);
    let root = tempfile::tempdir().unwrap();
    let (seq, anchors) = demo(&DemoSpec {
        triangles,
        frames,
        fold_scale,
        ..Default::default()
    })
    .unwrap();
    let (input, anchors_path) =
        crease_core::synth::write_demo(root.path(), &seq, &anchors).unwrap();
    println!(
        "{} triangles, {frames} frames, {:.0} anchors/frame",
        seq.topology.n_triangles(),
        anchors.total() as f64 / frames as f64
    );

    let c = Instant::now();
    let opened = open_sequence(&input).unwrap();
    let open_s = c.elapsed().as_secs_f64();
    let c = Instant::now();
    let set = AnchorSet::read(
        &anchors_path,
        frames,
        opened.source.topology().n_triangles(),
    )
    .unwrap();
    let anchors_s = c.elapsed().as_secs_f64();
    let c = Instant::now();
    let w = Window {
        start: 0,
        len: frames.min(10),
    };
    let problem = WindowProblem::new(opened.source.topology(), &set, w, Default::default());
    let op_s = c.elapsed().as_secs_f64();
    drop(problem);
    println!("fixed cost per task: open input {open_s:.3}s, read anchors {anchors_s:.3}s, window operator {op_s:.3}s");

    let spec = JobSpec::from_toml_str(&format!(
        "input = {:?}\noutput = {:?}\n[folds]\nkind = \"anchors\"\nuri = {:?}\n[deform]\nmode = \"per-anchor\"\n",
        input.display().to_string(),
        root.path().join("out").display().to_string(),
        anchors_path.display().to_string()
    ))
    .unwrap();
    let info = inspect_input(&spec).await.unwrap();
    let tasks = plan(&spec, &info).unwrap();
    let ctx = ExecContext {
        progress: Arc::new(NoProgress),
        cache_dir: root.path().join("cache"),
    };
    let mut per_kind: BTreeMap<&str, (usize, f64, f64)> = BTreeMap::new();
    for t in &tasks {
        let c = Instant::now();
        let out = execute(&t.spec, &ctx).await.unwrap();
        let e = per_kind.entry(t.spec.kind()).or_default();
        e.0 += 1;
        e.1 += c.elapsed().as_secs_f64();
        e.2 += out.work_seconds;
    }
    for (k, (n, wall, _)) in per_kind {
        println!("{k:>14}: {n:4} tasks, {:.3}s each", wall / n as f64);
    }
}

//! `crease bench --dispatch`: how many tasks per second the coordinator hands out when tasks are tiny, i.e.
//! where the coordinator itself, not the workers, becomes the limit of a farm.
//!
//! The job is the smallest real task a job has: a per-anchor job on a small mesh with one anchor column per
//! weight block (each task a single CG column on a few thousand nodes, a few milliseconds), plus its reduces,
//! one positioning task per frame and finalize. It runs on the local cluster (in-process coordinator, gRPC
//! workers on 127.0.0.1) with every `--dispatch-slots` configuration. A row reports the dispatch rate (tasks
//! / wall), the mean work per task, the mean time an attempt spent outside its work (dispatch, gRPC, result
//! handling) and the occupancy: summed attempt time / (slots × wall), the share of the slots' time that had a
//! task in flight. When more slots stop raising the rate and occupancy falls, the coordinator is the limit.

use super::args::BenchArgs;
use super::jobs::{self, path_str};
use anyhow::{bail, Result};
use crease_core::synth::{self, DemoSpec};
use serde_json::json;

pub fn bench_dispatch(a: &BenchArgs) -> Result<()> {
    let dir = jobs::scratch("dispatch")?;
    let (seq, _) = synth::demo(&DemoSpec {
        triangles: a.dispatch_triangles,
        frames: a.frames,
        ..Default::default()
    })?;
    let anchors = synth::random_anchors(&seq.topology, &seq.frames, a.dispatch_anchors, 7)?;
    let (input, anchors_path) = synth::write_demo(&dir, &seq, &anchors)?;
    let threads = rayon::current_num_threads();
    println!(
        "crease bench --dispatch: {} triangles, {} frames, {} anchors/frame, one anchor column per weight block, \
         one frame per positioning task; {threads} compute threads; loopback gRPC",
        seq.topology.n_triangles(),
        a.frames,
        a.dispatch_anchors
    );
    println!(
        "{:>8} {:>6} {:>7} {:>8} {:>9} {:>12} {:>14} {:>10}",
        "workers",
        "slots",
        "tasks",
        "wall s",
        "tasks/s",
        "work ms/task",
        "outside ms/task",
        "occupancy"
    );
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    let mut rows = Vec::new();
    for cfg in &a.dispatch_slots {
        let (workers, capacity) = parse_slots(cfg)?;
        let out = dir.join(format!("out-{workers}x{capacity}"));
        let spec = json!({
            "name": format!("dispatch-{workers}x{capacity}"),
            "input": path_str(&input),
            "output": path_str(&out),
            "folds": { "kind": "anchors", "uri": path_str(&anchors_path) },
            "deform": { "mode": "per-anchor" },
            "partition": { "anchor_block": 1, "frames_per_chunk": 1 },
            "preview": { "size": 32 },
        });
        let run = jobs::run_job(&rt, &spec, workers, capacity, dir.join("cache"))?;
        let tasks = run.status.tasks.len().max(1) as f64;
        let work: f64 = run.status.tasks.iter().map(|t| t.work_seconds).sum();
        let attempt: f64 = run.status.tasks.iter().map(|t| t.wall_seconds).sum();
        let outside: f64 = run
            .status
            .tasks
            .iter()
            .map(|t| (t.wall_seconds - t.work_seconds).max(0.0))
            .sum();
        let slots = workers * capacity as usize;
        let occupancy = attempt / (slots as f64 * run.wall);
        println!(
            "{:>8} {:>6} {:>7} {:>8.2} {:>9.1} {:>12.2} {:>14.2} {:>9.0}%",
            workers,
            slots,
            run.status.tasks.len(),
            run.wall,
            tasks / run.wall,
            work / tasks * 1e3,
            outside / tasks * 1e3,
            occupancy * 100.0
        );
        rows.push(json!({
            "workers": workers, "slots": slots, "tasks": run.status.tasks.len(), "wall_seconds": run.wall,
            "tasks_per_second": tasks / run.wall, "work_seconds_per_task": work / tasks,
            "outside_seconds_per_task": outside / tasks, "occupancy": occupancy,
        }));
        let _ = std::fs::remove_dir_all(&out);
    }
    println!(
        "machine load during the run: {}",
        std::fs::read_to_string("/proc/loadavg")
            .unwrap_or_default()
            .trim()
    );
    if let Some(path) = &a.json {
        let doc = json!({
            "triangles": seq.topology.n_triangles(), "frames": a.frames,
            "anchors_per_frame": a.dispatch_anchors, "threads": threads, "runs": rows,
        });
        crease_core::fsutil::write_atomic(path, serde_json::to_string_pretty(&doc)?.as_bytes())?;
    }
    let _ = std::fs::remove_dir_all(&dir);
    Ok(())
}

/// `WORKERSxCAPACITY`, e.g. `4x8`.
fn parse_slots(s: &str) -> Result<(usize, u32)> {
    let parsed = s
        .split_once('x')
        .and_then(|(w, c)| Some((w.trim().parse().ok()?, c.trim().parse().ok()?)));
    match parsed {
        Some((w, c)) if w > 0 && c > 0 => Ok((w, c)),
        _ => {
            bail!("--dispatch-slots: `{s}` is not WORKERSxCAPACITY with both at least 1 (e.g. 4x8)")
        }
    }
}

//! `crease bench --cluster`: the paper-scale per-anchor case run as a cluster job on loopback with 1, 2 and 4
//! workers (in-process coordinator and gRPC workers on 127.0.0.1, as in `crease run`).
//!
//! Prints, per worker count: tasks, wall time, summed task work time, throughput (tasks/s and frames/s),
//! efficiency = work time / (workers × wall time), and the per-task overhead outside the task's own work
//! (dispatch, gRPC, payload handling and intermediate storage I/O), measured as the coordinator-side attempt
//! wall time minus the worker-reported work time, averaged over tasks.
//!
//! In the same process it times the in-process per-anchor deformation of the same input and anchors (the
//! `crease bench --modes per-anchor` run) before the first cluster run and after each, so the cluster /
//! in-process ratio holds on a loaded machine; and after each cluster run it prints where the time went: work
//! per task kind, the weight-block and reduce phases (`crease_jobs::phase_times`; the workers run in this
//! process) and the workers' time outside any task.

use super::args::BenchArgs;
use anyhow::{bail, Context, Result};
use crease_core::mesh::MemorySink;
use crease_core::progress::NoProgress;
use crease_core::spacetime::{deform, DeformParams, WeightMode};
use serde_json::json;
use std::time::Instant;

pub fn bench_cluster(a: &BenchArgs) -> Result<()> {
    let triangles = a.cluster_triangles;
    let dir = tempfile_dir()?;
    let input = dir.join("input");
    let anchors_path = dir.join("anchors.json");
    eprintln!(
        "writing the input: {triangles} triangles, {} frames, {} anchors/frame -> {}",
        a.frames,
        a.anchors,
        dir.display()
    );
    let (seq, anchors) = super::measure::case_input(triangles, a.frames, a.anchors)?;
    crease_core::synth::write_demo(&dir, &seq, &anchors)?;
    let params = DeformParams {
        mode: WeightMode::PerAnchor,
        anchor_block: a.cluster_anchor_block,
        ..Default::default()
    };
    // The in-process run the cluster is compared with: the same deformation, per-anchor, in this process.
    let in_process = || -> Result<f64> {
        let t = Instant::now();
        let mut sink = MemorySink::default();
        deform(&seq, &anchors, &params, &mut sink, &NoProgress, &[])?;
        Ok(t.elapsed().as_secs_f64())
    };
    let threads = rayon::current_num_threads();
    println!(
        "crease bench --cluster: {} triangles, {} frames, {} anchors/frame, per-anchor mode, anchor block {}, \
         window 10 / shift 7, {} compute threads shared by the workers, loopback gRPC",
        triangles, a.frames, a.anchors, a.cluster_anchor_block, threads
    );
    println!(
        "{:>7} {:>6} {:>8} {:>9} {:>8} {:>9} {:>10} {:>14}",
        "workers",
        "tasks",
        "wall s",
        "work s",
        "tasks/s",
        "frames/s",
        "efficiency",
        "overhead ms/task"
    );
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    let mut rows = Vec::new();
    let mut first_wall: Option<f64> = None;
    eprintln!("in-process reference");
    let mut refs = vec![in_process()?];
    let mut breakdowns = Vec::new();
    for &n in &a.cluster_workers {
        if n == 0 {
            bail!("--cluster-workers: 0 workers");
        }
        let out = dir.join(format!("out-{n}"));
        let spec = json!({
            "name": format!("bench-{n}"),
            "input": input.display().to_string(),
            "output": out.display().to_string(),
            "folds": { "kind": "anchors", "uri": anchors_path.display().to_string() },
            "deform": { "mode": "per-anchor" },
            "partition": { "anchor_block": a.cluster_anchor_block },
            "preview": { "size": 64 },
        });
        crease_jobs::phase_times::take();
        let run = super::jobs::run_job(&rt, &spec, n, 1, dir.join("cache"))?;
        let phases = crease_jobs::phase_times::take();
        let by_kind = run.work_by_kind();
        let super::jobs::JobRun { status, wall } = run;
        let tasks = status.tasks.len().max(1) as f64;
        let work: f64 = status.tasks.iter().map(|t| t.work_seconds).sum();
        let overhead: f64 = status
            .tasks
            .iter()
            .map(|t| (t.wall_seconds - t.work_seconds).max(0.0))
            .sum::<f64>()
            / tasks;
        let efficiency = work / (n as f64 * wall);
        println!(
            "{:>7} {:>6} {:>8.2} {:>9.2} {:>8.2} {:>9.3} {:>9.0}% {:>7.2}x {:>14.1}",
            n,
            status.tasks.len(),
            wall,
            work,
            tasks / wall,
            a.frames as f64 / wall,
            efficiency * 100.0,
            first_wall.get_or_insert(wall).to_owned() / wall,
            overhead * 1e3
        );
        let attempts: f64 = status.tasks.iter().map(|t| t.wall_seconds).sum();
        rows.push(json!({
            "workers": n, "tasks": status.tasks.len(), "wall_seconds": wall, "work_seconds": work,
            "tasks_per_second": tasks / wall, "frames_per_second": a.frames as f64 / wall,
            "efficiency": efficiency, "overhead_seconds_per_task": overhead,
            "work_by_kind": by_kind.iter().map(|(k, (c, s))| (k.clone(), json!({"tasks": c, "seconds": s})))
                .collect::<serde_json::Map<_, _>>(),
            "phases": phases.iter().map(|(p, c, s)| json!({"phase": p, "samples": c, "seconds": s}))
                .collect::<Vec<_>>(),
            "outside_tasks_seconds": (n as f64 * wall - attempts).max(0.0),
        }));
        breakdowns.push((n, wall, by_kind, phases, attempts));
        let _ = std::fs::remove_dir_all(&out);
        eprintln!("in-process reference");
        refs.push(in_process()?);
    }
    let reference = super::measure::median(refs.clone());
    println!(
        "\nin-process per-anchor deformation of the same input and anchors (this process, one run before the \
         first cluster run and one after each): {} s; median {reference:.2} s",
        refs.iter()
            .map(|r| format!("{r:.2}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    for (n, wall, by_kind, phases, attempts) in &breakdowns {
        println!(
            "\n{n} worker(s): wall {wall:.2} s = {:.2}x in-process; worker time outside tasks (idle, dispatch, \
             gRPC) {:.2} s of {:.2}",
            wall / reference,
            (*n as f64 * wall - attempts).max(0.0),
            *n as f64 * wall
        );
        for (kind, (count, seconds)) in by_kind {
            println!(
                "  {kind:<14} {count:>5} tasks {seconds:>8.2} s work {:>8.1} ms/task",
                seconds / (*count).max(1) as f64 * 1e3
            );
        }
        for (phase, count, seconds) in phases {
            println!(
                "    {phase:<44} {seconds:>8.2} s {:>8.2} ms each",
                seconds / (*count).max(1) as f64 * 1e3
            );
        }
    }
    if let Some(path) = &a.json {
        let doc = json!({
            "triangles": triangles, "frames": a.frames, "anchors_per_frame": a.anchors,
            "anchor_block": a.cluster_anchor_block, "threads": threads, "runs": rows,
            "in_process_seconds": refs, "in_process_median_seconds": reference,
        });
        std::fs::write(path, serde_json::to_string_pretty(&doc)?)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    let _ = std::fs::remove_dir_all(&dir);
    println!(
        "efficiency = summed task work time / (workers x wall); task work time is wall time inside the task, so \
         when workers outnumber cores it stretches with contention; speedup = wall(first row) / wall"
    );
    Ok(())
}

fn tempfile_dir() -> Result<std::path::PathBuf> {
    let dir = std::env::temp_dir().join(format!("crease-bench-cluster-{}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    Ok(dir)
}

//! `crease bench --pipeline`: fold detection and deformation end to end on the paper-scale case, through the
//! local cluster (in-process coordinator, gRPC workers on 127.0.0.1), as a user's `crease run` would.
//!
//! The input is a compressed, twisting tube (the `--stretch-folds-only` case) with a rendered 640x480 video
//! from two cameras, so both detectors find folds. Three measurements, all in this one process so that their
//! ratios hold on a loaded machine:
//!
//! 1. **reference**: the stretch detector and the fused deformation called directly, no cluster;
//! 2. **cluster jobs** with stretch folds and with video folds: seconds per frame per stage (summed task work
//!    time / frames), end-to-end wall time per frame, and the process's peak memory (VmHWM, reset per job;
//!    coordinator and workers all live in this process);
//! 3. **per-task costs and storage traffic**: the stretch job's tasks executed one at a time in process, each
//!    with its work time and the bytes it read and wrote (`rchar`/`wchar` of /proc/self/io), per task kind and
//!    per frame — the figures the farm-sizing estimate in docs/benchmarks.md ("Sizing a farm") is built from.

use super::args::BenchArgs;
use super::jobs::{self, path_str};
use anyhow::{bail, Context, Result};
use crease_core::folds::stretch::StretchDetector;
use crease_core::folds::{AnchorSet, FrameAnchors, FrameDetection};
use crease_core::mesh::MemorySink;
use crease_core::progress::NoProgress;
use crease_core::spacetime::{deform, DeformParams};
use crease_core::synth;
use crease_jobs::{execute, expand, inspect_input, plan, ExecContext, JobSpec};
use serde_json::json;
use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Instant;

/// Task kinds grouped into the stages the table prints.
const STAGES: &[(&str, &[&str])] = &[
    (
        "detection",
        &[
            "fold-steps",
            "fold-phases",
            "fold-detect",
            "fold-settle",
            "fold-merge",
            "fold-files",
            "fold-plot",
        ],
    ),
    ("relief", &["relief"]),
    ("weights", &["weight-window", "weight-block", "reduce"]),
    ("positioning", &["position"]),
    ("finalize", &["finalize"]),
];

pub fn bench_pipeline(a: &BenchArgs) -> Result<()> {
    let triangles = a.cluster_triangles;
    let frames = a.frames;
    let workers = a.pipeline_workers;
    if frames < 2 || workers == 0 {
        bail!("--pipeline needs --frames ≥ 2 and --pipeline-workers ≥ 1");
    }
    let dir = jobs::scratch("pipeline")?;
    let seq = synth::compressed_tube(triangles, frames, 0.3, -1.0)?;
    let input = dir.join("input");
    synth::write_frames(&input, &seq)?;
    let video = dir.join("video");
    eprintln!(
        "writing the input ({} triangles, {frames} frames) and its video (2 cameras, 640x480) -> {}",
        seq.topology.n_triangles(),
        dir.display()
    );
    crease_core::fsutil::create_dir_all(&video)?;
    crease_core::synth_video::write_video(&video, &seq.topology, &seq.frames, 2, 640, 480, 1)?;
    let threads = rayon::current_num_threads();
    println!(
        "crease bench --pipeline: {} triangles, {frames} frames, fused deformation (window 10 / shift 7), \
         {workers} workers x 1 task, {threads} compute threads, loopback gRPC",
        seq.topology.n_triangles()
    );

    // 1. Reference: the same computation without the cluster.
    eprintln!("reference: stretch detection + deformation in process");
    let per_frame = |s: f64| s / frames as f64;
    // What `StretchDetector::detect` does (no subdivision, no overlay frames), in its two timed parts: the two
    // passes with the tracing, then the whole-sequence end (temporal coherence), so that the tasks' costs can be
    // set against each part.
    let det = StretchDetector::default();
    let t = Instant::now();
    let mut traced = Vec::with_capacity(frames);
    let timing = det.run_timed(&seq, &NoProgress, |t, _, _, folds| {
        traced.push(FrameAnchors {
            frame: t,
            anchors: folds.anchors,
            detection: Some(FrameDetection {
                folds: folds.folds.len(),
                seeds_tried: Some(folds.seeds_tried),
            }),
            control_lines: folds.folds.into_iter().flat_map(|f| f.lines).collect(),
        });
        Ok(())
    })?;
    let ref_passes = t.elapsed().as_secs_f64() - timing.tracing;
    let t = Instant::now();
    let (detected, _) = det.finish(&seq, traced, &[])?;
    let ref_settle = t.elapsed().as_secs_f64();
    let ref_detect = ref_passes + timing.tracing + ref_settle;
    let anchors = AnchorSet::from_frame_anchors(detected, seq.topology.n_triangles(), None)?;
    let t = Instant::now();
    let mut sink = MemorySink::default();
    deform(
        &seq,
        &anchors,
        &DeformParams::default(),
        &mut sink,
        &NoProgress,
        &[],
    )?;
    drop(sink);
    let ref_deform = t.elapsed().as_secs_f64();
    let ref_total = ref_detect + ref_deform;
    drop(seq);

    // 2. Cluster jobs.
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    let jobs = [
        ("stretch", json!({ "kind": "stretch" })),
        (
            "video",
            json!({ "kind": "video", "cameras": path_str(&video.join("cameras.json")) }),
        ),
    ];
    let mut rows = Vec::new();
    let mut busy = Vec::new();
    for (label, folds) in &jobs {
        eprintln!("cluster job with {label} folds");
        let out = dir.join(format!("out-{label}"));
        let spec = json!({
            "name": format!("pipeline-{label}"),
            "input": path_str(&input),
            "output": path_str(&out),
            "folds": folds,
            "preview": { "size": 64 },
        });
        super::measure::reset_peak_rss();
        let run = jobs::run_job(&rt, &spec, workers, 1, dir.join("cache"))?;
        let peak = super::measure::peak_rss().unwrap_or(0);
        let by_kind = run.work_by_kind();
        let anchors = AnchorSet::read(
            &out.join(crease_jobs::storage::keys::ANCHORS),
            frames,
            triangles_of(&input)?,
        )
        .map(|s| s.total())
        .unwrap_or(0);
        let stages: Vec<(String, f64)> = STAGES
            .iter()
            .map(|(name, kinds)| {
                let work: f64 = kinds
                    .iter()
                    .filter_map(|k| by_kind.get(*k))
                    .map(|(_, s)| s)
                    .sum();
                (name.to_string(), per_frame(work))
            })
            .collect();
        let work_total: f64 = stages.iter().map(|(_, s)| s).sum();
        // Where the workers' time went: inside a task's work, in an attempt but outside its work (dispatch,
        // gRPC, the task's hand-off to its thread), or idle (nothing ready for it, or waiting for a
        // dependency).
        let attempts: f64 = run.status.tasks.iter().map(|t| t.wall_seconds).sum();
        let work: f64 = run.status.tasks.iter().map(|t| t.work_seconds).sum();
        let slots = workers as f64 * run.wall;
        busy.push((
            label.to_string(),
            run.status.tasks.len(),
            work / slots,
            (attempts - work).max(0.0) / slots,
            (slots - attempts).max(0.0) / slots,
        ));
        rows.push((
            label.to_string(),
            stages,
            work_total,
            per_frame(run.wall),
            peak,
            anchors,
        ));
        let _ = std::fs::remove_dir_all(&out);
    }

    println!("\nseconds per frame (stages: summed task work time / frames; wall: submit to done / frames)");
    print!("{:>9}", "folds");
    for (name, _) in STAGES {
        print!(" {name:>11}");
    }
    println!(
        " {:>10} {:>9} {:>9} {:>10}",
        "work", "wall", "peak MiB", "anchors/f"
    );
    for (label, stages, work, wall, peak, anchors) in &rows {
        print!("{label:>9}");
        for (_, s) in stages {
            print!(" {s:>11.3}");
        }
        println!(
            " {work:>10.3} {wall:>9.3} {:>9.0} {:>10.1}",
            *peak as f64 / (1u64 << 20) as f64,
            *anchors as f64 / frames as f64
        );
    }
    for (label, tasks, work, outside, idle) in &busy {
        println!(
            "{label:>9} job: {tasks} tasks; of the workers' time {:.0}% in task work, {:.0}% in attempts outside \
             the work (dispatch, gRPC), {:.0}% idle (waiting for a dependency or the coordinator)",
            work * 100.0,
            outside * 100.0,
            idle * 100.0
        );
    }
    println!(
        "reference (same process, no cluster): stretch detection {:.3} s/frame (passes {:.3}, tracing {:.3}, \
         temporal settle {:.3}), deformation {:.3} s/frame, total {:.3} s/frame; stretch job wall / reference = \
         {:.2}x",
        per_frame(ref_detect),
        per_frame(ref_passes),
        per_frame(timing.tracing),
        per_frame(ref_settle),
        per_frame(ref_deform),
        per_frame(ref_total),
        rows[0].3 / per_frame(ref_total)
    );

    // 3. Per-task costs and traffic, one task at a time.
    eprintln!("per-task costs: the stretch job's tasks one at a time in process");
    let out = dir.join("out-sequential");
    let spec = JobSpec::from_json_str(
        &json!({
            "name": "pipeline-sequential",
            "input": path_str(&input),
            "output": path_str(&out),
            "folds": { "kind": "stretch" },
            "preview": { "size": 64 },
        })
        .to_string(),
    )?;
    crease_jobs::phase_times::take();
    let (mut costs, timed) = rt.block_on(sequential_costs(&spec, &dir.join("cache-sequential")))?;
    let phases = crease_jobs::phase_times::take();
    // The per-anchor task kinds, on the anchors the stretch job just detected.
    let spec = JobSpec::from_json_str(
        &json!({
            "name": "pipeline-sequential-per-anchor",
            "input": path_str(&input),
            "output": path_str(&dir.join("out-sequential-per-anchor")),
            "folds": { "kind": "anchors", "uri": path_str(&out.join(crease_jobs::storage::keys::ANCHORS)) },
            "deform": { "mode": "per-anchor" },
            "preview": { "size": 64 },
        })
        .to_string(),
    )?;
    let (per_anchor, _) = rt.block_on(sequential_costs(&spec, &dir.join("cache-sequential")))?;
    for kind in ["weight-block", "reduce"] {
        if let Some(c) = per_anchor.get(kind) {
            costs.insert(format!("{kind} (p-a)"), c.clone());
        }
    }
    println!(
        "\nper task kind, tasks run one at a time (work s; MB read and written through read()/write()); \
         (p-a): the per-anchor kinds, from the same input and detected anchors in per-anchor mode"
    );
    println!(
        "{:>18} {:>6} {:>10} {:>10} {:>10} {:>12} {:>12}",
        "kind", "tasks", "s/task", "s/frame", "MB read/t", "MB written/t", "MB r+w/frame"
    );
    let mb = |b: u64| b as f64 / 1e6;
    let (mut seq_work, mut traffic) = (0.0, 0u64);
    for (kind, c) in &costs {
        let n = c.tasks as f64;
        println!(
            "{kind:>18} {:>6} {:>10.3} {:>10.3} {:>10.2} {:>12.2} {:>12.2}",
            c.tasks,
            c.seconds / n,
            per_frame(c.seconds),
            mb(c.read) / n,
            mb(c.written) / n,
            mb(c.read + c.written) / frames as f64
        );
        if !kind.ends_with("(p-a)") {
            seq_work += c.seconds;
            traffic += c.read + c.written;
        }
    }
    println!(
        "{:>18} {:>6} {:>10} {:>10.3} {:>10} {:>12} {:>12.2}",
        "all but (p-a)",
        costs
            .iter()
            .filter(|(k, _)| !k.ends_with("(p-a)"))
            .map(|(_, c)| c.tasks)
            .sum::<usize>(),
        "",
        per_frame(seq_work),
        "",
        "",
        mb(traffic) / frames as f64
    );
    // Where the stretch job's wall goes: no schedule on `workers` workers beats the longest dependency chain
    // (each task at its one-at-a-time cost) nor the summed work / workers.
    let (path_seconds, chain) = critical_path(&timed);
    let spread = per_frame(seq_work) / workers as f64;
    println!(
        "\nstretch job, tasks one at a time: critical path {:.3} s/frame, summed work / {workers} workers {:.3} \
         s/frame; the cluster job's wall was {:.3} s/frame",
        per_frame(path_seconds),
        spread,
        rows[0].3
    );
    println!("critical path (s/frame per task):");
    for (key, seconds) in &chain {
        println!("  {key:<28} {:>8.3}", per_frame(*seconds));
    }
    println!("phases of the stretch job's tasks, one at a time (s/frame):");
    for (phase, count, seconds) in &phases {
        println!(
            "  {phase:<52} {:>8.3} ({count} samples)",
            per_frame(*seconds)
        );
    }
    println!(
        "machine load during the run: {}",
        std::fs::read_to_string("/proc/loadavg")
            .unwrap_or_default()
            .trim()
    );
    if let Some(path) = &a.json {
        let doc = json!({
            "triangles": triangles, "frames": frames, "workers": workers, "threads": threads,
            "reference_seconds_per_frame": {
                "detect": per_frame(ref_detect), "deform": per_frame(ref_deform),
                "detect_passes": per_frame(ref_passes), "detect_tracing": per_frame(timing.tracing),
                "detect_settle": per_frame(ref_settle),
            },
            "jobs": rows.iter().map(|(label, stages, work, wall, peak, anchors)| json!({
                "folds": label,
                "stage_seconds_per_frame": stages.iter().cloned().collect::<BTreeMap<_, _>>(),
                "work_seconds_per_frame": work, "wall_seconds_per_frame": wall,
                "peak_rss_bytes": peak, "anchors": anchors,
            })).collect::<Vec<_>>(),
            "worker_time": busy.iter().map(|(label, tasks, work, outside, idle)| json!({
                "folds": label, "tasks": tasks, "work": work, "outside_work": outside, "idle": idle,
            })).collect::<Vec<_>>(),
            "phases": phases.iter().map(|(p, c, s)| json!({"phase": p, "samples": c, "seconds": s}))
                .collect::<Vec<_>>(),
            "critical_path": {
                "seconds_per_frame": per_frame(path_seconds),
                "tasks": chain.iter().map(|(k, s)| json!({"task": k, "seconds": s})).collect::<Vec<_>>(),
            },
            "per_task": costs.iter().map(|(k, c)| (k.clone(), json!({
                "tasks": c.tasks, "seconds": c.seconds, "bytes_read": c.read, "bytes_written": c.written,
            }))).collect::<serde_json::Map<_, _>>(),
        });
        crease_core::fsutil::write_atomic(path, serde_json::to_string_pretty(&doc)?.as_bytes())?;
    }
    let _ = std::fs::remove_dir_all(&dir);
    Ok(())
}

fn triangles_of(input: &std::path::Path) -> Result<usize> {
    let opened = crease_core::mesh::io::open_sequence(input)?;
    Ok(opened.source.topology().n_triangles())
}

/// Work time and I/O of one task kind, summed over its tasks.
#[derive(Default, Clone)]
struct KindCost {
    tasks: usize,
    seconds: f64,
    read: u64,
    written: u64,
}

/// One task run on its own: key, dependencies and work seconds.
type Timed = (String, Vec<String>, f64);

/// The longest chain of dependent tasks (by their one-at-a-time seconds): its total and its tasks in order.
fn critical_path(tasks: &[Timed]) -> (f64, Vec<(String, f64)>) {
    // Tasks are listed in an order where dependencies come first (plan order, expansions appended).
    let mut best: BTreeMap<&str, (f64, Option<&str>)> = BTreeMap::new();
    for (key, deps, seconds) in tasks {
        let before = deps
            .iter()
            .filter_map(|d| best.get(d.as_str()).map(|(s, _)| (*s, d.as_str())))
            .max_by(|a, b| a.0.total_cmp(&b.0));
        let (start, prev) = before.map_or((0.0, None), |(s, d)| (s, Some(d)));
        best.insert(key, (start + seconds, prev));
    }
    let Some((mut at, (total, _))) = best
        .iter()
        .max_by(|a, b| a.1 .0.total_cmp(&b.1 .0))
        .map(|(k, v)| (*k, *v))
    else {
        return (0.0, Vec::new());
    };
    let own: BTreeMap<&str, f64> = tasks.iter().map(|(k, _, s)| (k.as_str(), *s)).collect();
    let mut path = vec![(at.to_string(), own[at])];
    while let Some(prev) = best[at].1 {
        path.push((prev.to_string(), own[prev]));
        at = prev;
    }
    path.reverse();
    (total, path)
}

/// Executes every task of `spec` one at a time (plan order, expanding as the coordinator does) and measures
/// each: wall time and the process's read/write byte counters around it.
async fn sequential_costs(
    spec: &JobSpec,
    cache: &std::path::Path,
) -> Result<(BTreeMap<String, KindCost>, Vec<Timed>)> {
    let info = inspect_input(spec).await?;
    let mut pending = plan(spec, &info)?;
    let ctx = ExecContext {
        progress: Arc::new(NoProgress),
        cache_dir: cache.to_path_buf(),
    };
    let mut costs: BTreeMap<String, KindCost> = BTreeMap::new();
    let mut timed = Vec::new();
    let mut i = 0;
    while i < pending.len() {
        let task = pending[i].clone();
        i += 1;
        let (r0, w0) = super::measure::io_counters().unwrap_or_default();
        let t = Instant::now();
        let out = execute(&task.spec, &ctx)
            .await
            .map_err(|e| anyhow::anyhow!("task {}: {}", task.key, e.reason))?;
        let seconds = t.elapsed().as_secs_f64();
        let (r1, w1) = super::measure::io_counters().unwrap_or_default();
        let c = costs.entry(task.spec.kind().to_string()).or_default();
        c.tasks += 1;
        c.seconds += seconds;
        c.read += r1.saturating_sub(r0);
        c.written += w1.saturating_sub(w0);
        timed.push((task.key.clone(), task.deps.clone(), seconds));
        if task.expands {
            pending.extend(expand(spec, &info, &task.key, &out).context("expanding the plan")?);
        }
    }
    Ok((costs, timed))
}

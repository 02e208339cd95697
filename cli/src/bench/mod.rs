//! `crease bench`: the paper-scale benchmark (Popa et al. 2009 §6: ~100K triangles, ~2000 anchors per frame,
//! 10-frame windows shifted by 7) at several mesh sizes, in both weight modes.
//!
//! Reports seconds per frame per stage (work time summed over frames, divided by the frame count) and the
//! wall-clock seconds per frame, medians over repeats, and the peak resident memory of each case (the kernel's
//! high-water mark is reset between cases). With `--export DIR` it also writes the matrices of one window and
//! one frame as `.npy` together with our own timings of exactly those solves, for `bench/scipy_compare.py`.

mod args;
mod cluster;
#[cfg(feature = "deep")]
mod deep;
mod dispatch;
mod jobs;
mod measure;
mod pipeline;

use anyhow::{Context, Result};
pub use args::BenchArgs;
use crease_core::mesh::MemorySink;
use crease_core::npy;
use crease_core::progress::NoProgress;
use crease_core::spacetime::blend::so3;
use crease_core::spacetime::position::PositionSystem;
use crease_core::spacetime::weights::per_anchor::LocalCg;
use crease_core::spacetime::weights::{solve_window, WindowProblem};
use crease_core::spacetime::windows::Window;
use crease_core::spacetime::{deform, DeformParams, WeightMode};
use crease_core::synth::{self, DemoSpec};
use measure::{case_input, median, peak_rss, reset_peak_rss, scratch_dir};
use serde_json::json;
use std::path::Path;
use std::time::Instant;

pub fn bench(a: BenchArgs) -> Result<()> {
    if a.cluster {
        return cluster::bench_cluster(&a);
    }
    if a.pipeline {
        return pipeline::bench_pipeline(&a);
    }
    if a.dispatch {
        return dispatch::bench_dispatch(&a);
    }
    if a.deep {
        #[cfg(feature = "deep")]
        return deep::bench_deep(&a);
        #[cfg(not(feature = "deep"))]
        anyhow::bail!(crate::without_deep::HOW_TO_GET_IT);
    }
    if a.edges_only {
        let edges = edges_stage(&a)?;
        if let Some(path) = &a.json {
            let doc = json!({ "video_edges": edges });
            crease_core::fsutil::write_atomic(
                path,
                serde_json::to_string_pretty(&doc)?.as_bytes(),
            )?;
        }
        return Ok(());
    }
    if a.frames < 2 || a.repeats == 0 {
        anyhow::bail!("--frames must be ≥ 2 and --repeats ≥ 1");
    }
    if a.stretch_folds_only {
        return stretch_folds_stage(&a);
    }
    let threads = rayon::current_num_threads();
    println!(
        "crease bench: {} frames, {} anchors/frame, window 10 / shift 7, {} threads, median of {} runs",
        a.frames, a.anchors, threads, a.repeats
    );
    println!("seconds per frame per stage (work time summed over frames / frames); wall = elapsed / frames");
    println!("CG it: iterations per window (fused) or per anchor column (per-anchor)");
    println!(
        "{:>8} {:>10} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>9} {:>10}",
        "tris",
        "mode",
        "weights",
        "blend",
        "factor",
        "solve",
        "pass1",
        "pass2",
        "wall",
        "peak MiB",
        "CG it"
    );
    let mut rows = Vec::new();
    for &size in &a.sizes {
        let (seq, anchors) = case_input(size, a.frames, a.anchors)?;
        for &mode in &a.modes {
            let params = DeformParams {
                mode,
                ..Default::default()
            };
            let mut samples: Vec<crease_core::spacetime::DeformReport> = Vec::new();
            let mut peak = 0u64;
            for _ in 0..a.repeats {
                reset_peak_rss();
                let mut sink = MemorySink::default();
                let (report, _) = deform(&seq, &anchors, &params, &mut sink, &NoProgress, &[])?;
                drop(sink);
                peak = peak.max(peak_rss().unwrap_or(0));
                samples.push(report);
            }
            let n = a.frames as f64;
            let med = |f: &dyn Fn(&crease_core::spacetime::DeformReport) -> f64| {
                median(samples.iter().map(f).collect())
            };
            let weights = med(&|r| r.timings.weights / n);
            let blend = med(&|r| r.timings.blend / n);
            let factor = med(&|r| r.timings.factor / n);
            let solve = med(&|r| r.timings.position / n);
            let pass =
                |k: usize| med(&|r| r.timings.stretch_passes.get(k).copied().unwrap_or(0.0) / n);
            let wall = med(&|r| r.timings.wall / n);
            // Fused: CG iterations per window; per-anchor: mean CG iterations per anchor column.
            let it = med(&|r| {
                let (it, cols): (usize, usize) = r
                    .windows
                    .iter()
                    .map(|w| (w.cg_iterations, w.anchors))
                    .fold((0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
                match mode {
                    WeightMode::Fused => it as f64 / r.windows.len() as f64,
                    WeightMode::PerAnchor => it as f64 / cols.max(1) as f64,
                }
            });
            let r0 = &samples[0];
            println!(
                "{:>8} {:>10} {:>8.4} {:>8.4} {:>8.4} {:>8.4} {:>8.4} {:>8.4} {:>8.4} {:>9.0} {:>10.1}",
                r0.triangles,
                mode.to_string(),
                weights,
                blend,
                factor,
                solve,
                pass(0),
                pass(1),
                wall,
                peak as f64 / (1 << 20) as f64,
                it
            );
            rows.push(json!({
                "triangles": r0.triangles, "vertices": r0.vertices, "frames": a.frames, "anchors_per_frame": a.anchors,
                "mode": mode.to_string(), "threads": threads, "repeats": a.repeats,
                "seconds_per_frame": {"weights": weights, "blend": blend, "factor": factor, "position": solve,
                    "stretch_pass_1": pass(0), "stretch_pass_2": pass(1), "wall": wall},
                "peak_rss_bytes": peak, "cg_iterations": it,
                "stretch_final": r0.stretch.last(),
            }));
        }
    }
    aux_stages(&a)?;
    stretch_folds_stage(&a)?;
    let edges = edges_stage(&a)?;
    let export = match &a.export {
        Some(dir) => Some(export_case(
            dir,
            a.export_size,
            a.frames.max(10),
            a.anchors,
            a.repeats,
        )?),
        None => None,
    };
    if let Some(path) = &a.json {
        let doc = json!({"cases": rows, "export": export, "video_edges": edges});
        crease_core::fsutil::write_atomic(path, serde_json::to_string_pretty(&doc)?.as_bytes())?;
    }
    Ok(())
}

/// Stages around the deformation: reading and writing one OBJ frame, and rendering one 512x512 preview tile.
fn aux_stages(a: &BenchArgs) -> Result<()> {
    println!(
        "\nI/O and preview, seconds per frame (median of {} runs)",
        a.repeats.max(3)
    );
    println!(
        "{:>8} {:>10} {:>10} {:>10}",
        "tris", "OBJ read", "OBJ write", "render"
    );
    for &size in &a.sizes {
        let spec = DemoSpec {
            triangles: size,
            frames: 1,
            ..Default::default()
        };
        let (seq, _) = synth::demo(&spec)?;
        let dir = scratch_dir()?;
        let input = dir.join("in");
        crease_core::fsutil::create_dir_all(&input)?;
        crease_core::mesh::io::write_obj_sequence(
            &input,
            &seq.topology,
            [("frame_0001.obj".to_string(), seq.frames[0].as_slice())],
        )?;
        let opened = crease_core::mesh::io::open_sequence(&input)?;
        let runs = a.repeats.max(3);
        let read = median(
            (0..runs)
                .map(|_| {
                    let t = Instant::now();
                    let ok = opened.source.read_frame(0).is_ok();
                    if ok {
                        t.elapsed().as_secs_f64()
                    } else {
                        f64::NAN
                    }
                })
                .collect(),
        );
        let out = dir.join("out");
        let write = median(
            (0..runs)
                .map(|_| {
                    let t = Instant::now();
                    let ok = crease_core::mesh::io::create_sink(&opened.layout, &out)
                        .and_then(|mut sink| {
                            sink.write_frame(0, &seq.frames[0])?;
                            sink.finish()
                        })
                        .is_ok();
                    if ok {
                        t.elapsed().as_secs_f64()
                    } else {
                        f64::NAN
                    }
                })
                .collect(),
        );
        let (lo, hi) = crease_core::mesh::geometry::bounding_box(&seq.frames[0]);
        let cam =
            crease_core::render::Camera::fit(lo, hi, [0.0, 1.0, -0.3], [0.0, 0.0, 1.0], 512, 512);
        let render = median(
            (0..runs)
                .map(|_| {
                    let t = Instant::now();
                    let img = crease_core::render::render(
                        &seq.frames[0],
                        &seq.topology,
                        &cam,
                        &Default::default(),
                    );
                    std::hint::black_box(img);
                    t.elapsed().as_secs_f64()
                })
                .collect(),
        );
        println!(
            "{:>8} {:>10.4} {:>10.4} {:>10.4}",
            seq.topology.n_triangles(),
            read,
            write,
            render
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
    Ok(())
}

/// Geometric fold estimation (Chen 2011, `--folds stretch`) on a compressed, twisting tube: seconds per frame
/// for the whole detector (both passes and the tracing) and for the tracing alone, with folds and anchors per
/// frame.
fn stretch_folds_stage(a: &BenchArgs) -> Result<()> {
    use crease_core::folds::stretch::StretchDetector;
    let frames = a.frames.clamp(4, 12);
    println!(
        "\nstretch folds (Chen 2011), seconds per frame over {frames} frames of a compressed sleeve"
    );
    println!(
        "(tracing: its seconds per frame, the rest of s/frame is the two passes; ahead/f: seeds per frame traced \
         ahead of their turn on another thread, of them wasted/f discarded)"
    );
    println!(
        "{:>8} {:>10} {:>10} {:>10} {:>10} {:>12} {:>9} {:>8} {:>9}",
        "tris",
        "s/frame",
        "tracing",
        "folds/f",
        "anchors/f",
        "seeds tried/f",
        "peak MiB",
        "ahead/f",
        "wasted/f"
    );
    for &size in &a.sizes {
        let seq = synth::compressed_tube(size, frames, 0.3, -1.0)?;
        let (mut folds, mut anchors, mut seeds) = (0usize, 0usize, 0usize);
        reset_peak_rss();
        let t = Instant::now();
        let detector = StretchDetector::default();
        let timing = detector.run_timed(&seq, &NoProgress, |_, _, _, f| {
            folds += f.folds.len();
            anchors += f.anchors.len();
            seeds += f.seeds_tried;
            Ok(())
        })?;
        let per = |x: usize| x as f64 / frames as f64;
        let seconds = t.elapsed().as_secs_f64();
        // The process's peak since the reset: the sequence, the detector's buffers and the tracing scratch.
        let peak = peak_rss().unwrap_or(0) as f64 / (1 << 20) as f64;
        println!(
            "{:>8} {:>10.3} {:>10.3} {:>10.1} {:>10.1} {:>12.1} {:>9.0} {:>8.1} {:>9.1}",
            seq.topology.n_triangles(),
            seconds / frames as f64,
            timing.tracing / frames as f64,
            per(folds),
            per(anchors),
            per(seeds),
            peak,
            per(timing.traced_ahead),
            per(timing.wasted)
        );
    }
    Ok(())
}

/// Video fold-edge stage (Popa et al. 2009 §4): one 640x480 image at the default 4 Canny radii — Canny, chaining
/// and quadric fits alone, and with orientation, merging, pairing and the union over radii.
fn edges_stage(a: &BenchArgs) -> Result<serde_json::Value> {
    use crease_core::folds::video::{edges, image_pairs, Photo, VideoParams};
    use rayon::prelude::*;
    let img = match &a.edges_image {
        Some(p) => image::open(p)
            .with_context(|| format!("reading {}", p.display()))?
            .to_rgba8(),
        None => crease_core::synth_video::folded_demo_image(40_000, 640, 480)?,
    };
    let photo = Photo::from_rgba(&img);
    let params = VideoParams::default();
    let mask = photo.eroded_mask(params.silhouette_margin);
    let runs = a.repeats.max(3);
    let mut n_edges = 0;
    let extract = median(
        (0..runs)
            .map(|_| {
                let t = Instant::now();
                // In parallel over levels, as `image_pairs` runs them.
                n_edges = edges::levels(&params)
                    .into_par_iter()
                    .map(|l| edges::extract(&photo, &mask, l, &params).edges.len())
                    .sum();
                t.elapsed().as_secs_f64()
            })
            .collect(),
    );
    let mut n_pairs = 0;
    let full = median(
        (0..runs)
            .map(|_| {
                let t = Instant::now();
                n_pairs = image_pairs(&photo, &params).1.len();
                t.elapsed().as_secs_f64()
            })
            .collect(),
    );
    println!(
        "\nvideo fold edges, one {}x{} image, radii {:?} (median of {runs} runs)",
        photo.width, photo.height, params.radii
    );
    println!(
        "{:>12} {:>14} {:>8} {:>8}",
        "edges (s)", "edges+pairs (s)", "edges", "pairs"
    );
    println!("{extract:>12.4} {full:>14.4} {n_edges:>8} {n_pairs:>8}");
    Ok(
        json!({"width": photo.width, "height": photo.height, "radii": params.radii,
              "edges_seconds": extract, "edges_and_pairs_seconds": full,
              "edges": n_edges, "pairs": n_pairs}),
    )
}

/// Exports the first window's weight matrix and right-hand sides, and frame 0's positioning matrix and
/// right-hand side, with our timings of the same solves, for comparison with SciPy.
fn export_case(
    dir: &Path,
    size: usize,
    frames: usize,
    anchors_per_frame: usize,
    repeats: usize,
) -> Result<serde_json::Value> {
    crease_core::fsutil::create_dir_all(dir)?;
    let (seq, anchors) = case_input(size, frames, anchors_per_frame)?;
    let topo = seq.topology.clone();
    let params = DeformParams::default();
    let window = Window {
        start: 0,
        len: params.window.min(frames),
    };
    let problem = WindowProblem::new(&topo, &anchors, window, params.coefficients);
    let (indptr, indices, values) = problem.op.to_csr();
    let n = problem.op.n_nodes();
    npy::write(&dir.join("weights_indptr.npy"), &[indptr.len()], &indptr)?;
    npy::write(&dir.join("weights_indices.npy"), &[indices.len()], &indices)?;
    npy::write(&dir.join("weights_data.npy"), &[values.len()], &values)?;
    npy::write_v3(&dir.join("weights_rhs.npy"), &problem.fused_rhs())?;
    let anchor_nodes: Vec<u32> = problem.anchors.iter().map(|a| a.node).collect();
    npy::write(
        &dir.join("weights_anchor_nodes.npy"),
        &[anchor_nodes.len()],
        &anchor_nodes,
    )?;

    // Our fused 3-RHS solve of this window.
    let fused = median(
        (0..repeats)
            .map(|_| {
                let t = Instant::now();
                let r = solve_window(&problem, &params, &NoProgress);
                r.map(|_| t.elapsed().as_secs_f64()).unwrap_or(f64::NAN)
            })
            .collect(),
    );
    // Our per-anchor column solve: time per column over the first 200 anchors.
    let sample = problem.anchors.len().min(200);
    let per_column = median(
        (0..repeats)
            .map(|_| {
                let mut cg = LocalCg::new(n);
                let t = Instant::now();
                for a in &problem.anchors[..sample] {
                    let solved = cg.solve(
                        &problem.op,
                        a.node,
                        params.coefficients.c_a,
                        params.cg_tolerance,
                        params.cg_max_iterations,
                    );
                    if solved.is_err() {
                        return f64::NAN;
                    }
                }
                t.elapsed().as_secs_f64() / sample as f64
            })
            .collect(),
    );
    let per_anchor_window = {
        let pa = DeformParams {
            mode: WeightMode::PerAnchor,
            ..params.clone()
        };
        let t = Instant::now();
        solve_window(&problem, &pa, &NoProgress)?;
        t.elapsed().as_secs_f64()
    };

    // Positioning of frame 0 with the demo's blended rotations of this window.
    let (field, _) = solve_window(&problem, &params, &NoProgress)?;
    let rotations: Vec<_> = field[..topo.n_triangles()]
        .iter()
        .map(|&p| so3::exp(p))
        .collect();
    let edge = crease_core::shape::mean_edge_length(&topo, &seq.frames[0]);
    let system = PositionSystem::new(topo.clone(), params.pinning, params.scales(edge).screen)?;
    let rest = &seq.frames[0];
    let (lower, _, _, _) = system.assemble(rest)?;
    let (col_ptr, row_idx) = system.pattern();
    let col_ptr: Vec<u64> = col_ptr.iter().map(|&c| c as u64).collect();
    let row_idx: Vec<u64> = row_idx.iter().map(|&r| r as u64).collect();
    npy::write(&dir.join("position_colptr.npy"), &[col_ptr.len()], &col_ptr)?;
    npy::write(&dir.join("position_rowidx.npy"), &[row_idx.len()], &row_idx)?;
    npy::write(&dir.join("position_lower.npy"), &[lower.len()], &lower)?;
    let fp = system.factor_frame(rest)?;
    let rhs = fp.rhs(&rotations);
    let rhs_rows: Vec<[f64; 3]> = (0..rhs.nrows())
        .map(|i| [rhs[(i, 0)], rhs[(i, 1)], rhs[(i, 2)]])
        .collect();
    npy::write_v3(&dir.join("position_rhs.npy"), &rhs_rows)?;
    let factor = median(
        (0..repeats)
            .map(|_| {
                let t = Instant::now();
                let f = system.factor_frame(rest);
                let e = t.elapsed().as_secs_f64();
                drop(f);
                e
            })
            .collect(),
    );
    let solve = median(
        (0..repeats)
            .map(|_| {
                let mut b = rhs.clone();
                let t = Instant::now();
                fp.solve_in_place(&mut b);
                t.elapsed().as_secs_f64()
            })
            .collect(),
    );
    let ours = json!({
        "triangles": topo.n_triangles(), "window_nodes": n, "window_anchors": problem.anchors.len(),
        "weights_fused_seconds": fused, "weights_per_column_seconds": per_column,
        "weights_per_anchor_window_seconds": per_anchor_window,
        "position_unknowns": system.pattern().0.len() - 1, "position_factor_seconds": factor,
        "position_solve3_seconds": solve, "cg_tolerance": params.cg_tolerance,
        "threads": rayon::current_num_threads(), "c_a": params.coefficients.c_a,
    });
    crease_core::fsutil::write_atomic(
        &dir.join("ours.json"),
        serde_json::to_string_pretty(&ours)?.as_bytes(),
    )
    .context("writing ours.json")?;
    println!(
        "exported window ({} nodes, {} anchors) and frame-0 positioning ({} unknowns) to {}",
        n,
        problem.anchors.len(),
        system.pattern().0.len() - 1,
        dir.display()
    );
    Ok(ours)
}

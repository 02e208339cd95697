//! The DeepWrinkles figures on the sleeve training data, one sequence held out (docs/deepwrinkles.md):
//!
//! ```text
//! cargo run --release -p crease-deep --example deep_report -- subspace   DATA OUT [held-out]
//! cargo run --release -p crease-deep --example deep_report -- regression DATA OUT [held-out] [epochs] [layers] [hidden] [ridge] [AR states, e.g. 10,25,50]
//! cargo run --release -p crease-deep --example deep_report -- regression DATA OUT all [epochs] [layers] [hidden] [ridge] [AR states] [rollout-fit iterations, e.g. 0,5,20,50] [history time constants, e.g. "none;3,10,30"] [all|blend: every row, or only the linear, AR and blend rows]
//! cargo run --release -p crease-deep --example deep_report -- fitloso    DATA OUT "features,mirror,ridge[,lstm LAYERSxHIDDENxEPOCHS[,residual base|none[,cf|in[,es|all[,lr]]]]];…"
//! cargo run --release -p crease-deep --example deep_report -- cgan       DATA OUT [held-out] [epochs] [res] [filters] [ridge] [AR state] [variants, e.g. captured,captured_notemp,subspace200,subspace50,regression] [batch] [minutes per variant] [learning rate]
//! cargo run --release -p crease-deep --example deep_report -- register   DATA OUT [frames] [target points] [min weight] [iterations]
//! cargo run --release -p crease-deep --example deep_report -- score      APPLY_OUT GT CAPTURED
//! cargo run --release -p crease-deep --example deep_report -- tube       [target points, e.g. 1,12] [min weights, e.g. 1,20,100] [iterations]
//! cargo run --release -p crease-deep --example deep_report -- detail     DATA OUT [held-out|all] [degrees, e.g. 20,40] [ridges, e.g. 1e-8,1e-10] [map resolutions] [frame step]
//! cargo run --release -p crease-deep --example deep_report -- posenorm   DATA OUT [held-out|all] [time σ, e.g. 2,4] [map frame step] [map resolution]
//! cargo run --release -p crease-deep --example deep_report -- posenormals DATA OUT [held-out|all] [normal subspace sizes, e.g. 25,100,200] [map frame step] [map resolution]
//! cargo run --release -p crease-deep --example deep_report -- posesmooth DATA OUT [held-out|all] [low-pass steps, e.g. 0,80,160] [leading coefficients, e.g. 0,10,50] [map frame step] [map resolution]
//! ```
//!
//! DATA is `sleeve-train/` (seed_1, seed_2, seed_3); the held-out sequence defaults to seed_3. Every part
//! prints a Markdown table and writes JSON (and PNGs) under OUT.

use crease_core::mesh::geometry::vertex_normals;
use crease_core::mesh::io::open_sequence;
use crease_core::mesh::{Frame, Sequence, Topology};
use crease_core::vec3::{self, V3};
use crease_deep::cgan::data::{map_pairs, samples};
use crease_deep::cgan::{Cgan, CganConfig, Sample};
use crease_deep::normal_maps::bake::{map_normal_error, mesh_normal_error};
use crease_deep::normal_maps::raster::TexelMap;
use crease_deep::normal_maps::uv::{auto_atlas, read_obj_uv};
use crease_deep::normal_maps::{sample_vertex_normals, NormalMap};
use crease_deep::registration::{synth_scan, RegisterParams, Registration};
use crease_deep::regression::autoregress::{
    AutoregressiveLinear, ControlsAndCoefficients, ShapeHistory,
};
use crease_deep::regression::linear::LinearRegression;
use crease_deep::regression::lstm::{windows, LstmConfig, LstmRegressor};
use crease_deep::regression::pose::ControlSpec;
use crease_deep::subspace::{vertex_error, Subspace};
use crease_deep::train::{load_training_dir, TrainParams, TrainingSequence};
use std::path::{Path, PathBuf};
use std::time::Instant;

type R<T> = Result<T, Box<dyn std::error::Error>>;

fn main() -> R<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let part = args.first().map(String::as_str).unwrap_or("");
    let arg = |i: usize| args.get(i).cloned();
    match part {
        "subspace" => subspace(
            &arg(1).ok_or("DATA")?,
            &arg(2).ok_or("OUT")?,
            &arg(3).unwrap_or("seed_3".into()),
        ),
        "fitloso" => fit_loso(
            &arg(1).ok_or("DATA")?,
            &arg(2).ok_or("OUT")?,
            &arg(3).unwrap_or("raw,none,1e-3;auto,auto,1e-3".into()),
            arg(4),
        ),
        "regression" if arg(3).as_deref() == Some("all") => regression_loso(
            &arg(1).ok_or("DATA")?,
            &arg(2).ok_or("OUT")?,
            LstmShape {
                epochs: arg(4).map_or(Ok(0), |s| s.parse())?,
                layers: arg(5).map_or(Ok(2), |s| s.parse())?,
                hidden: arg(6).map_or(Ok(64), |s| s.parse())?,
            },
            arg(7).map_or(Ok(1e-3), |s| s.parse())?,
            &list(arg(8), "10,25,50")?,
            &list(arg(9), "0,5,20,50")?,
            &history_sets(arg(10))?,
            arg(11).as_deref() != Some("blend"),
        ),
        "regression" => regression(
            &arg(1).ok_or("DATA")?,
            &arg(2).ok_or("OUT")?,
            &arg(3).unwrap_or("seed_3".into()),
            LstmShape {
                epochs: arg(4).map_or(Ok(300), |s| s.parse())?,
                layers: arg(5).map_or(Ok(4), |s| s.parse())?,
                hidden: arg(6).map_or(Ok(256), |s| s.parse())?,
            },
            arg(7).map_or(Ok(1e-3), |s| s.parse())?,
            &arg(8)
                .unwrap_or("10,25,50".into())
                .split(',')
                .map(|s| s.parse())
                .collect::<Result<Vec<usize>, _>>()?,
        ),
        "cgan" => cgan(
            &arg(1).ok_or("DATA")?,
            &arg(2).ok_or("OUT")?,
            &arg(3).unwrap_or("seed_3".into()),
            &CganRun {
                epochs: arg(4).map_or(Ok(3), |s| s.parse())?,
                res: arg(5).map_or(Ok(64), |s| s.parse())?,
                filters: arg(6).map_or(Ok(16), |s| s.parse())?,
                kinds: arg(9)
                    .unwrap_or_else(|| VARIANTS.map(|v| v.1).join(","))
                    .split(',')
                    .map(String::from)
                    .collect(),
                batch: arg(10).map_or(Ok(4), |s| s.parse())?,
                budget_min: arg(11).map_or(Ok(0.0), |s| s.parse())?,
                lr: arg(12).map(|s| s.parse()).transpose()?,
            },
            arg(7).map_or(Ok(1e-3), |s| s.parse())?,
            arg(8).map_or(Ok(10), |s| s.parse())?,
        ),
        "mapbound" => mapbound(
            &arg(1).ok_or("DATA")?,
            &arg(2).unwrap_or("seed_3".into()),
            &list(arg(3), "64,128,256")?,
            arg(4).map_or(Ok(4), |s| s.parse())?,
        ),
        "register" => register(
            &arg(1).ok_or("DATA")?,
            &arg(2).ok_or("OUT")?,
            &arg(3).unwrap_or("5".into()),
            RegisterParams {
                target_points: arg(4)
                    .map_or(Ok(RegisterParams::default().target_points), |s| s.parse())?,
                min_weight: arg(5)
                    .map_or(Ok(RegisterParams::default().min_weight), |s| s.parse())?,
                iterations: arg(6)
                    .map_or(Ok(RegisterParams::default().iterations), |s| s.parse())?,
                ..register_env(RegisterParams::default())?
            },
        ),
        "detail" => detail(
            &arg(1).ok_or("DATA")?,
            &arg(2).ok_or("OUT")?,
            &arg(3).unwrap_or("all".into()),
            &list(arg(4), "40")?,
            &arg(5)
                .unwrap_or("1e-10".into())
                .split(',')
                .map(|s| s.parse())
                .collect::<Result<Vec<f64>, _>>()?,
            &list(arg(6), "128,256,512")?,
            arg(7).map_or(Ok(1), |s| s.parse())?,
        ),
        "tube" => tube_register(
            &arg(1).unwrap_or("1".into()),
            &arg(2).unwrap_or("1".into()),
            arg(3).map_or(Ok(RegisterParams::default().iterations), |s| s.parse())?,
        ),
        "lstmcheck" => lstm_check(
            &arg(1).ok_or("DATA")?,
            &arg(2).ok_or("OUT")?,
            &arg(3).unwrap_or("all".into()),
            &arg(4).unwrap_or("2x64x100".into()),
            &arg(5).unwrap_or("coef,const;shared,const;shared,cosine;shared,cosine,std".into()),
        ),
        "posenorm" => posenorm(
            &arg(1).ok_or("DATA")?,
            &arg(2).ok_or("OUT")?,
            &arg(3).unwrap_or("seed_3".into()),
            &arg(4)
                .unwrap_or("2,4".into())
                .split(',')
                .map(|s| s.parse())
                .collect::<Result<Vec<f64>, _>>()?,
            arg(5).map_or(Ok(4), |s| s.parse())?,
            arg(6).map_or(Ok(256), |s| s.parse())?,
        ),
        "posesmooth" => posesmooth(
            &arg(1).ok_or("DATA")?,
            &arg(2).ok_or("OUT")?,
            &arg(3).unwrap_or("seed_3".into()),
            &list(arg(4), "0,80,160,320,640,1280")?,
            &list(arg(5), "0,10,25,50,100")?,
            arg(6).map_or(Ok(4), |s| s.parse())?,
            arg(7).map_or(Ok(256), |s| s.parse())?,
        ),
        "posenormals" => posenormals(
            &arg(1).ok_or("DATA")?,
            &arg(2).ok_or("OUT")?,
            &arg(3).unwrap_or("seed_3".into()),
            &list(arg(4), "25,100,200")?,
            arg(5).map_or(Ok(4), |s| s.parse())?,
            arg(6).map_or(Ok(256), |s| s.parse())?,
        ),
        "params" => {
            println!("{}", serde_json::to_string(&register_env(RegisterParams::default())?)?);
            Ok(())
        }
        "score" => score(
            &arg(1).ok_or("APPLY_OUT")?,
            &arg(2).ok_or("GT")?,
            &arg(3).ok_or("CAPTURED")?,
        ),
        _ => Err("usage: deep_report subspace|regression|fitloso|cgan|mapbound|register|score|detail ...".into()),
    }
}

fn list(arg: Option<String>, default: &str) -> R<Vec<usize>> {
    Ok(arg
        .unwrap_or(default.into())
        .split(',')
        .map(|s| s.parse())
        .collect::<Result<Vec<usize>, _>>()?)
}

fn split(data: &str, held: &str) -> R<(Vec<TrainingSequence>, TrainingSequence)> {
    let mut train = Vec::new();
    let mut test = None;
    let mut names: Vec<PathBuf> = std::fs::read_dir(data)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.join("pose.json").exists())
        .collect();
    names.sort();
    for p in names {
        let s = load_training_dir(&p)?;
        if p.file_name().is_some_and(|n| n == held) {
            test = Some(s);
        } else {
            train.push(s);
        }
    }
    Ok((train, test.ok_or("held-out sequence not found")?))
}

fn mm(x: f64) -> String {
    format!("{:.2}", x * 1e3)
}

/// Mean normal error of `frames` against `fine`: at the vertices over every frame, and sampled back from
/// world-space maps of their vertex normals over the frames `idx` (the two figures the pose experiments compare).
fn normal_errors(
    topo: &Topology,
    texels: &TexelMap,
    layout: &crease_deep::normal_maps::uv::UvLayout,
    idx: &[usize],
    frames: &[Frame],
    fine: &[Frame],
) -> (f64, f64) {
    let n = frames.len();
    let mesh = (0..n)
        .map(|t| mesh_normal_error(topo, &frames[t], &fine[t]))
        .sum::<f64>()
        / n as f64;
    let map = idx
        .iter()
        .map(|&t| {
            let m = crease_deep::normal_maps::world_from_vertex_normals(
                texels,
                topo,
                &vertex_normals(topo, &frames[t]),
            );
            map_normal_error(&sample_vertex_normals(&m, topo, layout), topo, &fine[t]).0
        })
        .sum::<f64>()
        / idx.len() as f64;
    (mesh, map)
}

fn mean_err(a: &[Frame], b: &[Frame]) -> (f64, f64) {
    let e: Vec<(f64, f64)> = a.iter().zip(b).map(|(x, y)| vertex_error(x, y)).collect();
    let n = e.len() as f64;
    (
        e.iter().map(|x| x.0).sum::<f64>() / n,
        e.iter().map(|x| x.1).sum::<f64>() / n,
    )
}

fn write_json(out: &str, name: &str, v: &serde_json::Value) -> R<()> {
    std::fs::create_dir_all(out)?;
    std::fs::write(Path::new(out).join(name), serde_json::to_string_pretty(v)?)?;
    Ok(())
}

fn subspace(data: &str, out: &str, held: &str) -> R<()> {
    let (train, test) = split(data, held)?;
    let frames: Vec<&[V3]> = train
        .iter()
        .flat_map(|s| s.fine.iter().map(|f| f.as_slice()))
        .collect();
    let t0 = Instant::now();
    let full = Subspace::fit(&frames, frames.len())?;
    let fit_s = t0.elapsed().as_secs_f64();
    println!(
        "subspace of {} training frames ({} components) in {fit_s:.1} s; held out: {held}",
        frames.len(),
        full.k()
    );
    println!("| k | train mean (mm) | train p95 (mm) | held-out mean (mm) | held-out p95 (mm) |\n|---|---|---|---|---|");
    let mut rows = Vec::new();
    let train_frames: Vec<Frame> = train.iter().flat_map(|s| s.fine.iter().cloned()).collect();
    for k in [5, 10, 25, 50, 100, 200, full.k()] {
        let s = full.truncated(k);
        let rec = |f: &Frame| s.reconstruct(&s.project(f, k));
        let tr: Vec<Frame> = train_frames.iter().map(rec).collect();
        let te: Vec<Frame> = test.fine.iter().map(rec).collect();
        let (a, b) = mean_err(&tr, &train_frames);
        let (c, d) = mean_err(&te, &test.fine);
        println!("| {k} | {} | {} | {} | {} |", mm(a), mm(b), mm(c), mm(d));
        rows.push(serde_json::json!({"k": k, "train_mean_m": a, "train_p95_m": b, "heldout_mean_m": c, "heldout_p95_m": d}));
    }
    write_json(
        out,
        "subspace.json",
        &serde_json::json!({"held_out": held, "fit_s": fit_s, "rows": rows}),
    )
}

/// The LSTM rows of `regression`: training epochs (0 skips them), layers and hidden units.
#[derive(Clone, Copy)]
struct LstmShape {
    epochs: usize,
    layers: usize,
    hidden: usize,
}

fn regression(
    data: &str,
    out: &str,
    held: &str,
    lstm: LstmShape,
    ridge: f64,
    ar_states: &[usize],
) -> R<()> {
    let LstmShape {
        epochs,
        layers,
        hidden,
    } = lstm;
    let (train, test) = split(data, held)?;
    let frames: Vec<&[V3]> = train
        .iter()
        .flat_map(|s| s.fine.iter().map(|f| f.as_slice()))
        .collect();
    let k = 200;
    let sub = Subspace::fit(&frames, k)?;
    let k = sub.k();
    let pose_refs: Vec<&[Vec<f64>]> = train.iter().map(|s| s.poses.as_slice()).collect();
    let mut rows = Vec::new();
    println!("held out: {held}; subspace k = {k}");
    println!("| regressor | coefficient MSE (m²) | held-out vertex error mean (mm) | p95 (mm) | normal error (°) | captured normal error (°) | fit s |\n|---|---|---|---|---|---|---|");
    let truth: Vec<Vec<f64>> = test.fine.iter().map(|f| sub.project(f, k)).collect();
    let topo = test.topology.clone();
    let captured_ne: f64 = test
        .fine
        .iter()
        .zip(&test.coarse)
        .map(|(g, c)| mesh_normal_error(&topo, g, c))
        .sum::<f64>()
        / test.fine.len() as f64;
    let report = |name: &str, pred: Vec<Vec<f64>>, secs: f64, rows: &mut Vec<serde_json::Value>| {
        let mse = pred
            .iter()
            .zip(&truth)
            .map(|(p, t)| p.iter().zip(t).map(|(a, b)| (a - b).powi(2)).sum::<f64>() / k as f64)
            .sum::<f64>()
            / pred.len() as f64;
        let shapes: Vec<Frame> = pred.iter().map(|c| sub.reconstruct(c)).collect();
        let (m, p) = mean_err(&shapes, &test.fine);
        let ne = shapes
            .iter()
            .zip(&test.fine)
            .map(|(s, g)| mesh_normal_error(&topo, s, g))
            .sum::<f64>()
            / shapes.len() as f64;
        println!(
            "| {name} | {mse:.3e} | {} | {} | {ne:.2} | {captured_ne:.2} | {secs:.1} |",
            mm(m),
            mm(p)
        );
        rows.push(serde_json::json!({"regressor": name, "coeff_mse": mse, "vertex_mean_m": m, "vertex_p95_m": p, "normal_error_deg": ne, "captured_normal_error_deg": captured_ne, "fit_s": secs}));
    };
    report(
        "subspace projection (oracle)",
        truth.clone(),
        0.0,
        &mut rows,
    );
    for (name, lags) in [
        ("linear, pose+vel+acc", vec![]),
        ("linear, + pose lags 1..32", vec![1, 2, 4, 8, 16, 32]),
    ] {
        let spec = ControlSpec::fit(&pose_refs, lags)?;
        let mut c = Vec::new();
        let mut t = Vec::new();
        for s in &train {
            c.extend(spec.controls(&s.poses)?);
            t.extend(s.fine.iter().map(|f| sub.project(f, k)));
        }
        let t0 = Instant::now();
        let reg = LinearRegression::fit(&c, &t, ridge)?;
        let secs = t0.elapsed().as_secs_f64();
        let pred: Vec<Vec<f64>> = spec
            .controls(&test.poses)?
            .iter()
            .map(|c| reg.predict(c))
            .collect();
        report(name, pred, secs, &mut rows);
    }
    // Autoregressive linear (§3.3 with α_{t−1}, α_{t−2} in the control vector), rolled out from the first
    // frame; one-step (teacher-forced) rows show how much of the error the rollout adds.
    let spec = ControlSpec::fit(&pose_refs, vec![1, 2, 4, 8, 16, 32])?;
    let train_c: Vec<Vec<Vec<f64>>> = train
        .iter()
        .map(|s| spec.controls(&s.poses))
        .collect::<Result<_, _>>()?;
    let train_a: Vec<Vec<Vec<f64>>> = train
        .iter()
        .map(|s| s.fine.iter().map(|f| sub.project(f, k)).collect())
        .collect();
    let tc = spec.controls(&test.poses)?;
    let seqs: Vec<ControlsAndCoefficients> = train_c
        .iter()
        .zip(&train_a)
        .map(|(c, a)| (c.as_slice(), a.as_slice()))
        .collect();
    let a_refs: Vec<&[Vec<f64>]> = train_a.iter().map(|a| a.as_slice()).collect();
    let mut best: Option<(f64, usize, usize)> = None;
    for k_state in ar_states.iter().copied() {
        for dagger in [0usize, 3] {
            let hist = ShapeHistory::fit(&a_refs, k_state.min(k), 2)?;
            let t0 = Instant::now();
            let ar = AutoregressiveLinear::fit(&seqs, hist, ridge, dagger)?;
            let secs = t0.elapsed().as_secs_f64();
            if dagger == 0 {
                report(
                    &format!(
                        "AR linear, state {k_state}, one step (teacher-forced, not a forecast)"
                    ),
                    ar.one_step(&tc, &truth),
                    secs,
                    &mut rows,
                );
            }
            let pred = ar.rollout(&tc);
            let e = mean_err(
                &pred.iter().map(|c| sub.reconstruct(c)).collect::<Vec<_>>(),
                &test.fine,
            )
            .0;
            if best.is_none_or(|b| e < b.0) {
                best = Some((e, k_state, dagger));
            }
            report(
                &format!("AR linear, state {k_state}, DAgger {dagger}, rollout"),
                pred,
                secs,
                &mut rows,
            );
        }
    }
    let mut lstm_notes = Vec::new();
    // epochs = 0 skips the LSTMs (the linear rows take seconds, the LSTMs minutes).
    if epochs > 0 {
        let data = LstmData {
            train_c: &train_c,
            train_a: &train_a,
            controls: &tc,
            truth: &truth,
            k,
        };
        let (pred, note) = lstm_pose_only(&data, layers, hidden, epochs)?;
        report(
            &format!("LSTM {layers}x{hidden}, pose only, seq 3, {epochs} epochs"),
            pred,
            note["s_per_epoch"].as_f64().unwrap_or(0.0) * epochs as f64,
            &mut rows,
        );
        lstm_notes.push(note);
        if let Some((_, k_state, _)) = best {
            let hist = ShapeHistory::fit(&a_refs, k_state.min(k), 2)?;
            let (pred, note) = lstm_autoregressive(&data, &hist, layers, hidden, epochs)?;
            report(
                &format!("LSTM {layers}x{hidden}, AR state {k_state}, DAgger 1, rollout, {epochs}+{} epochs", epochs / 3),
                pred,
                note["s_per_epoch"].as_f64().unwrap_or(0.0) * (epochs + epochs / 3) as f64,
                &mut rows,
            );
            lstm_notes.push(note);
        }
    }
    write_json(
        out,
        "regression.json",
        &serde_json::json!({"held_out": held, "k": k, "ridge": ridge, "rows": rows, "lstm": lstm_notes}),
    )
}

/// Names of the sequences under DATA (directories with a pose.json), sorted.
fn sequence_names(data: &str) -> R<Vec<String>> {
    let mut names: Vec<String> = std::fs::read_dir(data)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.join("pose.json").exists())
        .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .collect();
    names.sort();
    Ok(names)
}

/// Leave-one-sequence-out over every sequence under DATA: each held out in turn, the models fitted on the
/// others (subspace k = 200), pose-only vertex error (mean and p95 per frame, averaged over its frames) and
/// coefficient MSE per split and the mean over splits, by which the defaults are chosen. The autoregressive
/// rows are the ridge (teacher-forced) fit and the rollout fit after each listed number of iterations, once
/// per control vector: pose + velocity + acceleration, and that plus each listed set of decayed pose history
/// time constants. With `extras` false only the linear, autoregressive and blend rows are computed (the nearest
/// neighbours and the spectral-radius experiments are skipped).
#[allow(clippy::too_many_arguments)]
fn regression_loso(
    data: &str,
    out: &str,
    lstm: LstmShape,
    ridge: f64,
    ar_states: &[usize],
    iterations: &[usize],
    histories: &[Vec<f64>],
    extras: bool,
) -> R<()> {
    let names = sequence_names(data)?;
    let mut table: Vec<(String, Vec<Scores>)> = Vec::new();
    let mut add =
        |split: usize, name: String, e: Scores| match table.iter_mut().find(|(n, _)| *n == name) {
            Some((_, v)) => v.push(e),
            None => {
                assert_eq!(split, 0, "row {name} missing from an earlier split");
                table.push((name, vec![e]));
            }
        };
    let max_iter = iterations.iter().copied().max().unwrap_or(0);
    let mut notes = Vec::new();
    for (si, held) in names.iter().enumerate() {
        let t_split = Instant::now();
        let (train, test) = split(data, held)?;
        let frames: Vec<&[V3]> = train
            .iter()
            .flat_map(|s| s.fine.iter().map(|f| f.as_slice()))
            .collect();
        let sub = Subspace::fit(&frames, 200)?;
        let k = sub.k();
        let truth: Vec<Vec<f64>> = test.fine.iter().map(|f| sub.project(f, k)).collect();
        let err = |pred: &[Vec<f64>]| scores(&sub, pred, &truth, &test.fine);
        add(si, "subspace projection of gt (bound)".into(), err(&truth));
        let pose_refs: Vec<&[Vec<f64>]> = train.iter().map(|s| s.poses.as_slice()).collect();
        let train_a: Vec<Vec<Vec<f64>>> = train
            .iter()
            .map(|s| s.fine.iter().map(|f| sub.project(f, k)).collect())
            .collect();
        let a_refs: Vec<&[Vec<f64>]> = train_a.iter().map(|a| a.as_slice()).collect();
        // (row label, pose lags, history time constants, with autoregressive rows)
        let mut variants: Vec<(String, Vec<usize>, Vec<f64>, bool)> = vec![
            ("pose+vel+acc".into(), vec![], vec![], true),
            (
                "pose lags 1..32".into(),
                vec![1, 2, 4, 8, 16, 32],
                vec![],
                false,
            ),
        ];
        for h in histories.iter().filter(|h| !h.is_empty()) {
            let taus: Vec<String> = h.iter().map(|t| format!("{t}")).collect();
            variants.push((
                format!("decayed pose history τ = {}", taus.join(",")),
                vec![],
                h.clone(),
                true,
            ));
        }
        for (ctl, lags, taus, with_ar) in &variants {
            let spec =
                ControlSpec::fit(&pose_refs, lags.clone())?.with_history(&pose_refs, taus)?;
            let train_c: Vec<Vec<Vec<f64>>> = train
                .iter()
                .map(|s| spec.controls(&s.poses))
                .collect::<Result<_, _>>()?;
            let tc = spec.controls(&test.poses)?;
            let reg = LinearRegression::fit(&train_c.concat(), &train_a.concat(), ridge)?;
            let pred: Vec<Vec<f64>> = tc.iter().map(|c| reg.predict(c)).collect();
            add(si, format!("linear, {ctl}"), err(&pred));
            if extras {
                add(
                    si,
                    format!("5 nearest neighbours, {ctl}"),
                    err(&nearest_neighbours(
                        &train_c.concat(),
                        &train_a.concat(),
                        &tc,
                        5,
                    )),
                );
            }
            if !with_ar {
                continue;
            }
            let seqs: Vec<ControlsAndCoefficients> = train_c
                .iter()
                .zip(&train_a)
                .map(|(c, a)| (c.as_slice(), a.as_slice()))
                .collect();
            for &k_state in ar_states {
                let hist = ShapeHistory::fit(&a_refs, k_state.min(k), 2)?;
                let mut ar = AutoregressiveLinear::fit(&seqs, hist, ridge, 0)?;
                add(
                    si,
                    format!("AR state {k_state}, {ctl}, one step with the true history (not a forecast)"),
                    err(&ar.one_step(&tc, &truth)),
                );
                let mut rows_here: Vec<(usize, Scores)> = Vec::new();
                if iterations.contains(&0) {
                    rows_here.push((0, err(&ar.rollout(&tc))));
                }
                let t0 = Instant::now();
                let report = crease_deep::regression::rollout_fit::refine(
                    &mut ar,
                    &seqs,
                    ridge,
                    max_iter,
                    |i, m| {
                        if iterations.contains(&i) {
                            rows_here.push((i, err(&m.rollout(&tc))));
                        }
                    },
                )?;
                let secs = t0.elapsed().as_secs_f64();
                // A fit that stalled before an iteration count keeps its final model for that count.
                let final_e = err(&ar.rollout(&tc));
                for &n in iterations {
                    let e = rows_here.iter().find(|r| r.0 == n).map_or(final_e, |r| r.1);
                    let label = if n == 0 {
                        format!("AR state {k_state}, {ctl}, ridge fit, rollout")
                    } else {
                        format!("AR state {k_state}, {ctl}, rollout fit {n} it., rollout")
                    };
                    add(si, label, e);
                }
                // The rollout fit constrained to a stable recurrence: projected after every step, so the
                // remaining weights can make up for what the projection takes.
                for bound in [0.98, 0.95].into_iter().filter(|_| extras) {
                    let hist = ShapeHistory::fit(&a_refs, k_state.min(k), 2)?;
                    let mut stable = AutoregressiveLinear::fit(&seqs, hist, ridge, 0)?;
                    crease_deep::regression::stable_state::project(&mut stable, bound)?;
                    for _ in 0..max_iter {
                        crease_deep::regression::rollout_fit::refine(
                            &mut stable,
                            &seqs,
                            ridge,
                            1,
                            |_, _| {},
                        )?;
                        crease_deep::regression::stable_state::project(&mut stable, bound)?;
                    }
                    add(
                        si,
                        format!("AR state {k_state}, {ctl}, rollout fit {max_iter} it. projected to spectral radius ≤ {bound} after every step, rollout"),
                        err(&stable.rollout(&tc)),
                    );
                }
                // An even blend of the pose-only map and the rollout: whether their errors cancel.
                let rolled = ar.rollout(&tc);
                let blend: Vec<Vec<f64>> = pred
                    .iter()
                    .zip(&rolled)
                    .map(|(a, b)| a.iter().zip(b).map(|(x, y)| 0.5 * (x + y)).collect())
                    .collect();
                add(
                    si,
                    format!(
                        "mean of linear and AR state {k_state} rollout fit {max_iter} it., {ctl}"
                    ),
                    err(&blend),
                );
                // The stored blend regressor: its weight from an inner leave-one-out over the training
                // sequences (crease_deep::train::inner_blend_weight, `crease deep train --blend-fit`), and for
                // comparison the weight that would have been best on the held-out sequence itself.
                let params = TrainParams {
                    ridge,
                    ar_state: k_state,
                    ar_rollout_iters: max_iter,
                    ..Default::default()
                };
                let t_inner = Instant::now();
                let inner = crease_deep::train::inner_blend_weight(&seqs, &params, k)?;
                let inner_s = t_inner.elapsed().as_secs_f64();
                add(
                    si,
                    format!("blend, inner leave-one-out weight, AR state {k_state} rollout fit {max_iter} it., {ctl}"),
                    err(&crease_deep::regression::blend::mix(&pred, &rolled, inner.weight)),
                );
                let mut oracle = crease_deep::regression::blend::WeightFit::default();
                oracle.add(&pred, &rolled, &truth);
                add(
                    si,
                    format!("blend, weight fitted on the held-out sequence (not a forecast), AR state {k_state}, {ctl}"),
                    err(&crease_deep::regression::blend::mix(&pred, &rolled, oracle.weight())),
                );
                eprintln!(
                    "{held}: blend weight: inner leave-one-out {:.3} (folds {:?}, {inner_s:.1} s), best on the held-out sequence {:.3}",
                    inner.weight, inner.fold_weights, oracle.weight()
                );
                notes.push(serde_json::json!({"held_out": held, "controls": ctl, "k_state": k_state, "blend_inner": inner, "blend_oracle": oracle.weight(), "inner_s": inner_s}));
                // The fitted recurrence's spectral radius, and the rollout with it projected below a bound
                // (stable_state.rs): whether drift comes from an unstable state map.
                let rho = crease_deep::regression::stable_state::spectral_radius(&ar)?;
                for bound in [0.95, 0.9, 0.8].into_iter().filter(|_| extras) {
                    let mut stable = ar.clone();
                    crease_deep::regression::stable_state::project(&mut stable, bound)?;
                    add(
                        si,
                        format!("AR state {k_state}, {ctl}, rollout fit {max_iter} it., spectral radius ≤ {bound}, rollout"),
                        err(&stable.rollout(&tc)),
                    );
                }
                eprintln!(
                    "{held}: AR state {k_state}, {ctl}: spectral radius {rho:.3}; rollout loss {:.3e} -> {:.3e} in {} iterations, {secs:.1} s{}",
                    report.losses[0],
                    report.losses[report.losses.len() - 1],
                    report.losses.len() - 1,
                    if report.stalled { " (stalled)" } else { "" }
                );
                notes.push(serde_json::json!({"held_out": held, "controls": ctl, "k_state": k_state, "spectral_radius": rho, "rollout_losses": report.losses, "stalled": report.stalled, "fit_s": secs}));
            }
        }
        if lstm.epochs > 0 {
            // The networks get the paper's control vector (pose, velocity, acceleration) and, for the
            // autoregressive one, the default regressor's fed-back state (10 coefficients).
            let spec = ControlSpec::fit(&pose_refs, vec![])?;
            let train_c: Vec<Vec<Vec<f64>>> = train
                .iter()
                .map(|s| spec.controls(&s.poses))
                .collect::<Result<_, _>>()?;
            let tc = spec.controls(&test.poses)?;
            for (name, e, note) in
                loso_lstm(&train_c, &train_a, &tc, &truth, &a_refs, k, &lstm, &err)?
            {
                add(si, name, e);
                notes.push(serde_json::json!({"held_out": held, "lstm": note}));
            }
        }
        eprintln!("{held} held out: {:.1} s", t_split.elapsed().as_secs_f64());
    }
    print!("| pose-only regressor |");
    for n in &names {
        print!(" {n} held out: mean / p95 (mm), MSE (m²) |");
    }
    println!(" mean over splits (mm) | p95 over splits (mm) | MSE over splits (m²) |");
    println!("|---|{}---|---|---|", "---|".repeat(names.len()));
    let mut rows = Vec::new();
    for (name, v) in &table {
        let avg = |f: fn(&Scores) -> f64| v.iter().map(f).sum::<f64>() / v.len() as f64;
        let (mean, p95, mse) = (avg(|e| e.mean), avg(|e| e.p95), avg(|e| e.mse));
        print!("| {name} |");
        for e in v {
            print!(" {} / {}, {:.2e} |", mm(e.mean), mm(e.p95), e.mse);
        }
        println!(" {} | {} | {mse:.2e} |", mm(mean), mm(p95));
        rows.push(serde_json::json!({"regressor": name, "per_split_mean_m": v.iter().map(|e| e.mean).collect::<Vec<_>>(), "per_split_p95_m": v.iter().map(|e| e.p95).collect::<Vec<_>>(), "per_split_coeff_mse": v.iter().map(|e| e.mse).collect::<Vec<_>>(), "mean_m": mean, "p95_m": p95, "coeff_mse": mse}));
    }
    write_json(
        out,
        "regression_loso.json",
        &serde_json::json!({"splits": names, "ridge": ridge, "rows": rows, "fits": notes}),
    )
}

/// Leave one sequence out through `crease deep train`'s own fit ([`crease_deep::train::fit`]: the subspace,
/// the pose features, the mirror augmentation and every regressor as the model stores them): per variant
/// (`features,mirror,ridge` with `--pose-features`, `--mirror` and `--ridge` values, optionally
/// `,lstm LxHxE` for an LSTM of L layers × H units trained E epochs), the pose-only vertex error of the
/// linear, autoregressive, blend (and LSTM) regressors on each held-out sequence, and the bound of the fitted
/// subspace (projection of the held-out gt).
fn fit_loso(data: &str, out: &str, variants: &str, held_only: Option<String>) -> R<()> {
    use crease_deep::model::RegressorKind;
    let mut names = sequence_names(data)?;
    // Optional comma-separated list of the splits to run (their held-out sequences), e.g. "seed_3": a large
    // network's splits one at a time on a slow machine.
    if let Some(only) = held_only {
        let keep: Vec<&str> = only.split(',').map(str::trim).collect();
        names.retain(|n| keep.contains(&n.as_str()));
    }
    let mut table: Vec<(String, Vec<Scores>)> = Vec::new();
    let mut notes = Vec::new();
    for (si, held) in names.iter().enumerate() {
        let (train, test) = split(data, held)?;
        for v in variants.split(';').filter(|v| !v.trim().is_empty()) {
            let f: Vec<&str> = v.split(',').map(str::trim).collect();
            let mut params = TrainParams {
                pose_features: f.first().copied().unwrap_or("auto").parse()?,
                mirror: f.get(1).copied().unwrap_or("auto").parse()?,
                ridge: f.get(2).map_or(Ok(1e-3), |r| r.parse())?,
                ..Default::default()
            };
            if let Some(l) = f.get(3).and_then(|l| l.strip_prefix("lstm ")) {
                let n: Vec<usize> = l.split('x').map(|x| x.parse()).collect::<Result<_, _>>()?;
                params.regressor = RegressorKind::Lstm;
                // Optional: residual base (none|linear|autoregressive|blend), cross-fit (cf|in),
                // early stopping (es|all), learning rate.
                params.lstm = LstmConfig {
                    layers: n[0],
                    hidden: n[1],
                    epochs: n[2],
                    residual_of: match f.get(4).copied().unwrap_or("none") {
                        "none" => None,
                        k => Some(k.parse()?),
                    },
                    cross_fit: f.get(5).copied() == Some("cf"),
                    early_stopping: f.get(6).copied() == Some("es"),
                    lr: f.get(7).map_or(Ok(2e-3), |r| r.parse())?,
                    ..lstm_config(n[0], n[1], n[2])
                };
            }
            let t0 = Instant::now();
            let fitted =
                crease_deep::train::fit(&train, &params, &crease_core::progress::NoProgress)?;
            let fit_s = t0.elapsed().as_secs_f64();
            eprintln!(
                "{held} held out, {v}: fit {fit_s:.0} s, LSTM {:.1} s/epoch, kept epoch {:?}, held-out MSE {:?}",
                fitted.seconds.lstm_s_per_epoch, fitted.lstm_best_epoch, fitted.lstm_held_out
            );
            let sub = &fitted.subspace;
            let k = sub.k();
            let truth: Vec<Vec<f64>> = test.fine.iter().map(|fr| sub.project(fr, k)).collect();
            let mut kinds = vec![
                RegressorKind::Linear,
                RegressorKind::Autoregressive,
                RegressorKind::Blend,
            ];
            if fitted.lstm.is_some() {
                kinds.push(RegressorKind::Lstm);
            }
            let mut rows = vec![(
                format!("{v}: subspace projection of gt (bound)"),
                scores(sub, &truth, &truth, &test.fine),
            )];
            for kind in kinds {
                let pred = fitted.coefficients(kind, &test.poses)?;
                rows.push((
                    format!("{v}: {}", kind.name()),
                    scores(sub, &pred, &truth, &test.fine),
                ));
            }
            for (name, e) in rows {
                eprintln!(
                    "{held} held out, {name}: {} mm (p95 {})",
                    mm(e.mean),
                    mm(e.p95)
                );
                match table.iter_mut().find(|(n, _)| *n == name) {
                    Some((_, r)) => r.push(e),
                    None => {
                        assert_eq!(si, 0, "row {name} missing from an earlier split");
                        table.push((name, vec![e]));
                    }
                }
            }
            notes.push(serde_json::json!({"held_out": held, "variant": v, "k": k, "fit_s": fit_s,
                "features": fitted.control.features, "mirror": fitted.mirror.as_ref().map(|r| (r.axis_name(), r.asymmetry)),
                "ar_rollout_losses": [fitted.ar_rollout_losses.first(), fitted.ar_rollout_losses.last()],
                "lstm_final_loss": fitted.lstm_losses.last(), "lstm_s_per_epoch": fitted.seconds.lstm_s_per_epoch,
                "lstm_best_epoch": fitted.lstm_best_epoch, "lstm_held_out": fitted.lstm_held_out}));
        }
    }
    print!("| variant: regressor |");
    for n in &names {
        print!(" {n} held out: mean / p95 (mm) |");
    }
    println!(" mean over splits (mm) | p95 (mm) | coefficient MSE (m²) |");
    println!("|---|{}---|---|---|", "---|".repeat(names.len()));
    let mut rows = Vec::new();
    for (name, v) in &table {
        let avg = |f: fn(&Scores) -> f64| v.iter().map(f).sum::<f64>() / v.len() as f64;
        let (mean, p95, mse) = (avg(|e| e.mean), avg(|e| e.p95), avg(|e| e.mse));
        print!("| {name} |");
        for e in v {
            print!(" {} / {} |", mm(e.mean), mm(e.p95));
        }
        println!(" {} | {} | {mse:.2e} |", mm(mean), mm(p95));
        rows.push(serde_json::json!({"row": name, "per_split_mean_m": v.iter().map(|e| e.mean).collect::<Vec<_>>(), "mean_m": mean, "p95_m": p95, "coeff_mse": mse}));
    }
    write_json(
        out,
        "fit_loso.json",
        &serde_json::json!({"splits": names, "rows": rows, "fits": notes}),
    )
}

/// One regressor's errors on one held-out sequence: vertex error mean and p95 (m, per frame, averaged over
/// its frames) and coefficient MSE (m², averaged over the coefficients and frames).
#[derive(Clone, Copy)]
struct Scores {
    mean: f64,
    p95: f64,
    mse: f64,
}

fn scores(sub: &Subspace, pred: &[Vec<f64>], truth: &[Vec<f64>], fine: &[Frame]) -> Scores {
    let (mean, p95) = mean_err(
        &pred.iter().map(|c| sub.reconstruct(c)).collect::<Vec<_>>(),
        fine,
    );
    let mse = pred
        .iter()
        .zip(truth)
        .map(|(p, t)| p.iter().zip(t).map(|(a, b)| (a - b).powi(2)).sum::<f64>() / p.len() as f64)
        .sum::<f64>()
        / pred.len() as f64;
    Scores { mean, p95, mse }
}

/// Local regression in control space: each frame's coefficients are the inverse-distance weighted mean of
/// those of its `n` nearest training frames, distances over the standardised control vectors.
fn nearest_neighbours(
    train: &[Vec<f64>],
    targets: &[Vec<f64>],
    query: &[Vec<f64>],
    n: usize,
) -> Vec<Vec<f64>> {
    let norm = Standardizer::fit(train.iter());
    let xs = norm.apply_all(train);
    query
        .iter()
        .map(|q| {
            let q = norm.apply(q);
            let mut d: Vec<(f64, usize)> = xs
                .iter()
                .enumerate()
                .map(|(i, x)| {
                    (
                        x.iter()
                            .zip(&q)
                            .map(|(a, b)| (a - b).powi(2))
                            .sum::<f64>()
                            .sqrt(),
                        i,
                    )
                })
                .collect();
            d.sort_by(|a, b| a.0.total_cmp(&b.0));
            let near = &d[..n.min(d.len())];
            let w: Vec<f64> = near.iter().map(|(di, _)| 1.0 / (di + 1e-9)).collect();
            let total: f64 = w.iter().sum();
            let mut out = vec![0.0; targets[0].len()];
            for ((_, i), wi) in near.iter().zip(&w) {
                for (o, t) in out.iter_mut().zip(&targets[*i]) {
                    *o += wi / total * t;
                }
            }
            out
        })
        .collect()
}

/// Sets of decayed pose history time constants: `none;3,10,30;5,20` (`none` or empty: no history).
fn history_sets(arg: Option<String>) -> R<Vec<Vec<f64>>> {
    arg.unwrap_or("none".into())
        .split(';')
        .map(|set| {
            if set.is_empty() || set == "none" {
                Ok(vec![])
            } else {
                set.split(',')
                    .map(|t| t.parse::<f64>().map_err(|e| e.into()))
                    .collect()
            }
        })
        .collect()
}

/// What the LSTM rows train on and are evaluated with: per training sequence the control vectors and true
/// coefficients, and the held-out sequence's controls and true coefficients.
struct LstmData<'a> {
    train_c: &'a [Vec<Vec<f64>>],
    train_a: &'a [Vec<Vec<f64>>],
    controls: &'a [Vec<f64>],
    truth: &'a [Vec<f64>],
    k: usize,
}

impl LstmData<'_> {
    /// Training standard deviation of each coefficient (the networks' output units).
    fn scale(&self) -> Vec<f64> {
        let n = self.train_a.iter().map(|a| a.len()).sum::<usize>() as f64;
        (0..self.k)
            .map(|j| {
                (self
                    .train_a
                    .iter()
                    .flatten()
                    .map(|t| t[j] * t[j])
                    .sum::<f64>()
                    / n)
                    .sqrt()
                    .max(1e-9)
            })
            .collect()
    }
}

fn lstm_config(layers: usize, hidden: usize, epochs: usize) -> LstmConfig {
    LstmConfig {
        layers,
        hidden,
        seq_len: 3,
        epochs,
        batch: 16,
        lr: 2e-3,
        seed: 1,
        residual_of: None,
        cross_fit: false,
        early_stopping: false,
    }
}

/// Cosine decay from `top` to 1e-5 over `epochs`.
fn cosine(top: f64, epochs: usize) -> impl Fn(usize) -> f64 {
    move |e: usize| {
        let x = e as f64 / epochs.max(1) as f64;
        1e-5 + 0.5 * (top - 1e-5) * (1.0 + (std::f64::consts::PI * x).cos())
    }
}

fn log_every_25(name: &'static str) -> impl FnMut(usize, f64) {
    move |e: usize, l: f64| {
        if (e + 1).is_multiple_of(25) {
            eprintln!("{name} epoch {}: {l:.5}", e + 1)
        }
    }
}

/// LSTM from pose alone: inputs standardised, outputs in units of each coefficient's standard deviation,
/// cosine learning-rate decay. Returns the held-out predictions and a note with the losses and timing.
fn lstm_pose_only(
    d: &LstmData,
    layers: usize,
    hidden: usize,
    epochs: usize,
) -> R<(Vec<Vec<f64>>, serde_json::Value)> {
    let norm = Standardizer::fit(d.train_c.iter().flatten());
    let mut data_w = Vec::new();
    for (c, a) in d.train_c.iter().zip(d.train_a) {
        data_w.extend(windows(&norm.apply_all(c), a, 3));
    }
    let in_dim = d.controls[0].len();
    let mut net = LstmRegressor::new(lstm_config(layers, hidden, epochs), in_dim, d.k, d.scale())?;
    let t0 = Instant::now();
    let losses = net.train_scheduled(
        &data_w,
        cosine(2e-3, epochs),
        log_every_25("lstm pose-only"),
    )?;
    let secs = t0.elapsed().as_secs_f64();
    let pred = net.predict(&windows(&norm.apply_all(d.controls), d.truth, 3))?;
    eprintln!(
        "LSTM pose-only: {:.2} s/epoch; loss {:.4} -> {:.4}",
        secs / epochs.max(1) as f64,
        losses[0],
        losses[losses.len() - 1]
    );
    Ok((
        pred,
        serde_json::json!({"net": "pose only", "s_per_epoch": secs / epochs.max(1) as f64, "losses": losses}),
    ))
}

/// Autoregressive LSTM: [controls, shape history] standardised, teacher-forced training, then one DAgger
/// round (the histories of its own rollouts over the training sequences added, fine-tuned for a third of the
/// epochs), evaluated rolled out from the first frame.
fn lstm_autoregressive(
    d: &LstmData,
    hist: &ShapeHistory,
    layers: usize,
    hidden: usize,
    epochs: usize,
) -> R<(Vec<Vec<f64>>, serde_json::Value)> {
    let aug: Vec<Vec<Vec<f64>>> = d
        .train_c
        .iter()
        .zip(d.train_a)
        .map(|(c, a)| {
            (0..c.len())
                .map(|t| [c[t].clone(), hist.features(a, t)].concat())
                .collect()
        })
        .collect();
    let norm = Standardizer::fit(aug.iter().flatten());
    let in_dim = aug[0][0].len();
    let teacher = |hists: &[Vec<Vec<f64>>]| -> Vec<crease_deep::regression::lstm::Window> {
        let mut w = Vec::new();
        for ((c, a), h) in d.train_c.iter().zip(d.train_a).zip(hists) {
            let x: Vec<Vec<f64>> = (0..c.len())
                .map(|t| norm.apply(&[c[t].clone(), hist.features(h, t)].concat()))
                .collect();
            w.extend(windows(&x, a, 3));
        }
        w
    };
    let mut data_w = teacher(d.train_a);
    let mut net = LstmRegressor::new(lstm_config(layers, hidden, epochs), in_dim, d.k, d.scale())?;
    let t0 = Instant::now();
    let mut losses = net.train_scheduled(&data_w, cosine(2e-3, epochs), log_every_25("lstm AR"))?;
    let rolled: Vec<Vec<Vec<f64>>> = d
        .train_c
        .iter()
        .map(|c| lstm_ar_rollout(&net, hist, &norm, c))
        .collect::<Result<_, _>>()?;
    data_w.extend(teacher(&rolled));
    let tail = epochs / 3;
    net.config.epochs = tail.max(1);
    losses.extend(net.train_scheduled(
        &data_w,
        cosine(5e-4, tail),
        log_every_25("lstm AR dagger"),
    )?);
    let secs = t0.elapsed().as_secs_f64();
    let pred = lstm_ar_rollout(&net, hist, &norm, d.controls)?;
    eprintln!(
        "LSTM AR: {:.2} s/epoch; loss {:.4} -> {:.4}",
        secs / (epochs + tail).max(1) as f64,
        losses[0],
        losses[losses.len() - 1]
    );
    Ok((
        pred,
        serde_json::json!({"net": "autoregressive", "k_state": hist.k_state, "s_per_epoch": secs / (epochs + tail).max(1) as f64, "losses": losses}),
    ))
}

/// The two LSTM rows of one leave-one-sequence-out split (pose only; autoregressive with state 10), with
/// their training notes (losses, seconds per epoch).
#[allow(clippy::too_many_arguments)]
fn loso_lstm(
    train_c: &[Vec<Vec<f64>>],
    train_a: &[Vec<Vec<f64>>],
    controls: &[Vec<f64>],
    truth: &[Vec<f64>],
    a_refs: &[&[Vec<f64>]],
    k: usize,
    shape: &LstmShape,
    err: &dyn Fn(&[Vec<f64>]) -> Scores,
) -> R<Vec<(String, Scores, serde_json::Value)>> {
    let d = LstmData {
        train_c,
        train_a,
        controls,
        truth,
        k,
    };
    let LstmShape {
        epochs,
        layers,
        hidden,
    } = *shape;
    let (pred, note) = lstm_pose_only(&d, layers, hidden, epochs)?;
    let mut rows = vec![(
        format!("LSTM {layers}x{hidden}, pose+vel+acc, seq 3, {epochs} epochs"),
        err(&pred),
        note,
    )];
    let hist = ShapeHistory::fit(a_refs, 10.min(k), 2)?;
    let (pred, note) = lstm_autoregressive(&d, &hist, layers, hidden, epochs)?;
    rows.push((
        format!(
            "LSTM {layers}x{hidden}, AR state 10, pose+vel+acc, seq 3, DAgger 1, rollout, {epochs}+{} epochs",
            epochs / 3
        ),
        err(&pred),
        note,
    ));
    Ok(rows)
}

/// Per-dimension standardisation of the LSTM inputs (constant dimensions pass through centred).
struct Standardizer {
    mean: Vec<f64>,
    inv_std: Vec<f64>,
}

impl Standardizer {
    fn fit<'a>(rows: impl Iterator<Item = &'a Vec<f64>>) -> Self {
        let rows: Vec<&Vec<f64>> = rows.collect();
        let n = rows.len() as f64;
        let d = rows[0].len();
        let mean: Vec<f64> = (0..d)
            .map(|j| rows.iter().map(|r| r[j]).sum::<f64>() / n)
            .collect();
        let inv_std = (0..d)
            .map(|j| {
                let v = rows.iter().map(|r| (r[j] - mean[j]).powi(2)).sum::<f64>() / n;
                if v > 1e-18 {
                    1.0 / v.sqrt()
                } else {
                    0.0
                }
            })
            .collect();
        Standardizer { mean, inv_std }
    }
    fn apply(&self, r: &[f64]) -> Vec<f64> {
        r.iter()
            .zip(&self.mean)
            .zip(&self.inv_std)
            .map(|((x, m), s)| (x - m) * s)
            .collect()
    }
    fn apply_all(&self, rs: &[Vec<f64>]) -> Vec<Vec<f64>> {
        rs.iter().map(|r| self.apply(r)).collect()
    }
}

/// Rollout of an autoregressive LSTM whose inputs are standardised [controls, shape history].
fn lstm_ar_rollout(
    net: &LstmRegressor,
    hist: &ShapeHistory,
    norm: &Standardizer,
    controls: &[Vec<f64>],
) -> R<Vec<Vec<f64>>> {
    let len = net.config.seq_len;
    let mut out: Vec<Vec<f64>> = Vec::with_capacity(controls.len());
    let mut xs: Vec<Vec<f64>> = Vec::with_capacity(controls.len());
    for t in 0..controls.len() {
        xs.push(norm.apply(&[controls[t].clone(), hist.features(&out, t)].concat()));
        let w = crease_deep::regression::lstm::Window {
            controls: (0..len)
                .map(|i| xs[(t + i + 1).saturating_sub(len)].clone())
                .collect(),
            targets: vec![vec![0.0; net.out_dim]; len],
        };
        out.extend(net.predict(std::slice::from_ref(&w))?);
    }
    Ok(out)
}

/// Pixel-wise errors of Eq. 4 on held-out frames: mean |G(x_t) − y_t| and |mean(G(x_t) − y_{t−1})| over
/// covered texel channels, plus the DESIGN §9 normal error of the maps sampled at the vertices.
fn eval_maps(preds: &[NormalMap], pairs: &[(NormalMap, NormalMap)]) -> (f64, f64) {
    let (mut data, mut temp) = (0.0, 0.0);
    for (t, p) in preds.iter().enumerate() {
        let y = &pairs[t].1;
        let yp = &pairs[t.saturating_sub(1)].1;
        let (mut s, mut st, mut c) = (0.0, 0.0, 0.0);
        for k in 0..p.n.len() {
            if y.covered[k] {
                for ch in 0..3 {
                    s += (p.n[k][ch] - y.n[k][ch]).abs() as f64;
                    st += (p.n[k][ch] - yp.n[k][ch]) as f64;
                    c += 1.0;
                }
            }
        }
        data += s / c;
        temp += (st / c).abs();
    }
    (data / preds.len() as f64, temp / preds.len() as f64)
}

fn to_rgb(m: &NormalMap) -> image::RgbImage {
    image::RgbImage::from_fn(m.width as u32, m.height as u32, |x, y| {
        let k = y as usize * m.width + x as usize;
        if !m.covered[k] {
            return image::Rgb([128, 128, 128]);
        }
        let c = |v: f32| ((v.clamp(-1.0, 1.0) + 1.0) * 127.5) as u8;
        image::Rgb([c(m.n[k][0]), c(m.n[k][1]), c(m.n[k][2])])
    })
}

/// The Table 1 variants in row order: (row name, input kind, temporal weight). The subspace of the plain
/// subspace rows is fitted on every training frame, so it reproduces the training frames almost exactly
/// (k = 200 of 240 frames: 0.03 mm) and the cGAN sees input ≈ target in training; the cross-fitted rows
/// reconstruct each training sequence in a subspace of the other training sequences (k capped at their frame
/// count), so training inputs carry the same kind of error as the held-out ones.
const VARIANTS: [(&str, &str, f64); 7] = [
    ("captured, Eq. 4", "captured", 50.0),
    ("captured, no temporal term", "captured_notemp", 0.0),
    ("subspace k = 200", "subspace200", 50.0),
    ("subspace k = 50", "subspace50", 50.0),
    (
        "subspace k = 200, training inputs cross-fitted",
        "subspace200x",
        50.0,
    ),
    (
        "subspace k = 50, training inputs cross-fitted",
        "subspace50x",
        50.0,
    ),
    ("regression", "regression", 50.0),
];

/// What `deep_report cgan` trains: the network's size and how long.
struct CganRun {
    epochs: usize,
    res: usize,
    filters: usize,
    batch: usize,
    /// Variant kinds to run (a subset of [`VARIANTS`]'s).
    kinds: Vec<String>,
    /// Minutes of training per variant; after an epoch that leaves less than another epoch's time, the
    /// variant stops early (its checkpoint lets a later run continue).
    budget_min: f64,
    /// Adam's learning rate (default: the paper's 2e-4).
    lr: Option<f64>,
}

/// Table 1 in spirit: one cGAN per input variant, trained epoch by epoch with a checkpoint after each
/// (`OUT/ck_KIND`, resumed when present) and the held-out errors logged after each (the learning curve,
/// `OUT/curve_KIND.jsonl`). Each finished variant writes `OUT/table1_KIND.json` and its Fig. 11 row; the table
/// and the strip are then assembled from every variant present, so variants may run in separate invocations.
fn cgan(data: &str, out: &str, held: &str, run: &CganRun, ridge: f64, ar_state: usize) -> R<()> {
    let (res, filters, epochs) = (run.res, run.filters, run.epochs);
    for k in &run.kinds {
        if !VARIANTS.iter().any(|v| v.1 == k) {
            return Err(format!("unknown variant {k}").into());
        }
    }
    std::fs::create_dir_all(out)?;
    let (train, test) = split(data, held)?;
    let topo = test.topology.clone();
    let frames: Vec<&[V3]> = train
        .iter()
        .flat_map(|s| s.fine.iter().map(|f| f.as_slice()))
        .collect();
    let sub = Subspace::fit(&frames, 200)?;
    let mean_shape = crease_deep::subspace::unflatten(&sub.mean);
    let layout = auto_atlas(&topo, &mean_shape, 0.01)?;
    let texels = TexelMap::new(&layout, res, res);
    // The regression input: the shapes `crease deep train`'s default pose-only regressor predicts (fitted on
    // the training sequences with the default parameters, the ridge and fed-back state given here).
    let reg_params = TrainParams {
        ridge,
        ar_state,
        ..Default::default()
    };
    let fitted = if run.kinds.iter().any(|k| k == "regression") {
        Some(crease_deep::train::fit(
            &train,
            &reg_params,
            &crease_core::progress::NoProgress,
        )?)
    } else {
        None
    };
    let reg_kind = reg_params.regressor;
    let shapes = |s: &TrainingSequence, kind: &str| -> R<Vec<Frame>> {
        Ok(match kind {
            "captured" | "captured_notemp" => s.coarse.clone(),
            "subspace200" | "subspace50" => {
                let k = if kind == "subspace200" { 200 } else { 50 };
                let st = sub.truncated(k);
                s.fine
                    .iter()
                    .map(|f| st.reconstruct(&st.project(f, k)))
                    .collect()
            }
            "subspace200x" | "subspace50x" => {
                let k = if kind == "subspace200x" { 200 } else { 50 };
                let st = if train.iter().any(|t| t.dir == s.dir) {
                    let others: Vec<&[V3]> = train
                        .iter()
                        .filter(|t| t.dir != s.dir)
                        .flat_map(|t| t.fine.iter().map(|f| f.as_slice()))
                        .collect();
                    Subspace::fit(&others, k)?
                } else {
                    sub.truncated(k)
                };
                let k = st.k();
                s.fine
                    .iter()
                    .map(|f| st.reconstruct(&st.project(f, k)))
                    .collect()
            }
            _ => {
                let fitted = fitted.as_ref().ok_or("regression variant without a fit")?;
                fitted
                    .coefficients(reg_kind, &s.poses)?
                    .iter()
                    .map(|c| fitted.subspace.reconstruct(c))
                    .collect()
            }
        })
    };
    eprintln!("held out: {held}; {res}x{res} maps, generator {filters} filters, batch {}, up to {epochs} epochs per variant", run.batch);
    let show = test.fine.len() / 3;
    let gt_ne: f64 = test
        .fine
        .iter()
        .zip(&test.coarse)
        .map(|(g, c)| mesh_normal_error(&topo, g, c))
        .sum::<f64>()
        / test.fine.len() as f64;
    // DESIGN §9 normal error of maps sampled at the vertices, averaged over the held-out frames.
    let vertex_ne = |maps: &[&NormalMap]| -> f64 {
        maps.iter()
            .zip(&test.fine)
            .map(|(p, g)| map_normal_error(&sample_vertex_normals(p, &topo, &layout), &topo, g).0)
            .sum::<f64>()
            / maps.len() as f64
    };
    let t_all = Instant::now();
    for &(name, kind, w_temp) in VARIANTS
        .iter()
        .filter(|v| run.kinds.iter().any(|k| k == v.1))
    {
        let name = if kind == "regression" {
            format!("regression ({} regressor)", reg_kind.name())
        } else {
            name.to_string()
        };
        let name = name.as_str();
        let t_prep = Instant::now();
        let mut train_samples: Vec<Sample> = Vec::new();
        for s in &train {
            train_samples.extend(samples(&map_pairs(
                &topo,
                &texels,
                &shapes(s, kind)?,
                &s.fine,
                8.0,
            )?));
        }
        let test_shapes = shapes(&test, kind)?;
        let test_pairs = map_pairs(&topo, &texels, &test_shapes, &test.fine, 8.0)?;
        let inputs: Vec<&NormalMap> = test_pairs.iter().map(|p| &p.0).collect();
        let targets: Vec<&NormalMap> = test_pairs.iter().map(|p| &p.1).collect();
        let input_ne = vertex_ne(&inputs);
        let target_ne = vertex_ne(&targets);
        eprintln!(
            "{name}: maps in {:.0} s; held-out vertex normal error: input map {input_ne:.2}°, target map {target_ne:.2}°, captured mesh {gt_ne:.2}°",
            t_prep.elapsed().as_secs_f64()
        );
        let cfg = CganConfig {
            resolution: res,
            filters,
            disc_filters: filters,
            w_temporal: w_temp,
            epochs,
            batch: run.batch,
            lr: run.lr.unwrap_or(CganConfig::default().lr),
            ..Default::default()
        };
        let ck = Path::new(out).join(format!("ck_{kind}"));
        let curve_path = Path::new(out).join(format!("curve_{kind}.jsonl"));
        let mut gan = if ck.join("state.json").exists() {
            let g = Cgan::resume(cfg.clone(), &ck)?;
            eprintln!(
                "{name}: resuming from {} after epoch {}",
                ck.display(),
                g.epoch
            );
            g
        } else {
            let _ = std::fs::remove_file(&curve_path);
            Cgan::new(cfg.clone())?
        };
        let evaluate = |gan: &Cgan| -> R<(Vec<NormalMap>, f64, f64, f64)> {
            let preds: Vec<NormalMap> = test_pairs
                .iter()
                .map(|p| gan.enhance(&p.0))
                .collect::<Result<_, _>>()?;
            let (d, tmp) = eval_maps(&preds, &test_pairs);
            let refs: Vec<&NormalMap> = preds.iter().collect();
            let ne = vertex_ne(&refs);
            Ok((preds, d, tmp, ne))
        };
        let log_curve = |line: serde_json::Value| -> R<()> {
            use std::io::Write;
            let mut f = std::fs::OpenOptions::new()
                .create(true)
                .append(true)
                .open(&curve_path)?;
            writeln!(f, "{line}")?;
            Ok(())
        };
        if gan.epoch == 0 {
            let (_, d, tmp, ne) = evaluate(&gan)?;
            eprintln!("{name}: epoch 0 (untrained): held-out data {d:.4} temporal {tmp:.4} vertex normal error {ne:.2}°");
            log_curve(
                serde_json::json!({"epoch": 0, "data_l1": d, "temporal": tmp, "vertex_normal_error_deg": ne}),
            )?;
        }
        let budget = run.budget_min * 60.0;
        let t_var = Instant::now();
        let mut epoch_s: Vec<f64> = Vec::new();
        while gan.epoch < epochs {
            let spent = t_var.elapsed().as_secs_f64();
            if let Some(&last) = epoch_s.last() {
                if budget > 0.0 && spent + last > budget {
                    eprintln!("{name}: stopping after epoch {} ({spent:.0} s of the {budget:.0} s budget)", gan.epoch);
                    break;
                }
            }
            gan.config.epochs = gan.epoch + 1;
            let te = Instant::now();
            let steps = train_samples.len().div_ceil(run.batch);
            let hist = gan.train(
                &train_samples,
                |e, i, l| {
                    if i % 10 == 0 || i + 1 == steps {
                        eprintln!(
                            "{name}: epoch {} step {}/{steps} ({:.0} s): L1 {:.4} temporal {:.4} GAN {:.3} D {:.3}",
                            e + 1,
                            i + 1,
                            te.elapsed().as_secs_f64(),
                            l.l1,
                            l.temporal,
                            l.gan,
                            l.disc
                        )
                    }
                },
                |_, _, _| Ok(()),
            )?;
            let secs = te.elapsed().as_secs_f64();
            epoch_s.push(secs);
            gan.save_checkpoint(&ck)?;
            let (_, d, tmp, ne) = evaluate(&gan)?;
            let l = hist.last().copied().unwrap_or_default();
            eprintln!(
                "{name}: epoch {} in {secs:.0} s: train L1 {:.4} temporal {:.4} GAN {:.3} D {:.3}; held-out data {d:.4} temporal {tmp:.4} vertex normal error {ne:.2}° ({:.0} s since start)",
                gan.epoch, l.l1, l.temporal, l.gan, l.disc, t_all.elapsed().as_secs_f64()
            );
            log_curve(
                serde_json::json!({"epoch": gan.epoch, "seconds": secs, "train": l, "data_l1": d, "temporal": tmp, "vertex_normal_error_deg": ne}),
            )?;
        }
        let per_epoch = if epoch_s.is_empty() {
            f64::NAN
        } else {
            epoch_s.iter().sum::<f64>() / epoch_s.len() as f64
        };
        let (preds, d, tmp, ne) = evaluate(&gan)?;
        let (d_in, _) = eval_maps(
            &test_pairs.iter().map(|p| p.0.clone()).collect::<Vec<_>>(),
            &test_pairs,
        );
        let angle = preds
            .iter()
            .zip(&test_pairs)
            .map(|(p, q)| p.mean_angle_deg(&q.1))
            .sum::<f64>()
            / preds.len() as f64;
        let curve: Vec<serde_json::Value> = std::fs::read_to_string(&curve_path)?
            .lines()
            .map(serde_json::from_str)
            .collect::<Result<_, _>>()?;
        write_json(
            out,
            &format!("table1_{kind}.json"),
            &serde_json::json!({"input": name, "kind": kind, "epochs": gan.epoch, "resolution": res, "filters": filters, "batch": run.batch, "lr": cfg.lr,
                "residual": gan.config.residual, "data_l1": d, "temporal": tmp, "map_angle_deg": angle, "input_data_l1": d_in,
                "input_map_vertex_normal_error_deg": input_ne, "vertex_normal_error_deg": ne, "target_map_vertex_normal_error_deg": target_ne,
                "captured_normal_error_deg": gt_ne, "s_per_epoch": per_epoch, "curve": curve}),
        )?;
        if kind == "captured" {
            // The same frames as `crease deep apply --coarse` writes them (DESIGN §7 contract), for `score`.
            let dir = Path::new(out).join("apply_captured");
            crease_deep::contract::prepare(&dir)?;
            for (t, p) in preds.iter().enumerate() {
                crease_deep::contract::write_frame(
                    &dir,
                    t,
                    &topo,
                    &test_shapes[t],
                    &layout,
                    &p.dilated(3),
                )?;
            }
            crease_deep::contract::finish(
                &dir,
                preds.len(),
                crease_deep::normal_maps::Space::World,
                res,
                "deep_report cgan",
            )?;
        }
        // Fig. 11 row: input | prediction | target.
        let (w, h) = (res as u32, res as u32);
        let mut row = image::RgbImage::new(3 * w, h);
        for (i, m) in [&test_pairs[show].0, &preds[show], &test_pairs[show].1]
            .iter()
            .enumerate()
        {
            image::imageops::overlay(&mut row, &to_rgb(m), (i as u32 * w) as i64, 0);
        }
        row.save(Path::new(out).join(format!("fig11_{kind}.png")))?;
    }
    // The table and the strip over every variant that has a result in OUT.
    println!(
        "held out: {held}; {res}x{res} maps, generator {filters} filters; frame {} in the strip",
        show + 1
    );
    println!("| input | epochs | data (L1) | temporal | map angle to target (°) | input's data (L1) | vertex normal error: input map (°) | prediction (°) | target map (°) | captured mesh (°) | s/epoch |\n|---|---|---|---|---|---|---|---|---|---|---|");
    let mut rows = Vec::new();
    let mut strip: Vec<image::RgbImage> = Vec::new();
    for &(_, kind, _) in &VARIANTS {
        let p = Path::new(out).join(format!("table1_{kind}.json"));
        if !p.exists() {
            continue;
        }
        let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&p)?)?;
        let f = |k: &str| r[k].as_f64().unwrap_or(f64::NAN);
        println!(
            "| {} | {} | {:.4} | {:.4} | {:.2} | {:.4} | {:.2} | {:.2} | {:.2} | {:.2} | {:.0} |",
            r["input"].as_str().unwrap_or(kind),
            r["epochs"],
            f("data_l1"),
            f("temporal"),
            f("map_angle_deg"),
            f("input_data_l1"),
            f("input_map_vertex_normal_error_deg"),
            f("vertex_normal_error_deg"),
            f("target_map_vertex_normal_error_deg"),
            f("captured_normal_error_deg"),
            f("s_per_epoch")
        );
        rows.push(r);
        strip.push(image::open(Path::new(out).join(format!("fig11_{kind}.png")))?.to_rgb8());
    }
    if let Some(first) = strip.first() {
        let (w, h) = (first.width(), first.height());
        let mut fig = image::RgbImage::new(w, h * strip.len() as u32);
        for (i, r) in strip.iter().enumerate() {
            image::imageops::overlay(&mut fig, r, 0, (i as u32 * h) as i64);
        }
        fig.save(Path::new(out).join("fig11_strip.png"))?;
    }
    write_json(
        out,
        "table1.json",
        &serde_json::json!({"held_out": held, "resolution": res, "filters": filters, "frame_shown": show + 1, "rows": rows}),
    )
}

/// What a map of each resolution can carry at best: the DESIGN §9 vertex normal error of the coarse
/// (captured) map and of the target map (gt projected onto the captured mesh), both sampled at the vertices,
/// beside the captured mesh's own, over every `step`-th frame of the held-out sequence. A cGAN's prediction is
/// scored the same way, so the target map's error is the floor it can reach at that resolution.
fn mapbound(data: &str, held: &str, resolutions: &[usize], step: usize) -> R<()> {
    let (_, test) = split(data, held)?;
    let topo = test.topology.clone();
    let layout = auto_atlas(&topo, &test.fine[0], 0.01)?;
    let idx: Vec<usize> = (0..test.fine.len()).step_by(step.max(1)).collect();
    let coarse: Vec<Frame> = idx.iter().map(|&t| test.coarse[t].clone()).collect();
    let fine: Vec<Frame> = idx.iter().map(|&t| test.fine[t].clone()).collect();
    let mesh_ne = coarse
        .iter()
        .zip(&fine)
        .map(|(c, g)| mesh_normal_error(&topo, g, c))
        .sum::<f64>()
        / idx.len() as f64;
    println!("held out: {held}, {} frames\n| resolution | coverage | input map (°) | target map (°) | captured mesh (°) |\n|---|---|---|---|---|", idx.len());
    for &res in resolutions {
        let texels = TexelMap::new(&layout, res, res);
        let pairs = map_pairs(&topo, &texels, &coarse, &fine, 8.0)?;
        let ne = |m: &dyn Fn(&(NormalMap, NormalMap)) -> &NormalMap| {
            pairs
                .iter()
                .zip(&fine)
                .map(|(p, g)| {
                    map_normal_error(&sample_vertex_normals(m(p), &topo, &layout), &topo, g).0
                })
                .sum::<f64>()
                / pairs.len() as f64
        };
        println!(
            "| {res}² | {:.2} | {:.2} | {:.2} | {mesh_ne:.2} |",
            texels.coverage(),
            ne(&|p| &p.0),
            ne(&|p| &p.1)
        );
    }
    Ok(())
}

/// Why the LSTM under-fits: per held-out split, `crease deep train`'s fit (subspace, controls, mirror) and
/// then LSTMs (LAYERSxHIDDENxEPOCHS) trained on the same windows by variants `scale,schedule[,std]`: outputs in
/// units of each coefficient's standard deviation (`coef`, what the model did) or of one shared scale
/// (`shared`: the RMS over all coefficients, so the loss is the vertex MSE up to a constant); a constant
/// learning rate (`const`) or cosine decay (`cosine`); `std` standardises the inputs. Prints the final training
/// loss in both units beside the linear map's, and the held-out vertex error.
fn lstm_check(data: &str, out: &str, held_arg: &str, shape: &str, variants: &str) -> R<()> {
    let n: Vec<usize> = shape
        .split('x')
        .map(|x| x.parse())
        .collect::<Result<_, _>>()?;
    let names = sequence_names(data)?;
    let helds: Vec<String> = if held_arg == "all" {
        names.clone()
    } else {
        vec![held_arg.to_string()]
    };
    let mut notes = Vec::new();
    let mut table: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for held in &helds {
        let (train, test) = split(data, held)?;
        let params = TrainParams::default();
        let fitted = crease_deep::train::fit(&train, &params, &crease_core::progress::NoProgress)?;
        let sub = &fitted.subspace;
        let k = sub.k();
        let mut seqs: Vec<(Vec<Frame>, Vec<Vec<f64>>)> = train
            .iter()
            .map(|s| (s.fine.clone(), s.poses.clone()))
            .collect();
        if let Some(r) = &fitted.mirror {
            for s in &train {
                seqs.push((
                    s.fine.iter().map(|f| r.reflect_frame(f)).collect(),
                    s.poses
                        .iter()
                        .map(|p| crease_deep::subspace::mirror::reflect_pose(p, r.axis))
                        .collect(),
                ));
            }
        }
        type ControlsTargets = (Vec<Vec<f64>>, Vec<Vec<f64>>);
        let per_seq: Vec<ControlsTargets> = seqs
            .iter()
            .map(|(f, p)| -> R<_> {
                Ok((
                    fitted.control.controls(p)?,
                    f.iter().map(|fr| sub.project(fr, k)).collect(),
                ))
            })
            .collect::<R<_>>()?;
        let all_t: Vec<&Vec<f64>> = per_seq.iter().flat_map(|(_, t)| t).collect();
        let cnt = all_t.len() as f64;
        let coef: Vec<f64> = (0..k)
            .map(|j| {
                (all_t.iter().map(|t| t[j] * t[j]).sum::<f64>() / cnt)
                    .sqrt()
                    .max(1e-9)
            })
            .collect();
        let shared_v = (coef.iter().map(|c| c * c).sum::<f64>() / k as f64).sqrt();
        let shared = vec![shared_v; k];
        // The linear map's training loss in both units.
        let loss_in = |pred: &dyn Fn(usize, usize) -> Vec<f64>, scale: &[f64]| -> f64 {
            let mut sum = 0.0;
            let mut m = 0usize;
            for (si, (_, t)) in per_seq.iter().enumerate() {
                for (fi, tr) in t.iter().enumerate() {
                    let p = pred(si, fi);
                    sum += p
                        .iter()
                        .zip(tr)
                        .zip(scale)
                        .map(|((a, b), s)| ((a - b) / s).powi(2))
                        .sum::<f64>();
                    m += k;
                }
            }
            sum / m as f64
        };
        let lin = |si: usize, fi: usize| fitted.linear.predict(&per_seq[si].0[fi]);
        let lin_coef = loss_in(&lin, &coef);
        let lin_shared = loss_in(&lin, &shared);
        let ranges: Vec<f64> = {
            let c: Vec<&Vec<f64>> = per_seq.iter().flat_map(|(c, _)| c).collect();
            let d = c[0].len();
            (0..d)
                .map(|j| {
                    let m = c.iter().map(|r| r[j]).sum::<f64>() / c.len() as f64;
                    (c.iter().map(|r| (r[j] - m).powi(2)).sum::<f64>() / c.len() as f64).sqrt()
                })
                .collect()
        };
        eprintln!(
            "{held}: linear training loss {lin_coef:.4} (per-coefficient units) {lin_shared:.4} (shared); control std min {:.3} max {:.3}",
            ranges.iter().cloned().fold(f64::INFINITY, f64::min),
            ranges.iter().cloned().fold(0.0, f64::max)
        );
        let truth: Vec<Vec<f64>> = test.fine.iter().map(|fr| sub.project(fr, k)).collect();
        let test_c = fitted.control.controls(&test.poses)?;
        let lin_pred: Vec<Vec<f64>> = test_c.iter().map(|c| fitted.linear.predict(c)).collect();
        let mut rows = vec![(
            "linear".to_string(),
            scores(sub, &lin_pred, &truth, &test.fine),
        )];
        for v in variants.split(';').filter(|v| !v.is_empty()) {
            let f: Vec<&str> = v.split(',').collect();
            let scale = if f[0] == "shared" {
                shared.clone()
            } else {
                coef.clone()
            };
            let std = f.get(2) == Some(&"std");
            let norm = Standardizer::fit(per_seq.iter().flat_map(|(c, _)| c));
            let prep = |c: &[Vec<f64>]| if std { norm.apply_all(c) } else { c.to_vec() };
            let mut data_w = Vec::new();
            for (c, a) in &per_seq {
                data_w.extend(windows(&prep(c), a, 3));
            }
            let cfg = lstm_config(n[0], n[1], n[2]);
            let mut net = LstmRegressor::new(cfg.clone(), test_c[0].len(), k, scale.clone())?;
            let t0 = Instant::now();
            let losses = if f.get(1) == Some(&"cosine") {
                net.train_scheduled(&data_w, cosine(cfg.lr, cfg.epochs), log_every_25("lstm"))?
            } else {
                net.train(&data_w, log_every_25("lstm"))?
            };
            let secs = t0.elapsed().as_secs_f64();
            let train_pred: Vec<Vec<Vec<f64>>> = per_seq
                .iter()
                .map(|(c, a)| net.predict(&windows(&prep(c), a, 3)))
                .collect::<Result<_, _>>()?;
            let tp = |si: usize, fi: usize| train_pred[si][fi].clone();
            let (l_coef, l_shared) = (loss_in(&tp, &coef), loss_in(&tp, &shared));
            let pred = net.predict(&windows(&prep(&test_c), &truth, 3))?;
            let sc = scores(sub, &pred, &truth, &test.fine);
            eprintln!(
                "{held} {v}: held-out {} / {} mm; training loss {l_coef:.4} (coef) {l_shared:.4} (shared); {:.2} s/epoch",
                mm(sc.mean),
                mm(sc.p95),
                secs / cfg.epochs.max(1) as f64
            );
            notes.push(serde_json::json!({"held_out": held, "variant": v, "mean_m": sc.mean, "p95_m": sc.p95,
                "train_loss_coef": l_coef, "train_loss_shared": l_shared, "linear_train_loss_coef": lin_coef,
                "linear_train_loss_shared": lin_shared, "losses": losses, "s_per_epoch": secs / cfg.epochs.max(1) as f64}));
            rows.push((format!("LSTM {shape} {v}"), sc));
        }
        for (name, sc) in rows {
            match table.iter_mut().find(|(n, _)| *n == name) {
                Some((_, r)) => r.push((sc.mean, sc.p95)),
                None => table.push((name, vec![(sc.mean, sc.p95)])),
            }
        }
    }
    println!("| regressor | {} | mean (mm) |", helds.join(" | "));
    for (name, v) in &table {
        let cells: Vec<String> = v
            .iter()
            .map(|(m, p)| format!("{} / {}", mm(*m), mm(*p)))
            .collect();
        println!(
            "| {name} | {} | {} |",
            cells.join(" | "),
            mm(v.iter().map(|x| x.0).sum::<f64>() / v.len() as f64)
        );
    }
    write_json(out, "lstmcheck.json", &serde_json::json!({"rows": notes}))
}

/// Registration parameters overridden by environment variables (experiments without a rebuild):
/// CREASE_REG_{W_TEMPORAL, NOISE_FLOOR, W_PLANE, W_POINT, MAX_NORMAL_ANGLE, GN_STEPS, MIN_WEIGHT,
/// TARGET_POINTS, NODE_SPACING, ITERATIONS}.
fn register_env(mut p: RegisterParams) -> R<RegisterParams> {
    let get = |name: &str| std::env::var(format!("CREASE_REG_{name}")).ok();
    macro_rules! set {
        ($field:ident, $name:expr) => {
            if let Some(v) = get($name) {
                p.$field = v.parse()?;
            }
        };
    }
    set!(w_temporal, "W_TEMPORAL");
    set!(noise_floor, "NOISE_FLOOR");
    set!(w_plane, "W_PLANE");
    set!(w_point, "W_POINT");
    set!(max_normal_angle, "MAX_NORMAL_ANGLE");
    set!(gn_steps, "GN_STEPS");
    set!(min_weight, "MIN_WEIGHT");
    set!(target_points, "TARGET_POINTS");
    set!(node_spacing, "NODE_SPACING");
    set!(iterations, "ITERATIONS");
    set!(multi_start, "MULTI_START");
    set!(restart_from_template, "RESTART");
    Ok(p)
}

/// Mean normal and tangential parts (along and across `reference`'s vertex normals) of `got − reference`.
fn error_parts(topo: &Topology, got: &[V3], reference: &[V3]) -> (f64, f64) {
    let n = vertex_normals(topo, reference);
    let (mut sn, mut st) = (0.0, 0.0);
    for ((g, r), nv) in got.iter().zip(reference).zip(&n) {
        let e = vec3::sub(*g, *r);
        let nn = vec3::normalize(*nv);
        let along = vec3::dot(e, nn);
        sn += along.abs();
        st += vec3::norm(vec3::sub(e, vec3::scale(nn, along)));
    }
    let c = got.len().max(1) as f64;
    (sn / c, st / c)
}

/// The issue's registration test on the sleeve: gt frame 1 of a sequence (CREASE_REG_SEQ, default seed_1) as
/// the template, tracked through scans sampled from later gt frames (20 % holes, 2 mm noise). `frames` is a
/// count (evenly spaced) or a list of 1-based frame numbers, e.g. 11,41,81,111.
fn register(data: &str, out: &str, frames: &str, params: RegisterParams) -> R<()> {
    let seq_name = std::env::var("CREASE_REG_SEQ").unwrap_or("seed_1".into());
    let seq = Sequence::load(
        open_sequence(&Path::new(data).join(&seq_name).join("gt"))?
            .source
            .as_ref(),
    )?;
    let topo: std::sync::Arc<Topology> = seq.topology.clone();
    println!("{seq_name}; params {}", serde_json::to_string(&params)?);
    let mut reg = Registration::new(topo.clone(), &seq.frames[0], params.clone())?;
    println!("{} graph nodes; template = gt frame 1; scans sampled from later frames (20% holes, 2 mm noise)", reg.n_nodes());
    println!(
        "| frame | mean (mm) | p95 (mm) | normal / tangential (mm) | template-to-frame mean (mm) | normal / tangential (mm) | noise σ² (edges²), floor | s |\n|---|---|---|---|---|---|---|---|"
    );
    let list: Vec<usize> = if frames.contains(',') {
        frames
            .split(',')
            .map(|f| f.trim().parse::<usize>().map(|f| f.saturating_sub(1)))
            .collect::<Result<_, _>>()?
    } else {
        let n: usize = frames.parse()?;
        let step = (seq.frames.len() / n.max(1)).max(1);
        (step..seq.frames.len()).step_by(step).take(n).collect()
    };
    let mut rows = Vec::new();
    let (mut sum_got, mut sum_before) = (0.0, 0.0);
    for t in list {
        if t >= seq.frames.len() {
            return Err(format!(
                "frame {} is past the sequence's {}",
                t + 1,
                seq.frames.len()
            )
            .into());
        }
        let scan = synth_scan(&topo, &seq.frames[t], 3.0, 0.2, 0.002, t as u64);
        // CREASE_REG_WRITE_SCANS=DIR: also write the template and the scans, the input of `crease deep register`.
        if let Some(dir) = std::env::var_os("CREASE_REG_WRITE_SCANS") {
            let dir = Path::new(&dir);
            std::fs::create_dir_all(dir.join("scans"))?;
            crease_core::mesh::io::write_obj(&dir.join("template.obj"), &topo, &seq.frames[0])?;
            crease_deep::registration::write_scan(
                &dir.join("scans").join(format!("scan_{:04}.obj", t + 1)),
                &scan,
            )?;
        }
        let t0 = Instant::now();
        let got = reg.register(&scan)?;
        let secs = t0.elapsed().as_secs_f64();
        let (m, p) = vertex_error(&got, &seq.frames[t]);
        let (b, _) = vertex_error(&seq.frames[0], &seq.frames[t]);
        let (gn, gt) = error_parts(&topo, &got, &seq.frames[t]);
        let (bn, bt) = error_parts(&topo, &seq.frames[0], &seq.frames[t]);
        let (noise, floor) = reg.last_noise();
        sum_got += m;
        sum_before += b;
        println!(
            "| {} | {} | {} | {} / {} | {} | {} / {} | {} {floor:.1} | {secs:.1} |",
            t + 1,
            mm(m),
            mm(p),
            mm(gn),
            mm(gt),
            mm(b),
            mm(bn),
            mm(bt),
            noise.map_or("-".into(), |v| format!("{v:.4}")),
        );
        rows.push(serde_json::json!({"frame": t + 1, "mean_m": m, "p95_m": p, "before_m": b, "normal_m": gn, "tangential_m": gt,
            "before_normal_m": bn, "before_tangential_m": bt, "noise_var_edges2": noise, "floor": floor, "seconds": secs}));
    }
    let n = rows.len().max(1) as f64;
    println!(
        "mean over frames: registered {} mm, unregistered {} mm",
        mm(sum_got / n),
        mm(sum_before / n)
    );
    write_json(
        out,
        "registration.json",
        &serde_json::json!({"sequence": seq_name, "rows": rows, "nodes": reg.n_nodes(), "params": params}),
    )
}

/// DESIGN §9 normal error of an apply output (mesh/ + normals/) against gt, beside the captured input's and the
/// coarse mesh's own; shape error of the coarse mesh to gt.
fn score(out: &str, gt: &str, captured: &str) -> R<()> {
    let gt = Sequence::load(open_sequence(Path::new(gt))?.source.as_ref())?;
    let cap = Sequence::load(open_sequence(Path::new(captured))?.source.as_ref())?;
    let topo = gt.topology.clone();
    let (mut map_e, mut mesh_e, mut cap_e, mut shape) = (0.0, 0.0, 0.0, 0.0);
    let n = gt.frames.len();
    for t in 0..n {
        let stem = format!("frame_{:04}", t + 1);
        let obj = Path::new(out).join("mesh").join(format!("{stem}.obj"));
        let (mtopo, coarse, layout) = crease_deep::normal_maps::uv::read_obj_mesh(&obj)?;
        let layout = layout.ok_or("output mesh without vt")?;
        let _ = read_obj_uv(&obj, &mtopo)?;
        let map = NormalMap::read_png(&Path::new(out).join("normals").join(format!("{stem}.png")))?;
        map_e += map_normal_error(
            &sample_vertex_normals(&map, &mtopo, &layout),
            &topo,
            &gt.frames[t],
        )
        .0;
        mesh_e += mesh_normal_error(&topo, &coarse, &gt.frames[t]);
        cap_e += mesh_normal_error(&topo, &cap.frames[t], &gt.frames[t]);
        shape += vertex_error(&coarse, &gt.frames[t]).0;
        let _ = vertex_normals(&topo, &coarse);
        let _ = vec3::norm([0.0; 3]);
    }
    let n = n as f64;
    println!("| frames | map normal error (°) | coarse mesh normal error (°) | captured normal error (°) | shape error (mm) |\n|---|---|---|---|---|");
    println!(
        "| {} | {:.2} | {:.2} | {:.2} | {} |",
        n,
        map_e / n,
        mesh_e / n,
        cap_e / n,
        mm(shape / n)
    );
    Ok(())
}

/// The mesh-space detail filter ([`crease_deep::detail`]) per held-out sequence: fitted on the other
/// sequences' (captured, gt) pairs for every degree and ridge, scored on the held-out one by the DESIGN §9 normal
/// error of the predicted fine mesh (vertex normals) beside the captured mesh's; then, for the first degree and
/// ridge, what drawing those normals into a map and sampling it back at the vertices (as `score` does) keeps, at
/// each resolution, beside the same round trip of gt's own normals (the sampler's floor) and of the captured
/// mesh's map (what `apply` wrote before). Every `step`-th held-out frame.
fn detail(
    data: &str,
    out: &str,
    held: &str,
    degrees: &[usize],
    ridges: &[f64],
    resolutions: &[usize],
    step: usize,
) -> R<()> {
    use crease_deep::detail::{fit_system, Umbrella};
    use crease_deep::normal_maps::world_from_vertex_normals;
    let helds = if held == "all" {
        sequence_names(data)?
    } else {
        vec![held.to_string()]
    };
    let mut rows = Vec::new();
    println!("| held out | degree | ridge | captured mesh (°) | predicted fine mesh (°) | fit (s) |\n|---|---|---|---|---|---|");
    for h in &helds {
        let (train, test) = split(data, h)?;
        let topo = test.topology.clone();
        let op = Umbrella::new(&topo);
        let idx: Vec<usize> = (0..test.fine.len()).step_by(step.max(1)).collect();
        let cap_ne = idx
            .iter()
            .map(|&t| mesh_normal_error(&topo, &test.coarse[t], &test.fine[t]))
            .sum::<f64>()
            / idx.len() as f64;
        let pairs: Vec<(&[V3], &[V3])> = train
            .iter()
            .flat_map(|s| {
                s.coarse
                    .iter()
                    .zip(&s.fine)
                    .map(|(c, f)| (c.as_slice(), f.as_slice()))
            })
            .collect();
        let mut first = None;
        for &degree in degrees {
            let t0 = Instant::now();
            let system = fit_system(&topo, &pairs, degree)?;
            let fit_s = t0.elapsed().as_secs_f64();
            for &ridge in ridges {
                let filter = system.solve(ridge)?;
                let ne = idx
                    .iter()
                    .map(|&t| {
                        mesh_normal_error(&topo, &filter.apply(&op, &test.coarse[t]), &test.fine[t])
                    })
                    .sum::<f64>()
                    / idx.len() as f64;
                println!("| {h} | {degree} | {ridge:e} | {cap_ne:.2} | {ne:.2} | {fit_s:.1} |");
                rows.push(serde_json::json!({"held_out": h, "degree": degree, "ridge": ridge, "captured_deg": cap_ne, "predicted_deg": ne, "fit_s": fit_s}));
                if first.is_none() {
                    first = Some(filter);
                }
            }
        }
        let Some(filter) = first else { continue };
        let mean_shape: Vec<V3> = {
            let frames: Vec<&Frame> = train.iter().flat_map(|s| s.fine.iter()).collect();
            (0..topo.n_vertices())
                .map(|v| {
                    let mut p = [0.0; 3];
                    for f in &frames {
                        p = vec3::add(p, f[v]);
                    }
                    vec3::scale(p, 1.0 / frames.len() as f64)
                })
                .collect()
        };
        let layout = auto_atlas(&topo, &mean_shape, 0.01)?;
        println!("\n{h}: maps sampled back at the vertices (DESIGN §9), degree {} ridge {:e}\n| resolution | coverage | gt's own normals (°) | captured map (°) | predicted fine normals (°) |\n|---|---|---|---|---|", filter.degree, ridges[0]);
        for &res in resolutions {
            let texels = TexelMap::new(&layout, res, res);
            let (mut e_gt, mut e_cap, mut e_det) = (0.0, 0.0, 0.0);
            for &t in &idx {
                let (c, g) = (&test.coarse[t], &test.fine[t]);
                let score = |vn: &[V3]| {
                    let m = world_from_vertex_normals(&texels, &topo, vn);
                    map_normal_error(&sample_vertex_normals(&m, &topo, &layout), &topo, g).0
                };
                e_gt += score(&vertex_normals(&topo, g));
                e_cap += score(&vertex_normals(&topo, c));
                e_det += score(&vertex_normals(&topo, &filter.apply(&op, c)));
            }
            let n = idx.len() as f64;
            println!(
                "| {res}² | {:.2} | {:.2} | {:.2} | {:.2} |",
                texels.coverage(),
                e_gt / n,
                e_cap / n,
                e_det / n
            );
            rows.push(serde_json::json!({"held_out": h, "resolution": res, "coverage": texels.coverage(), "gt_roundtrip_deg": e_gt / n, "captured_map_deg": e_cap / n, "detail_map_deg": e_det / n}));
        }
    }
    write_json(
        out,
        "detail.json",
        &serde_json::json!({"rows": rows, "step": step}),
    )
}

/// deep/tests/registration.rs's synthetic bend: a 32 × 24 tube bent, twisted and bulged by 68 mm, tracked in
/// four steps through scans with 20 % holes and 2 mm noise; the vertex error per (target points, min weight).
fn tube_register(targets: &str, floors: &str, iterations: usize) -> R<()> {
    let parse = |s: &str| -> R<Vec<f64>> {
        Ok(s.split(',')
            .map(|x| x.parse::<f64>())
            .collect::<Result<Vec<_>, _>>()?)
    };
    let na = 32;
    let nr = 24;
    let tris = {
        let mut tris = Vec::new();
        for j in 0..nr - 1 {
            for i in 0..na {
                let i1 = (i + 1) % na;
                let a = (j * na + i) as u32;
                let (b, c, d) = (
                    (j * na + i1) as u32,
                    ((j + 1) * na + i1) as u32,
                    ((j + 1) * na + i) as u32,
                );
                tris.push([a, b, c]);
                tris.push([a, c, d]);
            }
        }
        tris
    };
    let topo = std::sync::Arc::new(Topology::new(na * nr, tris)?);
    let rest: Vec<V3> = (0..nr)
        .flat_map(|j| {
            (0..na).map(move |i| {
                let phi = std::f64::consts::TAU * i as f64 / na as f64;
                [
                    0.5 * j as f64 / (nr - 1) as f64,
                    0.07 * phi.cos(),
                    0.07 * phi.sin(),
                ]
            })
        })
        .collect();
    let deform = |amount: f64| -> Vec<V3> {
        let kappa = 1.5 * amount;
        rest.iter()
            .map(|p| {
                let s = p[0] / 0.5;
                let ang = 0.5 * s * amount;
                let r = 1.0 + 0.1 * amount * (std::f64::consts::PI * s).sin();
                let (y0, z0) = (p[1] * r, p[2] * r);
                let (y, z) = (
                    y0 * ang.cos() - z0 * ang.sin(),
                    y0 * ang.sin() + z0 * ang.cos(),
                );
                let th = kappa * p[0];
                let (cx, cz) = if kappa > 0.0 {
                    (th.sin() / kappa, (1.0 - th.cos()) / kappa)
                } else {
                    (p[0], 0.0)
                };
                [cx - z * th.sin(), y, cz + z * th.cos()]
            })
            .collect()
    };
    let target = deform(1.0);
    println!("| target points | min weight | mean (mm) | p95 (mm) | before (mm) | s |\n|---|---|---|---|---|---|");
    for tp in parse(targets)? {
        for floor in parse(floors)? {
            let params = RegisterParams {
                target_points: tp as usize,
                min_weight: floor,
                iterations,
                ..register_env(RegisterParams::default())?
            };
            let t0 = Instant::now();
            let mut reg = Registration::new(topo.clone(), &rest, params)?;
            let mut out = rest.clone();
            for (i, amount) in [0.25, 0.5, 0.75, 1.0].into_iter().enumerate() {
                let scan = synth_scan(&topo, &deform(amount), 3.0, 0.2, 0.002, 11 + i as u64);
                out = reg.register(&scan)?;
                let (noise, f) = reg.last_noise();
                eprintln!("step {i}: noise σ² {noise:?} edges², floor {f:.1}");
            }
            let (before, _) = vertex_error(&rest, &target);
            let (m, p) = vertex_error(&out, &target);
            println!(
                "| {tp} | {floor} | {} | {} | {} | {:.1} |",
                mm(m),
                mm(p),
                mm(before),
                t0.elapsed().as_secs_f64()
            );
        }
    }
    Ok(())
}

/// Per split: mesh normal error (°), map normal error (°), mean vertex error (m).
type ScoreTriple = (f64, f64, f64);

/// Prints the pose experiments' table (per split: mesh and map normal error, vertex error; then the means) and
/// returns its rows for the JSON report.
fn print_score_table(
    header: &str,
    helds: &[String],
    res: usize,
    table: &[(String, Vec<ScoreTriple>)],
) -> Vec<serde_json::Value> {
    print!("| {header} |");
    for h in helds {
        print!(" {h}: mesh / {res}² map (°), vertex (mm) |");
    }
    println!(" mean map (°) | mean vertex (mm) |");
    println!("|---|{}---|---|", "---|".repeat(helds.len()));
    let mut rows = Vec::new();
    for (name, r) in table {
        print!("| {name} |");
        for (a, b, c) in r {
            print!(" {a:.2} / {b:.2}, {} |", mm(*c));
        }
        let k = r.len() as f64;
        let map = r.iter().map(|x| x.1).sum::<f64>() / k;
        let vert = r.iter().map(|x| x.2).sum::<f64>() / k;
        println!(" {map:.2} | {} |", mm(vert));
        rows.push(serde_json::json!({"variant": name, "per_split": r, "mean_map_deg": map, "mean_vertex_m": vert}));
    }
    rows
}

/// Gaussian smoothing of a coefficient sequence over time (centred, σ in frames, the kernel cut at 3σ and
/// renormalised at the sequence's ends); σ = 0 returns the input.
fn smooth_in_time(c: &[Vec<f64>], sigma: f64) -> Vec<Vec<f64>> {
    if sigma <= 0.0 {
        return c.to_vec();
    }
    let r = (3.0 * sigma).ceil() as isize;
    (0..c.len() as isize)
        .map(|t| {
            let mut acc = vec![0.0; c[0].len()];
            let mut wsum = 0.0;
            for s in (t - r).max(0)..=(t + r).min(c.len() as isize - 1) {
                let w = (-((s - t) as f64).powi(2) / (2.0 * sigma * sigma)).exp();
                wsum += w;
                for (a, x) in acc.iter_mut().zip(&c[s as usize]) {
                    *a += w * x;
                }
            }
            acc.iter().map(|a| a / wsum).collect()
        })
        .collect()
}

/// Issue 12's pose-only normal error, taken apart and the coarse-then-detail variants measured, per held-out
/// sequence: `crease deep train`'s own fit (defaults) on the other sequences, the pose file of the held-out one
/// rolled out, and every variant scored by the DESIGN §9 normal error against gt at the mesh (vertex normals,
/// every frame) and through a `res`² map sampled back at the vertices (every `step`-th frame), beside its
/// vertex error. L is the capture filter (Taubin λ|μ, 80 steps: what made `captured/`), D the model's detail
/// filter (fitted on captured → gt pairs), P the blend regressor's reconstruction (gt subspace), Q the same fit
/// on the captured meshes (a smooth subspace and regressors), "~σ" a Gaussian over time on the coefficients.
fn posenorm(data: &str, out: &str, held: &str, sigmas: &[f64], step: usize, res: usize) -> R<()> {
    use crease_core::shape::TaubinFilter;
    use crease_deep::detail::Umbrella;
    use crease_deep::model::RegressorKind;
    let helds = if held == "all" {
        sequence_names(data)?
    } else {
        vec![held.to_string()]
    };
    // (variant, per split: (mesh °, map °, vertex error m))
    let mut table: Vec<(String, Vec<ScoreTriple>)> = Vec::new();
    let mut low_band = Vec::new();
    for h in &helds {
        let (train, test) = split(data, h)?;
        let topo = test.topology.clone();
        let op = Umbrella::new(&topo);
        let low = TaubinFilter::capture(&topo);
        let low_half = TaubinFilter::new(&topo, 0.5, -0.53, 40);
        let low_double = TaubinFilter::new(&topo, 0.5, -0.53, 160);
        let t0 = Instant::now();
        let params = TrainParams::default();
        let fit_gt = crease_deep::train::fit(&train, &params, &crease_core::progress::NoProgress)?;
        let (detail, _) = crease_deep::train::fit_detail(&train, &topo)?;
        let smooth_train: Vec<TrainingSequence> = train
            .iter()
            .map(|s| TrainingSequence {
                dir: s.dir.clone(),
                topology: s.topology.clone(),
                fine: s.coarse.clone(),
                coarse: s.coarse.clone(),
                poses: s.poses.clone(),
                pose_names: s.pose_names.clone(),
            })
            .collect();
        let fit_cap =
            crease_deep::train::fit(&smooth_train, &params, &crease_core::progress::NoProgress)?;
        eprintln!("{h}: fits in {:.1} s", t0.elapsed().as_secs_f64());
        let n = test.fine.len();
        let recon = |sub: &Subspace, c: &[Vec<f64>]| -> Vec<Frame> {
            c.iter().map(|x| sub.reconstruct(x)).collect()
        };
        let map_all = |f: &dyn Fn(&[V3]) -> Vec<V3>, xs: &[Frame]| -> Vec<Frame> {
            xs.iter().map(|x| f(x)).collect()
        };
        let d = |x: &[V3]| detail.apply(&op, x);
        let d_alpha = |x: &[V3], a: f64| -> Vec<V3> {
            d(x).iter()
                .zip(x)
                .map(|(p, q)| vec3::add(*q, vec3::scale(vec3::sub(*p, *q), a)))
                .collect()
        };
        let lp = |x: &[V3]| low.apply(x);
        let sub_gt = &fit_gt.subspace;
        let sub_cap = &fit_cap.subspace;
        let cp = fit_gt.coefficients(RegressorKind::Blend, &test.poses)?;
        let cq = fit_cap.coefficients(RegressorKind::Blend, &test.poses)?;
        let clin = fit_gt.coefficients(RegressorKind::Linear, &test.poses)?;
        let p = recon(sub_gt, &cp);
        let q = recon(sub_cap, &cq);
        let plin = recon(sub_gt, &clin);
        let gproj: Vec<Frame> = test
            .fine
            .iter()
            .map(|f| sub_gt.reconstruct(&sub_gt.project(f, sub_gt.k())))
            .collect();
        let lpp = map_all(&lp, &p);
        let mut v: Vec<(String, Vec<Frame>)> = vec![
            ("captured (= L(gt))".into(), test.coarse.clone()),
            (
                "D(captured) (apply --coarse)".into(),
                map_all(&d, &test.coarse),
            ),
            ("P (apply --pose now)".into(), p.clone()),
            ("L(P)".into(), lpp.clone()),
            (
                "L(P) + (gt − captured): predicted low band, true folds".into(),
                (0..n)
                    .map(|t| {
                        (0..topo.n_vertices())
                            .map(|i| {
                                vec3::add(lpp[t][i], vec3::sub(test.fine[t][i], test.coarse[t][i]))
                            })
                            .collect()
                    })
                    .collect(),
            ),
            (
                "captured + (P − L(P)): true low band, predicted folds".into(),
                (0..n)
                    .map(|t| {
                        (0..topo.n_vertices())
                            .map(|i| vec3::add(test.coarse[t][i], vec3::sub(p[t][i], lpp[t][i])))
                            .collect()
                    })
                    .collect(),
            ),
            ("L_40 steps(P)".into(), map_all(&|x| low_half.apply(x), &p)),
            (
                "L_160 steps(P)".into(),
                map_all(&|x| low_double.apply(x), &p),
            ),
            ("D(P)".into(), map_all(&d, &p)),
            ("D(L(P))".into(), map_all(&d, &lpp)),
            ("D_0.5(L(P))".into(), map_all(&|x| d_alpha(x, 0.5), &lpp)),
            ("D_0.25(L(P))".into(), map_all(&|x| d_alpha(x, 0.25), &lpp)),
            ("Plin (linear regressor)".into(), plin.clone()),
            ("L(Plin)".into(), map_all(&lp, &plin)),
            ("D(L(Plin))".into(), map_all(&|x| d(&lp(x)), &plin)),
            ("gt projected on the subspace (bound)".into(), gproj.clone()),
            ("L(gt projected)".into(), map_all(&lp, &gproj)),
            ("D(L(gt projected))".into(), map_all(&|x| d(&lp(x)), &gproj)),
            ("Q (smooth subspace, regressed)".into(), q.clone()),
            ("L(Q)".into(), map_all(&lp, &q)),
            ("D(Q)".into(), map_all(&d, &q)),
            ("D_0.5(Q)".into(), map_all(&|x| d_alpha(x, 0.5), &q)),
            ("D(L(Q))".into(), map_all(&|x| d(&lp(x)), &q)),
        ];
        for &s in sigmas {
            let ps = recon(sub_gt, &smooth_in_time(&cp, s));
            let qs = recon(sub_cap, &smooth_in_time(&cq, s));
            v.push((format!("P~{s}"), ps.clone()));
            v.push((format!("L(P~{s})"), map_all(&lp, &ps)));
            v.push((format!("D(L(P~{s}))"), map_all(&|x| d(&lp(x)), &ps)));
            v.push((
                format!("D_0.5(L(P~{s}))"),
                map_all(&|x| d_alpha(&lp(x), 0.5), &ps),
            ));
            v.push((format!("Q~{s}"), qs.clone()));
            v.push((format!("D(Q~{s})"), map_all(&d, &qs)));
            v.push((format!("D_0.5(Q~{s})"), map_all(&|x| d_alpha(x, 0.5), &qs)));
        }
        // Low band alone: L(P) against the captured mesh (not gt).
        let low_only = (0..n)
            .map(|t| mesh_normal_error(&topo, &lpp[t], &test.coarse[t]))
            .sum::<f64>()
            / n as f64;
        eprintln!("{h}: L(P) against captured (low band alone): {low_only:.2}°");
        let mean_shape = crease_deep::subspace::unflatten(&sub_gt.mean);
        let layout = auto_atlas(&topo, &mean_shape, 0.01)?;
        let texels = TexelMap::new(&layout, res, res);
        let idx: Vec<usize> = (0..n).step_by(step.max(1)).collect();
        for (name, frames) in &v {
            let (mesh, map) = normal_errors(&topo, &texels, &layout, &idx, frames, &test.fine);
            let (vert, _) = mean_err(frames, &test.fine);
            eprintln!("{h} | {name} | {mesh:.2} | {map:.2} | {}", mm(vert));
            match table.iter_mut().find(|(n, _)| n == name) {
                Some((_, r)) => r.push((mesh, map, vert)),
                None => table.push((name.clone(), vec![(mesh, map, vert)])),
            }
        }
        low_band.push(low_only);
    }
    println!("L(P) against the captured mesh (the low band's own error, °): {low_band:.2?}");
    let rows = print_score_table("variant", &helds, res, &table);
    write_json(
        out,
        "posenorm.json",
        &serde_json::json!({"splits": helds, "rows": rows, "step": step, "resolution": res, "low_band_vs_captured_deg": low_band}),
    )
}

/// How smooth the pose-only shape should be for its normals: `crease deep train`'s fit (defaults) per held-out
/// sequence, the blend (and linear) regressor's coefficients truncated to their leading `k'` (all: 0), the
/// reconstruction low-passed by `s` steps of the capture filter's λ|μ (0: none), scored like `posenorm`.
fn posesmooth(
    data: &str,
    out: &str,
    held: &str,
    steps: &[usize],
    truncs: &[usize],
    step: usize,
    res: usize,
) -> R<()> {
    use crease_core::shape::TaubinFilter;
    use crease_deep::model::RegressorKind;
    let helds = if held == "all" {
        sequence_names(data)?
    } else {
        vec![held.to_string()]
    };
    let mut table: Vec<(String, Vec<ScoreTriple>)> = Vec::new();
    for h in &helds {
        let (train, test) = split(data, h)?;
        let topo = test.topology.clone();
        let fit = crease_deep::train::fit(
            &train,
            &TrainParams::default(),
            &crease_core::progress::NoProgress,
        )?;
        let sub = &fit.subspace;
        let mean_shape = crease_deep::subspace::unflatten(&sub.mean);
        let layout = auto_atlas(&topo, &mean_shape, 0.01)?;
        let texels = TexelMap::new(&layout, res, res);
        let n = test.fine.len();
        let idx: Vec<usize> = (0..n).step_by(step.max(1)).collect();
        for kind in [RegressorKind::Blend, RegressorKind::Linear] {
            let c = fit.coefficients(kind, &test.poses)?;
            for &kt in truncs {
                let frames: Vec<Frame> = c
                    .iter()
                    .map(|x| {
                        let mut x = x.clone();
                        if kt > 0 {
                            x.iter_mut().skip(kt).for_each(|v| *v = 0.0);
                        }
                        sub.reconstruct(&x)
                    })
                    .collect();
                for &s in steps {
                    let f = TaubinFilter::new(&topo, 0.5, -0.53, s);
                    let fr: Vec<Frame> = if s == 0 {
                        frames.clone()
                    } else {
                        frames.iter().map(|x| f.apply(x)).collect()
                    };
                    let (mesh, map) = normal_errors(&topo, &texels, &layout, &idx, &fr, &test.fine);
                    let (vert, _) = mean_err(&fr, &test.fine);
                    let name = format!("{}, k' {kt}, {s} steps", kind.name());
                    eprintln!("{h} | {name} | {mesh:.2} | {map:.2} | {}", mm(vert));
                    match table.iter_mut().find(|(n, _)| *n == name) {
                        Some((_, r)) => r.push((mesh, map, vert)),
                        None => table.push((name, vec![(mesh, map, vert)])),
                    }
                }
            }
        }
    }
    let rows = print_score_table(
        "regressor, leading coefficients, low-pass steps",
        &helds,
        res,
        &table,
    );
    write_json(
        out,
        "posesmooth.json",
        &serde_json::json!({"splits": helds, "rows": rows, "step": step, "resolution": res}),
    )
}

/// Normals regressed directly: a PCA of the training frames' vertex normal fields (gt's, or the captured
/// meshes' smooth ones; with the mirrored frames when the fit mirrors), the control vectors of `crease deep
/// train`'s fit mapped onto its coefficients by ridge regression, the prediction renormalised per vertex and
/// scored like `posenorm`; beside the normal subspace's own bound (held-out gt normals projected).
fn posenormals(data: &str, out: &str, held: &str, ks: &[usize], step: usize, res: usize) -> R<()> {
    use crease_deep::normal_maps::world_from_vertex_normals;
    let helds = if held == "all" {
        sequence_names(data)?
    } else {
        vec![held.to_string()]
    };
    let mut table: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for h in &helds {
        let (train, test) = split(data, h)?;
        let topo = test.topology.clone();
        let fit = crease_deep::train::fit(
            &train,
            &TrainParams::default(),
            &crease_core::progress::NoProgress,
        )?;
        let mean_shape = crease_deep::subspace::unflatten(&fit.subspace.mean);
        let layout = auto_atlas(&topo, &mean_shape, 0.01)?;
        let texels = TexelMap::new(&layout, res, res);
        let n = test.fine.len();
        let idx: Vec<usize> = (0..n).step_by(step.max(1)).collect();
        let truth: Vec<Vec<V3>> = test.fine.iter().map(|f| vertex_normals(&topo, f)).collect();
        let score = |pred: &[Vec<V3>]| -> (f64, f64) {
            let mesh = (0..n)
                .map(|t| {
                    pred[t]
                        .iter()
                        .zip(&truth[t])
                        .map(|(a, b)| vec3::dot(*a, *b).clamp(-1.0, 1.0).acos().to_degrees())
                        .sum::<f64>()
                        / a_len(&pred[t])
                })
                .sum::<f64>()
                / n as f64;
            let map = idx
                .iter()
                .map(|&t| {
                    let m = world_from_vertex_normals(&texels, &topo, &pred[t]);
                    map_normal_error(
                        &sample_vertex_normals(&m, &topo, &layout),
                        &topo,
                        &test.fine[t],
                    )
                    .0
                })
                .sum::<f64>()
                / idx.len() as f64;
            (mesh, map)
        };
        for source in ["gt", "captured"] {
            let mut fields: Vec<Vec<V3>> = Vec::new();
            let mut controls: Vec<Vec<f64>> = Vec::new();
            for s in &train {
                let frames = if source == "gt" { &s.fine } else { &s.coarse };
                fields.extend(frames.iter().map(|f| vertex_normals(&topo, f)));
                controls.extend(fit.control.controls(&s.poses)?);
                if let Some(r) = &fit.mirror {
                    fields.extend(
                        frames
                            .iter()
                            .map(|f| vertex_normals(&topo, &r.reflect_frame(f))),
                    );
                    let rp: Vec<Vec<f64>> = s
                        .poses
                        .iter()
                        .map(|p| crease_deep::subspace::mirror::reflect_pose(p, r.axis))
                        .collect();
                    controls.extend(fit.control.controls(&rp)?);
                }
            }
            let refs: Vec<&[V3]> = fields.iter().map(|f| f.as_slice()).collect();
            let test_controls = fit.control.controls(&test.poses)?;
            for &k in ks {
                let sub = Subspace::fit(&refs, k)?;
                let kk = sub.k();
                let targets: Vec<Vec<f64>> = fields.iter().map(|f| sub.project(f, kk)).collect();
                let lin = LinearRegression::fit(&controls, &targets, 1e-3)?;
                let norm = |v: Vec<V3>| -> Vec<V3> { v.into_iter().map(vec3::normalize).collect() };
                let pred: Vec<Vec<V3>> = test_controls
                    .iter()
                    .map(|c| norm(sub.reconstruct(&lin.predict(c))))
                    .collect();
                let bound: Vec<Vec<V3>> = truth
                    .iter()
                    .map(|f| norm(sub.reconstruct(&sub.project(f, kk))))
                    .collect();
                for (name, p) in [
                    (format!("{source} normals, k {k}: regressed (linear)"), pred),
                    (
                        format!("{source} normals, k {k}: held-out gt normals projected (bound)"),
                        bound,
                    ),
                ] {
                    let (mesh, map) = score(&p);
                    eprintln!("{h} | {name} | {mesh:.2} | {map:.2}");
                    match table.iter_mut().find(|(n, _)| *n == name) {
                        Some((_, r)) => r.push((mesh, map)),
                        None => table.push((name, vec![(mesh, map)])),
                    }
                }
            }
        }
    }
    print!("| normal field, subspace size: variant |");
    for h in &helds {
        print!(" {h}: mesh / {res}² map (°) |");
    }
    println!(" mean map (°) |");
    println!("|---|{}---|", "---|".repeat(helds.len()));
    let mut rows = Vec::new();
    for (name, r) in &table {
        print!("| {name} |");
        for (a, b) in r {
            print!(" {a:.2} / {b:.2} |");
        }
        let map = r.iter().map(|x| x.1).sum::<f64>() / r.len() as f64;
        println!(" {map:.2} |");
        rows.push(serde_json::json!({"variant": name, "per_split": r, "mean_map_deg": map}));
    }
    write_json(
        out,
        "posenormals.json",
        &serde_json::json!({"splits": helds, "rows": rows, "step": step, "resolution": res}),
    )
}

fn a_len(v: &[V3]) -> f64 {
    v.len().max(1) as f64
}

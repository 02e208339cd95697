//! The residual LSTM (model format 7): `--regressor lstm` learns what the blend regressor leaves of each
//! training sequence's coefficients (cross-fitted: the blend fitted on the other sequences), with early
//! stopping on the last training sequence. Untrained, it is the blend exactly; on a shape with a term no
//! linear map of the pose can express it beats the blend on an unseen motion; a version 6 LSTM (no
//! `residual_of`) still runs as the absolute network it was.

mod support;

use crease_core::progress::NoProgress;
use crease_deep::apply::shapes_from_poses;
use crease_deep::model::{Model, RegressorKind};
use crease_deep::regression::lstm::LstmConfig;
use crease_deep::train::{fit, train, TrainParams, TrainingSequence};
use std::path::Path;

/// Tube frames whose bulge follows a leaky integral of the pose (the blend's autoregressive part can express
/// it) plus a ring term in a² (no linear map of the pose, its velocity and acceleration can).
fn sequence(dir: &Path, frames: usize, freq: f64, phase: f64) -> TrainingSequence {
    let (topo, _) = support::tube(16, 8, |_, _| 0.07);
    let (mut fine, mut poses) = (Vec::new(), Vec::new());
    let mut s = 0.0;
    for t in 0..frames {
        let a = (freq * t as f64 + phase).sin();
        s = 0.8 * s + 0.5 * a;
        poses.push(vec![a, 0.0, 0.2]);
        fine.push(
            support::tube(16, 8, |phi, x| {
                0.07 + 0.004 * s * (6.0 * x).sin()
                    + 0.012 * (a * a - 0.5) * (4.0 * phi).cos() * (3.0 * x).cos()
            })
            .1,
        );
    }
    support::pose_sequence(dir, topo, fine, poses, None)
}

fn params(epochs: usize) -> TrainParams {
    TrainParams {
        k: 4,
        lags: vec![],
        ridge: 1e-6,
        ar_state: 2,
        resolution: 16,
        regressor: RegressorKind::Lstm,
        lstm: LstmConfig {
            layers: 1,
            hidden: 16,
            epochs,
            batch: 16,
            lr: 1e-2,
            ..LstmConfig::default()
        },
        ..Default::default()
    }
}

fn coefficient_error(
    sub: &crease_deep::subspace::Subspace,
    c: &[Vec<f64>],
    t: &[Vec<[f64; 3]>],
) -> f64 {
    let shapes: Vec<Vec<[f64; 3]>> = c.iter().map(|c| sub.reconstruct(c)).collect();
    support::mean_vertex_error(&shapes, t)
}

#[test]
fn the_residual_lstm_starts_as_the_blend_and_learns_what_the_linear_maps_cannot() {
    let tmp = tempfile::tempdir().unwrap();
    let seqs = vec![
        sequence(&tmp.path().join("a"), 60, 0.21, 0.0),
        sequence(&tmp.path().join("b"), 60, 0.13, 1.0),
        sequence(&tmp.path().join("c"), 60, 0.29, 2.0),
    ];
    let held = sequence(&tmp.path().join("held"), 60, 0.17, 0.5);
    let defaults = LstmConfig::default();
    assert_eq!(defaults.residual_of, Some(RegressorKind::Blend));
    assert!(defaults.cross_fit && defaults.early_stopping);

    // No epochs: the zero output layer adds nothing, the LSTM is the blend to the bit.
    let untrained = fit(&seqs, &params(0), &NoProgress).unwrap();
    assert_eq!(
        untrained
            .coefficients(RegressorKind::Lstm, &held.poses)
            .unwrap(),
        untrained
            .coefficients(RegressorKind::Blend, &held.poses)
            .unwrap()
    );
    assert_eq!(untrained.lstm_best_epoch, Some(0));

    let fitted = fit(&seqs, &params(80), &NoProgress).unwrap();
    let best = fitted.lstm_best_epoch.expect("early stopping ran");
    let h = &fitted.lstm_held_out;
    assert_eq!(h.len(), 81, "before training and after each epoch");
    assert!(
        best > 0,
        "no epoch beat the blend on the held-out training sequence: {h:?}"
    );
    assert!(
        h[best] < 0.5 * h[0],
        "held-out MSE {} against the blend's {}",
        h[best],
        h[0]
    );
    assert!(
        h.iter().all(|&e| e >= h[best]),
        "the kept epoch is the best one"
    );
    let sub = &fitted.subspace;
    let blend = coefficient_error(
        sub,
        &fitted
            .coefficients(RegressorKind::Blend, &held.poses)
            .unwrap(),
        &held.fine,
    );
    let lstm = coefficient_error(
        sub,
        &fitted
            .coefficients(RegressorKind::Lstm, &held.poses)
            .unwrap(),
        &held.fine,
    );
    eprintln!(
        "unseen motion: blend {:.3} mm, residual LSTM {:.3} mm (kept epoch {best})",
        blend * 1e3,
        lstm * 1e3
    );
    assert!(
        lstm < 0.8 * blend,
        "residual LSTM {lstm} against the blend {blend}"
    );
}

#[test]
fn a_stored_residual_lstm_adds_to_the_blend_and_a_plain_one_runs_alone() {
    let tmp = tempfile::tempdir().unwrap();
    let seqs = vec![
        sequence(&tmp.path().join("a"), 40, 0.21, 0.0),
        sequence(&tmp.path().join("b"), 40, 0.13, 1.0),
    ];
    let dir = tmp.path().join("model");
    // Without early stopping, so that the 5 epochs are kept whatever they do on the held-out sequence.
    let five = TrainParams {
        lstm: LstmConfig {
            early_stopping: false,
            ..params(5).lstm
        },
        ..params(5)
    };
    train(&seqs, &five, &dir, &NoProgress).unwrap();
    let v7 = Model::load(&dir).unwrap();
    assert_eq!(
        v7.manifest.lstm.as_ref().unwrap().residual_of,
        Some(RegressorKind::Blend)
    );
    let pose = seqs[1].dir.join("pose.json");
    let run = |m: &Model, r| shapes_from_poses(m, &pose, r).unwrap();
    let (lstm, blend) = (
        run(&v7, RegressorKind::Lstm),
        run(&v7, RegressorKind::Blend),
    );
    assert!(lstm != blend, "5 epochs changed the network");

    // The same weights in a model whose LSTM is not residual (`--lstm-residual none`): they are then the
    // shape's coefficients themselves.
    let old = tmp.path().join("plain");
    std::fs::create_dir_all(&old).unwrap();
    for e in std::fs::read_dir(&dir).unwrap() {
        let p = e.unwrap().path();
        std::fs::copy(&p, old.join(p.file_name().unwrap())).unwrap();
    }
    let mpath = old.join("manifest.json");
    let mut m: serde_json::Value = serde_json::from_slice(&std::fs::read(&mpath).unwrap()).unwrap();
    m["lstm"]["residual_of"] = serde_json::Value::Null;
    std::fs::write(&mpath, m.to_string()).unwrap();
    let plain = Model::load(&old).unwrap();
    assert_eq!(plain.manifest.lstm.as_ref().unwrap().residual_of, None);
    let alone = run(&plain, RegressorKind::Lstm);
    // residual = mean + B (blend + net), plain = mean + B net, blend = mean + B blend: residual − blend =
    // plain − mean.
    let mean = crease_deep::subspace::unflatten(&v7.subspace.mean);
    let mut worst: f64 = 0.0;
    for ((a, b), c) in lstm.iter().zip(&blend).zip(&alone) {
        for (((p, q), r), m) in a.iter().zip(b).zip(c).zip(&mean) {
            for k in 0..3 {
                worst = worst.max(((p[k] - q[k]) - (r[k] - m[k])).abs());
            }
        }
    }
    assert!(worst < 1e-9, "residual vs absolute network: {worst}");

    // An LSTM that would correct itself is refused naming the field.
    let bad = tmp.path().join("bad");
    let e = train(
        &seqs,
        &TrainParams {
            lstm: LstmConfig {
                residual_of: Some(RegressorKind::Lstm),
                ..params(1).lstm
            },
            ..params(1)
        },
        &bad,
        &NoProgress,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("residual_of"), "{e}");
    assert!(!bad.exists());
}

//! Subspace (§3.2) and pose-to-shape regression (§3.3) on small synthetic sequences whose shape depends on
//! the pose and its history, like the sleeve's.

mod support;

use crease_core::vec3::V3;
use crease_deep::regression::linear::LinearRegression;
use crease_deep::regression::lstm::{windows, LstmConfig, LstmRegressor};
use crease_deep::regression::pose::ControlSpec;
use crease_deep::subspace::{vertex_error, Subspace};

/// A tube whose radius bulges with a pose signal and a lagged copy of it (history matters).
fn synthetic(n_frames: usize, phase: f64) -> (Vec<Vec<V3>>, Vec<Vec<f64>>) {
    let pose: Vec<f64> = (0..n_frames)
        .map(|t| (0.15 * t as f64 + phase).sin() + 0.6 * (0.41 * t as f64 + 2.0 * phase).sin())
        .collect();
    let frames = (0..n_frames)
        .map(|t| {
            let p = pose[t];
            let lag = pose[t.saturating_sub(4)];
            support::tube(20, 10, |phi, x| {
                0.07 + 0.01 * p * (8.0 * x).sin() + 0.006 * lag * (2.0 * phi).cos()
            })
            .1
        })
        .collect();
    let poses = pose.iter().map(|&p| vec![p, 0.0, 0.3]).collect();
    (frames, poses)
}

#[test]
fn subspace_reconstructs_exactly_with_enough_components_and_error_falls_with_k() {
    let (frames, _) = synthetic(40, 0.0);
    let refs: Vec<&[V3]> = frames.iter().map(|f| f.as_slice()).collect();
    let s = Subspace::fit(&refs, 10).unwrap();
    // The data spans two modes: two components reconstruct it to rounding.
    assert!(s.k() >= 2 && s.k() <= 10);
    let sv = &s.singular_values;
    assert!(
        sv[0] >= sv[1] && sv[1] > 1e-3 * sv[0] && sv[2] < 1e-6 * sv[0],
        "{:?}",
        &sv[..4]
    );
    let mut errs = Vec::new();
    for k in [1, 2] {
        let t = s.truncated(k);
        let e: f64 = frames
            .iter()
            .map(|f| vertex_error(&t.reconstruct(&t.project(f, k)), f).0)
            .sum::<f64>()
            / 40.0;
        errs.push(e);
    }
    assert!(
        errs[0] > 1e-4,
        "one component misses the second mode: {}",
        errs[0]
    );
    assert!(errs[1] < 1e-9, "two components are exact: {}", errs[1]);
    // Components are orthonormal.
    let b = &s.basis;
    let g = b.transpose() * b;
    for i in 0..s.k().min(2) {
        for j in 0..s.k().min(2) {
            let want = if i == j { 1.0 } else { 0.0 };
            assert!((g[(i, j)] - want).abs() < 1e-9);
        }
    }
    assert!(Subspace::fit(&refs[..1], 3).is_err());
}

#[test]
fn linear_regression_needs_the_pose_history_to_predict_history_dependent_shapes() {
    let (train_f, train_p) = synthetic(120, 0.0);
    let (test_f, test_p) = synthetic(60, 1.3);
    let refs: Vec<&[V3]> = train_f.iter().map(|f| f.as_slice()).collect();
    let s = Subspace::fit(&refs, 4).unwrap();
    let k = s.k();
    let coeffs: Vec<Vec<f64>> = train_f.iter().map(|f| s.project(f, k)).collect();
    let err_with = |lags: Vec<usize>| {
        let spec = ControlSpec::fit(&[&train_p], lags).unwrap();
        let reg = LinearRegression::fit(&spec.controls(&train_p).unwrap(), &coeffs, 1e-6).unwrap();
        let c = spec.controls(&test_p).unwrap();
        test_f
            .iter()
            .zip(&c)
            .map(|(f, c)| vertex_error(&s.reconstruct(&reg.predict(c)), f).0)
            .sum::<f64>()
            / test_f.len() as f64
    };
    let no_history = err_with(vec![]);
    let history = err_with(vec![1, 2, 4, 8]);
    assert!(
        history < 0.5 * no_history,
        "with lags {history:.2e} vs without {no_history:.2e}"
    );
    assert!(history < 1e-3, "lagged linear model error {history:.2e} m");
}

#[test]
fn lstm_loss_falls_and_training_is_deterministic() {
    let (frames, poses) = synthetic(60, 0.0);
    let refs: Vec<&[V3]> = frames.iter().map(|f| f.as_slice()).collect();
    let s = Subspace::fit(&refs, 3).unwrap();
    let coeffs: Vec<Vec<f64>> = frames.iter().map(|f| s.project(f, s.k())).collect();
    let spec = ControlSpec::fit(&[&poses], vec![2, 4]).unwrap();
    let controls = spec.controls(&poses).unwrap();
    let scale: Vec<f64> = (0..s.k())
        .map(|j| (coeffs.iter().map(|c| c[j] * c[j]).sum::<f64>() / coeffs.len() as f64).sqrt())
        .collect();
    let cfg = LstmConfig {
        layers: 2,
        hidden: 16,
        seq_len: 3,
        epochs: 40,
        batch: 16,
        lr: 5e-3,
        seed: 7,
        residual_of: None,
        cross_fit: false,
        early_stopping: false,
    };
    let data = windows(&controls, &coeffs, 3);
    let run = || {
        let mut net = LstmRegressor::new(cfg.clone(), spec.len(), s.k(), scale.clone()).unwrap();
        let losses = net.train(&data, |_, _| {}).unwrap();
        let pred = net.predict(&data).unwrap();
        (losses, pred)
    };
    let (l1, p1) = run();
    let (l2, p2) = run();
    assert_eq!(l1.len(), 40);
    assert!(l1[39] < 0.3 * l1[0], "loss {} -> {}", l1[0], l1[39]);
    assert_eq!(p1.len(), 60);
    assert_eq!(p1[0].len(), s.k());
    let bytes = |p: &Vec<Vec<f64>>| {
        p.iter()
            .flatten()
            .flat_map(|x| x.to_le_bytes())
            .collect::<Vec<u8>>()
    };
    assert_eq!(bytes(&p1), bytes(&p2), "same seed, same predictions");
    assert_eq!(l1, l2);
}

/// The LSTM's output unit: one shared scale makes the training loss the vertex MSE, so a large predictable
/// component is learned even when many small unpredictable ones sit beside it (PCA coefficients of cloth: the
/// first few carry the motion, the last hundreds fold detail no pose predicts). In units of each coefficient's
/// own standard deviation the small ones dominate the loss and the large one is learned worse.
#[test]
fn lstm_shared_output_unit_learns_the_large_component() {
    use crease_deep::regression::lstm::{cosine_lr, output_scale};
    let n = 90;
    let poses: Vec<Vec<f64>> = (0..n)
        .map(|t| {
            let t = t as f64;
            vec![(0.2 * t).sin(), (0.13 * t).cos()]
        })
        .collect();
    let spec = ControlSpec::fit(&[&poses], vec![]).unwrap();
    let controls = spec.controls(&poses).unwrap();
    let mut rng = crease_deep::nn::seed::Rng::new(5);
    let targets: Vec<Vec<f64>> = poses
        .iter()
        .map(|p| {
            let mut c = vec![3.0 * p[0] * p[1] + p[0]];
            c.extend((0..40).map(|_| 0.02 * (rng.uniform() - 0.5)));
            c
        })
        .collect();
    let big_sd = (targets.iter().map(|c| c[0] * c[0]).sum::<f64>() / n as f64).sqrt();
    let shared = output_scale(&targets);
    assert_eq!(shared.len(), 41);
    assert!(shared.iter().all(|&s| s == shared[0]));
    let per_coefficient: Vec<f64> = (0..41)
        .map(|j| (targets.iter().map(|c| c[j] * c[j]).sum::<f64>() / n as f64).sqrt())
        .collect();
    let cfg = LstmConfig {
        layers: 2,
        hidden: 16,
        seq_len: 3,
        epochs: 60,
        batch: 16,
        lr: 5e-3,
        seed: 3,
        residual_of: None,
        cross_fit: false,
        early_stopping: false,
    };
    let data = windows(&controls, &targets, 3);
    let big_rms = |scale: Vec<f64>| -> f64 {
        let mut net = LstmRegressor::new(cfg.clone(), spec.len(), 41, scale).unwrap();
        let losses = net
            .train_scheduled(&data, cosine_lr(cfg.lr, cfg.epochs), |_, _| {})
            .unwrap();
        assert!(losses[cfg.epochs - 1] < losses[0]);
        let pred = net.predict(&data).unwrap();
        (pred
            .iter()
            .zip(&targets)
            .map(|(p, t)| (p[0] - t[0]).powi(2))
            .sum::<f64>()
            / n as f64)
            .sqrt()
    };
    let (with_shared, with_own) = (big_rms(shared), big_rms(per_coefficient));
    eprintln!(
        "large component RMS error: shared unit {:.4}, per-coefficient units {:.4} (its sd {big_sd:.4})",
        with_shared, with_own
    );
    // Measured: 0.318 with the shared unit, 0.697 with per-coefficient units (sd 1.60). Both bounds fail with
    // per-coefficient units.
    assert!(
        with_shared < 0.3 * big_sd,
        "shared unit: {with_shared} of {big_sd}"
    );
    assert!(
        with_shared < 0.6 * with_own,
        "shared {with_shared} against per-coefficient {with_own}"
    );
}

//! Autoregressive regression (§3.3 with the previous shape coefficients in the control vector): on a system
//! whose state is its history, the rollout from pose alone recovers what a pose-only map cannot.

use crease_deep::regression::autoregress::{
    AutoregressiveLinear, ControlsAndCoefficients, ShapeHistory,
};
use crease_deep::regression::linear::LinearRegression;

/// A leaky integrator of the pose: a_t = 0.8 a_{t−1} + 0.5 pose_t, two coefficients (the second a copy scaled
/// by −2), so the shape at a pose depends on the poses before it.
fn sequence(freq: f64, phase: f64, n: usize) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let mut a = 0.0;
    let mut controls = Vec::new();
    let mut coeffs = Vec::new();
    for t in 0..n {
        let pose = (freq * t as f64 + phase).sin();
        a = 0.8 * a + 0.5 * pose;
        controls.push(vec![pose, 1.0]);
        coeffs.push(vec![a, -2.0 * a]);
    }
    (controls, coeffs)
}

fn rms(a: &[Vec<f64>], b: &[Vec<f64>]) -> f64 {
    let s: f64 = a
        .iter()
        .zip(b)
        .flat_map(|(x, y)| x.iter().zip(y).map(|(p, q)| (p - q).powi(2)))
        .sum();
    (s / (a.len() * a[0].len()) as f64).sqrt()
}

#[test]
fn rollout_from_pose_alone_recovers_a_history_dependent_shape() {
    let train = [sequence(0.21, 0.0, 150), sequence(0.13, 1.0, 150)];
    let test = sequence(0.17, 2.0, 150);
    let seqs: Vec<ControlsAndCoefficients> = train
        .iter()
        .map(|(c, a)| (c.as_slice(), a.as_slice()))
        .collect();
    let a_refs: Vec<&[Vec<f64>]> = train.iter().map(|(_, a)| a.as_slice()).collect();
    let hist = ShapeHistory::fit(&a_refs, 1, 2).unwrap();
    let ar = AutoregressiveLinear::fit(&seqs, hist, 1e-6, 2).unwrap();
    let rolled = ar.rollout(&test.0);
    assert_eq!(rolled.len(), 150);
    // Pose-only ridge on the same data.
    let all_c: Vec<Vec<f64>> = train.iter().flat_map(|s| s.0.clone()).collect();
    let all_a: Vec<Vec<f64>> = train.iter().flat_map(|s| s.1.clone()).collect();
    let lin = LinearRegression::fit(&all_c, &all_a, 1e-6).unwrap();
    let pose_only: Vec<Vec<f64>> = test.0.iter().map(|c| lin.predict(c)).collect();
    let (e_ar, e_lin) = (rms(&rolled, &test.1), rms(&pose_only, &test.1));
    eprintln!("rms: autoregressive rollout {e_ar:.2e}, pose only {e_lin:.2e}");
    assert!(
        e_lin > 0.1,
        "the pose alone should not determine this shape ({e_lin})"
    );
    assert!(e_ar < 0.1 * e_lin, "rollout {e_ar} vs pose-only {e_lin}");
    // The start state comes from the training sequences' first frames, not from the test sequence.
    let first_mean = (train[0].1[0][0] + train[1].1[0][0]) / 2.0;
    assert!((ar.history.start[0] - first_mean).abs() < 1e-12);
}

#[test]
fn shape_history_rejects_bad_parameters_by_name() {
    let a = vec![vec![1.0, 2.0], vec![3.0, 4.0]];
    let err = ShapeHistory::fit(&[a.as_slice()], 3, 2)
        .unwrap_err()
        .to_string();
    assert!(err.contains("k_state"), "{err}");
    let err = ShapeHistory::fit(&[a.as_slice()], 1, 0)
        .unwrap_err()
        .to_string();
    assert!(err.contains("order"), "{err}");
    let hist = ShapeHistory::fit(&[a.as_slice()], 2, 1).unwrap();
    let c = vec![vec![1.0]];
    let err = AutoregressiveLinear::fit(&[(c.as_slice(), a.as_slice())], hist, 1e-3, 0)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("sequence 1") && err.contains("1 control vectors for 2"),
        "{err}"
    );
}

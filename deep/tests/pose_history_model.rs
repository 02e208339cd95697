//! Decayed pose history in a stored model: trained with `pose_history`, the control vector carries leaky
//! averages of the pose, the manifest records them (format version 3), apply rebuilds the same controls from
//! the pose file, and on a cloth whose shape is a leaky integral of the pose they beat the pose-only map on a
//! held-out motion. A model of a newer format is refused by name.

mod support;

use crease_core::progress::NoProgress;
use crease_deep::apply::shapes_from_poses;
use crease_deep::model::{Model, RegressorKind, MODEL_VERSION};
use crease_deep::train::{train, TrainParams, TrainingSequence};
use std::path::Path;

/// A tube whose bulge follows a slow leaky integral of the pose (s_t = 0.9 s_{t−1} + 0.3 pose_t): the shape
/// depends on the last ~10 poses, not on the current one alone. Like the sleeve, it starts at rest: settled
/// at its first pose.
fn sequence(dir: &Path, frames: usize, freq: f64, phase: f64) -> TrainingSequence {
    let (topo, _) = support::tube(16, 8, |_, _| 0.07);
    let (mut fine, mut poses) = (Vec::new(), Vec::new());
    let mut s = 3.0 * phase.sin();
    for t in 0..frames {
        let a = (freq * t as f64 + phase).sin();
        s = 0.9 * s + 0.3 * a;
        poses.push(vec![a, 0.0]);
        fine.push(
            support::tube(16, 8, |phi, x| {
                0.07 + 0.01 * s * (6.0 * x).sin() + 0.002 * a * phi.cos()
            })
            .1,
        );
    }
    support::pose_sequence(dir, topo, fine, poses, None)
}

fn params(pose_history: Vec<f64>) -> TrainParams {
    TrainParams {
        k: 4,
        ridge: 1e-6,
        ar_state: 2,
        pose_history,
        resolution: 16,
        ..Default::default()
    }
}

#[test]
fn history_features_are_stored_rebuilt_by_apply_and_carry_the_cloths_memory() {
    let tmp = tempfile::tempdir().unwrap();
    let seqs = vec![
        sequence(&tmp.path().join("a"), 80, 0.21, 0.0),
        sequence(&tmp.path().join("b"), 80, 0.13, 1.0),
    ];
    let held = sequence(&tmp.path().join("held"), 80, 0.17, 2.0);
    let pose_file = held.dir.join("pose.json");

    let plain_dir = tmp.path().join("plain");
    train(&seqs, &params(vec![]), &plain_dir, &NoProgress).unwrap();
    let hist_dir = tmp.path().join("history");
    train(&seqs, &params(vec![3.0, 10.0]), &hist_dir, &NoProgress).unwrap();
    let plain = Model::load(&plain_dir).unwrap();
    let hist = Model::load(&hist_dir).unwrap();
    assert_eq!(hist.manifest.version, MODEL_VERSION);
    let h = hist
        .manifest
        .control
        .history
        .as_ref()
        .expect("history in the manifest");
    assert_eq!(h.time_constants, vec![3.0, 10.0]);
    assert!(plain.manifest.control.history.is_none());
    // Two time constants × two pose numbers more per control vector.
    assert_eq!(
        hist.manifest.control.len(),
        plain.manifest.control.len() + 4
    );

    let lin_plain = shapes_from_poses(&plain, &pose_file, RegressorKind::Linear).unwrap();
    let lin_hist = shapes_from_poses(&hist, &pose_file, RegressorKind::Linear).unwrap();
    let (e_plain, e_hist) = (
        support::mean_vertex_error(&lin_plain, &held.fine),
        support::mean_vertex_error(&lin_hist, &held.fine),
    );
    eprintln!("held-out linear: pose only {e_plain:.2e} m, with history {e_hist:.2e} m");
    assert!(
        e_plain > 3e-4,
        "the pose alone should not determine the shape"
    );
    assert!(
        e_hist < 0.3 * e_plain,
        "history {e_hist} vs pose only {e_plain}"
    );
    // The autoregressive regressor on the longer control vector runs too and is no worse than pose only.
    let ar_hist = shapes_from_poses(&hist, &pose_file, RegressorKind::Autoregressive).unwrap();
    let e_ar = support::mean_vertex_error(&ar_hist, &held.fine);
    assert!(
        e_ar < e_plain,
        "autoregressive with history {e_ar} vs pose only {e_plain}"
    );

    // A frame's shape depends on the poses before it only: a change at frame 50 leaves frames 1..49 alone.
    let mut poses = held.poses.clone();
    poses[49][0] += 0.5;
    let changed = tmp.path().join("changed.json");
    std::fs::write(
        &changed,
        serde_json::json!({ "pose_vectors": poses }).to_string(),
    )
    .unwrap();
    let other = shapes_from_poses(&hist, &changed, RegressorKind::Linear).unwrap();
    assert_eq!(&other[..49], &lin_hist[..49]);
    assert_ne!(other[49], lin_hist[49]);
}

#[test]
fn a_model_of_a_newer_format_is_refused_by_name() {
    let tmp = tempfile::tempdir().unwrap();
    let seqs = vec![
        sequence(&tmp.path().join("a"), 30, 0.21, 0.0),
        sequence(&tmp.path().join("b"), 30, 0.13, 1.0),
    ];
    let dir = tmp.path().join("model");
    train(&seqs, &params(vec![]), &dir, &NoProgress).unwrap();
    let mut manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("manifest.json")).unwrap()).unwrap();
    assert!(manifest["control"].get("history").is_none());
    manifest["version"] = (MODEL_VERSION + 1).into();
    std::fs::write(dir.join("manifest.json"), manifest.to_string()).unwrap();
    let e = Model::load(&dir).err().expect("refused").to_string();
    assert!(
        e.contains("manifest.json") && e.contains(&format!("version {}", MODEL_VERSION + 1)),
        "{e}"
    );
}

//! The autoregressive regressor inside a stored model: `crease deep train` fits and stores it, `apply --pose`
//! rolls it out from the first frame exactly as the loop written out below does, and a version 1 model
//! (which has none) is still read but refuses it by name.

mod support;

use crease_core::npy;
use crease_core::progress::NoProgress;
use crease_deep::apply::{apply, shapes_from_poses, ApplyInput, ApplyParams};
use crease_deep::model::{Model, RegressorKind};
use crease_deep::train::{fit, train, TrainParams};
use std::path::Path;
use support::leaky_sequence as sequence;

fn params() -> TrainParams {
    TrainParams {
        k: 4,
        lags: vec![],
        ridge: 1e-6,
        ar_state: 2,
        resolution: 16,
        // The blend of this rollout and the linear map (the kernel regressor is the library's default).
        regressor: RegressorKind::Blend,
        ..Default::default()
    }
}

fn array(dir: &Path, name: &str) -> (Vec<usize>, Vec<f64>) {
    let p = dir.join(name);
    npy::from_bytes::<f64>(&p, &std::fs::read(&p).unwrap()).unwrap()
}

#[test]
fn stored_rollout_equals_a_hand_rolled_loop_and_beats_the_pose_only_map() {
    let tmp = tempfile::tempdir().unwrap();
    let seqs = vec![
        sequence(&tmp.path().join("a"), 60, 0.21, 0.0),
        sequence(&tmp.path().join("b"), 60, 0.13, 1.0),
    ];
    let held = sequence(&tmp.path().join("held"), 60, 0.17, 2.0);
    let dir = tmp.path().join("model");
    train(&seqs, &params(), &dir, &NoProgress).unwrap();
    let model = Model::load(&dir).unwrap();
    assert_eq!(model.manifest.version, crease_deep::model::MODEL_VERSION);
    assert_eq!(
        model.manifest.regressor,
        RegressorKind::Blend,
        "as trained: this rollout blended with the linear map"
    );
    // The stored regressor is the fitted one, bit for bit.
    let fitted = fit(&seqs, &params(), &NoProgress).unwrap();
    assert_eq!(model.autoregressive.as_ref(), Some(&fitted.autoregressive));

    // The rollout written out from the model's files: x_t = [Θ_t, clip(s ⊙ α_{t−1}[..k_state]),
    // clip(s ⊙ α_{t−2}[..k_state])], α_t = W x_t, frames before the first at the stored start state.
    let spec = model.manifest.autoregressive.clone().unwrap();
    assert_eq!((spec.k_state, spec.order), (2, 2));
    let (wshape, w) = array(&dir, "autoregressive.npy");
    let (_, scale) = array(&dir, "ar_scale.npy");
    let (_, start) = array(&dir, "ar_start.npy");
    let (k, m) = (wshape[0], wshape[1]);
    let controls = model.manifest.control.controls(&held.poses).unwrap();
    assert_eq!(m, controls[0].len() + 2 * 2);
    let mut alphas: Vec<Vec<f64>> = Vec::new();
    for (t, c) in controls.iter().enumerate() {
        let mut x = c.clone();
        for lag in 1..=2 {
            let prev = if t >= lag { &alphas[t - lag] } else { &start };
            for j in 0..2 {
                x.push((prev[j] * scale[j]).clamp(-spec.clip, spec.clip));
            }
        }
        alphas.push(
            (0..k)
                .map(|r| (0..m).map(|i| w[r * m + i] * x[i]).sum())
                .collect(),
        );
    }
    let by_hand: Vec<Vec<[f64; 3]>> = alphas
        .iter()
        .map(|a| model.subspace.reconstruct(a))
        .collect();
    let pose_file = held.dir.join("pose.json");
    let rolled = shapes_from_poses(&model, &pose_file, RegressorKind::Autoregressive).unwrap();
    assert_eq!(rolled.len(), 60);
    let diff = support::mean_vertex_error(&rolled, &by_hand);
    assert!(diff < 1e-12, "rollout vs hand-rolled loop: {diff}");

    // On the held-out motion the history matters: the rollout is closer to the truth than the pose-only map.
    let linear = shapes_from_poses(&model, &pose_file, RegressorKind::Linear).unwrap();
    let (e_ar, e_lin) = (
        support::mean_vertex_error(&rolled, &held.fine),
        support::mean_vertex_error(&linear, &held.fine),
    );
    eprintln!("held-out mean vertex error: autoregressive {e_ar:.2e} m, linear {e_lin:.2e} m");
    assert!(
        e_lin > 2e-4,
        "the pose alone should not determine the shape"
    );
    assert!(
        e_ar < 0.5 * e_lin,
        "autoregressive {e_ar} vs linear {e_lin}"
    );

    // A frame range (a job's chunk) writes the bytes of the full run's frames.
    let full = tmp.path().join("full");
    let input = ApplyInput::Pose(pose_file.clone());
    apply(&model, &input, &ApplyParams::default(), &full, &NoProgress).unwrap();
    let part = tmp.path().join("part");
    let chunk = ApplyParams {
        frames: Some(40..44),
        ..Default::default()
    };
    apply(&model, &input, &chunk, &part, &NoProgress).unwrap();
    for t in 41..=44 {
        for f in [
            format!("mesh/frame_{t:04}.obj"),
            format!("normals/frame_{t:04}.png"),
        ] {
            assert_eq!(
                std::fs::read(full.join(&f)).unwrap(),
                std::fs::read(part.join(&f)).unwrap(),
                "{f}"
            );
        }
    }
}

#[test]
fn models_of_older_versions_are_refused_by_version_and_missing_regressors_by_name() {
    let tmp = tempfile::tempdir().unwrap();
    let seqs = vec![
        sequence(&tmp.path().join("a"), 30, 0.21, 0.0),
        sequence(&tmp.path().join("b"), 30, 0.13, 1.0),
    ];
    let dir = tmp.path().join("model");
    train(&seqs, &params(), &dir, &NoProgress).unwrap();
    let v = Model::load(&dir).unwrap();
    let pose = seqs[0].dir.join("pose.json");
    // No LSTM was trained: asking for it is refused naming the model.
    let e = shapes_from_poses(&v, &pose, RegressorKind::Lstm)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("manifest.json") && e.contains("no lstm regressor"),
        "{e}"
    );
    // A model of an older format (its detail and pose low-pass were tied to one data set's capture) is refused
    // by version, with what to do.
    let path = dir.join("manifest.json");
    let mut manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    manifest["version"] = (crease_deep::model::MODEL_VERSION_MIN - 1).into();
    std::fs::write(&path, manifest.to_string()).unwrap();
    let e = Model::load(&dir).err().unwrap().to_string();
    assert!(
        e.contains("manifest.json")
            && e.contains(&format!(
                "version {}",
                crease_deep::model::MODEL_VERSION_MIN - 1
            ))
            && e.contains("retrain"),
        "{e}"
    );
}

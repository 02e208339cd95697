//! The kernel regressor inside a stored model: `crease deep train` stores its centres, dual weights and the
//! width, ridge and input weights its inner leave-one-out chose (format version 11); `apply --pose` reproduces the fitted
//! predictions from the stored files; on a shape that is a nonlinear function of the last poses it beats the
//! linear map on an unseen motion; a model without it, or with damaged arrays, is refused naming the file.

mod support;

use crease_core::progress::NoProgress;
use crease_core::vec3::V3;
use crease_deep::apply::{apply, shapes_from_poses, ApplyInput, ApplyParams};
use crease_deep::model::{Model, RegressorKind, MODEL_VERSION};
use crease_deep::regression::kernel::{OUTSIDE, RIDGES, WIDTHS};
use crease_deep::train::{fit, train, TrainParams, TrainingSequence};
use std::path::Path;

/// A tube whose bulge is the product of the cuff's travel and its twist a few frames ago (no linear map of
/// the poses holds a product), driven by two incommensurate motions per sequence.
fn sequence(dir: &Path, frames: usize, f1: f64, f2: f64, phase: f64) -> TrainingSequence {
    let (topo, _) = support::tube(16, 8, |_, _| 0.07);
    let mut poses: Vec<Vec<f64>> = Vec::new();
    let mut fine: Vec<Vec<V3>> = Vec::new();
    for t in 0..frames {
        let travel = (f1 * t as f64 + phase).sin();
        let twist = (f2 * t as f64 + 2.0 * phase).cos();
        poses.push(vec![travel, twist]);
        let back = &poses[t.saturating_sub(2)];
        let bulge = travel * back[1];
        fine.push(
            support::tube(16, 8, |phi, x| {
                0.07 + 0.01 * bulge * (6.0 * x).sin() + 0.002 * travel * phi.cos()
            })
            .1,
        );
    }
    support::pose_sequence(dir, topo, fine, poses, None)
}

fn params() -> TrainParams {
    TrainParams {
        k: 6,
        ridge: 1e-6,
        ar_state: 2,
        resolution: 16,
        regressor: RegressorKind::Kernel,
        kernel_window: vec![0, 2],
        ..Default::default()
    }
}

#[test]
fn the_stored_kernel_reproduces_its_fit_and_beats_the_linear_map_on_an_unseen_motion() {
    let tmp = tempfile::tempdir().unwrap();
    let seqs: Vec<TrainingSequence> = (0..3)
        .map(|i| {
            let i = i as f64;
            sequence(
                &tmp.path().join(format!("s{i}")),
                70,
                0.11 + 0.03 * i,
                0.07 + 0.02 * i,
                0.9 * i,
            )
        })
        .collect();
    let held = sequence(&tmp.path().join("held"), 70, 0.15, 0.1, 2.2);
    let dir = tmp.path().join("model");
    train(&seqs, &params(), &dir, &NoProgress).unwrap();
    let model = Model::load(&dir).unwrap();
    assert_eq!(model.manifest.version, MODEL_VERSION);
    assert_eq!(model.manifest.regressor, RegressorKind::Kernel);
    let spec = model.manifest.kernel.clone().expect("a kernel spec");
    assert_eq!(spec.method, "inner-leave-one-out");
    assert_eq!(spec.scores.len(), WIDTHS.len() * RIDGES.len());
    assert_eq!(spec.centres, 3 * 70, "every training frame is a centre");
    assert!(WIDTHS.contains(&spec.width) && RIDGES.contains(&spec.ridge));

    // The stored arrays give what the fit gives, bit for bit.
    let fitted = fit(&seqs, &params(), &NoProgress).unwrap();
    assert_eq!(fitted.kernel.spec, spec);
    let coeffs = fitted
        .coefficients(RegressorKind::Kernel, &held.poses)
        .unwrap();
    let expect: Vec<Vec<V3>> = coeffs
        .iter()
        .map(|c| fitted.subspace.reconstruct(c))
        .collect();
    let pose = held.dir.join("pose.json");
    let got = shapes_from_poses(&model, &pose, RegressorKind::Kernel).unwrap();
    assert_eq!(got, expect, "apply --pose differs from the fit");

    let lin = shapes_from_poses(&model, &pose, RegressorKind::Linear).unwrap();
    let (e_kernel, e_lin) = (
        support::mean_vertex_error(&got, &held.fine),
        support::mean_vertex_error(&lin, &held.fine),
    );
    eprintln!("held-out error: kernel {e_kernel:.2e} m, linear {e_lin:.2e} m");
    assert!(
        e_kernel < 0.5 * e_lin,
        "kernel {e_kernel} vs linear {e_lin}"
    );

    // `apply --pose` says which frames lie outside what the kernel learned: none of a motion like the
    // training ones, the frames of a travel five times as long.
    let run = |pose: &Path, name: &str| {
        apply(
            &model,
            &ApplyInput::Pose(pose.to_path_buf()),
            &ApplyParams::default(),
            &tmp.path().join(name),
            &NoProgress,
        )
        .unwrap()
    };
    assert!(run(&pose, "near").outside.is_empty());
    let far: Vec<Vec<f64>> = held.poses.iter().map(|p| vec![5.0 * p[0], p[1]]).collect();
    let far_pose = tmp.path().join("far.json");
    std::fs::write(
        &far_pose,
        serde_json::json!({ "pose_vectors": far }).to_string(),
    )
    .unwrap();
    let outside = run(&far_pose, "far").outside;
    assert!(
        !outside.is_empty() && outside.iter().all(|(_, d)| *d > OUTSIDE),
        "{outside:?}"
    );
    // Where the travel is small the five-fold motion stays among the trained ones.
    assert!(outside.len() < 70, "{}", outside.len());
}

#[test]
fn a_model_without_a_kernel_or_with_a_damaged_one_is_refused_by_name() {
    let tmp = tempfile::tempdir().unwrap();
    let seqs: Vec<TrainingSequence> = (0..2)
        .map(|i| {
            let i = i as f64;
            sequence(
                &tmp.path().join(format!("s{i}")),
                40,
                0.13 + 0.02 * i,
                0.09,
                i,
            )
        })
        .collect();
    let dir = tmp.path().join("model");
    train(&seqs, &params(), &dir, &NoProgress).unwrap();
    let manifest_path = dir.join("manifest.json");
    let original = std::fs::read(&manifest_path).unwrap();
    let edit = |f: &dyn Fn(&mut serde_json::Value)| {
        let mut m: serde_json::Value = serde_json::from_slice(&original).unwrap();
        f(&mut m);
        std::fs::write(&manifest_path, serde_json::to_string_pretty(&m).unwrap()).unwrap();
    };

    // A version 9 model has no kernel: it loads, and asking for the kernel names the model and what to do.
    edit(&|m| {
        m["version"] = 9.into();
        m.as_object_mut().unwrap().remove("kernel");
        m["regressor"] = "blend".into();
    });
    let old = Model::load(&dir).unwrap();
    let e = old
        .check_regressor(RegressorKind::Kernel)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("manifest.json") && e.contains("kernel") && e.contains("retrain"),
        "{e}"
    );

    // Centres that do not match the stored arrays.
    edit(&|m| m["kernel"]["centres"] = 7.into());
    let e = Model::load(&dir).err().expect("refused").to_string();
    assert!(
        e.contains("kernel_dual.npy") && e.contains("7 centres"),
        "{e}"
    );

    // A width that is no width.
    edit(&|m| m["kernel"]["width"] = (-1.0).into());
    let e = Model::load(&dir).err().expect("refused").to_string();
    assert!(e.contains("kernel") && e.contains("width -1"), "{e}");

    // A dual-weight file from elsewhere fails its hash.
    std::fs::write(&manifest_path, &original).unwrap();
    let dual = dir.join("kernel_dual.npy");
    let mut bytes = std::fs::read(&dual).unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 1;
    std::fs::write(&dual, bytes).unwrap();
    let e = Model::load(&dir).err().expect("refused").to_string();
    assert!(e.contains("kernel_dual.npy"), "{e}");
}

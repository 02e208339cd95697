//! Issue 12 item 9: bad inputs get clear errors naming the file, frame or field; a half-written or foreign
//! model is never taken for a complete one.

mod support;

use crease_core::mesh::io::write_obj;
use crease_core::progress::NoProgress;
use crease_deep::apply::{apply, ApplyInput, ApplyParams};
use crease_deep::model::Model;
use crease_deep::regression::pose::read_pose_file;
use crease_deep::train::{layout_for, train, TrainParams, TrainingSequence};
use std::path::Path;

fn sequence(dir: &Path, frames: usize, phase: f64) -> TrainingSequence {
    let (topo, _) = support::tube(16, 8, |_, _| 0.07);
    let mut fine = Vec::new();
    let mut poses = Vec::new();
    for t in 0..frames {
        let a = (0.4 * t as f64 + phase).sin();
        poses.push(vec![a, 0.0, 0.2]);
        fine.push(
            support::tube(16, 8, |phi, x| {
                0.07 + 0.01 * a * (6.0 * x).sin() + 0.003 * a * (4.0 * phi).cos()
            })
            .1,
        );
    }
    TrainingSequence {
        dir: dir.to_path_buf(),
        topology: topo,
        fine,
        poses,
        pose_names: None,
    }
}

fn err<T>(r: crease_core::Result<T>) -> String {
    match r {
        Ok(_) => panic!("expected an error"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn pose_files_with_nan_wrong_count_or_wrong_length_are_named() {
    let tmp = tempfile::tempdir().unwrap();
    let p = tmp.path().join("pose.json");
    std::fs::write(&p, r#"{"pose_vectors": [[0.5, 0, 0], [0.4, NaN, 0]]}"#).unwrap();
    let e = err(read_pose_file(&p, None));
    assert!(
        e.contains("pose.json") && e.contains("frame 2") && e.contains("pose_vectors[1][1]"),
        "{e}"
    );
    std::fs::write(&p, r#"{"pose_vectors": [[0.5, 0, 0], [0.4, 0, 0]]}"#).unwrap();
    let e = err(read_pose_file(&p, Some(3)));
    assert!(
        e.contains("pose.json") && e.contains("2 pose vectors") && e.contains("3 frames"),
        "{e}"
    );
    std::fs::write(&p, r#"{"pose_vectors": [[0.5, 0, 0], [0.4, 0]]}"#).unwrap();
    let e = err(read_pose_file(&p, None));
    assert!(e.contains("frame 2") && e.contains("2 numbers"), "{e}");
    std::fs::write(&p, r#"{"frames": []}"#).unwrap();
    assert!(err(read_pose_file(&p, None)).contains("pose_vectors"));
    assert!(read_pose_file(&p.with_file_name("ok.json"), None).is_err());
}

#[test]
fn models_meshes_and_uv_requirements_are_checked() {
    let tmp = tempfile::tempdir().unwrap();
    let seqs = vec![
        sequence(&tmp.path().join("a"), 10, 0.0),
        sequence(&tmp.path().join("b"), 10, 0.9),
    ];
    let model_dir = tmp.path().join("model");
    let params = TrainParams {
        k: 3,
        lags: vec![1],
        resolution: 16,
        ..Default::default()
    };
    train(&seqs, &params, &model_dir, &NoProgress).unwrap();
    let model = Model::load(&model_dir).unwrap();

    // Pose vectors of another length than the model's.
    let pose = tmp.path().join("short.json");
    std::fs::write(&pose, r#"{"pose_vectors": [[0.5, 0.1], [0.5, 0.2]]}"#).unwrap();
    let e = err(apply(
        &model,
        &ApplyInput::Pose(pose),
        &ApplyParams::default(),
        &tmp.path().join("o1"),
        &NoProgress,
    ));
    assert!(
        e.contains("short.json") && e.contains("2 numbers") && e.contains("trained on 3"),
        "{e}"
    );

    // Coarse meshes of another topology.
    let other = tmp.path().join("other");
    std::fs::create_dir_all(&other).unwrap();
    let (topo, p) = support::tube(16, 7, |_, _| 0.07);
    write_obj(&other.join("frame_0001.obj"), &topo, &p).unwrap();
    let e = err(apply(
        &model,
        &ApplyInput::Coarse(other),
        &ApplyParams::default(),
        &tmp.path().join("o2"),
        &NoProgress,
    ));
    assert!(
        e.contains("other") && e.contains("do not match the model's topology"),
        "{e}"
    );

    // A model from another format version, a damaged file, a half-written model.
    let copy = |name: &str| {
        let d = tmp.path().join(name);
        std::fs::create_dir_all(&d).unwrap();
        for e in std::fs::read_dir(&model_dir).unwrap() {
            let p = e.unwrap().path();
            std::fs::copy(&p, d.join(p.file_name().unwrap())).unwrap();
        }
        d
    };
    let old = copy("old");
    let m = std::fs::read_to_string(old.join("manifest.json"))
        .unwrap()
        .replace(
            &format!("\"version\": {}", crease_deep::model::MODEL_VERSION),
            "\"version\": 99",
        );
    std::fs::write(old.join("manifest.json"), m).unwrap();
    let e = err(Model::load(&old));
    let range = format!(
        "reads versions {} to {}",
        crease_deep::model::MODEL_VERSION_MIN,
        crease_deep::model::MODEL_VERSION
    );
    assert!(
        e.contains("manifest.json") && e.contains("version 99") && e.contains(&range),
        "{e}"
    );
    let damaged = copy("damaged");
    let mut bytes = std::fs::read(damaged.join("basis.npy")).unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 0x55;
    std::fs::write(damaged.join("basis.npy"), bytes).unwrap();
    let e = err(Model::load(&damaged));
    assert!(
        e.contains("basis.npy") && e.contains("does not match the model manifest"),
        "{e}"
    );
    let half = copy("half");
    std::fs::remove_file(half.join("manifest.json")).unwrap();
    let e = err(Model::load(&half));
    assert!(e.contains("not a complete"), "{e}");
    // Training that fails leaves no model and no staging directory behind.
    let bad = TrainParams {
        k: 0,
        ..params.clone()
    };
    assert!(train(&seqs, &bad, &tmp.path().join("never"), &NoProgress).is_err());
    assert!(!tmp.path().join("never").exists());
    assert!(std::fs::read_dir(tmp.path()).unwrap().all(|e| !e
        .unwrap()
        .file_name()
        .to_string_lossy()
        .contains("partial")));

    // --uv must point at a mesh with texture coordinates.
    let plain = tmp.path().join("plain.obj");
    write_obj(&plain, &model.topology, &seqs[0].fine[0]).unwrap();
    let e = err(layout_for(Some(&plain), &model.topology, &seqs[0].fine[0]));
    assert!(
        e.contains("plain.obj") && e.contains("vt") && e.contains("--uv"),
        "{e}"
    );
}

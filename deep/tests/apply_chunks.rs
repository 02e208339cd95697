//! Apply in frame chunks writes the same bytes as one run over all frames: what the job system relies on to
//! split apply across workers.

mod support;

use crease_core::progress::NoProgress;
use crease_deep::apply::{apply, ApplyInput, ApplyParams, CoarseDetail};
use crease_deep::cgan::CganConfig;
use crease_deep::detail::captures::{self, CaptureDraw, Family};
use crease_deep::model::{Model, RegressorKind};
use crease_deep::nn::seed::Rng;
use crease_deep::train::{train, TrainParams, TrainingSequence};
use std::path::Path;

fn sequence(dir: &Path, frames: usize, phase: f64) -> TrainingSequence {
    let (topo, _) = support::tube(16, 8, |_, _| 0.07);
    let mut fine = Vec::new();
    let mut poses = Vec::new();
    for t in 0..frames {
        let a = (0.4 * t as f64 + phase).sin();
        poses.push(vec![a, 0.0]);
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

fn read_tree(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    for sub in ["mesh", "normals"] {
        let mut files: Vec<_> = std::fs::read_dir(dir.join(sub))
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        files.sort();
        for f in files {
            out.push((
                format!("{sub}/{}", f.file_name().unwrap().to_string_lossy()),
                std::fs::read(&f).unwrap(),
            ));
        }
    }
    out
}

#[test]
fn chunked_apply_equals_the_single_run_byte_for_byte() {
    let tmp = tempfile::tempdir().unwrap();
    let seqs = vec![
        sequence(&tmp.path().join("a"), 12, 0.0),
        sequence(&tmp.path().join("b"), 12, 0.7),
    ];
    let params = TrainParams {
        k: 4,
        lags: vec![1, 2],
        regressor: RegressorKind::Lstm,
        lstm: crease_deep::regression::lstm::LstmConfig {
            layers: 1,
            hidden: 8,
            epochs: 3,
            ..Default::default()
        },
        resolution: 32,
        cgan: Some(CganConfig {
            filters: 4,
            disc_filters: 4,
            depth: 3,
            crop: 16,
            batch: 2,
            steps: 3,
            ..Default::default()
        }),
        ..Default::default()
    };
    let model_dir = tmp.path().join("model");
    train(&seqs, &params, &model_dir, &NoProgress).unwrap();
    let model = Model::load(&model_dir).unwrap();
    assert!(model.lstm.is_some());
    let pose = tmp.path().join("pose.json");
    let doc = serde_json::json!({ "pose_vectors": seqs[1].poses });
    std::fs::write(&pose, doc.to_string()).unwrap();
    let input = ApplyInput::Pose(pose);
    let full = tmp.path().join("full");
    assert_eq!(
        apply(&model, &input, &ApplyParams::default(), &full, &NoProgress)
            .unwrap()
            .frames,
        12
    );
    let chunked = tmp.path().join("chunked");
    for r in [0..5, 5..9, 9..12] {
        let p = ApplyParams {
            frames: Some(r.clone()),
            ..Default::default()
        };
        assert_eq!(
            apply(&model, &input, &p, &chunked, &NoProgress)
                .unwrap()
                .frames,
            r.len()
        );
    }
    let a = read_tree(&full);
    assert_eq!(a.len(), 24);
    assert_eq!(a, read_tree(&chunked));
    // The maps change with the cGAN exactly when the model decided to use it from poses.
    let use_pose = model.manifest.cgan.as_ref().unwrap().use_pose;
    let plain = tmp.path().join("plain");
    apply(
        &model,
        &input,
        &ApplyParams {
            no_cgan: true,
            ..Default::default()
        },
        &plain,
        &NoProgress,
    )
    .unwrap();
    assert_eq!(read_tree(&plain)[12..] != a[12..], use_pose);
    // The coarse path too, with the detail model (guard included) and with the relief, whose heights read the
    // frames around each one: a chunk's frames are the whole run's.
    // A smoothed capture (one that lost surface), so that every path adds detail rather than falling back.
    let capture = tmp.path().join("capture");
    let topo = &seqs[1].topology;
    let draw = CaptureDraw {
        family: Family::Heat {
            half_wavelength: 8.0,
        },
        noise_sigma: 0.0,
        noise_rings: 0,
    };
    let smoothed: Vec<_> = seqs[1]
        .fine
        .iter()
        .map(|f| {
            let h = crease_core::shape::mean_edge_length(topo, f);
            captures::capture(topo, f, h, &draw, &mut Rng::new(1))
        })
        .collect();
    support::write_sequence(&capture, topo, &smoothed);
    let input = ApplyInput::Coarse(capture);
    let mut trees = Vec::new();
    for detail in [
        CoarseDetail::Model,
        CoarseDetail::Relief,
        CoarseDetail::Blend,
    ] {
        let with = |frames| ApplyParams {
            frames,
            coarse_detail: Some(detail),
            ..Default::default()
        };
        let full = tmp.path().join(format!("full-coarse-{}", detail.as_str()));
        let summary = apply(&model, &input, &with(None), &full, &NoProgress).unwrap();
        let chunked = tmp
            .path()
            .join(format!("chunked-coarse-{}", detail.as_str()));
        for r in [0..7, 7..12] {
            apply(&model, &input, &with(Some(r)), &chunked, &NoProgress).unwrap();
        }
        assert_eq!(read_tree(&full), read_tree(&chunked), "{}", detail.as_str());
        assert!(summary.fallback.is_empty(), "{summary:?}");
        trees.push(read_tree(&full));
    }
    // The paths draw different maps (the relief adds to the capture what the filter does not), not only
    // different notes: compare the PNGs.
    let pngs = |t: &Vec<(String, Vec<u8>)>| -> Vec<Vec<u8>> {
        t.iter()
            .filter(|(n, _)| n.ends_with(".png"))
            .map(|(_, b)| b.clone())
            .collect()
    };
    assert_ne!(pngs(&trees[0]), pngs(&trees[1]));
    assert_ne!(pngs(&trees[1]), pngs(&trees[2]));
    assert_ne!(pngs(&trees[0]), pngs(&trees[2]));
    // A frame range outside the input is refused.
    let bad = ApplyParams {
        frames: Some(10..13),
        ..Default::default()
    };
    let err = apply(&model, &input, &bad, &tmp.path().join("x"), &NoProgress)
        .unwrap_err()
        .to_string();
    assert!(err.contains("frames"), "{err}");
}

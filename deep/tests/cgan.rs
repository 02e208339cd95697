//! cGAN (§4.2) on small maps: untrained it returns its input, training lowers its losses and brings it closer
//! to the target, it is deterministic and resumes exactly from a checkpoint, and a trained model uses it only
//! where it beat the maps without it on the held-out sequence.

mod support;

use crease_core::progress::NoProgress;
use crease_deep::cgan::data::TrainingSet;
use crease_deep::cgan::{Cgan, CganConfig};
use crease_deep::normal_maps::raster::TexelMap;
use crease_deep::normal_maps::{world_from_vertex_normals, NormalMap};
use support::ripple_data;

fn config(steps: usize) -> CganConfig {
    CganConfig {
        filters: 4,
        disc_filters: 4,
        depth: 3,
        crop: 16,
        batch: 4,
        steps,
        lr: 2e-3,
        seed: 5,
        ..Default::default()
    }
}

/// Mean |a − b| over the texel channels `b` covers.
fn l1(a: &NormalMap, b: &NormalMap) -> f64 {
    let (mut s, mut c) = (0.0, 0.0);
    for k in 0..b.n.len() {
        if b.covered[k] {
            for ch in 0..3 {
                s += (a.n[k][ch] - b.n[k][ch]).abs() as f64;
                c += 1.0;
            }
        }
    }
    s / c
}

#[test]
fn untrained_it_is_the_identity_and_training_brings_it_to_the_target() {
    let data = ripple_data(33, 8);
    let texels = TexelMap::new(&data.layout, 32, 32);
    let set = TrainingSet::new(&data.topo, &texels, vec![data.frames.clone()], 16);
    let input = world_from_vertex_normals(&texels, &data.topo, &data.frames[3].0);
    let target = world_from_vertex_normals(&texels, &data.topo, &data.frames[3].1);
    let mut gan = Cgan::new(config(60)).unwrap();
    let out = gan.enhance(&input).unwrap();
    assert!(
        l1(&out, &input) < 1e-6,
        "an untrained generator returns its input"
    );
    let before = l1(&out, &target);
    let hist = gan.train(&set, 10, |_, _, _| Ok(())).unwrap();
    assert_eq!(hist.len(), 6);
    assert!(
        hist[5].l1 < 0.8 * hist[0].l1,
        "L1 {} -> {}",
        hist[0].l1,
        hist[5].l1
    );
    let out = gan.enhance(&input).unwrap();
    let after = l1(&out, &target);
    assert!(after < before, "closer to the target: {before} -> {after}");
    assert_eq!(out.covered, input.covered);
    for (k, n) in out.n.iter().enumerate() {
        if out.covered[k] {
            let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            assert!((l - 1.0).abs() < 1e-4, "unit normals");
        }
    }
    // Configurations the U-Net cannot take are refused by name.
    let e = CganConfig {
        crop: 20,
        ..config(1)
    }
    .validate()
    .unwrap_err()
    .to_string();
    assert!(e.contains("crop"), "{e}");
    let e = config(1).check_resolution(36).unwrap_err().to_string();
    assert!(e.contains("resolution"), "{e}");
}

#[test]
fn same_seed_same_bytes_and_resume_continues_exactly() {
    let data = ripple_data(33, 6);
    let texels = TexelMap::new(&data.layout, 32, 32);
    let set = TrainingSet::new(&data.topo, &texels, vec![data.frames.clone()], 16);
    let run = |steps| {
        let mut gan = Cgan::new(config(steps)).unwrap();
        gan.train(&set, 2, |_, _, _| Ok(())).unwrap();
        gan
    };
    let a = run(8);
    let b = run(8);
    assert_eq!(a.generator_bytes().unwrap(), b.generator_bytes().unwrap());
    // Four steps, checkpoint, resume for four more = eight straight.
    let tmp = tempfile::tempdir().unwrap();
    let ck = tmp.path().join("ck");
    let mut first = Cgan::new(config(4)).unwrap();
    first
        .train(&set, 2, |g, _, _| g.save_checkpoint(&ck))
        .unwrap();
    let mut resumed = Cgan::resume(config(8), &ck).unwrap();
    assert_eq!(resumed.step, 4);
    let hist = resumed.train(&set, 2, |_, _, _| Ok(())).unwrap();
    assert_eq!(hist.len(), 2);
    assert_eq!(
        resumed.generator_bytes().unwrap(),
        a.generator_bytes().unwrap()
    );
    // Another architecture cannot resume this checkpoint.
    assert!(Cgan::resume(
        CganConfig {
            filters: 8,
            ..config(8)
        },
        &ck
    )
    .is_err());
}

#[test]
fn a_trained_model_uses_its_generator_only_where_it_won_on_held_out_frames() {
    let tmp = tempfile::tempdir().unwrap();
    let seqs: Vec<_> = (0..3)
        .map(|i| {
            support::leaky_sequence(
                &tmp.path().join(format!("s{i}")),
                16,
                0.3 + 0.1 * i as f64,
                i as f64,
            )
        })
        .collect();
    let params = crease_deep::train::TrainParams {
        k: 4,
        resolution: 32,
        cgan: Some(config(6)),
        ..Default::default()
    };
    let dir = tmp.path().join("model");
    crease_deep::train::train(&seqs, &params, &dir, &NoProgress).unwrap();
    let model = crease_deep::model::Model::load(&dir).unwrap();
    let spec = model.manifest.cgan.clone().expect("a cGAN");
    assert!(
        spec.coarse_deg
            .iter()
            .chain(&spec.pose_deg)
            .all(|d| d.is_finite()),
        "{spec:?}"
    );
    assert_eq!(spec.use_coarse, spec.coarse_deg[1] < spec.coarse_deg[0]);
    assert_eq!(spec.use_pose, spec.pose_deg[1] < spec.pose_deg[0]);
    // The pose path's OBJ says whether the generator ran.
    let out = tmp.path().join("out");
    crease_deep::apply::apply(
        &model,
        &crease_deep::apply::ApplyInput::Pose(seqs[0].dir.join("pose.json")),
        &Default::default(),
        &out,
        &NoProgress,
    )
    .unwrap();
    let obj = std::fs::read_to_string(out.join("mesh/frame_0001.obj")).unwrap();
    assert_eq!(
        obj.lines().nth(1).unwrap().contains("cGAN"),
        spec.use_pose,
        "{:?}",
        obj.lines().nth(1)
    );
}

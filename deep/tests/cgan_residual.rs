//! The residual generator (`CganConfig::residual`, the default): untrained it returns its input map, a few
//! steps only bring it closer to the target, and a model of format version 2 (whose manifest predates the
//! field) still runs its generator as the plain one it was trained as.

mod support;

use crease_core::progress::NoProgress;
use crease_deep::cgan::enhance::Enhancer;
use crease_deep::cgan::{Cgan, CganConfig, GeneratorModel};
use crease_deep::model::Model;
use crease_deep::normal_maps::NormalMap;
use crease_deep::train::{train, TrainParams, TrainingSequence};
use std::path::Path;
use support::ripple_samples as samples;

fn config(epochs: usize) -> CganConfig {
    CganConfig {
        resolution: 16,
        filters: 8,
        disc_filters: 8,
        epochs,
        batch: 2,
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

fn max_diff(a: &NormalMap, b: &NormalMap) -> f32 {
    a.n.iter()
        .zip(&b.n)
        .zip(&b.covered)
        .filter(|(_, &c)| c)
        .flat_map(|((p, q), _)| (0..3).map(move |ch| (p[ch] - q[ch]).abs()))
        .fold(0.0, f32::max)
}

#[test]
fn an_untrained_residual_generator_returns_its_input_map() {
    assert!(CganConfig::default().residual, "the default");
    let data = samples(3, 16);
    let gan = Cgan::new(config(1)).unwrap();
    for s in &data {
        let out = gan.enhance(&s.input).unwrap();
        assert_eq!(out.covered, s.input.covered);
        let d = max_diff(&out, &s.input);
        assert!(d < 1e-5, "largest texel difference {d}");
    }
    // The plain generator, with the same seed, starts from noise: far from its input.
    let plain = Cgan::new(CganConfig {
        residual: false,
        ..config(1)
    })
    .unwrap();
    let d = max_diff(&plain.enhance(&data[0].input).unwrap(), &data[0].input);
    assert!(d > 0.1, "plain generator's largest difference {d}");
}

#[test]
fn a_few_steps_bring_the_residual_generator_closer_to_the_target() {
    let data = samples(8, 16);
    let before_train: f64 = data.iter().map(|s| l1(&s.input, &s.target)).sum::<f64>();
    let mut gan = Cgan::new(config(12)).unwrap();
    let hist = gan.train(&data, |_, _, _| {}, |_, _, _| Ok(())).unwrap();
    assert_eq!(hist.len(), 12);
    assert!(
        hist[11].l1 < 0.9 * hist[0].l1,
        "training L1 {} -> {}",
        hist[0].l1,
        hist[11].l1
    );
    let after_train: f64 = data
        .iter()
        .map(|s| l1(&gan.enhance(&s.input).unwrap(), &s.target))
        .sum::<f64>();
    assert!(
        after_train < before_train,
        "L1 of the output maps to their targets: input {before_train}, after training {after_train}"
    );
}

fn sequence(dir: &Path, frames: usize, phase: f64) -> TrainingSequence {
    let (topo, _) = support::tube(16, 8, |_, _| 0.07);
    let mut fine = Vec::new();
    let mut coarse = Vec::new();
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
        coarse.push(support::tube(16, 8, |_, x| 0.07 + 0.01 * a * (6.0 * x).sin()).1);
    }
    TrainingSequence {
        dir: dir.to_path_buf(),
        topology: topo,
        fine,
        coarse,
        poses,
        pose_names: None,
    }
}

#[test]
fn a_version_2_models_generator_runs_as_the_plain_one_it_was() {
    let tmp = tempfile::tempdir().unwrap();
    let seqs = vec![
        sequence(&tmp.path().join("a"), 8, 0.0),
        sequence(&tmp.path().join("b"), 8, 0.7),
    ];
    let params = TrainParams {
        k: 4,
        resolution: 32,
        cgan: Some(CganConfig {
            filters: 4,
            disc_filters: 4,
            epochs: 1,
            ..Default::default()
        }),
        ..Default::default()
    };
    let dir = tmp.path().join("model");
    train(&seqs, &params, &dir, &NoProgress).unwrap();
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("manifest.json")).unwrap()).unwrap();
    assert_eq!(manifest["version"], 8);
    assert_eq!(manifest["cgan"]["residual"], true);

    // What version 2 wrote: the same files, no `residual` in the cGAN section.
    let old = tmp.path().join("v2");
    std::fs::create_dir_all(&old).unwrap();
    let mut m2 = manifest.clone();
    m2["version"] = 2.into();
    m2["cgan"].as_object_mut().unwrap().remove("residual");
    for f in manifest["files"].as_object().unwrap().keys() {
        std::fs::copy(dir.join(f), old.join(f)).unwrap();
    }
    std::fs::write(
        old.join("manifest.json"),
        serde_json::to_string_pretty(&m2).unwrap(),
    )
    .unwrap();

    let new = Model::load(&dir).unwrap();
    let v2 = Model::load(&old).unwrap();
    let input = samples(1, 32).pop().unwrap().input;
    let out_new = Enhancer::for_model(&new)
        .unwrap()
        .unwrap()
        .enhance(&input)
        .unwrap();
    let out_v2 = Enhancer::for_model(&v2)
        .unwrap()
        .unwrap()
        .enhance(&input)
        .unwrap();
    let plain_cfg: CganConfig = serde_json::from_value(m2["cgan"].clone()).unwrap();
    assert!(!plain_cfg.residual);
    let plain = GeneratorModel::load(plain_cfg, &dir.join("cgan.safetensors"))
        .unwrap()
        .enhance(&input)
        .unwrap();
    assert_eq!(
        out_v2.n, plain.n,
        "the version 2 model runs the plain generator"
    );
    assert!(
        max_diff(&out_v2, &out_new) > 1e-3,
        "and that differs from the residual reading of the same weights"
    );
    // A format 3 manifest without the field is damaged, not an old model: refused, naming the field.
    let mut m3 = manifest.clone();
    m3["cgan"].as_object_mut().unwrap().remove("residual");
    std::fs::write(
        dir.join("manifest.json"),
        serde_json::to_string_pretty(&m3).unwrap(),
    )
    .unwrap();
    match Enhancer::for_model(&Model::load(&dir).unwrap()) {
        Ok(_) => panic!("a format 3 cGAN section without `residual` was accepted"),
        Err(e) => {
            let e = e.to_string();
            assert!(e.contains("manifest.json") && e.contains("residual"), "{e}");
        }
    }
    // The residual model after one epoch stays near its input; it is not the input itself.
    let d = max_diff(&out_new, &input);
    assert!(d > 0.0 && d < 1.0, "residual output's largest change {d}");
}

//! cGAN (§4.2) on tiny maps: losses fall, shapes are right, training is deterministic, checkpoints resume.

use crease_deep::cgan::{Cgan, CganConfig, Sample};
use crease_deep::normal_map::NormalMap;

/// Input: a smooth map; target: the same with a ripple whose phase moves with t (temporal data).
fn samples(n: usize, res: usize) -> Vec<Sample> {
    let map = |t: usize, ripple: f32| {
        let mut m = NormalMap {
            width: res,
            height: res,
            n: vec![[0.0; 3]; res * res],
            covered: vec![false; res * res],
        };
        for y in 0..res {
            for x in 0..res {
                let k = y * res + x;
                let u = x as f32 / res as f32;
                let tilt = 0.3 * (u * 3.0 + t as f32 * 0.2).sin();
                let r = ripple * (u * 25.0 + t as f32 * 0.5).sin();
                let v = [tilt + r, 0.1, 1.0];
                let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                m.n[k] = [v[0] / l, v[1] / l, v[2] / l];
                m.covered[k] = x > 1 && y > 1;
            }
        }
        m
    };
    (0..n)
        .map(|t| Sample {
            input: map(t, 0.0),
            target: map(t, 0.4),
            prev_target: map(t.saturating_sub(1), 0.4),
        })
        .collect()
}

fn config(epochs: usize) -> CganConfig {
    CganConfig {
        resolution: 16,
        filters: 8,
        disc_filters: 8,
        epochs,
        batch: 2,
        lr: 2e-3,
        seed: 5,
        // The plain generator (format 2 models): the residual one has its own tests (cgan_residual.rs).
        residual: false,
        ..Default::default()
    }
}

#[test]
fn losses_fall_and_the_output_has_the_input_shape() {
    let data = samples(8, 16);
    let mut gan = Cgan::new(config(12)).unwrap();
    assert_eq!(config(12).depth(), 4);
    let hist = gan.train(&data, |_, _, _| {}, |_, _, _| Ok(())).unwrap();
    assert_eq!(hist.len(), 12);
    assert!(
        hist[11].l1 < 0.7 * hist[0].l1,
        "L1 {} -> {}",
        hist[0].l1,
        hist[11].l1
    );
    let out = gan.enhance(&data[0].input).unwrap();
    assert_eq!((out.width, out.height, out.n.len()), (16, 16, 256));
    assert_eq!(out.covered, data[0].input.covered);
    for (k, n) in out.n.iter().enumerate() {
        if out.covered[k] {
            let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            assert!((l - 1.0).abs() < 1e-4, "unit normals");
        }
    }
    assert!(CganConfig {
        resolution: 48,
        ..config(1)
    }
    .validate()
    .is_err());
}

#[test]
fn same_seed_same_bytes_and_resume_continues_exactly() {
    let data = samples(6, 16);
    let run = |epochs| {
        let mut gan = Cgan::new(config(epochs)).unwrap();
        gan.train(&data, |_, _, _| {}, |_, _, _| Ok(())).unwrap();
        gan
    };
    let a = run(4);
    let b = run(4);
    assert_eq!(a.generator_bytes().unwrap(), b.generator_bytes().unwrap());
    // Two epochs, checkpoint, resume for two more = four straight.
    let tmp = tempfile::tempdir().unwrap();
    let ck = tmp.path().join("ck");
    let mut first = Cgan::new(config(2)).unwrap();
    first
        .train(&data, |_, _, _| {}, |g, _, _| g.save_checkpoint(&ck))
        .unwrap();
    let mut resumed = Cgan::resume(config(4), &ck).unwrap();
    assert_eq!(resumed.epoch, 2);
    let hist = resumed
        .train(&data, |_, _, _| {}, |_, _, _| Ok(()))
        .unwrap();
    assert_eq!(hist.len(), 2);
    assert_eq!(
        resumed.generator_bytes().unwrap(),
        a.generator_bytes().unwrap()
    );
    // Another architecture cannot resume this checkpoint.
    assert!(Cgan::resume(
        CganConfig {
            filters: 4,
            ..config(4)
        },
        &ck
    )
    .is_err());
}

//! cGAN (§4.2) on tiny maps: losses fall, shapes are right, training is deterministic, checkpoints resume.

mod support;

use crease_deep::cgan::{Cgan, CganConfig};
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

//! Non-rigid ICP (§3.1) on a synthetic sleeve: a tube registered to noisy, holey scans of a deformed copy.

mod support;

use crease_deep::registration::{
    boundary_pairs, read_scan, synth_scan, write_scan, RegisterParams, Registration,
};
use crease_deep::subspace::vertex_error;

#[test]
fn registration_follows_a_bent_twisted_tube_through_holes_and_noise() {
    let (topo, rest) = support::tube(32, 24, |_, _| 0.07);
    // Targets: the tube bent (its axis on an arc), twisted and bulged, close to an isometry as cloth moves,
    // in four steps that the registration tracks (each scan starts from the previous result).
    let deform = |amount: f64| -> Vec<[f64; 3]> {
        let kappa = 1.5 * amount;
        rest.iter()
            .map(|p| {
                let s = p[0] / 0.5;
                let ang = 0.5 * s * amount;
                let r = 1.0 + 0.1 * amount * (std::f64::consts::PI * s).sin();
                let (y0, z0) = (p[1] * r, p[2] * r);
                let (y, z) = (
                    y0 * ang.cos() - z0 * ang.sin(),
                    y0 * ang.sin() + z0 * ang.cos(),
                );
                let th = kappa * p[0];
                let (cx, cz) = if kappa > 0.0 {
                    (th.sin() / kappa, (1.0 - th.cos()) / kappa)
                } else {
                    (p[0], 0.0)
                };
                [cx - z * th.sin(), y, cz + z * th.cos()]
            })
            .collect()
    };
    let params = RegisterParams::default();
    let mut reg = Registration::new(topo.clone(), &rest, params).unwrap();
    assert!(reg.n_nodes() > 20 && reg.n_nodes() < rest.len());
    let mut out = rest.clone();
    for (i, amount) in [0.25, 0.5, 0.75, 1.0].into_iter().enumerate() {
        let scan = synth_scan(&topo, &deform(amount), 3.0, 0.2, 0.002, 11 + i as u64);
        out = reg.register(&scan).unwrap();
    }
    let target = deform(1.0);
    let (before, _) = vertex_error(&rest, &target);
    let (mean, p95) = vertex_error(&out, &target);
    eprintln!(
        "registration: before {:.1} mm, after mean {:.2} mm p95 {:.2} mm",
        before * 1e3,
        mean * 1e3,
        p95 * 1e3
    );
    assert!(before > 0.05);
    // Measured: 68.3 mm before, 11.99 mm mean / 21.14 mm p95 after (12.94 / 26.66 mm with the previous
    // defaults: nearest point, floor 1; vertex-to-vertex, so sliding along the surface counts as error). The bounds leave room for other CPUs' float order, not for a regression.
    assert!(
        mean < 0.25 * before,
        "mean vertex error {:.2} mm of {:.2} mm",
        mean * 1e3,
        before * 1e3
    );
    assert!(p95 < 0.5 * before, "p95 vertex error {:.2} mm", p95 * 1e3);
}

/// The normal equations are assembled in parallel (`register_system.rs`), each block's rows in a fixed order:
/// the registration must not depend on how many threads run it.
#[test]
fn registration_is_the_same_to_the_bit_on_one_thread_and_on_four() {
    let (topo, rest) = support::tube(32, 24, |_, _| 0.07);
    let target: Vec<[f64; 3]> = rest
        .iter()
        .map(|p| [p[0], p[1] + 0.01 * (6.0 * p[0]).sin(), p[2] * 1.05])
        .collect();
    let scans: Vec<_> = (0..2)
        .map(|i| synth_scan(&topo, &target, 3.0, 0.2, 0.002, 5 + i))
        .collect();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let params = RegisterParams {
                iterations: 8,
                ..Default::default()
            };
            let mut reg = Registration::new(topo.clone(), &rest, params).unwrap();
            let mut out = Vec::new();
            for scan in &scans {
                out = reg.register(scan).unwrap();
            }
            out
        })
    };
    let (one, four) = (run(1), run(4));
    assert_eq!(one.len(), rest.len());
    let bits = |v: &[[f64; 3]]| -> Vec<u64> { v.iter().flatten().map(|x| x.to_bits()).collect() };
    assert!(vertex_error(&one, &rest).0 > 1e-4, "the fit did not move");
    assert_eq!(bits(&one), bits(&four));
}

/// The sleeve's case (bench/results/2026-12-05-deep-registration.md): the scan's noise (σ ≈ 0.35 mean edge lengths per
/// coordinate) is as large as the deformation, and a fit that follows its nearest scan points slides along the
/// surface after them. The defaults (point-to-plane data term, floor of ω_r, ω_s tied to the scan's noise) must
/// follow the noise much less than the previous schedule (nearest point, floor 1). Neither beats the
/// template on this single untracked scan (measured: template 3.14 mm, defaults 5.42 mm, previous 7.61 mm);
/// on the sleeve the defaults beat it at three of four tracked frames. The acceptance test (`multi_start`)
/// keeps the template here.
#[test]
fn registration_of_a_noisy_scan_of_a_small_deformation_follows_the_noise_less() {
    use std::f64::consts::PI;
    // Tapered and oval, so that neither a turn about the axis nor a slide along it leaves the surface where it
    // was (a plain cylinder would let the point-to-plane term slide freely, as no sleeve does).
    let base = |phi: f64, x: f64| 0.06 + 0.04 * x + 0.012 * (2.0 * phi).cos();
    let (topo, rest) = support::tube(48, 36, base);
    let target = support::tube(48, 36, |phi, x| {
        base(phi, x) + 0.008 * (4.0 * PI * x / 0.5).sin() * (2.0 * phi + 0.5).cos()
    })
    .1;
    let scan = synth_scan(&topo, &target, 3.0, 0.2, 0.0045, 21);
    let run = |params: RegisterParams| {
        let mut reg = Registration::new(topo.clone(), &rest, params).unwrap();
        let out = reg.register(&scan).unwrap();
        (vertex_error(&out, &target).0, reg.last_noise())
    };
    let (before, _) = vertex_error(&rest, &target);
    let (now, (noise, floor)) = run(RegisterParams::default());
    let (old, _) = run(RegisterParams {
        w_plane: 0.0,
        w_point: 1.0,
        noise_floor: 0.0,
        ..Default::default()
    });
    let (multi, _) = run(RegisterParams {
        multi_start: true,
        ..Default::default()
    });
    eprintln!("acceptance test (multi_start): {:.2} mm", multi * 1e3);
    eprintln!(
        "unregistered {:.2} mm, defaults {:.2} mm (noise σ² {noise:?} edges², floor {floor:.1}), previous schedule {:.2} mm",
        before * 1e3,
        now * 1e3,
        old * 1e3
    );
    assert!(noise.is_some_and(|v| v > 0.05 && v < 0.3), "{noise:?}");
    assert!(
        now < 0.8 * old,
        "defaults {:.2} mm against the previous schedule's {:.2} mm",
        now * 1e3,
        old * 1e3
    );
    // The acceptance test (`multi_start`): the fit's Eq. 1 energy (measured 1135) is above the unregistered
    // template's (1106) at the relaxed floor, so the template is kept instead of the worse fit.
    assert!(
        multi <= before + 1e-9,
        "acceptance test {:.2} mm, template {:.2} mm",
        multi * 1e3,
        before * 1e3
    );
    assert!(
        now < 2.0 * before,
        "defaults {:.2} mm, template {:.2} mm",
        now * 1e3,
        before * 1e3
    );
}

#[test]
fn boundary_pairs_follow_equation_2() {
    // Template boundary points at x = 0 and x = 1; scan boundary points nearer to each.
    let current = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [5.0, 5.0, 5.0]];
    let scan = vec![
        [0.1, 0.0, 0.0],
        [0.3, 0.0, 0.0],
        [0.45, 0.0, 0.0],
        [0.9, 0.0, 0.0],
    ];
    let pairs = boundary_pairs(&[0, 1, 2], &current, &scan);
    // Vertex 0 is closest to 0.1, 0.3 and 0.45 and takes the farthest of them; vertex 1 only has 0.9; vertex 2
    // is nobody's nearest, so it gets no pair.
    assert_eq!(pairs, vec![(0, [0.45, 0.0, 0.0]), (1, [0.9, 0.0, 0.0])]);
}

#[test]
fn scans_round_trip_with_their_boundary_colour_and_bad_files_are_named() {
    let (topo, p) = support::tube(12, 6, |_, _| 0.07);
    let scan = synth_scan(&topo, &p, 1.0, 0.2, 0.0, 3);
    assert!(scan.boundary.iter().any(|&b| b) && scan.boundary.iter().any(|&b| !b));
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scan.obj");
    write_scan(&path, &scan).unwrap();
    let back = read_scan(&path).unwrap();
    assert_eq!(back.boundary, scan.boundary);
    assert_eq!(back.points.len(), scan.points.len());
    std::fs::write(dir.path().join("bad.obj"), "v 0 0 0\nv 1 nan 0\n").unwrap();
    let err = read_scan(&dir.path().join("bad.obj"))
        .unwrap_err()
        .to_string();
    assert!(err.contains("bad.obj:2"), "{err}");
}

#[test]
fn scan_noise_variance_is_measured_along_the_normal() {
    use crease_deep::registration::kdtree::KdTree;
    use crease_deep::registration::point_normals::noise_variance;
    // A plane sampled on a jittered grid with Gaussian noise of σ = 0.05 along its normal only: the estimate is
    // σ² (within sampling error), and zero noise gives (nearly) zero.
    let mut rng = crease_deep::nn::seed::Rng::new(9);
    let mut gauss = || {
        let (u1, u2) = (rng.uniform().max(1e-12), rng.uniform());
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    };
    let mut noisy = Vec::new();
    let mut clean = Vec::new();
    for i in 0..60 {
        for j in 0..60 {
            let (x, y) = (i as f64 + 0.3 * gauss(), j as f64 + 0.3 * gauss());
            clean.push([x, y, 0.0]);
            noisy.push([x, y, 0.05 * gauss()]);
        }
    }
    let v = noise_variance(&noisy, &KdTree::new(&noisy), 16, 3);
    assert!((v - 0.0025).abs() < 0.0006, "{v}");
    let v0 = noise_variance(&clean, &KdTree::new(&clean), 16, 3);
    assert!(v0 < 1e-12, "{v0}");
}

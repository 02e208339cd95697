//! The fold relief (`spacetime/shape/relief.rs`) gives back, in place, the folds a capture smoothed without
//! erasing — for a capture made by a low-pass it knows nothing about — never amplifies a capture's noise, and
//! leaves a garment without anchors as it was. The lost-area bound (`spacetime/shape/lost_area.rs`) gives back
//! a capture that kept its folds as it was, however its anchors turn it, and lets the folds of one that lost
//! them through.

use crease_core::folds::{Anchor, AnchorSet};
use crease_core::mesh::{geometry, MemorySink, Sequence, Topology};
use crease_core::progress::NoProgress;
use crease_core::spacetime::shape::lost_area::{TRUST_FULL, TRUST_NONE};
use crease_core::spacetime::shape::relief::ReliefParams;
use crease_core::spacetime::{deform, DeformParams, DeformReport};
use crease_core::vec3::{self, V3};
use std::sync::Arc;

/// A flat sheet of near-equilateral triangles (`nx` × `ny` vertices, edge 1) in the z = 0 plane.
fn sheet(nx: usize, ny: usize) -> (Topology, Vec<V3>) {
    let mut p = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            p.push([
                i as f64 + 0.5 * (j % 2) as f64,
                j as f64 * 0.75f64.sqrt(),
                0.0,
            ]);
        }
    }
    let mut tris = Vec::new();
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            let a = (j * nx + i) as u32;
            let (b, c, d) = (a + 1, a + nx as u32, a + nx as u32 + 1);
            if j % 2 == 0 {
                tris.extend([[a, b, c], [b, d, c]]);
            } else {
                tris.extend([[a, b, d], [a, d, c]]);
            }
        }
    }
    (Topology::new(nx * ny, tris).unwrap(), p)
}

/// Ripples of 6 edges across x in [12, 30], height 0.35 edges, fading in and out: the real cloth.
fn ripple(p: &[V3]) -> Vec<V3> {
    p.iter()
        .map(|q| {
            let env = if (12.0..30.0).contains(&q[0]) {
                (std::f64::consts::PI * (q[0] - 12.0) / 18.0).sin()
            } else {
                0.0
            };
            [
                q[0],
                q[1],
                0.35 * env * (2.0 * std::f64::consts::PI * q[0] / 6.0).sin(),
            ]
        })
        .collect()
}

fn mean_normal_error(topo: &Topology, a: &[V3], b: &[V3], keep: impl Fn(usize) -> bool) -> f64 {
    let (na, nb) = (
        geometry::vertex_normals(topo, a),
        geometry::vertex_normals(topo, b),
    );
    let (mut sum, mut n) = (0.0, 0);
    for v in (0..a.len()).filter(|&v| keep(v)) {
        sum += vec3::dot(na[v], nb[v]).clamp(-1.0, 1.0).acos();
        n += 1;
    }
    sum / n as f64
}

/// A low-pass of its own family, which the relief does not model: repeated implicit-like steps of the uniform
/// (umbrella) Laplacian with a boundary kept in place.
fn blur(topo: &Topology, p: &[V3], rounds: usize) -> Vec<V3> {
    let mut x = p.to_vec();
    for _ in 0..rounds {
        x = (0..x.len())
            .map(|v| {
                let nb = topo.vertex_neighbors(v);
                if nb.len() < 6 {
                    return x[v];
                }
                let avg = nb
                    .iter()
                    .fold([0.0; 3], |a, &u| vec3::add(a, x[u as usize]));
                vec3::add(
                    vec3::scale(x[v], 0.6),
                    vec3::scale(avg, 0.4 / nb.len() as f64),
                )
            })
            .collect();
    }
    x
}

/// A small deterministic generator (the tests must not depend on a random crate's stream).
struct Lcg(u64);
impl Lcg {
    fn uniform(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    }
}

const FRAMES: usize = 7;

/// Every seventh triangle of the rippled band's interior (by its flat position): where the anchors go.
fn anchored_triangles<'a>(topo: &'a Topology, flat: &'a [V3]) -> impl Iterator<Item = usize> + 'a {
    (0..topo.n_triangles()).filter(move |&t| {
        let x = topo.triangles()[t]
            .iter()
            .map(|&v| flat[v as usize][0])
            .sum::<f64>()
            / 3.0;
        let y = flat[topo.triangles()[t][0] as usize][1];
        (16.0..26.0).contains(&x) && (4.0..16.0).contains(&y) && t % 7 == 0
    })
}

/// Seven frames of the captured sheet (the ripple after a low-pass of another family, plus `noise` edges of
/// uniform noise, new in every frame) with anchors that tilt the rippled band a little (a detector that knows
/// where the cloth folded, not where its ridges are).
fn captured_case(noise: f64) -> (Sequence, AnchorSet, Vec<V3>) {
    let (topo, flat) = sheet(42, 24);
    let truth = ripple(&flat);
    let smooth = blur(&topo, &truth, 6);
    let mut rng = Lcg(99);
    let frames: Vec<Vec<V3>> = (0..FRAMES)
        .map(|_| {
            smooth
                .iter()
                .map(|q| [q[0], q[1], q[2] + noise * 2.0 * rng.uniform()])
                .collect()
        })
        .collect();
    let topo = Arc::new(topo);
    let anchors: Vec<Anchor> = anchored_triangles(&topo, &flat)
        .map(|t| Anchor {
            triangle: t as u32,
            axis: [0.0, 1.0, 0.0],
            angle: if t % 2 == 0 { 0.15 } else { -0.15 },
        })
        .collect();
    assert!(anchors.len() > 10);
    let seq = Sequence::new(topo.clone(), frames).unwrap();
    let set = AnchorSet::from_frames(vec![anchors; FRAMES], topo.n_triangles(), None).unwrap();
    (seq, set, truth)
}

fn run(seq: &Sequence, anchors: &AnchorSet, steps: u32) -> Vec<Vec<V3>> {
    run_with(seq, anchors, steps, false)
}

fn run_with(seq: &Sequence, anchors: &AnchorSet, steps: u32, bound: bool) -> Vec<Vec<V3>> {
    run_reporting(seq, anchors, steps, bound).0
}

/// [`run_with`], with the deformation's report.
fn run_reporting(
    seq: &Sequence,
    anchors: &AnchorSet,
    steps: u32,
    bound: bool,
) -> (Vec<Vec<V3>>, DeformReport) {
    let params = DeformParams {
        relief: ReliefParams {
            steps,
            ..Default::default()
        },
        // The relief as such (`run`): the captured sheet of `captured_case` is the same in every frame, so it
        // shows no lost surface and the bound would give it back unchanged.
        lost_area_bound: bound,
        ..DeformParams::default()
    };
    let mut sink = MemorySink::default();
    let (report, _) = deform(seq, anchors, &params, &mut sink, &NoProgress, &[]).unwrap();
    (sink.frames.into_values().collect(), report)
}

#[test]
fn the_relief_brings_the_output_closer_to_the_cloth_the_capture_smoothed() {
    let (seq, anchors, truth) = captured_case(0.0);
    let topo = seq.topology.clone();
    let captured = &seq.frames[0];
    // The interior of the anchored band, away from the sheet's rim.
    let band = |v: usize| {
        let q = captured[v];
        (17.0..25.0).contains(&q[0]) && (5.0..15.0).contains(&q[1])
    };
    let plain = run(&seq, &anchors, 0);
    let restored = run(&seq, &anchors, 8);
    let t = FRAMES / 2;
    let e_captured = mean_normal_error(&topo, captured, &truth, band);
    let e_plain = mean_normal_error(&topo, &plain[t], &truth, band);
    let e_restored = mean_normal_error(&topo, &restored[t], &truth, band);
    assert!(
        e_restored < 0.88 * e_captured && e_restored < 0.88 * e_plain,
        "normal error vs the cloth: captured {e_captured}, plain {e_plain}, restored {e_restored}"
    );
    // In phase: what the relief added points the way the cloth's ripple does.
    let n = geometry::vertex_normals(&topo, captured);
    let (mut agree, mut moved) = (0, 0);
    for v in (0..captured.len()).filter(|&v| band(v)) {
        let added = vec3::dot(vec3::sub(restored[t][v], plain[t][v]), n[v]);
        let real = vec3::dot(vec3::sub(truth[v], captured[v]), n[v]);
        if added.abs() > 1e-3 && real.abs() > 1e-2 {
            moved += 1;
            agree += usize::from(added * real > 0.0);
        }
    }
    assert!(
        moved > 20 && agree as f64 > 0.9 * moved as f64,
        "{agree} of {moved}"
    );
}

/// Anchors a faithful detector would give on the sheet: on the band's anchored triangles, the turn about the
/// ripple's ridge line (y) that takes the noise-free capture's triangle normal to the cloth's.
fn faithful_anchors(seq: &Sequence, truth: &[V3]) -> AnchorSet {
    let topo = &seq.topology;
    let (_, flat) = sheet(42, 24);
    let smooth = blur(topo, truth, 6);
    let (ns, nt) = (
        geometry::triangle_normals(topo, &smooth),
        geometry::triangle_normals(topo, truth),
    );
    let anchors: Vec<Anchor> = anchored_triangles(topo, &flat)
        .map(|t| {
            let (a, b) = (ns[t], nt[t]);
            Anchor {
                triangle: t as u32,
                axis: [0.0, 1.0, 0.0],
                angle: (a[2] * b[0] - a[0] * b[2]).atan2(a[0] * b[0] + a[2] * b[2]),
            }
        })
        .collect();
    AnchorSet::from_frames(vec![anchors; FRAMES], topo.n_triangles(), None).unwrap()
}

/// A capture with reconstruction noise (fresh in every frame, a tenth of an edge) comes out no further from the
/// cloth than it went in, over the whole sheet, with the anchors a faithful detector gives; and the relief, which
/// measures that noise over time, amplifies none of it: it moves the vertices by less than a twentieth of the
/// noise, and the output is no further from the cloth (to 0.1 %) than the anchors' deformation alone.
#[test]
fn a_noisy_capture_comes_out_no_further_from_the_cloth() {
    let (seq, _, truth) = captured_case(0.1);
    let anchors = faithful_anchors(&seq, &truth);
    let topo = seq.topology.clone();
    let everywhere = |_| true;
    let out = run(&seq, &anchors, 8);
    let plain = run(&seq, &anchors, 0);
    // The noise's rms: uniform in ±0.1 edges.
    let noise_rms = 0.1 / 3f64.sqrt();
    for t in 0..FRAMES {
        let e_in = mean_normal_error(&topo, &seq.frames[t], &truth, everywhere);
        let e_out = mean_normal_error(&topo, &out[t], &truth, everywhere);
        let e_plain = mean_normal_error(&topo, &plain[t], &truth, everywhere);
        let added = (out[t]
            .iter()
            .zip(&plain[t])
            .map(|(o, p)| vec3::norm(vec3::sub(*o, *p)).powi(2))
            .sum::<f64>()
            / out[t].len() as f64)
            .sqrt();
        eprintln!(
            "frame {t}: in {e_in:.6} plain {e_plain:.6} out {e_out:.6}; relief rms {added:.2e}"
        );
        assert!(
            e_out <= e_in && e_out <= e_plain * 1.001,
            "frame {t}: normal error vs the cloth {e_out} after, {e_plain} without the relief, {e_in} before"
        );
        assert!(
            added <= 0.05 * noise_rms,
            "frame {t}: the relief moved vertices by {added} rms, against noise of {noise_rms} rms"
        );
    }
}

#[test]
fn without_anchors_the_relief_leaves_the_input_bit_for_bit() {
    let (seq, _, _) = captured_case(0.0);
    let none = AnchorSet::empty(seq.frames.len());
    let out = run(&seq, &none, 8);
    for (o, i) in out.iter().zip(&seq.frames) {
        let bits = |f: &[V3]| f.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(o), bits(i));
    }
}

#[test]
fn the_relief_settings_are_validated_by_name() {
    for (bad, key) in [
        (
            ReliefParams {
                steps: 33,
                ..Default::default()
            },
            "relief.steps",
        ),
        (
            ReliefParams {
                scale: f64::NAN,
                ..Default::default()
            },
            "relief.scale",
        ),
        (
            ReliefParams {
                temporal_sigma: -1.0,
                ..Default::default()
            },
            "relief.temporal_sigma",
        ),
    ] {
        let params = DeformParams {
            relief: bad,
            ..DeformParams::default()
        };
        let err = params.validate().unwrap_err().to_string();
        assert!(err.contains(key), "{key}: {err}");
    }
    for share in [-0.1, 1.5, f64::NAN] {
        let params = DeformParams {
            release_share: share,
            ..DeformParams::default()
        };
        let err = params.validate().unwrap_err().to_string();
        assert!(err.contains("release_share"), "{share}: {err}");
    }
}

/// The flat sheet bent, without stretching, into `ripple`'s profile at `a` times its height: each row is the
/// curve (x(u), a·h(u)) parametrised by arc length u (x′ = √(1 − (a·h′)²), integrated in fine steps), so the
/// cloth draws in as it folds and its surface stays what it was.
fn folded(flat: &[V3], a: f64) -> Vec<V3> {
    let h = |u: f64| a * ripple(&[[u, 0.0, 0.0]])[0][2];
    let x_of = |u: f64| {
        let steps = (u * 200.0).ceil().max(1.0) as usize;
        let du = u / steps as f64;
        (0..steps)
            .map(|i| {
                let m = (i as f64 + 0.5) * du;
                let slope = (h(m + 1e-5) - h(m - 1e-5)) / 2e-5;
                (1.0 - slope * slope).max(0.0).sqrt() * du
            })
            .sum::<f64>()
    };
    flat.iter().map(|q| [x_of(q[0]), q[1], h(q[0])]).collect()
}

/// Nine frames in which the ripple rises from a flat sheet to its full height and stays (cloth that folds as it
/// moves, so that some frame shows each region open), captured by `capture`, with the band's tilting anchors
/// of `captured_case` in every frame.
fn rising_case(
    mut capture: impl FnMut(&Topology, &[V3], usize) -> Vec<V3>,
) -> (Sequence, AnchorSet, Vec<Vec<V3>>) {
    const N: usize = 9;
    let (topo, flat) = sheet(42, 24);
    let truths: Vec<Vec<V3>> = (0..N)
        .map(|t| folded(&flat, (t as f64 / 4.0).min(1.0)))
        .collect();
    let frames: Vec<Vec<V3>> = truths
        .iter()
        .enumerate()
        .map(|(t, p)| capture(&topo, p, t))
        .collect();
    let anchors: Vec<Anchor> = anchored_triangles(&topo, &flat)
        .map(|t| Anchor {
            triangle: t as u32,
            axis: [0.0, 1.0, 0.0],
            angle: if t % 2 == 0 { 0.15 } else { -0.15 },
        })
        .collect();
    let topo = Arc::new(topo);
    let seq = Sequence::new(topo.clone(), frames).unwrap();
    let set = AnchorSet::from_frames(vec![anchors; N], topo.n_triangles(), None).unwrap();
    (seq, set, truths)
}

/// A capture that kept its folds, with reconstruction noise of a twentieth of an edge, and anchors that turn
/// its band anyway (a detector fooled by the noise): without the bound the output is further from the cloth
/// than the input (up to 2.4 times); with it, every frame comes back as captured, bit for bit (what the
/// deformation adds lands where the capture lost nothing, so the frame is not trusted at all).
#[test]
fn a_capture_that_kept_its_folds_comes_back_no_further_from_the_cloth() {
    let mut rng = Lcg(7);
    let (seq, anchors, truths) = rising_case(|_, p, _| {
        p.iter()
            .map(|q| {
                [
                    q[0] + 0.05 * rng.uniform(),
                    q[1] + 0.05 * rng.uniform(),
                    q[2] + 0.05 * rng.uniform(),
                ]
            })
            .collect()
    });
    let topo = seq.topology.clone();
    let everywhere = |_| true;
    let (bounded, report) = run_reporting(&seq, &anchors, 8, true);
    let free = run_with(&seq, &anchors, 8, false);
    // The report says why: every frame's share of the added surface that was lost is below the trust floor.
    assert_eq!(report.frame_lost_share.len(), truths.len());
    for (t, share) in report.frame_lost_share.iter().enumerate() {
        let share = share.unwrap_or_else(|| panic!("frame {t}: not judged"));
        assert!(share < TRUST_NONE, "frame {t}: share {share}");
    }
    let mut worse_without = 0;
    for (t, truth) in truths.iter().enumerate() {
        let e_in = mean_normal_error(&topo, &seq.frames[t], truth, everywhere);
        let e_out = mean_normal_error(&topo, &bounded[t], truth, everywhere);
        let e_free = mean_normal_error(&topo, &free[t], truth, everywhere);
        eprintln!("frame {t}: in {e_in:.5} bounded {e_out:.5} free {e_free:.5}");
        assert!(
            bounded[t] == seq.frames[t],
            "frame {t}: {e_out} after, {e_in} before"
        );
        worse_without += usize::from(e_free > e_in * 1.01);
    }
    assert!(
        worse_without >= 5,
        "the unbounded output is worse than its input in {worse_without} frames only"
    );
}

/// A capture that lost its folds (smoothed by a low-pass the relief does not model): with the bound the output
/// still comes closer to the cloth in the band wherever the ripple stands at full height.
#[test]
fn a_capture_that_lost_its_folds_keeps_them_under_the_bound() {
    let (seq, anchors, truths) = rising_case(|topo, p, _| blur(topo, p, 6));
    let topo = seq.topology.clone();
    let band = |v: usize| {
        let q = seq.frames[0][v];
        (17.0..25.0).contains(&q[0]) && (5.0..15.0).contains(&q[1])
    };
    let (out, report) = run_reporting(&seq, &anchors, 8, true);
    eprintln!("lost shares: {:?}", report.frame_lost_share);
    for t in 5..truths.len() {
        let share = report.frame_lost_share[t].unwrap_or_else(|| panic!("frame {t}: not judged"));
        assert!(share >= TRUST_FULL, "frame {t}: share {share}");
        let e_in = mean_normal_error(&topo, &seq.frames[t], &truths[t], band);
        let e_out = mean_normal_error(&topo, &out[t], &truths[t], band);
        assert!(
            e_out < 0.9 * e_in,
            "frame {t}: {e_out} after, {e_in} before"
        );
    }
}

//! The fold restoration (`spacetime/restore.rs`) gives back, in place, the folds a capture smoothed without
//! erasing, where the deformation put folds; it leaves a garment without anchors as it was.

use crease_core::folds::{Anchor, AnchorSet};
use crease_core::mesh::{geometry, MemorySink, Sequence, Topology};
use crease_core::progress::NoProgress;
use crease_core::shape::TaubinFilter;
use crease_core::spacetime::{deform, DeformParams};
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

/// Three frames of the captured sheet (the ripple after the data's capture filter) with anchors that tilt the
/// rippled band a little (a detector that knows where the cloth folded, not where its ridges are).
fn captured_case() -> (Sequence, AnchorSet, Vec<V3>) {
    let (topo, flat) = sheet(42, 24);
    let truth = ripple(&flat);
    let captured = TaubinFilter::capture(&topo).apply(&truth);
    let topo = Arc::new(topo);
    let anchors: Vec<Anchor> = (0..topo.n_triangles())
        .filter(|&t| {
            let x = topo.triangles()[t]
                .iter()
                .map(|&v| flat[v as usize][0])
                .sum::<f64>()
                / 3.0;
            let y = flat[topo.triangles()[t][0] as usize][1];
            (16.0..26.0).contains(&x) && (4.0..16.0).contains(&y) && t % 7 == 0
        })
        .map(|t| Anchor {
            triangle: t as u32,
            axis: [0.0, 1.0, 0.0],
            angle: if t % 2 == 0 { 0.15 } else { -0.15 },
        })
        .collect();
    assert!(anchors.len() > 10);
    let seq = Sequence::new(topo.clone(), vec![captured.clone(); 3]).unwrap();
    let set = AnchorSet::from_frames(vec![anchors; 3], topo.n_triangles(), None).unwrap();
    (seq, set, truth)
}

fn run(seq: &Sequence, anchors: &AnchorSet, fold_restore: f64) -> Vec<Vec<V3>> {
    let params = DeformParams {
        fold_restore,
        ..DeformParams::default()
    };
    let mut sink = MemorySink::default();
    deform(seq, anchors, &params, &mut sink, &NoProgress, &[]).unwrap();
    sink.frames.into_values().collect()
}

#[test]
fn restoration_brings_the_output_closer_to_the_cloth_the_capture_smoothed() {
    let (seq, anchors, truth) = captured_case();
    let topo = seq.topology.clone();
    let captured = &seq.frames[0];
    // The interior of the anchored band, away from the sheet's rim.
    let band = |v: usize| {
        let q = captured[v];
        (17.0..25.0).contains(&q[0]) && (5.0..15.0).contains(&q[1])
    };
    let plain = run(&seq, &anchors, 0.0);
    let restored = run(&seq, &anchors, 3.0);
    let e_captured = mean_normal_error(&topo, captured, &truth, band);
    let e_plain = mean_normal_error(&topo, &plain[1], &truth, band);
    let e_restored = mean_normal_error(&topo, &restored[1], &truth, band);
    // 0.85 of either with the deconvolution (3 steps) and the data's capture filter, which keeps 68% of a
    // 6-edge ripple on this grid; the old gain of 3 on the half-strength filter's residue overshot the ripple
    // and scored below 0.8 here.
    assert!(
        e_restored < 0.88 * e_captured && e_restored < 0.88 * e_plain,
        "normal error vs the cloth: captured {e_captured}, plain {e_plain}, restored {e_restored}"
    );
    // In phase: what the restoration added points the way the cloth's ripple does.
    let n = geometry::vertex_normals(&topo, captured);
    let (mut agree, mut moved) = (0, 0);
    for v in (0..captured.len()).filter(|&v| band(v)) {
        let added = vec3::dot(vec3::sub(restored[1][v], plain[1][v]), n[v]);
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

#[test]
fn without_anchors_the_restoration_leaves_the_input_bit_for_bit() {
    let (seq, _, _) = captured_case();
    let none = AnchorSet::empty(seq.frames.len());
    let out = run(&seq, &none, 3.0);
    for (o, i) in out.iter().zip(&seq.frames) {
        let bits = |f: &[V3]| f.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(o), bits(i));
    }
}

#[test]
fn the_restoration_gain_is_validated() {
    for bad in [-1.0, f64::NAN, 21.0] {
        let params = DeformParams {
            fold_restore: bad,
            ..DeformParams::default()
        };
        let err = params.validate().unwrap_err().to_string();
        assert!(err.contains("fold_restore"), "{bad}: {err}");
    }
}

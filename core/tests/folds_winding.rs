//! The mesh's winding is arbitrary (files from different tools disagree): it must not decide which way a fold
//! rises. Flipping every triangle of the input must give the same output geometry.

use crease_core::folds::stretch::StretchDetector;
use crease_core::folds::{AnchorSet, FoldDetector};
use crease_core::mesh::{FrameSource, MemorySink, Sequence, Topology};
use crease_core::progress::NoProgress;
use crease_core::spacetime::{deform, DeformParams};
use crease_core::synth;
use crease_core::vec3;
use std::sync::Arc;

fn output(seq: &Sequence) -> (AnchorSet, Vec<Vec<[f64; 3]>>) {
    let n = seq.n_frames();
    let detector = StretchDetector::default();
    let frames = detector.detect(seq, 0..n, &NoProgress).unwrap();
    let anchors = AnchorSet::from_frame_anchors(frames, seq.topology.n_triangles(), None).unwrap();
    let mut sink = MemorySink::default();
    deform(
        seq,
        &anchors,
        &DeformParams::default(),
        &mut sink,
        &NoProgress,
        &[],
    )
    .unwrap();
    (anchors, sink.frames.into_values().collect())
}

/// Patches are flattened by unfolding (LSCM where a patch folds over); both give the mirrored layout bit for bit
/// under the flip.
#[test]
fn flipped_winding_gives_identical_geometry() {
    let seq = synth::compressed_tube(2500, 10, 0.3, 0.5).unwrap();
    let flipped: Vec<[u32; 3]> = seq
        .topology
        .triangles()
        .iter()
        .map(|t| [t[0], t[2], t[1]])
        .collect();
    let topo = Arc::new(Topology::new(seq.topology.n_vertices(), flipped).unwrap());
    let seq2 = Sequence::new(topo, seq.frames.clone()).unwrap();
    let (a1, out1) = output(&seq);
    let (a2, out2) = output(&seq2);
    assert!(a1.total() > 50, "only {} anchors", a1.total());
    // The same triangles get the same rotations.
    for t in 0..seq.n_frames() {
        let (f1, f2) = (a1.frame(t), a2.frame(t));
        assert_eq!(
            f1.iter().map(|a| a.triangle).collect::<Vec<_>>(),
            f2.iter().map(|a| a.triangle).collect::<Vec<_>>(),
            "frame {t}"
        );
        for (x, y) in f1.iter().zip(f2) {
            let d = vec3::norm(vec3::sub(x.rotation_vector(), y.rotation_vector()));
            assert!(
                d < 1e-6,
                "frame {t} triangle {}: {x:?} vs {y:?}",
                x.triangle
            );
        }
    }
    // And the deformation puts every vertex at the same place.
    let h = crease_core::folds::stretch::mean_edge_length(&seq.topology, &seq.frames[0]);
    let mut worst = 0.0f64;
    let mut moved = 0.0f64;
    for (t, (p1, p2)) in out1.iter().zip(&out2).enumerate() {
        for (k, (x, y)) in p1.iter().zip(p2).enumerate() {
            worst = worst.max(vec3::norm(vec3::sub(*x, *y)));
            moved = moved.max(vec3::norm(vec3::sub(*x, seq.frames[t][k])));
        }
    }
    assert!(
        moved > 0.05 * h,
        "the folds moved the surface by only {moved}"
    );
    assert!(
        worst < 1e-6 * h,
        "flipped winding moved a vertex by {worst} (edge {h})"
    );
}

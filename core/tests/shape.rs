//! The deformation adds folds without moving the garment (issue 11, "shape is kept"): checked on a real hanging
//! sheet (the public drape's captured frames 1–16 at half resolution, `fixtures/drape-coarse`) with the folds
//! the stretch detector finds in it.

use crease_core::folds::stretch::{StretchDetector, StretchParams};
use crease_core::folds::{AnchorSet, FoldDetector};
use crease_core::mesh::io::open_sequence;
use crease_core::mesh::{geometry, MemorySink, Sequence};
use crease_core::progress::NoProgress;
use crease_core::shape::{ShapeAccumulator, TaubinFilter};
use crease_core::spacetime::{deform, so3, DeformParams};
use crease_core::vec3::{self, V3};
use std::path::Path;

fn drape() -> Sequence {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/drape-coarse");
    Sequence::load(open_sequence(&dir).unwrap().source.as_ref()).unwrap()
}

fn anchors_of(seq: &Sequence) -> AnchorSet {
    let frames = StretchDetector::new(StretchParams::default())
        .detect(seq, 0..seq.frames.len(), &NoProgress)
        .unwrap();
    AnchorSet::from_frame_anchors(frames, seq.topology.n_triangles(), None).unwrap()
}

fn run(seq: &Sequence, anchors: &AnchorSet, params: &DeformParams) -> Vec<Vec<V3>> {
    let mut sink = MemorySink::default();
    deform(seq, anchors, params, &mut sink, &NoProgress, &[]).unwrap();
    sink.frames.into_values().collect()
}

fn width(p: &[V3]) -> f64 {
    let (lo, hi) = geometry::bounding_box(p);
    hi[0] - lo[0]
}

#[test]
fn hanging_sheet_keeps_its_width_and_does_not_drift() {
    let seq = drape();
    let anchors = anchors_of(&seq);
    assert!(
        anchors.total() > 100,
        "the fixture must have folds to add: {} anchors",
        anchors.total()
    );
    let out = run(&seq, &anchors, &DeformParams::default());
    let filter = TaubinFilter::captured(&seq.topology);
    let mut shape = ShapeAccumulator::default();
    let mut moved = 0.0f64;
    for (t, (o, c)) in out.iter().zip(&seq.frames).enumerate() {
        let change = (width(o) - width(c)).abs() / width(c);
        assert!(
            change <= 0.01,
            "frame {t}: width {:.4} m against the captured {:.4} m ({:.1}%)",
            width(o),
            width(c),
            100.0 * change
        );
        shape.add_frame(&seq.topology, &filter, c, o);
        moved = moved.max(
            o.iter()
                .zip(c)
                .map(|(a, b)| vec3::norm(vec3::sub(*a, *b)))
                .fold(0.0, f64::max),
        );
    }
    let s = shape.stats();
    // Folds were added (the output is not the input), but the garment's low-frequency shape stayed: drift well
    // under the displacement, and at most a fraction of an edge on average.
    assert!(s.displacement_max > 0.5, "no folds were added: {s:?}");
    assert!(
        s.drift_mean < 0.1 && s.drift_mean < 0.5 * s.displacement_mean,
        "{s:?}"
    );
    assert!(s.extent_change <= 0.01, "{s:?}");
    assert!(moved > 0.0);
}

#[test]
fn rigid_motion_of_the_input_moves_the_output_rigidly() {
    let seq = drape();
    let q = so3::exp([0.9, -0.4, 1.3]);
    let shift = [2.0, -1.5, 0.7];
    let moved = Sequence::new(
        seq.topology.clone(),
        seq.frames
            .iter()
            .map(|f| {
                f.iter()
                    .map(|p| vec3::add(vec3::mat_vec(&q, *p), shift))
                    .collect()
            })
            .collect(),
    )
    .unwrap();
    let params = DeformParams::default();
    let a = anchors_of(&seq);
    let b = anchors_of(&moved);
    assert_eq!(
        (0..seq.frames.len())
            .map(|t| a.frame(t).len())
            .collect::<Vec<_>>(),
        (0..seq.frames.len())
            .map(|t| b.frame(t).len())
            .collect::<Vec<_>>(),
        "the detector found different folds after a rigid motion"
    );
    let out = run(&seq, &a, &params);
    let out_moved = run(&moved, &b, &params);
    let mut worst = 0.0f64;
    for (o, m) in out.iter().zip(&out_moved) {
        for (p, pm) in o.iter().zip(m) {
            let expect = vec3::add(vec3::mat_vec(&q, *p), shift);
            worst = worst.max(vec3::norm(vec3::sub(expect, *pm)));
        }
    }
    // The sheet is 1 m wide with 2 cm edges: agreement to a micrometre is round-off, not geometry.
    assert!(
        worst < 1e-6,
        "output differs from the moved output by {worst} m"
    );
}

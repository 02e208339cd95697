//! The deformation adds folds without moving the garment ("shape is kept"): checked on a real hanging
//! sheet (the public drape's captured frames 1–16 at half resolution, `fixtures/drape-coarse`) with the folds
//! the stretch detector finds in it.

use crease_core::folds::stretch::{StretchDetector, StretchParams};
use crease_core::folds::{Anchor, AnchorSet, FoldDetector, FrameAnchors};
use crease_core::mesh::io::open_sequence;
use crease_core::mesh::{geometry, MemorySink, Sequence};
use crease_core::progress::NoProgress;
use crease_core::shape::ShapeAccumulator;
use crease_core::spacetime::blend::so3;
use crease_core::spacetime::shape::relief::ReliefParams;
use crease_core::spacetime::{deform, DeformParams};
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
    // The defaults, fold relief included.
    let params = DeformParams::default();
    let out = run(&seq, &anchors, &params);
    let filter = crease_core::eval::drift_ruler(&seq.topology);
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
        shape.add_frame(&seq.topology, &|d: &[V3]| filter.apply(d), c, o);
        moved = moved.max(
            o.iter()
                .zip(c)
                .map(|(a, b)| vec3::norm(vec3::sub(*a, *b)))
                .fold(0.0, f64::max),
        );
    }
    let s = shape.stats();
    // Folds were added (the output is not the input), but the garment's low-frequency shape stayed: at most a
    // fraction of an edge of drift on average.
    assert!(
        s.displacement_max > 0.3 && moved > 0.0,
        "no folds were added: {s:?}"
    );
    assert!(s.drift_mean < 0.1, "{s:?}");
    // The bound is the ground truth's own extent change + 1 %. This fixture has no ground truth; the
    // full drape's gt changes its extent by 0.57 % (`crease eval`), so the bound is 1.57 %. (The per-frame width
    // above is held to 1 % outright.) Folds take up some extent legitimately: with the default detector (no
    // seed memory, about a quarter more folds than with it) this fixture measures 1.46 %, the full drape 0.59 %.
    assert!(s.extent_change <= 0.0157, "{s:?}");

    // The same folds through the unscreened system (the positioning before the screen) lose the width: the
    // check above is one the old behaviour fails.
    let old = DeformParams {
        shape_cutoff: 0.0,
        ..DeformParams::default()
    };
    let out = run(&seq, &anchors, &old);
    let worst = out
        .iter()
        .zip(&seq.frames)
        .map(|(o, c)| (width(o) - width(c)).abs() / width(c))
        .fold(0.0, f64::max);
    assert!(
        worst > 0.01,
        "unscreened width change only {:.2}%",
        100.0 * worst
    );
}

/// The detected anchors, turned by `q` (anchor axes are world vectors).
fn rotated(anchors: &AnchorSet, n_tri: usize, q: &[[f64; 3]; 3]) -> AnchorSet {
    let frames = (0..anchors.n_frames())
        .map(|t| FrameAnchors {
            frame: t,
            anchors: anchors
                .frame(t)
                .iter()
                .map(|a| Anchor {
                    axis: vec3::mat_vec(q, a.axis),
                    ..*a
                })
                .collect(),
            ..Default::default()
        })
        .collect();
    AnchorSet::from_frame_anchors(frames, n_tri, None).unwrap()
}

/// Moving the capture rigidly moves the result rigidly: the shape screen pulls towards the input wherever it
/// is, and nothing in the positioning depends on world axes. (The same anchors, turned with the garment: the
/// stretch detector's own invariance belongs to the detector's tests.)
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
    let b = rotated(&a, seq.topology.n_triangles(), &q);
    let out = run(&seq, &a, &params);
    let out_moved = run(&moved, &b, &params);
    let mut worst = 0.0f64;
    let mut folded = 0.0f64;
    for ((o, m), c) in out.iter().zip(&out_moved).zip(&seq.frames) {
        for ((p, pm), pc) in o.iter().zip(m).zip(c) {
            let expect = vec3::add(vec3::mat_vec(&q, *p), shift);
            worst = worst.max(vec3::norm(vec3::sub(expect, *pm)));
            folded = folded.max(vec3::norm(vec3::sub(*p, *pc)));
        }
    }
    assert!(folded > 1e-3, "no folds to move: {folded} m");
    // The sheet is 1 m wide with 2 cm edges: agreement to a micrometre is round-off, not geometry.
    assert!(
        worst < 1e-6,
        "output differs from the moved output by {worst} m"
    );
}

fn load(dir: &Path) -> Sequence {
    Sequence::load(open_sequence(dir).unwrap().source.as_ref()).unwrap()
}

/// Shape figures of `out` (or of the ground truth) against the captured sequence, with `crease eval`'s ruler.
fn shape_of(seq: &Sequence, out: &[Vec<V3>]) -> crease_core::shape::ShapeStats {
    let filter = crease_core::eval::drift_ruler(&seq.topology);
    let mut acc = ShapeAccumulator::default();
    for (o, c) in out.iter().zip(&seq.frames) {
        acc.add_frame(&seq.topology, &|d: &[V3]| filter.apply(d), c, o);
    }
    acc.stats()
}

/// The sleeve's open cuffs keep their shape (drift ≤ 2× the ground truth's): on the public sleeve
/// the output's largest low-frequency drift was on the two rims, which flapped by up to 0.7 edges (along the
/// surface normal) where the real cloth's rims drift by 0.05. Checked on the sleeve fixture (captured frames
/// 20–23 with their ground truth) with the folds the stretch detector finds and the lost-area bound off (four
/// frames are too few for it): the output's drift, mean
/// and max, stays within twice the ground truth's and its extent change within the ground truth's + 1 %, and
/// the shape projection lowers the drift against the behaviour before it (`shape_projection` 0; by about a
/// quarter here: the default screen already holds most of what it would remove). Four frames
/// are too few for the rims to flap as they do over the whole sequence (frames 9–44), so without the
/// projection this fixture is within the bound as well (0.31 against 0.55): the 48-frame figures are in
/// bench/results/2026-12-02-shape-projection.md.
#[test]
fn sleeve_rims_drift_no_more_than_twice_the_ground_truth() {
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures");
    let seq = load(&fixtures.join("sleeve"));
    let gt = load(&fixtures.join("sleeve-gt"));
    let anchors = anchors_of(&seq);
    assert!(anchors.total() > 100, "{} anchors", anchors.total());
    let truth = shape_of(&seq, &gt.frames);
    // Four frames are also too few for the lost-area bound, which measures what the capture lost against the
    // sequence's own frames: the cloth never lies open in them, so it would give the frames back as captured
    // and leave no folds to check the shape of.
    let defaults = DeformParams {
        lost_area_bound: false,
        ..DeformParams::default()
    };
    let out = run(&seq, &anchors, &defaults);
    let s = shape_of(&seq, &out);
    assert!(s.displacement_max > 0.3, "no folds were added: {s:?}");
    assert!(
        s.drift_max <= 2.0 * truth.drift_max && s.drift_mean <= 2.0 * truth.drift_mean,
        "output {s:?}\nground truth {truth:?}"
    );
    assert!(
        s.extent_change <= truth.extent_change + 0.01,
        "output {s:?}\nground truth {truth:?}"
    );
    // What the projection itself does, without the relief that follows it (the relief's heights are detail
    // along the normal, which the drift partly counts).
    let no_relief = DeformParams {
        relief: ReliefParams {
            steps: 0,
            ..Default::default()
        },
        ..defaults.clone()
    };
    let unprojected = DeformParams {
        shape_projection: 0.0,
        ..no_relief.clone()
    };
    let projected = shape_of(&seq, &run(&seq, &anchors, &no_relief));
    let old = shape_of(&seq, &run(&seq, &anchors, &unprojected));
    assert!(
        projected.drift_max < 0.9 * old.drift_max && projected.drift_mean < 0.8 * old.drift_mean,
        "projected {projected:?}\nwithout the projection: {old:?}"
    );
}

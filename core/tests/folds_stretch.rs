//! Geometric fold estimation (Chen 2011 ch. 4) on procedural sequences with known answers.

use crease_core::folds::stretch::{StretchDetector, StretchParams, TracedFold};
use crease_core::folds::{FoldDetector, Granularity};
use crease_core::mesh::{FrameSource, Sequence};
use crease_core::progress::NoProgress;
use crease_core::synth;
use crease_core::vec3::{self, V3};

/// Runs the detector and keeps the traced folds and anchor counts of every frame.
fn folds_of(seq: &Sequence, params: StretchParams) -> Vec<(Vec<TracedFold>, usize)> {
    let mut out = Vec::new();
    StretchDetector::new(params)
        .run(seq, &NoProgress, |_, _, _, f| {
            out.push((f.folds, f.anchors.len()));
            Ok(())
        })
        .unwrap();
    assert_eq!(out.len(), seq.n_frames());
    out
}

fn centroid(seq: &Sequence, t: usize, tri: u32) -> V3 {
    let v = seq.topology.triangles()[tri as usize];
    let p = &seq.frames[t];
    vec3::scale(
        vec3::add(
            vec3::add(p[v[0] as usize], p[v[1] as usize]),
            p[v[2] as usize],
        ),
        1.0 / 3.0,
    )
}

/// Ramp 0 → 1 over `up` frames, hold for `hold`, back to 0 over `down`, then rest for `rest`.
fn envelope(up: usize, hold: usize, down: usize, rest: usize) -> Vec<f64> {
    let mut e = vec![0.0];
    e.extend((1..=up).map(|i| i as f64 / up as f64));
    e.extend(std::iter::repeat_n(1.0, hold));
    e.extend((1..=down).map(|i| 1.0 - i as f64 / down as f64));
    e.extend(std::iter::repeat_n(0.0, rest));
    e
}

#[test]
fn compression_gives_perpendicular_axes_and_seeds_in_the_region() {
    let phi = 0.5f64; // compression direction, not aligned with the grid
    let env = envelope(6, 1, 0, 0);
    let seq = synth::compressed_sheet(32, 32, 0.1, phi, (0.35, 0.65), 0.12, 0.03, &env).unwrap();
    let folds = folds_of(&seq, StretchParams::default());
    let mut n_folds = 0;
    for (t, (ff, _)) in folds.iter().enumerate() {
        // Compression direction at frame t (the sheet spins by 0.03 rad per frame).
        let a = phi + 0.03 * t as f64;
        let c = [a.cos(), a.sin(), 0.0];
        // Band in the rotated frame: s measured along c from the sheet's extent, as the generator does.
        let s_of = |p: V3| vec3::dot(p, c);
        let (lo, hi) = seq.frames[t]
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(x, y), &p| {
                (x.min(s_of(p)), y.max(s_of(p)))
            });
        for f in ff {
            n_folds += 1;
            let ang = vec3::dot(f.direction, c).abs().asin().to_degrees();
            assert!(
                ang < 15.0,
                "frame {t}: fold axis {:.1}° off perpendicular",
                ang
            );
            let s = (s_of(centroid(&seq, t, f.seed)) - lo) / (hi - lo);
            // The band [0.35, 0.65] shrinks towards its lower end: at 12% it spans [0.35, ~0.62] of the extent.
            assert!(
                (0.33..=0.67).contains(&s),
                "frame {t}: seed at {s:.2} outside the compressed band"
            );
        }
    }
    assert!(
        n_folds >= 3,
        "expected folds in the compressed frames, got {n_folds}"
    );
    // Nothing before the compression starts.
    assert!(folds[0].0.is_empty());
}

#[test]
fn rigid_motion_and_isometric_bending_give_no_folds() {
    // Rigid: a sheet that only spins and translates.
    let (topo, flat) = synth::sheet(24, 24, 0.1).unwrap();
    let frames: Vec<Vec<V3>> = (0..8)
        .map(|t| {
            let (s, c) = (0.2 * t as f64).sin_cos();
            flat.iter()
                .map(|p| {
                    [
                        c * p[0] - s * p[2] + 0.1 * t as f64,
                        p[1],
                        s * p[0] + c * p[2],
                    ]
                })
                .collect()
        })
        .collect();
    let rigid = Sequence::new(topo.clone(), frames).unwrap();
    for (t, (f, a)) in folds_of(&rigid, StretchParams::default())
        .iter()
        .enumerate()
    {
        assert!(
            f.is_empty() && *a == 0,
            "rigid motion: {} folds at frame {t}",
            f.len()
        );
    }
    // Isometric bending: the sheet rolls onto cylinders of decreasing radius (developable, no stretch).
    let frames: Vec<Vec<V3>> = (0..8)
        .map(|t| {
            let k = 0.6 * t as f64; // curvature 1/m
            flat.iter()
                .map(|p| {
                    if k == 0.0 {
                        *p
                    } else {
                        let th = p[0] * k;
                        [th.sin() / k, p[1], (1.0 - th.cos()) / k]
                    }
                })
                .collect()
        })
        .collect();
    let bent = Sequence::new(topo, frames).unwrap();
    for (t, (f, a)) in folds_of(&bent, StretchParams::default()).iter().enumerate() {
        assert!(
            f.is_empty() && *a == 0,
            "isometric bending: {} folds at frame {t}",
            f.len()
        );
    }
}

#[test]
fn a_fold_that_forms_and_relaxes_is_found_in_both_phases() {
    // Forms over frames 1..=5, holds 1 frame, relaxes over 5 frames, rests.
    let env = envelope(5, 1, 5, 2);
    let seq = synth::compressed_sheet(28, 28, 0.1, 0.0, (0.4, 0.6), 0.12, 0.0, &env).unwrap();
    let folds = folds_of(&seq, StretchParams::default());
    let with_folds = |r: std::ops::Range<usize>| r.filter(|&t| !folds[t].0.is_empty()).count();
    assert!(
        with_folds(2..6) >= 3,
        "forming phase: {:?}",
        folds.iter().map(|f| f.0.len()).collect::<Vec<_>>()
    );
    assert!(
        with_folds(7..11) >= 3,
        "relaxing phase: {:?}",
        folds.iter().map(|f| f.0.len()).collect::<Vec<_>>()
    );
    // At rest, before and after, there is nothing to find.
    assert!(folds[0].0.is_empty() && folds[env.len() - 1].0.is_empty());
    for (ff, a) in &folds {
        assert!(ff.is_empty() || *a > 0, "traced folds must produce anchors");
    }
}

#[test]
fn detector_contract() {
    let env = envelope(3, 0, 0, 0);
    let seq = synth::compressed_sheet(12, 12, 0.1, 0.0, (0.3, 0.7), 0.1, 0.0, &env).unwrap();
    let d = StretchDetector::default();
    assert_eq!(d.granularity(), Granularity::WholeSequence);
    let out = d.detect(&seq, 0..seq.n_frames(), &NoProgress).unwrap();
    assert_eq!(
        out.iter().map(|f| f.frame).collect::<Vec<_>>(),
        (0..4).collect::<Vec<_>>()
    );
    let e = d.detect(&seq, 1..3, &NoProgress).unwrap_err().to_string();
    assert!(e.contains("whole sequence"), "{e}");
    let bad = StretchDetector::new(StretchParams {
        theta0_deg: 120.0,
        ..Default::default()
    });
    let e = bad.detect(&seq, 0..4, &NoProgress).unwrap_err().to_string();
    assert!(e.contains("theta0"), "{e}");
}

/// Frames computed on demand (nothing stored), counting reads: the detector must stream.
struct GeneratedSheet {
    topo: std::sync::Arc<crease_core::mesh::Topology>,
    flat: Vec<V3>,
    n: usize,
    reads: Vec<std::sync::atomic::AtomicUsize>,
}

impl FrameSource for GeneratedSheet {
    fn topology(&self) -> &std::sync::Arc<crease_core::mesh::Topology> {
        &self.topo
    }
    fn n_frames(&self) -> usize {
        self.n
    }
    fn read_frame(&self, t: usize) -> crease_core::Result<Vec<V3>> {
        self.reads[t].fetch_add(1, std::sync::atomic::Ordering::SeqCst);
        // Compression of the middle band, cycling every 20 frames.
        let e = 0.5 * (1.0 - (2.0 * std::f64::consts::PI * t as f64 / 20.0).cos());
        Ok(self
            .flat
            .iter()
            .map(|p| {
                let x = p[0].clamp(0.6, 1.2);
                [p[0] - 0.1 * e * (x - 0.6), p[1], p[2]]
            })
            .collect())
    }
    fn describe_frame(&self, t: usize) -> String {
        format!("generated frame {t}")
    }
}

#[test]
fn long_sequences_are_streamed_twice_and_folds_keep_cycling() {
    let (topo, flat) = synth::sheet(19, 12, 0.1).unwrap();
    let n = 120;
    let src = GeneratedSheet {
        topo,
        flat,
        n,
        reads: (0..n).map(|_| Default::default()).collect(),
    };
    let mut with_folds = 0;
    StretchDetector::default()
        .run(&src, &NoProgress, |_, _, _, f| {
            with_folds += usize::from(!f.folds.is_empty());
            Ok(())
        })
        .unwrap();
    // One backward and one forward pass: every frame is read at most twice, whatever the length.
    for (t, r) in src.reads.iter().enumerate() {
        let r = r.load(std::sync::atomic::Ordering::SeqCst);
        assert!((1..=2).contains(&r), "frame {t} read {r} times");
    }
    // Six compression cycles: folds form and relax in every one, not only in the first.
    assert!(
        with_folds >= 6 * 8,
        "only {with_folds} of {n} frames have folds"
    );
}

#[test]
fn a_compressed_tube_gets_folds_around_its_axis() {
    // The benchmark's sleeve, small and without twist: compressed along z, then released, over 10 frames.
    let seq = synth::compressed_tube(2500, 10, 0.3, 0.0).unwrap();
    let folds = folds_of(&seq, StretchParams::default());
    assert!(folds[0].0.is_empty(), "nothing at rest");
    let mut n = 0;
    for (t, (ff, a)) in folds.iter().enumerate() {
        assert!(ff.is_empty() || *a > 0);
        for f in ff {
            n += 1;
            // Compression is along the tube's axis (z): fold axes run around it.
            let off = f.direction[2].abs().asin().to_degrees();
            assert!(
                off < 15.0,
                "frame {t}: fold axis {off:.1}° off the circumferential direction"
            );
        }
    }
    assert!(n >= 10, "only {n} folds");
}

//! Properties of the space-time deformation that must hold whatever the implementation details.

use crease_core::folds::{Anchor, AnchorSet};
use crease_core::mesh::{MemorySink, Sequence};
use crease_core::progress::NoProgress;
use crease_core::spacetime::blend::so3;
use crease_core::spacetime::position::stretch::StretchRotation;
use crease_core::spacetime::shape::relief::ReliefParams;
use crease_core::spacetime::weights::operator::SpaceTimeOperator;
use crease_core::spacetime::weights::per_anchor::LocalCg;
use crease_core::spacetime::weights::{solve_window, WindowProblem};
use crease_core::spacetime::windows::Window;
use crease_core::spacetime::{deform, Coefficients, DeformParams, WeightMode};
use crease_core::synth::{self, DemoSpec};
use crease_core::vec3;
use std::sync::Arc;

fn small_demo(frames: usize) -> (Sequence, AnchorSet) {
    synth::demo(&DemoSpec {
        triangles: 6000,
        frames,
        ..Default::default()
    })
    .unwrap()
}

/// The blended rotation-vector field of frames `0..n` solved as one window.
fn whole_sequence_field(
    topo: &crease_core::mesh::Topology,
    anchors: &AnchorSet,
    n: usize,
    params: &DeformParams,
) -> Vec<[f64; 3]> {
    let problem = WindowProblem::new(
        topo,
        anchors,
        Window { start: 0, len: n },
        params.coefficients,
    );
    solve_window(&problem, params, &NoProgress).unwrap().0
}

fn run(
    seq: &Sequence,
    anchors: &AnchorSet,
    params: &DeformParams,
) -> (Vec<Vec<[f64; 3]>>, crease_core::spacetime::DeformReport) {
    let mut sink = MemorySink::default();
    let (report, _) = deform(seq, anchors, params, &mut sink, &NoProgress, &[]).unwrap();
    (sink.frames.into_values().collect(), report)
}

#[test]
fn no_anchors_returns_input() {
    let (seq, _) = small_demo(12);
    let anchors = AnchorSet::empty(seq.frames.len());
    for mode in [WeightMode::Fused, WeightMode::PerAnchor] {
        let params = DeformParams {
            mode,
            ..Default::default()
        };
        let (out, _) = run(&seq, &anchors, &params);
        assert_eq!(out.len(), seq.frames.len());
        // The promise is bit for bit (the positioning solves for a displacement whose right-hand side is exactly
        // zero without anchors), so compare the bits, not within a tolerance.
        for (t, (o, i)) in out.iter().zip(&seq.frames).enumerate() {
            assert_eq!(o.len(), i.len());
            for (v, (a, b)) in o.iter().zip(i).enumerate() {
                assert!(
                    (0..3).all(|k| a[k].to_bits() == b[k].to_bits()),
                    "{mode}: frame {t} vertex {v}: {a:?} vs {b:?}"
                );
            }
        }
    }
}

#[test]
fn rigid_motion_of_input_moves_output_rigidly() {
    let (seq, anchors) = small_demo(9);
    let params = DeformParams::default();
    let (out, _) = run(&seq, &anchors, &params);
    let q = so3::exp([0.4, -1.1, 0.7]);
    let shift = [3.0, -2.0, 0.5];
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
    let moved_anchors = AnchorSet::from_frames(
        (0..seq.frames.len())
            .map(|t| {
                anchors
                    .frame(t)
                    .iter()
                    .map(|a| Anchor {
                        axis: vec3::mat_vec(&q, a.axis),
                        ..*a
                    })
                    .collect()
            })
            .collect(),
        seq.topology.n_triangles(),
        None,
    )
    .unwrap();
    let (out_moved, _) = run(&moved, &moved_anchors, &params);
    let mut worst = 0.0f64;
    for (a, b) in out.iter().zip(&out_moved) {
        for (p, pm) in a.iter().zip(b) {
            let want = vec3::add(vec3::mat_vec(&q, *p), shift);
            worst = worst.max(vec3::norm(vec3::sub(want, *pm)));
        }
    }
    // Fold displacements are millimetres to centimetres; equivariance holds to CG/round-off accuracy.
    assert!(worst < 1e-6, "rigid motion changed the result by {worst}");
}

/// Rotation (angle, unit axis) taking a triangle's original orthonormal frame (first edge, normal) to its output
/// frame.
fn triangle_rotation(rest: &[[f64; 3]], out: &[[f64; 3]], tri: [u32; 3]) -> (f64, [f64; 3]) {
    let frame = |p: &[[f64; 3]]| {
        let a = p[tri[0] as usize];
        let e = vec3::normalize(vec3::sub(p[tri[1] as usize], a));
        let n = vec3::normalize(vec3::cross(
            vec3::sub(p[tri[1] as usize], a),
            vec3::sub(p[tri[2] as usize], a),
        ));
        let b = vec3::cross(n, e);
        [e, b, n]
    };
    let f0 = frame(rest);
    let f1 = frame(out);
    // R = F1ᵀ F0 in column terms: R maps e0→e1, b0→b1, n0→n1.
    let mut r = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            r[i][j] = (0..3).map(|k| f1[k][i] * f0[k][j]).sum();
        }
    }
    let phi = so3::log(&r);
    (vec3::norm(phi), vec3::normalize(phi))
}

#[test]
fn single_anchor_rotates_its_triangle_and_decays() {
    let (topo, rest) = synth::sheet(60, 60, 0.01).unwrap();
    let n = 15;
    let seq = Sequence::new(topo.clone(), vec![rest.clone(); n]).unwrap();
    // Anchor in the middle of the sheet at frame 7, axis in the plane.
    let centre_tri = {
        let mut best = (f64::INFINITY, 0u32);
        for (t, tri) in topo.triangles().iter().enumerate() {
            let c = tri
                .iter()
                .fold([0.0; 3], |s, &v| vec3::add(s, rest[v as usize]));
            let d = vec3::norm(vec3::sub(vec3::scale(c, 1.0 / 3.0), [0.3, 0.3, 0.0]));
            if d < best.0 {
                best = (d, t as u32);
            }
        }
        best.1
    };
    let angle = 0.6;
    let mut lists = vec![Vec::new(); n];
    lists[7].push(Anchor {
        triangle: centre_tri,
        axis: [1.0, 0.0, 0.0],
        angle,
    });
    let anchors = AnchorSet::from_frames(lists, topo.n_triangles(), None).unwrap();
    let params = DeformParams {
        window: n,
        shift: n,
        stretch_passes: 0,
        // The positioning of one rotated triangle as such: the shape projection (on by default) takes
        // away the wide part of a lone anchor's turn, which a capture would have seen, and the lost-area bound
        // takes all of it on a still sheet that lost no surface.
        shape_projection: 0.0,
        lost_area_bound: false,
        ..Default::default()
    };
    // The blended rotation field itself: the anchor's own triangle gets close to the full rotation.
    let field = whole_sequence_field(&topo, &anchors, n, &params);
    let n_tri = topo.n_triangles();
    let at = |t: usize, tri: usize| vec3::norm(field[t * n_tri + tri]);
    let own = at(7, centre_tri as usize);
    // c_a/(c_a + neighbours' pull): the anchor term dominates, the smoothness terms pull it down somewhat.
    assert!(
        own > 0.6 * angle && own <= angle * 1.001,
        "own rotation {own}"
    );
    // Decay in space: rings of triangles further away rotate less.
    let centroid = |tri: usize| {
        let t = topo.triangles()[tri];
        vec3::scale(
            t.iter()
                .fold([0.0; 3], |s, &v| vec3::add(s, rest[v as usize])),
            1.0 / 3.0,
        )
    };
    let c0 = centroid(centre_tri as usize);
    let mean_at = |t: usize, lo: f64, hi: f64| {
        let (mut s, mut k) = (0.0, 0);
        for tri in 0..n_tri {
            let d = vec3::norm(vec3::sub(centroid(tri), c0));
            if d >= lo && d < hi {
                s += at(t, tri);
                k += 1;
            }
        }
        s / k as f64
    };
    let rings: Vec<f64> = (0..5)
        .map(|k| mean_at(7, 0.02 * k as f64 + 0.005, 0.02 * (k + 1) as f64 + 0.005))
        .collect();
    for w in rings.windows(2) {
        assert!(w[1] < w[0], "spatial decay {rings:?}");
    }
    // Decay in time: the same triangle in frames further from 7.
    let times: Vec<f64> = (0..5).map(|d| at(7 + d, centre_tri as usize)).collect();
    for w in times.windows(2) {
        assert!(w[1] < w[0], "temporal decay {times:?}");
    }
    // After positioning, a lone anchor's triangle turns about the anchor's axis, less than the blend asks: one
    // rotated triangle in an unrotated neighbourhood is not the gradient of any surface, and the least-squares
    // fit spreads it (a line of anchors, as a fold edge gives, is realised fully; see `anchor_line_...`).
    let (out, _) = run(&seq, &anchors, &params);
    let tri = topo.triangles()[centre_tri as usize];
    let (applied, axis) = triangle_rotation(&rest, &out[7], tri);
    assert!(applied > 0.25 * own, "applied {applied} vs blended {own}");
    assert!(
        axis[0].abs() > 0.9,
        "rotation axis {axis:?} is not the anchor's"
    );
    let (far, _) = triangle_rotation(&rest, &out[0], tri);
    assert!(far < 0.15 * applied, "frame 0 rotated by {far}");
}

#[test]
fn anchor_line_is_realised_by_positioning() {
    // A fold edge: a row of anchors across a sheet, all frames; the positioned triangles on the row turn by
    // about the blended rotation.
    let (topo, rest) = synth::sheet(50, 50, 0.01).unwrap();
    let n = 5;
    let seq = Sequence::new(topo.clone(), vec![rest.clone(); n]).unwrap();
    let row: Vec<u32> = (0..topo.n_triangles() as u32)
        .filter(|&t| {
            let c = topo.triangles()[t as usize]
                .iter()
                .fold([0.0; 3], |s, &v| vec3::add(s, rest[v as usize]));
            (c[1] / 3.0 - 0.245).abs() < 0.004 && c[0] / 3.0 > 0.05 && c[0] / 3.0 < 0.44
        })
        .collect();
    assert!(row.len() > 40);
    let angle = 0.5;
    let lists = (0..n)
        .map(|_| {
            row.iter()
                .map(|&t| Anchor {
                    triangle: t,
                    axis: [1.0, 0.0, 0.0],
                    angle,
                })
                .collect()
        })
        .collect();
    let anchors = AnchorSet::from_frames(lists, topo.n_triangles(), None).unwrap();
    // A lone line of anchors turning one way is a hinge: everything on one side of it moves as a block, a
    // displacement as long as the sheet, which the shape screen holds to the input by design (a fold is a pair
    // of lines turning opposite ways). This checks the paper's positioning, so without the screen, and without
    // the lost-area bound: five identical frames lost no surface, so it would give every frame back.
    let params = DeformParams {
        stretch_passes: 0,
        shape_cutoff: 0.0,
        lost_area_bound: false,
        ..Default::default()
    };
    let field = whole_sequence_field(&topo, &anchors, n, &params);
    let (out, _) = run(&seq, &anchors, &params);
    let mid = row[row.len() / 2] as usize;
    let blended = vec3::norm(field[2 * topo.n_triangles() + mid]);
    let (applied, axis) = triangle_rotation(&rest, &out[2], topo.triangles()[mid]);
    eprintln!("anchor line: blended {blended:.3} rad, positioned {applied:.3} rad");
    assert!(
        (applied - blended).abs() < 0.2 * blended,
        "applied {applied} vs blended {blended}"
    );
    assert!(axis[0].abs() > 0.95);
}

#[test]
fn per_anchor_and_fused_agree_and_weights_are_convex() {
    let (seq, anchors) = small_demo(10);
    let topo = seq.topology.clone();
    let window = Window { start: 0, len: 10 };
    let coeffs = Coefficients::default();
    let problem = WindowProblem::new(&topo, &anchors, window, coeffs);
    assert!(
        problem.anchors.len() >= 300,
        "only {} anchors",
        problem.anchors.len()
    );
    let fused = DeformParams {
        mode: WeightMode::Fused,
        ..Default::default()
    };
    let per = DeformParams {
        mode: WeightMode::PerAnchor,
        anchor_block: 37,
        ..Default::default()
    };
    let (xf, sf) = solve_window(&problem, &fused, &NoProgress).unwrap();
    let (xp, sp) = solve_window(&problem, &per, &NoProgress).unwrap();
    assert!(sp.blocks > 5);
    // The tolerance bounds residuals, so that is where agreement is measured: the per-anchor sum must solve the
    // fused system to within the tolerance (its error is the sum of the columns' residuals), and tightening the
    // tolerance must bring the two modes together.
    let b = problem.fused_rhs();
    let resid = |x: &[[f64; 3]]| {
        let mut q = vec![[0.0; 3]; x.len()];
        problem.op.apply3(x, &mut q);
        let (mut num, mut den) = (0.0, 0.0);
        for (qq, bb) in q.iter().zip(&b) {
            num += vec3::dot(vec3::sub(*qq, *bb), vec3::sub(*qq, *bb));
            den += vec3::dot(*bb, *bb);
        }
        (num / den).sqrt()
    };
    let rel = |a: &[[f64; 3]], b: &[[f64; 3]]| {
        let (mut num, mut den) = (0.0, 0.0);
        for (x, y) in a.iter().zip(b) {
            num += vec3::dot(vec3::sub(*x, *y), vec3::sub(*x, *y));
            den += vec3::dot(*y, *y);
        }
        (num / den).sqrt()
    };
    let tol = fused.cg_tolerance;
    let diff: Vec<[f64; 3]> = xp.iter().zip(&xf).map(|(p, f)| vec3::sub(*p, *f)).collect();
    let r_f = resid(&xf);
    let r_p = resid(&xp);
    let mut q = vec![[0.0; 3]; diff.len()];
    problem.op.apply3(&diff, &mut q);
    let r_diff = (q.iter().map(|v| vec3::dot(*v, *v)).sum::<f64>()
        / b.iter().map(|v| vec3::dot(*v, *v)).sum::<f64>())
    .sqrt();
    let e_loose = rel(&xp, &xf);
    eprintln!(
        "{} anchors, {} blocks: residual fused {r_f:.2e} ({} it), per-anchor {r_p:.2e} ({} column it); difference {r_diff:.2e} in residual, {e_loose:.2e} relative",
        problem.anchors.len(), sp.blocks, sf.cg_iterations, sp.cg_iterations
    );
    assert!(r_f <= tol && r_p <= 3.0 * tol && r_diff <= 3.0 * tol);
    let tighter = |p: &DeformParams| DeformParams {
        cg_tolerance: tol / 10.0,
        ..p.clone()
    };
    let (xf2, _) = solve_window(&problem, &tighter(&fused), &NoProgress).unwrap();
    let (xp2, _) = solve_window(&problem, &tighter(&per), &NoProgress).unwrap();
    let e_tight = rel(&xp2, &xf2);
    eprintln!(
        "relative difference at tol {tol:e}: {e_loose:.2e}; at {:e}: {e_tight:.2e}",
        tol / 10.0
    );
    assert!(e_tight < e_loose / 4.0 && e_tight < 2e-2);

    // Convexity: every anchor's weight column is in [0, 1] (to the CG tolerance) and their sum is ≤ 1.
    let op = &problem.op;
    let mut sum = vec![0.0f64; op.n_nodes()];
    let mut cg = LocalCg::new(op.n_nodes());
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for a in &problem.anchors {
        cg.solve(op, a.node, coeffs.c_a, 1e-3, 1000).unwrap();
        for (g, w) in cg.column() {
            lo = lo.min(w);
            hi = hi.max(w);
            sum[g as usize] += w;
        }
    }
    let max_sum = sum.iter().cloned().fold(0.0, f64::max);
    eprintln!("weights in [{lo:.2e}, {hi:.4}], max sum {max_sum:.4}");
    assert!(lo >= -1e-3 && hi <= 1.0 + 1e-3 && max_sum <= 1.0 + 1e-3);
    assert!(hi > 0.5, "anchor weights should be substantial: {hi}");
}

#[test]
fn local_cg_matches_whole_window_cg() {
    // The growing-active-set CG must reproduce CG on the whole window (same iterates), not approximate it.
    let (seq, _) = small_demo(10);
    let topo = seq.topology.clone();
    let node = (4 * topo.n_triangles() + 123) as u32;
    let op = SpaceTimeOperator::new(&topo, 10, Coefficients::default(), &[node]);
    let mut cg = LocalCg::new(op.n_nodes());
    cg.solve(&op, node, 10.0, 1e-3, 1000).unwrap();
    let mut b = vec![[0.0; 3]; op.n_nodes()];
    b[node as usize] = [10.0, 0.0, 0.0];
    let (x, _) = crease_core::spacetime::weights::fused::solve3(&op, &b, 1e-3, 1000).unwrap();
    let mut dense = vec![0.0; op.n_nodes()];
    for (g, w) in cg.column() {
        dense[g as usize] = w;
    }
    let worst = dense
        .iter()
        .zip(&x)
        .map(|(a, b)| (a - b[0]).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-12, "local and global CG differ by {worst}");
}

#[test]
fn no_jump_at_window_boundaries() {
    let n = 24;
    let (seq, anchors) = small_demo(n);
    let topo = seq.topology.clone();
    let n_tri = topo.n_triangles();
    let staggered = DeformParams::default();
    // Rotation fields per frame, staggered windows vs one global window.
    let fields = |params: &DeformParams| {
        let windows = crease_core::spacetime::windows::plan_windows(n, params.window, params.shift);
        let mut fade = crease_core::spacetime::blend::CrossFade::new(windows.clone(), n_tri);
        let mut frames = vec![Vec::new(); n];
        for w in windows {
            let p = WindowProblem::new(&topo, &anchors, w, params.coefficients);
            let (x, _) = solve_window(&p, params, &NoProgress).unwrap();
            for (t, f) in fade.push(&x) {
                frames[t] = f;
            }
        }
        frames
    };
    let fs = fields(&staggered);
    let fg = fields(&DeformParams {
        window: n,
        shift: n,
        ..Default::default()
    });
    let change = |f: &Vec<Vec<[f64; 3]>>, t: usize| {
        (0..n_tri)
            .map(|i| so3::angle_between(&so3::exp(f[t][i]), &so3::exp(f[t + 1][i])))
            .fold(0.0, f64::max)
    };
    // Boundary frames: where a window starts or ends (7, 9, 10, 14, 16, 17).
    let boundaries = [6usize, 7, 9, 10, 13, 14, 16, 17];
    let mut worst_ratio = 0.0f64;
    for &t in &boundaries {
        let s = change(&fs, t);
        let g = change(&fg, t);
        worst_ratio = worst_ratio.max(s / g.max(1e-3));
        // The staggered field may not change between frames much more than the global solution does.
        assert!(
            s <= 1.5 * g + 0.02,
            "frame {t}->{}: staggered change {s:.4} rad vs global {g:.4}",
            t + 1
        );
    }
    // And the staggered field stays close to the global one.
    let mut diff = 0.0f64;
    for t in 0..n {
        for i in 0..n_tri {
            diff = diff.max(vec3::norm(vec3::sub(fs[t][i], fg[t][i])));
        }
    }
    eprintln!("max rotation-vector difference staggered vs global {diff:.4} rad; worst boundary ratio {worst_ratio:.3}");
    assert!(diff < 0.15, "staggered differs from global by {diff} rad");
}

#[test]
fn stretch_passes_lower_max_stretch() {
    let (seq, anchors) = small_demo(10);
    // Popa's stretch reduction as such: passes that follow the surface only (the anchored default trades
    // some of this reduction for fold amplitude, see the next test).
    let params = DeformParams {
        stretch_passes: 2,
        stretch_rotation: StretchRotation::Polar,
        // The passes as such: the shape projection, the relief and the lost-area bound (on by default) end
        // the last pass and change its figure (docs/fidelity.md).
        shape_projection: 0.0,
        lost_area_bound: false,
        relief: ReliefParams {
            steps: 0,
            ..Default::default()
        },
        ..Default::default()
    };
    let (_, report) = run(&seq, &anchors, &params);
    let s = &report.stretch;
    eprintln!("stretch per pass: {s:?}");
    assert_eq!(s.len(), 3);
    assert!(
        s[1].max < s[0].max && s[2].max <= s[1].max * 1.0001,
        "{s:?}"
    );
    assert!(s[2].l2 > 0.9 && s[2].l2 < 1.1);
    // Figures (measured on this demo: max 13.0% → 7.7% → 5.6%, L2 excess 8.1e-4 → 4.7e-4 → 3.1e-4): two passes
    // take the worst triangle's stretch below 8% and to at most 0.6 of the unreduced one, and at least halve the
    // L2 stretch excess (the paper: 8% → 4%, 1.00036 → 1.00017).
    assert!(
        s[2].max < 0.08 && s[2].max <= 0.6 * s[0].max,
        "max stretch after two passes: {s:?}"
    );
    assert!(
        s[2].l2 - 1.0 <= 0.5 * (s[0].l2 - 1.0),
        "L2 stretch excess after two passes: {s:?}"
    );
}

/// Mean vertex displacement of `out` from the input sequence.
fn mean_displacement(seq: &Sequence, out: &[Vec<[f64; 3]>]) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for (f, o) in seq.frames.iter().zip(out) {
        for (a, b) in f.iter().zip(o) {
            sum += vec3::norm(vec3::sub(*a, *b));
            n += 1;
        }
    }
    sum / n as f64
}

/// Polar passes forget the anchors and converge to the captured surface, so they erase the folds; anchored
/// passes (the default) pull each triangle halfway back to the blended rotation, so the folds keep most of
/// the amplitude the positioning gave them, while the passes still lower the worst stretch.
#[test]
fn anchored_passes_keep_the_folds_that_polar_passes_erase() {
    let (seq, anchors) = small_demo(10);
    let with = |passes, rotation| {
        let params = DeformParams {
            stretch_passes: passes,
            stretch_rotation: rotation,
            // The passes as such, without the shape projection and the relief that end the last one.
            shape_projection: 0.0,
            relief: ReliefParams {
                steps: 0,
                ..Default::default()
            },
            ..Default::default()
        };
        let (out, report) = run(&seq, &anchors, &params);
        (mean_displacement(&seq, &out), report.stretch)
    };
    assert_eq!(
        DeformParams::default().stretch_rotation,
        StretchRotation::Anchored
    );
    let (d0, _) = with(0, StretchRotation::Anchored);
    let (dp, _) = with(4, StretchRotation::Polar);
    let (da, sa) = with(4, StretchRotation::Anchored);
    eprintln!("mean displacement: no passes {d0:.3e}, 4 polar {dp:.3e}, 4 anchored {da:.3e}; stretch {sa:?}");
    assert!(d0 > 0.0);
    assert!(da > 1.2 * dp, "anchored {da} vs polar {dp}");
    assert!(da > 0.5 * d0, "anchored {da} vs unreduced {d0}");
    assert!(sa[4].max < sa[0].max, "{sa:?}");
}

/// A long procedural sequence produced frame by frame, counting how many frames are held at once.
struct CountingSource {
    seq: Sequence,
    reads: std::sync::atomic::AtomicUsize,
    writes: Arc<std::sync::atomic::AtomicUsize>,
    max_in_flight: std::sync::atomic::AtomicUsize,
    repeat: usize,
}

impl crease_core::mesh::FrameSource for CountingSource {
    fn topology(&self) -> &Arc<crease_core::mesh::Topology> {
        &self.seq.topology
    }
    fn n_frames(&self) -> usize {
        self.seq.frames.len() * self.repeat
    }
    fn read_frame(&self, t: usize) -> crease_core::Result<crease_core::mesh::Frame> {
        use std::sync::atomic::Ordering::SeqCst;
        let r = self.reads.fetch_add(1, SeqCst) + 1;
        let in_flight = r - self.writes.load(SeqCst);
        self.max_in_flight.fetch_max(in_flight, SeqCst);
        Ok(self.seq.frames[t % self.seq.frames.len()].clone())
    }
    fn describe_frame(&self, t: usize) -> String {
        format!("generated frame {t}")
    }
}

struct CountingSink(Arc<std::sync::atomic::AtomicUsize>, Vec<bool>);
impl crease_core::mesh::FrameSink for CountingSink {
    fn write_frame(&mut self, t: usize, _: &[[f64; 3]]) -> crease_core::Result<()> {
        self.0.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
        self.1[t] = true;
        Ok(())
    }
    fn finish(&mut self) -> crease_core::Result<Vec<std::path::PathBuf>> {
        Ok(Vec::new())
    }
}

#[test]
fn long_sequences_stream_with_memory_bounded_by_the_window() {
    let (seq, _) = synth::demo(&DemoSpec {
        triangles: 1500,
        frames: 10,
        ..Default::default()
    })
    .unwrap();
    let writes = Arc::new(std::sync::atomic::AtomicUsize::new(0));
    let source = CountingSource {
        seq,
        reads: Default::default(),
        writes: writes.clone(),
        max_in_flight: Default::default(),
        repeat: 12,
    };
    let n = crease_core::mesh::FrameSource::n_frames(&source);
    let anchors = AnchorSet::empty(n);
    let mut sink = CountingSink(writes, vec![false; n]);
    let params = DeformParams::default();
    deform(&source, &anchors, &params, &mut sink, &NoProgress, &[]).unwrap();
    assert!(sink.1.iter().all(|&w| w), "every frame written");
    let held = source
        .max_in_flight
        .load(std::sync::atomic::Ordering::SeqCst);
    // At most the frames one window releases are read before they are written, however long the sequence.
    assert!(
        held <= params.window,
        "{held} frames held at once for a {n}-frame sequence"
    );
}

#[test]
fn results_are_bit_identical_across_thread_counts() {
    // The cluster will split the same work differently; outputs must not depend on how many threads ran it.
    let (seq, anchors) = small_demo(12);
    for mode in [WeightMode::Fused, WeightMode::PerAnchor] {
        let params = DeformParams {
            mode,
            anchor_block: 50,
            ..Default::default()
        };
        let outputs: Vec<Vec<Vec<[f64; 3]>>> = [1usize, 2, 3]
            .iter()
            .map(|&threads| {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                pool.install(|| run(&seq, &anchors, &params).0)
            })
            .collect();
        for other in &outputs[1..] {
            let same = outputs[0]
                .iter()
                .flatten()
                .zip(other.iter().flatten())
                .all(|(a, b)| a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits()));
            assert!(same, "{mode}: output depends on the thread count");
        }
    }
}

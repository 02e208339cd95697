//! End-to-end tests of `crease run --folds stretch` (fold estimation from the geometry, Chen 2011 ch. 4).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn crease(args: &[&str]) -> Output {
    Command::new(crease_e2e::bin())
        .args(args)
        .args(["--threads", "2", "--quiet", "--preview-size", "64"])
        .output()
        .expect("run crease")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn obj_counts(path: &Path) -> (usize, usize) {
    let text = std::fs::read_to_string(path).unwrap();
    let v = text.lines().filter(|l| l.starts_with("v ")).count();
    let f = text.lines().filter(|l| l.starts_with("f ")).count();
    (v, f)
}

fn frames_in(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "obj"))
        .collect();
    v.sort();
    v
}

#[test]
fn stretch_folds_on_the_captured_sleeve_fixture() {
    let input = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/sleeve");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let o = crease(&[
        "run",
        "--input",
        input.to_str().unwrap(),
        "--folds",
        "stretch",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    // The output is the deformed sequence, with the input's names and vertex counts.
    let ins = frames_in(&input);
    let outs = frames_in(&out);
    assert_eq!(ins.len(), outs.len());
    assert_eq!(obj_counts(&ins[0]).0, obj_counts(&outs[0]).0);
    // The detection is written beside it, inspectable and re-usable as an anchors file.
    let anchors: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("anchors.json")).unwrap()).unwrap();
    assert_eq!(anchors["version"], 1);
    let n_anchors: usize = anchors["frames"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["anchors"].as_array().map_or(0, |a| a.len()))
        .sum();
    assert!(
        n_anchors > 0,
        "the captured sleeve is compressing: folds expected"
    );
    assert!(out.join("folds.png").is_file());
    let lines = std::fs::read_to_string(out.join("folds/control_lines.obj")).unwrap();
    assert!(lines.lines().any(|l| l.starts_with("l ")));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["complete"], true);
    assert_eq!(report["fold_detection"]["source"], "stretch");
    assert_eq!(report["fold_detection"]["anchors"], n_anchors);
    // The lost-area bound judged every frame, and the summary counts those judgements.
    let shares = report["report"]["frame_lost_share"].as_array().unwrap();
    assert_eq!(shares.len(), ins.len());
    assert!(shares
        .iter()
        .all(|s| s.as_f64().is_some_and(|s| (0.0..=1.0).contains(&s))));
    let judged = &report["summary"]["lost_area"];
    let counted: u64 = ["frames_kept", "frames_scaled", "frames_given_back"]
        .iter()
        .map(|k| judged[k].as_u64().unwrap())
        .sum();
    assert_eq!(counted as usize, ins.len(), "{judged}");
    // And what the relief gives back of the surface the smoothed capture lost: a share, with its median.
    let relief = report["report"]["frame_relief_share"].as_array().unwrap();
    assert_eq!(relief.len(), ins.len());
    assert!(relief
        .iter()
        .all(|s| s.is_null() || s.as_f64().is_some_and(|s| (0.0..=1.0).contains(&s))));
    let median = judged["median_relief_share"]
        .as_f64()
        .expect("a median relief share");
    assert!(median > 0.0 && median <= 1.0, "{judged}");
    // Per frame: the folds traced and the seeds tried to find them. Every fold took a
    // seed; a frame with anchors has folds; the anchors file itself does not carry these figures.
    let per_frame = report["fold_detection"]["per_frame"].as_array().unwrap();
    assert_eq!(per_frame.len(), ins.len());
    let mut total_folds = 0;
    for f in per_frame {
        let folds = f["folds"].as_u64().expect("folds per frame");
        let seeds = f["seeds_tried"].as_u64().expect("seeds tried per frame");
        assert!(seeds >= folds, "{f}");
        if f["anchors"].as_u64().unwrap() > 0 {
            assert!(folds > 0, "{f}");
        }
        total_folds += folds;
    }
    assert!(total_folds > 0);
    assert!(!std::fs::read_to_string(out.join("anchors.json"))
        .unwrap()
        .contains("seeds_tried"));
    // The written anchors drive a plain anchors run to the same kind of output.
    let out2 = dir.path().join("again");
    let o = crease(&[
        "run",
        "--input",
        input.to_str().unwrap(),
        "--anchors",
        out.join("anchors.json").to_str().unwrap(),
        "--out",
        out2.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn subdivided_output_keeps_the_original_vertices_first() {
    let env: Vec<f64> = (0..6).map(|t| t as f64 / 5.0).collect();
    let seq = crease_core::synth::compressed_sheet(10, 10, 0.1, 0.3, (0.3, 0.7), 0.12, 0.0, &env)
        .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in");
    crease_core::synth::write_frames(&input, &seq).unwrap();
    let out = dir.path().join("out");
    let o = crease(&[
        "run",
        "--input",
        input.to_str().unwrap(),
        "--folds",
        "stretch",
        "--subdivide",
        "1",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let outs = frames_in(&out);
    assert_eq!(outs.len(), 6);
    let (v, f) = obj_counts(&outs[0]);
    let nv = seq.topology.n_vertices();
    let nt = seq.topology.n_triangles();
    assert_eq!(f, 4 * nt);
    // V + E with E = (3F + boundary edges) / 2 on the coarse mesh.
    let boundary = seq
        .topology
        .tri_adj()
        .iter()
        .flatten()
        .filter(|&&u| u == u32::MAX)
        .count();
    assert_eq!(v, nv + (3 * nt + boundary) / 2);
    // Frame 0 is at rest (no folds yet): its original vertices come back first and (nearly) unmoved.
    let first: Vec<[f64; 3]> = std::fs::read_to_string(&outs[0])
        .unwrap()
        .lines()
        .filter(|l| l.starts_with("v "))
        .take(nv)
        .map(|l| {
            let x: Vec<f64> = l
                .split_whitespace()
                .skip(1)
                .map(|s| s.parse().unwrap())
                .collect();
            [x[0], x[1], x[2]]
        })
        .collect();
    for (a, b) in first.iter().zip(&seq.frames[0]) {
        let d = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
        assert!(d < 0.05, "original vertex moved by {d}");
    }
}

#[test]
fn bad_stretch_parameters_name_their_key() {
    let input = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/sleeve");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let base = [
        "run",
        "--input",
        input.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    let cases: [(&[&str], &str); 6] = [
        (
            &["--folds", "stretch", "--set", "stretch.theta0_deg=95"],
            "stretch.theta0_deg",
        ),
        (
            &["--folds", "stretch", "--set", "stretch.theta0_deg=0"],
            "(0, 90)",
        ),
        (
            &["--folds", "stretch", "--set", "stretch.fold_width=-1"],
            "stretch.fold_width",
        ),
        (
            &["--folds", "stretch", "--set", "stretch.alpha=nan"],
            "stretch.alpha",
        ),
        (
            &["--folds", "stretch", "--anchors", "a.json"],
            "exclude each other",
        ),
        (&["--subdivide", "1", "--anchors", "a.json"], "--subdivide"),
    ];
    for (extra, want) in cases {
        let mut args: Vec<&str> = base.to_vec();
        args.extend_from_slice(extra);
        let o = crease(&args);
        assert!(!o.status.success(), "{extra:?} should fail");
        assert!(stderr(&o).contains(want), "{extra:?}: {}", stderr(&o));
        assert!(!out.join("report.json").exists());
    }
}

//! End-to-end tests of the `crease` binary: real processes, real files.

use crease_e2e::{fixture, stderr, write_anchors};

use std::path::Path;
use std::process::{Command, Output};

fn crease(args: &[&str]) -> Output {
    Command::new(crease_e2e::bin())
        .args(args)
        .args(["--threads", "2"])
        .output()
        .expect("run crease")
}

/// Runs `crease run` on `input` with `anchors` into `out` (small previews).
fn run_on(input: &Path, anchors: &Path, out: &Path) -> Output {
    crease(&[
        "run",
        "--input",
        input.to_str().unwrap(),
        "--anchors",
        anchors.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--preview-size",
        "64",
    ])
}

/// [`run_on`], asserting success.
fn run_ok(input: &Path, anchors: &Path, out: &Path) {
    let o = run_on(input, anchors, out);
    assert!(o.status.success(), "{}", stderr(&o));
}

fn obj_vertices(path: &Path) -> Vec<[f64; 3]> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter(|l| l.starts_with("v "))
        .map(|l| {
            let v: Vec<f64> = l
                .split_whitespace()
                .skip(1)
                .take(3)
                .map(|x| x.parse().unwrap())
                .collect();
            [v[0], v[1], v[2]]
        })
        .collect()
}

#[test]
fn demo_runs_end_to_end() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("demo");
    let o = crease(&[
        "run",
        "--out",
        out.to_str().unwrap(),
        "--demo-triangles",
        "3000",
        "--demo-frames",
        "12",
        "--preview-size",
        "128",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("output/report.json")).unwrap())
            .unwrap();
    assert_eq!(report["complete"], true);
    assert_eq!(report["summary"]["frames"], 12);
    let inputs = std::fs::read_dir(out.join("input")).unwrap().count();
    let outputs: Vec<_> = std::fs::read_dir(out.join("output"))
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.path().extension().is_some_and(|x| x == "obj"))
        .collect();
    assert_eq!(inputs, 12);
    assert_eq!(outputs.len(), 12);
    for png in ["preview.png", "stretch.png"] {
        let bytes = std::fs::read(out.join("output").join(png)).unwrap();
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    }
    // Stretch passes do their job and the folds actually moved vertices.
    let stretch = report["report"]["stretch"].as_array().unwrap();
    assert_eq!(stretch.len(), 3);
    let max0 = stretch[0]["max"].as_f64().unwrap();
    let max2 = stretch[2]["max"].as_f64().unwrap();
    assert!(max2 < max0, "{max0} -> {max2}");
    // The shape figures are in the summary, and the folds did not move the garment as a whole.
    let shape = &report["summary"]["shape_kept"];
    assert!(shape["displacement_max"].as_f64().unwrap() > 0.0, "{shape}");
    assert!(shape["drift_mean"].as_f64().unwrap() < shape["displacement_mean"].as_f64().unwrap());
    let a = obj_vertices(&out.join("input/frame_0006.obj"));
    let b = obj_vertices(&out.join("output/frame_0006.obj"));
    let moved = a
        .iter()
        .zip(&b)
        .filter(|(p, q)| (0..3).any(|k| (p[k] - q[k]).abs() > 1e-4))
        .count();
    assert!(moved > 50, "only {moved} vertices moved");
}

#[test]
fn runs_on_captured_sleeve_fixture_keeping_layout() {
    let dir = tempfile::tempdir().unwrap();
    let anchors = dir.path().join("anchors.json");
    // A short fold edge pair on the sleeve, all four frames.
    write_anchors(&anchors);
    let out = dir.path().join("out");
    let o = crease(&[
        "run",
        "--input",
        fixture().to_str().unwrap(),
        "--anchors",
        anchors.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--mode",
        "per-anchor",
        "--preview-size",
        "96",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    for f in [
        "frame_0020.obj",
        "frame_0021.obj",
        "frame_0022.obj",
        "frame_0023.obj",
    ] {
        let a = obj_vertices(&fixture().join(f));
        let b = obj_vertices(&out.join(f));
        assert_eq!(a.len(), b.len());
        // Vertex order kept: far from the anchors, vertices barely move.
        let close = a
            .iter()
            .zip(&b)
            .filter(|(p, q)| (0..3).all(|k| (p[k] - q[k]).abs() < 2e-3))
            .count();
        assert!(
            close > a.len() / 2,
            "{f}: only {close} of {} vertices stayed in place",
            a.len()
        );
        // Comments of the input survive.
        assert!(std::fs::read_to_string(out.join(f))
            .unwrap()
            .starts_with("# captured"));
    }
}

#[test]
fn bad_inputs_get_clear_errors_and_no_report() {
    let dir = tempfile::tempdir().unwrap();
    let good = fixture();
    let anchors = dir.path().join("a.json");
    std::fs::write(&anchors, r#"{"version":1,"frames":[{"frame":0,"anchors":[{"triangle":99999999,"axis":[1,0,0],"angle":0.5}]}]}"#).unwrap();
    let out = dir.path().join("out");
    let cases: Vec<(Vec<String>, Vec<&str>)> = vec![
        (
            vec!["--anchors".into(), anchors.display().to_string()],
            vec!["a.json", "triangle 99999999 is out of range"],
        ),
        (
            vec!["--set".into(), "deform.shift=0".into()],
            vec!["deform.shift"],
        ),
        (
            vec!["--set".into(), "deform.window=0".into()],
            vec!["deform.window"],
        ),
        (
            vec!["--set".into(), "deform.shift=11".into()],
            vec!["deform.shift:", "window (10)"],
        ),
        (
            vec!["--set".into(), "deform.c_a=-1".into()],
            vec!["deform.c_a"],
        ),
        (
            vec!["--set".into(), "deform.cg_tolerance=2".into()],
            vec!["deform.cg_tolerance"],
        ),
        (
            vec!["--set".into(), "deform.cg_tol=1e-4".into()],
            vec!["`deform.cg_tol` is not a tuning key"],
        ),
        (
            vec!["--set".into(), "deform.operator_block=7".into()],
            vec!["was removed"],
        ),
        (vec!["--mode".into(), "magic".into()], vec!["magic"]),
        (
            vec!["--preview-frames".into(), "9".into()],
            vec!["frame 9 is out of range"],
        ),
    ];
    let empty = dir.path().join("empty.json");
    std::fs::write(&empty, r#"{"version":1,"frames":[]}"#).unwrap();
    for (extra, want) in cases {
        let mut args: Vec<String> = vec![
            "run".into(),
            "--input".into(),
            good.display().to_string(),
            "--out".into(),
            out.display().to_string(),
        ];
        if !extra.contains(&"--anchors".to_string()) {
            args.extend(["--anchors".into(), empty.display().to_string()]);
        }
        args.extend(extra.clone());
        let o = crease(&args.iter().map(String::as_str).collect::<Vec<_>>());
        let err = stderr(&o);
        assert!(!o.status.success(), "{extra:?} should fail");
        for w in want {
            assert!(err.contains(w), "{extra:?}: {err}");
        }
        assert!(!out.join("report.json").exists());
    }
    // A frame with a NaN: the error names the file and the vertex, and nothing is presented as complete.
    let bad = dir.path().join("bad");
    std::fs::create_dir(&bad).unwrap();
    for f in ["frame_0020.obj", "frame_0021.obj"] {
        std::fs::copy(good.join(f), bad.join(f)).unwrap();
    }
    let text = std::fs::read_to_string(bad.join("frame_0021.obj")).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let idx = lines.iter().position(|l| l.starts_with("v ")).unwrap() + 10;
    lines[idx] = "v nan 0 0".into();
    std::fs::write(bad.join("frame_0021.obj"), lines.join("\n")).unwrap();
    let o = run_on(&bad, &empty, &out);
    let err = stderr(&o);
    assert!(!o.status.success());
    assert!(
        // 1-based, as in the file: the 11th `v` line.
        err.contains("frame_0021.obj") && err.contains("vertex 11"),
        "{err}"
    );
    assert!(!out.join("report.json").exists());
    // Output directory equal to the input directory is refused.
    let o = run_on(&bad, &empty, &bad);
    assert!(
        !o.status.success() && stderr(&o).contains("input directory"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn point_cache_and_ply_inputs_keep_their_layout() {
    use crease_core::mesh::io::{read_pc2_header, write_obj, write_pc2, write_ply_frame};
    use crease_core::synth::{self, DemoSpec};
    let (seq, anchors) = synth::demo(&DemoSpec {
        triangles: 2000,
        frames: 8,
        ..Default::default()
    })
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let anchors_path = dir.path().join("anchors.json");
    anchors.write(&anchors_path).unwrap();

    // OBJ topology + PC2 point cache.
    let pc = dir.path().join("pc");
    std::fs::create_dir(&pc).unwrap();
    write_obj(&pc.join("sleeve.obj"), &seq.topology, &seq.frames[0]).unwrap();
    write_pc2(&pc.join("sleeve.pc2"), &seq.frames, 1.0, 1.0).unwrap();
    let out = dir.path().join("out-pc");
    run_ok(&pc, &anchors_path, &out);
    let h_in = read_pc2_header(&pc.join("sleeve.pc2")).unwrap();
    let h_out = read_pc2_header(&out.join("sleeve.pc2")).unwrap();
    assert_eq!(h_in, h_out);
    assert!(out.join("sleeve.obj").exists());

    // Binary PLY frames.
    let ply = dir.path().join("ply");
    std::fs::create_dir(&ply).unwrap();
    for (t, f) in seq.frames.iter().enumerate() {
        write_ply_frame(
            &ply.join(format!("cloth_{t:03}.ply")),
            &seq.topology,
            f,
            true,
        )
        .unwrap();
    }
    let out = dir.path().join("out-ply");
    run_ok(&ply, &anchors_path, &out);
    for t in 0..seq.frames.len() {
        let name = format!("cloth_{t:03}.ply");
        let bytes = std::fs::read(out.join(&name)).unwrap();
        assert!(
            bytes.starts_with(b"ply\nformat binary_little_endian"),
            "{name}"
        );
        assert_eq!(
            bytes.len(),
            std::fs::metadata(ply.join(&name)).unwrap().len() as usize
        );
    }
}

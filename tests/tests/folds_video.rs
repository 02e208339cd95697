//! `crease demo --with-video` and `crease run --folds video` as a user runs them (small sizes, seconds).

use std::path::Path;
use std::process::{Command, Output};

fn crease(args: &[&str]) -> Output {
    Command::new(crease_e2e::bin())
        .args(args)
        .args(["--threads", "2"])
        .output()
        .expect("run crease")
}

fn ok(o: &Output) -> String {
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{err}");
    err
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The demo capture with a synthetic three-camera video, small enough for seconds.
fn video_demo(d: &Path) {
    ok(&crease(&[
        "demo",
        "--out",
        s(d),
        "--triangles",
        "6000",
        "--frames",
        "3",
        "--with-video",
        "--video-cameras",
        "3",
        "--video-width",
        "300",
        "--video-height",
        "400",
    ]));
}

#[test]
fn demo_video_then_run_with_video_folds() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    video_demo(d);
    for f in [
        "cameras.json",
        "input/frame_0001.obj",
        "gt/frame_0003.obj",
        "images/cam02/frame_0003.png",
    ] {
        assert!(d.join(f).is_file(), "{f} missing");
    }
    let out = d.join("out");
    let log = ok(&crease(&[
        "run",
        "--input",
        s(&d.join("input")),
        "--folds",
        "video",
        "--cameras",
        s(&d.join("cameras.json")),
        "--out",
        s(&out),
        "--set",
        "video.overlay_frames=1",
        "--preview-size",
        "64",
        "--set",
        "deform.stretch_passes=1",
    ]));
    assert!(log.contains("tracked vertices"), "{log}");
    let anchors: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("anchors.json")).unwrap()).unwrap();
    let n: usize = anchors["frames"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["anchors"].as_array().map_or(0, Vec::len))
        .sum();
    assert!(n > 0, "no anchors detected");
    assert!(out.join("overlays/frame_0001.png").is_file());
    assert!(out.join("frame_0003.obj").is_file());

    // Explicit vertices out of range, a missing image, and a wrong size are clear errors.
    let e = crease(&[
        "run",
        "--input",
        s(&d.join("input")),
        "--folds",
        "video",
        "--cameras",
        s(&d.join("cameras.json")),
        "--out",
        s(&out),
        "--set",
        "video.front_vertex=0",
        "--set",
        "video.back_vertex=999999",
    ]);
    assert!(!e.status.success());
    assert!(String::from_utf8_lossy(&e.stderr).contains("999999"));
    std::fs::remove_file(d.join("images/cam01/frame_0002.png")).unwrap();
    let e = crease(&[
        "run",
        "--input",
        s(&d.join("input")),
        "--folds",
        "video",
        "--cameras",
        s(&d.join("cameras.json")),
        "--out",
        s(&out),
    ]);
    let msg = String::from_utf8_lossy(&e.stderr);
    assert!(
        !e.status.success()
            && msg.contains("camera cam01, frame 1")
            && msg.contains("frame_0002.png"),
        "{msg}"
    );
    image::RgbImage::new(10, 10)
        .save(d.join("images/cam01/frame_0002.png"))
        .unwrap();
    let e = crease(&[
        "run",
        "--input",
        s(&d.join("input")),
        "--folds",
        "video",
        "--cameras",
        s(&d.join("cameras.json")),
        "--out",
        s(&out),
    ]);
    let msg = String::from_utf8_lossy(&e.stderr);
    assert!(
        !e.status.success() && msg.contains("10x10") && msg.contains("300x400"),
        "{msg}"
    );
}

/// The anchors of `dir/anchors.json` as detectors hand them over: one entry per frame.
fn anchors_of(
    dir: &Path,
    n_frames: usize,
    n_triangles: usize,
) -> Vec<crease_core::folds::FrameAnchors> {
    let set = crease_core::folds::AnchorSet::read(&dir.join("anchors.json"), n_frames, n_triangles)
        .unwrap();
    (0..n_frames)
        .map(|t| crease_core::folds::FrameAnchors {
            frame: t,
            anchors: set.frame(t).to_vec(),
            ..Default::default()
        })
        .collect()
}

/// A video job's anchors are the images' and the stretch detector's made one (the mean rotation where both
/// anchor a triangle, every angle times `video.fused_gain`), exactly as `crease run` finds each alone; and
/// `video.geometry_folds=false` leaves the images' alone.
#[test]
fn the_geometrys_folds_join_the_images() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    video_demo(d);
    let input = d.join("input");
    let video = |out: &Path, extra: &[&str]| {
        let mut args = vec!["run", "--input", s(&input), "--folds", "video", "--cameras"];
        let cameras = d.join("cameras.json");
        args.extend([
            s(&cameras),
            "--out",
            s(out),
            "--quiet",
            "--preview-size",
            "32",
        ]);
        args.extend(extra);
        ok(&crease(&args));
    };
    let (fused, images, geometry) = (d.join("fused"), d.join("images"), d.join("geometry"));
    video(&fused, &["--set", "video.fused_gain=0.6"]);
    video(&images, &["--set", "video.geometry_folds=false"]);
    ok(&crease(&[
        "run",
        "--input",
        s(&input),
        "--folds",
        "stretch",
        "--out",
        s(&geometry),
        "--quiet",
        "--preview-size",
        "32",
    ]));

    let report = |dir: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).unwrap()).unwrap()
    };
    let r = report(&fused);
    let g = &r["fold_detection"]["geometry"];
    let count = |k: &str| {
        g[k].as_u64()
            .unwrap_or_else(|| panic!("geometry.{k} missing: {g}")) as usize
    };
    assert!(
        count("images_anchors") > 0 && count("geometry_anchors") > 0,
        "{g}"
    );
    assert_eq!(g["fused_gain"].as_f64(), Some(0.6));
    assert!(report(&images)["fold_detection"].get("geometry").is_none());

    let n_tri = r["summary"]["triangles"].as_u64().unwrap() as usize;
    let (want, counts) = crease_core::folds::fuse::fuse(
        anchors_of(&images, 3, n_tri),
        &anchors_of(&geometry, 3, n_tri),
        0.6,
    )
    .unwrap();
    assert_eq!(counts.primary, count("images_anchors"));
    assert_eq!(counts.secondary, count("geometry_anchors"));
    assert_eq!(counts.shared, count("shared_triangles"));
    let got = anchors_of(&fused, 3, n_tri);
    for (w, g) in want.iter().zip(&got) {
        assert_eq!(w.anchors.len(), g.anchors.len(), "frame {}", w.frame);
        for (a, b) in w.anchors.iter().zip(&g.anchors) {
            assert_eq!(a.triangle, b.triangle, "frame {}", w.frame);
            let (va, vb) = (a.rotation_vector(), b.rotation_vector());
            assert!(
                (0..3).all(|k| (va[k] - vb[k]).abs() < 1e-12),
                "frame {} triangle {}: {va:?} against {vb:?}",
                w.frame,
                a.triangle
            );
        }
    }
}

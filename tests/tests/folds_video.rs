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

#[test]
fn demo_video_then_run_with_video_folds() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
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

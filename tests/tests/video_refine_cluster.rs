//! The shading refinement of video jobs runs inside the positioning tasks, reading each frame's images where
//! the frame is positioned: split over two workers on 127.0.0.1, one frame per task, the job writes the same
//! bytes as `crease run --folds video`; and the refinement does change the result (it is not a no-op that
//! byte-identity would hide).

use crease_e2e::*;
use std::path::Path;
use std::process::Command;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A small demo capture in `d`, with a synthetic three-camera video.
fn demo(d: &Path, frames: usize) {
    let o = Command::new(bin())
        .args(["demo", "--out", s(d), "--triangles", "3000"])
        .args(["--frames", &frames.to_string()])
        .args(["--with-video", "--video-cameras", "3"])
        .args(["--video-width", "240", "--video-height", "320"])
        .output()
        .unwrap();
    assert!(o.status.success(), "crease demo: {}", stderr(&o));
}

fn run_video(d: &Path, out: &Path, extra: &[&str]) {
    let o = Command::new(bin())
        .args(["run", "--input", s(&d.join("input")), "--folds", "video"])
        .args(["--cameras", s(&d.join("cameras.json"))])
        .args(["--out", s(out), "--mode", "fused", "--preview-size", "64"])
        .args(["--set", "deform.window=3", "--set", "deform.shift=2"])
        // The demo's capture is its own rest state: it lost no surface, and the lost-area bound would take back
        // everything the refinement adds.
        .args(["--set", "deform.lost_area_bound=false"])
        .args(["--threads", "2"])
        .args(extra)
        .output()
        .unwrap();
    assert!(o.status.success(), "crease run: {}", stderr(&o));
}

#[test]
fn refined_video_job_on_two_workers_matches_crease_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    demo(d, 4);

    let reference = d.join("reference");
    run_video(d, &reference, &[]);
    let unrefined = d.join("unrefined");
    run_video(d, &unrefined, &["--set", "video.refine_rounds=0"]);
    let (a, b) = (
        std::fs::read(reference.join("frame_0002.obj")).unwrap(),
        std::fs::read(unrefined.join("frame_0002.obj")).unwrap(),
    );
    assert!(a != b, "the shading refinement left frame 2 as it was");

    let c = Coordinator::start(d, &[]);
    let _w1 = c.worker("w-one", &[]);
    let _w2 = c.worker("w-two", &[]);
    let out = d.join("cluster");
    let job = d.join("job.toml");
    std::fs::write(
        &job,
        format!(
            "name = \"refined\"\ninput = \"{}\"\noutput = \"{}\"\n[folds]\nkind = \"video\"\ncameras = \"{}\"\n\
             [deform]\nmode = \"fused\"\nwindow = 3\nshift = 2\nlost_area_bound = false\n[partition]\nframes_per_chunk = 1\n\
             [preview]\nsize = 64\n",
            d.join("input").display(),
            out.display(),
            d.join("cameras.json").display(),
        ),
    )
    .unwrap();
    let id = c.submit(&job);
    let st = c.wait_state(&id, &["done", "failed"]);
    assert_eq!(st["state"], "done", "{st}");
    let positioning = tasks(&st)
        .iter()
        .filter(|t| t["kind"].as_str() == Some("position"))
        .count();
    assert_eq!(positioning, 4, "one positioning task per frame");
    assert_complete_and_identical(&reference, &out);
}

/// `crease refine` refines any sequence with calibrated images, and names what is wrong with its input.
#[test]
fn crease_refine_alone_and_its_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    demo(d, 2);
    let refine = |out: &str, extra: &[&str]| {
        Command::new(bin())
            .args(["refine", "--input", s(&d.join("input"))])
            .args(["--cameras", s(&d.join("cameras.json"))])
            .args(["--out", s(&d.join(out)), "--quiet"])
            .args(extra)
            .output()
            .unwrap()
    };
    let o = refine("refined", &[]);
    assert!(o.status.success(), "crease refine: {}", stderr(&o));
    let (a, b) = (
        std::fs::read(d.join("input/frame_0001.obj")).unwrap(),
        std::fs::read(d.join("refined/frame_0001.obj")).unwrap(),
    );
    assert!(a != b, "crease refine wrote its input back");

    let o = refine("bad", &["--smoothness=-1"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("smoothness"), "{}", stderr(&o));

    std::fs::remove_file(d.join("images/cam01/frame_0002.png")).unwrap();
    let o = refine("missing", &[]);
    let msg = stderr(&o);
    assert!(
        !o.status.success() && msg.contains("frame_0002.png"),
        "{msg}"
    );
    assert!(
        !d.join("missing/frame_0001.obj").exists(),
        "a failed refinement wrote frames"
    );
}

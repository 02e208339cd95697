//! Output hygiene: a second run into the same output removes the files only the first run wrote (frames past
//! the new sequence's end, detected anchors, fold images) and keeps files crease did not write, both for the
//! local `crease run` and for a job submitted to a coordinator and workers.

use crease_e2e::*;
use std::path::Path;
use std::process::Command;

fn crease(args: &[&str]) {
    let o = Command::new(bin()).args(args).output().unwrap();
    assert!(o.status.success(), "crease {args:?}: {}", stderr(&o));
}

fn demo(dir: &Path, name: &str, frames: &str) -> (String, String) {
    let root = dir.join(name);
    crease(&[
        "demo",
        "--out",
        root.to_str().unwrap(),
        "--triangles",
        "1000",
        "--frames",
        frames,
    ]);
    (
        root.join("input").display().to_string(),
        root.join("anchors.json").display().to_string(),
    )
}

/// What the first (6 frames, stretch folds) run leaves, and the user's own files beside it.
fn first_run_left(out: &Path) {
    for f in [
        "frame_0006.obj",
        "anchors.json",
        "folds.png",
        "folds/control_lines.obj",
    ] {
        assert!(out.join(f).exists(), "the first run wrote no {f}");
    }
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    std::fs::create_dir_all(out.join("mine")).unwrap();
    std::fs::write(out.join("mine/frame_0009.obj"), "mine").unwrap();
}

/// After the second (4 frames, anchors file) run: only its own outputs and the user's files.
fn second_run_is_clean(out: &Path) {
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["complete"], true);
    for stale in [
        "frame_0005.obj",
        "frame_0006.obj",
        "anchors.json",
        "folds.png",
        "folds/control_lines.obj",
    ] {
        assert!(
            !out.join(stale).exists(),
            "stale {stale} stayed beside the new result"
        );
    }
    for kept in [
        "frame_0004.obj",
        "preview.png",
        "notes.txt",
        "mine/frame_0009.obj",
    ] {
        assert!(out.join(kept).exists(), "{kept} is gone");
    }
    let manifest: Vec<&str> = report["manifest"]
        .as_array()
        .expect("report.json lists what the run owns")
        .iter()
        .filter_map(|v| v.as_str())
        .collect();
    assert!(manifest.contains(&"frame_0004.obj") && manifest.contains(&"report.json"));
    assert!(!manifest.contains(&"frame_0005.obj") && !manifest.contains(&"notes.txt"));
}

#[test]
fn local_run_removes_what_only_the_earlier_run_wrote() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (input6, _) = demo(d, "six", "6");
    let (input4, anchors4) = demo(d, "four", "4");
    let out = d.join("out");
    let o = out.to_str().unwrap();
    let common = ["--quiet", "--preview-size", "64", "--threads", "2"];
    let mut first = vec!["run", "--input", &input6, "--folds", "stretch", "--out", o];
    first.extend(common);
    crease(&first);
    first_run_left(&out);
    let mut second = vec![
        "run",
        "--input",
        &input4,
        "--anchors",
        &anchors4,
        "--out",
        o,
    ];
    second.extend(common);
    crease(&second);
    second_run_is_clean(&out);
}

#[test]
fn cluster_job_removes_what_only_the_earlier_job_wrote() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (input6, _) = demo(d, "six", "6");
    let (input4, anchors4) = demo(d, "four", "4");
    let out = d.join("out");
    let c = Coordinator::start(d, &[]);
    let _w = c.worker("w", &[]);
    // Submits a job into `out` and follows it to the end.
    let submit = |name: &str, input: &str, folds: &str| {
        let job = d.join(format!("{name}.toml"));
        let text = format!(
            "input = \"{input}\"\noutput = \"{}\"\n[folds]\n{folds}\n[preview]\nsize = 64\n",
            out.display()
        );
        std::fs::write(&job, text).unwrap();
        let o = c.cli(&["submit", job.to_str().unwrap(), "--watch"]);
        assert!(o.status.success(), "{name}: {}", stderr(&o));
    };
    submit("first", &input6, "kind = \"stretch\"");
    first_run_left(&out);
    submit(
        "second",
        &input4,
        &format!("kind = \"anchors\"\nuri = \"{anchors4}\""),
    );
    second_run_is_clean(&out);
}

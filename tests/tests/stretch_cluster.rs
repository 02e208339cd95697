//! Stretch fold detection split across a real coordinator and two workers on 127.0.0.1 (step chunks, the
//! phase task, one-frame tracing chunks without warm-up, one-frame settle ranges, the reconciling merge) writes
//! the same bytes as `crease run --folds stretch` with its default chunking; the positioning tasks, one frame each,
//! also let the shape screen go where the capture kept no trace of what it lost (`deform.release_share`), as the
//! single run does.

use crease_e2e::*;
use std::collections::BTreeMap;
use std::process::Command;

#[test]
fn split_stretch_detection_on_two_workers_matches_crease_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let input = fixture();
    let reference = d.join("reference");
    let o = Command::new(bin())
        .args([
            "run",
            "--input",
            input.to_str().unwrap(),
            "--folds",
            "stretch",
        ])
        .args(["--out", reference.to_str().unwrap(), "--mode", "fused"])
        .args(["--set", "deform.window=3", "--set", "deform.shift=2"])
        .args(["--set", "deform.release_share=0.1"])
        .args(["--preview-size", "64"])
        .args(["--threads", "2"])
        .output()
        .unwrap();
    assert!(o.status.success(), "crease run: {}", stderr(&o));

    let c = Coordinator::start(d, &[]);
    let _w1 = c.worker("w-one", &[]);
    let _w2 = c.worker("w-two", &[]);
    let out = d.join("cluster");
    let job = d.join("job.toml");
    std::fs::write(
        &job,
        format!(
            "name = \"split\"\ninput = \"{}\"\noutput = \"{}\"\n[folds]\nkind = \"stretch\"\n\
             [deform]\nmode = \"fused\"\nwindow = 3\nshift = 2\nrelease_share = 0.1\n[partition]\nframes_per_chunk = 1\n\
             stretch_frames_per_chunk = 1\nstretch_warm_up = 0\n[preview]\nsize = 64\n",
            input.display(),
            out.display()
        ),
    )
    .unwrap();
    let id = c.submit(&job);
    let s = c.wait_state(&id, &["done", "failed"]);
    assert_eq!(s["state"], "done", "{s}");
    let mut kinds: BTreeMap<String, usize> = BTreeMap::new();
    for t in tasks(&s) {
        *kinds
            .entry(t["kind"].as_str().unwrap_or("").to_string())
            .or_default() += 1;
    }
    assert_eq!(
        kinds.get("fold-steps"),
        Some(&2),
        "step chunks of at most half the sequence: {kinds:?}"
    );
    assert_eq!(kinds.get("fold-files"), Some(&1), "{kinds:?}");
    assert_eq!(kinds.get("fold-plot"), Some(&1), "{kinds:?}");
    assert_eq!(kinds.get("fold-phases"), Some(&1), "{kinds:?}");
    assert_eq!(
        kinds.get("fold-detect"),
        Some(&4),
        "one tracing task per frame: {kinds:?}"
    );
    assert_eq!(
        kinds.get("fold-settle"),
        Some(&4),
        "one temporal-coherence task per frame: {kinds:?}"
    );
    assert_complete_and_identical(&reference, &out);
    for f in ["anchors.json", "folds.png", "folds/control_lines.obj"] {
        let (a, b) = (
            std::fs::read(reference.join(f)).unwrap(),
            std::fs::read(out.join(f)).unwrap(),
        );
        assert!(a == b, "{f} differs from crease run's");
    }
    let anchors = std::fs::read_to_string(out.join("anchors.json")).unwrap();
    assert!(
        anchors.matches("\"triangle\"").count() > 10,
        "the sleeve has detected folds"
    );
}

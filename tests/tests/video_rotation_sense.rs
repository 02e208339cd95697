//! End to end, the sense of the video anchors' rotations: on the synthetic capture `crease demo --with-video`
//! writes (images rendered from the ground truth `gt/`, input = the fold-free sequence), the anchors
//! `crease run --folds video` detects must turn the surface toward the ground truth, not away from it: near the
//! anchors, the output's normals are closer to the ground truth's than the input's are.

use crease_core::folds::AnchorSet;
use crease_core::mesh::geometry::triangle_normals;
use crease_core::mesh::io::open_sequence;
use std::process::Command;

fn crease(args: &[&str]) {
    let o = Command::new(crease_e2e::bin()).args(args).output().unwrap();
    assert!(
        o.status.success(),
        "crease {args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

fn angle(a: [f64; 3], b: [f64; 3]) -> f64 {
    let dot = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]).clamp(-1.0, 1.0);
    dot.acos().to_degrees()
}

#[test]
fn video_anchors_turn_the_surface_toward_the_ground_truth() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let demo = d.join("demo");
    let out = d.join("out");
    let s = |p: &std::path::Path| p.to_str().unwrap().to_string();
    crease(&[
        "demo",
        "--out",
        &s(&demo),
        "--triangles",
        "8000",
        "--frames",
        "4",
        "--with-video",
        "--video-cameras",
        "4",
        "--video-width",
        "360",
        "--video-height",
        "480",
    ]);
    // The demo's folds are wider in pixels than the sleeve-tuned default pair distances.
    crease(&[
        "run",
        "--input",
        &s(&demo.join("input")),
        "--folds",
        "video",
        "--cameras",
        &s(&demo.join("cameras.json")),
        "--out",
        &s(&out),
        "--set",
        "video.max_distance=24",
        "--set",
        "video.max_avg_distance=18",
        // The demo's capture is its garment before the folds were put in, not after a capture lost them: it
        // shows no lost surface, and the bound would give it back unchanged.
        "--set",
        "deform.lost_area_bound=false",
        // The sense of the images' anchors is under test, not the geometry's (the demo's capture lost no length
        // for the stretch detector to read).
        "--set",
        "video.geometry_folds=false",
        "--quiet",
        "--preview-size",
        "64",
    ]);
    let input = open_sequence(&demo.join("input")).unwrap().source;
    let gt = open_sequence(&demo.join("gt")).unwrap().source;
    let output = open_sequence(&out).unwrap().source;
    let topo = input.topology().clone();
    let n = input.n_frames();
    let anchors = AnchorSet::read(&out.join("anchors.json"), n, topo.n_triangles()).unwrap();
    let (mut before, mut after, mut count) = (0.0, 0.0, 0usize);
    for t in 0..n {
        let ni = triangle_normals(&topo, &input.read_frame(t).unwrap());
        let ng = triangle_normals(&topo, &gt.read_frame(t).unwrap());
        let no = triangle_normals(&topo, &output.read_frame(t).unwrap());
        for a in anchors.frame(t) {
            let k = a.triangle as usize;
            before += angle(ni[k], ng[k]);
            after += angle(no[k], ng[k]);
            count += 1;
        }
    }
    assert!(count >= 50, "only {count} anchors detected");
    let (before, after) = (before / count as f64, after / count as f64);
    eprintln!("at {count} anchors: normal error vs ground truth {before:.2}° (input) -> {after:.2}° (output)");
    assert!(
        after < before,
        "the video anchors turned the surface away from the ground truth: {before:.2}° -> {after:.2}°"
    );
}

//! Jobs that detect their folds (`stretch`, `video`) write the same bytes however they are cut into tasks and
//! in whatever valid order the tasks run (with duplicates), and their anchors are what the detector finds on
//! the whole sequence at once, i.e. what the former direct path of `crease run` computed.

mod common;

use common::*;
use crease_core::folds::stretch::StretchDetector;
use crease_core::folds::{AnchorSet, FoldDetector};
use crease_core::mesh::io::open_sequence;
use crease_core::progress::NoProgress;
use crease_jobs::JobSpec;
use std::collections::BTreeMap;
use std::path::Path;

/// Every file under `dir`, recursively (relative path → bytes), except hidden entries and `report.json`
/// (it holds timings).
fn tree(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    fn walk(root: &Path, dir: &Path, out: &mut BTreeMap<String, Vec<u8>>) {
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            if name.starts_with('.') || name == "report.json" {
                continue;
            }
            if p.is_dir() {
                walk(root, &p, out);
            } else {
                let rel = p.strip_prefix(root).unwrap().to_string_lossy().into_owned();
                out.insert(rel, std::fs::read(&p).unwrap());
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(dir, dir, &mut out);
    out
}

fn spec(input: &Path, out: &Path, folds: &str, partition: &str) -> JobSpec {
    let text = format!(
        "input = {:?}\noutput = {:?}\n[folds]\n{folds}\n[partition]\n{partition}\n[preview]\nsize = 64\n",
        input.display().to_string(),
        out.display().to_string()
    );
    JobSpec::from_toml_str(&text).unwrap_or_else(|e| panic!("{e}\n{text}"))
}

async fn run_ok(spec: &JobSpec, cache: &Path, order: Order) -> BTreeMap<String, Vec<u8>> {
    let run = run_job(spec, cache, order).await;
    for (k, r) in &run.outcomes {
        assert!(r.is_ok(), "task {k} failed: {:?}", r.as_ref().err());
    }
    assert_eq!(
        run.outcomes.len(),
        run.tasks.len(),
        "every planned task ran"
    );
    let out = Path::new(&spec.output);
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["complete"], true);
    tree(out)
}

fn assert_same(a: &BTreeMap<String, Vec<u8>>, b: &BTreeMap<String, Vec<u8>>, what: &str) {
    assert_eq!(
        a.keys().collect::<Vec<_>>(),
        b.keys().collect::<Vec<_>>(),
        "{what}: same files"
    );
    for (k, v) in a {
        assert!(b[k] == *v, "{what}: {k} differs");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn stretch_folds_are_partition_and_order_independent() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    let (input, _) = fixture(root, 900, 8);
    let folds = "kind = \"stretch\"";
    let a = spec(&input, &root.join("a"), folds, "frames_per_chunk = 8");
    let b = spec(&input, &root.join("b"), folds, "frames_per_chunk = 3");
    let ta = run_ok(&a, &root.join("cache-a"), PLAN_ORDER).await;
    let tb = run_ok(&b, &root.join("cache-b"), Order { seed: 7, rerun: 3 }).await;
    for f in [
        "anchors.json",
        "folds/control_lines.obj",
        "folds.png",
        "frame_0004.obj",
    ] {
        assert!(ta.contains_key(f), "{f} missing");
    }
    assert_same(&ta, &tb, "stretch, 1 vs 3 frames per chunk");
    // The anchors are the detector's on the whole sequence, as the direct path wrote them.
    let opened = open_sequence(&input).unwrap();
    let source = opened.source.as_ref();
    let direct = StretchDetector::default()
        .detect(source, 0..8, &NoProgress)
        .unwrap();
    let direct =
        AnchorSet::from_frame_anchors(direct, source.topology().n_triangles(), None).unwrap();
    let (got, want) = (&ta["anchors.json"], direct.to_json().into_bytes());
    if let Some(i) = (0..got.len().min(want.len())).find(|&i| got[i] != want[i]) {
        let ctx = |b: &[u8]| {
            String::from_utf8_lossy(&b[i.saturating_sub(80)..(i + 80).min(b.len())]).into_owned()
        };
        panic!(
            "anchors.json differs from the direct detection at byte {i}:\n{}\nvs\n{}",
            ctx(got),
            ctx(&want)
        );
    }
    assert_eq!(got.len(), want.len(), "anchors.json length");

    // Subdivided: plain OBJ frames with 4× the triangles, equally independent of the partition.
    let folds = "kind = \"stretch\"\nsubdivide = 1";
    let c = spec(&input, &root.join("c"), folds, "frames_per_chunk = 8");
    let d = spec(&input, &root.join("d"), folds, "frames_per_chunk = 2");
    let info = crease_jobs::inspect_input(&c).await.unwrap();
    assert_eq!(info.n_triangles, 4 * source.topology().n_triangles());
    let tc = run_ok(&c, &root.join("cache-c"), PLAN_ORDER).await;
    let td = run_ok(&d, &root.join("cache-d"), Order { seed: 3, rerun: 4 }).await;
    assert_same(&tc, &td, "subdivided stretch");
    let text = String::from_utf8_lossy(&tc["frame_0001.obj"]).into_owned();
    let faces = text.lines().filter(|l| l.starts_with("f ")).count();
    assert_eq!(faces, info.n_triangles);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn video_folds_are_partition_and_order_independent() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    // Large enough that the rendered folds are resolved as paired edges after the lighting residual (as in
    // core/tests/folds_video.rs): at 900 triangles and 240x320 the folds are a few pixels of shading.
    let (input, anchors) = fixture(root, 12_000, 6);
    // The capture video of the ground truth (the input deformed with its anchors), as `crease demo
    // --with-video` renders it.
    let gt = root.join("gt");
    // Made without the shape screen: the truth is the anchors' full effect (as `crease demo --with-video`).
    let truth = crease_core::spacetime::DeformParams {
        shape_cutoff: 0.0,
        // Nor crease's fold relief (it reads the captured surface).
        relief: crease_core::spacetime::shape::relief::ReliefParams {
            steps: 0,
            ..Default::default()
        },
        ..Default::default()
    };
    reference(&input, Some(&anchors), &truth, &gt);
    let gt = open_sequence(&gt).unwrap();
    let frames: Vec<_> = (0..6).map(|t| gt.source.read_frame(t).unwrap()).collect();
    let opened = open_sequence(&input).unwrap();
    let source = opened.source.as_ref();
    crease_core::synth_video::write_video(root, source.topology(), &frames, 3, 360, 480, 1)
        .unwrap();
    // The demo's folds are wider than the sleeve-tuned default pair distances (as in core/tests/folds_video.rs).
    let folds = format!(
        "kind = \"video\"\ncameras = {:?}\noverlay_frames = [1, 4]\n[folds.params]\nmax_distance = 24.0\nmax_avg_distance = 18.0",
        root.join("cameras.json").display().to_string()
    );
    let a = spec(&input, &root.join("a"), &folds, "fold_frames_per_chunk = 6");
    let b = spec(
        &input,
        &root.join("b"),
        &folds,
        "fold_frames_per_chunk = 1\nframes_per_chunk = 2",
    );
    let ta = run_ok(&a, &root.join("cache-a"), PLAN_ORDER).await;
    let tb = run_ok(&b, &root.join("cache-b"), Order { seed: 11, rerun: 3 }).await;
    for f in [
        "anchors.json",
        "overlays/frame_0001.png",
        "overlays/frame_0004.png",
    ] {
        assert!(ta.contains_key(f), "{f} missing");
    }
    assert_same(&ta, &tb, "video, 6 vs 1 frames per detection chunk");
    // The temporal settle in one range (the whole-sequence settle), and in two uneven ones across the
    // detection chunks (a: 2 ranges of 3 frames, b: 6 of 1).
    for (name, partition, settles) in [
        (
            "c",
            "fold_frames_per_chunk = 4\nsettle_frames_per_chunk = 6",
            1,
        ),
        (
            "d",
            "fold_frames_per_chunk = 2\nsettle_frames_per_chunk = 4",
            2,
        ),
    ] {
        let s = spec(&input, &root.join(name), &folds, partition);
        let planned =
            crease_jobs::plan(&s, &crease_jobs::inspect_input(&s).await.unwrap()).unwrap();
        let n_settle = planned
            .iter()
            .filter(|t| matches!(t.spec, crease_jobs::TaskSpec::FoldSettle { .. }))
            .count();
        assert_eq!(n_settle, settles, "{partition}");
        let t = run_ok(
            &s,
            &root.join(format!("cache-{name}")),
            Order { seed: 5, rerun: 2 },
        )
        .await;
        assert_same(&ta, &t, &format!("video, {partition}"));
    }
    let set = AnchorSet::parse(
        &String::from_utf8_lossy(&ta["anchors.json"]),
        None,
        6,
        source.topology().n_triangles(),
    )
    .unwrap();
    assert!(set.total() > 0, "the rendered folds give anchors");

    // A missing image fails the submit, naming the camera, the frame and the file.
    std::fs::remove_file(root.join("images/cam01/frame_0003.png")).unwrap();
    let e = crease_jobs::inspect_input(&a)
        .await
        .unwrap_err()
        .to_string();
    assert!(e.contains("frame_0003.png") && e.contains("frame 2"), "{e}");
}

#[test]
fn detector_specs_are_validated_naming_the_field() {
    let cases = [
        ("kind = \"stretch\"\nsubdivide = 5", "folds.subdivide"),
        (
            "kind = \"stretch\"\n[folds.params]\ntheta0_deg = 95.0",
            "folds.params.theta0_deg",
        ),
        (
            "kind = \"stretch\"\n[folds.params]\nfold_width = -1.0",
            "folds.params.fold_width",
        ),
        (
            "kind = \"video\"\ncameras = \"/c.json\"\nfront_vertex = 3",
            "folds.front_vertex",
        ),
        (
            "kind = \"video\"\ncameras = \"/c.json\"\n[folds.params]\nbogus = 1",
            "bogus",
        ),
    ];
    for (folds, want) in cases {
        let text = format!("input = \"/in\"\noutput = \"/out\"\n[folds]\n{folds}\n");
        let e = JobSpec::from_toml_str(&text).unwrap_err().to_string();
        assert!(e.contains(want), "{folds}: {e}");
    }
    let ok = "input = \"/in\"\noutput = \"/out\"\n[folds]\nkind = \"stretch\"\n[folds.params]\nmin_shrink = 0.03\n";
    assert!(JobSpec::from_toml_str(ok).is_ok());
}

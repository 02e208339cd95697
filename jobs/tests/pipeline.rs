//! Executing a job's plan task by task in one process gives exactly what `crease_core::spacetime::deform`
//! writes through the same sink: in any valid order, with tasks executed twice, with other partition sizes,
//! in both weight modes and in the point-cache layout.

mod common;

use common::*;
use crease_core::mesh::io::{open_sequence, write_obj, write_pc2};
use crease_core::mesh::Sequence;
use crease_jobs::storage::keys;
use crease_jobs::{final_outputs, Storage, TaskSpec};
use serde_json::Value;
use std::path::Path;

/// Runs `spec` in process with `order` and checks its outputs against the reference run.
async fn assert_matches_reference(
    input: &Path,
    anchors: Option<&Path>,
    root: &Path,
    name: &str,
    extra: &str,
    order: Order,
) -> Run {
    let out = root.join(name);
    let spec = job(input, anchors, &out, extra);
    let run = run_job(&spec, &root.join("cache"), order).await;
    for (k, r) in &run.outcomes {
        assert!(r.is_ok(), "{name}: task {k} failed: {:?}", r.as_ref().err());
    }
    assert_eq!(
        run.outcomes.len(),
        run.tasks.len(),
        "{name}: every planned task ran"
    );
    let ref_dir = root.join(format!("{name}-reference"));
    let report = reference(input, anchors, &spec.params(), &ref_dir);
    let got = files(&out, &["report.json", "preview.png", "stretch.png"]);
    let want = files(&ref_dir, &[]);
    assert_eq!(
        got.keys().collect::<Vec<_>>(),
        want.keys().collect::<Vec<_>>(),
        "{name}: same output files"
    );
    for (f, bytes) in &want {
        assert!(got[f] == *bytes, "{name}: {f} differs from the reference");
    }
    // The report carries the reference's figures exactly. (Both sides go through the same text → Value parse,
    // so equal values mean equal shortest-round-trip texts, i.e. equal f64 bits.)
    let doc: Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(doc["complete"], Value::Bool(true));
    let want_report: Value =
        serde_json::from_str(&serde_json::to_string(&report).unwrap()).unwrap();
    for field in [
        "stretch",
        "frame_stretch",
        "frame_lost_share",
        "anchors",
        "frames",
        "params",
    ] {
        assert_eq!(
            doc["report"][field], want_report[field],
            "{name}: report.{field}"
        );
    }
    for (w, r) in doc["report"]["windows"]
        .as_array()
        .unwrap()
        .iter()
        .zip(want_report["windows"].as_array().unwrap())
    {
        for field in [
            "start",
            "len",
            "anchors",
            "blocks",
            "cg_iterations",
            "node_updates",
            "max_relative_residual",
        ] {
            assert_eq!(w[field], r[field], "{name}: window {field}");
        }
    }
    // Everything the coordinator checks before marking the job done exists.
    let storage = Storage::open(&spec.output).unwrap();
    for key in final_outputs(&spec, &run.info) {
        assert!(storage.exists(&key).await.unwrap(), "{name}: {key} missing");
    }
    run
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn per_anchor_plan_in_any_valid_order_matches_deform() {
    let root = tempfile::tempdir().unwrap();
    let (input, anchors) = fixture(root.path(), 1500, 16);
    let deform = "[deform]\nmode = \"per-anchor\"\nwindow = 6\nshift = 4\n";
    let run = assert_matches_reference(
        &input,
        Some(&anchors),
        root.path(),
        "plan-order",
        &format!("{deform}[partition]\nanchor_block = 12\n"),
        PLAN_ORDER,
    )
    .await;
    let blocks = run
        .tasks
        .iter()
        .filter(|t| matches!(t.spec, TaskSpec::WeightBlock { .. }))
        .count();
    let windows = run
        .tasks
        .iter()
        .filter(|t| matches!(t.spec, TaskSpec::Reduce { .. }))
        .count();
    assert_eq!(windows, 4, "16 frames in windows of 6 shifted by 4");
    assert!(
        blocks >= 3 * windows,
        "many blocks per window, got {blocks}"
    );
    // Random valid orders, with every third task executed a second time, and other chunk sizes.
    let run = assert_matches_reference(
        &input,
        Some(&anchors),
        root.path(),
        "shuffled",
        &format!("{deform}[partition]\nanchor_block = 12\nframes_per_chunk = 3\n"),
        Order { seed: 7, rerun: 3 },
    )
    .await;
    assert!(run.executed.len() > run.tasks.len(), "some tasks ran twice");
    assert_matches_reference(
        &input,
        Some(&anchors),
        root.path(),
        "big-blocks",
        &format!("{deform}[partition]\nanchor_block = 40\nframes_per_chunk = 16\n"),
        Order { seed: 99, rerun: 2 },
    )
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn fused_plan_matches_deform_and_no_folds_returns_the_input() {
    let root = tempfile::tempdir().unwrap();
    let (input, anchors) = fixture(root.path(), 1200, 12);
    let run = assert_matches_reference(
        &input,
        Some(&anchors),
        root.path(),
        "fused",
        "[partition]\nframes_per_chunk = 1\n",
        Order { seed: 3, rerun: 4 },
    )
    .await;
    assert!(run.tasks.iter().all(|t| !matches!(
        t.spec,
        TaskSpec::WeightBlock { .. } | TaskSpec::Reduce { .. }
    )));
    // No folds: the output positions are the input's.
    assert_matches_reference(&input, None, root.path(), "none", "", PLAN_ORDER).await;
    let a = open_sequence(&input).unwrap();
    let b = open_sequence(&root.path().join("none")).unwrap();
    for t in 0..12 {
        assert_eq!(
            a.source.read_frame(t).unwrap(),
            b.source.read_frame(t).unwrap()
        );
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn point_cache_layout_matches_deform() {
    let root = tempfile::tempdir().unwrap();
    let (frames_dir, anchors) = fixture(root.path(), 1000, 9);
    let seq = Sequence::load(open_sequence(&frames_dir).unwrap().source.as_ref()).unwrap();
    let input = root.path().join("cache-input");
    std::fs::create_dir_all(&input).unwrap();
    write_obj(&input.join("cloth.obj"), &seq.topology, &seq.frames[0]).unwrap();
    write_pc2(&input.join("cloth.pc2"), &seq.frames, 1.0, 1.0).unwrap();
    assert_matches_reference(
        &input,
        Some(&anchors),
        root.path(),
        "pc2",
        "[deform]\nmode = \"per-anchor\"\n[partition]\nanchor_block = 50\nframes_per_chunk = 2\n",
        Order { seed: 11, rerun: 3 },
    )
    .await;
    assert!(root.path().join("pc2/cloth.pc2").is_file());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_rerun_writes_the_same_bytes_and_report_is_written_last() {
    let root = tempfile::tempdir().unwrap();
    let (input, anchors) = fixture(root.path(), 800, 8);
    let out = root.path().join("out");
    let spec = job(
        &input,
        Some(&anchors),
        &out,
        "[deform]\nmode = \"per-anchor\"\n[partition]\nanchor_block = 30\n",
    );
    let cache = root.path().join("cache");
    run_job(&spec, &cache, PLAN_ORDER).await;
    let snapshot = |d: &Path| {
        let mut all = files(d, &["report.json"]);
        for (k, v) in files(&d.join(keys::WORK_DIR).join("positions"), &[]) {
            if k.ends_with(".npy") {
                all.insert(format!("positions/{k}"), v);
            }
        }
        all
    };
    let first = snapshot(&out);
    // A finalize that is cancelled half-way removes the old report and never writes a new one.
    let cancelling = crease_jobs::ExecContext {
        progress: std::sync::Arc::new(CancelAfter {
            after: 3,
            seen: Default::default(),
        }),
        cache_dir: cache.clone(),
    };
    let err = crease_jobs::execute(&TaskSpec::Finalize { job: spec.clone() }, &cancelling)
        .await
        .unwrap_err();
    assert!(err.is_cancelled() && err.retryable(), "{err:?}");
    assert!(
        !out.join("report.json").exists(),
        "no report vouches for a half-written output"
    );
    // Running everything again rewrites identical bytes.
    run_job(&spec, &cache, Order { seed: 5, rerun: 0 }).await;
    assert_eq!(first, snapshot(&out));
    assert!(out.join("report.json").is_file());
}

//! Stretch fold detection split into tasks (step chunks → phases → tracing chunks → settle ranges → merge)
//! writes the single detector's anchors and `folds.png` byte for byte, for any chunking, warm-up and settle
//! split and any valid task order with duplicates; the whole output (and report.json's per-frame detection
//! lines) is then the same for every partition.

mod common;

use common::*;
use crease_core::folds::stretch::StretchDetector;
use crease_core::folds::{AnchorSet, FoldDetector};
use crease_core::mesh::io::open_sequence;
use crease_core::progress::NoProgress;
use crease_jobs::{JobSpec, TaskSpec};
use std::collections::BTreeMap;
use std::path::Path;

fn spec(input: &Path, out: &Path, partition: &str) -> JobSpec {
    spec_with(input, out, partition, false)
}

fn spec_with(input: &Path, out: &Path, partition: &str, seed_memory: bool) -> JobSpec {
    let text = format!(
        "input = {:?}\noutput = {:?}\n[folds]\nkind = \"stretch\"\n[folds.params]\nseed_memory = {seed_memory}\n\
         [deform]\nwindow = 4\nshift = 3\n\
         [partition]\nframes_per_chunk = 5\n{partition}\n[preview]\nsize = 64\n",
        input.display().to_string(),
        out.display().to_string()
    );
    JobSpec::from_toml_str(&text).unwrap_or_else(|e| panic!("{e}\n{text}"))
}

/// Every file of the output except intermediates and report.json (timings), recursively.
fn tree(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut out = files(dir, &["report.json"]);
    for (k, v) in files(&dir.join("folds"), &[]) {
        out.insert(format!("folds/{k}"), v);
    }
    out
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn split_stretch_detection_is_the_single_detector_for_any_chunking() {
    split_is_single(false).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn with_the_seed_memory_the_merge_traces_again_and_is_still_exact() {
    split_is_single(true).await;
}

async fn split_is_single(seed_memory: bool) {
    let spec =
        |input: &Path, out: &Path, partition: &str| spec_with(input, out, partition, seed_memory);
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    let (input, _) = fixture(root, 900, 11);
    // The single-task detector on the whole sequence.
    let opened = open_sequence(&input).unwrap();
    let source = opened.source.as_ref();
    let probe = spec(&input, &root.join("probe"), "");
    let det: StretchDetector = crease_jobs::plan::detect::stretch_detector(&probe, 11).unwrap();
    let (direct, artifacts) = det
        .detect_with_artifacts(source, 0..11, &NoProgress)
        .unwrap();
    let direct = AnchorSet::from_frame_anchors(direct, source.topology().n_triangles(), None)
        .unwrap()
        .to_json();
    assert!(direct.matches("\"triangle\"").count() > 20, "folds found");
    let png = &artifacts[0].bytes;

    let mut reference: Option<BTreeMap<String, Vec<u8>>> = None;
    let mut reference_lines: Option<Vec<serde_json::Value>> = None;
    let mut retraced_total = 0;
    for (i, (partition, order)) in [
        ("", PLAN_ORDER),
        (
            "stretch_frames_per_chunk = 1\nstretch_warm_up = 0",
            Order { seed: 5, rerun: 3 },
        ),
        (
            "stretch_frames_per_chunk = 3\nstretch_warm_up = 1",
            Order { seed: 11, rerun: 0 },
        ),
        (
            "stretch_frames_per_chunk = 2\nstretch_warm_up = 6",
            Order { seed: 2, rerun: 4 },
        ),
        ("stretch_frames_per_chunk = 11", PLAN_ORDER),
        // The temporal settle in 1, 2 (uneven), 3 (uneven) and 11 ranges, cut across the tracing chunks.
        (
            "stretch_frames_per_chunk = 4\nsettle_frames_per_chunk = 11",
            Order { seed: 7, rerun: 2 },
        ),
        (
            "stretch_frames_per_chunk = 3\nstretch_warm_up = 0\nsettle_frames_per_chunk = 6",
            Order { seed: 3, rerun: 5 },
        ),
        (
            "stretch_frames_per_chunk = 5\nsettle_frames_per_chunk = 4",
            PLAN_ORDER,
        ),
        (
            "stretch_frames_per_chunk = 2\nstretch_warm_up = 0\nsettle_frames_per_chunk = 1",
            Order { seed: 9, rerun: 6 },
        ),
    ]
    .into_iter()
    .enumerate()
    {
        let s = spec(&input, &root.join(format!("out{i}")), partition);
        let run = run_job(&s, &root.join(format!("cache{i}")), order).await;
        for (k, r) in &run.outcomes {
            assert!(
                r.is_ok(),
                "{partition}: task {k} failed: {:?}",
                r.as_ref().err()
            );
        }
        let count = |f: fn(&TaskSpec) -> bool| run.tasks.iter().filter(|t| f(&t.spec)).count();
        let traces = count(|t| matches!(t, TaskSpec::FoldDetect { .. }));
        assert_eq!(count(|t| matches!(t, TaskSpec::FoldPhases { .. })), 1);
        assert!(count(|t| matches!(t, TaskSpec::FoldSteps { .. })) >= 1);
        let expected = crease_jobs::plan::chunks::trace_chunks(&s, 11, 900).len();
        assert_eq!(traces, expected, "{partition}: tracing tasks");
        // The settle runs in its own tasks, one per range; the merge waits for them all.
        let settles = crease_jobs::plan::settle::job_settle_chunks(&s, 11, 900);
        assert_eq!(
            count(|t| matches!(t, TaskSpec::FoldSettle { .. })),
            settles.len(),
            "{partition}: settle tasks"
        );
        if let Some(k) = partition
            .split("settle_frames_per_chunk = ")
            .nth(1)
            .and_then(|k| k.parse::<usize>().ok())
        {
            assert_eq!(settles.len(), 11usize.div_ceil(k), "{partition}");
        }
        let merge = run
            .tasks
            .iter()
            .find(|t| matches!(t.spec, TaskSpec::FoldMerge { .. }))
            .unwrap();
        for r in &settles {
            let key = crease_jobs::storage::keys::fold_settle_task(r.start);
            assert!(
                merge.deps.contains(&key),
                "{partition}: merge waits for {key}"
            );
        }
        // The user-facing anchor files are written off the chain: after the merge, and only finalize waits.
        assert_eq!(count(|t| matches!(t, TaskSpec::FoldFiles { .. })), 1);
        for t in &run.tasks {
            let waits = t
                .deps
                .iter()
                .any(|d| d == crease_jobs::storage::keys::FOLD_FILES_TASK);
            let is_finalize = matches!(t.spec, TaskSpec::Finalize { .. });
            assert_eq!(waits, is_finalize, "{partition}: {} and fold-files", t.key);
            if matches!(t.spec, TaskSpec::FoldFiles { .. }) {
                assert_eq!(t.deps, [crease_jobs::storage::keys::FOLD_MERGE_TASK]);
            }
        }
        // `folds.png` is drawn by its own task from the tracing chunks alone (not the settled anchors, not
        // the merge), and only finalize waits for it; the random task orders above run it before, between and
        // after the settle ranges and the merge, and it is still the single detector's (checked below).
        assert_eq!(count(|t| matches!(t, TaskSpec::FoldPlot { .. })), 1);
        let tracing: Vec<&str> = run
            .tasks
            .iter()
            .filter(|t| matches!(t.spec, TaskSpec::FoldDetect { .. }))
            .map(|t| t.key.as_str())
            .collect();
        for t in &run.tasks {
            let waits = t
                .deps
                .iter()
                .any(|d| d == crease_jobs::storage::keys::FOLD_PLOT_TASK);
            let is_finalize = matches!(t.spec, TaskSpec::Finalize { .. });
            assert_eq!(waits, is_finalize, "{partition}: {} and fold-plot", t.key);
            if matches!(t.spec, TaskSpec::FoldPlot { .. }) {
                assert_eq!(
                    t.deps, tracing,
                    "{partition}: fold-plot waits for tracing only"
                );
            }
        }
        let out = root.join(format!("out{i}"));
        let t = tree(&out);
        assert!(
            t["anchors.json"] == direct.as_bytes(),
            "{partition}: anchors.json is not the single detector's"
        );
        assert!(t["folds.png"] == *png, "{partition}: folds.png differs");
        let report: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
        assert_eq!(report["complete"], true);
        // The per-frame detection lines (settled anchors, control lines, folds) are the same for every
        // partition; only the tracing seconds differ.
        let lines: Vec<serde_json::Value> = report["fold_detection"]["per_frame"]
            .as_array()
            .unwrap_or_else(|| panic!("no per_frame in {}", report["fold_detection"]))
            .iter()
            .map(|l| {
                let mut l = l.clone();
                l.as_object_mut().unwrap().remove("detection_seconds");
                l
            })
            .collect();
        assert_eq!(lines.len(), 11);
        match &reference_lines {
            None => reference_lines = Some(lines),
            Some(r) => assert_eq!(*r, lines, "{partition}: report lines differ"),
        }
        retraced_total += report["fold_detection"]["retraced_frames"]
            .as_u64()
            .unwrap_or_else(|| panic!("no retraced_frames in {}", report["fold_detection"]));
        match &reference {
            None => reference = Some(t),
            Some(r) => {
                assert_eq!(r.keys().collect::<Vec<_>>(), t.keys().collect::<Vec<_>>());
                for (k, v) in r {
                    assert!(t[k] == *v, "{partition}: {k} differs from the first run's");
                }
            }
        }
    }
    if seed_memory {
        // Chunks cut through folds with no warm-up: the merge had frames to trace again.
        assert!(retraced_total > 0, "the merge never reconciled a chunk");
    } else {
        // Without the seed memory every tracing chunk is exact: the merge only gathers.
        assert_eq!(
            retraced_total, 0,
            "the merge traced again without a seed memory"
        );
    }
}

#[test]
fn chunk_size_follows_the_mesh_and_the_sequence() {
    let s = |p: &str| spec(Path::new("/in"), Path::new("/out"), p);
    let auto = s("");
    use crease_jobs::plan::chunks::trace_frames_per_chunk as k;
    assert_eq!(k(&auto, 1000, 100_000), 20);
    assert_eq!(k(&auto, 1000, 10_000), 64);
    assert_eq!(k(&auto, 1000, 2_000_000), 4);
    assert_eq!(k(&auto, 6, 1000), 3, "two chunks for a short sequence");
    assert_eq!(k(&auto, 1, 1000), 1);
    assert_eq!(k(&s("stretch_frames_per_chunk = 7"), 1000, 100_000), 7);
}

//! The worker's window cache (`crease_jobs::window_cache`): the weight-block tasks of a window after the first
//! are served from it, outputs stay those of the single-machine run, and a job resubmitted with the very same
//! spec after its anchors file or its input changed in place never gets a stale window. One test function:
//! the cache is per process, so its counters are only predictable when nothing else runs in this binary.

mod common;

use common::*;
use crease_core::synth::{self, DemoSpec};
use crease_jobs::window_cache;
use std::path::Path;

/// Columns of each weight-block task of the last [`run_and_check`], in the order it returns the tasks.
static COLUMNS: std::sync::Mutex<Vec<u64>> = std::sync::Mutex::new(Vec::new());

const DEFORM: &str =
    "[deform]\nmode = \"per-anchor\"\nwindow = 6\nshift = 4\n[partition]\nanchor_block = 40\n";

/// Runs `spec` and returns, in execution order, (task key, "hit"/"miss") of its weight-block tasks; also
/// checks that every task succeeded and that the output equals the single-machine run of the same inputs.
async fn run_and_check(
    input: &Path,
    anchors: &Path,
    root: &Path,
    out: &Path,
    what: &str,
) -> Vec<(String, String)> {
    let spec = job(input, Some(anchors), out, DEFORM);
    COLUMNS.lock().unwrap().clear();
    let run = run_job(&spec, &root.join("cache"), PLAN_ORDER).await;
    for (k, r) in &run.outcomes {
        assert!(r.is_ok(), "{what}: task {k} failed: {:?}", r.as_ref().err());
    }
    let ref_dir = root.join(format!("reference-{what}"));
    reference(input, Some(anchors), &spec.params(), &ref_dir);
    let got = files(out, &["report.json", "preview.png", "stretch.png"]);
    let want = files(&ref_dir, &[]);
    assert_eq!(
        got.keys().collect::<Vec<_>>(),
        want.keys().collect::<Vec<_>>(),
        "{what}: same output files"
    );
    for (f, bytes) in &want {
        assert!(got[f] == *bytes, "{what}: {f} differs from the reference");
    }
    run.executed
        .iter()
        .filter(|k| k.starts_with("weights/") && k.contains("/b"))
        .map(|k| {
            let summary = &run.outcomes[k].as_ref().unwrap().summary;
            COLUMNS
                .lock()
                .unwrap()
                .push(summary["columns"].as_u64().unwrap_or(u64::MAX));
            let state = summary["window_cache"]
                .as_str()
                .unwrap_or("absent")
                .to_string();
            (k.clone(), state)
        })
        .collect()
}

fn window_of(key: &str) -> &str {
    key.rsplit_once('/').map_or(key, |(w, _)| w)
}

/// The first block task of each window misses, every later one hits.
fn assert_first_misses_then_hits(blocks: &[(String, String)], what: &str) {
    let mut seen = std::collections::HashSet::new();
    for (k, state) in blocks {
        let want = if seen.insert(window_of(k).to_string()) {
            "miss"
        } else {
            "hit"
        };
        assert_eq!(state, want, "{what}: {k}");
    }
    assert!(
        blocks.len() > seen.len(),
        "{what}: the case needs windows with several blocks ({} blocks, {} windows)",
        blocks.len(),
        seen.len()
    );
}

/// Blocks are sized from their window's anchor count: at most `anchor_block` (40) columns, and the blocks of a
/// window differ by at most one column (no ragged last block).
fn assert_even_blocks(blocks: &[(String, String)], columns: &[u64]) {
    let mut per_window: std::collections::BTreeMap<&str, Vec<u64>> = Default::default();
    for ((k, _), &c) in blocks.iter().zip(columns) {
        per_window.entry(window_of(k)).or_default().push(c);
    }
    for (w, cols) in &per_window {
        let (lo, hi) = (cols.iter().min().unwrap(), cols.iter().max().unwrap());
        assert!(*hi <= 40 && hi - lo <= 1, "{w}: block columns {cols:?}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn blocks_share_their_window_and_changed_inputs_are_not_served_stale() {
    let root = tempfile::tempdir().unwrap();
    let root = root.path();
    let (input, anchors) = fixture(&root.join("a"), 1500, 10);
    let out = root.join("out");

    // 1. Fresh cache: one miss per window, hits after, output equal to the reference.
    let first = run_and_check(&input, &anchors, root, &out, "first").await;
    assert_first_misses_then_hits(&first, "first run");
    assert_even_blocks(&first, &COLUMNS.lock().unwrap());
    let (entries, bytes) = window_cache::usage();
    assert!(entries >= 2, "the windows stay cached ({entries} entries)");
    assert!(bytes <= window_cache::budget());

    // 2. The same spec again with nothing changed: every block is a hit.
    let again = run_and_check(&input, &anchors, root, &out, "again").await;
    assert!(
        again.iter().all(|(_, s)| s == "hit"),
        "unchanged resubmission: {again:?}"
    );

    // 3. Same spec, the anchors file replaced in place by other anchors: misses again, and the output is that
    //    of the new anchors (a stale window would reproduce the first run's output and fail the comparison).
    let (seq, _) = synth::demo(&DemoSpec {
        triangles: 1500,
        frames: 10,
        ..Default::default()
    })
    .unwrap();
    let other = synth::random_anchors(&seq.topology, &seq.frames, 150, 99).unwrap();
    other.write(&anchors).unwrap();
    let changed = run_and_check(&input, &anchors, root, &out, "anchors-changed").await;
    assert_first_misses_then_hits(&changed, "after the anchors changed");

    // 4. Same spec, one input frame rewritten in place (the sequence reopens): misses again, new output.
    let frame = std::fs::read_dir(&input)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "obj"))
        .min()
        .unwrap();
    let text = std::fs::read_to_string(&frame).unwrap();
    let moved: String = text
        .lines()
        .map(|l| match l.strip_prefix("v ") {
            Some(rest) => {
                let c: Vec<f64> = rest
                    .split_whitespace()
                    .map(|x| x.parse().unwrap())
                    .collect();
                format!("v {} {} {}\n", c[0] * 1.01, c[1], c[2] + 0.002)
            }
            None => format!("{l}\n"),
        })
        .collect();
    std::fs::write(&frame, moved).unwrap();
    let reopened = run_and_check(&input, &anchors, root, &out, "input-changed").await;
    assert_first_misses_then_hits(&reopened, "after the input changed");

    // 5. Budget 0 turns the cache off (everything misses, nothing is kept) without changing the output; a
    //    budget of half of what the full run kept keeps the cache within it.
    window_cache::set_budget(window_cache::DEFAULT_BUDGET_BYTES);
    run_and_check(&input, &anchors, root, &out, "full").await;
    let (full_entries, full_bytes) = window_cache::usage();
    window_cache::set_budget(full_bytes / 2);
    run_and_check(&input, &anchors, root, &out, "small").await;
    let (entries, bytes) = window_cache::usage();
    assert!(
        entries < full_entries && bytes <= full_bytes / 2,
        "half budget: {entries} entries, {bytes} bytes (full: {full_entries}, {full_bytes})"
    );
    window_cache::set_budget(window_cache::DEFAULT_BUDGET_BYTES);
}

//! The order of the planner's task list, which is the coordinator's dispatch order among ready tasks: every
//! task after its dependencies, each positioning chunk right after the last window it needs (so it runs beside
//! the next windows' weight tasks, not after all of them), `fold-files` right after the first weight task, and
//! a stretch job's `fold-plot` after its settle ranges and merge.

use crease_jobs::storage::keys;
use crease_jobs::{expand, plan, InputInfo, JobSpec, TaskDef, TaskOutput, TaskSpec};
use serde_json::json;

fn job(folds: &str, mode: &str) -> JobSpec {
    JobSpec::from_toml_str(&format!(
        "input = \"/in\"\noutput = \"/out\"\n{folds}\n[deform]\nmode = \"{mode}\"\nwindow = 4\nshift = 3\n\
         [partition]\nanchor_block = 8\nframes_per_chunk = 2\n[preview]\nsize = 64\n"
    ))
    .unwrap()
}

fn info(n: usize, anchors: Option<usize>) -> InputInfo {
    InputInfo {
        layout: "obj-frames".into(),
        n_frames: n,
        n_vertices: 100,
        n_triangles: 180,
        output_files: (1..=n).map(|i| format!("frame_{i:04}.obj")).collect(),
        anchors_per_frame: anchors.map(|a| vec![a; n]),
    }
}

fn index(tasks: &[TaskDef], key: &str) -> usize {
    tasks
        .iter()
        .position(|t| t.key == key)
        .unwrap_or_else(|| panic!("no task {key}"))
}

/// Every dependency is listed before its dependant, and keys are unique.
fn assert_topological(tasks: &[TaskDef]) {
    for (i, t) in tasks.iter().enumerate() {
        assert_eq!(index(tasks, &t.key), i, "duplicate key {}", t.key);
        for d in &t.deps {
            assert!(
                index(tasks, d) < i,
                "{} is listed before its dependency {d}",
                t.key
            );
        }
    }
}

/// Each positioning chunk comes after its last window's field task and before any task of the next window.
fn assert_positions_interleaved(tasks: &[TaskDef]) {
    let window_of = |t: &TaskDef| match t.spec {
        TaskSpec::WeightBlock { window, .. }
        | TaskSpec::WeightWindow { window, .. }
        | TaskSpec::Reduce { window, .. } => Some(window),
        _ => None,
    };
    let n_windows = tasks.iter().filter_map(window_of).max().unwrap() + 1;
    assert!(n_windows >= 3, "the case has several windows");
    let mut interleaved = 0;
    for (i, t) in tasks.iter().enumerate() {
        if !matches!(t.spec, TaskSpec::Position { .. }) {
            continue;
        }
        let last = t
            .deps
            .iter()
            .filter_map(|d| tasks.iter().find(|x| &x.key == d).and_then(window_of))
            .max()
            .unwrap();
        let next_window_starts = tasks
            .iter()
            .position(|x| window_of(x).is_some_and(|w| w > last))
            .unwrap_or(tasks.len());
        assert!(
            i < next_window_starts,
            "{} (last window {last}) is listed after window {}'s tasks",
            t.key,
            last + 1
        );
        if next_window_starts < tasks.len() {
            interleaved += 1;
        }
    }
    assert!(interleaved >= 2, "early chunks come before later windows");
}

#[test]
fn positioning_chunks_follow_their_last_window() {
    for mode in ["per-anchor", "fused"] {
        let j = job("[folds]\nkind = \"anchors\"\nuri = \"/anchors.json\"", mode);
        let tasks = plan(&j, &info(14, Some(6))).unwrap();
        assert_topological(&tasks);
        assert_positions_interleaved(&tasks);
        assert_eq!(tasks.last().unwrap().key, keys::FINALIZE_TASK, "{mode}");
    }
}

#[test]
fn detected_folds_files_after_the_first_weight_task_and_plot_after_the_merge() {
    let (j, i) = (
        job("[folds]\nkind = \"stretch\"", "per-anchor"),
        info(14, None),
    );
    let mut tasks = plan(&j, &i).unwrap();
    let plot = index(&tasks, keys::FOLD_PLOT_TASK);
    assert!(plot > index(&tasks, keys::FOLD_MERGE_TASK));
    for t in &tasks {
        if matches!(t.spec, TaskSpec::FoldSettle { .. }) {
            assert!(index(&tasks, &t.key) < plot, "{} before fold-plot", t.key);
        }
    }
    let out = TaskOutput {
        summary: json!({ "anchors_per_frame": vec![6usize; 14] }),
        ..Default::default()
    };
    let more = expand(&j, &i, keys::FOLD_MERGE_TASK, &out).unwrap();
    assert!(matches!(
        more[0].spec,
        TaskSpec::WeightBlock {
            window: 0,
            block: 0,
            ..
        }
    ));
    assert_eq!(more[1].key, keys::FOLD_FILES_TASK);
    let finalize = more.last().unwrap();
    assert!(finalize.deps.iter().any(|d| d == keys::FOLD_PLOT_TASK));
    tasks.extend(more);
    assert_topological(&tasks);
    assert_positions_interleaved(&tasks);
}

/// Positioning chunks end where a window releases its frames: each chunk holds at most `size` frames, all
/// needing the same last window, so a chunk never waits for a window some of its frames do not need.
#[test]
fn positioning_chunks_end_at_the_windows_release_points() {
    use crease_core::spacetime::windows::plan_windows;
    use crease_jobs::plan::chunks::position_chunks;
    let w = plan_windows(20, 10, 7);
    let got = position_chunks(20, &w, 4);
    assert_eq!(got, [0..4, 4..7, 7..11, 11..14, 14..18, 18..20]);
    for (n, window, shift, size) in [
        (1, 10, 7, 4),
        (12, 6, 4, 4),
        (14, 4, 3, 2),
        (31, 10, 7, 5),
        (9, 3, 3, 1),
    ] {
        let windows = plan_windows(n, window, shift);
        let last = |t: usize| windows.iter().rposition(|w| w.start <= t).unwrap();
        let chunks = position_chunks(n, &windows, size);
        let frames: Vec<usize> = chunks.iter().flat_map(|r| r.clone()).collect();
        assert_eq!(
            frames,
            (0..n).collect::<Vec<_>>(),
            "every frame once, in order"
        );
        for r in &chunks {
            assert!(!r.is_empty() && r.len() <= size, "{r:?}");
            assert!(
                r.clone().all(|t| last(t) == last(r.start)),
                "{r:?} straddles a release point"
            );
        }
        // Never more chunks than cutting each window's released frames alone would make.
        let released = |k: usize| (0..n).filter(|&t| last(t) == k).count();
        let bound: usize = (0..windows.len()).map(|k| released(k).div_ceil(size)).sum();
        assert_eq!(chunks.len(), bound);
    }
}

/// A video job that joins the geometry's folds lists the reliefs before its fold merge and makes the merge wait
/// for every one (it reads them to tell whether the capture erased its folds); with `geometry_folds = false`
/// the merge waits for the detection alone.
#[test]
fn a_video_merge_that_fuses_waits_for_every_relief() {
    let relief_keys = |tasks: &[TaskDef]| -> Vec<String> {
        tasks
            .iter()
            .filter(|t| matches!(t.spec, TaskSpec::Relief { .. }))
            .map(|t| t.key.clone())
            .collect()
    };
    for (extra, waits) in [
        ("", true),
        ("\n[folds.params]\ngeometry_folds = false", false),
    ] {
        let j = job(
            &format!("[folds]\nkind = \"video\"\ncameras = \"/c.json\"{extra}"),
            "fused",
        );
        let tasks = plan(&j, &info(9, None)).unwrap();
        assert_topological(&tasks);
        let reliefs = relief_keys(&tasks);
        assert!(reliefs.len() > 1, "the case has several relief chunks");
        let merge = &tasks[index(&tasks, keys::FOLD_MERGE_TASK)];
        for r in &reliefs {
            assert_eq!(merge.deps.contains(r), waits, "{extra:?}: merge and {r}");
        }
    }
}

//! Bad job specs and inputs are rejected with messages naming the field, URI or file; a task that meets bad
//! data fails as not retryable, naming the file and frame; cancellation stops a task.

mod common;

use common::*;
use crease_jobs::storage::keys;
use crease_jobs::{execute, inspect_input, JobError, JobSpec, Storage, TaskSpec};
use std::path::Path;
use std::sync::Arc;

fn toml_err(text: &str) -> String {
    JobSpec::from_toml_str(text).unwrap_err().to_string()
}

#[test]
fn malformed_specs_name_the_field() {
    let base = "input = \"/data/in\"\noutput = \"/data/out\"\n";
    // Negative block size: not a valid count.
    let e = toml_err(&format!("{base}[partition]\nanchor_block = -4\n"));
    assert!(e.contains("anchor_block") && e.contains("-4"), "{e}");
    let e = toml_err(&format!("{base}[partition]\nframes_per_chunk = 0\n"));
    assert!(
        e.contains("partition.frames_per_chunk") && e.contains("at least 1"),
        "{e}"
    );
    // Unknown fold kind.
    let e = toml_err(&format!("{base}[folds]\nkind = \"telepathy\"\n"));
    assert!(e.contains("telepathy") && e.contains("folds"), "{e}");
    // Anchors without a URI.
    let e = toml_err(&format!("{base}[folds]\nkind = \"anchors\"\n"));
    assert!(e.contains("uri"), "{e}");
    // Deformation parameters are checked by crease-core's rules and named with their table.
    let e = toml_err(&format!("{base}[deform]\nwindow = 10\nshift = 12\n"));
    assert!(e.contains("deform.shift"), "{e}");
    let e = toml_err(&format!(
        "{base}[deform.coefficients]\nc_s = 0.9\nc_t = 0.5\nc_i = 0.1\nc_a = -1.0\n"
    ));
    assert!(e.contains("deform.c_a"), "{e}");
    let e = toml_err(&format!("{base}[deform]\nanchor_block = 64\n"));
    assert!(
        e.contains("deform.anchor_block") && e.contains("partition.anchor_block"),
        "{e}"
    );
    let e = toml_err(&format!("{base}[deform]\nmode = \"sideways\"\n"));
    assert!(e.contains("sideways"), "{e}");
    // Typos are not silently ignored.
    let e = toml_err(&format!("{base}priorty = 3\n"));
    assert!(e.contains("priorty"), "{e}");
    let e = toml_err("output = \"/data/out\"\n");
    assert!(e.contains("input"), "{e}");
    let e = toml_err("input = \"\"\noutput = \"/o\"\n");
    assert!(e.contains("`input`"), "{e}");
    let e = toml_err(&format!("{base}max_task_attempts = 0\n"));
    assert!(e.contains("max_task_attempts"), "{e}");
    // JSON works the same way.
    let e = JobSpec::from_json_str(
        r#"{"input": "/a", "output": "/b", "partition": {"anchor_block": -1}}"#,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("anchor_block"), "{e}");
    let ok =
        JobSpec::from_toml_str(&format!("{base}priority = 5\nclient_token = \"abc\"\n")).unwrap();
    assert_eq!((ok.priority, ok.client_token.as_deref()), (5, Some("abc")));
    assert_eq!(ok.params(), crease_core::spacetime::DeformParams::default());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn unreachable_or_unreadable_inputs_are_rejected_at_submit() {
    let root = tempfile::tempdir().unwrap();
    let (input, anchors) = fixture(root.path(), 600, 4);
    let out = root.path().join("out");
    // Missing input: the error names the URI.
    let missing = root.path().join("nowhere");
    let e = inspect_input(&job(&missing, Some(&anchors), &out, ""))
        .await
        .unwrap_err();
    assert!(matches!(e, JobError::Input { .. }), "{e:?}");
    assert!(e.to_string().contains("nowhere"), "{e}");
    let uri = format!("file://{}", missing.display());
    let mut spec = job(&input, None, &out, "");
    spec.input = uri.clone();
    let e = inspect_input(&spec).await.unwrap_err().to_string();
    assert!(e.contains(&uri), "{e}");
    // Missing anchors file.
    let e = inspect_input(&job(&input, Some(&root.path().join("none.json")), &out, ""))
        .await
        .unwrap_err()
        .to_string();
    assert!(e.contains("none.json"), "{e}");
    // Unparsable anchors: named with the position of the error.
    let bad = root.path().join("bad.json");
    std::fs::write(&bad, "{ \"version\": 1, \"frames\": [ {\"frame\": 0, ").unwrap();
    let e = inspect_input(&job(&input, Some(&bad), &out, ""))
        .await
        .unwrap_err()
        .to_string();
    assert!(e.contains("bad.json") && e.contains("line"), "{e}");
    // Anchors that do not fit the input (a triangle index out of range).
    let text = std::fs::read_to_string(&anchors).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let mut v2 = v.clone();
    let frames = v2["frames"].as_array_mut().unwrap();
    let first = frames
        .iter_mut()
        .find(|f| !f["anchors"].as_array().unwrap().is_empty())
        .unwrap();
    first["anchors"][0]["triangle"] = serde_json::json!(10_000_000);
    let wrong = root.path().join("wrong.json");
    std::fs::write(&wrong, serde_json::to_string(&v2).unwrap()).unwrap();
    let e = inspect_input(&job(&input, Some(&wrong), &out, ""))
        .await
        .unwrap_err()
        .to_string();
    assert!(e.contains("wrong.json") && e.contains("10000000"), "{e}");
    // Output inside the input directory would overwrite the frames.
    let e = inspect_input(&job(&input, Some(&anchors), &input, ""))
        .await
        .unwrap_err()
        .to_string();
    assert!(e.contains("`output`") && e.contains("overwrite"), "{e}");
    // An output location that cannot be a directory.
    let file = root.path().join("plain-file");
    std::fs::write(&file, "x").unwrap();
    let e = inspect_input(&job(&input, Some(&anchors), &file, ""))
        .await
        .unwrap_err()
        .to_string();
    assert!(e.contains("output") && e.contains("plain-file"), "{e}");
    // Preview frames out of range.
    let e = inspect_input(&job(
        &input,
        Some(&anchors),
        &out,
        "[preview]\nframes = [9]\n",
    ))
    .await
    .unwrap_err()
    .to_string();
    assert!(e.contains("preview.frames") && e.contains('9'), "{e}");
    // A good job is accepted and described.
    let info = inspect_input(&job(&input, Some(&anchors), &out, ""))
        .await
        .unwrap();
    assert_eq!((info.n_frames, info.layout.as_str()), (4, "obj-frames"));
    assert_eq!(info.output_files.len(), 4);
}

/// Replaces the first vertex of an OBJ file with a NaN.
fn poison(path: &Path) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let i = lines.iter().position(|l| l.starts_with("v ")).unwrap();
    lines[i] = "v nan 0.0 0.0".to_string();
    std::fs::write(path, lines.join("\n") + "\n").unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn nan_in_a_late_frame_fails_exactly_the_task_that_reads_it_without_retry() {
    let root = tempfile::tempdir().unwrap();
    let (input, anchors) = fixture(root.path(), 700, 12);
    poison(&input.join("frame_0011.obj")); // frame 10 (0-based)
    let out = root.path().join("out");
    let spec = job(
        &input,
        Some(&anchors),
        &out,
        "[deform]\nmode = \"per-anchor\"\nwindow = 6\nshift = 4\n[partition]\nanchor_block = 40\nframes_per_chunk = 4\n",
    );
    // Submit-time inspection reads frame 0 only, so the job is accepted. The first task to read frame 10 is
    // the relief of its chunk (it reads the captured input alone and runs before any positioning).
    let run = run_job(&spec, &root.path().join("cache"), PLAN_ORDER).await;
    let failed: Vec<_> = run.outcomes.iter().filter(|(_, r)| r.is_err()).collect();
    assert_eq!(failed.len(), 1, "exactly one task fails: {failed:?}");
    let (key, err) = failed[0];
    assert_eq!(key, &keys::relief_task(8), "the chunk holding frame 10");
    let err = err.as_ref().unwrap_err();
    assert!(!err.retryable(), "bad data is not retryable: {err:?}");
    assert!(
        err.reason.contains("frame_0011.obj") && err.reason.contains("frame 10"),
        "{}",
        err.reason
    );
    // The weights (which read the anchors, not the frames) and the other reliefs succeeded; no positioning
    // that needs frame 10's relief ran, finalize never ran, and no report claims completeness.
    assert!(run
        .outcomes
        .iter()
        .filter(|(k, _)| k.starts_with("weights/") || k.starts_with("relief/"))
        .all(|(k, r)| r.is_ok() || *k == keys::relief_task(8)));
    assert!(!run.outcomes.contains_key(&keys::position_task(8)));
    assert!(!run.outcomes.contains_key(keys::FINALIZE_TASK));
    assert!(!out.join("report.json").exists());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cancellation_and_malformed_tasks() {
    let root = tempfile::tempdir().unwrap();
    let (input, anchors) = fixture(root.path(), 700, 10);
    let out = root.path().join("out");
    let spec = job(
        &input,
        Some(&anchors),
        &out,
        "[partition]\nframes_per_chunk = 10\n",
    );
    run_job(&spec, &root.path().join("cache"), PLAN_ORDER).await;
    let storage = Storage::open(&spec.output).unwrap();
    storage.delete(&keys::positions(9)).await.unwrap();
    // Cancelled before starting, and half-way through a chunk: stops without writing the remaining frames.
    for after in [0, 1] {
        let ctx = crease_jobs::ExecContext {
            progress: Arc::new(CancelAfter {
                after,
                seen: Default::default(),
            }),
            cache_dir: root.path().join("cache"),
        };
        let task = TaskSpec::Position {
            job: spec.clone(),
            frames: 0..10,
        };
        let err = execute(&task, &ctx).await.unwrap_err();
        assert!(err.is_cancelled(), "{err:?}");
        assert!(!storage.exists(&keys::positions(9)).await.unwrap());
    }
    // Tasks that do not fit the job are fatal errors naming what is wrong.
    let ctx = ctx(&root.path().join("cache"));
    for (task, needle) in [
        (
            TaskSpec::WeightWindow {
                job: spec.clone(),
                window: 7,
            },
            "window 7",
        ),
        (
            TaskSpec::Position {
                job: spec.clone(),
                frames: 8..12,
            },
            "8..12",
        ),
        (TaskSpec::FoldMerge { job: spec.clone() }, "not detected"),
        (
            TaskSpec::FoldSettle {
                job: spec.clone(),
                frames: 0..3,
            },
            "no settle tasks",
        ),
        (
            TaskSpec::FoldPlot { job: spec.clone() },
            "no stretch detection tasks",
        ),
    ] {
        let err = execute(&task, &ctx).await.unwrap_err();
        assert!(!err.retryable() && err.reason.contains(needle), "{err:?}");
    }
    // Finalize reads every frame's positions (shape figures): put back the one deleted above, then check that it
    // refuses to vouch for an output whose frame files are not all there.
    execute(
        &TaskSpec::Position {
            job: spec.clone(),
            frames: 0..10,
        },
        &ctx,
    )
    .await
    .unwrap();
    std::fs::remove_file(out.join("frame_0005.obj")).unwrap();
    let err = execute(&TaskSpec::Finalize { job: spec.clone() }, &ctx)
        .await
        .unwrap_err();
    assert!(
        !err.retryable() && err.reason.contains("frame_0005.obj"),
        "{err:?}"
    );
    assert!(!out.join("report.json").exists());
    let err = TaskSpec::from_payload("position", b"{\"kind\": \"finalize\"").unwrap_err();
    assert!(
        !err.retryable() && err.reason.contains("malformed"),
        "{err:?}"
    );
    let payload = TaskSpec::Finalize { job: spec.clone() }.to_payload();
    let err = TaskSpec::from_payload("position", &payload).unwrap_err();
    assert!(err.reason.contains("finalize"), "{err:?}");
    assert_eq!(
        TaskSpec::from_payload("finalize", &payload).unwrap(),
        TaskSpec::Finalize { job: spec }
    );
}

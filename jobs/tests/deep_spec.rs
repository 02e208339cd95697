//! The `[deep]` job kind without storage: parsing, validation naming the field, the task graph, and the farm
//! export refusing it, and the inspection a coordinator without the learning library makes (the cluster run
//! itself is in tests/tests/deep.rs).

use crease_jobs::deep::{DeepSpec, Regressor};
use crease_jobs::farm::farm_graph;
use crease_jobs::{final_outputs, plan, InputInfo, JobError, JobSpec, TaskSpec};

fn spec(deep: &str, extra: &str) -> Result<JobSpec, JobError> {
    JobSpec::from_toml_str(&format!(
        "input = \"/data/in\"\noutput = \"/data/out\"\n{extra}\n[deep]\n{deep}"
    ))
}

fn field_of(e: JobError) -> String {
    match e {
        JobError::Spec { field, .. } => field,
        other => panic!("not a spec error: {other}"),
    }
}

fn info(n: usize, files: Vec<String>) -> InputInfo {
    InputInfo {
        layout: "deep-apply".into(),
        n_frames: n,
        n_vertices: 10,
        n_triangles: 8,
        output_files: files,
        anchors_per_frame: None,
    }
}

#[test]
fn train_and_apply_specs_parse_with_the_cli_defaults() {
    let train = spec(
        "task = \"train\"\ndata = [\"/data/b\"]\n[deep.params]\nk = 50\ncgan_steps = 2\n",
        "",
    )
    .unwrap();
    match train.deep.as_ref().unwrap() {
        DeepSpec::Train { data, params } => {
            assert_eq!(data, &["/data/b"]);
            assert_eq!(params.k, 50);
            assert_eq!(params.cgan_steps, 2);
            assert_eq!(params.resolution, 512, "crease deep train's default");
            assert_eq!(params.cgan_filters, 8);
            assert_eq!(params.regressor, Regressor::Kernel);
            assert_eq!(params.kernel_window, [0, 2, 4, 6]);
            assert!(!params.kernel_uniform);
            assert_eq!(params.pose_lowpass, 6.0);
            assert_eq!((params.ar_state, params.ar_rollout_iters), (10, 20));
            assert_eq!((params.blend_weight, params.blend_fit), (0.5, false));
            assert!(params.lags.is_empty());
        }
        other => panic!("{other:?}"),
    }
    let apply = spec(
        "task = \"apply\"\nmodel = \"/m\"\nfrom = \"coarse\"\nspace = \"tangent\"\n",
        "",
    )
    .unwrap();
    assert_eq!(apply.deep.as_ref().unwrap().kind(), "deep-apply");
    // JSON round trip (the coordinator stores the spec as JSON).
    let back: JobSpec = serde_json::from_str(&serde_json::to_string(&apply).unwrap()).unwrap();
    assert_eq!(back, apply);
    // A deformation spec serialises without a `deep` key, as before.
    let plain = JobSpec::from_toml_str("input = \"/a\"\noutput = \"/b\"\n").unwrap();
    assert!(!serde_json::to_string(&plain).unwrap().contains("deep"));
}

#[test]
fn bad_deep_specs_name_the_field() {
    // Only the learning library knows the ranges of the training parameters (checked at submit where the
    // coordinator has it, by the training task otherwise).
    #[cfg(feature = "deep")]
    let library_cases = [
        (
            spec("task = \"train\"\n[deep.params]\nresolution = 8\n", ""),
            "deep.params.resolution",
        ),
        (
            spec(
                "task = \"train\"\n[deep.params]\ncgan_steps = 1\nresolution = 48\n",
                "",
            ),
            "deep.params.resolution",
        ),
        (
            spec("task = \"train\"\n[deep.params]\nlstm_layers = 0\n", ""),
            "deep.params.lstm_layers",
        ),
        (
            spec("task = \"train\"\n[deep.params]\nar_state = 0\n", ""),
            "deep.params.ar_state",
        ),
    ];
    #[cfg(not(feature = "deep"))]
    let library_cases = [];
    let cases = [
        (spec("task = \"apply\"\nfrom = \"pose\"\n", ""), "model"),
        (
            spec("task = \"apply\"\nmodel = \"/m\"\nfrom = \"scan\"\n", ""),
            "unknown variant `scan`",
        ),
        (
            spec(
                "task = \"apply\"\nmodel = \"/m\"\nfrom = \"coarse\"\nregressor = \"lstm\"\n",
                "",
            ),
            "deep.regressor",
        ),
        (
            spec(
                "task = \"apply\"\nmodel = \"/m\"\nfrom = \"pose\"\ncoarse_detail = \"relief\"\n",
                "",
            ),
            "deep.coarse_detail",
        ),
        (
            spec(
                "task = \"apply\"\nmodel = \"/m\"\nfrom = \"coarse\"\ncoarse_detail = \"blur\"\n",
                "",
            ),
            "unknown variant `blur`",
        ),
        (
            spec(
                "task = \"train\"\n",
                "[folds]\nkind = \"anchors\"\nuri = \"/a.json\"\n",
            ),
            "folds",
        ),
        (
            spec("task = \"train\"\n", "[deform]\nwindow = 5\n"),
            "deform",
        ),
        (
            spec("task = \"train\"\n", "[export]\nformats = [\"glb\"]\n"),
            "export",
        ),
        (
            spec(
                "task = \"apply\"\nmodel = \"s3://b/../m\"\nfrom = \"pose\"\n",
                "",
            ),
            "deep.model",
        ),
    ];
    for (i, (result, want)) in cases.into_iter().chain(library_cases).enumerate() {
        let err = result.expect_err(&format!("case {i} should be refused"));
        let text = err.to_string();
        let field = field_of(err);
        // The field, or (where serde gives no position: internally tagged tables) the message, names it.
        assert!(
            field.starts_with(want) || text.contains(want),
            "case {i}: field `{field}`, expected `{want}` ({text})"
        );
    }
}

#[test]
fn an_unknown_deep_parameter_is_named() {
    // serde buffers internally tagged tables, so the TOML error has no position: the message names the key.
    let err = spec("task = \"train\"\n[deep.params]\nkk = 3\n", "")
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("unknown field `kk`") && err.contains("cgan_steps"),
        "{err}"
    );
}

#[test]
fn apply_plans_frame_chunks_then_finish_and_training_one_task() {
    let job = spec(
        "task = \"apply\"\nmodel = \"/m\"\nfrom = \"pose\"\n",
        "[partition]\nframes_per_chunk = 3\n",
    )
    .unwrap();
    let files = vec!["mesh/frame_0001.obj".to_string()];
    let tasks = plan(&job, &info(10, files.clone())).unwrap();
    let chunks: Vec<_> = tasks
        .iter()
        .filter_map(|t| match &t.spec {
            TaskSpec::DeepApply { frames, .. } => Some(frames.clone()),
            _ => None,
        })
        .collect();
    assert_eq!(chunks, vec![0..3, 3..6, 6..9, 9..10]);
    let last = tasks.last().unwrap();
    assert!(matches!(last.spec, TaskSpec::DeepFinish { frames: 10, .. }));
    assert_eq!(last.deps.len(), 4, "finish waits for every chunk");
    assert_eq!(
        final_outputs(&job, &info(10, files)),
        ["mesh/frame_0001.obj", "report.json"]
    );
    let train = spec("task = \"train\"\n", "").unwrap();
    let tasks = plan(&train, &info(30, vec![])).unwrap();
    assert_eq!(tasks.len(), 1);
    assert_eq!(tasks[0].spec.kind(), "deep-train");
    // The task travels as its kind and JSON payload, like every other.
    let back = TaskSpec::from_payload("deep-train", &tasks[0].spec.to_payload()).unwrap();
    assert_eq!(back, tasks[0].spec);
}

#[test]
fn the_farm_export_refuses_deep_jobs_with_a_clear_error() {
    for deep in [
        "task = \"train\"\n",
        "task = \"apply\"\nmodel = \"/m\"\nfrom = \"pose\"\n",
    ] {
        let job = spec(deep, "").unwrap();
        let err = farm_graph(&job, &info(4, vec![]), 4)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("[deep] job") && err.contains("cannot be exported to a render farm"),
            "{err}"
        );
    }
}

/// A coordinator built without the learning library still inspects and plans deep jobs: frame counts from the
/// training data's `gt/` sequences, the pose file and the model's manifest; what only the library checks is the
/// training task's to refuse.
#[cfg(not(feature = "deep"))]
#[tokio::test]
async fn without_the_library_deep_jobs_are_inspected_and_planned() {
    use crease_core::synth::{demo, write_frames, DemoSpec};
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    let (seq, _) = demo(&DemoSpec {
        triangles: 200,
        frames: 5,
        ..Default::default()
    })
    .unwrap();
    for name in ["a", "b"] {
        write_frames(&d.join(name).join("gt"), &seq).unwrap();
    }
    let s = |p: &std::path::Path| p.display().to_string();
    let train = JobSpec::from_toml_str(&format!(
        "input = \"{}\"\noutput = \"{}\"\n[deep]\ntask = \"train\"\ndata = [\"{}\"]\n",
        s(&d.join("a")),
        s(&d.join("out-train")),
        s(&d.join("b"))
    ))
    .unwrap();
    let info = crease_jobs::inspect_input(&train).await.unwrap();
    let topo = &seq.topology;
    assert_eq!(
        (info.n_frames, info.n_vertices, info.n_triangles),
        (10, topo.n_vertices(), topo.n_triangles())
    );
    assert!(info.output_files.last().unwrap().ends_with("manifest.json"));
    assert_eq!(plan(&train, &info).unwrap().len(), 1);

    let model = d.join("model");
    std::fs::create_dir_all(&model).unwrap();
    let pose = d.join("pose.json");
    std::fs::write(
        &pose,
        r#"{"pose_vectors": [[0.1], [0.2], [0.3], [0.4], [0.5], [0.6], [0.7]]}"#,
    )
    .unwrap();
    let apply = JobSpec::from_toml_str(&format!(
        "input = \"{}\"\noutput = \"{}\"\n[partition]\nframes_per_chunk = 3\n[deep]\ntask = \"apply\"\nmodel = \"{}\"\nfrom = \"pose\"\n",
        s(&pose),
        s(&d.join("out-apply")),
        s(&model)
    ))
    .unwrap();
    // A model without its manifest is refused at submit, naming it.
    let err = crease_jobs::inspect_input(&apply)
        .await
        .unwrap_err()
        .to_string();
    assert!(err.contains("manifest.json"), "{err}");
    std::fs::write(
        model.join("manifest.json"),
        r#"{"vertices": 12, "triangles": 20}"#,
    )
    .unwrap();
    let info = crease_jobs::inspect_input(&apply).await.unwrap();
    assert_eq!(
        (info.n_frames, info.n_vertices, info.n_triangles),
        (7, 12, 20)
    );
    let tasks = plan(&apply, &info).unwrap();
    assert_eq!(tasks.len(), 4, "three frame chunks and the finish");
}

/// A worker built without the learning library refuses a deep task with the way to one that runs it, and the
/// refusal is not retried (every such worker would refuse it).
#[cfg(not(feature = "deep"))]
#[tokio::test]
async fn without_the_library_a_worker_refuses_deep_tasks() {
    let d = tempfile::tempdir().unwrap();
    let job = spec("task = \"train\"\n", "").unwrap();
    let ctx = crease_jobs::ExecContext {
        progress: std::sync::Arc::new(crease_core::progress::NoProgress),
        cache_dir: d.path().to_path_buf(),
    };
    let err = crease_jobs::execute(&TaskSpec::DeepTrain { job }, &ctx)
        .await
        .unwrap_err();
    assert!(!err.retryable(), "{err}");
    assert!(
        err.reason.contains("--features deep") && err.reason.starts_with("deep-train"),
        "{err}"
    );
}

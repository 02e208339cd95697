//! The farm job formats, checked offline with the farms' own tools: OpenJD templates pass `openjd check`, the
//! Flamenco job type authors (under node, with a mock of Flamenco's `author` API) exactly the planner's tasks,
//! commands and dependencies, and OpenCue specs are valid against OpenCue's DTD (`xmllint --dtdvalid`).

use crease_jobs::farm::{export_job, farm_graph, CueIdentity, Farm, FarmCommand, FarmGraph, Stage};
use crease_jobs::{plan, InputInfo, JobSpec};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

/// `name` in `.tools/venv/bin` or on PATH; a clear failure when missing (scripts/setup-tools installs it).
fn tool(name: &str) -> PathBuf {
    let local = repo().join(".tools/venv/bin").join(name);
    if local.is_file() {
        return local;
    }
    std::env::var_os("PATH")
        .and_then(|p| {
            std::env::split_paths(&p)
                .map(|d| d.join(name))
                .find(|p| p.is_file())
        })
        .unwrap_or_else(|| {
            panic!("{name} not found in .tools/venv/bin or on PATH: run scripts/setup-tools")
        })
}

fn job(folds: &str, mode: &str) -> JobSpec {
    JobSpec::from_toml_str(&format!(
        "name = \"sleeve take 3\"\ninput = \"/farm/in\"\noutput = \"/farm/out\"\n{folds}\n[deform]\nmode = \"{mode}\"\n\
         window = 3\nshift = 2\n[partition]\nanchor_block = 8\nframes_per_chunk = 2\nfold_frames_per_chunk = 3\n"
    ))
    .unwrap()
}

fn info(anchors: Option<usize>) -> InputInfo {
    InputInfo {
        layout: "obj-frames".into(),
        n_frames: 9,
        n_vertices: 100,
        n_triangles: 180,
        output_files: (1..=9).map(|i| format!("frame_{i:04}.obj")).collect(),
        anchors_per_frame: anchors.map(|a| vec![a; 9]),
    }
}

const ANCHORS: &str = "[folds]\nkind = \"anchors\"\nuri = \"/farm/anchors.json\"";
const STRETCH: &str = "[folds]\nkind = \"stretch\"";
const VIDEO: &str = "[folds]\nkind = \"video\"\ncameras = \"/farm/cameras.json\"";

fn cmd() -> FarmCommand {
    FarmCommand {
        exe: "/opt/crease/bin/crease".into(),
        job_file: "/farm/jobs/sleeve take 3.toml".into(),
    }
}

fn cue() -> CueIdentity {
    CueIdentity {
        show: "crease".into(),
        shot: "sleeve".into(),
        user: "td".into(),
    }
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn cases() -> Vec<(&'static str, JobSpec, InputInfo)> {
    vec![
        (
            "anchors, per-anchor",
            job(ANCHORS, "per-anchor"),
            info(Some(6)),
        ),
        ("anchors, fused", job(ANCHORS, "fused"), info(Some(6))),
        (
            "stretch, per-anchor",
            job(STRETCH, "per-anchor"),
            info(None),
        ),
        ("video, fused", job(VIDEO, "fused"), info(None)),
    ]
}

#[test]
fn farm_graph_mirrors_the_planner_and_slots_cover_detected_blocks() {
    // Anchors known: the farm graph is the planner's graph, task for task.
    let (j, i) = (job(ANCHORS, "per-anchor"), info(Some(6)));
    let g = farm_graph(&j, &i, 4).unwrap();
    let planned: BTreeMap<String, Vec<String>> = plan(&j, &i)
        .unwrap()
        .into_iter()
        .map(|t| (t.key, t.deps))
        .collect();
    let farm: BTreeMap<String, Vec<String>> = g
        .stages
        .iter()
        .flat_map(|s| s.tasks.iter().map(|t| (t.key.clone(), t.deps.clone())))
        .collect();
    assert_eq!(planned, farm);
    let names: Vec<&str> = g.stages.iter().map(|s| s.stage.name()).collect();
    assert_eq!(
        names,
        ["relief", "weights", "reduce", "position", "finalize"]
    );
    // 9 frames, windows of 3 shifted by 2: 4 windows; 18 anchors a window in blocks of 8: 3 blocks each.
    assert_eq!(g.stage(Stage::Weights).unwrap().tasks.len(), 12);
    assert_eq!(g.stage(Stage::Position).unwrap().tasks.len(), 5);
    assert_eq!(g.stage(Stage::Reduce).unwrap().depends_on, [Stage::Weights]);
    assert_eq!(
        g.stage(Stage::Position).unwrap().depends_on,
        [Stage::Relief, Stage::Reduce]
    );

    // Detected: stretch steps, phases, tracing, merge, then 4 slots per window feeding each reduce.
    let g = farm_graph(&job(STRETCH, "per-anchor"), &info(None), 4).unwrap();
    let names: Vec<&str> = g.stages.iter().map(|s| s.stage.name()).collect();
    assert_eq!(
        names,
        [
            "relief",
            "fold-steps",
            "fold-phases",
            "fold-detect",
            "fold-settle",
            "fold-merge",
            "fold-files",
            "fold-plot",
            "weights",
            "reduce",
            "position",
            "finalize"
        ]
    );
    assert_eq!(
        g.stage(Stage::FoldPhases).unwrap().depends_on,
        [Stage::FoldSteps]
    );
    assert_eq!(
        g.stage(Stage::FoldDetect).unwrap().depends_on,
        [Stage::FoldPhases]
    );
    // The merge reconciles the tracing chunks and concatenates the settled ranges.
    assert_eq!(
        g.stage(Stage::FoldSettle).unwrap().depends_on,
        [Stage::FoldDetect]
    );
    assert_eq!(
        g.stage(Stage::FoldMerge).unwrap().depends_on,
        [Stage::FoldDetect, Stage::FoldSettle]
    );
    assert_eq!(g.stage(Stage::FoldSettle).unwrap().tasks.len(), 2);
    // 9 frames at 180 triangles: tracing chunks of 5 frames (half the sequence); step chunks of 4 × 5 frames,
    // but at most half the sequence, so two workers share them too.
    assert_eq!(g.stage(Stage::FoldDetect).unwrap().tasks.len(), 2);
    assert_eq!(g.stage(Stage::FoldSteps).unwrap().tasks.len(), 2);
    let weights = g.stage(Stage::Weights).unwrap();
    assert_eq!(weights.tasks.len(), 4 * 4);
    assert_eq!(weights.depends_on, [Stage::FoldMerge]);
    // The user-facing anchor files are written beside the weights; only finalize waits for them.
    assert_eq!(
        g.stage(Stage::FoldFiles).unwrap().depends_on,
        [Stage::FoldMerge]
    );
    // folds.png needs only the tracing chunks; only finalize waits for it.
    assert_eq!(
        g.stage(Stage::FoldPlot).unwrap().depends_on,
        [Stage::FoldDetect]
    );
    assert_eq!(
        g.stage(Stage::Finalize).unwrap().depends_on,
        [
            Stage::FoldMerge,
            Stage::FoldFiles,
            Stage::FoldPlot,
            Stage::Position
        ]
    );
    let reduce1 = &g.stage(Stage::Reduce).unwrap().tasks[1];
    assert_eq!(reduce1.key, "reduce/w0001");
    for s in 0..4 {
        assert!(
            reduce1.deps.contains(&format!("weights/w0001/slot{s}of4")),
            "{:?}",
            reduce1.deps
        );
    }
    // Per-frame detection in chunks of 3 frames.
    let g = farm_graph(&job(VIDEO, "fused"), &info(None), 4).unwrap();
    assert_eq!(g.stage(Stage::FoldDetect).unwrap().tasks.len(), 3);
    assert!(g.stage(Stage::Reduce).is_none());
    assert!(farm_graph(&job(VIDEO, "fused"), &info(None), 0).is_err());
}

#[test]
fn openjd_check_accepts_every_template() {
    let openjd = tool("openjd");
    let dir = tempfile::tempdir().unwrap();
    for (name, j, i) in cases() {
        let g = farm_graph(&j, &i, 4).unwrap();
        let text = export_job(Farm::OpenJd, &j, &g, &cmd(), &cue());
        let doc: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(doc["specificationVersion"], "jobtemplate-2023-09");
        assert_eq!(
            doc["steps"].as_array().unwrap().len(),
            g.stages.len(),
            "{name}"
        );
        let p = write(dir.path(), "t.json", &text);
        let o = Command::new(&openjd).arg("check").arg(&p).output().unwrap();
        assert!(
            o.status.success(),
            "{name}: openjd check: {}{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
    }
    // The check is real: a step depending on a step that does not exist is refused.
    let (_, j, i) = cases().remove(0);
    let g = farm_graph(&j, &i, 4).unwrap();
    let broken = export_job(Farm::OpenJd, &j, &g, &cmd(), &cue())
        .replace("\"dependsOn\": \"Reduce\"", "\"dependsOn\": \"Nope\"");
    let p = write(dir.path(), "broken.json", &broken);
    let o = Command::new(&openjd).arg("check").arg(&p).output().unwrap();
    assert!(
        !o.status.success(),
        "openjd check accepted a dangling dependency"
    );
}

#[derive(serde::Deserialize, Debug)]
struct Authored {
    label: String,
    tasks: Vec<AuthoredTask>,
}
#[derive(serde::Deserialize, Debug)]
struct AuthoredTask {
    name: String,
    #[serde(rename = "type")]
    kind: String,
    commands: Vec<serde_json::Value>,
    deps: Vec<String>,
}

fn run_flamenco(js: &Path, settings: &str) -> Authored {
    let node = tool("node");
    let o = Command::new(&node).arg("--check").arg(js).output().unwrap();
    assert!(
        o.status.success(),
        "node --check: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let mock = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/farm/flamenco_mock.js");
    let o = Command::new(&node)
        .arg(mock)
        .arg(js)
        .arg(settings)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "compileJob: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    serde_json::from_slice(&o.stdout).unwrap()
}

fn graph_tasks(g: &FarmGraph) -> Vec<(String, String, Vec<String>)> {
    g.stages
        .iter()
        .flat_map(|s| {
            s.tasks
                .iter()
                .map(move |t| (s.stage.name().to_string(), t.key.clone(), t.deps.clone()))
        })
        .collect()
}

#[test]
fn flamenco_job_type_authors_the_graph_under_node() {
    let dir = tempfile::tempdir().unwrap();
    for (name, j, i) in cases() {
        let g = farm_graph(&j, &i, 3).unwrap();
        let js = write(
            dir.path(),
            "crease.js",
            &export_job(Farm::Flamenco, &j, &g, &cmd(), &cue()),
        );
        let a = run_flamenco(&js, "{}");
        assert_eq!(a.label, "crease sleeve take 3");
        let want = graph_tasks(&g);
        assert_eq!(a.tasks.len(), want.len(), "{name}");
        let name_of: BTreeMap<&str, String> = want
            .iter()
            .map(|(s, k, _)| (k.as_str(), format!("{s} {k}")))
            .collect();
        for (t, (stage, key, deps)) in a.tasks.iter().zip(&want) {
            assert_eq!(t.name, format!("{stage} {key}"), "{name}");
            assert_eq!(t.kind, "misc");
            assert_eq!(t.commands.len(), 1);
            assert_eq!(t.commands[0]["name"], "exec");
            assert_eq!(t.commands[0]["params"]["exe"], "/opt/crease/bin/crease");
            assert_eq!(
                t.commands[0]["params"]["args"],
                serde_json::json!([
                    "task",
                    "run",
                    "--job",
                    "/farm/jobs/sleeve take 3.toml",
                    "--task",
                    key
                ])
            );
            let want_deps: Vec<&String> = deps.iter().map(|d| &name_of[d.as_str()]).collect();
            assert_eq!(
                t.deps.iter().collect::<Vec<_>>(),
                want_deps,
                "{name}: {key}"
            );
        }
    }
    // Settings given at submission override the defaults baked in.
    let (_, j, i) = cases().remove(1);
    let g = farm_graph(&j, &i, 3).unwrap();
    let js = write(
        dir.path(),
        "crease.js",
        &export_job(Farm::Flamenco, &j, &g, &cmd(), &cue()),
    );
    let a = run_flamenco(
        &js,
        r#"{"crease_exe": "crease", "job_file": "/mnt/j.toml"}"#,
    );
    assert_eq!(a.tasks[0].commands[0]["params"]["exe"], "crease");
    assert_eq!(a.tasks[0].commands[0]["params"]["args"][3], "/mnt/j.toml");
}

#[test]
fn opencue_specs_are_valid_against_the_vendored_dtd() {
    let xmllint = tool("xmllint");
    let dtd = Path::new(env!("CARGO_MANIFEST_DIR")).join("farm/opencue/cjsl-1.15.dtd");
    let dir = tempfile::tempdir().unwrap();
    let lint = |p: &Path| {
        Command::new(&xmllint)
            .args(["--noout", "--dtdvalid"])
            .arg(&dtd)
            .arg(p)
            .output()
            .unwrap()
    };
    for (name, j, i) in cases() {
        let g = farm_graph(&j, &i, 4).unwrap();
        let xml = export_job(Farm::OpenCue, &j, &g, &cmd(), &cue());
        let p = write(dir.path(), "job.xml", &xml);
        let o = lint(&p);
        assert!(
            o.status.success(),
            "{name}: xmllint: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert_eq!(xml.matches("<layer ").count(), g.stages.len());
        let deps: usize = g.stages.iter().map(|s| s.depends_on.len()).sum();
        assert_eq!(
            xml.matches("<depend type=\"LAYER_ON_LAYER\">").count(),
            deps
        );
        for s in &g.stages {
            assert!(xml.contains(&format!("<range>0-{}</range>", s.tasks.len() - 1)));
        }
        // The job file path has spaces: quoted for the shell OpenCue runs the command in.
        assert!(xml.contains("'/farm/jobs/sleeve take 3.toml'"), "{xml}");
        assert!(xml.contains("--index #IFRAME#"));
    }
    // The validation is real: a layer without its required <chunk> is refused.
    let (_, j, i) = cases().remove(0);
    let g = farm_graph(&j, &i, 4).unwrap();
    let xml = export_job(Farm::OpenCue, &j, &g, &cmd(), &cue()).replacen(
        "        <chunk>1</chunk>\n",
        "",
        1,
    );
    let o = lint(&write(dir.path(), "bad.xml", &xml));
    assert!(
        !o.status.success(),
        "xmllint accepted a layer without <chunk>"
    );
}

//! DeepWrinkles jobs (`[deep]`) on a real coordinator and two workers on 127.0.0.1: a training job publishes
//! the same model files as `crease deep train`, an apply job split into frame chunks across both workers writes
//! the same bytes as `crease deep apply`, and bad deep inputs are refused at submit with the file named.
#![cfg(feature = "deep")]

use crease_core::mesh::io::write_obj;
use crease_core::mesh::Topology;
use crease_e2e::*;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

const NA: usize = 24;
const NR: usize = 12;

fn tube_tris() -> Vec<[u32; 3]> {
    let mut tris = Vec::new();
    for j in 0..NR - 1 {
        for i in 0..NA {
            let i1 = (i + 1) % NA;
            let (a, b, c, d) = (j * NA + i, j * NA + i1, (j + 1) * NA + i1, (j + 1) * NA + i);
            tris.push([a as u32, b as u32, c as u32]);
            tris.push([a as u32, c as u32, d as u32]);
        }
    }
    tris
}

fn tube(radius: impl Fn(f64, f64) -> f64) -> Vec<[f64; 3]> {
    let mut p = Vec::new();
    for j in 0..NR {
        for i in 0..NA {
            let phi = std::f64::consts::TAU * i as f64 / NA as f64;
            let x = 0.5 * j as f64 / (NR - 1) as f64;
            let r = radius(phi, x);
            p.push([x, r * phi.cos(), r * phi.sin()]);
        }
    }
    p
}

/// A tiny training directory: `gt/` with pose-driven ripples, `captured/` without them, `pose.json`.
fn training_dir(root: &Path, name: &str, frames: usize, phase: f64) -> PathBuf {
    let dir = root.join(name);
    let topo = Topology::new(NA * NR, tube_tris()).unwrap();
    std::fs::create_dir_all(dir.join("gt")).unwrap();
    std::fs::create_dir_all(dir.join("captured")).unwrap();
    let mut poses = Vec::new();
    for t in 0..frames {
        let a = (0.5 * t as f64 + phase).sin();
        let b = (0.23 * t as f64 + 2.0 * phase).cos();
        poses.push(vec![0.5 - 0.05 * a, 0.0, 0.0, 0.8 * b, 0.0, 0.0]);
        let base = move |_: f64, x: f64| 0.07 + 0.01 * a * (6.0 * x).sin();
        let fine = tube(|phi, x| base(phi, x) + 0.004 * b * (5.0 * phi).sin() * (40.0 * x).cos());
        let name = format!("frame_{:04}.obj", t + 1);
        write_obj(&dir.join("gt").join(&name), &topo, &fine).unwrap();
        write_obj(&dir.join("captured").join(&name), &topo, &tube(base)).unwrap();
    }
    let doc = serde_json::json!({ "pose_vectors": poses });
    std::fs::write(dir.join("pose.json"), doc.to_string()).unwrap();
    dir
}

/// `crease deep train` flags and the `[deep.params]` table of the same tiny model (32² maps, a few steps).
const TRAIN_FLAGS: [&str; 16] = [
    "--k",
    "6",
    "--resolution",
    "32",
    "--cgan-steps",
    "2",
    "--cgan-depth",
    "3",
    "--cgan-crop",
    "16",
    "--cgan-filters",
    "4",
    "--cgan-disc-filters",
    "4",
    "--seed",
    "7",
];
const TRAIN_PARAMS: &str =
    "k = 6\nresolution = 32\ncgan_steps = 2\ncgan_depth = 3\ncgan_crop = 16\ncgan_filters = 4\ncgan_disc_filters = 4\nseed = 7\n";

fn crease(args: &[&str]) {
    let o = Command::new(bin()).args(args).output().unwrap();
    assert!(o.status.success(), "crease {args:?}: {}", stderr(&o));
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Every file under `dir` (relative path → bytes), except `report.json` (it holds timings) and the job's
/// hidden bookkeeping (`.crease-work/`).
fn tree(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    fn walk(root: &Path, dir: &Path, out: &mut BTreeMap<String, Vec<u8>>) {
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(root, &p, out);
            } else {
                let rel = p.strip_prefix(root).unwrap().to_string_lossy().into_owned();
                if rel != "report.json" && !rel.starts_with('.') {
                    out.insert(rel, std::fs::read(&p).unwrap());
                }
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(dir, dir, &mut out);
    out
}

fn manifest(dir: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(dir.join("manifest.json")).unwrap()).unwrap()
}

fn write_job(dir: &Path, name: &str, body: &str) -> PathBuf {
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, body).unwrap();
    path
}

#[test]
fn deep_jobs_on_two_workers_write_the_bytes_of_the_single_node_commands() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let a = training_dir(d, "a", 12, 0.0);
    let b = training_dir(d, "b", 12, 1.0);

    // Single node: the CLI.
    let ref_model = d.join("ref-model");
    let mut args = vec![
        "deep",
        "train",
        "--data",
        s(&a),
        s(&b),
        "--out",
        s(&ref_model),
        "--quiet",
    ];
    args.extend(TRAIN_FLAGS);
    crease(&args);
    let ref_pose = d.join("ref-pose");
    crease(&[
        "deep",
        "apply",
        "--model",
        s(&ref_model),
        "--pose",
        s(&a.join("pose.json")),
        "--out",
        s(&ref_pose),
        "--quiet",
    ]);
    let ref_coarse = d.join("ref-coarse");
    crease(&[
        "deep",
        "apply",
        "--model",
        s(&ref_model),
        "--coarse",
        s(&b.join("captured")),
        "--out",
        s(&ref_coarse),
        "--space",
        "tangent",
        "--quiet",
    ]);

    let c = Coordinator::start(d, &[]);
    let _w1 = c.worker("w-one", &[]);
    let _w2 = c.worker("w-two", &[]);

    // Training: one task; the model's files are the CLI's, byte for byte, and only the timings in the
    // manifest's free-form `training` section differ.
    let out_train = d.join("cluster-train");
    let job = write_job(
        d,
        "train",
        &format!(
            "input = \"{}\"\noutput = \"{}\"\n[deep]\ntask = \"train\"\ndata = [\"{}\"]\n[deep.params]\n{TRAIN_PARAMS}",
            s(&a),
            s(&out_train),
            s(&b)
        ),
    );
    let id = c.submit(&job);
    let st = c.wait_state(&id, &["done", "failed"]);
    assert_eq!(st["state"], "done", "{st}");
    let kinds: Vec<String> = tasks(&st)
        .iter()
        .map(|t| t["kind"].as_str().unwrap_or("").to_string())
        .collect();
    assert_eq!(kinds, ["deep-train"], "training is one task");
    let cluster_model = out_train.join("model");
    let (mut m_ref, mut m_cl) = (manifest(&ref_model), manifest(&cluster_model));
    assert_eq!(
        m_ref["files"], m_cl["files"],
        "same files, sizes and hashes"
    );
    assert!(m_ref["files"]["cgan.safetensors"].is_object());
    // The default regressor: the pose chunks below each read the poses of the frames before theirs (its
    // window); the autoregressive regressor the blend rolls out is stored too.
    assert_eq!(m_ref["regressor"], "kernel");
    assert!(m_ref["files"]["kernel_dual.npy"].is_object());
    assert!(m_ref["files"]["autoregressive.npy"].is_object());
    for (f, _) in m_ref["files"].as_object().unwrap() {
        assert!(
            std::fs::read(ref_model.join(f)).unwrap()
                == std::fs::read(cluster_model.join(f)).unwrap(),
            "{f} differs between crease deep train and the training job"
        );
    }
    m_ref.as_object_mut().unwrap().remove("training");
    m_cl.as_object_mut().unwrap().remove("training");
    assert_eq!(m_ref, m_cl);
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_train.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["complete"], true);

    // Apply from poses with the cluster-trained model, four frames per task: the bytes of `crease deep apply`
    // with the CLI-trained one.
    let out_pose = d.join("cluster-pose");
    let job = write_job(
        d,
        "apply-pose",
        &format!(
            "input = \"{}\"\noutput = \"{}\"\n[deep]\ntask = \"apply\"\nmodel = \"{}\"\nfrom = \"pose\"\n[partition]\nframes_per_chunk = 4\n",
            s(&a.join("pose.json")),
            s(&out_pose),
            s(&cluster_model)
        ),
    );
    let id = c.submit(&job);
    let st = c.wait_state(&id, &["done", "failed"]);
    assert_eq!(st["state"], "done", "{st}");
    let applies: Vec<serde_json::Value> = tasks(&st)
        .into_iter()
        .filter(|t| t["kind"] == "deep-apply")
        .collect();
    assert_eq!(applies.len(), 3, "12 frames in chunks of 4");
    let reference = tree(&ref_pose);
    assert_eq!(reference.len(), 25, "12 meshes, 12 maps, done.json");
    let got = tree(&out_pose);
    assert_eq!(
        reference.keys().collect::<Vec<_>>(),
        got.keys().collect::<Vec<_>>()
    );
    for (k, v) in &reference {
        assert!(
            v == &got[k],
            "{k} differs between crease deep apply and the job"
        );
    }

    // Apply to coarse meshes in tangent space, one frame per task so both workers take some.
    let out_coarse = d.join("cluster-coarse");
    let job = write_job(
        d,
        "apply-coarse",
        &format!(
            "input = \"{}\"\noutput = \"{}\"\n[deep]\ntask = \"apply\"\nmodel = \"{}\"\nfrom = \"coarse\"\nspace = \"tangent\"\n[partition]\nframes_per_chunk = 1\n",
            s(&b.join("captured")),
            s(&out_coarse),
            s(&ref_model)
        ),
    );
    let id = c.submit(&job);
    let st = c.wait_state(&id, &["done", "failed"]);
    assert_eq!(st["state"], "done", "{st}");
    let workers: std::collections::BTreeSet<String> = tasks(&st)
        .iter()
        .filter(|t| t["kind"] == "deep-apply")
        .map(|t| t["worker"].as_str().unwrap_or("").to_string())
        .collect();
    assert_eq!(
        workers.len(),
        2,
        "both workers ran frame chunks: {workers:?}"
    );
    assert_eq!(tree(&ref_coarse), tree(&out_coarse));

    // Bad inputs are refused at submit, naming the file: a half-written model (no manifest), a pose file of
    // another frame length, and a spec that mixes [deep] with [folds].
    let half = d.join("half-model");
    std::fs::create_dir_all(&half).unwrap();
    std::fs::copy(ref_model.join("basis.npy"), half.join("basis.npy")).unwrap();
    let refused = |name: &str, body: String, needles: &[&str]| {
        let job = write_job(d, name, &body);
        let o = c.cli(&["submit", s(&job)]);
        let err = stderr(&o);
        assert!(!o.status.success(), "{name} should be refused");
        for n in needles {
            assert!(
                err.contains(n),
                "{name}: the refusal should mention `{n}`: {err}"
            );
        }
    };
    refused(
        "half",
        format!(
            "input = \"{}\"\noutput = \"{}\"\n[deep]\ntask = \"apply\"\nmodel = \"{}\"\nfrom = \"pose\"\n",
            s(&a.join("pose.json")),
            s(&d.join("o-half")),
            s(&half)
        ),
        &["manifest.json", "not a complete"],
    );
    let short = d.join("short.json");
    std::fs::write(&short, r#"{"pose_vectors": [[0.5, 0.1], [0.5, 0.2]]}"#).unwrap();
    refused(
        "short",
        format!(
            "input = \"{}\"\noutput = \"{}\"\n[deep]\ntask = \"apply\"\nmodel = \"{}\"\nfrom = \"pose\"\n",
            s(&short),
            s(&d.join("o-short")),
            s(&ref_model)
        ),
        &["short.json", "2 numbers"],
    );
    refused(
        "mixed",
        format!(
            "input = \"{}\"\noutput = \"{}\"\n[folds]\nkind = \"stretch\"\n[deep]\ntask = \"train\"\n",
            s(&a),
            s(&d.join("o-mixed"))
        ),
        &["folds", "[deep]"],
    );
    assert!(!d.join("o-half").join("report.json").exists());
}

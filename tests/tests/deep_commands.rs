//! `crease deep train|apply` and `crease bake` end to end on tiny synthetic sleeves: the output layout
//! (meshes and normal maps), determinism, and bad inputs.
#![cfg(feature = "deep")]

use crease_core::mesh::io::write_obj;
use crease_core::mesh::Topology;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn tube_tris(na: usize, nr: usize) -> Vec<[u32; 3]> {
    let mut tris = Vec::new();
    for j in 0..nr - 1 {
        for i in 0..na {
            let i1 = (i + 1) % na;
            let (a, b, c, d) = (j * na + i, j * na + i1, (j + 1) * na + i1, (j + 1) * na + i);
            tris.push([a as u32, b as u32, c as u32]);
            tris.push([a as u32, c as u32, d as u32]);
        }
    }
    tris
}

fn tube(na: usize, nr: usize, radius: impl Fn(f64, f64) -> f64) -> Vec<[f64; 3]> {
    let mut p = Vec::new();
    for j in 0..nr {
        for i in 0..na {
            let phi = std::f64::consts::TAU * i as f64 / na as f64;
            let x = 0.5 * j as f64 / (nr - 1) as f64;
            let r = radius(phi, x);
            p.push([x, r * phi.cos(), r * phi.sin()]);
        }
    }
    p
}

const NA: usize = 24;
const NR: usize = 12;

/// A training directory: gt with pose-driven ripples, captured without them, pose.json.
fn training_dir(root: &Path, name: &str, frames: usize, phase: f64) -> PathBuf {
    let dir = root.join(name);
    let topo = Topology::new(NA * NR, tube_tris(NA, NR)).unwrap();
    std::fs::create_dir_all(dir.join("gt")).unwrap();
    std::fs::create_dir_all(dir.join("captured")).unwrap();
    let mut poses = Vec::new();
    for t in 0..frames {
        let a = (0.5 * t as f64 + phase).sin();
        let b = (0.23 * t as f64 + 2.0 * phase).cos();
        poses.push(vec![0.5 - 0.05 * a, 0.0, 0.0, 0.8 * b, 0.0, 0.0]);
        let base = move |_: f64, x: f64| 0.07 + 0.01 * a * (6.0 * x).sin();
        let fine = tube(NA, NR, |phi, x| {
            base(phi, x) + 0.004 * b * (5.0 * phi).sin() * (40.0 * x).cos()
        });
        let coarse = tube(NA, NR, base);
        write_obj(
            &dir.join("gt").join(format!("frame_{:04}.obj", t + 1)),
            &topo,
            &fine,
        )
        .unwrap();
        write_obj(
            &dir.join("captured").join(format!("frame_{:04}.obj", t + 1)),
            &topo,
            &coarse,
        )
        .unwrap();
    }
    let doc = serde_json::json!({ "pose_vectors": poses });
    std::fs::write(dir.join("pose.json"), doc.to_string()).unwrap();
    dir
}

fn run(args: &[&str]) -> Output {
    Command::new(crease_e2e::bin())
        .args(args)
        .arg("--quiet")
        .output()
        .unwrap()
}

fn ok(args: &[&str]) {
    let o = run(args);
    assert!(
        o.status.success(),
        "{args:?} failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

fn fails(args: &[&str], needles: &[&str]) {
    let o = run(args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{args:?} should fail");
    assert_eq!(
        o.status.code(),
        Some(1),
        "a clear error, not a panic: {err}"
    );
    for n in needles {
        assert!(
            err.contains(n),
            "error of {args:?} should mention `{n}`: {err}"
        );
    }
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn tree_bytes(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    for sub in ["mesh", "normals"] {
        let mut files: Vec<PathBuf> = std::fs::read_dir(dir.join(sub))
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        files.sort();
        for f in files {
            out.push((
                format!("{sub}/{}", f.file_name().unwrap().to_string_lossy()),
                std::fs::read(&f).unwrap(),
            ));
        }
    }
    out
}

#[test]
fn train_apply_writes_the_output_contract_deterministically() {
    let tmp = tempfile::tempdir().unwrap();
    let a = training_dir(tmp.path(), "a", 16, 0.0);
    let b = training_dir(tmp.path(), "b", 16, 1.0);
    let model = tmp.path().join("model");
    let train = [
        "deep",
        "train",
        "--data",
        s(&a),
        s(&b),
        "--out",
        s(&model),
        "--k",
        "6",
        "--regressor",
        "lstm",
        "--lstm-layers",
        "1",
        "--lstm-hidden",
        "8",
        "--lstm-epochs",
        "5",
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
    ];
    ok(&train);
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(model.join("manifest.json")).unwrap())
            .unwrap();
    assert_eq!(manifest["version"], 11);
    // The synthetic shapes are affine in the two pose numbers that move (a, b): the subspace keeps only
    // components with non-negligible variance, so k is capped at that rank.
    assert_eq!(manifest["k"], 2);
    assert!(manifest["files"]["cgan.safetensors"].is_object());
    assert!(manifest["files"]["lstm.safetensors"].is_object());
    // Retraining with the same seed gives the same model files.
    let model2 = tmp.path().join("model2");
    let mut again = train.to_vec();
    again[6] = s(&model2);
    ok(&again);
    for f in [
        "basis.npy",
        "linear.npy",
        "cgan.safetensors",
        "lstm.safetensors",
    ] {
        assert_eq!(
            std::fs::read(model.join(f)).unwrap(),
            std::fs::read(model2.join(f)).unwrap(),
            "{f} differs"
        );
    }

    // From pose, world space.
    let out = tmp.path().join("out-pose");
    ok(&[
        "deep",
        "apply",
        "--model",
        s(&model),
        "--pose",
        s(&a.join("pose.json")),
        "--out",
        s(&out),
    ]);
    let files = tree_bytes(&out);
    assert_eq!(files.len(), 32, "16 meshes and 16 maps");
    let obj = String::from_utf8(files[0].1.clone()).unwrap();
    assert_eq!(obj.lines().filter(|l| l.starts_with("v ")).count(), NA * NR);
    assert!(
        obj.lines().filter(|l| l.starts_with("vt ")).count() > NA * NR,
        "seams give extra vt"
    );
    let face = obj.lines().find(|l| l.starts_with("f ")).unwrap();
    assert!(
        face.split_whitespace().skip(1).all(|c| c.contains('/')),
        "faces are f v/vt: {face}"
    );
    let img = image::open(out.join("normals/frame_0001.png")).unwrap();
    assert_eq!(img.color(), image::ColorType::Rgba16);
    assert_eq!((img.width(), img.height()), (32, 32));
    assert!(out.join("done.json").exists());
    // Same inputs, same bytes.
    let out_again = tmp.path().join("out-pose-2");
    ok(&[
        "deep",
        "apply",
        "--model",
        s(&model),
        "--pose",
        s(&a.join("pose.json")),
        "--out",
        s(&out_again),
    ]);
    assert_eq!(tree_bytes(&out_again), files);

    // From coarse meshes, tangent space: the coarse map part is close to +z where the cGAN is not.
    let out_c = tmp.path().join("out-coarse");
    ok(&[
        "deep",
        "apply",
        "--model",
        s(&model),
        "--coarse",
        s(&b.join("captured")),
        "--out",
        s(&out_c),
        "--space",
        "tangent",
    ]);
    assert_eq!(tree_bytes(&out_c).len(), 32);
}

/// The vertices of an OBJ file.
fn obj_vertices(path: &Path) -> Vec<[f64; 3]> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter_map(|l| l.strip_prefix("v "))
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            [v[0], v[1], v[2]]
        })
        .collect()
}

#[test]
fn apply_rolls_out_the_autoregressive_regressor_and_uses_the_kernel_by_default() {
    let tmp = tempfile::tempdir().unwrap();
    let a = training_dir(tmp.path(), "a", 16, 0.0);
    let b = training_dir(tmp.path(), "b", 16, 1.0);
    let model = tmp.path().join("model");
    ok(&[
        "deep",
        "train",
        "--data",
        s(&a),
        s(&b),
        "--out",
        s(&model),
        "--k",
        "4",
        "--resolution",
        "16",
        "--ar-state",
        "3",
        // This test is about the regressors: their reconstruction as it is.
        "--pose-lowpass",
        "0",
        "--cgan-steps",
        "0",
    ]);
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(model.join("manifest.json")).unwrap())
            .unwrap();
    assert_eq!(manifest["regressor"], "kernel", "the default");
    assert_eq!(
        manifest["kernel"]["window"],
        serde_json::json!([0, 2, 4, 6])
    );
    assert_eq!(manifest["pose_lowpass"]["half_wavelength"], 0.0);
    assert_eq!(manifest["blend"]["weight"], 0.5);
    // k is capped at the data's rank (2), and the fed-back state at k.
    assert_eq!(manifest["autoregressive"]["k_state"], 2);
    assert!(manifest["files"]["autoregressive.npy"].is_object());

    let pose = a.join("pose.json");
    let apply = |name: &str, extra: &[&str]| -> PathBuf {
        let out = tmp.path().join(name);
        let mut args = vec![
            "deep",
            "apply",
            "--model",
            s(&model),
            "--pose",
            s(&pose),
            "--out",
            s(&out),
        ];
        args.extend(extra);
        ok(&args);
        out
    };
    let rolled = apply("out-ar", &["--regressor", "autoregressive"]);
    assert_eq!(
        tree_bytes(&rolled),
        tree_bytes(&apply("out-ar-2", &["--regressor", "autoregressive"])),
        "the rollout is deterministic"
    );
    let default = tree_bytes(&apply("out-default", &[]));
    assert_eq!(
        default,
        tree_bytes(&apply("out-kernel", &["--regressor", "kernel"])),
        "the default is the kernel regressor"
    );
    let blend = tree_bytes(&apply("out-blend", &["--regressor", "blend"]));
    assert_ne!(blend, tree_bytes(&rolled), "the blend is not the rollout");
    assert_ne!(default, blend, "the kernel is not the blend");
    // The rollout follows the training sequence's ripples (4 mm) and bulge (10 mm) from pose alone: far closer
    // to each frame than the training mean shape (the model's template.obj) is.
    let dist = |x: &[[f64; 3]], y: &[[f64; 3]]| -> f64 {
        assert_eq!(x.len(), y.len());
        x.iter()
            .zip(y)
            .map(|(p, q)| {
                ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
            })
            .sum::<f64>()
            / x.len() as f64
    };
    let mean_shape = obj_vertices(&model.join("template.obj"));
    let (mut e_rollout, mut e_mean) = (0.0, 0.0);
    for t in 1..=16 {
        let got = obj_vertices(&rolled.join(format!("mesh/frame_{t:04}.obj")));
        let gt = obj_vertices(&a.join(format!("gt/frame_{t:04}.obj")));
        e_rollout += dist(&got, &gt) / 16.0;
        e_mean += dist(&mean_shape, &gt) / 16.0;
    }
    assert!(
        e_rollout < 0.2 * e_mean,
        "mean vertex error {e_rollout} m; the mean shape's {e_mean} m"
    );

    // A model of format version 1 (its detail and smoothing were another capture's inverse) is refused by
    // version, with what to do about it, and nothing is written.
    let old = tmp.path().join("v1-model");
    std::fs::create_dir_all(&old).unwrap();
    let mut m = manifest.clone();
    let o = m.as_object_mut().unwrap();
    o.insert("version".into(), 1.into());
    o.insert("regressor".into(), "linear".into());
    o.remove("autoregressive");
    o.remove("blend");
    for f in o["files"].as_object().unwrap().keys() {
        std::fs::copy(model.join(f), old.join(f)).unwrap();
    }
    std::fs::write(old.join("manifest.json"), m.to_string()).unwrap();
    let out_old = tmp.path().join("out-v1");
    fails(
        &[
            "deep",
            "apply",
            "--model",
            s(&old),
            "--pose",
            s(&pose),
            "--out",
            s(&out_old),
        ],
        &["manifest.json", "version 1", "retrain"],
    );
    assert!(
        !out_old.exists(),
        "a refused model wrote {}",
        out_old.display()
    );
    // A blend weight that is not a weight is refused before anything is written.
    let bad = tmp.path().join("bad-blend");
    fails(
        &[
            "deep",
            "train",
            "--data",
            s(&a),
            "--out",
            s(&bad),
            "--blend-weight",
            "1.5",
        ],
        &["blend_weight", "1.5"],
    );
    assert!(!bad.exists());
}

#[test]
fn bake_turns_a_detailed_sequence_into_maps_on_the_coarse_one() {
    let tmp = tempfile::tempdir().unwrap();
    let a = training_dir(tmp.path(), "a", 3, 0.3);
    let out = tmp.path().join("baked");
    ok(&[
        "bake",
        "--coarse",
        s(&a.join("captured")),
        "--detailed",
        s(&a.join("gt")),
        "--out",
        s(&out),
        "--resolution",
        "64",
    ]);
    assert_eq!(tree_bytes(&out).len(), 6);
    let img = image::open(out.join("normals/frame_0002.png"))
        .unwrap()
        .to_rgba16();
    assert!(
        img.pixels().filter(|p| p[3] > 0).count() > 64 * 64 / 5,
        "maps cover the atlas"
    );
    // --uv must have texture coordinates.
    let plain = a.join("captured/frame_0001.obj");
    fails(
        &[
            "bake",
            "--coarse",
            s(&a.join("captured")),
            "--detailed",
            s(&a.join("gt")),
            "--out",
            s(&out),
            "--uv",
            s(&plain),
        ],
        &["frame_0001.obj", "vt"],
    );
    // A detailed sequence with another frame count.
    let short = training_dir(tmp.path(), "short", 2, 0.0);
    fails(
        &[
            "bake",
            "--coarse",
            s(&a.join("captured")),
            "--detailed",
            s(&short.join("gt")),
            "--out",
            s(&out),
        ],
        &["2 frames"],
    );
}

#[test]
fn bad_inputs_get_clear_errors_naming_file_frame_or_field() {
    let tmp = tempfile::tempdir().unwrap();
    let a = training_dir(tmp.path(), "a", 10, 0.0);
    let b = training_dir(tmp.path(), "b", 10, 1.0);
    let model = tmp.path().join("model");
    ok(&[
        "deep",
        "train",
        "--data",
        s(&a),
        s(&b),
        "--out",
        s(&model),
        "--k",
        "4",
        "--resolution",
        "32",
        "--cgan-steps",
        "0",
    ]);

    // Pose file with the wrong frame count for its meshes.
    let bad = training_dir(tmp.path(), "bad", 10, 0.5);
    let doc = serde_json::json!({ "pose_vectors": vec![vec![0.5, 0.0, 0.0, 0.0, 0.0, 0.0]; 9] });
    std::fs::write(bad.join("pose.json"), doc.to_string()).unwrap();
    fails(
        &[
            "deep",
            "train",
            "--data",
            s(&a),
            s(&bad),
            "--out",
            s(&tmp.path().join("m2")),
        ],
        &["pose.json", "9 pose vectors", "10 frames"],
    );
    assert!(
        !tmp.path().join("m2").exists(),
        "no model from a failed training"
    );

    // Eq. 4's weights and the learning rate are checked before anything is trained.
    for (flag, field) in [
        ("--cgan-w-gan=-1", "cgan.w_gan"),
        ("--cgan-w-l1=NaN", "cgan.w_l1"),
        ("--cgan-lr=0", "cgan.lr"),
    ] {
        let out = tmp.path().join(format!("m-{field}"));
        fails(
            &[
                "deep",
                "train",
                "--data",
                s(&a),
                s(&b),
                "--out",
                s(&out),
                "--resolution",
                "32",
                "--cgan-steps",
                "1",
                flag,
            ],
            &[field],
        );
        assert!(!out.exists(), "no model from a refused {flag}");
    }

    // NaN in a pose (as Python's json writes it).
    let text = std::fs::read_to_string(a.join("pose.json")).unwrap();
    let nan_pose = tmp.path().join("nan.json");
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["pose_vectors"][3][0] = serde_json::json!("__NAN__");
    std::fs::write(&nan_pose, v.to_string().replace("\"__NAN__\"", "NaN")).unwrap();
    fails(
        &[
            "deep",
            "apply",
            "--model",
            s(&model),
            "--pose",
            s(&nan_pose),
            "--out",
            s(&tmp.path().join("o1")),
        ],
        &["nan.json", "frame 4", "pose_vectors[3][0]"],
    );

    // Pose vectors of another length.
    let short_pose = tmp.path().join("short.json");
    std::fs::write(&short_pose, r#"{"pose_vectors": [[0.5, 0.1], [0.5, 0.2]]}"#).unwrap();
    fails(
        &[
            "deep",
            "apply",
            "--model",
            s(&model),
            "--pose",
            s(&short_pose),
            "--out",
            s(&tmp.path().join("o2")),
        ],
        &["short.json", "2 numbers", "6"],
    );

    // Coarse meshes of another topology.
    let other = tmp.path().join("other");
    std::fs::create_dir_all(&other).unwrap();
    let topo = Topology::new(NA * (NR - 1), tube_tris(NA, NR - 1)).unwrap();
    write_obj(
        &other.join("frame_0001.obj"),
        &topo,
        &tube(NA, NR - 1, |_, _| 0.07),
    )
    .unwrap();
    fails(
        &[
            "deep",
            "apply",
            "--model",
            s(&model),
            "--coarse",
            s(&other),
            "--out",
            s(&tmp.path().join("o3")),
        ],
        &["other", "do not match the model's topology"],
    );

    // A model from another format version.
    let old = tmp.path().join("old-model");
    std::fs::create_dir_all(&old).unwrap();
    for e in std::fs::read_dir(&model).unwrap() {
        let p = e.unwrap().path();
        std::fs::copy(&p, old.join(p.file_name().unwrap())).unwrap();
    }
    let m = std::fs::read_to_string(old.join("manifest.json"))
        .unwrap()
        .replace("\"version\": 11", "\"version\": 99");
    std::fs::write(old.join("manifest.json"), m).unwrap();
    fails(
        &[
            "deep",
            "apply",
            "--model",
            s(&old),
            "--pose",
            s(&a.join("pose.json")),
            "--out",
            s(&tmp.path().join("o4")),
        ],
        &["manifest.json", "version 99", "versions 9 to 11"],
    );

    // A half-written model (no manifest) is not a model; a damaged file is caught by the manifest.
    std::fs::remove_file(old.join("manifest.json")).unwrap();
    fails(
        &[
            "deep",
            "apply",
            "--model",
            s(&old),
            "--pose",
            s(&a.join("pose.json")),
            "--out",
            s(&tmp.path().join("o5")),
        ],
        &["manifest.json", "not a complete"],
    );
    let damaged = tmp.path().join("damaged");
    std::fs::create_dir_all(&damaged).unwrap();
    for e in std::fs::read_dir(&model).unwrap() {
        let p = e.unwrap().path();
        std::fs::copy(&p, damaged.join(p.file_name().unwrap())).unwrap();
    }
    let mut bytes = std::fs::read(damaged.join("linear.npy")).unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 0x55;
    std::fs::write(damaged.join("linear.npy"), bytes).unwrap();
    fails(
        &[
            "deep",
            "apply",
            "--model",
            s(&damaged),
            "--pose",
            s(&a.join("pose.json")),
            "--out",
            s(&tmp.path().join("o6")),
        ],
        &["linear.npy", "does not match the model manifest"],
    );

    // --uv without texture coordinates.
    fails(
        &[
            "deep",
            "train",
            "--data",
            s(&a),
            "--out",
            s(&tmp.path().join("m3")),
            "--uv",
            s(&a.join("gt/frame_0001.obj")),
        ],
        &["frame_0001.obj", "vt", "--uv"],
    );
}

//! The mesh-space detail filter in a trained model: `apply --coarse` draws the normals of the captured mesh's
//! predicted fine shape, which on an unseen motion must be closer to the fine surface than the captured mesh's
//! own map; models without the filter (format 5) keep writing the plain coarse maps; a damaged filter is named.

mod support;

use crease_core::mesh::geometry::vertex_normals;
use crease_core::progress::NoProgress;
use crease_core::shape::TaubinFilter;
use crease_core::vec3::V3;
use crease_deep::apply::{apply, ApplyInput, ApplyParams};
use crease_deep::model::{Model, MODEL_VERSION};
use crease_deep::normal_maps::bake::map_normal_error;
use crease_deep::normal_maps::raster::TexelMap;
use crease_deep::normal_maps::{bake_coarse, sample_vertex_normals, NormalMap};
use crease_deep::train::{train, TrainParams, TrainingSequence};
use std::path::Path;

const NA: usize = 32;
const NR: usize = 40;

/// A tube whose folds (about six edges long, along and around it) move and change amplitude with `t`; the
/// coarse frames are the data's capture filter of the fine ones, as in sleeve-train.
fn sequence(dir: &Path, frames: usize, seed: f64) -> TrainingSequence {
    let (topo, _) = support::tube(NA, NR, |_, _| 0.07);
    let capture = TaubinFilter::capture(&topo);
    let (mut fine, mut coarse, mut poses) = (Vec::new(), Vec::new(), Vec::new());
    for t in 0..frames {
        let s = 0.37 * t as f64 + seed;
        let (a1, a2) = (s.sin(), (1.3 * s + 0.5).cos());
        let h = 0.5 / (NR - 1) as f64;
        let f = support::tube(NA, NR, |phi, x| {
            0.07 + 0.003 * a1 * (std::f64::consts::TAU * x / (6.0 * h) + 2.0 * s).sin()
                + 0.002 * a2 * (5.0 * phi + s).cos()
        })
        .1;
        coarse.push(capture.apply(&f));
        fine.push(f);
        poses.push(vec![a1, a2]);
    }
    std::fs::create_dir_all(dir).unwrap();
    let doc = serde_json::json!({ "pose_vectors": poses });
    std::fs::write(dir.join("pose.json"), doc.to_string()).unwrap();
    TrainingSequence {
        dir: dir.to_path_buf(),
        topology: topo,
        fine,
        coarse,
        poses,
        pose_names: None,
    }
}

/// Every file under `dir/mesh` and `dir/normals` (temporary files included), by name.
fn read_tree(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    for sub in ["mesh", "normals"] {
        let mut files: Vec<_> = std::fs::read_dir(dir.join(sub))
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        files.sort();
        for f in files {
            let name = f.file_name().unwrap().to_string_lossy().into_owned();
            out.push((format!("{sub}/{name}"), std::fs::read(&f).unwrap()));
        }
    }
    out
}

fn write_pc2(path: &Path, frames: &[Vec<V3>]) {
    let mut b = Vec::new();
    b.extend_from_slice(b"POINTCACHE2\0");
    b.extend_from_slice(&1i32.to_le_bytes());
    b.extend_from_slice(&(frames[0].len() as i32).to_le_bytes());
    b.extend_from_slice(&1f32.to_le_bytes());
    b.extend_from_slice(&1f32.to_le_bytes());
    b.extend_from_slice(&(frames.len() as i32).to_le_bytes());
    for f in frames {
        for p in f {
            for c in p {
                b.extend_from_slice(&(*c as f32).to_le_bytes());
            }
        }
    }
    std::fs::write(path, b).unwrap();
}

/// `dir/mesh.obj` + `dir/frames.pc2`, the layout `crease deep apply --coarse` reads. Returns the frames as
/// they read back (f32).
fn write_sequence(dir: &Path, seq: &TrainingSequence, frames: &[Vec<V3>]) -> Vec<Vec<V3>> {
    std::fs::create_dir_all(dir).unwrap();
    let mut obj = String::new();
    for p in &frames[0] {
        obj.push_str(&format!(
            "v {} {} {}\n",
            p[0] as f32, p[1] as f32, p[2] as f32
        ));
    }
    for t in seq.topology.triangles() {
        obj.push_str(&format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1));
    }
    std::fs::write(dir.join("mesh.obj"), obj).unwrap();
    write_pc2(&dir.join("frames.pc2"), frames);
    frames
        .iter()
        .map(|f| {
            f.iter()
                .map(|p| p.map(|c| c as f32 as f64))
                .collect::<Vec<_>>()
        })
        .collect()
}

/// Mean DESIGN §9 normal error of the written maps against `fine`.
fn map_error(out: &Path, model: &Model, fine: &[Vec<V3>]) -> f64 {
    fine.iter()
        .enumerate()
        .map(|(t, f)| {
            let map =
                NormalMap::read_png(&out.join(format!("normals/frame_{:04}.png", t + 1))).unwrap();
            map_normal_error(
                &sample_vertex_normals(&map, &model.topology, &model.layout),
                &model.topology,
                f,
            )
            .0
        })
        .sum::<f64>()
        / fine.len() as f64
}

fn params() -> TrainParams {
    TrainParams {
        k: 4,
        resolution: 128,
        ..Default::default()
    }
}

#[test]
fn apply_coarse_draws_the_predicted_folds_and_beats_the_captured_map() {
    let tmp = tempfile::tempdir().unwrap();
    let seqs = vec![
        sequence(&tmp.path().join("a"), 10, 0.0),
        sequence(&tmp.path().join("b"), 10, 2.1),
    ];
    let model_dir = tmp.path().join("model");
    train(&seqs, &params(), &model_dir, &NoProgress).unwrap();
    let model = Model::load(&model_dir).unwrap();
    assert_eq!(model.manifest.version, MODEL_VERSION);
    assert_eq!(MODEL_VERSION, 8);
    let spec = model.manifest.detail.clone().expect("a detail filter");
    // The filter explains most of what the capture removed on its own training frames.
    assert!(
        spec.train_mse_after < 0.2 * spec.train_mse_before,
        "{spec:?}"
    );

    // An unseen motion: other phases and amplitudes.
    let held = sequence(&tmp.path().join("held"), 6, 4.4);
    let coarse = write_sequence(&tmp.path().join("held/captured"), &held, &held.coarse);
    let out = tmp.path().join("out");
    apply(
        &model,
        &ApplyInput::Coarse(tmp.path().join("held/captured")),
        &ApplyParams::default(),
        &out,
        &NoProgress,
    )
    .unwrap();
    let detailed = map_error(&out, &model, &held.fine);
    // Frames run in parallel when there are threads: one thread or three, the same files byte for byte.
    let trees: Vec<Vec<(String, Vec<u8>)>> = [1usize, 3]
        .iter()
        .map(|&threads| {
            let dir = tmp.path().join(format!("out-{threads}-threads"));
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| {
                    apply(
                        &model,
                        &ApplyInput::Coarse(tmp.path().join("held/captured")),
                        &ApplyParams::default(),
                        &dir,
                        &NoProgress,
                    )
                })
                .unwrap();
            assert!(dir.join("done.json").exists());
            read_tree(&dir)
        })
        .collect();
    assert_eq!(trees[0].len(), 12, "6 frames, 2 files each, nothing else");
    assert_eq!(trees[0], trees[1]);
    assert_eq!(trees[0], read_tree(&out));
    // What the captured mesh's own map scores (what apply wrote before the filter).
    let texels = TexelMap::new(&model.layout, 128, 128);
    let plain = coarse
        .iter()
        .zip(&held.fine)
        .map(|(c, f)| {
            let m = bake_coarse(&texels, &model.topology, c);
            map_normal_error(
                &sample_vertex_normals(&m, &model.topology, &model.layout),
                &model.topology,
                f,
            )
            .0
        })
        .sum::<f64>()
        / coarse.len() as f64;
    let mesh = coarse
        .iter()
        .zip(&held.fine)
        .map(|(c, f)| crease_deep::normal_maps::bake::mesh_normal_error(&model.topology, c, f))
        .sum::<f64>()
        / coarse.len() as f64;
    eprintln!("held-out normal error: captured mesh {mesh:.2}°, its map {plain:.2}°, detail map {detailed:.2}°");
    assert!(
        plain > 1.0,
        "the capture must have removed visible folds ({plain:.2}°)"
    );
    assert!(
        detailed < 0.5 * plain && detailed < mesh,
        "detail map {detailed:.2}° against the captured map {plain:.2}° and mesh {mesh:.2}°"
    );
    // The output mesh is still the coarse one (the filter moves only the normals).
    let (_, written, _) =
        crease_deep::normal_maps::uv::read_obj_mesh(&out.join("mesh/frame_0001.obj")).unwrap();
    for (a, b) in written.iter().zip(&coarse[0]) {
        for k in 0..3 {
            assert!((a[k] - b[k]).abs() < 1e-6);
        }
    }
    // The fine normals the filter predicts, not the map sampling, carry the gain.
    let f0 = model.detail.as_ref().unwrap().apply(
        &crease_deep::detail::Umbrella::new(&model.topology),
        &coarse[0],
    );
    assert_eq!(vertex_normals(&model.topology, &f0).len(), f0.len());

    // A format 5 model (no filter) still loads and writes the captured mesh's own maps.
    let manifest_path = model_dir.join("manifest.json");
    let mut manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&manifest_path).unwrap()).unwrap();
    manifest["version"] = 5.into();
    manifest.as_object_mut().unwrap().remove("detail");
    std::fs::write(&manifest_path, manifest.to_string()).unwrap();
    let old = Model::load(&model_dir).unwrap();
    assert!(old.detail.is_none());
    let out5 = tmp.path().join("out5");
    apply(
        &old,
        &ApplyInput::Coarse(tmp.path().join("held/captured")),
        &ApplyParams::default(),
        &out5,
        &NoProgress,
    )
    .unwrap();
    let again = map_error(&out5, &old, &held.fine);
    assert!((again - plain).abs() < 0.05, "{again} vs {plain}");
}

#[test]
fn a_damaged_detail_filter_is_refused_naming_its_file() {
    let tmp = tempfile::tempdir().unwrap();
    let seqs = vec![
        sequence(&tmp.path().join("a"), 5, 0.0),
        sequence(&tmp.path().join("b"), 5, 1.0),
    ];
    let model_dir = tmp.path().join("model");
    train(&seqs, &params(), &model_dir, &NoProgress).unwrap();
    // A degree that does not fit the stored weights.
    let manifest_path = model_dir.join("manifest.json");
    let mut manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&manifest_path).unwrap()).unwrap();
    let degree = manifest["detail"]["degree"].as_u64().unwrap();
    manifest["detail"]["degree"] = (degree + 1).into();
    std::fs::write(&manifest_path, manifest.to_string()).unwrap();
    let e = Model::load(&model_dir).err().unwrap().to_string();
    assert!(e.contains("detail.npy") && e.contains("degree"), "{e}");
    // Restored degree, damaged bytes: the manifest's hash names the file.
    manifest["detail"]["degree"] = degree.into();
    std::fs::write(&manifest_path, manifest.to_string()).unwrap();
    let npy = model_dir.join("detail.npy");
    let mut bytes = std::fs::read(&npy).unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 0x40;
    std::fs::write(&npy, bytes).unwrap();
    let e = Model::load(&model_dir).err().unwrap().to_string();
    assert!(e.contains("detail.npy"), "{e}");
}

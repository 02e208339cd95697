//! The pose-only shape's low-pass in a trained model: `apply --pose` writes the diffused reconstruction, which
//! on an unseen motion whose folds the pose does not determine has a lower normal error than the
//! reconstruction as it is; a half wavelength of 0 is the reconstruction itself; a manifest without the field,
//! or with a bad one, is refused naming it.

mod support;

use crease_core::mesh::geometry::vertex_normals;
use crease_core::progress::NoProgress;
use crease_core::vec3::{self, V3};
use crease_deep::apply::{apply, pose_shapes, shapes_from_poses, ApplyInput, ApplyParams};
use crease_deep::detail::captures::frequency_of;
use crease_deep::detail::operator::Walk;
use crease_deep::model::{Model, RegressorKind};
use crease_deep::regression::pose_lowpass::PoseLowpass;
use crease_deep::train::{train, TrainParams, TrainingSequence};
use std::path::Path;

const NA: usize = 32;
const NR: usize = 40;

/// A tube with a bulge the pose drives (predictable) and folds about six edges long whose phase jumps from
/// frame to frame independently of the pose (what the pose cannot tell: in sleeve-train, where along the arm
/// the cloth bunches).
fn sequence(dir: &Path, frames: usize, seed: f64) -> TrainingSequence {
    let h = 0.5 / (NR - 1) as f64;
    let (mut fine, mut poses) = (Vec::new(), Vec::new());
    let mut topo = None;
    for t in 0..frames {
        let s = 0.31 * t as f64 + seed;
        let a = s.sin();
        // A fixed pseudo-random phase per frame (golden-ratio sequence), unrelated to a.
        let phase = std::f64::consts::TAU * ((t as f64 + 7.0 * seed) * 0.618_034).fract();
        let (tp, f) = support::tube(NA, NR, |phi, x| {
            0.07 + 0.006 * a * (std::f64::consts::PI * x / 0.5).sin() * (1.0 + 0.3 * phi.cos())
                + 0.0025 * (std::f64::consts::TAU * x / (6.0 * h) + phase).sin()
        });
        topo.get_or_insert(tp);
        fine.push(f);
        poses.push(vec![a, 0.5 * a * a]);
    }
    let topology = topo.unwrap();
    std::fs::create_dir_all(dir).unwrap();
    let doc = serde_json::json!({ "pose_vectors": poses });
    std::fs::write(dir.join("pose.json"), doc.to_string()).unwrap();
    TrainingSequence {
        dir: dir.to_path_buf(),
        topology,
        fine,
        poses,
        pose_names: None,
    }
}

const LOWPASS: PoseLowpass = PoseLowpass {
    components: 0,
    half_wavelength: 8.0,
};

fn params() -> TrainParams {
    TrainParams {
        k: 16,
        resolution: 64,
        pose_lowpass: LOWPASS,
        regressor: RegressorKind::Blend,
        ..Default::default()
    }
}

fn normal_error(topo: &crease_core::mesh::Topology, a: &[Vec<V3>], b: &[Vec<V3>]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| {
            let (nx, ny) = (vertex_normals(topo, x), vertex_normals(topo, y));
            nx.iter()
                .zip(&ny)
                .map(|(p, q)| vec3::dot(*p, *q).clamp(-1.0, 1.0).acos().to_degrees())
                .sum::<f64>()
                / nx.len() as f64
        })
        .sum::<f64>()
        / a.len() as f64
}

fn edit_manifest(src: &Path, dst: &Path, edit: impl Fn(&mut serde_json::Value)) {
    std::fs::create_dir_all(dst).unwrap();
    for e in std::fs::read_dir(src).unwrap() {
        let p = e.unwrap().path();
        std::fs::copy(&p, dst.join(p.file_name().unwrap())).unwrap();
    }
    let mut m: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dst.join("manifest.json")).unwrap()).unwrap();
    edit(&mut m);
    std::fs::write(dst.join("manifest.json"), m.to_string()).unwrap();
}

#[test]
fn apply_pose_writes_the_smoothed_shape_and_its_normals_are_closer_to_the_truth() {
    let tmp = tempfile::tempdir().unwrap();
    let seqs = vec![
        sequence(&tmp.path().join("a"), 24, 0.0),
        sequence(&tmp.path().join("b"), 24, 1.7),
    ];
    let held = sequence(&tmp.path().join("c"), 24, 3.1);
    let dir = tmp.path().join("model");
    train(&seqs, &params(), &dir, &NoProgress).unwrap();
    let model = Model::load(&dir).unwrap();
    assert_eq!(model.manifest.pose_lowpass, LOWPASS);

    let pose = held.dir.join("pose.json");
    let raw = shapes_from_poses(&model, &pose, RegressorKind::Blend).unwrap();
    let smooth = pose_shapes(&model, &pose, RegressorKind::Blend, None).unwrap();
    // The smoothed shape is the mean plus the cotangent diffusion of the reconstruction's departure from it,
    // computed here on its own.
    let mean = crease_deep::subspace::unflatten(&model.subspace.mean);
    for (s, r) in smooth.iter().zip(&raw) {
        let t = 1.0 / frequency_of(LOWPASS.half_wavelength);
        let d: Vec<V3> = r
            .iter()
            .zip(&mean)
            .map(|(p, m)| vec3::sub(*p, *m))
            .collect();
        let e = Walk::cotangent(&model.topology, r).diffuse(&d, t);
        let want: Vec<V3> = mean
            .iter()
            .zip(&e)
            .map(|(m, x)| vec3::add(*m, *x))
            .collect();
        assert_eq!(s, &want);
    }
    // The folds in the reconstruction are other frames' folds: without them the normals are closer to the
    // truth's. The shape keeps its predicted bulge: the vertex error grows only by part of the folds' own size.
    let (e_raw, e_smooth) = (
        normal_error(&model.topology, &raw, &held.fine),
        normal_error(&model.topology, &smooth, &held.fine),
    );
    let (v_raw, v_smooth) = (
        support::mean_vertex_error(&raw, &held.fine),
        support::mean_vertex_error(&smooth, &held.fine),
    );
    eprintln!(
        "normal error {e_raw:.2}° → {e_smooth:.2}°, vertex error {v_raw:.2e} → {v_smooth:.2e} m"
    );
    assert!(e_smooth < e_raw - 0.2, "{e_raw} → {e_smooth}");
    assert!(v_smooth < 1.25 * v_raw, "{v_raw} → {v_smooth}");

    // apply writes that shape: the OBJ's vertices are the smoothed ones (to the file's precision), and a frame
    // range smooths only its own frames but writes the same bytes as the full run.
    let full = tmp.path().join("full");
    let input = ApplyInput::Pose(pose.clone());
    apply(&model, &input, &ApplyParams::default(), &full, &NoProgress).unwrap();
    let (_, written, _) =
        crease_deep::normal_maps::uv::read_obj_mesh(&full.join("mesh/frame_0005.obj")).unwrap();
    let worst = written
        .iter()
        .zip(&smooth[4])
        .map(|(a, b)| vec3::norm(vec3::sub(*a, *b)))
        .fold(0.0, f64::max);
    assert!(worst < 1e-5, "{worst}");
    let part = tmp.path().join("part");
    let chunk = ApplyParams {
        frames: Some(3..6),
        ..Default::default()
    };
    apply(&model, &input, &chunk, &part, &NoProgress).unwrap();
    for f in ["mesh/frame_0005.obj", "normals/frame_0005.png"] {
        assert_eq!(
            std::fs::read(full.join(f)).unwrap(),
            std::fs::read(part.join(f)).unwrap(),
            "{f}"
        );
    }
}

#[test]
fn no_low_pass_is_the_reconstruction_and_bad_fields_are_named() {
    let tmp = tempfile::tempdir().unwrap();
    let seqs = vec![
        sequence(&tmp.path().join("a"), 12, 0.0),
        sequence(&tmp.path().join("b"), 12, 1.7),
    ];
    let dir = tmp.path().join("model");
    train(&seqs, &params(), &dir, &NoProgress).unwrap();
    let pose = seqs[1].dir.join("pose.json");
    // A half wavelength of 0 and all components is the reconstruction itself.
    let off = tmp.path().join("off");
    edit_manifest(&dir, &off, |m| {
        m["pose_lowpass"]["half_wavelength"] = 0.0.into()
    });
    let m = Model::load(&off).unwrap();
    assert_eq!(
        pose_shapes(&m, &pose, RegressorKind::Linear, None).unwrap(),
        shapes_from_poses(&m, &pose, RegressorKind::Linear).unwrap()
    );

    let err = |d: &Path| Model::load(d).err().expect("refused").to_string();
    let missing = tmp.path().join("missing");
    edit_manifest(&dir, &missing, |m| {
        m.as_object_mut().unwrap().remove("pose_lowpass");
    });
    let e = err(&missing);
    assert!(
        e.contains("manifest.json") && e.contains("pose_lowpass"),
        "{e}"
    );
    let huge = tmp.path().join("huge");
    edit_manifest(&dir, &huge, |m| {
        m["pose_lowpass"]["half_wavelength"] = 1e6.into()
    });
    let e = err(&huge);
    assert!(
        e.contains("manifest.json") && e.contains("pose_lowpass"),
        "{e}"
    );

    // The training parameter is checked before anything is written.
    let bad = TrainParams {
        pose_lowpass: PoseLowpass {
            components: 0,
            half_wavelength: 1e6,
        },
        ..params()
    };
    let out = tmp.path().join("bad");
    let e = train(&seqs, &bad, &out, &NoProgress)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("pose_lowpass"), "{e}");
    assert!(!out.exists());
}

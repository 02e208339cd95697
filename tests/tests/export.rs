#![allow(clippy::needless_range_loop)]
//! `crease export` writes files the DCCs and engines read: GLB that Khronos' glTF-Validator passes, USD that
//! Pixar's USD opens with the OBJ's points, and MDD/PC2 point caches that read back frame for frame. Texture
//! coordinates travel end to end: a UV'd tube with a seam, through `crease run` (subdivided) and `crease
//! export`, into GLB's `TEXCOORD_0` and USD's `primvars:st`.

use crease_e2e::tools;

use crease_core::mesh::io::{open_sequence, read_pc2_header, read_pc2_sample_from};
use crease_e2e::{fixture, stderr};
use std::path::{Path, PathBuf};
use std::process::Command;

fn export(input: &Path, format: &str, out: &Path) -> std::process::Output {
    Command::new(crease_e2e::bin())
        .args([
            "export",
            "--input",
            input.to_str().unwrap(),
            "--format",
            format,
        ])
        .args(["--out", out.to_str().unwrap(), "--quiet"])
        .output()
        .unwrap()
}

/// The fixture's frames, as the f32 every format stores.
fn frames_f32(input: &Path) -> Vec<Vec<[f32; 3]>> {
    let s = open_sequence(input).unwrap();
    (0..s.source.n_frames())
        .map(|t| {
            s.source
                .read_frame(t)
                .unwrap()
                .iter()
                .map(|p| [p[0] as f32, p[1] as f32, p[2] as f32])
                .collect()
        })
        .collect()
}

/// Khronos' validator report for a .glb.
pub fn validate_gltf(glb: &Path) -> serde_json::Value {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/validate_gltf.js");
    let o = Command::new(tools::tool("node"))
        .arg(script)
        .arg(glb)
        .env("NODE_PATH", tools::node_modules())
        .output()
        .unwrap();
    assert!(o.status.success(), "gltf-validator: {}", stderr(&o));
    serde_json::from_slice(&o.stdout).unwrap()
}

/// USD's view of a .usda at the given time codes.
pub fn read_usd(usda: &Path, times: &[&str]) -> serde_json::Value {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/read_usd.py");
    let o = Command::new(tools::python())
        .arg(script)
        .arg(usda)
        .args(times)
        .output()
        .unwrap();
    assert!(o.status.success(), "usd-core: {}", stderr(&o));
    serde_json::from_slice(&o.stdout).unwrap()
}

fn out_dir() -> (tempfile::TempDir, PathBuf) {
    let d = tempfile::tempdir().unwrap();
    let p = d.path().to_path_buf();
    (d, p)
}

#[test]
fn glb_passes_khronos_gltf_validator_with_no_errors() {
    let (_d, dir) = out_dir();
    let glb = dir.join("sleeve.glb");
    let o = export(&fixture(), "glb", &glb);
    assert!(o.status.success(), "{}", stderr(&o));
    let report = validate_gltf(&glb);
    std::fs::write(dir.join("validator.json"), report.to_string()).unwrap();
    let issues = &report["issues"];
    assert_eq!(
        issues["numErrors"], 0,
        "validator errors: {}",
        issues["messages"]
    );
    // It is the animated mesh: 4 frames = base + 3 morph targets, one animation.
    let info = &report["info"];
    assert_eq!(info["hasMorphTargets"], true, "{info}");
    assert_eq!(info["animationCount"], 1, "{info}");
    let n = frames_f32(&fixture())[0].len() as u64;
    assert_eq!(info["totalVertexCount"], n, "{info}");
}

#[test]
fn usd_opens_in_pixar_usd_with_the_obj_points() {
    let (_d, dir) = out_dir();
    let usda = dir.join("sleeve.usda");
    let o = export(&fixture(), "usd", &usda);
    assert!(o.status.success(), "{}", stderr(&o));
    let frames = frames_f32(&fixture());
    let usd = read_usd(&usda, &["1", "3", "4"]);
    assert_eq!(usd["start"], 1.0);
    assert_eq!(usd["end"], frames.len() as f64);
    assert_eq!(usd["fps"], 30.0);
    assert_eq!(usd["up"], "Z");
    assert_eq!(usd["samples"], frames.len());
    for (code, t) in [("1", 0), ("3", 2), ("4", 3)] {
        let f = &usd["frames"][code];
        let pts = f["points"].as_array().unwrap();
        assert_eq!(pts.len(), frames[t].len());
        for (v, p) in pts.iter().enumerate() {
            for c in 0..3 {
                let got = p[c].as_f64().unwrap() as f32;
                assert_eq!(got, frames[t][v][c], "time {code} vertex {v}");
            }
        }
        assert_eq!(f["normals"], frames[t].len());
        assert_eq!(f["normals_interpolation"], "vertex");
    }
}

#[test]
fn mdd_and_pc2_read_back_frame_for_frame() {
    let (_d, dir) = out_dir();
    let frames = frames_f32(&fixture());
    let pc2 = dir.join("sleeve.pc2");
    let o = export(&fixture(), "pc2", &pc2);
    assert!(o.status.success(), "{}", stderr(&o));
    let h = read_pc2_header(&pc2).unwrap();
    assert_eq!(
        (h.num_samples, h.num_points),
        (frames.len(), frames[0].len())
    );
    let mut f = std::fs::File::open(&pc2).unwrap();
    for (t, want) in frames.iter().enumerate() {
        let got = read_pc2_sample_from(&pc2, &mut f, &h, t).unwrap();
        let got: Vec<[f32; 3]> = got
            .iter()
            .map(|p| [p[0] as f32, p[1] as f32, p[2] as f32])
            .collect();
        assert_eq!(&got, want, "pc2 frame {t}");
    }
    let mdd = dir.join("sleeve.mdd");
    let o = export(&fixture(), "mdd", &mdd);
    assert!(o.status.success(), "{}", stderr(&o));
    let b = std::fs::read(&mdd).unwrap();
    let be = |at: usize| <[u8; 4]>::try_from(&b[at..at + 4]).unwrap();
    let (n, v) = (
        i32::from_be_bytes(be(0)) as usize,
        i32::from_be_bytes(be(4)) as usize,
    );
    assert_eq!((n, v), (frames.len(), frames[0].len()));
    assert_eq!(b.len(), 8 + 4 * n + 12 * n * v);
    assert_eq!(f32::from_be_bytes(be(8 + 4)), 1.0 / 30.0);
    for (t, want) in frames.iter().enumerate() {
        for (i, p) in want.iter().enumerate() {
            for c in 0..3 {
                let at = 8 + 4 * n + (t * v + i) * 12 + c * 4;
                assert_eq!(f32::from_be_bytes(be(at)), p[c], "mdd frame {t} vertex {i}");
            }
        }
    }
}

#[test]
fn bad_export_requests_are_named_and_write_nothing() {
    let (_d, dir) = out_dir();
    let o = export(&fixture(), "fbx", &dir.join("a.fbx"));
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("unknown export format `fbx`"),
        "{}",
        stderr(&o)
    );
    let o = export(&dir.join("missing"), "glb", &dir.join("a.glb"));
    assert!(!o.status.success());
    assert!(stderr(&o).contains("missing"), "{}", stderr(&o));
    let o = Command::new(crease_e2e::bin())
        .args([
            "export",
            "--input",
            fixture().to_str().unwrap(),
            "--format",
            "usd",
        ])
        .args(["--out", dir.join("a.usda").to_str().unwrap(), "--fps", "0"])
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(stderr(&o).contains("`fps`"), "{}", stderr(&o));
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
}

/// The UV tube (synthetic, with a seam) written as OBJ frames with `vt` and `f v/vt`.
fn uv_tube_input(dir: &Path) -> (PathBuf, crease_core::mesh::Sequence) {
    let seq = crease_core::synth::uv_tube(12, 8, 4).unwrap();
    let input = dir.join("uv-in");
    crease_core::synth::write_frames(&input, &seq).unwrap();
    (input, seq)
}

/// OBJ's texture coordinate of every triangle corner of a sequence's topology.
fn corner_uvs(seq_topo: &crease_core::mesh::Topology) -> Vec<[f32; 2]> {
    let uvs = seq_topo
        .uvs()
        .expect("the sequence has texture coordinates");
    uvs.corners()
        .iter()
        .flatten()
        .map(|&k| uvs.uv()[k as usize])
        .collect()
}

#[test]
fn uvs_run_through_a_subdivided_run_into_glb_and_usd() {
    let (_d, dir) = out_dir();
    let (input, seq) = uv_tube_input(&dir);
    // `crease run --folds stretch --subdivide 1`: the output OBJ frames carry the subdivided UVs.
    let out = dir.join("out");
    let o = Command::new(crease_e2e::bin())
        .args([
            "run",
            "--input",
            input.to_str().unwrap(),
            "--folds",
            "stretch",
        ])
        .args([
            "--subdivide",
            "1",
            "--out",
            out.to_str().unwrap(),
            "--quiet",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let opened = open_sequence(&out).unwrap();
    let topo = opened.source.topology().clone();
    assert_eq!(topo.n_triangles(), 4 * seq.topology.n_triangles());
    let fine = corner_uvs(&topo);
    let coarse = corner_uvs(&seq.topology);
    // Corner a of child 0 of each coarse triangle is the coarse corner a; the middle child's corners are
    // the midpoints of the coarse triangle's corner coordinates, on each side of the seam.
    for t in 0..seq.topology.n_triangles() {
        assert_eq!(fine[12 * t], coarse[3 * t], "triangle {t}");
        let mid = |i: usize, j: usize| {
            let (p, q) = (coarse[3 * t + i], coarse[3 * t + j]);
            [0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1])]
        };
        assert_eq!(fine[12 * t + 9], mid(0, 1), "triangle {t}");
        assert_eq!(fine[12 * t + 10], mid(1, 2), "triangle {t}");
        assert_eq!(fine[12 * t + 11], mid(2, 0), "triangle {t}");
    }
    // Some corner has u = 1 (the seam's far side) and its own vertex also appears with u = 0.
    assert!(fine.iter().any(|c| c[0] == 1.0) && fine.iter().any(|c| c[0] == 0.0));

    let glb = dir.join("uv.glb");
    let o = export(&out, "glb", &glb);
    assert!(o.status.success(), "{}", stderr(&o));
    let report = validate_gltf(&glb);
    std::fs::write(dir.join("validator-uv.json"), report.to_string()).unwrap();
    let issues = &report["issues"];
    assert_eq!(
        issues["numErrors"], 0,
        "validator errors: {}",
        issues["messages"]
    );
    let info = &report["info"];
    assert_eq!(info["maxUVs"], 1, "{info}");
    assert_eq!(info["hasMorphTargets"], true, "{info}");
    // The seam vertices are split: more vertices than the mesh has, one copy per seam row.
    let split = info["totalVertexCount"].as_u64().unwrap() as usize;
    assert!(split > topo.n_vertices(), "{info}");

    let usda = dir.join("uv.usda");
    let o = export(&out, "usd", &usda);
    assert!(o.status.success(), "{}", stderr(&o));
    let usd = read_usd(&usda, &["1"]);
    let st = &usd["st"];
    assert_eq!(st["type"], "texCoord2f[]", "{st}");
    assert_eq!(st["interpolation"], "faceVarying", "{st}");
    assert_eq!(st["indexed"], true, "{st}");
    let got: Vec<[f32; 2]> = st["corners"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| [c[0].as_f64().unwrap() as f32, c[1].as_f64().unwrap() as f32])
        .collect();
    assert_eq!(got, fine, "USD's st at every face corner");
    // Without UVs the stage has no st.
    assert!(read_usd_fixture_has_no_st(&dir));
}

fn read_usd_fixture_has_no_st(dir: &Path) -> bool {
    let usda = dir.join("plain.usda");
    let o = export(&fixture(), "usd", &usda);
    assert!(o.status.success(), "{}", stderr(&o));
    read_usd(&usda, &[]).get("st").is_none()
}

//! glTF 2.0 binary (`.glb`): the mesh of the first frame with vertex normals, and every later frame as a morph
//! target (position and normal deltas from the first frame), played by one `weights` animation with LINEAR
//! interpolation whose key at frame k is 1 for target k and 0 for the rest.
//!
//! Why morph targets: they are glTF's only vertex animation that engines (three.js, Babylon, Unity glTFast,
//! Unreal) and Blender's importer all play back. Data is frames × vertices × 24 bytes whatever the layout
//! (positions + normals; glTF has no compressed vertex animation), and the one-hot weights keep at most two
//! targets active at any time, under every engine's active-morph-target limit (three.js: 8). The weights
//! keyframes are frames × (frames − 1) floats, 9 KB at 48 frames but 4 MB at 1,000: beyond a few hundred
//! frames, USD or a point cache is the better container (docs/export.md).
//!
//! With texture coordinates (`TEXCOORD_0`), vertices on a UV seam are split ([`crate::mesh::UvSet::split_seams`]):
//! glTF has one coordinate per vertex. Positions, normals and every morph target go through the same index
//! map, and normals are computed on the unsplit mesh so that shading stays smooth across the seam. glTF's UV
//! origin is the top left of the image, OBJ's the bottom left, so v is written as 1 − v.
//!
//! A GLB's JSON chunk precedes its binary chunk and must carry every morph target's min/max, so the writer reads
//! the frames twice: once for the bounds, once to stream the binary chunk. Memory stays at one frame.

use super::staging::{put, write_staged};
use super::{to_f32, unit_normals, ExportOptions, FrameReader, UpAxis};
use crate::error::{Error, Result};
use crate::mesh::uv::SeamSplit;
use serde_json::{json, Value};
use std::path::Path;

const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;

pub fn write_glb(frames: &FrameReader, out: &Path, opts: &ExportOptions) -> Result<()> {
    let topo = frames.source.topology().clone();
    let n = frames.n_frames();
    let nt = topo.n_triangles();
    let targets = n - 1;
    let split: Option<SeamSplit> = topo
        .uvs()
        .map(|u| u.split_seams(topo.n_vertices(), topo.triangles()));
    // Vertices as written: the mesh's own, or with the seam copies appended.
    let nv = split.as_ref().map_or(topo.n_vertices(), |s| s.source.len());
    let per_vertex = |v: Vec<[f32; 3]>| match &split {
        Some(s) => s.gather(&v),
        None => v,
    };
    let triangles = split
        .as_ref()
        .map_or(topo.triangles(), |s| s.triangles.as_slice());

    // Pass 1: bounds of the base positions and of every target's position deltas.
    let base = frames.read(0)?;
    let base32: Vec<[f32; 3]> = base.iter().map(|p| to_f32(*p)).collect();
    let base_bounds = bounds(base32.iter().copied());
    let mut target_bounds = Vec::with_capacity(targets);
    for t in 1..n {
        let f = frames.read(t)?;
        target_bounds.push(bounds(f.iter().zip(&base).map(|(p, b)| delta(*p, *b))));
    }

    // Layout of the binary chunk: one buffer view per accessor, each 4-byte aligned by construction.
    let vec3_len = nv as u64 * 12;
    let mut views: Vec<Value> = Vec::new();
    let mut accessors: Vec<Value> = Vec::new();
    let mut offset = 0u64;
    let mut add = |len: u64, target: Option<u32>, accessor: Value| -> usize {
        let mut view = json!({ "buffer": 0, "byteOffset": offset, "byteLength": len });
        if let Some(t) = target {
            view["target"] = json!(t);
        }
        views.push(view);
        let mut acc = accessor;
        acc["bufferView"] = json!(views.len() - 1);
        accessors.push(acc);
        offset += len;
        accessors.len() - 1
    };
    let vec3 = |count: usize, b: Option<&Bounds>| {
        let mut a = json!({ "componentType": FLOAT, "count": count, "type": "VEC3" });
        if let Some(b) = b {
            a["min"] = json!(b.min);
            a["max"] = json!(b.max);
        }
        a
    };
    let indices = add(
        nt as u64 * 12,
        Some(ELEMENT_ARRAY_BUFFER),
        json!({ "componentType": UNSIGNED_INT, "count": nt * 3, "type": "SCALAR",
                "min": [0], "max": [nv.saturating_sub(1)] }),
    );
    let position = add(vec3_len, Some(ARRAY_BUFFER), vec3(nv, Some(&base_bounds)));
    let normal = add(vec3_len, Some(ARRAY_BUFFER), vec3(nv, None));
    let texcoord = split.as_ref().map(|_| {
        add(
            nv as u64 * 8,
            Some(ARRAY_BUFFER),
            json!({ "componentType": FLOAT, "count": nv, "type": "VEC2" }),
        )
    });
    let mut target_json = Vec::with_capacity(targets);
    for b in &target_bounds {
        let p = add(vec3_len, Some(ARRAY_BUFFER), vec3(nv, Some(b)));
        let q = add(vec3_len, Some(ARRAY_BUFFER), vec3(nv, None));
        target_json.push(json!({ "POSITION": p, "NORMAL": q }));
    }
    let mut primitive = json!({
        "attributes": { "POSITION": position, "NORMAL": normal },
        "indices": indices,
        "mode": 4,
    });
    if let Some(t) = texcoord {
        primitive["attributes"]["TEXCOORD_0"] = json!(t);
    }
    let mut mesh = json!({ "name": "garment", "primitives": [] });
    let mut animations = Vec::new();
    if targets > 0 {
        primitive["targets"] = json!(target_json);
        mesh["weights"] = json!(vec![0.0; targets]);
        let last = ((n - 1) as f64 / opts.fps) as f32;
        let input = add(
            n as u64 * 4,
            None,
            json!({ "componentType": FLOAT, "count": n, "type": "SCALAR", "min": [0.0], "max": [last] }),
        );
        let output = add(
            n as u64 * targets as u64 * 4,
            None,
            json!({ "componentType": FLOAT, "count": n * targets, "type": "SCALAR" }),
        );
        animations.push(json!({
            "name": "crease",
            "samplers": [{ "input": input, "output": output, "interpolation": "LINEAR" }],
            "channels": [{ "sampler": 0, "target": { "node": 0, "path": "weights" } }],
        }));
    }
    mesh["primitives"] = json!([primitive]);
    let bin_len = offset;
    let mut node = json!({ "name": "garment", "mesh": 0 });
    if opts.up_axis == UpAxis::Z {
        // glTF is +y up: turn +z up data by −90° about x.
        let h = std::f64::consts::FRAC_1_SQRT_2;
        node["rotation"] = json!([-h, 0.0, 0.0, h]);
    }
    let mut doc = json!({
        "asset": { "version": "2.0", "generator": concat!("crease ", env!("CARGO_PKG_VERSION")) },
        "scene": 0,
        "scenes": [{ "nodes": [0] }],
        "nodes": [node],
        "meshes": [mesh],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{ "byteLength": bin_len }],
    });
    if !animations.is_empty() {
        doc["animations"] = json!(animations);
    }
    let mut json_bytes = serde_json::to_vec(&doc)
        .map_err(|e| Error::format(out, None, format!("glTF JSON: {e}")))?;
    while json_bytes.len() % 4 != 0 {
        json_bytes.push(b' ');
    }
    let total = 12 + 8 + json_bytes.len() as u64 + 8 + bin_len;
    let total32 = u32::try_from(total).map_err(|_| {
        Error::param(
            "input",
            format!(
                "{n} frames of {nv} vertices make a {total}-byte GLB, over the format's 4 GiB limit; export USD \
                 or a point cache, or fewer frames"
            ),
        )
    })?;

    // Pass 2: stream the binary chunk in the order laid out above.
    write_staged(out, |w| {
        put(w, out, b"glTF")?;
        put(w, out, &2u32.to_le_bytes())?;
        put(w, out, &total32.to_le_bytes())?;
        put(w, out, &(json_bytes.len() as u32).to_le_bytes())?;
        put(w, out, b"JSON")?;
        put(w, out, &json_bytes)?;
        put(w, out, &(bin_len as u32).to_le_bytes())?;
        put(w, out, b"BIN\0")?;
        let mut buf = Vec::with_capacity(nv * 12);
        for tri in triangles {
            for v in tri {
                buf.extend_from_slice(&v.to_le_bytes());
            }
        }
        put(w, out, &buf)?;
        let base_normals = per_vertex(unit_normals(&topo, &base));
        put(w, out, vec3_bytes(&per_vertex(base32), &mut buf))?;
        put(w, out, vec3_bytes(&base_normals, &mut buf))?;
        if let Some(s) = &split {
            buf.clear();
            for c in &s.uv {
                buf.extend_from_slice(&c[0].to_le_bytes());
                buf.extend_from_slice(&(1.0 - c[1]).to_le_bytes());
            }
            put(w, out, &buf)?;
        }
        for t in 1..n {
            let f = frames.read(t)?;
            let d: Vec<[f32; 3]> = f.iter().zip(&base).map(|(p, b)| delta(*p, *b)).collect();
            put(w, out, vec3_bytes(&per_vertex(d), &mut buf))?;
            let normals = per_vertex(unit_normals(&topo, &f));
            let dn: Vec<[f32; 3]> = normals
                .iter()
                .zip(&base_normals)
                .map(|(a, b)| [a[0] - b[0], a[1] - b[1], a[2] - b[2]])
                .collect();
            put(w, out, vec3_bytes(&dn, &mut buf))?;
        }
        if targets > 0 {
            buf.clear();
            for t in 0..n {
                buf.extend_from_slice(&((t as f64 / opts.fps) as f32).to_le_bytes());
            }
            put(w, out, &buf)?;
            // Key k: target k − 1 at weight 1 (frame 0 is the base mesh, all weights 0).
            let mut row = vec![0u8; targets * 4];
            for t in 0..n {
                row.fill(0);
                if t > 0 {
                    row[(t - 1) * 4..t * 4].copy_from_slice(&1f32.to_le_bytes());
                }
                put(w, out, &row)?;
            }
        }
        Ok(())
    })
}

/// Position delta from the base frame, rounded so that base + delta is the frame's own `f32` position to
/// within one rounding.
fn delta(p: crate::vec3::V3, base: crate::vec3::V3) -> [f32; 3] {
    let (a, b) = (to_f32(p), to_f32(base));
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

struct Bounds {
    min: [f32; 3],
    max: [f32; 3],
}

fn bounds(points: impl Iterator<Item = [f32; 3]>) -> Bounds {
    let mut b = Bounds {
        min: [f32::INFINITY; 3],
        max: [f32::NEG_INFINITY; 3],
    };
    for p in points {
        for ((lo, hi), x) in b.min.iter_mut().zip(b.max.iter_mut()).zip(p) {
            *lo = lo.min(x);
            *hi = hi.max(x);
        }
    }
    b
}

fn vec3_bytes<'a>(v: &[[f32; 3]], buf: &'a mut Vec<u8>) -> &'a [u8] {
    buf.clear();
    for p in v {
        for c in p {
            buf.extend_from_slice(&c.to_le_bytes());
        }
    }
    buf
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::super::test_support::{read_le_f32, read_le_u32, two_triangles};
    use super::super::{export, ExportFormat, ExportOptions};
    use crate::progress::NoProgress;

    #[test]
    fn chunks_accessors_and_targets_reproduce_every_frame() {
        let seq = two_triangles(3);
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("a.glb");
        export(
            &seq,
            ExportFormat::Glb,
            &out,
            &ExportOptions::default(),
            &NoProgress,
        )
        .unwrap();
        let b = std::fs::read(&out).unwrap();
        assert_eq!(&b[0..4], b"glTF");
        assert_eq!(read_le_u32(&b, 4), 2);
        assert_eq!(read_le_u32(&b, 8) as usize, b.len());
        let json_len = read_le_u32(&b, 12) as usize;
        assert_eq!(&b[16..20], b"JSON");
        let doc: serde_json::Value = serde_json::from_slice(&b[20..20 + json_len]).unwrap();
        let bin_at = 20 + json_len;
        assert_eq!(&b[bin_at + 4..bin_at + 8], b"BIN\0");
        let bin = &b[bin_at + 8..];
        assert_eq!(read_le_u32(&b, bin_at) as usize, bin.len());
        assert_eq!(doc["buffers"][0]["byteLength"], bin.len());
        let prim = &doc["meshes"][0]["primitives"][0];
        let targets = prim["targets"].as_array().unwrap();
        assert_eq!(targets.len(), 2);
        // Reads accessor `a`'s VEC3 element v.
        let vec3 = |a: &serde_json::Value, v: usize| -> [f32; 3] {
            let acc = &doc["accessors"][a.as_u64().unwrap() as usize];
            let view = &doc["bufferViews"][acc["bufferView"].as_u64().unwrap() as usize];
            let at = view["byteOffset"].as_u64().unwrap() as usize + v * 12;
            [
                read_le_f32(bin, at),
                read_le_f32(bin, at + 4),
                read_le_f32(bin, at + 8),
            ]
        };
        for t in 0..3 {
            for v in 0..4 {
                let mut p = vec3(&prim["attributes"]["POSITION"], v);
                if t > 0 {
                    let d = vec3(&targets[t - 1]["POSITION"], v);
                    p = [p[0] + d[0], p[1] + d[1], p[2] + d[2]];
                }
                for c in 0..3 {
                    let want = seq.frames[t][v][c] as f32;
                    assert!((p[c] - want).abs() <= 1e-6, "frame {t} vertex {v}: {p:?}");
                }
            }
        }
        // Weights: key t is one-hot on target t − 1.
        let sampler = &doc["animations"][0]["samplers"][0];
        assert_eq!(sampler["interpolation"], "LINEAR");
        let out_acc = &doc["accessors"][sampler["output"].as_u64().unwrap() as usize];
        let view = &doc["bufferViews"][out_acc["bufferView"].as_u64().unwrap() as usize];
        let at = view["byteOffset"].as_u64().unwrap() as usize;
        let w: Vec<f32> = (0..6).map(|i| read_le_f32(bin, at + 4 * i)).collect();
        assert_eq!(w, vec![0.0, 0.0, 1.0, 0.0, 0.0, 1.0]);
    }

    /// A tube with a UV seam: the seam vertices are split, and through the index map every triangle corner
    /// still has its frame's position (base + morph target) and its own texture coordinate (v flipped).
    #[test]
    fn seams_split_with_every_target_following_the_index_map() {
        let seq = crate::synth::uv_tube(6, 4, 3).unwrap();
        let topo = seq.topology.clone();
        let uvs = topo.uvs().unwrap();
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("a.glb");
        export(
            &seq,
            ExportFormat::Glb,
            &out,
            &ExportOptions::default(),
            &NoProgress,
        )
        .unwrap();
        let b = std::fs::read(&out).unwrap();
        let json_len = read_le_u32(&b, 12) as usize;
        let doc: serde_json::Value = serde_json::from_slice(&b[20..20 + json_len]).unwrap();
        let bin = &b[20 + json_len + 8..];
        let prim = &doc["meshes"][0]["primitives"][0];
        let at = |a: &serde_json::Value| -> (usize, usize) {
            let acc = &doc["accessors"][a.as_u64().unwrap() as usize];
            let view = &doc["bufferViews"][acc["bufferView"].as_u64().unwrap() as usize];
            (
                view["byteOffset"].as_u64().unwrap() as usize,
                acc["count"].as_u64().unwrap() as usize,
            )
        };
        let (uv_at, n_split) = at(&prim["attributes"]["TEXCOORD_0"]);
        // Each of the four rows has one seam vertex, which gets a second copy.
        assert_eq!(n_split, topo.n_vertices() + 4);
        assert_eq!(at(&prim["attributes"]["POSITION"]).1, n_split);
        assert_eq!(at(&prim["attributes"]["NORMAL"]).1, n_split);
        let (idx_at, n_idx) = at(&prim["indices"]);
        assert_eq!(n_idx, 3 * topo.n_triangles());
        let targets = prim["targets"].as_array().unwrap();
        let vec3 = |a: &serde_json::Value, v: usize| -> [f32; 3] {
            let (o, n) = at(a);
            assert_eq!(n, n_split);
            [0, 4, 8].map(|c| read_le_f32(bin, o + v * 12 + c))
        };
        for (t, tri) in topo.triangles().iter().enumerate() {
            for k in 0..3 {
                let g = read_le_u32(bin, idx_at + 4 * (3 * t + k)) as usize;
                let want_uv = uvs.uv()[uvs.corners()[t][k] as usize];
                let got_uv = [
                    read_le_f32(bin, uv_at + 8 * g),
                    read_le_f32(bin, uv_at + 8 * g + 4),
                ];
                assert_eq!(
                    got_uv,
                    [want_uv[0], 1.0 - want_uv[1]],
                    "triangle {t} corner {k}"
                );
                for f in 0..3 {
                    let mut p = vec3(&prim["attributes"]["POSITION"], g);
                    if f > 0 {
                        let d = vec3(&targets[f - 1]["POSITION"], g);
                        p = [p[0] + d[0], p[1] + d[1], p[2] + d[2]];
                    }
                    let want = seq.frames[f][tri[k] as usize];
                    for c in 0..3 {
                        assert!(
                            (p[c] - want[c] as f32).abs() <= 1e-6,
                            "frame {f} triangle {t} corner {k}"
                        );
                    }
                }
            }
        }
        // Normals are the unsplit mesh's: a seam vertex and its copy have the same normal.
        let n = |v: usize| vec3(&prim["attributes"]["NORMAL"], v);
        assert_eq!(n(0), n(topo.n_vertices()));
    }

    #[test]
    fn a_single_frame_is_a_static_mesh() {
        let seq = two_triangles(1);
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("a.glb");
        export(
            &seq,
            ExportFormat::Glb,
            &out,
            &ExportOptions::default(),
            &NoProgress,
        )
        .unwrap();
        let b = std::fs::read(&out).unwrap();
        let json_len = read_le_u32(&b, 12) as usize;
        let doc: serde_json::Value = serde_json::from_slice(&b[20..20 + json_len]).unwrap();
        assert!(doc.get("animations").is_none());
        assert!(doc["meshes"][0]["primitives"][0].get("targets").is_none());
    }
}

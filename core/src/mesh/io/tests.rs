//! Table-driven error tests (every bad input must produce a message naming the file and the frame, line or
//! index at fault) and round trips through every layout.

use super::*;
use crate::mesh::{geometry, Topology};
use crate::vec3::V3;
use std::path::{Path, PathBuf};

const QUAD: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";
const TWO_TRIS: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n";

fn put(dir: &Path, name: &str, content: impl AsRef<[u8]>) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, content).unwrap();
    path
}

/// A regular grid in the z = 0 plane (`nx` × `ny` vertices), bent by `t` so that frames differ.
fn grid(nx: usize, ny: usize, t: f64) -> (Vec<V3>, Vec<[u32; 3]>) {
    let mut p = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let x = i as f64 / (nx - 1) as f64;
            let y = j as f64 / (ny - 1) as f64;
            p.push([x + 0.01 * t, y, 0.1 * t * x * x]);
        }
    }
    let mut tris = Vec::new();
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            let a = (j * nx + i) as u32;
            let b = a + 1;
            let c = a + nx as u32;
            let d = c + 1;
            tris.push([a, b, d]);
            tris.push([a, d, c]);
        }
    }
    (p, tris)
}

fn grid_topology(nx: usize, ny: usize) -> Topology {
    Topology::new(nx * ny, grid(nx, ny, 0.0).1).unwrap()
}

/// Opens `path` and reads every frame, returning the first error.
fn open_and_read_all(path: &Path) -> crate::Result<()> {
    let opened = open_sequence(path)?;
    for t in 0..opened.source.n_frames() {
        opened.source.read_frame(t)?;
    }
    Ok(())
}

fn read_all(path: &Path) -> (OpenedSequence, Vec<Vec<V3>>) {
    let opened = open_sequence(path).unwrap();
    let frames = (0..opened.source.n_frames())
        .map(|t| opened.source.read_frame(t).unwrap())
        .collect();
    (opened, frames)
}

fn modified(frames: &[Vec<V3>]) -> Vec<Vec<V3>> {
    frames
        .iter()
        .enumerate()
        .map(|(t, f)| {
            f.iter()
                .map(|p| {
                    [
                        p[0] * 1.5 + 0.25,
                        p[1] - 0.1 * t as f64,
                        p[2] * 2.0 + 1.0 / 3.0,
                    ]
                })
                .collect()
        })
        .collect()
}

fn as_f32(frames: &[Vec<V3>]) -> Vec<Vec<V3>> {
    frames
        .iter()
        .map(|f| f.iter().map(|p| p.map(|c| c as f32 as f64)).collect())
        .collect()
}

fn write_through_sink(
    layout: &SequenceLayout,
    out: &Path,
    frames: &[Vec<V3>],
    order: &[usize],
) -> Vec<PathBuf> {
    let mut sink = create_sink(layout, out).unwrap();
    for &t in order {
        sink.write_frame(t, &frames[t]).unwrap();
    }
    sink.finish().unwrap()
}

fn pc2_pair(dir: &Path, points: usize, samples: usize) -> PathBuf {
    let (nx, ny) = (2, points / 2);
    let topo = grid_topology(nx, ny);
    write_obj(&dir.join("cache.obj"), &topo, &grid(nx, ny, 0.0).0).unwrap();
    let frames: Vec<Vec<V3>> = (0..samples).map(|t| grid(nx, ny, t as f64).0).collect();
    let path = dir.join("cache.pc2");
    write_pc2(&path, &frames, 1.0, 1.0).unwrap();
    path
}

fn truncate_by(path: &Path, n: u64) {
    let f = std::fs::OpenOptions::new().write(true).open(path).unwrap();
    let len = f.metadata().unwrap().len();
    f.set_len(len - n).unwrap();
}

const ASCII_PLY_HEAD: &str = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                              property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";

type Setup = fn(&Path) -> PathBuf;

/// Every bad input, the path to open, and fragments the error message must contain.
const ERROR_CASES: &[(&str, Setup, &[&str])] = &[
    (
        "vertex count differs between frames",
        |d| {
            put(d, "f1.obj", QUAD);
            put(d, "f2.obj", format!("v 5 5 5\n{QUAD}"));
            d.to_path_buf()
        },
        &[
            "f2.obj",
            "(frame 1)",
            "has 5 vertices",
            "frame 0 (f1.obj) has 4",
        ],
    ),
    (
        "nan coordinate",
        |d| {
            put(d, "f1.obj", QUAD);
            put(d, "f2.obj", QUAD.replace("v 1 1 0", "v 1 nan 0"));
            d.to_path_buf()
        },
        &["f2.obj", "(frame 1)", "vertex 3 (line 3)", "non-finite"],
    ),
    (
        "inf coordinate",
        |d| {
            put(d, "f1.obj", QUAD.replace("v 1 0 0", "v 1 0 -inf"));
            d.to_path_buf()
        },
        &["f1.obj", "(frame 0)", "vertex 2 (line 2)", "non-finite"],
    ),
    (
        "out-of-range index (OBJ)",
        |d| {
            put(
                d,
                "f1.obj",
                "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 9\n",
            );
            d.to_path_buf()
        },
        &[
            "f1.obj:6",
            "face `f 1 3 9`",
            "references vertex 9",
            "only 4 vertices",
        ],
    ),
    (
        "out-of-range index (PLY)",
        |d| {
            put(
                d,
                "f1.ply",
                format!("{ASCII_PLY_HEAD}0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n"),
            );
            d.to_path_buf()
        },
        &["f1.ply:13", "face 0 references vertex 7", "only 3 vertices"],
    ),
    (
        "relative index before the first vertex",
        |d| {
            put(d, "f1.obj", "v 0 0 0\nv 1 0 0\nf 1 2 -3\n");
            d.to_path_buf()
        },
        &["f1.obj:3", "relative vertex index -3"],
    ),
    (
        "index 0 in OBJ",
        |d| {
            put(d, "frame_0001.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 0 1 2\n");
            d.to_path_buf()
        },
        &["frame_0001.obj:4", "index 0", "f 0 1 2"],
    ),
    (
        "unparsable coordinate",
        |d| {
            put(d, "f1.obj", "v 0 0 0\nv 1 abc 0\nv 1 1 0\nf 1 2 3\n");
            d.to_path_buf()
        },
        &["f1.obj:2", "`abc`"],
    ),
    (
        "too few coordinates",
        |d| {
            put(d, "f1.obj", "v 0 0 0\nv 1 0 0\r\nv 1 1\r\nf 1 2 3\n");
            d.to_path_buf()
        },
        &["f1.obj:3", "2 coordinates"],
    ),
    (
        "face with two vertices",
        |d| {
            put(d, "f1.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2\n");
            d.to_path_buf()
        },
        &["f1.obj:4", "face has 2 vertices"],
    ),
    (
        "zero-area triangle (collinear vertices)",
        |d| {
            put(
                d,
                "f1.obj",
                "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 4\nf 1 3 2\n",
            );
            d.to_path_buf()
        },
        &[
            "f1.obj",
            "(frame 0)",
            "face 2 (line 6) (`f 1 3 2`)",
            "degenerate",
        ],
    ),
    (
        "zero-area triangle inside a quad",
        |d| {
            put(
                d,
                "f1.obj",
                "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0.5 0.5 0\nf 1 2 3 4\n",
            );
            d.to_path_buf()
        },
        &[
            "f1.obj",
            "(frame 0)",
            "face 1 (line 5) (`f 1 2 3 4`)",
            "fan triangle of vertices 1 3 4",
        ],
    ),
    (
        "repeated-vertex triangle",
        |d| {
            put(d, "f1.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\nf 1 3 3\n");
            d.to_path_buf()
        },
        &[
            "f1.obj",
            "(frame 0)",
            "face 2 (line 5) (`f 1 3 3`) repeats a vertex",
        ],
    ),
    (
        "non-manifold edge",
        |d| {
            put(
                d,
                "f1.obj",
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n",
            );
            d.to_path_buf()
        },
        &[
            "f1.obj",
            "(frame 0)",
            "non-manifold edge between vertices 1 and 2",
            "3 faces: 1 (line 6), 2 (line 7), 3 (line 8)",
        ],
    ),
    (
        "empty file",
        |d| {
            put(d, "f1.obj", "");
            d.to_path_buf()
        },
        &["f1.obj", "empty"],
    ),
    (
        "OBJ with no faces",
        |d| {
            put(d, "f1.obj", "# only points\nv 0 0 0\nv 1 0 0\nv 1 1 0\n");
            d.to_path_buf()
        },
        &["f1.obj", "no faces"],
    ),
    (
        "truncated binary PLY",
        |d| {
            let topo = grid_topology(2, 2);
            let path = d.join("f1.ply");
            write_ply_frame(&path, &topo, &grid(2, 2, 0.0).0, true).unwrap();
            truncate_by(&path, 3);
            d.to_path_buf()
        },
        &["f1.ply", "element `face` index 1", "ends early"],
    ),
    (
        "ASCII PLY with too few tokens",
        |d| {
            put(
                d,
                "f1.ply",
                format!("{ASCII_PLY_HEAD}0 0 0\n1 0\n0 1 0\n3 0 1 2\n"),
            );
            d.to_path_buf()
        },
        &["f1.ply:11", "too few values", "`vertex` 1", "`z`"],
    ),
    (
        "bad PLY header",
        |d| {
            put(
                d,
                "f1.ply",
                ASCII_PLY_HEAD.replace("property float y", "property flot y"),
            );
            d.to_path_buf()
        },
        &["f1.ply:5", "bad PLY header", "unknown type `flot`"],
    ),
    (
        "PLY without end_header",
        |d| {
            put(d, "f1.ply", "ply\nformat ascii 1.0\nelement vertex 3\n");
            d.to_path_buf()
        },
        &["f1.ply", "end_header"],
    ),
    (
        "truncated PC2",
        |d| {
            let pc2 = pc2_pair(d, 4, 3);
            truncate_by(&pc2, 7);
            d.to_path_buf()
        },
        &["cache.pc2", "169 bytes", "176 bytes", "truncated"],
    ),
    (
        "over-long PC2",
        |d| {
            let pc2 = pc2_pair(d, 4, 3);
            let mut bytes = std::fs::read(&pc2).unwrap();
            bytes.extend_from_slice(&[0; 4]);
            std::fs::write(&pc2, bytes).unwrap();
            pc2
        },
        &["cache.pc2", "180 bytes", "176 bytes", "over-long"],
    ),
    (
        "PC2 with wrong point count",
        |d| {
            pc2_pair(d, 4, 2);
            let frames = vec![vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]];
            write_pc2(&d.join("cache.pc2"), &frames, 0.0, 1.0).unwrap();
            d.to_path_buf()
        },
        &["cache.pc2", "3 points", "cache.obj has 4 vertices"],
    ),
    (
        "PC2 with wrong magic",
        |d| {
            let pc2 = pc2_pair(d, 4, 2);
            let mut bytes = std::fs::read(&pc2).unwrap();
            bytes[..11].copy_from_slice(b"POINTCACHE3");
            std::fs::write(&pc2, bytes).unwrap();
            pc2
        },
        &["cache.pc2", "not a PC2"],
    ),
    (
        "PC2 with version 2",
        |d| {
            let pc2 = pc2_pair(d, 4, 2);
            let mut bytes = std::fs::read(&pc2).unwrap();
            bytes[12] = 2;
            std::fs::write(&pc2, bytes).unwrap();
            pc2
        },
        &["cache.pc2", "version 2"],
    ),
    (
        "PC2 without samples",
        |d| {
            let pc2 = pc2_pair(d, 4, 1);
            let mut bytes = std::fs::read(&pc2).unwrap();
            bytes[28] = 0;
            bytes.truncate(32);
            std::fs::write(&pc2, bytes).unwrap();
            pc2
        },
        &["cache.pc2", "0 samples"],
    ),
    (
        "PC2 without its OBJ",
        |d| {
            let pc2 = pc2_pair(d, 4, 1);
            std::fs::remove_file(d.join("cache.obj")).unwrap();
            pc2
        },
        &["cache.pc2", "expected cache.obj"],
    ),
    (
        "different face list in frame 2",
        |d| {
            put(d, "f1.obj", TWO_TRIS);
            put(d, "f2.obj", TWO_TRIS);
            put(d, "f3.obj", TWO_TRIS.replace("f 1 3 4", "f 1 4 3"));
            d.to_path_buf()
        },
        &[
            "f3.obj",
            "(frame 2)",
            "different triangle list than frame 0 (f1.obj)",
            "face 1 (line 6) is (1 4 3)",
        ],
    ),
    (
        "duplicate frame numbers",
        |d| {
            put(d, "f1.obj", QUAD);
            put(d, "f01.obj", QUAD);
            put(d, "f2.obj", QUAD);
            d.to_path_buf()
        },
        &["f1.obj", "f01.obj", "frame number 1"],
    ),
    (
        "file without a frame number",
        |d| {
            put(d, "f1.obj", QUAD);
            put(d, "shirt.obj", QUAD);
            d.to_path_buf()
        },
        &["shirt.obj", "no frame number", "f1.obj"],
    ),
    (
        "mixed .obj/.ply directory",
        |d| {
            put(d, "f1.obj", QUAD);
            put(d, "f2.ply", ASCII_PLY_HEAD);
            d.to_path_buf()
        },
        &["mixes OBJ and PLY", "f1.obj", "f2.ply"],
    ),
    (
        "empty directory",
        |d| {
            let empty = d.join("empty_seq");
            std::fs::create_dir(&empty).unwrap();
            empty
        },
        &["empty_seq", "directory is empty"],
    ),
];

#[test]
fn bad_inputs_are_named() {
    let mut failures = Vec::new();
    for (name, setup, fragments) in ERROR_CASES {
        let dir = tempfile::tempdir().unwrap();
        let path = setup(dir.path());
        match open_and_read_all(&path) {
            Ok(()) => failures.push(format!("{name}: no error")),
            Err(e) => {
                let msg = e.to_string();
                // Shown with --nocapture, to review the wording of every message at once.
                eprintln!("{name}:\n    {msg}");
                let missing: Vec<_> = fragments.iter().filter(|f| !msg.contains(*f)).collect();
                if !missing.is_empty() {
                    failures.push(format!("{name}: {missing:?} not in `{msg}`"));
                }
            }
        }
    }
    assert!(failures.is_empty(), "\n{}", failures.join("\n"));
}

#[test]
fn obj_directory_round_trip_keeps_everything_but_positions() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in");
    std::fs::create_dir(&input).unwrap();
    let frame_text = |t: usize| {
        let dx = 0.1 * t as f64;
        format!(
            "# exported by test\r\nmtllib cloth.mtl\no cloth\n\
             v {} 0 0 1 0 0\nv {} 0 0 0 1 0\nv {} 0 {} 0 0 1\nv {} 1 0 1 1 0\nv {} 1 0 0 1 1\nv {} 1 {} 1 0 1\n\
             vt 0 0\nvt 0.5 0\nvt 1 0\nvt 0 1\nvt 0.5 1\nvt 1 1\nvn 0 0 1\ng front\nusemtl red\ns off\n\
             f 1/1/1 2/2/1 5/5/1 4/4/1\n# second quad\nf 2//1 3//1 6//1 5//1\n",
            dx,
            1.0 + dx,
            2.0 + dx,
            dx,
            dx,
            1.0 + dx,
            2.0 + dx,
            dx
        )
    };
    for (t, name) in ["f9.obj", "f10.obj", "f11.obj"].iter().enumerate() {
        put(&input, name, frame_text(t));
    }
    put(&input, "cloth.mtl", "newmtl red\nKd 1 0 0\n");
    let (opened, frames) = read_all(&input);
    assert_eq!(opened.layout.kind(), "obj-frames");
    assert_eq!(opened.source.topology().n_triangles(), 4);
    assert!(opened.source.describe_frame(1).ends_with("f10.obj"));
    let new = modified(&frames);
    let out = dir.path().join("out");
    let written = write_through_sink(&opened.layout, &out, &new, &[2, 0, 1]);
    let names: Vec<_> = written
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, ["f9.obj", "f10.obj", "f11.obj"]);

    let (_, reread) = read_all(&out);
    assert_eq!(reread, new, "OBJ output must round-trip positions exactly");
    // The material library the frames refer to comes along.
    assert_eq!(
        std::fs::read_to_string(out.join("cloth.mtl")).unwrap(),
        "newmtl red\nKd 1 0 0\n"
    );
    let text = std::fs::read_to_string(out.join("f10.obj")).unwrap();
    assert!(
        text.starts_with("# exported by test\r\nmtllib cloth.mtl\no cloth\n"),
        "{text}"
    );
    assert_eq!(text.lines().filter(|l| l.starts_with("vt ")).count(), 6);
    assert_eq!(text.lines().filter(|l| l.starts_with("vn ")).count(), 0);
    assert!(
        text.contains("\nf 1/1 2/2 5/5 4/4\n# second quad\nf 2 3 6 5\n"),
        "{text}"
    );
    assert!(text.contains("g front\nusemtl red\ns off\n"), "{text}");
    let first_v = text.lines().find(|l| l.starts_with("v ")).unwrap();
    assert!(
        first_v.ends_with(" 1 0 0"),
        "vertex colours must be kept: {first_v}"
    );
    // Deterministic: writing again gives the same bytes.
    let again = dir.path().join("again");
    write_through_sink(&opened.layout, &again, &new, &[0, 1, 2]);
    assert_eq!(
        std::fs::read(again.join("f11.obj")).unwrap(),
        std::fs::read(out.join("f11.obj")).unwrap()
    );
}

const ASCII_NORMALS_PLY: &str = "ply\nformat ascii 1.0\ncomment made by hand\nelement vertex 4\nproperty float x\n\
    property float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\n\
    property uchar red\nelement face 2\nproperty list uchar int vertex_indices\nelement extra 1\nproperty int flag\n\
    end_header\n";

#[test]
fn ascii_ply_round_trip_recomputes_normals() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in");
    std::fs::create_dir(&input).unwrap();
    for t in 0..2 {
        let z = 0.5 * t as f64;
        let body = format!(
            "0 0 0 1 0 0 200\n1 0 {z} 1 0 0 201\n1 1 {z} 1 0 0 202\n0 1 0 1 0 0 203\n3 0 1 2\n3 0 2 3\n42\n"
        );
        put(
            &input,
            &format!("cloth.{:04}.ply", t + 1),
            format!("{ASCII_NORMALS_PLY}{body}"),
        );
    }
    let (opened, frames) = read_all(&input);
    assert_eq!(opened.layout.kind(), "ply-frames");
    let new = modified(&frames);
    let out = dir.path().join("out");
    write_through_sink(&opened.layout, &out, &new, &[1, 0]);
    let (reread_src, reread) = read_all(&out);
    assert_eq!(reread, as_f32(&new));

    let text = std::fs::read_to_string(out.join("cloth.0002.ply")).unwrap();
    assert!(text.starts_with(ASCII_NORMALS_PLY));
    assert!(text.ends_with("3 0 1 2\n3 0 2 3\n42\n"), "{text}");
    let normals = geometry::vertex_normals(reread_src.source.topology(), &new[1]);
    let vertex_lines: Vec<&str> = text[ASCII_NORMALS_PLY.len()..].lines().take(4).collect();
    for (i, line) in vertex_lines.iter().enumerate() {
        let toks: Vec<&str> = line.split(' ').collect();
        assert_eq!(toks.len(), 7, "{line}");
        assert_eq!(
            toks[6],
            (200 + i).to_string(),
            "colour must be copied: {line}"
        );
        for k in 0..3 {
            let n: f32 = toks[3 + k].parse().unwrap();
            assert_eq!(n, normals[i][k] as f32, "normal of vertex {i}: {line}");
        }
    }
}

#[test]
fn binary_le_ply_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in");
    let topo = grid_topology(4, 3);
    for t in 0..3 {
        std::fs::create_dir_all(&input).unwrap();
        write_ply_frame(
            &input.join(format!("{t}.ply")),
            &topo,
            &grid(4, 3, t as f64).0,
            true,
        )
        .unwrap();
    }
    let (opened, frames) = read_all(&input);
    assert_eq!(frames[2], as_f32(&[grid(4, 3, 2.0).0])[0]);
    let new = modified(&frames);
    let out = dir.path().join("out");
    write_through_sink(&opened.layout, &out, &new, &[0, 1, 2]);
    let (_, reread) = read_all(&out);
    assert_eq!(reread, as_f32(&new));
    // Header and faces byte-identical.
    let a = std::fs::read(input.join("1.ply")).unwrap();
    let b = std::fs::read(out.join("1.ply")).unwrap();
    let head = a.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    let vertex_end = head + 12 * topo.n_vertices();
    assert_eq!(a.len(), b.len());
    assert_eq!(a[..head], b[..head]);
    assert_eq!(a[vertex_end..], b[vertex_end..]);
}

/// A big-endian PLY with double positions, float normals, a per-vertex list, extra face properties and an extra
/// element after the faces: everything the binary walker has to step over.
fn big_endian_ply(positions: &[V3], tris: &[[u32; 3]]) -> Vec<u8> {
    let mut b = format!(
        "ply\nformat binary_big_endian 1.0\nobj_info test\nelement vertex {}\nproperty double x\n\
         property double y\nproperty double z\nproperty float nx\nproperty float ny\nproperty float nz\n\
         property uchar red\nproperty list uchar ushort tags\nelement face {}\n\
         property list uchar int vertex_indices\nproperty int flags\nelement material 1\n\
         property list uchar float params\nend_header\n",
        positions.len(),
        tris.len()
    )
    .into_bytes();
    for (i, p) in positions.iter().enumerate() {
        for &c in p {
            b.extend_from_slice(&c.to_be_bytes());
        }
        for c in [0.0f32, 0.0, -1.0] {
            b.extend_from_slice(&c.to_be_bytes());
        }
        b.push(i as u8);
        b.push(2);
        b.extend_from_slice(&(i as u16).to_be_bytes());
        b.extend_from_slice(&7u16.to_be_bytes());
    }
    for (k, t) in tris.iter().enumerate() {
        b.push(3);
        for &v in t {
            b.extend_from_slice(&(v as i32).to_be_bytes());
        }
        b.extend_from_slice(&(k as i32 * 10).to_be_bytes());
    }
    b.push(2);
    b.extend_from_slice(&1.5f32.to_be_bytes());
    b.extend_from_slice(&2.5f32.to_be_bytes());
    b
}

#[test]
fn binary_be_ply_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in");
    std::fs::create_dir(&input).unwrap();
    let (_, tris) = grid(3, 3, 0.0);
    for t in 0..2 {
        put(
            &input,
            &format!("s_{t:03}.ply"),
            big_endian_ply(&grid(3, 3, t as f64).0, &tris),
        );
    }
    let (opened, frames) = read_all(&input);
    assert_eq!(
        frames[1],
        grid(3, 3, 1.0).0,
        "double positions are read exactly"
    );
    let new = modified(&frames);
    let out = dir.path().join("out");
    write_through_sink(&opened.layout, &out, &new, &[1, 0]);
    let (src, reread) = read_all(&out);
    assert_eq!(reread, new, "double positions are written exactly");

    let expected = big_endian_ply(&new[1], &tris);
    let got = std::fs::read(out.join("s_001.ply")).unwrap();
    assert_eq!(got.len(), expected.len());
    let normals = geometry::vertex_normals(src.source.topology(), &new[1]);
    let head = expected
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    let record = 24 + 12 + 1 + 1 + 4;
    for (i, n) in normals.iter().enumerate() {
        let at = head + i * record;
        assert_eq!(
            got[at..at + 24],
            expected[at..at + 24],
            "positions of vertex {i}"
        );
        for (k, &expected_n) in n.iter().enumerate() {
            let o = at + 24 + 4 * k;
            let v = f32::from_be_bytes(got[o..o + 4].try_into().unwrap());
            assert_eq!(v, expected_n as f32, "normal of vertex {i}");
        }
        assert_eq!(
            got[at + 36..at + record],
            expected[at + 36..at + record],
            "other properties of vertex {i}"
        );
    }
    let vertex_end = head + record * new[1].len();
    assert_eq!(got[vertex_end..], expected[vertex_end..]);
    assert_eq!(got[..head], expected[..head]);
}

#[test]
fn obj_pc2_round_trip_in_any_order() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in");
    std::fs::create_dir(&input).unwrap();
    let topo = grid_topology(3, 3);
    write_obj(&input.join("cloth.obj"), &topo, &grid(3, 3, 0.0).0).unwrap();
    let samples: Vec<Vec<V3>> = (0..4).map(|t| grid(3, 3, t as f64 + 1.0).0).collect();
    write_pc2(&input.join("cloth.pc2"), &samples, 5.0, 0.5).unwrap();
    put(&input, "notes.txt", "ignored");

    // The directory, the cache and the OBJ all open the same layout.
    for path in [
        input.clone(),
        input.join("cloth.pc2"),
        input.join("cloth.obj"),
    ] {
        let layout = detect_layout(&path).unwrap();
        assert_eq!(layout.kind(), "obj+pc2", "{}", path.display());
    }
    let (opened, frames) = read_all(&input.join("cloth.pc2"));
    assert_eq!(frames, as_f32(&samples));
    assert!(opened
        .source
        .describe_frame(3)
        .ends_with("cloth.pc2 sample 3"));
    let new = modified(&frames);
    let out = dir.path().join("out");
    let written = write_through_sink(&opened.layout, &out, &new, &[3, 1, 0, 2]);
    assert_eq!(written, vec![out.join("cloth.obj"), out.join("cloth.pc2")]);
    assert_eq!(
        std::fs::read(out.join("cloth.obj")).unwrap(),
        std::fs::read(input.join("cloth.obj")).unwrap()
    );
    let header = read_pc2_header(&out.join("cloth.pc2")).unwrap();
    assert_eq!(
        header,
        Pc2Header {
            num_points: 9,
            start_frame: 5.0,
            sample_rate: 0.5,
            num_samples: 4
        }
    );
    let (_, reread) = read_all(&out);
    assert_eq!(reread, as_f32(&new));
    let leftovers: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(leftovers.len(), 2, "{leftovers:?}");
}

#[test]
fn pc2_sink_refuses_incomplete_output() {
    let dir = tempfile::tempdir().unwrap();
    let pc2 = pc2_pair(dir.path(), 4, 5);
    let (opened, frames) = read_all(&pc2);
    let out = dir.path().join("out");
    let mut sink = create_sink(&opened.layout, &out).unwrap();
    sink.write_frame(0, &frames[0]).unwrap();
    sink.write_frame(4, &frames[4]).unwrap();
    let msg = sink.finish().unwrap_err().to_string();
    assert!(
        msg.contains("cache.pc2") && msg.contains("frames 1-3 were never written"),
        "{msg}"
    );
    assert!(!out.join("cache.pc2").exists() && !out.join("cache.obj").exists());
    drop(sink);
    assert_eq!(
        std::fs::read_dir(&out).unwrap().count(),
        0,
        "the temporary cache must be removed"
    );
}

#[test]
fn sinks_reject_bad_frames() {
    let dir = tempfile::tempdir().unwrap();
    let obj_dir = dir.path().join("obj");
    let topo = grid_topology(2, 2);
    let p = grid(2, 2, 0.0).0;
    let names = ["a1.obj".to_string(), "a2.obj".to_string()];
    let written = write_obj_sequence(
        &obj_dir,
        &topo,
        names.iter().map(|n| (n.clone(), p.as_slice())),
    )
    .unwrap();
    assert_eq!(written.len(), 2);
    let ply_dir = dir.path().join("ply");
    std::fs::create_dir(&ply_dir).unwrap();
    write_ply_frame(&ply_dir.join("b1.ply"), &topo, &p, false).unwrap();
    let pc2 = pc2_pair(dir.path(), 4, 2);
    for input in [obj_dir, ply_dir, pc2] {
        let layout = detect_layout(&input).unwrap();
        let mut sink =
            create_sink(&layout, &dir.path().join(format!("out-{}", layout.kind()))).unwrap();
        let n = layout.n_frames();
        let e = sink.write_frame(n, &p).unwrap_err().to_string();
        assert!(e.contains(&format!("frame {n} is out of range")), "{e}");
        let e = sink.write_frame(0, &p[..3]).unwrap_err().to_string();
        assert!(e.contains("3") && e.contains("4"), "{e}");
        let mut bad = p.clone();
        bad[2][1] = f64::NAN;
        let e = sink.write_frame(0, &bad).unwrap_err().to_string();
        assert!(e.contains("vertex 2"), "{e}");
        let e = sink.finish().unwrap_err().to_string();
        assert!(e.contains("never written"), "{e}");
        // Writing into the input directory would overwrite the input.
        let in_dir = layout.input_files()[0].parent().unwrap().to_path_buf();
        let e = create_sink(&layout, &in_dir).err().unwrap().to_string();
        assert!(e.contains("overwrite"), "{e}");
    }
}

#[test]
fn frames_sort_numerically() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["f10.obj", "f2.obj", "f1.obj"] {
        put(dir.path(), name, QUAD);
    }
    put(dir.path(), "cloth.mtl", "newmtl red\n");
    put(dir.path(), ".f3.obj", "not a frame");
    let layout = detect_layout(dir.path()).unwrap();
    let names: Vec<_> = layout
        .input_files()
        .iter()
        .map(|p| p.file_name().unwrap().to_owned())
        .collect();
    assert_eq!(names, ["f1.obj", "f2.obj", "f10.obj"]);

    let dir = tempfile::tempdir().unwrap();
    put(dir.path(), "frame_0002.obj", QUAD);
    put(dir.path(), "frame_001.obj", QUAD);
    let layout = detect_layout(dir.path()).unwrap();
    let numbers: Vec<u64> = match &layout {
        SequenceLayout::ObjFrames { frames, .. } => frames.iter().map(|f| f.number).collect(),
        other => panic!("unexpected layout {other}"),
    };
    assert_eq!(numbers, [1, 2]);
    assert_eq!(open_sequence(dir.path()).unwrap().source.n_frames(), 2);
}

#[test]
fn plain_writers_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let topo = grid_topology(3, 2);
    let p = grid(3, 2, 1.0).0;
    write_obj(&dir.path().join("m_1.obj"), &topo, &p).unwrap();
    let opened = open_sequence(dir.path()).unwrap();
    assert_eq!(opened.source.read_frame(0).unwrap(), p);
    assert_eq!(opened.source.topology().triangles(), topo.triangles());
    assert!(opened.source.read_frame(1).is_err());
    let e = write_obj_sequence(dir.path(), &topo, [("../x.obj".to_string(), p.as_slice())])
        .unwrap_err();
    assert!(e.to_string().contains("plain file name"), "{e}");
}

/// Mutated and truncated inputs must give errors, never panics (parsers and rewriters alike).
#[test]
fn corrupted_inputs_never_panic() {
    let topo = grid_topology(3, 3);
    let (p, tris) = grid(3, 3, 1.0);
    let dir = tempfile::tempdir().unwrap();
    let mut seeds: Vec<(bool, Vec<u8>)> = Vec::new();
    for binary in [false, true] {
        let path = dir.path().join("x.ply");
        write_ply_frame(&path, &topo, &p, binary).unwrap();
        seeds.push((false, std::fs::read(&path).unwrap()));
    }
    seeds.push((false, big_endian_ply(&p, &tris)));
    let body = "0 0 0 1 0 0 1\n1 0 0 1 0 0 1\n1 1 0 1 0 0 1\n0 1 0 1 0 0 1\n3 0 1 2\n3 0 2 3\n7\n";
    seeds.push((false, format!("{ASCII_NORMALS_PLY}{body}").into_bytes()));
    let obj =
        "# c\nv 0 0 0 1 1 1\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nf 1/1/1 2/1/1 -2/1\nf 1//1 3//1 4\n";
    seeds.push((true, obj.as_bytes().to_vec()));
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut rng = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    let path = Path::new("fuzz");
    for (is_obj, seed) in &seeds {
        for round in 0..3000 {
            let mut bytes = seed.clone();
            match round % 3 {
                0 => bytes.truncate((rng() as usize) % (seed.len() + 1)),
                1 => {
                    for _ in 0..1 + rng() % 4 {
                        let i = (rng() as usize) % bytes.len();
                        bytes[i] = rng() as u8;
                    }
                }
                _ => {
                    let i = (rng() as usize) % bytes.len();
                    let chars = b" \n-0123456789./e#";
                    bytes.insert(i, chars[(rng() as usize) % chars.len()]);
                }
            }
            if *is_obj {
                let _ = super::obj::parse_obj_with_uvs(path, &bytes);
                if let Ok(m) = super::obj::parse_obj(path, &bytes) {
                    let _ = m.faces.triangulate();
                    let _ = super::obj::rewrite_obj(path, &bytes, &m.positions);
                }
            } else if let Ok(m) = super::ply::parse_ply(path, &bytes) {
                let header = super::ply::parse_header(path, &bytes).unwrap();
                let normals = vec![[0.0, 0.0, 1.0]; m.positions.len()];
                let _ =
                    super::ply::rewrite_ply(path, &bytes, &header, &m.positions, Some(&normals));
            }
        }
    }
}

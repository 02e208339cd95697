//! USD ASCII (`.usda`): one `Mesh` prim with time-sampled `points`, `normals` (per vertex) and `extent`, one
//! time code per frame. USD is the DCC-neutral way in for Houdini, Maya, Blender and Omniverse, and the way to
//! Alembic (export from the DCC). Floats are written in their shortest exact `f32` form, so a reader gets
//! the same `f32` back.
//!
//! Texture coordinates, when the input has them, are the `primvars:st` primvar: `texCoord2f[]` values with
//! `faceVarying` interpolation and `primvars:st:indices` (one per face corner), so seams are exact and shared
//! coordinates are written once. USD's st origin is the bottom left of the image, like OBJ's.
//!
//! Text USD puts all samples of one attribute in one dictionary, so the points are written in a first pass over
//! the frames and the normals in a second; the per-frame extents (6 floats a frame) are kept in between.

use super::staging::{io_at, write_staged};
use super::{to_f32, unit_normals, ExportOptions, FrameReader, UpAxis};
use crate::error::Result;
use std::io::Write;
use std::path::Path;

pub fn write_usda(frames: &FrameReader, out: &Path, opts: &ExportOptions) -> Result<()> {
    let topo = frames.source.topology().clone();
    let n = frames.n_frames();
    let io = io_at(out);
    let time = |t: usize| fmt_num(opts.first_frame + t as f64);
    write_staged(out, |w| {
        let up = match opts.up_axis {
            UpAxis::Y => "Y",
            UpAxis::Z => "Z",
        };
        write!(
            w,
            "#usda 1.0\n(\n    defaultPrim = \"Garment\"\n    doc = \"crease export\"\n    metersPerUnit = 1\n    \
             upAxis = \"{up}\"\n    startTimeCode = {}\n    endTimeCode = {}\n    timeCodesPerSecond = {}\n    \
             framesPerSecond = {}\n)\n\ndef Xform \"Garment\" (\n    kind = \"component\"\n)\n{{\n    \
             def Mesh \"mesh\"\n    {{\n        uniform bool doubleSided = 1\n        \
             uniform token subdivisionScheme = \"none\"\n        int[] faceVertexCounts = [",
            time(0),
            time(n - 1),
            fmt_num(opts.fps),
            fmt_num(opts.fps)
        )
        .map_err(&io)?;
        for i in 0..topo.n_triangles() {
            w.write_all(if i == 0 { b"3" } else { b", 3" })
                .map_err(&io)?;
        }
        w.write_all(b"]\n        int[] faceVertexIndices = [")
            .map_err(&io)?;
        for (i, t) in topo.triangles().iter().enumerate() {
            let sep = if i == 0 { "" } else { ", " };
            write!(w, "{sep}{}, {}, {}", t[0], t[1], t[2]).map_err(&io)?;
        }
        w.write_all(b"]\n").map_err(&io)?;
        if let Some(uvs) = topo.uvs() {
            w.write_all(b"        texCoord2f[] primvars:st = [")
                .map_err(&io)?;
            for (i, c) in uvs.uv().iter().enumerate() {
                let sep = if i == 0 { "" } else { ", " };
                write!(w, "{sep}({}, {})", fmt_f32(c[0]), fmt_f32(c[1])).map_err(&io)?;
            }
            w.write_all(
                b"] (\n            interpolation = \"faceVarying\"\n        )\n        int[] primvars:st:indices = [",
            )
            .map_err(&io)?;
            for (i, c) in uvs.corners().iter().enumerate() {
                let sep = if i == 0 { "" } else { ", " };
                write!(w, "{sep}{}, {}, {}", c[0], c[1], c[2]).map_err(&io)?;
            }
            w.write_all(b"]\n").map_err(&io)?;
        }
        w.write_all(b"        point3f[] points.timeSamples = {\n")
            .map_err(&io)?;
        let mut extents = Vec::with_capacity(n);
        for t in 0..n {
            let p: Vec<[f32; 3]> = frames.read(t)?.into_iter().map(to_f32).collect();
            extents.push(extent(&p));
            write!(w, "            {}: ", time(t)).map_err(&io)?;
            write_vec3_array(w, &p).map_err(&io)?;
            w.write_all(b",\n").map_err(&io)?;
        }
        w.write_all(b"        }\n        normal3f[] normals (\n            interpolation = \"vertex\"\n        )\n")
            .map_err(&io)?;
        w.write_all(b"        normal3f[] normals.timeSamples = {\n")
            .map_err(&io)?;
        for t in 0..n {
            let p = frames.read(t)?;
            write!(w, "            {}: ", time(t)).map_err(&io)?;
            write_vec3_array(w, &unit_normals(&topo, &p)).map_err(&io)?;
            w.write_all(b",\n").map_err(&io)?;
        }
        w.write_all(b"        }\n        float3[] extent.timeSamples = {\n")
            .map_err(&io)?;
        for (t, e) in extents.iter().enumerate() {
            write!(w, "            {}: ", time(t)).map_err(&io)?;
            write_vec3_array(w, e).map_err(&io)?;
            w.write_all(b",\n").map_err(&io)?;
        }
        w.write_all(b"        }\n    }\n}\n").map_err(&io)?;
        Ok(())
    })
}

fn extent(p: &[[f32; 3]]) -> [[f32; 3]; 2] {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for v in p {
        for c in 0..3 {
            lo[c] = lo[c].min(v[c]);
            hi[c] = hi[c].max(v[c]);
        }
    }
    [lo, hi]
}

/// `[(x, y, z), …]` with each `f32` in its shortest round-trip form.
fn write_vec3_array(w: &mut impl Write, v: &[[f32; 3]]) -> std::io::Result<()> {
    w.write_all(b"[")?;
    for (i, p) in v.iter().enumerate() {
        let sep = if i == 0 { "" } else { ", " };
        write!(
            w,
            "{sep}({}, {}, {})",
            fmt_f32(p[0]),
            fmt_f32(p[1]),
            fmt_f32(p[2])
        )?;
    }
    w.write_all(b"]")
}

/// Rust's shortest round-trip form (`0.1`, `1.0`, `1e-7`), which USD's parser reads back to the same `f32`;
/// `-0` is written as `0`.
fn fmt_f32(x: f32) -> String {
    if x == 0.0 {
        return "0".into();
    }
    format!("{x:?}")
}

fn fmt_num(x: f64) -> String {
    if x.fract() == 0.0 && x.abs() < 1e15 {
        format!("{}", x as i64)
    } else {
        format!("{x}")
    }
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::super::test_support::two_triangles;
    use super::super::{export, ExportFormat, ExportOptions};
    use crate::progress::NoProgress;

    /// Parses the `points.timeSamples` dictionary back into f32 triples per time code.
    fn points_samples(text: &str) -> Vec<(f64, Vec<[f32; 3]>)> {
        let start = text.find("points.timeSamples = {").unwrap();
        let body = &text[start..];
        let body = &body[body.find('\n').unwrap() + 1..body.find("\n        }").unwrap()];
        body.lines()
            .map(|line| {
                let (time, arr) = line.trim().split_once(": ").unwrap();
                let arr = arr.trim_end_matches(',');
                let nums: Vec<f32> = arr
                    .trim_matches(['[', ']'])
                    .split(['(', ')', ','])
                    .map(str::trim)
                    .filter(|s| !s.is_empty())
                    .map(|s| s.parse().unwrap())
                    .collect();
                (
                    time.parse().unwrap(),
                    nums.chunks(3).map(|c| [c[0], c[1], c[2]]).collect(),
                )
            })
            .collect()
    }

    #[test]
    fn every_frame_is_a_time_sample_with_exact_f32_points() {
        let seq = two_triangles(4);
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("a.usda");
        export(
            &seq,
            ExportFormat::Usd,
            &out,
            &ExportOptions::default(),
            &NoProgress,
        )
        .unwrap();
        let text = std::fs::read_to_string(&out).unwrap();
        assert!(text.starts_with("#usda 1.0\n"));
        assert!(text.contains("int[] faceVertexIndices = [0, 1, 2, 0, 2, 3]"));
        assert!(text.contains("startTimeCode = 1\n") && text.contains("endTimeCode = 4\n"));
        let samples = points_samples(&text);
        assert_eq!(samples.len(), 4);
        for (t, (time, pts)) in samples.iter().enumerate() {
            assert_eq!(*time, 1.0 + t as f64);
            let want: Vec<[f32; 3]> = seq.frames[t].iter().map(|p| super::to_f32(*p)).collect();
            assert_eq!(pts, &want, "frame {t}");
        }
        assert_eq!(text.matches("normals.timeSamples").count(), 1);
        assert_eq!(text.matches("extent.timeSamples").count(), 1);
        assert!(!text.contains("primvars:st"), "no UVs in, none out");
    }

    /// The UV tube's texture coordinates come out as an indexed faceVarying `st` whose value at every face
    /// corner is the corner's own coordinate.
    #[test]
    fn texture_coordinates_are_an_indexed_face_varying_primvar() {
        let seq = crate::synth::uv_tube(5, 3, 2).unwrap();
        let uvs = seq.topology.uvs().unwrap().clone();
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("a.usda");
        export(
            &seq,
            ExportFormat::Usd,
            &out,
            &ExportOptions::default(),
            &NoProgress,
        )
        .unwrap();
        let text = std::fs::read_to_string(&out).unwrap();
        let line = |key: &str| {
            let at = text.find(key).unwrap_or_else(|| panic!("no {key}"));
            let rest = &text[at..];
            let open = rest.find("= [").unwrap() + 3;
            rest[open..open + rest[open..].find(']').unwrap()].to_string()
        };
        let values: Vec<f32> = line("texCoord2f[] primvars:st = ")
            .split(['(', ')', ','])
            .map(str::trim)
            .filter(|s| !s.is_empty())
            .map(|s| s.parse().unwrap())
            .collect();
        let indices: Vec<usize> = line("int[] primvars:st:indices = ")
            .split(", ")
            .map(|s| s.parse().unwrap())
            .collect();
        assert!(text.contains("interpolation = \"faceVarying\""));
        assert_eq!(indices.len(), 3 * seq.topology.n_triangles());
        for (i, &k) in indices.iter().enumerate() {
            let want = uvs.uv()[uvs.corners()[i / 3][i % 3] as usize];
            assert_eq!([values[2 * k], values[2 * k + 1]], want, "corner {i}");
        }
    }
}

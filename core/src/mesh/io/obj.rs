//! Wavefront OBJ: a fast hand-written reader for sequence frames, a rewriter that swaps in new positions while
//! keeping everything else of the input file, and a plain writer for generated data.
//!
//! Only what a frame of a captured sequence needs is interpreted: `v` (positions, with optional extra columns
//! such as `w` or vertex colours) and `f` (polygons in the `i`, `i/t`, `i//n`, `i/t/n` forms, with negative
//! indices relative to the vertices defined so far). The first frame (or a point cache's topology OBJ) is
//! also read for its texture coordinates (`vt` and the `t` of `i/t`), which hold for the whole sequence; later
//! frames skip them. Every other statement (`vn`, `o`, `g`, `s`, `usemtl`, `mtllib`, `l`, comments, …) is
//! ignored on input and kept verbatim on output. Line continuations (`\` at the end of a line) are not
//! supported.

use super::faces::Polygons;
use super::tokens::{self, parse_f64, parse_i64, show};
use crate::error::{Error, Result};
use crate::fsutil;
use crate::mesh::{geometry, Topology, UvSet};
use crate::vec3::V3;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Positions and original polygons of one OBJ file.
#[derive(Debug, Clone)]
pub(crate) struct ObjMesh {
    pub positions: Vec<V3>,
    pub faces: Polygons,
    /// Per-corner texture coordinates, triangulated like `faces`: read only by [`parse_obj_with_uvs`], and
    /// only when every face has them (a file where some faces have none is read without UVs).
    pub uvs: Option<UvSet>,
}

/// The 1-based absolute index of OBJ index `idx` given `defined` elements so far (negative indices count
/// back from the last one), or what is wrong with it.
fn absolute_index(idx: i64, defined: i64, what: &str) -> std::result::Result<i64, String> {
    let abs = match idx {
        0 => {
            return Err(format!(
                "{what} index 0 is invalid (OBJ indices start at 1)"
            ))
        }
        i if i < 0 => {
            let abs = defined + i + 1;
            if abs < 1 {
                return Err(format!(
                    "relative {what} index {i} points before the first {what} ({defined} are defined above this \
                     line)"
                ));
            }
            abs
        }
        i => i,
    };
    if abs > i64::from(u32::MAX - 1) {
        return Err(format!("{what} index {idx} is too large"));
    }
    Ok(abs)
}

/// Tokens of a statement up to an inline `#` comment.
fn statement_tokens(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    tokens::tokens(line).take_while(|t| t.first() != Some(&b'#'))
}

/// Parses the bytes of an OBJ file without its texture coordinates (frames after the first). Errors are
/// [`Error::Format`] naming `path` and the line; geometric checks (finite values, degenerate triangles) are
/// left to frame validation.
pub(crate) fn parse_obj(path: &Path, bytes: &[u8]) -> Result<ObjMesh> {
    parse(path, bytes, false)
}

/// Like [`parse_obj`], also reading the texture coordinates. A face whose corners mix `i/t` and `i` forms,
/// or a `t` out of range, is an error naming the line.
pub(crate) fn parse_obj_with_uvs(path: &Path, bytes: &[u8]) -> Result<ObjMesh> {
    parse(path, bytes, true)
}

fn parse(path: &Path, bytes: &[u8], want_uvs: bool) -> Result<ObjMesh> {
    let bytes = tokens::strip_bom(bytes);
    if bytes.iter().all(|b| b.is_ascii_whitespace()) {
        return Err(Error::format(path, None, "the file is empty"));
    }
    // A cheap over-estimate (one statement per ~30 bytes) avoids most re-allocations on large frames.
    let mut positions: Vec<V3> = Vec::with_capacity(bytes.len() / 60);
    let mut faces = Polygons::with_capacity(bytes.len() / 60, bytes.len() / 20);
    let mut poly: Vec<u32> = Vec::with_capacity(8);
    // Largest absolute (1-based) index and the line it was on: positive indices may refer to vertices defined
    // later in the file, so the range check happens once the vertex count is known.
    let mut max_ref: Option<(i64, usize)> = None;
    let mut uv: Vec<[f32; 2]> = Vec::new();
    let mut uv_faces = Polygons::default();
    let mut uv_poly: Vec<u32> = Vec::with_capacity(8);
    let mut max_uv_ref: Option<(i64, usize)> = None;
    for (line_no, line) in tokens::lines(bytes) {
        let mut toks = statement_tokens(line);
        match toks.next() {
            Some(b"v") => {
                let mut p = [0.0; 3];
                for (k, c) in p.iter_mut().enumerate() {
                    let tok = toks.next().ok_or_else(|| {
                        Error::format(
                            path,
                            Some(line_no),
                            format!(
                                "vertex has {k} coordinates, 3 are needed (`{}`)",
                                show(line)
                            ),
                        )
                    })?;
                    *c = parse_f64(tok).ok_or_else(|| {
                        Error::format(
                            path,
                            Some(line_no),
                            format!("cannot read vertex coordinate `{}` as a number", show(tok)),
                        )
                    })?;
                }
                positions.push(p);
            }
            Some(b"vt") if want_uvs => uv.push(parse_vt(path, line_no, line, toks)?),
            Some(b"f") => {
                poly.clear();
                uv_poly.clear();
                let defined = positions.len() as i64;
                for tok in toks {
                    let mut parts = tok.split(|&b| b == b'/');
                    let idx_text = parts.next().unwrap_or(tok);
                    let face_error = |msg: String| {
                        Error::format(
                            path,
                            Some(line_no),
                            format!("{msg} in face `{}`", show(line)),
                        )
                    };
                    let idx = parse_i64(idx_text).ok_or_else(|| {
                        face_error(format!("cannot read vertex index `{}`", show(tok)))
                    })?;
                    let abs = absolute_index(idx, defined, "vertex").map_err(face_error)?;
                    if max_ref.is_none_or(|(m, _)| abs > m) {
                        max_ref = Some((abs, line_no));
                    }
                    poly.push((abs - 1) as u32);
                    match parts.next() {
                        Some(t) if want_uvs && !t.is_empty() => {
                            let i = parse_i64(t).ok_or_else(|| {
                                face_error(format!(
                                    "cannot read texture coordinate index `{}`",
                                    show(tok)
                                ))
                            })?;
                            let abs = absolute_index(i, uv.len() as i64, "texture coordinate")
                                .map_err(face_error)?;
                            if max_uv_ref.is_none_or(|(m, _)| abs > m) {
                                max_uv_ref = Some((abs, line_no));
                            }
                            uv_poly.push((abs - 1) as u32);
                        }
                        _ => {}
                    }
                }
                if want_uvs && !uv_poly.is_empty() && uv_poly.len() != poly.len() {
                    return Err(Error::format(
                        path,
                        Some(line_no),
                        format!(
                            "face `{}` mixes corners with and without texture coordinates ({} of {} have one); \
                             give every corner a `v/vt` or none",
                            show(line),
                            uv_poly.len(),
                            poly.len()
                        ),
                    ));
                }
                if poly.len() < 3 {
                    return Err(Error::format(
                        path,
                        Some(line_no),
                        format!(
                            "face has {} vertices, at least 3 are needed (`{}`)",
                            poly.len(),
                            show(line)
                        ),
                    ));
                }
                faces.push(&poly);
                if want_uvs && !uv_poly.is_empty() {
                    uv_faces.push(&uv_poly);
                }
            }
            _ => {}
        }
    }
    if positions.is_empty() {
        return Err(Error::format(
            path,
            None,
            "the file has no vertices (no `v` lines)",
        ));
    }
    if faces.is_empty() {
        return Err(Error::format(
            path,
            None,
            "the file has no faces (no `f` lines); every frame must be a polygon mesh",
        ));
    }
    if let Some((m, line_no)) = max_ref {
        if m as usize > positions.len() {
            let text = line_text(bytes, line_no);
            return Err(Error::format(
                path,
                Some(line_no),
                format!(
                    "face `{text}` references vertex {m}, but the file has only {} vertices",
                    positions.len()
                ),
            ));
        }
    }
    if let Some((m, line_no)) = max_uv_ref.filter(|&(m, _)| m as usize > uv.len()) {
        return Err(Error::format(
            path,
            Some(line_no),
            format!(
                "face `{}` references texture coordinate {m}, but the file has only {} (`vt` lines)",
                line_text(bytes, line_no),
                uv.len()
            ),
        ));
    }
    let uvs = if want_uvs && uv_faces.len() == faces.len() {
        Some(
            UvSet::new(uv, uv_faces.triangulate())
                .map_err(|e| e.at(Some(path.to_path_buf()), None))?,
        )
    } else {
        None
    };
    Ok(ObjMesh {
        positions,
        faces,
        uvs,
    })
}

/// Text of 1-based line `line_no`, for messages.
fn line_text(bytes: &[u8], line_no: usize) -> String {
    tokens::lines(bytes)
        .nth(line_no - 1)
        .map(|(_, l)| show(l))
        .unwrap_or_default()
}

/// A `vt u [v [w]]` statement: `v` defaults to 0 and `w` is ignored (OBJ's rules); values must be finite.
fn parse_vt<'a>(
    path: &Path,
    line_no: usize,
    line: &[u8],
    mut toks: impl Iterator<Item = &'a [u8]>,
) -> Result<[f32; 2]> {
    let err = |msg: String| Error::format(path, Some(line_no), msg);
    let mut read = |required: bool| -> Result<f32> {
        match toks.next() {
            None if required => Err(err(format!(
                "texture coordinate has no values (`{}`)",
                show(line)
            ))),
            None => Ok(0.0),
            Some(tok) => match tokens::parse_f32(tok) {
                Some(x) if x.is_finite() => Ok(x),
                _ => Err(err(format!(
                    "cannot read texture coordinate `{}` as a finite number",
                    show(tok)
                ))),
            },
        }
    };
    Ok([read(true)?, read(false)?])
}

/// 1-based line number of face `k` (0-based, in file order) in an OBJ file's bytes.
pub(crate) fn face_line(bytes: &[u8], k: usize) -> Option<usize> {
    tokens::lines(tokens::strip_bom(bytes))
        .filter(|(_, line)| statement_tokens(line).next() == Some(b"f"))
        .nth(k)
        .map(|(n, _)| n)
}

/// Rewrites an OBJ file with new positions, for writing a processed frame in the layout of its input.
///
/// * every `v` line gets the next position (in order), followed by whatever the line had after its third
///   coordinate (a `w` or vertex colour columns, an inline comment);
/// * `vn` lines are dropped and normal references are stripped from `f` lines (`1/2/3` → `1/2`, `1//3` → `1`):
///   the input's normals describe the input's shape and would be wrong for the new positions, and a renderer
///   recomputes normals when none are given;
/// * every other line (comments, `vt`, groups, materials, the original polygons) is copied byte for byte,
///   including its line ending.
///
/// Coordinates are written as the shortest decimal that reads back as the same `f64`, so output is exact and
/// deterministic. `src` is the input file's content; `path` only names it in errors.
pub(crate) fn rewrite_obj(path: &Path, src: &[u8], positions: &[V3]) -> Result<Vec<u8>> {
    let mut out = Vec::with_capacity(src.len() + src.len() / 4);
    let body = match src.strip_prefix(b"\xEF\xBB\xBF") {
        Some(rest) => {
            out.extend_from_slice(b"\xEF\xBB\xBF");
            rest
        }
        None => src,
    };
    let mut next_vertex = 0usize;
    let mut line_no = 0usize;
    for (line, ending) in tokens::lines_with_endings(body) {
        line_no += 1;
        let mut spans = tokens::token_spans(line).take_while(|&(s, _)| line.get(s) != Some(&b'#'));
        let keyword = spans.next();
        match keyword.and_then(|(s, e)| line.get(s..e)) {
            Some(b"v") => {
                let (_, kw_end) = keyword.unwrap_or((0, 0));
                let Some((_, third_end)) = spans.nth(2) else {
                    return Err(Error::format(
                        path,
                        Some(line_no),
                        "vertex has fewer than 3 coordinates",
                    ));
                };
                let Some(p) = positions.get(next_vertex) else {
                    return Err(Error::mesh(format!(
                        "has more vertices than the {} positions given for it (line {line_no})",
                        positions.len()
                    ))
                    .at(Some(path.to_path_buf()), None));
                };
                next_vertex += 1;
                out.extend_from_slice(line.get(..kw_end).unwrap_or_default());
                for &c in p {
                    out.push(b' ');
                    tokens::push_f64(&mut out, c);
                }
                out.extend_from_slice(line.get(third_end..).unwrap_or_default());
                out.extend_from_slice(ending);
            }
            Some(b"vn") => {}
            Some(b"f") => {
                let mut copied = 0;
                for (s, e) in spans {
                    out.extend_from_slice(line.get(copied..s).unwrap_or_default());
                    let tok = line.get(s..e).unwrap_or_default();
                    let mut parts = tok.splitn(3, |&b| b == b'/');
                    match (parts.next(), parts.next(), parts.next()) {
                        (Some(i), Some(t), Some(_normal)) => {
                            out.extend_from_slice(i);
                            if !t.is_empty() {
                                out.push(b'/');
                                out.extend_from_slice(t);
                            }
                        }
                        _ => out.extend_from_slice(tok),
                    }
                    copied = e;
                }
                out.extend_from_slice(line.get(copied..).unwrap_or_default());
                out.extend_from_slice(ending);
            }
            _ => {
                out.extend_from_slice(line);
                out.extend_from_slice(ending);
            }
        }
    }
    if next_vertex != positions.len() {
        return Err(Error::mesh(format!(
            "has {next_vertex} vertices, but {} positions were given for it",
            positions.len()
        ))
        .at(Some(path.to_path_buf()), None));
    }
    Ok(out)
}

/// Writes a plain OBJ (`v` and `f` lines only, 1-based triangle indices) atomically; when the topology has
/// texture coordinates, also its `vt` lines and `f v/vt` corners.
pub fn write_obj(path: &Path, topology: &Topology, positions: &[V3]) -> Result<()> {
    geometry::check_position_count(topology, positions.len(), path)?;
    fsutil::write_atomic_with(path, |w| {
        let mut buf = Vec::with_capacity(64);
        for p in positions {
            buf.clear();
            buf.push(b'v');
            for &c in p {
                buf.push(b' ');
                tokens::push_f64(&mut buf, c);
            }
            buf.push(b'\n');
            w.write_all(&buf)?;
        }
        match topology.uvs() {
            None => {
                for t in topology.triangles() {
                    writeln!(w, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1)?;
                }
            }
            Some(uvs) => {
                for c in uvs.uv() {
                    buf.clear();
                    buf.extend_from_slice(b"vt ");
                    tokens::push_f32(&mut buf, c[0]);
                    buf.push(b' ');
                    tokens::push_f32(&mut buf, c[1]);
                    buf.push(b'\n');
                    w.write_all(&buf)?;
                }
                for (t, c) in topology.triangles().iter().zip(uvs.corners()) {
                    writeln!(
                        w,
                        "f {}/{} {}/{} {}/{}",
                        t[0] + 1,
                        c[0] + 1,
                        t[1] + 1,
                        c[1] + 1,
                        t[2] + 1,
                        c[2] + 1
                    )?;
                }
            }
        }
        Ok(())
    })
}

/// Writes a directory of plain OBJ frames (see [`write_obj`]) named by the caller, creating `dir` if needed, and
/// returns the paths written. Used for generated demo data and test inputs.
pub fn write_obj_sequence<'a>(
    dir: &Path,
    topology: &Topology,
    frames: impl IntoIterator<Item = (String, &'a [V3])>,
) -> Result<Vec<PathBuf>> {
    fsutil::create_dir_all(dir)?;
    let mut written = Vec::new();
    for (name, positions) in frames {
        let plain = Path::new(&name)
            .file_name()
            .is_some_and(|n| n == name.as_str());
        if !plain {
            return Err(Error::param(
                "file name",
                format!("`{name}` must be a plain file name without directories"),
            ));
        }
        let path = dir.join(&name);
        write_obj(&path, topology, positions)?;
        written.push(path);
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(src: &str) -> Result<ObjMesh> {
        parse_obj(Path::new("t.obj"), src.as_bytes())
    }

    fn parse_uv(src: &str) -> Result<ObjMesh> {
        parse_obj_with_uvs(Path::new("t.obj"), src.as_bytes())
    }

    #[test]
    fn face_forms_and_relative_indices() {
        let m =
            parse("v 0 0 0\nv 1 0 0\nv 1 1 0 0.5 0.5 0.5\nv 0 1 0\r\nf 1/1/1 2//2 3/3 -1 # quad\n")
                .unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.faces.get(0), &[0, 1, 2, 3]);
        assert_eq!(m.faces.triangulate(), vec![[0, 1, 2], [0, 2, 3]]);
        assert!(m.uvs.is_none());
    }

    const QUAD: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1 0\nvt 0.25\n";

    #[test]
    fn texture_coordinates_are_per_corner_in_every_face_form() {
        // `v/vt/vn` and `v/vt` with absolute and relative indices; the quad's fan splits the UV polygon alike.
        let m = parse_uv(&format!("{QUAD}vn 0 0 1\nf 1/1/1 2/2/1 3/-2 4/-1\n")).unwrap();
        let uvs = m.uvs.expect("the file has texture coordinates");
        assert_eq!(uvs.uv(), &[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.25, 0.0]]);
        assert_eq!(uvs.corners(), &[[0, 1, 2], [0, 2, 3]]);
        // `v//vn` and plain faces have none; neither has a file where only some faces have them.
        assert!(parse_uv(&format!("{QUAD}f 1//1 2//1 3//1\n"))
            .unwrap()
            .uvs
            .is_none());
        assert!(parse_uv(&format!("{QUAD}f 1/1 2/2 3/3\nf 1 3 4\n"))
            .unwrap()
            .uvs
            .is_none());
        // Frames after the first skip texture coordinates altogether.
        assert!(parse(&format!("{QUAD}f 1/1 2/2 3/3\n"))
            .unwrap()
            .uvs
            .is_none());
    }

    #[test]
    fn bad_texture_coordinates_name_the_file_and_line() {
        let e = parse_uv(&format!("{QUAD}f 1/1 2/2 3/3\nf 1/1 3 4/4\n"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("t.obj:10:") && e.contains("mixes corners"),
            "{e}"
        );
        let e = parse_uv(&format!("{QUAD}f 1/1 2/9 3/3\n"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("t.obj:9:") && e.contains("texture coordinate 9, but the file has only 4"),
            "{e}"
        );
        let e = parse_uv(&format!("{QUAD}f 1/-7 2/1 3/1\n"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("t.obj:9:") && e.contains("relative texture coordinate index -7"),
            "{e}"
        );
        let e = parse_uv("v 0 0 0\nvt nan 0\n").unwrap_err().to_string();
        assert!(e.contains("t.obj:2:") && e.contains("`nan`"), "{e}");
        let e = parse_uv("v 0 0 0\nvt\n").unwrap_err().to_string();
        assert!(e.contains("t.obj:2:") && e.contains("no values"), "{e}");
    }

    #[test]
    fn written_texture_coordinates_read_back_per_corner() {
        let m = parse_uv(&format!("{QUAD}f 1/1 2/2 3/3 4/4\n")).unwrap();
        let topo = Topology::new(4, m.faces.triangulate())
            .unwrap()
            .with_uvs(m.uvs.clone())
            .unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.obj");
        write_obj(&path, &topo, &m.positions).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(
            text.contains("\nvt 0.25 0\n") && text.contains("\nf 1/1 2/2 3/3\n"),
            "{text}"
        );
        let back = parse_uv(&text).unwrap();
        assert_eq!(back.uvs, m.uvs);
        assert_eq!(back.positions, m.positions);
        // Without texture coordinates the file is as before: `v` and `f i j k` only.
        write_obj(&path, &topo.clone().with_uvs(None).unwrap(), &m.positions).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(
            !text.contains("vt") && text.contains("\nf 1 2 3\n"),
            "{text}"
        );
    }

    #[test]
    fn nan_parses_for_validation() {
        let m = parse("v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
        assert!(m.positions[0][0].is_nan());
    }

    #[test]
    fn rewrite_keeps_everything_else() {
        let src = b"# c\r\nv 0 0 0 1 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nf 1/1/1 2//1 3/1\n";
        let out = rewrite_obj(
            Path::new("t.obj"),
            src,
            &[[0.5, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 2.0, 0.0]],
        )
        .unwrap();
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "# c\r\nv 0.5 0 0 1 0 0\nv 1 0 0\nv 0 2 0\nvt 0 0\nf 1/1 2 3/1\n"
        );
    }
}

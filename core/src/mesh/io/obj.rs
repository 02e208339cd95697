//! Wavefront OBJ: a fast hand-written reader for sequence frames, a rewriter that swaps in new positions while
//! keeping everything else of the input file, and a plain writer for generated data.
//!
//! Only what a frame of a captured sequence needs is interpreted: `v` (positions, with optional extra columns
//! such as `w` or vertex colours) and `f` (polygons in the `i`, `i/t`, `i//n`, `i/t/n` forms, with negative
//! indices relative to the vertices defined so far). Every other statement (`vt`, `vn`, `o`, `g`, `s`,
//! `usemtl`, `mtllib`, `l`, comments, …) is ignored on input and kept verbatim on output. Line continuations
//! (`\` at the end of a line) are not supported.

use super::faces::Polygons;
use super::tokens::{self, parse_f64, parse_i64, show};
use crate::error::{Error, Result};
use crate::fsutil;
use crate::mesh::{geometry, Topology};
use crate::vec3::V3;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Positions and original polygons of one OBJ file.
#[derive(Debug, Clone)]
pub(crate) struct ObjMesh {
    pub positions: Vec<V3>,
    pub faces: Polygons,
}

/// Tokens of a statement up to an inline `#` comment.
fn statement_tokens(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    tokens::tokens(line).take_while(|t| t.first() != Some(&b'#'))
}

/// Parses the bytes of an OBJ file. Errors are [`Error::Format`] naming `path` and the line; geometric checks
/// (finite values, degenerate triangles) are left to frame validation.
pub(crate) fn parse_obj(path: &Path, bytes: &[u8]) -> Result<ObjMesh> {
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
            Some(b"f") => {
                poly.clear();
                let defined = positions.len() as i64;
                for tok in toks {
                    let idx_text = tok.split(|&b| b == b'/').next().unwrap_or(tok);
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
                    let abs = match idx {
                        0 => {
                            return Err(face_error(
                                "vertex index 0 is invalid (OBJ indices start at 1)".into(),
                            ))
                        }
                        i if i < 0 => {
                            let abs = defined + i + 1;
                            if abs < 1 {
                                return Err(face_error(format!(
                                    "relative vertex index {i} points before the first vertex ({defined} vertices \
                                     are defined above this line)"
                                )));
                            }
                            abs
                        }
                        i => i,
                    };
                    if abs > i64::from(u32::MAX - 1) {
                        return Err(face_error(format!("vertex index {idx} is too large")));
                    }
                    if max_ref.is_none_or(|(m, _)| abs > m) {
                        max_ref = Some((abs, line_no));
                    }
                    poly.push((abs - 1) as u32);
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
            let text = tokens::lines(bytes)
                .nth(line_no - 1)
                .map(|(_, l)| show(l))
                .unwrap_or_default();
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
    Ok(ObjMesh { positions, faces })
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

/// Writes a plain OBJ (`v` and `f` lines only, 1-based triangle indices) atomically.
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
        for t in topology.triangles() {
            writeln!(w, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1)?;
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

    #[test]
    fn face_forms_and_relative_indices() {
        let m =
            parse("v 0 0 0\nv 1 0 0\nv 1 1 0 0.5 0.5 0.5\nv 0 1 0\r\nf 1/1/1 2//2 3/3 -1 # quad\n")
                .unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.faces.get(0), &[0, 1, 2, 3]);
        assert_eq!(m.faces.triangulate(), vec![[0, 1, 2], [0, 2, 3]]);
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

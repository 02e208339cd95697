//! Problems in an OBJ frame named the way the file numbers things: OBJ counts vertices and faces from 1, and
//! someone fixing a file goes by line, so a vertex or triangle the mesh checks find by 0-based index is reported
//! as the file's vertex or face number with the line it is on.

use super::faces::{describe_face, Polygons};
use super::tokens;
use crate::error::{Error, Result};
use crate::mesh::geometry::FrameProblem;
use std::path::Path;

/// 1-based line of the `k`-th (0-based) statement with keyword `kw` (`v`, `f`).
fn statement_line(bytes: &[u8], kw: &[u8], k: usize) -> Option<usize> {
    tokens::lines(tokens::strip_bom(bytes))
        .filter(|(_, line)| tokens::tokens(line).next() == Some(kw))
        .nth(k)
        .map(|(n, _)| n)
}

/// Face (0-based, file order) that fan triangle `t` of the triangulated polygons came from.
fn face_of_triangle(faces: &Polygons, t: usize) -> Option<usize> {
    let mut first = 0usize;
    for (k, face) in faces.iter().enumerate() {
        let n = face.len().saturating_sub(2);
        if t < first + n {
            return Some(k);
        }
        first += n;
    }
    None
}

fn on_line(line: Option<usize>) -> String {
    line.map(|l| format!(" (line {l})")).unwrap_or_default()
}

/// The message for a geometry problem of an OBJ frame, in the file's numbering.
pub(crate) fn describe(problem: &FrameProblem, faces: &Polygons, bytes: &[u8]) -> String {
    match problem {
        FrameProblem::NonFinite { vertex, at } => format!(
            "vertex {}{} has a non-finite coordinate ({}, {}, {})",
            vertex + 1,
            on_line(statement_line(bytes, b"v", *vertex)),
            at[0],
            at[1],
            at[2]
        ),
        FrameProblem::Degenerate { triangle, vertices } => {
            let corners = vertices.map(|v| (v + 1).to_string()).join(" ");
            match face_of_triangle(faces, *triangle) {
                Some(k) => format!(
                    "face {}{} (`f {}`) is degenerate (zero area{})",
                    k + 1,
                    on_line(statement_line(bytes, b"f", k)),
                    describe_face(faces.get(k), 1),
                    if faces.get(k).len() > 3 {
                        format!(", in its fan triangle of vertices {corners}")
                    } else {
                        String::new()
                    }
                ),
                None => format!("the triangle of vertices {corners} is degenerate (zero area)"),
            }
        }
    }
}

/// Refuses a face that names one vertex twice, and an edge shared by more than two faces, by face number and
/// line, before the topology would report them as 0-based triangles.
pub(crate) fn check_faces(path: &Path, faces: &Polygons, bytes: &[u8]) -> Result<()> {
    check_repeats(path, faces, bytes)?;
    // Undirected edges of the fan triangles with the face each came from; a run of three or more equal edges
    // is non-manifold.
    let mut edges: Vec<((u32, u32), usize)> = Vec::new();
    for (k, face) in faces.iter().enumerate() {
        if let Some((&a, rest)) = face.split_first() {
            for w in rest.windows(2) {
                let (b, c) = (w[0], w[1]);
                for (x, y) in [(a, b), (b, c), (c, a)] {
                    edges.push(((x.min(y), x.max(y)), k));
                }
            }
        }
    }
    edges.sort_unstable();
    for run in edges.chunk_by(|p, q| p.0 == q.0) {
        if run.len() > 2 {
            let (a, b) = run[0].0;
            let list: Vec<String> = run
                .iter()
                .map(|&(_, k)| format!("{}{}", k + 1, on_line(statement_line(bytes, b"f", k))))
                .collect();
            return Err(Error::mesh(format!(
                "non-manifold edge between vertices {} and {} is shared by {} faces: {}",
                a + 1,
                b + 1,
                run.len(),
                list.join(", ")
            ))
            .at(Some(path.to_path_buf()), Some(0)));
        }
    }
    Ok(())
}

fn check_repeats(path: &Path, faces: &Polygons, bytes: &[u8]) -> Result<()> {
    for (k, face) in faces.iter().enumerate() {
        let mut seen = face.to_vec();
        seen.sort_unstable();
        if seen.windows(2).any(|w| w[0] == w[1]) {
            return Err(Error::mesh(format!(
                "face {}{} (`f {}`) repeats a vertex: it has zero area",
                k + 1,
                on_line(statement_line(bytes, b"f", k)),
                describe_face(face, 1)
            ))
            .at(Some(path.to_path_buf()), Some(0)));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::io::obj::parse_obj;

    const QUADS: &str = "# two quads\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 2 1 0\n\nf 1 2 3 4\nf 2 5 6 3\n";

    #[test]
    fn numbers_and_lines_are_the_files() {
        let m = parse_obj(Path::new("a.obj"), QUADS.as_bytes()).unwrap();
        assert_eq!(face_of_triangle(&m.faces, 0), Some(0));
        assert_eq!(face_of_triangle(&m.faces, 3), Some(1));
        assert_eq!(face_of_triangle(&m.faces, 4), None);
        let nan = describe(
            &FrameProblem::NonFinite {
                vertex: 4,
                at: [f64::NAN, 0.0, 0.0],
            },
            &m.faces,
            QUADS.as_bytes(),
        );
        assert!(
            nan.starts_with("vertex 5 (line 6) has a non-finite"),
            "{nan}"
        );
        let flat = describe(
            &FrameProblem::Degenerate {
                triangle: 2,
                vertices: [1, 4, 5],
            },
            &m.faces,
            QUADS.as_bytes(),
        );
        assert!(
            flat.starts_with("face 2 (line 10) (`f 2 5 6 3`) is degenerate"),
            "{flat}"
        );
        assert!(flat.contains("vertices 2 5 6"), "{flat}");
    }

    #[test]
    fn a_repeated_vertex_names_the_face_and_line() {
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\nf 1 2 2\n";
        let m = parse_obj(Path::new("b.obj"), text.as_bytes()).unwrap();
        let e = check_faces(Path::new("b.obj"), &m.faces, text.as_bytes()).unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.contains("face 2 (line 5) (`f 1 2 2`) repeats a vertex"),
            "{msg}"
        );
    }
}

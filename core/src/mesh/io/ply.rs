//! Stanford PLY (ASCII, binary little- and big-endian): a hand-written reader for sequence frames, a rewriter
//! that swaps in new positions (and recomputed normals) while keeping every other byte of the input, and a
//! plain writer for generated data.
//!
//! The reader needs a `vertex` element with scalar `x`, `y`, `z` properties and a `face` element with a
//! `vertex_indices` (or `vertex_index`) list; every other element and property is walked over (so its data is
//! skipped correctly, also in binary files) and left alone.

use super::faces::Polygons;
use super::tokens::{self, parse_f32, parse_f64, parse_i64, show};
use crate::error::{Error, Result};
use crate::fsutil;
use crate::mesh::{geometry, Topology};
use crate::vec3::V3;
use std::io::Write;
use std::path::Path;

/// How the data after the header is stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Encoding {
    Ascii,
    BinaryLe,
    BinaryBe,
}

/// PLY scalar types (both the classic and the sized spellings map here).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn from_name(name: &[u8]) -> Option<Scalar> {
        Some(match name {
            b"char" | b"int8" => Scalar::I8,
            b"uchar" | b"uint8" => Scalar::U8,
            b"short" | b"int16" => Scalar::I16,
            b"ushort" | b"uint16" => Scalar::U16,
            b"int" | b"int32" => Scalar::I32,
            b"uint" | b"uint32" => Scalar::U32,
            b"float" | b"float32" => Scalar::F32,
            b"double" | b"float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_float(self) -> bool {
        matches!(self, Scalar::F32 | Scalar::F64)
    }
}

/// A property's storage: one scalar, or a length-prefixed list.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum PropKind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug, Clone)]
pub(crate) struct Property {
    pub name: String,
    pub kind: PropKind,
}

#[derive(Debug, Clone)]
pub(crate) struct Element {
    pub name: String,
    pub count: usize,
    pub props: Vec<Property>,
    /// Header line declaring the element, for messages.
    pub line: usize,
}

impl Element {
    fn scalar_prop(&self, name: &str) -> Option<(usize, Scalar)> {
        self.props
            .iter()
            .enumerate()
            .find_map(|(i, p)| match p.kind {
                PropKind::Scalar(s) if p.name == name => Some((i, s)),
                _ => None,
            })
    }
}

/// Parsed PLY header plus where the data starts.
#[derive(Debug, Clone)]
pub(crate) struct Header {
    pub encoding: Encoding,
    pub elements: Vec<Element>,
    /// Byte offset of the first data byte (just after the `end_header` line).
    pub body_start: usize,
    /// Number of header lines; ASCII data line numbers continue from here.
    pub header_lines: usize,
    /// Index of the `vertex` element and its `x`, `y`, `z` property indices.
    pub vertex: usize,
    pub xyz: [usize; 3],
    /// Index of the `face` element and its index-list property.
    pub face: usize,
    pub face_list: usize,
    /// `nx`, `ny`, `nz` property indices of the vertex element, when it has all three.
    pub normals: Option<[usize; 3]>,
}

/// Parses and checks the header: syntax, known types, integer list lengths, and that the file holds a mesh
/// (vertex element with x/y/z, face element with an integer index list).
pub(crate) fn parse_header(path: &Path, bytes: &[u8]) -> Result<Header> {
    let err = |line: usize, msg: String| {
        Error::format(path, Some(line), format!("bad PLY header: {msg}"))
    };
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut offset = 0usize;
    let mut line_no = 0usize;
    let mut body_start = None;
    for (line, ending) in tokens::lines_with_endings(bytes) {
        line_no += 1;
        offset += line.len() + ending.len();
        let toks: Vec<&[u8]> = tokens::tokens(line).collect();
        if line_no == 1 {
            if toks.as_slice() != [b"ply"] {
                return Err(err(
                    1,
                    "not a PLY file (the first line must be `ply`)".into(),
                ));
            }
            continue;
        }
        match toks.as_slice() {
            [] => {}
            [b"comment" | b"obj_info", ..] => {}
            [b"format", kind, version] => {
                if encoding.is_some() {
                    return Err(err(line_no, "a second `format` line".into()));
                }
                encoding = Some(match *kind {
                    b"ascii" => Encoding::Ascii,
                    b"binary_little_endian" => Encoding::BinaryLe,
                    b"binary_big_endian" => Encoding::BinaryBe,
                    other => return Err(err(line_no, format!("unknown format `{}`", show(other)))),
                });
                if *version != b"1.0" {
                    return Err(err(
                        line_no,
                        format!("unsupported version `{}` (expected 1.0)", show(version)),
                    ));
                }
            }
            [b"element", name, count] => {
                let count = parse_i64(count)
                    .and_then(|c| usize::try_from(c).ok())
                    .ok_or_else(|| {
                        err(
                            line_no,
                            format!("element count `{}` is not a number", show(count)),
                        )
                    })?;
                elements.push(Element {
                    name: String::from_utf8_lossy(name).into_owned(),
                    count,
                    props: Vec::new(),
                    line: line_no,
                });
            }
            [b"property", rest @ ..] => {
                let Some(element) = elements.last_mut() else {
                    return Err(err(line_no, "`property` before any `element`".into()));
                };
                let ty = |name: &[u8]| {
                    Scalar::from_name(name)
                        .ok_or_else(|| err(line_no, format!("unknown type `{}`", show(name))))
                };
                let (kind, name) = match rest {
                    [b"list", count, item, name] => {
                        let count = ty(count)?;
                        if count.is_float() {
                            return Err(err(
                                line_no,
                                "a list length type must be an integer type".into(),
                            ));
                        }
                        (
                            PropKind::List {
                                count,
                                item: ty(item)?,
                            },
                            name,
                        )
                    }
                    [t, name] if *t != b"list" => (PropKind::Scalar(ty(t)?), name),
                    _ => {
                        return Err(err(
                            line_no,
                            format!("cannot read property line `{}`", show(line)),
                        ))
                    }
                };
                element.props.push(Property {
                    name: String::from_utf8_lossy(name).into_owned(),
                    kind,
                });
            }
            [b"end_header"] => {
                body_start = Some(offset);
                break;
            }
            _ => {
                return Err(err(
                    line_no,
                    format!("unexpected header line `{}`", show(line)),
                ))
            }
        }
    }
    let Some(body_start) = body_start else {
        return Err(Error::format(
            path,
            None,
            if bytes.is_empty() {
                "the file is empty".to_string()
            } else {
                "bad PLY header: no `end_header` line".to_string()
            },
        ));
    };
    let encoding = encoding.ok_or_else(|| err(line_no, "no `format` line".into()))?;
    for e in &elements {
        if e.props.is_empty() && e.count > 0 {
            return Err(err(
                e.line,
                format!("element `{}` has no properties", e.name),
            ));
        }
    }
    let find = |name: &str| {
        let mut found = elements.iter().enumerate().filter(|(_, e)| e.name == name);
        match (found.next(), found.next()) {
            (Some((i, _)), None) => Ok(Some(i)),
            (None, _) => Ok(None),
            (Some(_), Some((_, e))) => Err(err(e.line, format!("a second `{name}` element"))),
        }
    };
    let vertex = find("vertex")?.ok_or_else(|| err(line_no, "no `vertex` element".into()))?;
    let face = find("face")?.ok_or_else(|| err(line_no, "no `face` element".into()))?;
    let (ve, fe) = (&elements[vertex], &elements[face]);
    let mut xyz = [0usize; 3];
    for (slot, name) in xyz.iter_mut().zip(["x", "y", "z"]) {
        *slot = ve
            .scalar_prop(name)
            .ok_or_else(|| {
                err(
                    ve.line,
                    format!("the vertex element has no scalar property `{name}`"),
                )
            })?
            .0;
    }
    let normals = match (
        ve.scalar_prop("nx"),
        ve.scalar_prop("ny"),
        ve.scalar_prop("nz"),
    ) {
        (Some(a), Some(b), Some(c)) => Some([a.0, b.0, c.0]),
        _ => None,
    };
    let face_list = fe
        .props
        .iter()
        .position(|p| {
            matches!(p.kind, PropKind::List { .. })
                && (p.name == "vertex_indices" || p.name == "vertex_index")
        })
        .ok_or_else(|| {
            err(
                fe.line,
                "the face element has no `vertex_indices` list property".into(),
            )
        })?;
    if let Some(PropKind::List { item, .. }) = fe.props.get(face_list).map(|p| p.kind) {
        if item.is_float() {
            return Err(err(
                fe.line,
                "face vertex indices must have an integer type".into(),
            ));
        }
    }
    Ok(Header {
        encoding,
        elements,
        body_start,
        header_lines: line_no,
        vertex,
        xyz,
        face,
        face_list,
        normals,
    })
}

/// One record (element instance) of the data, as located by a walker: where each property's data starts and
/// how many values it holds (1 for scalars, the length for lists).
struct Record<'r> {
    element: usize,
    index: usize,
    /// ASCII: line number and byte range of the line in the body; binary: unused.
    line_no: usize,
    span: (usize, usize),
    /// ASCII: token indices into `tokens`; binary: byte offsets into the body. For lists, the start of the
    /// length value; the items follow it.
    starts: &'r [usize],
    lens: &'r [usize],
    tokens: &'r [&'r [u8]],
}

/// Walks every record of ASCII data (one record per non-blank line), checking that each line holds exactly
/// the values its properties need.
fn walk_ascii(
    path: &Path,
    header: &Header,
    body: &[u8],
    mut visit: impl FnMut(&Record) -> Result<()>,
) -> Result<()> {
    let mut lines = tokens::lines_with_endings(body);
    let mut line_no = header.header_lines;
    let mut offset = 0usize;
    let mut toks: Vec<&[u8]> = Vec::new();
    let mut starts = Vec::new();
    let mut lens = Vec::new();
    for (ei, element) in header.elements.iter().enumerate() {
        for index in 0..element.count {
            // Next non-blank line.
            let (line, line_start) = loop {
                let Some((line, ending)) = lines.next() else {
                    return Err(Error::format(
                        path,
                        Some(line_no),
                        format!(
                            "the file ends before element `{}` {index} (the header declares {})",
                            element.name, element.count
                        ),
                    ));
                };
                line_no += 1;
                let start = offset;
                offset += line.len() + ending.len();
                if line.iter().any(|b| !b.is_ascii_whitespace()) {
                    break (line, start);
                }
            };
            toks.clear();
            toks.extend(tokens::tokens(line));
            starts.clear();
            lens.clear();
            let mut pos = 0usize;
            for prop in &element.props {
                let too_few = || {
                    Error::format(
                        path,
                        Some(line_no),
                        format!(
                            "too few values for element `{}` {index}: property `{}` is missing (`{}`)",
                            element.name,
                            prop.name,
                            show(line)
                        ),
                    )
                };
                starts.push(pos);
                match prop.kind {
                    PropKind::Scalar(_) => {
                        if pos >= toks.len() {
                            return Err(too_few());
                        }
                        lens.push(1);
                        pos += 1;
                    }
                    PropKind::List { .. } => {
                        let count_tok = toks.get(pos).ok_or_else(too_few)?;
                        let n = parse_i64(count_tok).and_then(|n| usize::try_from(n).ok()).ok_or_else(|| {
                            Error::format(
                                path,
                                Some(line_no),
                                format!(
                                    "list length `{}` of property `{}` in element `{}` {index} is not a \
                                     non-negative integer",
                                    show(count_tok),
                                    prop.name,
                                    element.name
                                ),
                            )
                        })?;
                        if toks.len() - pos - 1 < n {
                            return Err(too_few());
                        }
                        lens.push(n);
                        pos += 1 + n;
                    }
                }
            }
            if pos != toks.len() {
                return Err(Error::format(
                    path,
                    Some(line_no),
                    format!(
                        "element `{}` {index} has {} values, its properties need {pos}",
                        element.name,
                        toks.len()
                    ),
                ));
            }
            visit(&Record {
                element: ei,
                index,
                line_no,
                span: (line_start, line_start + line.len()),
                starts: &starts,
                lens: &lens,
                tokens: &toks,
            })?;
        }
    }
    Ok(())
}

fn read_uint(data: &[u8], at: usize, ty: Scalar, big: bool) -> Option<u64> {
    let v = read_f64(data, at, ty, big)?;
    (v >= 0.0 && v.fract() == 0.0 && !ty.is_float()).then_some(v as u64)
}

/// Reads one scalar of type `ty` at byte `at`, converted to f64 (exact for every PLY type). `None` when the data
/// ends early.
fn read_f64(data: &[u8], at: usize, ty: Scalar, big: bool) -> Option<f64> {
    let b = data.get(at..at.checked_add(ty.size())?)?;
    macro_rules! num {
        ($t:ty, $n:expr) => {{
            let arr: [u8; $n] = b.try_into().ok()?;
            (if big {
                <$t>::from_be_bytes(arr)
            } else {
                <$t>::from_le_bytes(arr)
            }) as f64
        }};
    }
    Some(match ty {
        Scalar::I8 => num!(i8, 1),
        Scalar::U8 => num!(u8, 1),
        Scalar::I16 => num!(i16, 2),
        Scalar::U16 => num!(u16, 2),
        Scalar::I32 => num!(i32, 4),
        Scalar::U32 => num!(u32, 4),
        Scalar::F32 => num!(f32, 4),
        Scalar::F64 => num!(f64, 8),
    })
}

/// Walks every record of binary data, checking that none runs past the end of the file.
fn walk_binary(
    path: &Path,
    header: &Header,
    body: &[u8],
    mut visit: impl FnMut(&Record) -> Result<()>,
) -> Result<()> {
    let big = header.encoding == Encoding::BinaryBe;
    let mut pos = 0usize;
    let mut starts = Vec::new();
    let mut lens = Vec::new();
    for (ei, element) in header.elements.iter().enumerate() {
        for index in 0..element.count {
            starts.clear();
            lens.clear();
            for prop in &element.props {
                let truncated = || {
                    Error::format(
                        path,
                        None,
                        format!(
                            "binary data ends early: element `{}` index {index} (of {}), property `{}` is past the \
                             end of the file ({} bytes)",
                            element.name,
                            element.count,
                            prop.name,
                            header.body_start + body.len()
                        ),
                    )
                };
                starts.push(pos);
                let size = match prop.kind {
                    PropKind::Scalar(s) => {
                        lens.push(1);
                        s.size()
                    }
                    PropKind::List { count, item } => {
                        let n = read_uint(body, pos, count, big).ok_or_else(truncated)?;
                        let n = usize::try_from(n).map_err(|_| truncated())?;
                        lens.push(n);
                        n.checked_mul(item.size())
                            .and_then(|s| s.checked_add(count.size()))
                            .ok_or_else(truncated)?
                    }
                };
                pos = pos
                    .checked_add(size)
                    .filter(|&end| end <= body.len())
                    .ok_or_else(truncated)?;
            }
            visit(&Record {
                element: ei,
                index,
                line_no: 0,
                span: (0, 0),
                starts: &starts,
                lens: &lens,
                tokens: &[],
            })?;
        }
    }
    Ok(())
}

fn walk(
    path: &Path,
    header: &Header,
    bytes: &[u8],
    visit: impl FnMut(&Record) -> Result<()>,
) -> Result<()> {
    let body = bytes.get(header.body_start..).unwrap_or_default();
    match header.encoding {
        Encoding::Ascii => walk_ascii(path, header, body, visit),
        _ => walk_binary(path, header, body, visit),
    }
}

/// Positions and original polygons of one PLY file.
#[derive(Debug, Clone)]
pub(crate) struct PlyMesh {
    pub positions: Vec<V3>,
    pub faces: Polygons,
}

/// Parses a PLY file's bytes. Errors are [`Error::Format`] naming `path` and, for ASCII data, the line; binary
/// errors name the element and record index.
pub(crate) fn parse_ply(path: &Path, bytes: &[u8]) -> Result<PlyMesh> {
    let header = parse_header(path, bytes)?;
    let body = bytes.get(header.body_start..).unwrap_or_default();
    let big = header.encoding == Encoding::BinaryBe;
    let n_vertices = header.elements[header.vertex].count;
    let n_faces = header.elements[header.face].count;
    // Never trust a header count for an allocation: a vertex record takes at least 3 bytes (three 1-byte
    // coordinates), a face record at least 4, an index at least 1.
    let mut positions: Vec<V3> = Vec::with_capacity(n_vertices.min(body.len() / 3));
    let mut faces = Polygons::with_capacity(
        n_faces.min(body.len() / 4),
        n_faces.saturating_mul(3).min(body.len()),
    );
    let mut poly: Vec<u32> = Vec::with_capacity(8);
    let face_item = match header.elements[header.face].props[header.face_list].kind {
        PropKind::List { count, item } => (count.size(), item),
        PropKind::Scalar(s) => (0, s),
    };
    walk(path, &header, bytes, |r| {
        let where_ = || {
            if header.encoding == Encoding::Ascii {
                (Some(r.line_no), String::new())
            } else {
                let e = &header.elements[r.element];
                (None, format!("element `{}` index {}: ", e.name, r.index))
            }
        };
        if r.element == header.vertex {
            let mut p = [0.0; 3];
            for (c, &prop) in p.iter_mut().zip(&header.xyz) {
                let start = r.starts.get(prop).copied().unwrap_or(usize::MAX);
                let ty = match header.elements[header.vertex].props[prop].kind {
                    PropKind::Scalar(s) => s,
                    PropKind::List { item, .. } => item,
                };
                let value = if header.encoding == Encoding::Ascii {
                    // A `float` property holds an f32: read it as one, so ASCII and binary files with the same
                    // values give the same positions.
                    r.tokens.get(start).and_then(|t| match ty {
                        Scalar::F32 => parse_f32(t).map(f64::from),
                        _ => parse_f64(t),
                    })
                } else {
                    read_f64(body, start, ty, big)
                };
                *c = value.ok_or_else(|| {
                    let (line, at) = where_();
                    let tok = r.tokens.get(start).map(|t| show(t)).unwrap_or_default();
                    Error::format(
                        path,
                        line,
                        format!(
                            "{at}cannot read vertex {} coordinate `{tok}` as a number",
                            r.index
                        ),
                    )
                })?;
            }
            positions.push(p);
        } else if r.element == header.face {
            poly.clear();
            let start = r.starts.get(header.face_list).copied().unwrap_or(0);
            let n = r.lens.get(header.face_list).copied().unwrap_or(0);
            for k in 0..n {
                let value = if header.encoding == Encoding::Ascii {
                    r.tokens.get(start + 1 + k).and_then(|t| parse_i64(t))
                } else {
                    let at = start + face_item.0 + k * face_item.1.size();
                    read_f64(body, at, face_item.1, big).map(|v| v as i64)
                };
                let (line, at) = where_();
                let value = value.ok_or_else(|| {
                    Error::format(
                        path,
                        line,
                        format!("{at}face {}: cannot read a vertex index", r.index),
                    )
                })?;
                match u32::try_from(value) {
                    Ok(v) if (v as usize) < n_vertices => poly.push(v),
                    _ => {
                        return Err(Error::format(
                            path,
                            line,
                            format!(
                                "{at}face {} references vertex {value}, but there are only {n_vertices} vertices",
                                r.index
                            ),
                        ))
                    }
                }
            }
            if poly.len() < 3 {
                let (line, at) = where_();
                return Err(Error::format(
                    path,
                    line,
                    format!(
                        "{at}face {} has {} vertices, at least 3 are needed",
                        r.index,
                        poly.len()
                    ),
                ));
            }
            faces.push(&poly);
        }
        Ok(())
    })?;
    if positions.is_empty() {
        return Err(Error::format(path, None, "the file has no vertices"));
    }
    if faces.is_empty() {
        return Err(Error::format(
            path,
            None,
            "the file has no faces; every frame must be a polygon mesh",
        ));
    }
    Ok(PlyMesh { positions, faces })
}

/// Stores `v` as type `ty` at `dst` (which has exactly `ty.size()` bytes). Only float types are written:
/// computed positions cannot be stored in integer properties without silently losing them.
fn put_float(dst: &mut [u8], ty: Scalar, v: f64, big: bool) -> bool {
    match ty {
        Scalar::F32 => {
            let b = if big {
                (v as f32).to_be_bytes()
            } else {
                (v as f32).to_le_bytes()
            };
            dst.copy_from_slice(&b);
            true
        }
        Scalar::F64 => {
            let b = if big {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            };
            dst.copy_from_slice(&b);
            true
        }
        _ => false,
    }
}

/// Rewrites a PLY file with new vertex positions, for writing a processed frame in the layout of its input.
///
/// The header and every non-vertex record stay byte-identical; in vertex records `x`, `y`, `z` are replaced
/// (stored in the property's declared type, which must be `float` or `double`), `nx`, `ny`, `nz` are replaced by
/// `normals` when the vertex element has them (stale input normals would shade the new shape wrongly), and every
/// other property is copied unchanged: raw bytes in binary files, the original tokens in ASCII files (where a
/// vertex line is re-joined with single spaces).
pub(crate) fn rewrite_ply(
    path: &Path,
    src: &[u8],
    header: &Header,
    positions: &[V3],
    normals: Option<&[V3]>,
) -> Result<Vec<u8>> {
    let ve = &header.elements[header.vertex];
    if positions.len() != ve.count {
        return Err(Error::mesh(format!(
            "has {} vertices, but {} positions were given for it",
            ve.count,
            positions.len()
        ))
        .at(Some(path.to_path_buf()), None));
    }
    // (property index, axis, values) for every property to replace.
    let mut targets: Vec<(usize, usize, &[V3])> = header
        .xyz
        .iter()
        .enumerate()
        .map(|(k, &p)| (p, k, positions))
        .collect();
    if let (Some(nrm), Some(values)) = (header.normals, normals) {
        if values.len() != positions.len() {
            return Err(Error::mesh("normals and positions differ in length")
                .at(Some(path.to_path_buf()), None));
        }
        targets.extend(nrm.iter().enumerate().map(|(k, &p)| (p, k, values)));
    }
    let mut types = Vec::with_capacity(targets.len());
    for &(p, _, _) in &targets {
        let prop = &ve.props[p];
        match prop.kind {
            PropKind::Scalar(s) if s.is_float() => types.push(s),
            _ => {
                return Err(Error::format(
                    path,
                    Some(ve.line),
                    format!(
                        "vertex property `{}` is not `float` or `double`; computed values cannot be stored in it",
                        prop.name
                    ),
                ))
            }
        }
    }
    let body = src.get(header.body_start..).unwrap_or_default();
    let head = src.get(..header.body_start).unwrap_or_default();
    match header.encoding {
        Encoding::Ascii => {
            let mut out = Vec::with_capacity(src.len() + src.len() / 4);
            out.extend_from_slice(head);
            let mut copied = 0usize;
            let mut replace: Vec<Option<f64>> = Vec::new();
            let mut is_f32: Vec<bool> = Vec::new();
            walk_ascii(path, header, body, |r| {
                if r.element != header.vertex {
                    return Ok(());
                }
                out.extend_from_slice(body.get(copied..r.span.0).unwrap_or_default());
                replace.clear();
                replace.resize(r.tokens.len(), None);
                is_f32.clear();
                is_f32.resize(r.tokens.len(), false);
                for (&(p, k, values), &ty) in targets.iter().zip(&types) {
                    let value = values.get(r.index).map_or(f64::NAN, |v| v[k]);
                    if let Some(&t) = r.starts.get(p) {
                        if let Some(slot) = replace.get_mut(t) {
                            *slot = Some(value);
                        }
                        if let Some(slot) = is_f32.get_mut(t) {
                            *slot = ty == Scalar::F32;
                        }
                    }
                }
                for (t, tok) in r.tokens.iter().enumerate() {
                    if t > 0 {
                        out.push(b' ');
                    }
                    match replace.get(t).copied().flatten() {
                        Some(v) if is_f32.get(t) == Some(&true) => {
                            tokens::push_f32(&mut out, v as f32)
                        }
                        Some(v) => tokens::push_f64(&mut out, v),
                        None => out.extend_from_slice(tok),
                    }
                }
                copied = r.span.1;
                Ok(())
            })?;
            out.extend_from_slice(body.get(copied..).unwrap_or_default());
            Ok(out)
        }
        Encoding::BinaryLe | Encoding::BinaryBe => {
            let big = header.encoding == Encoding::BinaryBe;
            let mut out = src.to_vec();
            let base = header.body_start;
            walk_binary(path, header, body, |r| {
                if r.element != header.vertex {
                    return Ok(());
                }
                for (&(p, k, values), &ty) in targets.iter().zip(&types) {
                    let value = values.get(r.index).map_or(f64::NAN, |v| v[k]);
                    let at = base + r.starts.get(p).copied().unwrap_or(0);
                    let ok = out
                        .get_mut(at..at + ty.size())
                        .is_some_and(|dst| put_float(dst, ty, value, big));
                    if !ok {
                        return Err(Error::format(
                            path,
                            None,
                            "internal error: vertex record outside the file",
                        ));
                    }
                }
                Ok(())
            })?;
            Ok(out)
        }
    }
}

/// Writes a plain PLY frame (float `x y z`, `uchar int vertex_indices` triangles) atomically, as ASCII or as
/// binary little-endian. Used for generated data and test inputs.
pub fn write_ply_frame(
    path: &Path,
    topology: &Topology,
    positions: &[V3],
    binary: bool,
) -> Result<()> {
    geometry::check_position_count(topology, positions.len(), path)?;
    fsutil::write_atomic_with(path, |w| {
        write!(
            w,
            "ply\nformat {} 1.0\ncomment written by crease\nelement vertex {}\nproperty float x\nproperty float y\n\
             property float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
            if binary { "binary_little_endian" } else { "ascii" },
            positions.len(),
            topology.n_triangles()
        )?;
        if binary {
            for p in positions {
                for &c in p {
                    w.write_all(&(c as f32).to_le_bytes())?;
                }
            }
            for t in topology.triangles() {
                w.write_all(&[3])?;
                for &v in t {
                    w.write_all(&(v as i32).to_le_bytes())?;
                }
            }
        } else {
            let mut buf = Vec::with_capacity(64);
            for p in positions {
                buf.clear();
                for (k, &c) in p.iter().enumerate() {
                    if k > 0 {
                        buf.push(b' ');
                    }
                    tokens::push_f32(&mut buf, c as f32);
                }
                buf.push(b'\n');
                w.write_all(&buf)?;
            }
            for t in topology.triangles() {
                writeln!(w, "3 {} {} {}", t[0], t[1], t[2])?;
            }
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn skips_other_elements_and_lists() {
        let src = "ply\nformat ascii 1.0\ncomment x\nelement material 1\nproperty list uchar float c\n\
                   element vertex 4\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\n\
                   element face 1\nproperty list uchar int vertex_index\nend_header\n2 0.5 0.5\n\
                   0 0 0 1\n1 0 0 2\n1 1 0 3\n0 1 0 4\n4 0 1 2 3\n";
        let m = parse_ply(Path::new("t.ply"), src.as_bytes()).unwrap();
        assert_eq!(m.positions[2], [1.0, 1.0, 0.0]);
        assert_eq!(m.faces.triangulate(), vec![[0, 1, 2], [0, 2, 3]]);
    }
}

//! Sequences stored as a directory of numbered frame files (OBJ or PLY): a lazy [`FrameSource`] and a
//! [`FrameSink`] that writes each output frame in the format, name and layout of its input file.

use super::faces::{describe_face, explain_triangle_numbers, Polygons};
use super::numbering::file_name;
use super::{obj, obj_blame, ply};
use crate::error::{Error, Result};
use crate::fsutil;
use crate::mesh::{geometry, Frame, FrameSink, FrameSource, Topology};
use crate::vec3::V3;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// File format of the frames of a directory sequence.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameFormat {
    Obj,
    Ply,
}

impl FrameFormat {
    /// Added to 0-based vertex indices in messages so that they read like the file (OBJ counts from 1).
    fn index_base(self) -> u64 {
        match self {
            FrameFormat::Obj => 1,
            FrameFormat::Ply => 0,
        }
    }
}

/// Positions and polygons of one frame file's bytes; `path` only names the file in errors.
fn parse_mesh(format: FrameFormat, path: &Path, bytes: &[u8]) -> Result<(Vec<V3>, Polygons)> {
    Ok(match format {
        FrameFormat::Obj => {
            let m = obj::parse_obj(path, bytes)?;
            (m.positions, m.faces)
        }
        FrameFormat::Ply => {
            let m = ply::parse_ply(path, bytes)?;
            (m.positions, m.faces)
        }
    })
}

fn read_bytes(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|e| Error::io(path, e))
}

pub(crate) fn out_of_range(t: usize, n: usize) -> Error {
    Error::param(
        "frame",
        format!("frame {t} is out of range: the sequence has {n} frames"),
    )
}

/// The first frame of a frame-file sequence, against which every later frame is checked. Works on bytes, so
/// that frames held in memory (fuzzing, services that fetched them) go through exactly the checks that
/// [`open_sequence`](super::open_sequence) applies to files.
pub struct FrameReference {
    format: FrameFormat,
    /// File name of the first frame, for messages about later frames.
    first: String,
    topology: Arc<Topology>,
    faces0: Polygons,
}

impl FrameReference {
    /// Parses the first frame and builds its topology (validated by [`Topology::new`]); `path` names it in
    /// errors.
    pub fn from_first_frame(format: FrameFormat, path: &Path, bytes: &[u8]) -> Result<Self> {
        // The first frame's texture coordinates hold for the sequence (PLY frames carry none).
        let (positions, faces0, uvs) = match format {
            FrameFormat::Obj => {
                let m = obj::parse_obj_with_uvs(path, bytes)?;
                obj_blame::check_faces(path, &m.faces, bytes)?;
                (m.positions, m.faces, m.uvs)
            }
            FrameFormat::Ply => {
                let (p, f) = parse_mesh(format, path, bytes)?;
                (p, f, None)
            }
        };
        let topology = Topology::new(positions.len(), faces0.triangulate())
            .and_then(|t| t.with_uvs(uvs))
            .map_err(|e| {
                explain_triangle_numbers(
                    e.at(Some(path.to_path_buf()), Some(0)),
                    faces0.has_polygons(),
                )
            })?;
        Ok(FrameReference {
            format,
            first: file_name(path),
            topology: Arc::new(topology),
            faces0,
        })
    }

    pub fn topology(&self) -> &Arc<Topology> {
        &self.topology
    }

    /// Parses frame `t` and checks it against the first frame: same vertex count, same polygons, and valid
    /// geometry (finite, no degenerate triangles).
    pub fn check_frame(&self, t: usize, path: &Path, bytes: &[u8]) -> Result<Frame> {
        let (positions, faces) = parse_mesh(self.format, path, bytes)?;
        let at = |e: Error| e.at(Some(path.to_path_buf()), Some(t));
        let n = self.topology.n_vertices();
        if positions.len() != n {
            return Err(at(Error::mesh(format!(
                "has {} vertices, but frame 0 ({}) has {n}; the vertex count must be the same in every frame",
                positions.len(),
                self.first
            ))));
        }
        if let Some(e) = self.different_faces(t, path, bytes, &faces) {
            return Err(e);
        }
        if self.format == FrameFormat::Obj {
            if let Some(p) = geometry::find_problem(&self.topology, &positions) {
                return Err(at(Error::mesh(obj_blame::describe(
                    &p,
                    &self.faces0,
                    bytes,
                ))));
            }
        }
        geometry::validate_frame(&self.topology, &positions)
            .map_err(|e| explain_triangle_numbers(at(e), self.faces0.has_polygons()))?;
        Ok(positions)
    }

    fn different_faces(
        &self,
        t: usize,
        path: &Path,
        bytes: &[u8],
        faces: &Polygons,
    ) -> Option<Error> {
        let k = self.faces0.first_difference(faces)?;
        let base = self.format.index_base();
        let line = match self.format {
            FrameFormat::Obj => obj::face_line(bytes, k)
                .map(|l| format!(" (line {l})"))
                .unwrap_or_default(),
            FrameFormat::Ply => String::new(),
        };
        let detail = if k >= faces.len() || k >= self.faces0.len() {
            format!(
                "it has {} faces, frame 0 has {}",
                faces.len(),
                self.faces0.len()
            )
        } else {
            format!(
                "face {k}{line} is ({}) here but ({}) in frame 0",
                describe_face(faces.get(k), base),
                describe_face(self.faces0.get(k), base)
            )
        };
        Some(
            Error::mesh(format!(
                "has a different triangle list than frame 0 ({}): {detail}; every frame must have the same \
                 connectivity",
                self.first
            ))
            .at(Some(path.to_path_buf()), Some(t)),
        )
    }
}

/// Reads frame `t` from the `t`-th file on demand; only the first frame's topology and polygon list (to check
/// that every frame has the same connectivity) stay in memory.
pub(crate) struct FrameDirSource {
    files: Vec<PathBuf>,
    reference: FrameReference,
}

impl FrameDirSource {
    /// Reads the first file for the topology.
    pub(crate) fn open(format: FrameFormat, files: Vec<PathBuf>) -> Result<Self> {
        let first = files
            .first()
            .ok_or_else(|| Error::mesh("the sequence has no frames"))?;
        let reference = FrameReference::from_first_frame(format, first, &read_bytes(first)?)?;
        Ok(FrameDirSource { files, reference })
    }
}

impl FrameSource for FrameDirSource {
    fn topology(&self) -> &Arc<Topology> {
        self.reference.topology()
    }

    fn n_frames(&self) -> usize {
        self.files.len()
    }

    fn read_frame(&self, t: usize) -> Result<Frame> {
        let path = self
            .files
            .get(t)
            .ok_or_else(|| out_of_range(t, self.files.len()))?;
        self.reference.check_frame(t, path, &read_bytes(path)?)
    }

    fn describe_frame(&self, t: usize) -> String {
        match self.files.get(t) {
            Some(p) => p.display().to_string(),
            None => format!("frame {t} (out of range)"),
        }
    }
}

/// Checks an output frame before anything is written: index in range, and finite positions (a NaN written
/// into a frame file would only be discovered by whoever reads it next).
pub(crate) fn check_output(t: usize, n_frames: usize, positions: &[V3]) -> Result<()> {
    if t >= n_frames {
        return Err(out_of_range(t, n_frames));
    }
    if let Some(i) = positions.iter().position(|p| !crate::vec3::is_finite(*p)) {
        return Err(
            Error::mesh(format!("output vertex {i} has a non-finite position")).at(None, Some(t)),
        );
    }
    Ok(())
}

/// "3, 5-9, 12" for messages about missing frames.
pub(crate) fn describe_missing(written: &[bool]) -> String {
    let mut parts = Vec::new();
    let mut t = 0;
    while t < written.len() {
        if written.get(t) == Some(&false) {
            let start = t;
            while written.get(t + 1) == Some(&false) {
                t += 1;
            }
            parts.push(if start == t {
                start.to_string()
            } else {
                format!("{start}-{t}")
            });
        }
        t += 1;
    }
    parts.join(", ")
}

/// Writes output frame `t` as `out_dir/<name of input file t>`, rewriting the input file (see
/// [`obj::rewrite_obj`] and [`ply::rewrite_ply`] for what is kept and what is replaced). Each file is written
/// atomically, so a failed run never leaves a half-written frame under a final name.
pub(crate) struct FrameDirSink {
    format: FrameFormat,
    inputs: Vec<PathBuf>,
    outputs: Vec<PathBuf>,
    written: Vec<bool>,
    out_dir: PathBuf,
    /// PLY normals need the connectivity; built from the first input that has normals.
    topology: Option<Arc<Topology>>,
}

impl FrameDirSink {
    pub(crate) fn new(format: FrameFormat, inputs: Vec<PathBuf>, out_dir: &Path) -> Result<Self> {
        let mut outputs = Vec::with_capacity(inputs.len());
        for input in &inputs {
            let name = input.file_name().ok_or_else(|| {
                Error::param("input", format!("{} has no file name", input.display()))
            })?;
            outputs.push(out_dir.join(name));
        }
        Ok(FrameDirSink {
            format,
            written: vec![false; inputs.len()],
            inputs,
            outputs,
            out_dir: out_dir.to_path_buf(),
            topology: None,
        })
    }

    fn normals(&mut self, input: &Path, src: &[u8], positions: &[V3]) -> Result<Vec<V3>> {
        let topology = match &self.topology {
            Some(t) => t.clone(),
            None => {
                let mesh = ply::parse_ply(input, src)?;
                let topo = Topology::new(mesh.positions.len(), mesh.faces.triangulate())
                    .map_err(|e| e.at(Some(input.to_path_buf()), None))?;
                let topo = Arc::new(topo);
                self.topology = Some(topo.clone());
                topo
            }
        };
        geometry::check_position_count(&topology, positions.len(), input)?;
        Ok(geometry::vertex_normals(&topology, positions))
    }
}

impl FrameSink for FrameDirSink {
    fn write_frame(&mut self, t: usize, positions: &[V3]) -> Result<()> {
        check_output(t, self.inputs.len(), positions)?;
        let (Some(input), Some(output)) =
            (self.inputs.get(t).cloned(), self.outputs.get(t).cloned())
        else {
            return Err(out_of_range(t, self.inputs.len()));
        };
        let src = std::fs::read(&input).map_err(|e| Error::io(&input, e))?;
        let bytes = match self.format {
            FrameFormat::Obj => obj::rewrite_obj(&input, &src, positions),
            FrameFormat::Ply => {
                let header = ply::parse_header(&input, &src)?;
                let normals = match header.normals {
                    Some(_) => Some(
                        self.normals(&input, &src, positions)
                            .map_err(|e| e.at(None, Some(t)))?,
                    ),
                    None => None,
                };
                ply::rewrite_ply(&input, &src, &header, positions, normals.as_deref())
            }
        }
        .map_err(|e| e.at(None, Some(t)))?;
        fsutil::write_atomic(&output, &bytes)?;
        if let Some(w) = self.written.get_mut(t) {
            *w = true;
        }
        Ok(())
    }

    /// Succeeds only when every frame was written; the error lists the missing frames.
    fn finish(&mut self) -> Result<Vec<PathBuf>> {
        if self.written.iter().any(|w| !w) {
            return Err(Error::format(
                &self.out_dir,
                None,
                format!(
                    "incomplete output: frames {} were never written",
                    describe_missing(&self.written)
                ),
            ));
        }
        Ok(self.outputs.clone())
    }
}

//! Sequences stored as an OBJ (topology) plus a PC2 point cache (positions): a lazy [`FrameSource`] that seeks
//! to one sample per read, and a [`FrameSink`] that fills a new cache frame by frame in any order.

use super::faces::explain_triangle_numbers;
use super::frame_dir::{check_output, describe_missing, out_of_range};
use super::obj;
use super::pc2::{self, Pc2Header};
use crate::error::{Error, Result};
use crate::fsutil;
use crate::mesh::{geometry, Frame, FrameSink, FrameSource, Topology};
use crate::vec3::V3;
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

/// The topology OBJ of a point cache checked against the cache's header, and the checks every sample goes
/// through. Works on bytes, so that caches held in memory (fuzzing, services that fetched them) are validated
/// exactly as [`open_sequence`](super::open_sequence) validates files.
pub struct Pc2Reference {
    pc2: PathBuf,
    header: Pc2Header,
    topology: Arc<Topology>,
    /// Whether the OBJ has polygons, so that errors naming a triangle explain the numbering.
    has_polygons: bool,
}

impl Pc2Reference {
    /// Parses the topology OBJ (its own positions, the rest pose, are not a frame), checks that its vertex
    /// count matches the cache's point count and builds the topology. The paths only name the files in errors.
    pub fn new(
        obj_path: &Path,
        obj_bytes: &[u8],
        pc2_path: &Path,
        header: Pc2Header,
    ) -> Result<Self> {
        // The topology OBJ's texture coordinates hold for every sample (the cache holds points only).
        let mesh = obj::parse_obj_with_uvs(obj_path, obj_bytes)?;
        if header.num_points != mesh.positions.len() {
            return Err(Error::format(
                pc2_path,
                None,
                format!(
                    "the cache has {} points, but its topology {} has {} vertices",
                    header.num_points,
                    obj_path.display(),
                    mesh.positions.len()
                ),
            ));
        }
        let topology = Topology::new(mesh.positions.len(), mesh.faces.triangulate())
            .and_then(|t| t.with_uvs(mesh.uvs.clone()))
            .map_err(|e| {
                explain_triangle_numbers(
                    e.at(Some(obj_path.to_path_buf()), None),
                    mesh.faces.has_polygons(),
                )
            })?;
        Ok(Pc2Reference {
            pc2: pc2_path.to_path_buf(),
            has_polygons: mesh.faces.has_polygons(),
            header,
            topology: Arc::new(topology),
        })
    }

    pub fn header(&self) -> &Pc2Header {
        &self.header
    }

    pub fn topology(&self) -> &Arc<Topology> {
        &self.topology
    }

    /// Reads sample `t` from `reader` (the whole cache) and validates it against the topology.
    pub fn read_sample<R: Read + Seek>(&self, reader: &mut R, t: usize) -> Result<Frame> {
        if t >= self.header.num_samples {
            return Err(out_of_range(t, self.header.num_samples));
        }
        let positions = pc2::read_pc2_sample_from(&self.pc2, reader, &self.header, t)?;
        geometry::validate_frame(&self.topology, &positions).map_err(|e| {
            explain_triangle_numbers(e.at(Some(self.pc2.clone()), Some(t)), self.has_polygons)
        })?;
        Ok(positions)
    }
}

/// Reads sample `t` of the cache on demand, opening the file for each read.
pub(crate) struct Pc2Source {
    reference: Pc2Reference,
}

impl Pc2Source {
    /// Validates the cache header and size, reads the OBJ's topology, and checks that the point count matches.
    pub(crate) fn open(obj_path: &Path, pc2_path: &Path) -> Result<Self> {
        let header = pc2::read_pc2_header(pc2_path)?;
        let obj_bytes = std::fs::read(obj_path).map_err(|e| Error::io(obj_path, e))?;
        Ok(Pc2Source {
            reference: Pc2Reference::new(obj_path, &obj_bytes, pc2_path, header)?,
        })
    }
}

impl FrameSource for Pc2Source {
    fn topology(&self) -> &Arc<Topology> {
        self.reference.topology()
    }

    fn n_frames(&self) -> usize {
        self.reference.header.num_samples
    }

    fn read_frame(&self, t: usize) -> Result<Frame> {
        let r = &self.reference;
        if t >= r.header.num_samples {
            return Err(out_of_range(t, r.header.num_samples));
        }
        let mut file = std::fs::File::open(&r.pc2).map_err(|e| Error::io(&r.pc2, e))?;
        r.read_sample(&mut file, t)
    }

    fn describe_frame(&self, t: usize) -> String {
        format!("{} sample {t}", self.reference.pc2.display())
    }
}

/// Distinguishes temporary files of sinks created by the same process.
static SINK_SERIAL: AtomicUsize = AtomicUsize::new(0);

/// Writes a point cache with the input's header (start frame, sample rate, sample count) and a copy of the
/// topology OBJ. Samples go to a hidden temporary file at their offsets, in any order; [`FrameSink::finish`]
/// renames it to the final name only once every sample was written, so an interrupted run never leaves a cache
/// that looks complete but holds zeros.
pub(crate) struct Pc2Sink {
    header: Pc2Header,
    obj_in: PathBuf,
    obj_out: PathBuf,
    pc2_out: PathBuf,
    tmp: PathBuf,
    file: Option<std::fs::File>,
    written: Vec<bool>,
    buf: Vec<u8>,
    done: Option<Vec<PathBuf>>,
}

impl Pc2Sink {
    pub(crate) fn create(
        obj_in: &Path,
        pc2_in: &Path,
        header: Pc2Header,
        out_dir: &Path,
    ) -> Result<Self> {
        let name_of = |p: &Path| {
            p.file_name()
                .map(|n| n.to_os_string())
                .ok_or_else(|| Error::param("input", format!("{} has no file name", p.display())))
        };
        let pc2_name = name_of(pc2_in)?;
        let obj_out = out_dir.join(name_of(obj_in)?);
        let pc2_out = out_dir.join(&pc2_name);
        pc2::check_counts(&pc2_out, header.num_points, header.num_samples)?;
        let tmp = out_dir.join(format!(
            ".{}.partial-{}-{}",
            pc2_name.to_string_lossy(),
            std::process::id(),
            SINK_SERIAL.fetch_add(1, Ordering::Relaxed)
        ));
        let len = header
            .file_len()
            .ok_or_else(|| Error::format(&pc2_out, None, "cache size overflows"))?;
        let file = (|| {
            let mut f = std::fs::File::create(&tmp)?;
            f.write_all(&header.to_bytes())?;
            f.set_len(len)?;
            Ok(f)
        })()
        .map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            Error::io(&tmp, e)
        })?;
        Ok(Pc2Sink {
            written: vec![false; header.num_samples],
            header,
            obj_in: obj_in.to_path_buf(),
            obj_out,
            pc2_out,
            tmp,
            file: Some(file),
            buf: Vec::new(),
            done: None,
        })
    }
}

impl FrameSink for Pc2Sink {
    fn write_frame(&mut self, t: usize, positions: &[V3]) -> Result<()> {
        check_output(t, self.header.num_samples, positions)?;
        if positions.len() != self.header.num_points {
            return Err(Error::mesh(format!(
                "output frame has {} vertices, the cache has {} points",
                positions.len(),
                self.header.num_points
            ))
            .at(Some(self.pc2_out.clone()), Some(t)));
        }
        let Some(file) = self.file.as_mut() else {
            return Err(Error::param(
                "frame",
                format!("frame {t} written after finish()"),
            ));
        };
        pc2::encode_sample(positions, &mut self.buf)
            .map_err(|m| Error::mesh(m).at(Some(self.pc2_out.clone()), Some(t)))?;
        let offset = self
            .header
            .sample_offset(t)
            .ok_or_else(|| out_of_range(t, self.header.num_samples))?;
        file.seek(SeekFrom::Start(offset))
            .and_then(|_| file.write_all(&self.buf))
            .map_err(|e| Error::io(&self.tmp, e))?;
        if let Some(w) = self.written.get_mut(t) {
            *w = true;
        }
        Ok(())
    }

    /// Succeeds only when every sample was written (the error lists the missing ones, and the sink stays
    /// usable so they can still be written). Copies the topology OBJ first, then renames the cache into place.
    fn finish(&mut self) -> Result<Vec<PathBuf>> {
        if let Some(done) = &self.done {
            return Ok(done.clone());
        }
        if self.written.iter().any(|w| !w) {
            return Err(Error::format(
                &self.pc2_out,
                None,
                format!(
                    "incomplete output: frames {} were never written; nothing was written under this name",
                    describe_missing(&self.written)
                ),
            ));
        }
        if let Some(file) = self.file.as_mut() {
            file.flush()
                .and_then(|_| file.sync_data())
                .map_err(|e| Error::io(&self.tmp, e))?;
        }
        let obj_bytes = std::fs::read(&self.obj_in).map_err(|e| Error::io(&self.obj_in, e))?;
        fsutil::write_atomic(&self.obj_out, &obj_bytes)?;
        self.file = None;
        std::fs::rename(&self.tmp, &self.pc2_out).map_err(|e| Error::io(&self.pc2_out, e))?;
        let done = vec![self.obj_out.clone(), self.pc2_out.clone()];
        self.done = Some(done.clone());
        Ok(done)
    }
}

impl Drop for Pc2Sink {
    /// An unfinished cache is removed, so partial output never lingers (not even under a hidden name).
    fn drop(&mut self) {
        if self.done.is_none() {
            self.file = None;
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

//! Detecting how a sequence is stored, opening it as a [`FrameSource`], and creating a [`FrameSink`] that writes
//! the output in the same layout.

use super::frame_dir::{FrameDirSink, FrameDirSource, FrameFormat};
use super::numbering::{file_name, sort_numbered, NumberedFile};
use super::pc2::{read_pc2_header, Pc2Header};
use super::point_cache::{Pc2Sink, Pc2Source};
use crate::error::{Error, Result};
use crate::fsutil;
use crate::mesh::{FrameSink, FrameSource};
use std::fmt;
use std::path::{Path, PathBuf};

/// How an input sequence is stored. Outputs are written in the layout of their input (same file names, same
/// vertex order), so the processed sequence drops into the pipeline where the original came from.
#[derive(Debug, Clone, PartialEq)]
pub enum SequenceLayout {
    /// A directory of numbered OBJ files, one per frame, in frame order.
    ObjFrames {
        dir: PathBuf,
        frames: Vec<NumberedFile>,
    },
    /// A directory of numbered PLY files (ASCII or binary), one per frame, in frame order.
    PlyFrames {
        dir: PathBuf,
        frames: Vec<NumberedFile>,
    },
    /// An OBJ holding the connectivity plus a PC2 point cache holding every frame's positions.
    ObjPc2 {
        obj: PathBuf,
        pc2: PathBuf,
        header: Pc2Header,
    },
}

impl SequenceLayout {
    pub fn n_frames(&self) -> usize {
        match self {
            SequenceLayout::ObjFrames { frames, .. } | SequenceLayout::PlyFrames { frames, .. } => {
                frames.len()
            }
            SequenceLayout::ObjPc2 { header, .. } => header.num_samples,
        }
    }

    /// Short name of the layout for logs and reports: `obj-frames`, `ply-frames` or `obj+pc2`.
    pub fn kind(&self) -> &'static str {
        match self {
            SequenceLayout::ObjFrames { .. } => "obj-frames",
            SequenceLayout::PlyFrames { .. } => "ply-frames",
            SequenceLayout::ObjPc2 { .. } => "obj+pc2",
        }
    }

    /// Every input file of the layout (frame files in order, or the OBJ and the PC2).
    pub fn input_files(&self) -> Vec<PathBuf> {
        match self {
            SequenceLayout::ObjFrames { frames, .. } | SequenceLayout::PlyFrames { frames, .. } => {
                frames.iter().map(|f| f.path.clone()).collect()
            }
            SequenceLayout::ObjPc2 { obj, pc2, .. } => vec![obj.clone(), pc2.clone()],
        }
    }

    /// Directories holding the input files (writing output there would overwrite the input).
    fn input_dirs(&self) -> Vec<PathBuf> {
        let parent = |p: &Path| p.parent().map(Path::to_path_buf).unwrap_or_default();
        match self {
            SequenceLayout::ObjFrames { dir, .. } | SequenceLayout::PlyFrames { dir, .. } => {
                vec![dir.clone()]
            }
            SequenceLayout::ObjPc2 { obj, pc2, .. } => vec![parent(obj), parent(pc2)],
        }
    }
}

impl fmt::Display for SequenceLayout {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SequenceLayout::ObjFrames { dir, frames } => {
                write!(
                    f,
                    "{} numbered OBJ frames in {}",
                    frames.len(),
                    dir.display()
                )
            }
            SequenceLayout::PlyFrames { dir, frames } => {
                write!(
                    f,
                    "{} numbered PLY frames in {}",
                    frames.len(),
                    dir.display()
                )
            }
            SequenceLayout::ObjPc2 { obj, pc2, header } => write!(
                f,
                "{} with {} samples of {} points (start frame {}, rate {}), topology {}",
                pc2.display(),
                header.num_samples,
                header.num_points,
                header.start_frame,
                header.sample_rate,
                obj.display()
            ),
        }
    }
}

/// An opened input: the lazy frame source and the layout it was read from (needed to create the matching sink).
pub struct OpenedSequence {
    pub source: Box<dyn FrameSource>,
    pub layout: SequenceLayout,
}

impl fmt::Debug for OpenedSequence {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("OpenedSequence")
            .field("layout", &self.layout)
            .field("n_frames", &self.source.n_frames())
            .finish_non_exhaustive()
    }
}

fn extension_is(path: &Path, ext: &str) -> bool {
    path.extension()
        .is_some_and(|e| e.to_string_lossy().eq_ignore_ascii_case(ext))
}

/// Lists the candidate files of a directory, sorted by name. Hidden files (`.name`, including macOS `._name`
/// resource forks and our own temporary files) and subdirectories are not part of a sequence.
fn list_files(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))? {
        let entry = entry.map_err(|e| Error::io(dir, e))?;
        let path = entry.path();
        if entry.file_name().to_string_lossy().starts_with('.') {
            continue;
        }
        // Follows symlinks, so linked frame files count.
        if path.is_file() {
            files.push(path);
        }
    }
    files.sort();
    Ok(files)
}

/// The OBJ next to `file` with the same stem (any case of the extension).
fn sibling_obj(file: &Path) -> Result<Option<PathBuf>> {
    let dir = file
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let stem = file.file_stem();
    Ok(list_files(dir)?
        .into_iter()
        .find(|p| extension_is(p, "obj") && p.file_stem() == stem))
}

/// Works out how the sequence at `path` is stored, without reading any frame:
/// * a directory of numbered `.obj` files, or of numbered `.ply` files (frame number = last run of digits in
///   the file stem, sorted numerically);
/// * a directory holding exactly one `.pc2` and one `.obj`, or the path of a `.pc2` (or of an `.obj`) whose
///   sibling with the same stem is the other half.
///
/// Files with other extensions (`.mtl`, notes, …) are ignored. A directory mixing OBJ and PLY frames, an empty
/// directory, or an ambiguous point-cache directory is an error that says what was found.
pub fn detect_layout(path: &Path) -> Result<SequenceLayout> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if meta.is_file() {
        let pair = if extension_is(path, "pc2") {
            let obj = sibling_obj(path)?.ok_or_else(|| {
                Error::format(
                    path,
                    None,
                    format!(
                        "no OBJ with the same name next to this point cache (expected {}.obj) to provide the \
                         topology",
                        path.file_stem().unwrap_or_default().to_string_lossy()
                    ),
                )
            })?;
            Some((obj, path.to_path_buf()))
        } else if extension_is(path, "obj") {
            let dir = path
                .parent()
                .filter(|p| !p.as_os_str().is_empty())
                .unwrap_or(Path::new("."));
            let stem = path.file_stem();
            list_files(dir)?
                .into_iter()
                .find(|p| extension_is(p, "pc2") && p.file_stem() == stem)
                .map(|pc2| (path.to_path_buf(), pc2))
        } else {
            None
        };
        let Some((obj, pc2)) = pair else {
            return Err(Error::format(
                path,
                None,
                "is a single file; expected a directory of numbered .obj or .ply frames, or a .pc2 point cache \
                 with an .obj of the same name next to it",
            ));
        };
        let header = read_pc2_header(&pc2)?;
        return Ok(SequenceLayout::ObjPc2 { obj, pc2, header });
    }

    let files = list_files(path)?;
    let of = |ext: &str| {
        files
            .iter()
            .filter(|p| extension_is(p, ext))
            .cloned()
            .collect::<Vec<_>>()
    };
    let (objs, plys, pc2s) = (of("obj"), of("ply"), of("pc2"));
    let names = |v: &[PathBuf]| {
        let shown: Vec<String> = v.iter().take(3).map(|p| file_name(p)).collect();
        let more = if v.len() > 3 {
            format!(", … ({} in all)", v.len())
        } else {
            String::new()
        };
        format!("{}{more}", shown.join(", "))
    };
    if !pc2s.is_empty() {
        return match (pc2s.as_slice(), objs.as_slice(), plys.is_empty()) {
            ([pc2], [obj], true) => Ok(SequenceLayout::ObjPc2 {
                obj: obj.clone(),
                pc2: pc2.clone(),
                header: read_pc2_header(pc2)?,
            }),
            _ => Err(Error::format(
                path,
                None,
                format!(
                    "a point-cache directory must hold exactly one .pc2 and one .obj (and no .ply); found {} .pc2 \
                     ({}), {} .obj, {} .ply",
                    pc2s.len(),
                    names(&pc2s),
                    objs.len(),
                    plys.len()
                ),
            )),
        };
    }
    match (objs.is_empty(), plys.is_empty()) {
        (true, true) => Err(Error::format(
            path,
            None,
            if files.is_empty() {
                "the directory is empty; expected numbered .obj or .ply frames, or a .pc2 with its .obj".to_string()
            } else {
                format!(
                    "the directory has no .obj, .ply or .pc2 files (found {} other files, e.g. {})",
                    files.len(),
                    names(&files)
                )
            },
        )),
        (false, false) => Err(Error::format(
            path,
            None,
            format!(
                "the directory mixes OBJ and PLY frames ({} .obj: {}; {} .ply: {}); keep one format per sequence",
                objs.len(),
                names(&objs),
                plys.len(),
                names(&plys)
            ),
        )),
        (false, true) => Ok(SequenceLayout::ObjFrames {
            dir: path.to_path_buf(),
            frames: sort_numbered(objs)?,
        }),
        (true, false) => Ok(SequenceLayout::PlyFrames {
            dir: path.to_path_buf(),
            frames: sort_numbered(plys)?,
        }),
    }
}

/// Opens a detected layout as a lazy frame source. Reads the topology (from the first frame, or from the OBJ of
/// a point cache) and validates it; frames are read and validated one by one in
/// [`FrameSource::read_frame`].
pub fn open_layout(layout: &SequenceLayout) -> Result<Box<dyn FrameSource>> {
    Ok(match layout {
        SequenceLayout::ObjFrames { frames, .. } => Box::new(FrameDirSource::open(
            FrameFormat::Obj,
            frames.iter().map(|f| f.path.clone()).collect(),
        )?),
        SequenceLayout::PlyFrames { frames, .. } => Box::new(FrameDirSource::open(
            FrameFormat::Ply,
            frames.iter().map(|f| f.path.clone()).collect(),
        )?),
        SequenceLayout::ObjPc2 { obj, pc2, .. } => Box::new(Pc2Source::open(obj, pc2)?),
    })
}

/// Detects the layout at `path` ([`detect_layout`]) and opens it ([`open_layout`]).
pub fn open_sequence(path: &Path) -> Result<OpenedSequence> {
    let layout = detect_layout(path)?;
    let source = open_layout(&layout)?;
    Ok(OpenedSequence { source, layout })
}

/// Copies the `.mtl` material libraries next to OBJ inputs into `out_dir`, so the output frames' `mtllib`
/// lines (kept verbatim) still resolve.
fn copy_material_libraries(input_dir: &Path, out_dir: &Path) -> Result<()> {
    let dir = if input_dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        input_dir
    };
    for file in list_files(dir)? {
        if extension_is(&file, "mtl") {
            if let Some(name) = file.file_name() {
                let bytes = std::fs::read(&file).map_err(|e| Error::io(&file, e))?;
                fsutil::write_atomic(&out_dir.join(name), &bytes)?;
            }
        }
    }
    Ok(())
}

/// Creates a sink writing into `out_dir` (created if needed) in the layout of the input: the same file names,
/// each output frame derived from its input file (see the OBJ and PLY rewriters for what is kept), or a copy of
/// the topology OBJ plus a PC2 with the input's header. `out_dir` must not be an input directory, since the
/// output files have the input's names.
pub fn create_sink(source_layout: &SequenceLayout, out_dir: &Path) -> Result<Box<dyn FrameSink>> {
    fsutil::create_dir_all(out_dir)?;
    let out_canon = std::fs::canonicalize(out_dir).map_err(|e| Error::io(out_dir, e))?;
    for dir in source_layout.input_dirs() {
        let dir = if dir.as_os_str().is_empty() {
            PathBuf::from(".")
        } else {
            dir
        };
        if std::fs::canonicalize(&dir).is_ok_and(|d| d == out_canon) {
            return Err(Error::param(
                "output directory",
                format!(
                    "{} holds the input sequence; writing there would overwrite the input files, choose another \
                     directory",
                    out_dir.display()
                ),
            ));
        }
    }
    if let SequenceLayout::ObjFrames { dir, .. } = source_layout {
        copy_material_libraries(dir, out_dir)?;
    }
    if let SequenceLayout::ObjPc2 { obj, .. } = source_layout {
        copy_material_libraries(obj.parent().unwrap_or(Path::new(".")), out_dir)?;
    }
    Ok(match source_layout {
        SequenceLayout::ObjFrames { frames, .. } => Box::new(FrameDirSink::new(
            FrameFormat::Obj,
            frames.iter().map(|f| f.path.clone()).collect(),
            out_dir,
        )?),
        SequenceLayout::PlyFrames { frames, .. } => Box::new(FrameDirSink::new(
            FrameFormat::Ply,
            frames.iter().map(|f| f.path.clone()).collect(),
            out_dir,
        )?),
        SequenceLayout::ObjPc2 { obj, pc2, header } => {
            Box::new(Pc2Sink::create(obj, pc2, *header, out_dir)?)
        }
    })
}

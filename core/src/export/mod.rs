//! Writers that hand a finished sequence to the tools artists use: glTF 2.0 binary (game engines, web viewers,
//! Blender), USD (Houdini, Maya, Blender, Omniverse; Alembic via USD in the DCC, see docs/export.md), and the
//! MDD and PC2 point caches (Blender's Mesh Cache modifier, Maya, Max).
//!
//! Every writer streams: frames are read from the [`FrameSource`] one at a time (twice where the format puts
//! per-frame metadata before the data), so memory is bounded by a frame, never by the shot. Each file is
//! written under a hidden temporary name and renamed into place only when complete, so a failed export (a bad
//! frame, a full disk) never leaves a truncated file that looks valid.

mod glb;
mod mdd;
mod pc2_cache;
mod staging;
mod usd;

use crate::error::{Error, Result};
use crate::mesh::{Frame, FrameSource};
use crate::progress::Progress;
use crate::vec3::V3;
use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;

pub use glb::write_glb;
pub use mdd::write_mdd;
pub use pc2_cache::write_pc2_cache;
pub use usd::write_usda;

/// A file format `crease export` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ExportFormat {
    /// glTF 2.0 binary: mesh, normals, one morph target per frame after the first, linear weights animation.
    Glb,
    /// USD ASCII (`.usda`): a Mesh with time-sampled points, normals and extent.
    Usd,
    /// MDD point cache (big-endian).
    Mdd,
    /// PC2 point cache (little-endian).
    Pc2,
}

impl ExportFormat {
    pub const ALL: [ExportFormat; 4] = [
        ExportFormat::Glb,
        ExportFormat::Usd,
        ExportFormat::Mdd,
        ExportFormat::Pc2,
    ];

    /// File extension of the written file.
    pub fn extension(self) -> &'static str {
        match self {
            ExportFormat::Glb => "glb",
            ExportFormat::Usd => "usda",
            ExportFormat::Mdd => "mdd",
            ExportFormat::Pc2 => "pc2",
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            ExportFormat::Glb => "glb",
            ExportFormat::Usd => "usd",
            ExportFormat::Mdd => "mdd",
            ExportFormat::Pc2 => "pc2",
        }
    }
}

impl fmt::Display for ExportFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for ExportFormat {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        ExportFormat::ALL
            .into_iter()
            .find(|f| f.name().eq_ignore_ascii_case(s) || f.extension().eq_ignore_ascii_case(s))
            .ok_or_else(|| {
                Error::param(
                    "format",
                    format!("unknown export format `{s}`; expected glb, usd, mdd or pc2"),
                )
            })
    }
}

/// Which axis points up in the exported sequence's coordinates (the data's convention, not the format's).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum UpAxis {
    Y,
    /// crease's sample data (Blender captures) are +z up.
    #[default]
    Z,
}

/// Timing and orientation of an export; the defaults suit the sample data (30 fps, +z up, frame 1 first).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ExportOptions {
    /// Frames per second of the sequence (glTF and MDD store seconds; USD stores it as timeCodesPerSecond).
    pub fps: f64,
    /// Frame number of the first frame (USD time code, PC2 start frame).
    pub first_frame: f64,
    /// The data's up axis: USD records it, glTF (always +y up) gets a root rotation for +z up data.
    pub up_axis: UpAxis,
}

impl Default for ExportOptions {
    fn default() -> Self {
        ExportOptions {
            fps: 30.0,
            first_frame: 1.0,
            up_axis: UpAxis::Z,
        }
    }
}

impl ExportOptions {
    pub fn validate(&self) -> Result<()> {
        if !(self.fps.is_finite() && self.fps > 0.0 && self.fps <= 10_000.0) {
            return Err(Error::param(
                "fps",
                format!("must be in (0, 10000], got {}", self.fps),
            ));
        }
        if !self.first_frame.is_finite() || self.first_frame.abs() > 1e7 {
            return Err(Error::param(
                "first_frame",
                format!("must be a finite frame number, got {}", self.first_frame),
            ));
        }
        Ok(())
    }
}

/// What an export wrote.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ExportSummary {
    pub format: ExportFormat,
    pub path: PathBuf,
    pub frames: usize,
    pub vertices: usize,
    pub bytes: u64,
}

/// Writes `source` to `out` in `format`, streaming frame by frame. `progress` sees one stage `export <format>`
/// advancing once per frame read (twice per frame for the two-pass formats).
pub fn export(
    source: &dyn FrameSource,
    format: ExportFormat,
    out: &Path,
    opts: &ExportOptions,
    progress: &dyn Progress,
) -> Result<ExportSummary> {
    opts.validate()?;
    if source.n_frames() == 0 {
        return Err(Error::param(
            "input",
            "the sequence has no frames to export",
        ));
    }
    let stage = format!("export {format}");
    let n = source.n_frames();
    // GLB keeps the base frame between its passes; USD reads every frame twice.
    let reads = match format {
        ExportFormat::Glb => 2 * n - 1,
        ExportFormat::Usd => 2 * n,
        ExportFormat::Mdd | ExportFormat::Pc2 => n,
    };
    progress.begin(&stage, reads as u64);
    let frames = FrameReader {
        source,
        progress,
        stage: &stage,
    };
    match format {
        ExportFormat::Glb => write_glb(&frames, out, opts)?,
        ExportFormat::Usd => write_usda(&frames, out, opts)?,
        ExportFormat::Mdd => write_mdd(&frames, out, opts)?,
        ExportFormat::Pc2 => write_pc2_cache(&frames, out, opts)?,
    }
    progress.end(&stage);
    let bytes = std::fs::metadata(out).map_err(|e| Error::io(out, e))?.len();
    Ok(ExportSummary {
        format,
        path: out.to_path_buf(),
        frames: source.n_frames(),
        vertices: source.topology().n_vertices(),
        bytes,
    })
}

/// A source plus progress and cancellation: the writers read frames only through this.
pub struct FrameReader<'a> {
    pub source: &'a dyn FrameSource,
    pub progress: &'a dyn Progress,
    pub stage: &'a str,
}

impl FrameReader<'_> {
    pub fn n_frames(&self) -> usize {
        self.source.n_frames()
    }

    /// Frame `t`, checked for the topology's vertex count and finite values (an export never writes NaN).
    pub fn read(&self, t: usize) -> Result<Frame> {
        if self.progress.cancelled() {
            return Err(Error::Cancelled);
        }
        let frame = self.source.read_frame(t)?;
        let n = self.source.topology().n_vertices();
        if frame.len() != n {
            return Err(Error::mesh(format!(
                "{} has {} vertices, the topology has {n}",
                self.source.describe_frame(t),
                frame.len()
            ))
            .at(None, Some(t)));
        }
        if let Some(v) = frame.iter().position(|p| !crate::vec3::is_finite(*p)) {
            return Err(Error::mesh(format!(
                "{}: vertex {v} is not finite",
                self.source.describe_frame(t)
            ))
            .at(None, Some(t)));
        }
        self.progress.advance(self.stage, 1);
        Ok(frame)
    }
}

/// Positions rounded to the f32 every format stores.
pub(crate) fn to_f32(p: V3) -> [f32; 3] {
    [p[0] as f32, p[1] as f32, p[2] as f32]
}

/// Unit vertex normals in f32 (area-weighted; an isolated or degenerate vertex gets +z so that every normal
/// is unit length, as glTF requires).
pub(crate) fn unit_normals(topo: &crate::mesh::Topology, p: &[V3]) -> Vec<[f32; 3]> {
    crate::mesh::geometry::vertex_normals(topo, p)
        .into_iter()
        .map(|n| {
            let f = to_f32(n);
            let len = (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
            if len.is_finite() && len > 0.5 {
                [f[0] / len, f[1] / len, f[2] / len]
            } else {
                [0.0, 0.0, 1.0]
            }
        })
        .collect()
}

#[cfg(test)]
pub(crate) mod test_support;

#[cfg(test)]
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::test_support::two_triangles;
    use super::*;
    use crate::mesh::{Sequence, Topology};
    use crate::progress::NoProgress;
    use std::sync::Arc;

    /// Frame 2 holds a NaN (as a corrupted intermediate would); the source itself does not validate.
    struct Poisoned(Sequence);
    impl FrameSource for Poisoned {
        fn topology(&self) -> &Arc<Topology> {
            &self.0.topology
        }
        fn n_frames(&self) -> usize {
            self.0.frames.len()
        }
        fn read_frame(&self, t: usize) -> Result<Frame> {
            let mut f = self.0.frames[t].clone();
            if t == 2 {
                f[1][0] = f64::NAN;
            }
            Ok(f)
        }
        fn describe_frame(&self, t: usize) -> String {
            format!("poisoned frame {t}")
        }
    }

    #[test]
    fn a_bad_frame_fails_the_export_naming_it_and_leaves_no_file() {
        let dir = tempfile::tempdir().unwrap();
        for format in ExportFormat::ALL {
            let out = dir.path().join(format!("a.{}", format.extension()));
            let err = export(
                &Poisoned(two_triangles(4)),
                format,
                &out,
                &ExportOptions::default(),
                &NoProgress,
            )
            .unwrap_err()
            .to_string();
            assert!(
                err.contains("poisoned frame 2") && err.contains("vertex 1"),
                "{format}: {err}"
            );
            assert!(!out.exists(), "{format}: a partial file was left behind");
        }
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            0,
            "temporary files left"
        );
    }

    #[test]
    fn formats_parse_by_name_or_extension_and_bad_options_are_named() {
        assert_eq!("USDA".parse::<ExportFormat>().unwrap(), ExportFormat::Usd);
        assert_eq!("glb".parse::<ExportFormat>().unwrap(), ExportFormat::Glb);
        let e = "abc".parse::<ExportFormat>().unwrap_err().to_string();
        assert!(
            e.contains("`abc`") && e.contains("glb, usd, mdd or pc2"),
            "{e}"
        );
        let bad = ExportOptions {
            fps: 0.0,
            ..Default::default()
        };
        let e = bad.validate().unwrap_err().to_string();
        assert!(e.contains("`fps`"), "{e}");
    }
}

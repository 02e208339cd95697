//! `crease run --folds stretch`: fold estimation from the geometry alone (Chen 2011 ch. 4).
//!
//! Flags are prefixed `--stretch-` (they only apply to this detector); `--subdivide` runs detection and
//! deformation on a midpoint-subdivided sequence. Writes `anchors.json` (anchors plus control lines),
//! `folds/control_lines.obj` (the lines as OBJ polylines, one object per frame) and `folds.png` next to the output.

use anyhow::{anyhow, Context, Result};
use clap::Args;
use crease_core::folds::stretch::overlay::{overlay, OverlayFrame};
use crease_core::folds::stretch::{StretchDetector, StretchParams};
use crease_core::folds::{AnchorSet, FrameAnchors};
use crease_core::mesh::io::write_obj;
use crease_core::mesh::{FrameSink, FrameSource, Topology};
use crease_core::progress::Progress;
use crease_core::vec3::V3;
use crease_core::{fsutil, render, Error};
use serde_json::json;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Parameters of `--folds stretch` (defaults: see README, "Folds from the geometry").
#[derive(Args, Clone, Debug)]
pub struct StretchArgs {
    /// θ0 (degrees, in (0, 90)): largest direction change within one phase (eq. 4.2).
    #[arg(long = "stretch-theta0", default_value_t = StretchParams::default().theta0_deg, allow_hyphen_values = true)]
    pub theta0: f64,
    /// Steps with absolute change below 1 + this are isometric (a fold holding its shape).
    #[arg(long = "stretch-isometry", default_value_t = StretchParams::default().isometry, allow_hyphen_values = true)]
    pub isometry: f64,
    /// Consecutive isometric steps a phase survives.
    #[arg(long = "stretch-max-hold", default_value_t = StretchParams::default().max_hold)]
    pub max_hold: usize,
    /// Smoothing iterations of Γ, γ and the direction angle.
    #[arg(long = "stretch-smooth-iterations", default_value_t = StretchParams::default().smooth_iterations)]
    pub smooth_iterations: usize,
    /// Valid range: absolute changes above this are outliers.
    #[arg(long = "stretch-max-change", default_value_t = StretchParams::default().max_change, allow_hyphen_values = true)]
    pub max_change: f64,
    /// Histogram tails: sparse extreme bins below this fraction of triangles are dropped (0 = off).
    #[arg(long = "stretch-tail-fraction", default_value_t = StretchParams::default().tail_fraction, allow_hyphen_values = true)]
    pub tail_fraction: f64,
    /// Seeds need integrated shrinkage of at least 1 + this (absolute change).
    #[arg(long = "stretch-min-shrink", default_value_t = StretchParams::default().min_shrink, allow_hyphen_values = true)]
    pub min_shrink: f64,
    /// Tracing stops where shrinkage falls below this fraction of the seed's.
    #[arg(long = "stretch-fade", default_value_t = StretchParams::default().fade, allow_hyphen_values = true)]
    pub fade: f64,
    /// Tracing stops at a direction turn above this many degrees.
    #[arg(long = "stretch-max-turn", default_value_t = StretchParams::default().max_turn_deg, allow_hyphen_values = true)]
    pub max_turn: f64,
    /// Fold width at |v| = 1 in mean edge lengths (width = this / |v|).
    #[arg(long = "stretch-fold-width", default_value_t = StretchParams::default().fold_width, allow_hyphen_values = true)]
    pub fold_width: f64,
    /// α of eq. 4.3 in mean edge lengths: region of influence radius α·|v|.
    #[arg(long = "stretch-alpha", default_value_t = StretchParams::default().alpha, allow_hyphen_values = true)]
    pub alpha: f64,
    /// Radius of the flattened patch around a seed, in mean edge lengths.
    #[arg(long = "stretch-patch-radius", default_value_t = StretchParams::default().patch_radius, allow_hyphen_values = true)]
    pub patch_radius: f64,
    /// Anchor angle (radians) per unit of shrinkage |v| − 1.
    #[arg(long = "stretch-angle-gain", default_value_t = StretchParams::default().angle_gain, allow_hyphen_values = true)]
    pub angle_gain: f64,
    /// Cap of the anchor angle, degrees.
    #[arg(long = "stretch-max-angle", default_value_t = StretchParams::default().max_angle_deg, allow_hyphen_values = true)]
    pub max_angle: f64,
    /// Shortest fold axis kept, in mean edge lengths.
    #[arg(long = "stretch-min-length", default_value_t = StretchParams::default().min_length, allow_hyphen_values = true)]
    pub min_length: f64,
    /// Levels of midpoint subdivision before detection (0 = none); output is then on the subdivided mesh,
    /// original vertices first.
    #[arg(long, default_value_t = 0)]
    pub subdivide: usize,
}

impl StretchArgs {
    pub fn params(&self) -> StretchParams {
        StretchParams {
            theta0_deg: self.theta0,
            isometry: self.isometry,
            max_hold: self.max_hold,
            smooth_iterations: self.smooth_iterations,
            max_change: self.max_change,
            tail_fraction: self.tail_fraction,
            min_shrink: self.min_shrink,
            fade: self.fade,
            max_turn_deg: self.max_turn,
            fold_width: self.fold_width,
            alpha: self.alpha,
            patch_radius: self.patch_radius,
            angle_gain: self.angle_gain,
            max_angle_deg: self.max_angle,
            min_length: self.min_length,
        }
    }

    /// Validates the parameters; errors name the flag.
    pub fn validated(&self) -> Result<StretchParams> {
        let p = self.params();
        p.validate().map_err(|e| match e {
            Error::Param { name, msg } => anyhow!("--stretch-{name}: {msg}"),
            e => e.into(),
        })?;
        if self.subdivide > 4 {
            return Err(anyhow!(
                "--subdivide: at most 4 levels (256× the triangles), got {}",
                self.subdivide
            ));
        }
        Ok(p)
    }
}

/// Runs the detector on `source`, writes `anchors.json`, `control_lines.obj` and `folds.png` into `out`, and
/// returns the anchors with a JSON summary for the report.
pub fn detect(
    source: &dyn FrameSource,
    params: StretchParams,
    out: &Path,
    overlay_frames: &[usize],
    overlay_size: u32,
    progress: &dyn Progress,
) -> Result<(AnchorSet, PathBuf, serde_json::Value)> {
    let topo = source.topology().clone();
    let start = std::time::Instant::now();
    let detector = StretchDetector::new(params.clone());
    let mut frames: Vec<FrameAnchors> = Vec::with_capacity(source.n_frames());
    let mut shown: Vec<OverlayFrame> = Vec::new();
    let mut n_folds = 0usize;
    let mut seeds_tried = 0usize;
    detector.run(source, progress, |t, positions, shrink, folds| {
        n_folds += folds.folds.len();
        seeds_tried += folds.seeds_tried;
        if overlay_frames.contains(&t) {
            shown.push(OverlayFrame {
                frame: t,
                positions: positions.to_vec(),
                shrink: shrink.to_vec(),
                anchors: folds.anchors.clone(),
                n_folds: folds.folds.len(),
            });
        }
        frames.push(FrameAnchors {
            frame: t,
            anchors: folds.anchors,
            control_lines: folds.folds.into_iter().flat_map(|f| f.lines).collect(),
        });
        Ok(())
    })?;
    let seconds = start.elapsed().as_secs_f64();
    let anchors = AnchorSet::from_frame_anchors(frames, topo.n_triangles(), None)?;
    let anchors_path = out.join("anchors.json");
    anchors.write(&anchors_path)?;
    // In a subdirectory: an extra .obj beside the output frames would make the output unreadable as a sequence.
    let lines_dir = out.join("folds");
    fsutil::create_dir_all(&lines_dir)?;
    let lines_path = lines_dir.join("control_lines.obj");
    write_control_lines(&lines_path, &anchors)?;
    let png = out.join("folds.png");
    let img = overlay(&topo, &shown, overlay_size, 1.0 + 4.0 * params.min_shrink);
    render::save_png(&img, &png)?;
    let n = source.n_frames().max(1);
    let summary = json!({
        "source": "stretch",
        "parameters": params,
        "folds": n_folds,
        "seeds_tried": seeds_tried,
        "anchors": anchors.total(),
        "seconds_per_frame": seconds / n as f64,
        "files": [anchors_path, lines_path, png],
    });
    Ok((anchors, anchors_path, summary))
}

/// Control lines as OBJ polylines (`v` + `l`), one `o frame_N` object per frame, for viewing in any DCC tool.
fn write_control_lines(path: &Path, anchors: &AnchorSet) -> Result<()> {
    let mut s = String::new();
    let mut next = 1usize;
    for t in 0..anchors.n_frames() {
        let lines = anchors.control_lines(t);
        if lines.is_empty() {
            continue;
        }
        let _ = writeln!(s, "o frame_{t}");
        for line in lines {
            for p in line {
                let _ = writeln!(s, "v {} {} {}", p[0], p[1], p[2]);
            }
            let idx: Vec<String> = (next..next + line.len()).map(|i| i.to_string()).collect();
            let _ = writeln!(s, "l {}", idx.join(" "));
            next += line.len();
        }
    }
    fsutil::write_atomic(path, s.as_bytes()).with_context(|| format!("writing {}", path.display()))
}

/// Writes plain OBJ frames of a (subdivided) topology that the input layout's sink cannot rewrite, named
/// after the input frames (`.obj`).
pub struct ObjFramesSink {
    dir: PathBuf,
    names: Vec<String>,
    topology: Arc<Topology>,
    written: Vec<PathBuf>,
}

impl ObjFramesSink {
    pub fn new(
        dir: &Path,
        input_files: &[PathBuf],
        n_frames: usize,
        topology: Arc<Topology>,
    ) -> Result<Self> {
        fsutil::create_dir_all(dir)?;
        let width = n_frames.to_string().len().max(4);
        let names = if input_files.len() == n_frames {
            input_files
                .iter()
                .map(|p| {
                    let stem = p.file_stem().map(|s| s.to_string_lossy().into_owned());
                    format!("{}.obj", stem.unwrap_or_default())
                })
                .collect()
        } else {
            (0..n_frames)
                .map(|t| format!("frame_{:0width$}.obj", t + 1))
                .collect()
        };
        Ok(ObjFramesSink {
            dir: dir.to_path_buf(),
            names,
            topology,
            written: Vec::new(),
        })
    }
}

impl FrameSink for ObjFramesSink {
    fn write_frame(&mut self, t: usize, positions: &[V3]) -> crease_core::Result<()> {
        let name = self
            .names
            .get(t)
            .ok_or_else(|| Error::param("frame", format!("output frame {t} is out of range")))?;
        let path = self.dir.join(name);
        write_obj(&path, &self.topology, positions)?;
        self.written.push(path);
        Ok(())
    }
    fn finish(&mut self) -> crease_core::Result<Vec<PathBuf>> {
        self.written.sort();
        Ok(self.written.clone())
    }
}

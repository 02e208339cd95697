//! The flags of `crease run`: what changes from shot to shot (input, output, the fold source and its files,
//! the weight mode, the strain limit), grouped under the headings `--help` shows. The job they describe is
//! built by [`crate::run_spec`] and run by [`crate::run`].

use clap::Args;
use crease_core::spacetime::WeightMode;
use std::path::PathBuf;

const DEMO: &str = "Built-in demo (without --input)";
const IO: &str = "Input and output";
const FOLDS: &str = "Folds";
const SOLVE: &str = "Deformation";
const LOCAL: &str = "Single-node cluster";

/// Where the folds come from.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Folds {
    /// An anchors file (--anchors).
    Anchors,
    /// The geometry alone (Chen 2011 ch. 4); --subdivide, `stretch.*` tuning keys.
    Stretch,
    /// The capture video (Popa et al. 2009 §4): --cameras, --images; `video.*` tuning keys.
    Video,
}

#[derive(Args, Debug)]
#[command(
    after_help = "Every other setting is a tuning key, set with --set KEY=VALUE (repeatable) or in a job \
spec's [tuning] table: `crease tuning` lists them with their defaults, ranges and meanings (docs/tuning.md)."
)]
pub struct RunArgs {
    /// Input sequence: a directory of numbered OBJ or PLY frames, or OBJ + PC2. Omit to run the built-in demo.
    #[arg(long, help_heading = IO)]
    pub input: Option<PathBuf>,
    /// Output directory (the wrinkled sequence, report.json, preview.png, stretch.png).
    #[arg(long, help_heading = IO)]
    pub out: Option<PathBuf>,
    /// Frames to show in preview.png (default: four spread over the sequence).
    #[arg(long, value_delimiter = ',', help_heading = IO)]
    pub preview_frames: Vec<usize>,
    /// Preview tile size in pixels.
    #[arg(long, default_value_t = 384, help_heading = IO)]
    pub preview_size: u32,
    /// No progress bars or log lines.
    #[arg(long, help_heading = IO)]
    pub quiet: bool,
    /// Where the folds come from: `anchors` (the --anchors file; the default), `stretch` (estimated from the
    /// geometry alone, Chen 2011 ch. 4) or `video` (from the capture video, Popa et al. 2009 §4). Detectors
    /// write anchors.json and their overlays to --out.
    #[arg(long, value_enum, help_heading = FOLDS)]
    pub folds: Option<Folds>,
    /// Anchors file (JSON, see docs/formats.md). Required with --input unless --folds detects them.
    #[arg(long, help_heading = FOLDS)]
    pub anchors: Option<PathBuf>,
    /// --folds video: the camera calibration (JSON, OpenCV convention; see docs/folds.md).
    #[arg(long, help_heading = FOLDS)]
    pub cameras: Option<PathBuf>,
    /// --folds video: directory holding `<camera>/frame_NNNN.png` (default: the cameras file's
    /// `image_pattern`, relative to it).
    #[arg(long, help_heading = FOLDS)]
    pub images: Option<PathBuf>,
    /// --folds stretch: levels of midpoint subdivision before detection (0 to 4); the output is then on the
    /// subdivided mesh, original vertices first.
    #[arg(long, default_value_t = 0, help_heading = FOLDS)]
    pub subdivide: u32,
    /// Detail scale, in the input's length unit (0.03 = 3 cm on a mesh in metres): the fold width a capture is
    /// taken to blur; the fold relief undoes a generic low-pass at it, and the shape is held at twice it
    /// [default: five mean edge lengths of the first frame].
    #[arg(long, value_name = "LENGTH", help_heading = FOLDS)]
    pub detail_scale: Option<f64>,
    /// Weight solve: `fused` (3 right-hand sides per window) or `per-anchor` (one CG column per anchor, in
    /// blocks) [default: fused].
    #[arg(long, help_heading = SOLVE)]
    pub mode: Option<WeightMode>,
    /// Strain limit: the positioning's last step shortens every edge longer than (1 + this) times its
    /// reference length (a fraction, 0.05 = 5%; `off` or 0 turns it off) [default: 0.05; the built-in demo,
    /// whose input is its own rest state, 0.02].
    #[arg(long, value_parser = parse_strain_limit, help_heading = SOLVE)]
    pub strain_limit: Option<f64>,
    /// A tuning key, KEY=VALUE (repeatable; lists as `1,1.5,2.5`): `crease tuning` lists every key with its
    /// default, range and meaning.
    #[arg(long = "set", value_name = "KEY=VALUE", help_heading = SOLVE)]
    pub set: Vec<String>,
    /// Demo size in triangles.
    #[arg(long, default_value_t = 40_000, help_heading = DEMO)]
    pub demo_triangles: usize,
    /// Demo length in frames.
    #[arg(long, default_value_t = 36, help_heading = DEMO)]
    pub demo_frames: usize,
    /// Workers of the single-node cluster (each a gRPC server on 127.0.0.1).
    #[arg(long, default_value_t = 1, help_heading = LOCAL)]
    pub local_workers: usize,
    /// Tasks each local worker runs at the same time.
    #[arg(long, default_value_t = 2, help_heading = LOCAL)]
    pub local_capacity: u32,
}

fn parse_strain_limit(s: &str) -> Result<f64, String> {
    if s == "off" {
        return Ok(0.0);
    }
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        _ => Err(format!(
            "`{s}` is not a strain limit (a fraction ≥ 0, 0.05 = 5%) or `off`"
        )),
    }
}

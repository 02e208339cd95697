//! `crease run --folds video`: flags and driver of video fold estimation (Popa et al. 2009 §4).

use crate::progress::CliProgress;
use anyhow::{bail, Context, Result};
use clap::Args;
use crease_core::folds::video::{overlay, CameraRig, VideoFolds, VideoParams};
use crease_core::folds::{AnchorSet, FoldDetector};
use crease_core::mesh::io::SequenceLayout;
use crease_core::mesh::FrameSource;
use crease_core::{fsutil, render};
use std::path::{Path, PathBuf};

/// Flags of `--folds video`. Tuning flags default to the paper's values (see README, "Folds from video").
#[derive(Args, Debug, Clone, Default)]
pub struct VideoArgs {
    /// Camera calibration (JSON, OpenCV convention; see README).
    #[arg(long)]
    pub cameras: Option<PathBuf>,
    /// Directory holding `<camera>/frame_NNNN.png` (default: the `image_pattern` of the cameras file, relative
    /// to it).
    #[arg(long)]
    pub images: Option<PathBuf>,
    /// Tracked front vertex for view selection (default: chosen automatically from frame 0).
    #[arg(long)]
    pub front_vertex: Option<usize>,
    /// Tracked back vertex for view selection (default: chosen automatically from frame 0).
    #[arg(long)]
    pub back_vertex: Option<usize>,
    /// Image number of sequence frame 0 (default: each input frame file's own number, e.g. frame_0001.obj ->
    /// frame_0001.png; 1 for point caches).
    #[arg(long)]
    pub first_image_number: Option<u64>,
    /// Frames (0-based) to draw fold-edge overlays for, into overlays/ (like the paper's Figure 4).
    #[arg(long, value_delimiter = ',')]
    pub overlay_frames: Vec<usize>,
    /// Canny Gaussian radii in pixels [default: 1,1.5,2.5,3.5].
    #[arg(long, value_delimiter = ',')]
    pub canny_radii: Vec<f64>,
    /// Image resolutions as fractions of the full image [default: 1].
    #[arg(long, value_delimiter = ',')]
    pub scales: Vec<f64>,
    /// Canny low / high gradient thresholds (0-255 grey) [default: 12, 30].
    #[arg(long)]
    pub canny_low: Option<f64>,
    #[arg(long)]
    pub canny_high: Option<f64>,
    /// Maximum angle between paired edges, degrees [default: 45].
    #[arg(long)]
    pub max_angle: Option<f64>,
    /// Maximal distance between paired edges, pixels [default: 12].
    #[arg(long)]
    pub max_distance: Option<f64>,
    /// Maximum average distance between paired edges, pixels [default: 9].
    #[arg(long)]
    pub max_avg_distance: Option<f64>,
    /// Minimum grey contrast across an edge for a clear orientation [default: 4].
    #[arg(long)]
    pub min_contrast: Option<f64>,
    /// Quadric fit tolerance, pixels [default: 1].
    #[arg(long)]
    pub fit_tolerance: Option<f64>,
    /// Maximum curvature of an edge, 1/pixel [default: 0.08].
    #[arg(long)]
    pub max_curvature: Option<f64>,
    /// Shortest edge kept, pixels [default: 8].
    #[arg(long)]
    pub min_edge_length: Option<f64>,
    /// Maximum chromaticity difference across an edge [default: 0.04].
    #[arg(long)]
    pub max_hue_difference: Option<f64>,
    /// Drop pairs whose edges run on the garment's border triangles (cuffs, collars, hems).
    #[arg(long)]
    pub skip_border: bool,
    /// Anchor angle of the narrowest / widest pairs of a frame, degrees [default: 60, 30].
    #[arg(long)]
    pub narrow_angle: Option<f64>,
    #[arg(long)]
    pub wide_angle: Option<f64>,
}

impl VideoArgs {
    pub fn params(&self) -> VideoParams {
        let d = VideoParams::default();
        let or = |v: Option<f64>, x: f64| v.unwrap_or(x);
        VideoParams {
            radii: if self.canny_radii.is_empty() {
                d.radii.clone()
            } else {
                self.canny_radii.clone()
            },
            scales: if self.scales.is_empty() {
                d.scales.clone()
            } else {
                self.scales.clone()
            },
            canny_low: or(self.canny_low, d.canny_low),
            canny_high: or(self.canny_high, d.canny_high),
            max_angle_deg: or(self.max_angle, d.max_angle_deg),
            max_distance: or(self.max_distance, d.max_distance),
            max_avg_distance: or(self.max_avg_distance, d.max_avg_distance),
            min_contrast: or(self.min_contrast, d.min_contrast),
            fit_tolerance: or(self.fit_tolerance, d.fit_tolerance),
            max_curvature: or(self.max_curvature, d.max_curvature),
            min_edge_length: or(self.min_edge_length, d.min_edge_length),
            max_hue_difference: or(self.max_hue_difference, d.max_hue_difference),
            narrow_angle_deg: or(self.narrow_angle, d.narrow_angle_deg),
            wide_angle_deg: or(self.wide_angle, d.wide_angle_deg),
            skip_border: self.skip_border,
            ..d
        }
    }
}

/// Image number of every sequence frame.
fn image_numbers(layout: &SequenceLayout, n: usize, first: Option<u64>) -> Vec<u64> {
    match (first, layout) {
        (Some(f), _) => (0..n as u64).map(|t| f + t).collect(),
        (
            None,
            SequenceLayout::ObjFrames { frames, .. } | SequenceLayout::PlyFrames { frames, .. },
        ) => frames.iter().map(|f| f.number).collect(),
        (None, _) => (1..=n as u64).collect(),
    }
}

/// Detects the folds of the whole sequence from video, writes `anchors.json` and the requested overlays into
/// `out`, and returns the anchors.
pub fn detect(
    args: &VideoArgs,
    source: &dyn FrameSource,
    layout: &SequenceLayout,
    out: &Path,
    progress: &CliProgress,
) -> Result<AnchorSet> {
    let Some(cameras) = &args.cameras else {
        bail!("--folds video needs --cameras (the calibration JSON, see README)")
    };
    let rig = CameraRig::read(cameras, args.images.as_deref())?;
    let n = source.n_frames();
    let numbers = image_numbers(layout, n, args.first_image_number);
    let frames: Vec<(usize, u64)> = numbers.iter().copied().enumerate().collect();
    rig.check_images(&frames)?;
    let mut det = VideoFolds::new(rig, args.params(), numbers)?;
    det.vertices = match (args.front_vertex, args.back_vertex) {
        (Some(f), Some(b)) => Some((f, b)),
        (None, None) => None,
        _ => {
            bail!("give both --front-vertex and --back-vertex, or neither for the automatic choice")
        }
    };
    let vertices = det.tracked_vertices(source)?;
    progress.println(&format!(
        "video folds: {} cameras, tracked vertices front {} back {}{}",
        det.rig.cameras.len(),
        vertices.0,
        vertices.1,
        if det.vertices.is_none() {
            " (automatic)"
        } else {
            ""
        }
    ));
    det.vertices = Some(vertices);
    for &f in &args.overlay_frames {
        if f >= n {
            bail!("--overlay-frames: frame {f} is out of range (the sequence has {n} frames, 0-based)");
        }
    }
    let t0 = std::time::Instant::now();
    let frames = det.detect(source, 0..n, progress)?;
    let topo = source.topology();
    let anchors = AnchorSet::from_frame_anchors(frames, topo.n_triangles(), None)?;
    let path = out.join("anchors.json");
    anchors.write(&path)?;
    progress.println(&format!(
        "video folds: {} anchors over {n} frames ({:.2}s/frame) -> {}",
        anchors.total(),
        t0.elapsed().as_secs_f64() / n.max(1) as f64,
        path.display()
    ));
    if !args.overlay_frames.is_empty() {
        let dir = out.join("overlays");
        fsutil::create_dir_all(&dir)?;
        let names: Vec<String> = det.rig.cameras.iter().map(|c| c.name.clone()).collect();
        for &t in &args.overlay_frames {
            let positions = source.read_frame(t)?;
            let a = det
                .analyze(topo, &positions, t, vertices)
                .with_context(|| format!("overlay of frame {t}"))?;
            let img = overlay::frame_overlay(&a, &names);
            let p = dir.join(format!("frame_{t:04}.png"));
            render::save_png(&img, &p)?;
        }
        progress.println(&format!(
            "video folds: {} overlay(s) -> {}",
            args.overlay_frames.len(),
            dir.display()
        ));
    }
    Ok(anchors)
}

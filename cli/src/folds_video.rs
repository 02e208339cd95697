//! `crease run --folds video`: flags of video fold estimation (Popa et al. 2009 §4), mapped onto the job's
//! `folds = { kind = "video" }`. The job checks the cameras and images at submit and writes `anchors.json` and
//! the overlays (see crease-jobs).

use anyhow::{bail, Result};
use clap::Args;
use crease_core::folds::video::VideoParams;
use serde_json::json;
use std::path::{Path, PathBuf};

/// Flags of `--folds video`. Tuning flags default to the paper's values (see docs/folds.md, "Folds from the capture video").
#[derive(Args, Debug, Clone, Default)]
pub struct VideoArgs {
    /// Camera calibration (JSON, OpenCV convention; see docs/folds.md).
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
    /// Canny low gradient threshold (0-255 grey) [default: 12].
    #[arg(long)]
    pub canny_low: Option<f64>,
    /// Canny high gradient threshold (0-255 grey) [default: 30].
    #[arg(long)]
    pub canny_high: Option<f64>,
    /// Read the Canny thresholds as the gradient at radius 1 and divide them by each level's radius, so every
    /// radius keeps edges of the same contrast (off: the thresholds apply unchanged at every radius).
    #[arg(long)]
    pub contrast_canny_thresholds: bool,
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
    /// Anchor angle of pairs `--narrow-width` wide or narrower, degrees [default: 60].
    #[arg(long)]
    pub narrow_angle: Option<f64>,
    /// Anchor angle of pairs `--wide-width` wide or wider, degrees [default: 30].
    #[arg(long)]
    pub wide_angle: Option<f64>,
    /// Pair width (mean edge lengths of frame 0) up to which pairs get the narrow angle [default: 1.5].
    #[arg(long)]
    pub narrow_width: Option<f64>,
    /// Pair width (mean edge lengths of frame 0) from which on pairs get the wide angle [default: 6].
    #[arg(long)]
    pub wide_width: Option<f64>,
    /// Look for fold edges in the raw image, not in its residual against the captured mesh's fitted shading.
    #[arg(long)]
    pub raw_darkness: bool,
    /// Analyse every camera that sees the garment, not only the front and back views (Popa et al.); each
    /// triangle takes the anchors of the camera that sees it most squarely.
    #[arg(long)]
    pub all_views: bool,
    /// Analyse only the front and back views (Popa et al.). By default, cameras that see squarely what those
    /// two see only obliquely (the sides of a tube in a ring of cameras) are added, each anchoring only that part.
    #[arg(long)]
    pub front_back_views: bool,
    /// Frames on each side over which anchors are matched and their angles averaged, 0 = off [default: 2].
    /// (Its own id: the stretch flags' `temporal_radius` field shares the name, and clap gave this flag's value
    /// to that one.)
    #[arg(long = "temporal-radius", id = "video_temporal_radius")]
    pub temporal_radius: Option<usize>,
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
            contrast_thresholds: self.contrast_canny_thresholds,
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
            narrow_width: or(self.narrow_width, d.narrow_width),
            wide_width: or(self.wide_width, d.wide_width),
            temporal_radius: self.temporal_radius.unwrap_or(d.temporal_radius),
            lighting_residual: !self.raw_darkness,
            all_views: self.all_views,
            cover_views: !self.front_back_views,
            skip_border: self.skip_border,
            ..d
        }
    }
}

impl VideoArgs {
    /// The job's `folds` table for these flags over a sequence of `n` frames; `abs` makes paths absolute.
    /// Flag-level mistakes are reported here under the flag's name; the files themselves are checked by the
    /// job's submit-time inspection.
    pub fn fold_spec(
        &self,
        n: usize,
        abs: &dyn Fn(&Path) -> Result<String>,
    ) -> Result<serde_json::Value> {
        let Some(cameras) = &self.cameras else {
            bail!("--folds video needs --cameras (the calibration JSON, see docs/folds.md)")
        };
        if self.front_vertex.is_some() != self.back_vertex.is_some() {
            bail!("give both --front-vertex and --back-vertex, or neither for the automatic choice")
        }
        for &f in &self.overlay_frames {
            if f >= n {
                bail!("--overlay-frames: frame {f} is out of range (the sequence has {n} frames, 0-based)");
            }
        }
        let vertex = |v: Option<usize>, flag: &str| -> Result<Option<u32>> {
            v.map(|v| {
                u32::try_from(v).map_err(|_| anyhow::anyhow!("{flag}: vertex {v} is out of range"))
            })
            .transpose()
        };
        let params = self.params();
        params
            .validate()
            .map_err(|e| anyhow::anyhow!("--folds video: {e}"))?;
        Ok(json!({
            "kind": "video",
            "cameras": abs(cameras)?,
            "images": self.images.as_deref().map(abs).transpose()?,
            "params": params,
            "front_vertex": vertex(self.front_vertex, "--front-vertex")?,
            "back_vertex": vertex(self.back_vertex, "--back-vertex")?,
            "first_image_number": self.first_image_number,
            "overlay_frames": self.overlay_frames,
        }))
    }
}

//! Tuning parameters of video fold estimation (Popa et al. 2009 §4 and Table 1), with the paper's defaults where
//! it gives them and values tuned on the sample sleeve elsewhere (see the README table).

use crate::error::{Error, Result};
use crate::shading_refine::ShadingRefineParams;

/// Parameters of [`super::VideoFolds`]. Distances are in pixels of the full-resolution camera image unless a
/// field says otherwise.
/// Serde: every field defaults (a job spec names only what it changes); unknown fields are errors.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VideoParams {
    /// Canny Gaussian radii (σ, in pixels of each resolution level). Table 1 lists 3–4 radii per garment, from
    /// 0.5 to 4.
    #[serde(alias = "canny_radii")]
    pub radii: Vec<f64>,
    /// Image resolutions as fractions of the full image (§4 "Multi-Resolution Processing").
    pub scales: Vec<f64>,
    /// Canny hysteresis thresholds on the Sobel gradient magnitude of the 0–255 grey image.
    pub canny_low: f64,
    pub canny_high: f64,
    /// Shortest edge kept after chaining, fitting and splitting.
    pub min_edge_length: f64,
    /// Largest distance of a chain point from its fitted quadric (pixels of the level) before it is split.
    pub fit_tolerance: f64,
    /// Largest curvature of the fitted quadric along the edge (1/pixel) before it is split: fold contours follow
    /// generalised cylinders with low-curvature axes (§3).
    pub max_curvature: f64,
    /// Smallest mean grey difference across an edge for it to have a clear orientation (§4 "Edge Orientation").
    pub min_contrast: f64,
    /// Fraction of an edge's samples whose darker side must agree with the edge's orientation.
    pub min_orientation_agreement: f64,
    /// Largest chromaticity difference across an edge (0–1 scale); above it the edge is texture, not shape.
    pub max_hue_difference: f64,
    /// Largest gap between the ends of two edges that may be merged (§4 "Merging").
    pub merge_gap: f64,
    /// Largest angle between paired edges, degrees (45° in all the paper's examples).
    #[serde(alias = "max_angle")]
    pub max_angle_deg: f64,
    /// Largest distance between paired edges at any point (Table 1 "Maximal distance").
    pub max_distance: f64,
    /// Largest average distance between paired edges.
    pub max_avg_distance: f64,
    /// Smallest fraction of the shorter edge that must run alongside the other edge of a pair.
    pub min_overlap: f64,
    /// Edge pixels closer than this to the image's garment mask boundary (alpha) are dropped: silhouettes are not
    /// folds.
    pub silhouette_margin: f64,
    /// A projected edge point is on the silhouette when |cos| of the angle between the viewing ray and the hit
    /// triangle's normal is below this (§5.1: pairs projecting onto the silhouette are discarded).
    pub silhouette_cos: f64,
    /// Largest fraction of an edge's rays that may miss the garment or hit its silhouette before its pair is
    /// discarded.
    pub max_off_garment: f64,
    /// Treat rays hitting the garment's border triangles (cuffs, collars, hems) like rays off the garment, so pairs
    /// outlining a border are dropped. Off by default: on the sample sleeve the compression folds crowd the cuff
    /// and dropping border pairs lowered the fold-signal correlation (0.320 → 0.303).
    pub skip_border: bool,
    /// Anchor rotation for narrow and wide pairs, degrees (§5.1: 60° down to 30°, inversely proportional to the
    /// width).
    #[serde(alias = "narrow_angle")]
    pub narrow_angle_deg: f64,
    #[serde(alias = "wide_angle")]
    pub wide_angle_deg: f64,
    /// Pair widths (on the surface, in mean edge lengths of the sequence's first frame) that get
    /// `narrow_angle_deg` and `wide_angle_deg`. One absolute scale for the whole sequence, so a fold of constant
    /// width keeps its angle from frame to frame; narrower and wider pairs are clamped to the ends.
    pub narrow_width: f64,
    pub wide_width: f64,
    /// Look for fold edges in the residual between the image and the captured mesh shaded under lighting fitted
    /// to the image (spherical harmonics, [`super::shading`]) rather than in the raw image.
    pub lighting_residual: bool,
    /// Anchor the cloth beside each detected pair too, tilted by the angle its lighting residual gives
    /// ([`super::flanks`]; needs `lighting_residual`). On by default: sleeve video κ 0.314 → 0.368, drape
    /// 0.473 → 0.505, normal error down on both (bench/results/2026-12-03-flank-tilts.md).
    pub flank_tilt: bool,
    /// How far beside a pair's edges flanks are anchored, in pair widths. Wider lifts κ further (5: sleeve
    /// 0.382) but raises the drape's popping towards its limit of 1.2 (1.12 at 5, 1.20 unbounded; 1.09 at 3).
    pub flank_band: f64,
    /// Smallest flank tilt anchored, degrees.
    pub flank_min_tilt_deg: f64,
    /// Prior scale of a flank's tilt, degrees: the estimate is shrunk towards 0 by `Σs² / (Σs² + σ²/prior²)`.
    pub flank_prior_deg: f64,
    /// Which cameras are analysed ([`Views`]).
    pub views: Views,
    /// |cos| between a triangle's normal and the viewing ray from which a camera sees the triangle squarely
    /// (0.5 = 60°: a fold's width appears halved).
    pub square_cos: f64,
    /// Smallest fraction of the garment's area, seen squarely by a camera and by no view chosen so far, for that
    /// camera to be added.
    pub min_cover_gain: f64,
    /// Frames on each side over which anchors are matched and their angles averaged (`crate::folds::temporal`);
    /// 0 leaves each frame's anchors as detected.
    pub temporal_radius: usize,
    /// Rings of the neighbourhood over which the tracked vertices' stable normals are averaged (§4: eight).
    pub stable_normal_rings: usize,
    /// Gauss–Newton rounds of the shading-based refinement of every finished frame
    /// ([`crate::shading_refine`]): the surface moved along its normals until its shading under the lighting
    /// fitted to it matches the images. 0 turns it off.
    pub refine_rounds: usize,
    /// The refinement's smoothness weight ([`ShadingRefineParams::smoothness`]).
    pub refine_smoothness: f64,
    /// The refinement's weight on staying at the deformed shape ([`ShadingRefineParams::stay`]).
    pub refine_stay: f64,
    /// The refinement's stay weight where the capture kept no trace of the surface it lost
    /// ([`ShadingRefineParams::erased_stay`]).
    pub refine_erased_stay: f64,
    /// The share of its lost surface given back by the fold relief from which the refinement's stay is
    /// `refine_stay` ([`ShadingRefineParams::erased_share`]).
    pub refine_erased_share: f64,
    /// The refinement's stay weight where the relief gives back all the capture lost
    /// ([`ShadingRefineParams::kept_stay`]).
    pub refine_kept_stay: f64,
    /// Largest offset the refinement gives a vertex, in mean edge lengths.
    pub refine_max_offset: f64,
    /// Wavelength in the input's units above which the refinement's offsets are removed (they move the garment
    /// rather than fold it); 0: the deformation's shape scale.
    pub refine_scale: f64,
    /// Whether the geometry's folds (Chen's stretch detector, with its default settings, on the same capture)
    /// join the images' ([`crate::folds::fuse`]): the two see different evidence of the same folds, and the
    /// rotation field spread from both is closer to the cloth than from either. `false`: the images' alone,
    /// as Popa et al.
    pub geometry_folds: bool,
    /// With `geometry_folds`, the factor on every anchor's angle after the two sets are made one, in (0, 1].
    pub fused_gain: f64,
    /// With `geometry_folds`, the capture trace (the median share of the surface the capture lost that the
    /// fold relief gives back) below which the geometry's folds are left out: such a capture erased its folds,
    /// and the geometry knows the band that lost length, not where each crest lies. 0: always fused.
    pub geometry_min_trace: f64,
}

/// The cameras video fold estimation analyses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Views {
    /// The front and back views, plus, greedily, the cameras that see squarely a part of the garment those see
    /// only obliquely; each added camera anchors only that part ([`super::cover`]). It lifts the tube-like
    /// sleeve and leaves the sheet as it was (bench/results/2026-12-02-video-views.md).
    #[default]
    Cover,
    /// The front and back views only, as Popa et al. analyse them.
    FrontBack,
    /// Every camera that sees the garment, each triangle taking the anchors of the camera that sees it most
    /// squarely ([`super::ownership`]). It helps the sleeve less than `Cover` and hurts the sheet.
    All,
}

impl Default for VideoParams {
    fn default() -> Self {
        let refine = ShadingRefineParams::default();
        VideoParams {
            radii: vec![1.0, 1.5, 2.5, 3.5],
            scales: vec![1.0],
            canny_low: 12.0,
            canny_high: 30.0,
            min_edge_length: 8.0,
            fit_tolerance: 1.0,
            max_curvature: 0.08,
            min_contrast: 4.0,
            min_orientation_agreement: 0.75,
            max_hue_difference: 0.04,
            merge_gap: 5.0,
            max_angle_deg: 45.0,
            max_distance: 12.0,
            max_avg_distance: 9.0,
            min_overlap: 0.5,
            silhouette_margin: 3.0,
            silhouette_cos: 0.2,
            max_off_garment: 0.1,
            skip_border: false,
            narrow_angle_deg: 60.0,
            wide_angle_deg: 30.0,
            narrow_width: 1.5,
            wide_width: 6.0,
            lighting_residual: true,
            flank_tilt: true,
            flank_band: 3.0,
            flank_min_tilt_deg: 10.0,
            flank_prior_deg: 20.0,
            views: Views::Cover,
            square_cos: 0.5,
            min_cover_gain: 0.1,
            temporal_radius: 2,
            stable_normal_rings: 8,
            refine_rounds: refine.rounds,
            refine_smoothness: refine.smoothness,
            refine_stay: refine.stay,
            refine_erased_stay: refine.erased_stay,
            refine_erased_share: refine.erased_share,
            refine_kept_stay: refine.kept_stay,
            refine_max_offset: refine.max_offset_edges,
            refine_scale: refine.shape_scale,
            geometry_folds: true,
            fused_gain: 0.7,
            geometry_min_trace: 0.1,
        }
    }
}

impl VideoParams {
    /// Rejects values the algorithm cannot work with, naming the parameter.
    pub fn validate(&self) -> Result<()> {
        let pos = |name: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(Error::param(
                    name,
                    format!("must be a positive number, got {v}"),
                ))
            }
        };
        let frac = |name: &str, v: f64| {
            if (0.0..=1.0).contains(&v) {
                Ok(())
            } else {
                Err(Error::param(name, format!("must be in [0, 1], got {v}")))
            }
        };
        if self.radii.is_empty() {
            return Err(Error::param("radii", "needs at least one Canny radius"));
        }
        for &r in &self.radii {
            if !(r.is_finite() && (0.2..=20.0).contains(&r)) {
                return Err(Error::param(
                    "radii",
                    format!("{r} is outside [0.2, 20] pixels"),
                ));
            }
        }
        if self.scales.is_empty() {
            return Err(Error::param("scales", "needs at least one resolution"));
        }
        for &s in &self.scales {
            if !(s.is_finite() && (0.05..=4.0).contains(&s)) {
                return Err(Error::param("scales", format!("{s} is outside [0.05, 4]")));
            }
        }
        pos("canny_low", self.canny_low)?;
        pos("canny_high", self.canny_high)?;
        if self.canny_high < self.canny_low {
            return Err(Error::param(
                "canny_high",
                format!(
                    "must not be below canny_low ({} < {})",
                    self.canny_high, self.canny_low
                ),
            ));
        }
        pos("min_edge_length", self.min_edge_length)?;
        pos("fit_tolerance", self.fit_tolerance)?;
        pos("max_curvature", self.max_curvature)?;
        pos("min_contrast", self.min_contrast)?;
        frac("min_orientation_agreement", self.min_orientation_agreement)?;
        pos("max_hue_difference", self.max_hue_difference)?;
        pos("merge_gap", self.merge_gap)?;
        if !(self.max_angle_deg > 0.0 && self.max_angle_deg < 90.0) {
            return Err(Error::param(
                "max_angle_deg",
                format!("must be in (0, 90) degrees, got {}", self.max_angle_deg),
            ));
        }
        pos("max_distance", self.max_distance)?;
        pos("max_avg_distance", self.max_avg_distance)?;
        frac("min_overlap", self.min_overlap)?;
        if !(self.silhouette_margin.is_finite() && self.silhouette_margin >= 0.0) {
            return Err(Error::param("silhouette_margin", "must be >= 0"));
        }
        if !(self.fused_gain > 0.0 && self.fused_gain <= 1.0) {
            return Err(Error::param(
                "fused_gain",
                format!("must be in (0, 1], got {}", self.fused_gain),
            ));
        }
        frac("geometry_min_trace", self.geometry_min_trace)?;
        frac("silhouette_cos", self.silhouette_cos)?;
        frac("square_cos", self.square_cos)?;
        frac("min_cover_gain", self.min_cover_gain)?;
        frac("max_off_garment", self.max_off_garment)?;
        for (name, a) in [
            ("narrow_angle_deg", self.narrow_angle_deg),
            ("wide_angle_deg", self.wide_angle_deg),
        ] {
            if !(a.is_finite() && (0.0..=180.0).contains(&a)) {
                return Err(Error::param(
                    name,
                    format!("must be in [0, 180] degrees, got {a}"),
                ));
            }
        }
        if self.temporal_radius > 50 {
            return Err(Error::param(
                "temporal_radius",
                format!("at most 50 frames, got {}", self.temporal_radius),
            ));
        }
        pos("flank_band", self.flank_band)?;
        pos("flank_prior_deg", self.flank_prior_deg)?;
        if !(self.flank_min_tilt_deg.is_finite() && (0.0..=90.0).contains(&self.flank_min_tilt_deg))
        {
            return Err(Error::param(
                "flank_min_tilt_deg",
                format!(
                    "must be in [0, 90] degrees, got {}",
                    self.flank_min_tilt_deg
                ),
            ));
        }
        pos("narrow_width", self.narrow_width)?;
        pos("wide_width", self.wide_width)?;
        if self.wide_width <= self.narrow_width {
            return Err(Error::param(
                "wide_width",
                format!(
                    "must exceed narrow_width ({}), got {}",
                    self.narrow_width, self.wide_width
                ),
            ));
        }
        self.refine_params().validate().map_err(|e| match e {
            Error::Param { name, msg } => Error::param(format!("refine_{name}"), msg),
            e => e,
        })
    }

    /// The shading refinement's settings (`refine_*`), with `shape_scale` the given fallback when
    /// `refine_scale` is 0.
    pub fn refine_params(&self) -> ShadingRefineParams {
        ShadingRefineParams {
            rounds: self.refine_rounds,
            smoothness: self.refine_smoothness,
            stay: self.refine_stay,
            erased_stay: self.refine_erased_stay,
            erased_share: self.refine_erased_share,
            kept_stay: self.refine_kept_stay,
            max_offset_edges: self.refine_max_offset,
            shape_scale: self.refine_scale,
            ..ShadingRefineParams::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_validate_and_bad_values_are_named() {
        VideoParams::default().validate().unwrap();
        let bad = VideoParams {
            canny_low: 9.0,
            canny_high: 3.0,
            ..Default::default()
        };
        assert!(bad
            .validate()
            .unwrap_err()
            .to_string()
            .contains("canny_high"));
        for (name, bad) in [
            (
                "square_cos",
                VideoParams {
                    square_cos: 1.5,
                    ..Default::default()
                },
            ),
            (
                "min_cover_gain",
                VideoParams {
                    min_cover_gain: f64::NAN,
                    ..Default::default()
                },
            ),
            (
                "fused_gain",
                VideoParams {
                    fused_gain: 0.0,
                    ..Default::default()
                },
            ),
        ] {
            assert!(bad.validate().unwrap_err().to_string().contains(name));
        }
        let bad = VideoParams {
            radii: vec![],
            ..Default::default()
        };
        assert!(bad.validate().unwrap_err().to_string().contains("radii"));
        let bad = VideoParams {
            max_angle_deg: 95.0,
            ..Default::default()
        };
        assert!(bad
            .validate()
            .unwrap_err()
            .to_string()
            .contains("max_angle"));
    }
}

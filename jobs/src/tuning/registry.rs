//! Every tuning key: its name, type and range, the field of the job spec it sets, and what it means. The
//! defaults are not written here: they are read from the spec's own defaults (`DeformParams::default()` and the
//! detectors'), so the listing cannot disagree with what a run uses.

use super::kind::{Bound, Kind};
use crate::spec::{FoldSpec, JobSpec, Partition};
use crease_core::folds::stretch::StretchParams;
use crease_core::folds::video::VideoParams;
use crease_core::spacetime::DeformParams;
use serde::de::DeserializeOwned;
use serde::Serialize;
use serde_json::Value;

/// A field of a job spec that a key sets, read and written as a JSON value.
pub trait Slot {
    fn get(&self) -> Value;
    fn put(&mut self, v: Value) -> Result<(), String>;
}

impl<T: Serialize + DeserializeOwned> Slot for T {
    fn get(&self) -> Value {
        serde_json::to_value(self).unwrap_or(Value::Null)
    }
    fn put(&mut self, v: Value) -> Result<(), String> {
        *self = serde_json::from_value(v).map_err(|e| e.to_string())?;
        Ok(())
    }
}

/// The field of `spec` a key sets, or `None` where the spec has no such field (a detector's key on a job whose
/// folds come from elsewhere).
pub type Access = fn(&mut JobSpec) -> Option<&mut dyn Slot>;

/// One tuning key.
pub struct Knob {
    /// `group.field`: the group names the spec table (`deform`, `partition`) or the fold source (`stretch`,
    /// `video`), the field is the spec field's own name.
    pub key: &'static str,
    pub kind: Kind,
    /// One line: what it changes, and what its special values mean.
    pub meaning: &'static str,
    pub access: Access,
}

impl Knob {
    /// `deform`, `partition`, `stretch` or `video`.
    pub fn group(&self) -> &'static str {
        self.key.split('.').next().unwrap_or("")
    }

    /// The field's name in the spec (the key without its group).
    pub fn field(&self) -> &'static str {
        self.key.split_once('.').map_or(self.key, |(_, f)| f)
    }

    /// Where the field lives in a job spec file.
    pub fn spec_path(&self) -> String {
        match self.group() {
            "stretch" | "video" if VIDEO_SPEC_FIELDS.contains(&self.field()) => {
                format!("folds.{}", self.field())
            }
            "stretch" | "video" => format!("folds.params.{}", self.field()),
            g => format!("{g}.{}", self.field()),
        }
    }

    /// The value a run uses when the key is not set.
    pub fn default_value(&self) -> Value {
        let mut spec = JobSpec::new("/in", "/out");
        spec.folds = match self.group() {
            "stretch" => FoldSpec::Stretch {
                params: StretchParams::default(),
                subdivide: 0,
            },
            "video" => FoldSpec::Video {
                cameras: "/cameras.json".into(),
                images: None,
                params: VideoParams::default(),
                front_vertex: None,
                back_vertex: None,
                first_image_number: None,
                overlay_frames: Vec::new(),
            },
            _ => FoldSpec::None,
        };
        (self.access)(&mut spec).map_or(Value::Null, |s| s.get())
    }
}

/// Video keys that are fields of the `[folds]` table itself rather than of `folds.params`.
const VIDEO_SPEC_FIELDS: &[&str] = &[
    "front_vertex",
    "back_vertex",
    "first_image_number",
    "overlay_frames",
];

fn deform(s: &mut JobSpec) -> Option<&mut DeformParams> {
    Some(&mut s.deform)
}
fn partition(s: &mut JobSpec) -> Option<&mut Partition> {
    Some(&mut s.partition)
}
fn stretch(s: &mut JobSpec) -> Option<&mut StretchParams> {
    match &mut s.folds {
        FoldSpec::Stretch { params, .. } => Some(params),
        _ => None,
    }
}
fn video(s: &mut JobSpec) -> Option<&mut VideoParams> {
    match &mut s.folds {
        FoldSpec::Video { params, .. } => Some(params),
        _ => None,
    }
}

/// The accessor of a field: `at!(deform.coefficients.c_s)`.
macro_rules! at {
    ($scope:ident . $($field:ident).+) => {
        |s: &mut JobSpec| -> Option<&mut dyn Slot> { $scope(s).map(|p| &mut p.$($field).+ as &mut dyn Slot) }
    };
}

/// The accessor of a field of the `[folds]` table of a video job (not of its `params`).
macro_rules! video_spec {
    ($field:ident) => {
        |s: &mut JobSpec| -> Option<&mut dyn Slot> {
            match &mut s.folds {
                FoldSpec::Video { $field, .. } => Some($field as &mut dyn Slot),
                _ => None,
            }
        }
    };
}

const FREE: Bound = Bound::Free;
const fn ge(x: f64) -> Bound {
    Bound::Closed(x)
}
const fn gt(x: f64) -> Bound {
    Bound::Open(x)
}
const fn le(x: f64) -> Bound {
    Bound::Closed(x)
}
const fn lt(x: f64) -> Bound {
    Bound::Open(x)
}
const fn num(lo: Bound, hi: Bound) -> Kind {
    Kind::Number { lo, hi }
}
const POSITIVE: Kind = num(gt(0.0), FREE);
const NON_NEGATIVE: Kind = num(ge(0.0), FREE);
const FRACTION: Kind = num(ge(0.0), le(1.0));
const fn count(lo: u64, hi: u64) -> Kind {
    Kind::Count { lo, hi }
}
const MANY: u64 = u64::MAX;

const fn knob(key: &'static str, kind: Kind, access: Access, meaning: &'static str) -> Knob {
    Knob {
        key,
        kind,
        meaning,
        access,
    }
}

/// Every key, grouped, in the order the listing shows them.
pub static KNOBS: &[Knob] = &[
    // The space-time deformation (Popa et al. 2009 §5).
    knob("deform.mode", Kind::Choice(&["fused", "per-anchor"]), at!(deform.mode),
        "weight solve: fused (3 right-hand sides per window) or per-anchor (one CG column per anchor, in blocks; `crease run --mode`)"),
    knob("deform.c_s", NON_NEGATIVE, at!(deform.coefficients.c_s), "spatial smoothness weight of the weight solve (§5.2)"),
    knob("deform.c_t", NON_NEGATIVE, at!(deform.coefficients.c_t), "temporal smoothness weight of the weight solve"),
    knob("deform.c_i", POSITIVE, at!(deform.coefficients.c_i), "mitigation weight pulling triangles without anchors towards the identity"),
    knob("deform.c_a", POSITIVE, at!(deform.coefficients.c_a), "anchor weight"),
    knob("deform.window", count(1, MANY), at!(deform.window), "frames per time window of the weight solve"),
    knob("deform.shift", count(1, MANY), at!(deform.shift), "frames between window starts, at most the window (window − shift frames are cross-faded)"),
    knob("deform.cg_tolerance", num(gt(0.0), lt(1.0)), at!(deform.cg_tolerance), "relative residual at which each CG solve stops"),
    knob("deform.cg_max_iterations", count(1, MANY), at!(deform.cg_max_iterations), "CG iteration limit (reaching it is an error naming the window)"),
    knob("deform.stretch_passes", count(0, 20), at!(deform.stretch_passes), "stretch-reduction passes after the positioning (§5.5), each reusing the frame's factor"),
    knob("deform.stretch_rotation", Kind::Choice(&["anchored", "polar", "normal"]), at!(deform.stretch_rotation),
        "rotation a stretch pass gives each triangle: anchored (halfway between polar and the folds' rotation: keeps the folds), polar (closest to its deformation) or normal (the paper's)"),
    knob("deform.shape_cutoff", NON_NEGATIVE, at!(deform.shape_cutoff),
        "cutoff wavelength of the positioning's shape screen in detail scales: longer displacements keep the captured shape, shorter ones (folds) are free; 0 = the paper's unscreened system"),
    knob("deform.pinning", Kind::Choice(&["centroid", "vertex"]), at!(deform.pinning),
        "with shape_cutoff 0 only: each component keeps its mean position (centroid) or its lowest-index vertex (vertex)"),
    knob("deform.relief.scale", NON_NEGATIVE, at!(deform.relief.scale),
        "detail scale, in the input's length unit: the wavelength a generic capture low-pass is taken to halve; the fold relief undoes it, the shape screen works at `deform.shape_cutoff` times it and the projection at twice it; 0 = five mean edge lengths of the first frame (`crease run --detail-scale`)"),
    knob("deform.relief.steps", count(0, 32), at!(deform.relief.steps),
        "fold relief: Van Cittert steps of the deconvolution (the gain on what the capture damped most is at most steps + 1); 0 = no relief"),
    knob("deform.relief.temporal_sigma", num(ge(0.0), le(8.0)), at!(deform.relief.temporal_sigma),
        "fold relief: standard deviation, in frames, of its average over time (folds are coherent over frames, capture noise is not); 0 = none"),
    knob("deform.shape_projection", FRACTION, at!(deform.shape_projection),
        "fraction of the long-wavelength part (twice the detail scale) of the displacement removed after the stretch passes, so the garment keeps the captured shape; 0 = off (acts with the shape screen only)"),
    knob("deform.strain_limit", FRACTION, at!(deform.strain_limit),
        "the positioning's last step shortens every edge longer than (1 + this) times its reference length; 0 = off (`crease run --strain-limit`; the built-in demo uses 0.02)"),
    knob("deform.lost_area_bound", Kind::Switch, at!(deform.lost_area_bound),
        "bound what the deformation adds (relief and anchors) by the surface the capture lost: a region whose captured area is as large as it ever is in the sequence gets no folds added; false: they act wherever they reach (folds that never open in any frame, anchors placed on purpose)"),
    knob("deform.release_share", FRACTION, at!(deform.release_share),
        "let the shape screen go where the capture kept no trace of the surface it lost: at a vertex whose lost surface the fold relief gives back less than this share of, the screen and projection hold only in proportion (folds a capture erased outright); 0 = the screen holds everywhere (needs lost_area_bound)"),
    knob("deform.strain_limit_sweeps", count(1, 1000), at!(deform.strain_limit_sweeps), "Gauss–Seidel sweeps of the strain limit (it stops once a sweep moves nothing)"),
    knob("deform.strain_reference", Kind::Choice(&["sequence", "frame"]), at!(deform.strain_reference),
        "the strain limit's reference length per edge: its longest captured length (sequence) or its length in the same frame (frame: an input that is its own rest state, as the built-in demo)"),
    // How a job is cut into tasks (any value gives the same output, anchor_block in per-anchor mode excepted).
    knob("partition.anchor_block", count(1, MANY), at!(partition.anchor_block),
        "anchor columns per weight task in per-anchor mode (part of the arithmetic: changes the output's last bits)"),
    knob("partition.frames_per_chunk", count(1, MANY), at!(partition.frames_per_chunk), "at most this many frames per positioning task"),
    knob("partition.fold_frames_per_chunk", count(1, MANY), at!(partition.fold_frames_per_chunk), "frames per fold-detection task (video folds)"),
    knob("partition.stretch_frames_per_chunk", count(0, MANY), at!(partition.stretch_frames_per_chunk),
        "frames per stretch tracing task; 0 = from the frame and triangle counts"),
    knob("partition.stretch_warm_up", count(0, MANY), at!(partition.stretch_warm_up),
        "frames a stretch tracing task traces before its first to warm its seed memory up (with stretch.seed_memory)"),
    knob("partition.settle_frames_per_chunk", count(0, MANY), at!(partition.settle_frames_per_chunk),
        "frames per temporal-coherence task of detected folds; 0 = the detection's chunks"),
    // Folds from the geometry alone (Chen 2011 ch. 4): `crease run --folds stretch`. Lengths in mean edge lengths.
    knob("stretch.theta0_deg", num(gt(0.0), lt(90.0)), at!(stretch.theta0_deg), "θ0 of eq. 4.2, degrees: largest direction change within one phase"),
    knob("stretch.isometry", NON_NEGATIVE, at!(stretch.isometry), "steps with absolute change below 1 + this are isometric (a fold holding its shape)"),
    knob("stretch.max_hold", count(0, MANY), at!(stretch.max_hold), "consecutive isometric steps a phase survives"),
    knob("stretch.transient_steps", count(0, 50), at!(stretch.transient_steps),
        "a stretch phase of at most this many steps that turns straight into shrinkage is a transient: shrinkage counts from before it"),
    knob("stretch.smooth_iterations", count(0, 1000), at!(stretch.smooth_iterations), "smoothing iterations of Γ, γ and the direction angle"),
    knob("stretch.max_change", num(gt(1.0), FREE), at!(stretch.max_change), "valid range: absolute changes above this are outliers"),
    knob("stretch.tail_fraction", num(ge(0.0), lt(0.5)), at!(stretch.tail_fraction), "histogram tails: sparse extreme bins below this fraction of the triangles are dropped; 0 = off"),
    knob("stretch.min_shrink", POSITIVE, at!(stretch.min_shrink), "seeds need an integrated shrinkage of at least 1 + this (below max_change)"),
    knob("stretch.fade", num(ge(0.0), lt(1.0)), at!(stretch.fade), "tracing stops where the shrinkage falls below this fraction of the seed's"),
    knob("stretch.max_turn_deg", num(gt(0.0), le(90.0)), at!(stretch.max_turn_deg), "tracing stops at a direction turn above this many degrees"),
    knob("stretch.fold_width", POSITIVE, at!(stretch.fold_width), "fold width at |v| = 1 (the width is this / |v|)"),
    knob("stretch.alpha", POSITIVE, at!(stretch.alpha), "α of eq. 4.3: the region of influence reaches α·|v| from the fold axis"),
    knob("stretch.patch_radius", num(gt(0.0), le(1000.0)), at!(stretch.patch_radius), "radius of the flattened patch around a seed"),
    knob("stretch.angle_gain", NON_NEGATIVE, at!(stretch.angle_gain),
        "anchor angle in radians per unit of shrinkage |v| − 1; 0 = the angle that gives back the length the capture lost"),
    knob("stretch.max_angle_deg", num(gt(0.0), le(180.0)), at!(stretch.max_angle_deg), "cap of the anchor angle, degrees"),
    knob("stretch.min_length", NON_NEGATIVE, at!(stretch.min_length), "shortest fold axis kept"),
    knob("stretch.temporal_radius", count(0, 50), at!(stretch.temporal_radius), "frames on each side over which anchors are matched and their angles averaged; 0 = off"),
    knob("stretch.seed_memory", Kind::Switch, at!(stretch.seed_memory),
        "the thesis' seed memory (§4.4): the previous frame's fold seeds are tried first, which makes tracing sequential over time"),
    // Folds from the capture video (Popa et al. 2009 §4): `crease run --folds video`. Distances in pixels.
    knob("video.radii", Kind::Numbers { lo: ge(0.2), hi: le(20.0) }, at!(video.radii), "Canny Gaussian radii, pixels (Table 1)"),
    knob("video.scales", Kind::Numbers { lo: ge(0.05), hi: le(4.0) }, at!(video.scales), "image resolutions as fractions of the full image"),
    knob("video.canny_low", POSITIVE, at!(video.canny_low), "Canny low gradient threshold (0–255 grey)"),
    knob("video.canny_high", POSITIVE, at!(video.canny_high), "Canny high gradient threshold (0–255 grey), at least canny_low"),
    knob("video.min_edge_length", POSITIVE, at!(video.min_edge_length), "shortest edge kept"),
    knob("video.fit_tolerance", POSITIVE, at!(video.fit_tolerance), "largest distance of an edge point from its fitted quadric before the edge is split"),
    knob("video.max_curvature", POSITIVE, at!(video.max_curvature), "largest curvature of an edge, 1/pixel, before it is split"),
    knob("video.min_contrast", POSITIVE, at!(video.min_contrast), "smallest grey difference across an edge for a clear orientation"),
    knob("video.min_orientation_agreement", FRACTION, at!(video.min_orientation_agreement), "fraction of an edge's samples whose darker side must agree with its orientation"),
    knob("video.max_hue_difference", POSITIVE, at!(video.max_hue_difference), "largest chromaticity difference across an edge (above it the edge is texture)"),
    knob("video.merge_gap", POSITIVE, at!(video.merge_gap), "largest gap between the ends of two edges that are merged"),
    knob("video.max_angle_deg", num(gt(0.0), lt(90.0)), at!(video.max_angle_deg), "largest angle between paired edges, degrees"),
    knob("video.max_distance", POSITIVE, at!(video.max_distance), "largest distance between paired edges at any point"),
    knob("video.max_avg_distance", POSITIVE, at!(video.max_avg_distance), "largest average distance between paired edges"),
    knob("video.min_overlap", FRACTION, at!(video.min_overlap), "smallest fraction of the shorter edge that runs alongside the other edge of a pair"),
    knob("video.silhouette_margin", NON_NEGATIVE, at!(video.silhouette_margin), "edge pixels this close to the garment mask's boundary are dropped"),
    knob("video.silhouette_cos", FRACTION, at!(video.silhouette_cos), "a projected edge point is on the silhouette when |cos| of ray and normal is below this"),
    knob("video.max_off_garment", FRACTION, at!(video.max_off_garment), "largest fraction of an edge's rays that may miss the garment or hit its silhouette"),
    knob("video.skip_border", Kind::Switch, at!(video.skip_border), "also drop pairs whose edges run on the garment's border triangles (cuff and hem outlines)"),
    knob("video.narrow_angle_deg", num(ge(0.0), le(180.0)), at!(video.narrow_angle_deg), "anchor angle of pairs narrow_width wide or narrower, degrees"),
    knob("video.wide_angle_deg", num(ge(0.0), le(180.0)), at!(video.wide_angle_deg), "anchor angle of pairs wide_width wide or wider, degrees"),
    knob("video.narrow_width", POSITIVE, at!(video.narrow_width), "pair width (mean edge lengths of frame 0) up to which pairs get narrow_angle_deg"),
    knob("video.wide_width", POSITIVE, at!(video.wide_width), "pair width from which on pairs get wide_angle_deg; above narrow_width"),
    knob("video.lighting_residual", Kind::Switch, at!(video.lighting_residual),
        "look for fold edges in the residual against the captured mesh's fitted shading; false = in the raw image (the paper's cue)"),
    knob("video.flank_tilt", Kind::Switch, at!(video.flank_tilt), "also anchor the cloth beside each pair, tilted by the angle its shading gives (needs lighting_residual)"),
    knob("video.flank_band", POSITIVE, at!(video.flank_band), "how far beside a pair's edges flanks are anchored, in pair widths"),
    knob("video.flank_min_tilt_deg", num(ge(0.0), le(90.0)), at!(video.flank_min_tilt_deg), "smallest flank tilt anchored, degrees"),
    knob("video.flank_prior_deg", POSITIVE, at!(video.flank_prior_deg), "prior scale of a flank's tilt, degrees (the estimate is shrunk towards 0)"),
    knob("video.views", Kind::Choice(&["cover", "front-back", "all"]), at!(video.views),
        "cameras analysed: front and back plus those that see squarely what those two see obliquely (cover), the paper's front and back views only (front-back), or every camera (all)"),
    knob("video.square_cos", FRACTION, at!(video.square_cos), "|cos| of normal and ray from which a camera sees a triangle squarely (views = cover)"),
    knob("video.min_cover_gain", FRACTION, at!(video.min_cover_gain), "smallest fraction of the garment a camera must add, seen squarely, to be chosen (views = cover)"),
    knob("video.temporal_radius", count(0, 50), at!(video.temporal_radius), "frames on each side over which anchors are matched and their angles averaged; 0 = off"),
    knob("video.stable_normal_rings", count(0, 100), at!(video.stable_normal_rings), "rings over which the tracked vertices' normals are averaged (§4)"),
    knob("video.refine_rounds", count(0, 20), at!(video.refine_rounds), "Gauss–Newton rounds of the shading refinement of every finished frame from its images; 0 = off"),
    knob("video.refine_smoothness", NON_NEGATIVE, at!(video.refine_smoothness), "shading refinement: weight of the offsets' squared Laplacian (offsets in mean edge lengths, residuals in the images' grain)"),
    knob("video.refine_stay", POSITIVE, at!(video.refine_stay), "shading refinement: weight of staying at the deformed shape, per unit of surface over offsets in fifths of the detail scale (mean edge lengths at the default detail scale), so a finer mesh of the same garment is held alike"),
    knob("video.refine_erased_stay", POSITIVE, at!(video.refine_erased_stay), "shading refinement: weight of staying where the capture kept no trace of the surface it lost (the fold relief gives back none of it), rising to refine_stay where it gives back refine_erased_share; equal to refine_stay = off"),
    knob("video.refine_erased_share", FRACTION, at!(video.refine_erased_share), "shading refinement: share of its lost surface given back by the fold relief from which a vertex's stay is refine_stay (below it falls to refine_erased_stay, above it rises to refine_kept_stay); 0 = no lower stay"),
    knob("video.refine_kept_stay", POSITIVE, at!(video.refine_kept_stay), "shading refinement: weight of staying where the fold relief gives back all the surface the capture lost, rising geometrically from refine_stay at refine_erased_share; equal to refine_stay = off"),
    knob("video.refine_max_offset", POSITIVE, at!(video.refine_max_offset), "shading refinement: largest offset along the normal, in fifths of the detail scale (mean edge lengths at the default detail scale)"),
    knob("video.refine_scale", NON_NEGATIVE, at!(video.refine_scale), "shading refinement: wavelength (input units) above which its offsets are removed; 0 = the deformation's shape scale"),
    knob("video.geometry_folds", Kind::Switch, at!(video.geometry_folds), "the geometry's folds (the stretch detector, default settings) join the images': the mean rotation where both anchor a triangle; false = the images' alone"),
    knob("video.fused_gain", num(gt(0.0), le(1.0)), at!(video.fused_gain), "with geometry_folds: the factor on every anchor's angle once the two sets are one"),
    knob("video.geometry_min_trace", FRACTION, at!(video.geometry_min_trace), "with geometry_folds: the capture trace (median share of the lost surface the fold relief gives back) below which the geometry's folds are left out, the capture having erased its folds; 0 = always fused"),
    knob("video.front_vertex", Kind::Optional { hi: u32::MAX as u64 }, video_spec!(front_vertex),
        "tracked front vertex for view selection (with back_vertex); unset = chosen from frame 0"),
    knob("video.back_vertex", Kind::Optional { hi: u32::MAX as u64 }, video_spec!(back_vertex),
        "tracked back vertex for view selection (with front_vertex); unset = chosen from frame 0"),
    knob("video.first_image_number", Kind::Optional { hi: MANY }, video_spec!(first_image_number),
        "image number of sequence frame 0; unset = each input frame file's own number (1 for point caches)"),
    knob("video.overlay_frames", Kind::Frames, video_spec!(overlay_frames), "frames whose fold-edge overlays are drawn into overlays/"),
];

/// The key named `key`.
pub fn find(key: &str) -> Option<&'static Knob> {
    KNOBS.iter().find(|k| k.key == key)
}

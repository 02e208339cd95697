//! `report.json`, the last file a deformation job writes: one type for the task that writes it (finalize) and
//! for whoever reads it back (`crease run` prints its figures from it).
//!
//! Written through a JSON value, whose objects keep their keys sorted, so the file's layout does not depend on
//! the order of the fields below.

use crate::spec::Partition;
use crease_core::metrics::StretchStats;
use crease_core::rest_stretch::RestStretchStats;
use crease_core::shape::ShapeStats;
use crease_core::spacetime::{DeformParams, DeformReport};
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::collections::BTreeMap;

/// The whole report.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct JobReport {
    /// Always true: the report is written after every output file, so its presence means they are complete.
    pub complete: bool,
    pub crease_version: String,
    /// The job's display name.
    pub job: String,
    pub input: String,
    /// How the input is laid out (`obj-frames`, `obj-pc2`, ...).
    pub input_layout: String,
    /// Where the anchors came from (none: a job without folds).
    pub anchors_file: Option<AnchorsSource>,
    /// What the fold detection found (none: folds from a file, or none).
    pub fold_detection: Option<FoldDetection>,
    pub output: String,
    /// Every file the job wrote (descriptions of their locations).
    pub output_files: Vec<String>,
    /// `preview.png` and `stretch.png`.
    pub preview: Vec<String>,
    /// The deformation parameters the tasks ran with.
    pub parameters: DeformParams,
    pub partition: Partition,
    pub summary: Summary,
    /// The deformation's own report: per-window statistics, stretch per pass and per frame, work seconds.
    pub report: DeformReport,
    /// Every key this run owns in the output (the next run removes those it does not write again).
    pub manifest: Vec<String>,
}

/// Where a job's anchors came from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum AnchorsSource {
    /// The anchors file the job named.
    File(String),
    /// Detected by the job: the detector, and the anchors file it wrote.
    Detected { detected: String, file: String },
}

/// What a fold detection found beyond the anchors; the `fold-merge` task stores it and finalize copies it in.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FoldDetection {
    /// The detector (`stretch`, `video`).
    pub source: String,
    /// Anchors over the whole sequence.
    pub anchors: usize,
    /// Video folds: cameras in the calibration.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cameras: Option<usize>,
    /// Video folds: the vertices the front and back views were chosen by.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tracked_vertices: Option<TrackedVertices>,
    /// The rest of what the detector reports: its parameters, per-frame counts and seconds.
    #[serde(flatten)]
    pub details: BTreeMap<String, Value>,
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TrackedVertices {
    pub front: usize,
    pub back: usize,
    /// Chosen from frame 0 rather than given.
    pub automatic: bool,
}

/// The figures a reader looks at first.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Summary {
    pub frames: usize,
    pub vertices: usize,
    pub triangles: usize,
    pub anchors: usize,
    /// What `stretch_after_positioning` and `stretch_final` measure against.
    pub stretch_reference: String,
    pub stretch_after_positioning: StretchStats,
    pub stretch_final: StretchStats,
    pub stretch_vs_rest: VsRest,
    /// Every output frame against its input frame.
    pub shape_kept: ShapeStats,
    /// The lengths the deformation worked at (none in reports written before they were recorded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scales: Option<SequenceLengths>,
    /// How the lost-area bound judged the frames (none: the bound did not run).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lost_area: Option<LostAreaJudgement>,
    pub seconds_per_frame: SecondsPerFrame,
    pub timings_note: String,
    pub preview_seconds: f64,
}

/// The lengths a run's deformation worked at, in the input's units: what `--detail-scale` would change.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SequenceLengths {
    /// Mean edge length of the input's first frame.
    pub mean_edge: f64,
    /// The detail scale: given (`deform.relief.scale`), or five mean edge lengths.
    pub detail: f64,
    /// Whether the detail scale was given rather than taken from the mesh.
    pub detail_given: bool,
    /// The shape screen's cutoff wavelength (none: no screen).
    pub screen: Option<f64>,
    /// The wavelength above which the displacement is removed as shape.
    pub shape: f64,
}

/// Edge tension of the output against the least-compressed captured edge lengths.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct VsRest {
    pub reference: String,
    #[serde(rename = "final")]
    pub output: RestStretchStats,
}

/// The lost-area bound's judgement of the frames, counted: each frame's share of the surface its deformation added
/// that the capture had lost (per frame in `report.frame_lost_share`) decides how much of its deformation stands.
/// A capture that kept its folds has most of its frames given back as captured.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LostAreaJudgement {
    /// What the counts mean.
    pub rule: String,
    /// Frames whose deformation stands whole.
    pub frames_kept: usize,
    /// Frames whose deformation was scaled down as a whole.
    pub frames_scaled: usize,
    /// Frames that came back as captured: what the deformation added was not surface the capture lost.
    pub frames_given_back: usize,
    /// The median share over the judged frames.
    pub median_share: f64,
    /// The median over the frames that lost surface of the share of it the fold relief gives back (per frame in
    /// `report.frame_relief_share`): a capture that blurred its folds keeps an attenuated copy for the relief to
    /// sharpen; one that erased them outright keeps almost none, and only the anchors can make them
    /// (`deform.release_share`). `None` without the relief.
    #[serde(default)]
    pub median_relief_share: Option<f64>,
}

impl LostAreaJudgement {
    /// Counts `shares` (one per frame, `None` where the bound did not run), with the median of `relief_shares`
    /// (likewise); none when no frame was judged.
    pub fn of_frames(shares: &[Option<f64>], relief_shares: &[Option<f64>]) -> Option<Self> {
        use crease_core::spacetime::shape::lost_area::{trust, TRUST_FULL, TRUST_NONE};
        let mut judged: Vec<f64> = shares.iter().flatten().copied().collect();
        if judged.is_empty() {
            return None;
        }
        judged.sort_by(f64::total_cmp);
        let count = |keep: fn(f64) -> bool| judged.iter().filter(|s| keep(trust(**s))).count();
        Some(LostAreaJudgement {
            rule: format!(
                "per frame, the share of the surface the deformation added that the capture had lost: below \
                 {TRUST_NONE} the frame is given back as captured, from {TRUST_FULL} its deformation stands \
                 whole, scaled linearly between"
            ),
            frames_kept: count(|w| w == 1.0),
            frames_scaled: count(|w| w > 0.0 && w < 1.0),
            frames_given_back: count(|w| w == 0.0),
            median_share: judged[judged.len() / 2],
            median_relief_share: {
                let mut r: Vec<f64> = relief_shares.iter().flatten().copied().collect();
                r.sort_by(f64::total_cmp);
                r.get(r.len() / 2).copied()
            },
        })
    }
}

/// Work seconds per frame of each stage, summed over tasks.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SecondsPerFrame {
    pub weights: f64,
    pub blend: f64,
    pub factor: f64,
    pub position: f64,
    pub stretch_passes: Vec<f64>,
}

impl JobReport {
    /// The text of `report.json`.
    pub fn to_text(&self) -> Result<String, serde_json::Error> {
        serde_json::to_string_pretty(&serde_json::to_value(self)?)
    }

    /// Reads `report.json`; `label` names the file in errors.
    pub fn from_text(text: &[u8], label: &str) -> Result<Self, String> {
        serde_json::from_slice(text).map_err(|e| format!("{label}: not a deformation report: {e}"))
    }
}

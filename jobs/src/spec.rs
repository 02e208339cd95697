//! The job spec users submit (TOML or JSON, docs/cluster.md): where the input and output live, where the folds come
//! from, the deformation parameters, and how the work is partitioned across tasks.
//!
//! Every field except `input` and `output` has a default, and the deformation defaults are the paper defaults
//! that `crease run` uses, so a two-line job file deforms a sequence exactly as `crease run` would.

use crate::error::JobError;
use crate::storage::location::parse_location;
use crate::tuning::removed::removed;
use crate::tuning::table::Tuning;
use crease_core::folds::stretch::StretchParams;
use crease_core::folds::video::VideoParams;
use crease_core::spacetime::DeformParams;
use serde::{Deserialize, Serialize};

/// Frames each tracing task traces ahead of its chunk by default.
pub const DEFAULT_WARM_UP: usize = 3;

/// A job as submitted. See the crate documentation for an example `job.toml`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JobSpec {
    /// Human-readable name shown by `crease jobs` (defaults to the input's last path segment).
    #[serde(default)]
    pub name: String,
    /// Input sequence URI: a plain path, `file://…` or `s3://bucket/…`: a directory of numbered OBJ/PLY frames,
    /// a directory with one `.obj` + one `.pc2`, or the `.pc2` itself.
    pub input: String,
    /// Output location URI (a directory): frames under the input's file names, `report.json` (written last),
    /// `preview.png`, `stretch.png`, and intermediates under `.crease-work/`.
    pub output: String,
    /// Where the folds (anchors) come from.
    #[serde(default)]
    pub folds: FoldSpec,
    /// Space-time deformation parameters (paper defaults).
    #[serde(default)]
    pub deform: DeformParams,
    /// Higher runs first; FIFO within a priority.
    #[serde(default)]
    pub priority: i32,
    #[serde(default)]
    pub partition: Partition,
    /// Submitting twice with the same token returns the first job instead of creating a second one.
    #[serde(default)]
    pub client_token: Option<String>,
    /// Attempts of one task before the job fails.
    #[serde(default = "default_max_task_attempts")]
    pub max_task_attempts: u32,
    /// Failed attempts, over all tasks of the job, before the job fails.
    #[serde(default = "default_max_task_failures_per_job")]
    pub max_task_failures_per_job: u32,
    #[serde(default)]
    pub preview: PreviewOptions,
    /// Formats finalize also writes (`[export]`, see [`crate::export_spec`]).
    #[serde(default)]
    pub export: crate::export_spec::ExportSpec,
    /// DeepWrinkles training or inference instead of a deformation ([`crate::deep`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub deep: Option<crate::deep::DeepSpec>,
    /// Tuning keys ([`crate::tuning`]), applied over the tables they name when the spec is read, which leaves
    /// this empty.
    #[serde(default, skip_serializing_if = "Tuning::is_empty")]
    pub tuning: Tuning,
}

fn default_max_task_attempts() -> u32 {
    3
}
fn default_max_task_failures_per_job() -> u32 {
    10
}

/// Where a job's anchors come from.
// One spec per job, parsed once: the video variant's size does not matter.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum FoldSpec {
    /// No folds: the output equals the input (useful to check a pipeline end to end).
    #[default]
    None,
    /// An anchors file (JSON, docs/formats.md) an artist or another tool wrote.
    Anchors {
        /// URI of the anchors file.
        uri: String,
    },
    /// Folds estimated from the geometry alone (Chen 2011 ch. 4): one whole-sequence detection task, which
    /// also draws `folds.png` (the preview frames); the merge writes `anchors.json` and
    /// `folds/control_lines.obj`.
    Stretch {
        /// Detector parameters; each defaults to the value `crease run --folds stretch` uses.
        #[serde(default)]
        params: StretchParams,
        /// Levels of midpoint subdivision (0–4) applied to the input before detection and deformation; the
        /// output is then plain OBJ frames of the subdivided mesh, original vertices first.
        #[serde(default)]
        subdivide: u32,
    },
    /// Folds from the capture video (Popa et al. 2009 §4): per-frame detection tasks in chunks of
    /// `partition.fold_frames_per_chunk` frames, each drawing the overlays of its `overlay_frames`.
    Video {
        /// Camera calibration (JSON, see docs/folds.md).
        cameras: String,
        /// Directory holding the images; default: the cameras file's `image_pattern`, relative to that file.
        #[serde(default)]
        images: Option<String>,
        /// Detector parameters; each defaults to the paper's value (docs/folds.md, "Folds from the capture video").
        #[serde(default)]
        params: VideoParams,
        /// Tracked front / back vertex for view selection; both or neither (automatic from frame 0).
        #[serde(default)]
        front_vertex: Option<u32>,
        #[serde(default)]
        back_vertex: Option<u32>,
        /// Image number of sequence frame 0; default: each input frame file's own number (1 for point caches).
        #[serde(default)]
        first_image_number: Option<u64>,
        /// Frames (0-based) whose fold-edge overlays are written to `overlays/frame_NNNN.png`.
        #[serde(default)]
        overlay_frames: Vec<usize>,
    },
    /// Test-only detector that derives anchors from the geometry of each frame; exercises the generic
    /// fold-detection path of the planner (see `detect.rs`).
    #[cfg(test)]
    #[serde(rename = "test-detector")]
    TestDetector { whole_sequence: bool },
}

impl FoldSpec {
    /// Levels of midpoint subdivision every task applies to the input (0 = none; stretch folds only).
    pub fn subdivide(&self) -> usize {
        match self {
            FoldSpec::Stretch { subdivide, .. } => *subdivide as usize,
            _ => 0,
        }
    }

    /// Short name for logs and reports.
    pub fn kind(&self) -> &'static str {
        match self {
            FoldSpec::None => "none",
            FoldSpec::Anchors { .. } => "anchors",
            FoldSpec::Stretch { .. } => "stretch",
            FoldSpec::Video { .. } => "video",
            #[cfg(test)]
            FoldSpec::TestDetector { .. } => "test-detector",
        }
    }
}

/// How a job is cut into tasks.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Partition {
    /// Anchor columns per weight block in per-anchor mode (overrides `deform.anchor_block` when set).
    pub anchor_block: usize,
    /// Frames per positioning task (at most: chunks also end where a window releases its frames, see
    /// [`crate::plan::chunks::position_chunks`]).
    pub frames_per_chunk: usize,
    /// Frames per fold-detection task (per-frame detectors only).
    pub fold_frames_per_chunk: usize,
    /// Stretch detector: frames per tracing task (step tasks take four times as many); 0 = from the frame and
    /// triangle counts ([`crate::plan::chunks::trace_frames_per_chunk`]).
    pub stretch_frames_per_chunk: usize,
    /// Stretch detector: frames a tracing task traces before its first one to warm its seed memory up
    /// (any value gives the same output; more costs each task more, fewer leaves more to the merge).
    pub stretch_warm_up: usize,
    /// Frames per temporal-coherence (`fold-settle`) task of detected folds; 0 = the detection's chunk size
    /// (tracing chunks for stretch folds), at most half the sequence. Any value gives the same output.
    pub settle_frames_per_chunk: usize,
}

impl Default for Partition {
    fn default() -> Self {
        Partition {
            anchor_block: 256,
            frames_per_chunk: 4,
            fold_frames_per_chunk: 8,
            stretch_frames_per_chunk: 0,
            stretch_warm_up: DEFAULT_WARM_UP,
            settle_frames_per_chunk: 0,
        }
    }
}

/// What `preview.png` shows.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PreviewOptions {
    /// Frames (0-based) shown before/after; empty = four spread over the sequence, as `crease run` does.
    pub frames: Vec<usize>,
    /// Tile size in pixels.
    pub size: u32,
}

impl Default for PreviewOptions {
    fn default() -> Self {
        PreviewOptions {
            frames: Vec::new(),
            size: 384,
        }
    }
}

impl JobSpec {
    /// A job that deforms `input` into `output` with every other field at its default.
    pub fn new(input: impl Into<String>, output: impl Into<String>) -> Self {
        JobSpec {
            name: String::new(),
            input: input.into(),
            output: output.into(),
            folds: FoldSpec::default(),
            deform: DeformParams::default(),
            priority: 0,
            partition: Partition::default(),
            client_token: None,
            max_task_attempts: default_max_task_attempts(),
            max_task_failures_per_job: default_max_task_failures_per_job(),
            preview: PreviewOptions::default(),
            export: Default::default(),
            deep: None,
            tuning: Tuning::default(),
        }
    }

    /// Parses a TOML job file, applies its `[tuning]` and validates it.
    pub fn from_toml_str(text: &str) -> Result<Self, JobError> {
        let spec: JobSpec = toml::from_str(text).map_err(|e| {
            let field = missing_field(e.message())
                .or_else(|| e.span().and_then(|span| toml_field_at(text, span.start)))
                .filter(|f| !f.is_empty())
                .unwrap_or_else(|| "job spec (TOML)".to_string());
            JobError::spec(field, with_removal_reason(e.message().trim()))
        })?;
        spec.resolved()
    }

    /// Parses a JSON job spec, applies its `tuning` and validates it.
    pub fn from_json_str(text: &str) -> Result<Self, JobError> {
        let spec: JobSpec = serde_json::from_str(text).map_err(|e| {
            let field = missing_field(&e.to_string())
                .or_else(|| json_key_before(text, e.line(), e.column()))
                .filter(|f| !f.is_empty())
                .unwrap_or_else(|| "job (JSON)".to_string());
            JobError::spec(field, with_removal_reason(&e.to_string()))
        })?;
        spec.resolved()
    }

    /// Every storage location of a job, with the spec field that names it.
    pub fn uris(&self) -> Vec<(&'static str, &str)> {
        let mut v = vec![
            ("input", self.input.as_str()),
            ("output", self.output.as_str()),
        ];
        match &self.folds {
            FoldSpec::Anchors { uri } => v.push(("folds.uri", uri)),
            FoldSpec::Video {
                cameras, images, ..
            } => {
                v.push(("folds.cameras", cameras));
                if let Some(images) = images {
                    v.push(("folds.images", images));
                }
            }
            _ => {}
        }
        if let Some(deep) = &self.deep {
            v.extend(deep.uris());
        }
        v
    }

    /// A `[deep]` job trains or applies a model and does not deform its input: the parts of a job spec that
    /// only deformations use must be left at their defaults, so that nothing set there is silently ignored.
    fn validate_deep_only(&self) -> Result<(), JobError> {
        if self.folds != FoldSpec::None {
            return Err(JobError::spec(
                "folds",
                "a [deep] job has no folds (it trains or applies a DeepWrinkles model); remove [folds]",
            ));
        }
        if !self.export.formats.is_empty() {
            return Err(JobError::spec(
                "export",
                "a [deep] job writes meshes and normal maps, not an exported sequence; remove [export]",
            ));
        }
        if self.deform != crease_core::spacetime::DeformParams::default() {
            return Err(JobError::spec(
                "deform",
                "a [deep] job does not deform its input; remove [deform]",
            ));
        }
        Ok(())
    }

    /// Checks everything that can be checked without touching storage, naming the field at fault.
    pub fn validate(&self) -> Result<(), JobError> {
        if let Some((key, _)) = self.tuning.iter().next() {
            return Err(JobError::spec(
                format!("tuning.{key}"),
                "is not applied: read specs with `from_toml_str` / `from_json_str`, or call `resolved`",
            ));
        }
        parse_location(&self.input, "input")?;
        parse_location(&self.output, "output")?;
        for (field, uri) in self.uris() {
            crate::storage::confine::check_remote_uri(field, uri)?;
        }
        if let Some(deep) = &self.deep {
            self.validate_deep_only()?;
            deep.validate()?;
            #[cfg(feature = "deep")]
            crate::deep::library::check_params(deep)?;
        }
        let param_err = |e: crease_core::Error| match e {
            crease_core::Error::Param { name, msg } => {
                JobError::spec(format!("folds.params.{name}"), msg)
            }
            e => JobError::spec("folds.params", e.to_string()),
        };
        match &self.folds {
            FoldSpec::Anchors { uri } => {
                parse_location(uri, "folds.uri")?;
            }
            FoldSpec::Stretch { params, subdivide } => {
                params.validate().map_err(param_err)?;
                if *subdivide > 4 {
                    return Err(JobError::spec(
                        "folds.subdivide",
                        format!("at most 4 levels (256× the triangles), got {subdivide}"),
                    ));
                }
            }
            FoldSpec::Video {
                cameras,
                images,
                params,
                front_vertex,
                back_vertex,
                ..
            } => {
                parse_location(cameras, "folds.cameras")?;
                if let Some(images) = images {
                    parse_location(images, "folds.images")?;
                }
                params.validate().map_err(param_err)?;
                if front_vertex.is_some() != back_vertex.is_some() {
                    return Err(JobError::spec(
                        "folds.front_vertex",
                        "give both front_vertex and back_vertex, or neither for the automatic choice",
                    ));
                }
            }
            _ => {}
        }
        self.deform.validate().map_err(|e| match e {
            crease_core::Error::Param { name, msg } => {
                JobError::spec(format!("deform.{name}"), msg)
            }
            e => JobError::spec("deform", e.to_string()),
        })?;
        self.export.validate()?;
        // The block size lives in [partition]; `deform.anchor_block` is accepted only when left at its default
        // or equal, so that a value set there is never silently ignored.
        if self.deform.anchor_block != DeformParams::default().anchor_block
            && self.deform.anchor_block != self.partition.anchor_block
        {
            return Err(JobError::spec(
                "deform.anchor_block",
                format!(
                    "is {} but partition.anchor_block is {}; the block size is set in [partition] only",
                    self.deform.anchor_block, self.partition.anchor_block
                ),
            ));
        }
        let at_least_one = |field: &str, v: usize| {
            if v == 0 {
                Err(JobError::spec(field, "must be at least 1"))
            } else {
                Ok(())
            }
        };
        at_least_one("partition.anchor_block", self.partition.anchor_block)?;
        at_least_one(
            "partition.frames_per_chunk",
            self.partition.frames_per_chunk,
        )?;
        at_least_one(
            "partition.fold_frames_per_chunk",
            self.partition.fold_frames_per_chunk,
        )?;
        at_least_one("max_task_attempts", self.max_task_attempts as usize)?;
        at_least_one(
            "max_task_failures_per_job",
            self.max_task_failures_per_job as usize,
        )?;
        if !(16..=4096).contains(&self.preview.size) {
            return Err(JobError::spec(
                "preview.size",
                format!(
                    "must be between 16 and 4096 pixels, got {}",
                    self.preview.size
                ),
            ));
        }
        if let Some(t) = &self.client_token {
            if t.is_empty() || t.len() > 256 {
                return Err(JobError::spec(
                    "client_token",
                    "must be 1 to 256 characters when given",
                ));
            }
        }
        Ok(())
    }

    /// The name shown for the job: `name`, or the input's last path segment.
    pub fn display_name(&self) -> String {
        if !self.name.is_empty() {
            return self.name.clone();
        }
        self.input
            .trim_end_matches('/')
            .rsplit('/')
            .next()
            .unwrap_or("job")
            .to_string()
    }

    /// The deformation parameters tasks run with (`partition.anchor_block` is the block size).
    pub fn params(&self) -> DeformParams {
        DeformParams {
            anchor_block: self.partition.anchor_block,
            ..self.deform.clone()
        }
    }
}

/// A parse error's message, with the reason when it is about a field that was removed (`unknown field
/// `operator_block``): an old spec then says what became of the setting.
fn with_removal_reason(message: &str) -> String {
    let field = message
        .find("unknown field `")
        .map(|i| &message[i + "unknown field `".len()..])
        .and_then(|rest| rest.find('`').map(|end| &rest[..end]));
    match field.and_then(removed) {
        Some(why) => format!("{message} (`{}` was removed: {why})", field.unwrap_or("")),
        None => message.to_string(),
    }
}

/// The field a serde "missing field `output`" error is about: the missing field itself, not the key the
/// parser happened to stop at.
fn missing_field(message: &str) -> Option<String> {
    let rest = &message[message.find("missing field `")? + "missing field `".len()..];
    Some(rest[..rest.find('`')?].to_string())
}

/// The dotted name (`partition.anchor_block`) of the key on the line holding byte `offset` of a TOML text, so
/// that parse errors name the field even when the message only quotes the value.
fn toml_field_at(text: &str, offset: usize) -> Option<String> {
    let before = text.get(..offset.min(text.len()))?;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    let line = text[line_start..].lines().next().unwrap_or("");
    let key = line
        .split_once('=')
        .map(|(k, _)| k.trim().trim_matches('"'));
    let table = before[..line_start]
        .lines()
        .rev()
        .map(str::trim)
        .find(|l| l.starts_with('[') && l.ends_with(']'))
        .map(|l| l.trim_matches(|c| c == '[' || c == ']').trim().to_string());
    match (table, key) {
        (Some(t), Some(k)) if !k.is_empty() => Some(format!("{t}.{k}")),
        (None, Some(k)) if !k.is_empty() => Some(k.to_string()),
        (Some(t), _) => Some(t),
        _ => None,
    }
}

/// The last object key (`"name":`) before line `line`, column `column` (1-based) of a JSON text: the field
/// a value error is about.
fn json_key_before(text: &str, line: usize, column: usize) -> Option<String> {
    let line_start: usize = text
        .split_inclusive('\n')
        .take(line.saturating_sub(1))
        .map(str::len)
        .sum();
    let before = text.get(..(line_start + column).min(text.len()))?;
    let colon = before.rfind(':')?;
    let key_end = before[..colon].trim_end().strip_suffix('"')?;
    let key_start = key_end.rfind('"')?;
    Some(key_end[key_start + 1..].to_string())
}

#[cfg(test)]
mod fuzz_regressions {
    use super::*;

    /// Fuzzing found parse errors whose field came out empty (`job spec: ``: …`): a TOML error after an empty
    /// table header `[]`, a JSON error right after an empty key `""`. The error then names the file instead.
    #[test]
    fn parse_errors_never_name_an_empty_field() {
        let toml_err = JobSpec::from_toml_str("input = \"a\"\n[]\nframes\n").unwrap_err();
        let json_err = JobSpec::from_json_str("{\"input\": \"\": \"t\"}").unwrap_err();
        for (e, want) in [(toml_err, "job spec (TOML)"), (json_err, "job (JSON)")] {
            match e {
                JobError::Spec { field, .. } => assert_eq!(field, want),
                other => panic!("{other}"),
            }
        }
    }
}

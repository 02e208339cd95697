//! The planner's task graph as a farm sees it: stages (a farm's steps, layers or job-type phases), each a list
//! of tasks, with the graph's dependencies.
//!
//! A farm needs the whole graph at submit, but when folds are detected the number of weight blocks per window
//! (per-anchor mode) is only known after `fold-merge`. The farm graph therefore gives each window a fixed
//! number of block *slots*: slot `s` of `S` runs the window's blocks `s, s + S, s + 2S, …`, whatever their
//! number turns out to be (a slot with no block succeeds doing nothing), and the window's reduce depends on all
//! its slots. Every other stage is known at submit: fused windows, reduces and positioning chunks depend only on
//! the frame count. A farm executes exactly the planner's tasks and writes the same keys, so its outputs are
//! the coordinator's, byte for byte.

use crate::error::JobError;
use crate::plan::graph::{expand, plan};
use crate::plan::input::InputInfo;
use crate::plan::task::{TaskDef, TaskOutput, TaskSpec};
use crate::spec::JobSpec;
use crate::storage::keys;
use serde_json::json;

/// Block slots per window when folds are detected in per-anchor mode (`crease export-job --block-slots`).
pub const DEFAULT_BLOCK_SLOTS: usize = 4;

/// The stages, in graph order. Names are the farm's step names.
pub const STAGES: [Stage; 12] = [
    Stage::Relief,
    Stage::FoldSteps,
    Stage::FoldPhases,
    Stage::FoldDetect,
    Stage::FoldSettle,
    Stage::FoldMerge,
    Stage::FoldFiles,
    Stage::FoldPlot,
    Stage::Weights,
    Stage::Reduce,
    Stage::Position,
    Stage::Finalize,
];

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Stage {
    /// The fold relief of frame chunks, from the input alone (jobs that add folds).
    Relief,
    /// Stretch detector: step records of frame chunks.
    FoldSteps,
    /// Stretch detector: the phase test (one task).
    FoldPhases,
    FoldDetect,
    /// Temporal coherence of detected anchors, per frame range.
    FoldSettle,
    FoldMerge,
    /// The user-facing anchor files (one task, beside the weights; finalize waits for it).
    FoldFiles,
    /// Stretch detector: `folds.png` from the tracing chunks (one task; only finalize waits for it).
    FoldPlot,
    Weights,
    Reduce,
    Position,
    Finalize,
}

impl Stage {
    /// kebab-case name (`crease task run --stage`, Flamenco task types).
    pub fn name(self) -> &'static str {
        match self {
            Stage::Relief => "relief",
            Stage::FoldSteps => "fold-steps",
            Stage::FoldPhases => "fold-phases",
            Stage::FoldDetect => "fold-detect",
            Stage::FoldSettle => "fold-settle",
            Stage::FoldMerge => "fold-merge",
            Stage::FoldFiles => "fold-files",
            Stage::FoldPlot => "fold-plot",
            Stage::Weights => "weights",
            Stage::Reduce => "reduce",
            Stage::Position => "position",
            Stage::Finalize => "finalize",
        }
    }

    /// CamelCase name (OpenJD step and OpenCue layer names: no spaces or dashes needed).
    pub fn title(self) -> &'static str {
        match self {
            Stage::Relief => "Relief",
            Stage::FoldSteps => "FoldSteps",
            Stage::FoldPhases => "FoldPhases",
            Stage::FoldDetect => "FoldDetect",
            Stage::FoldSettle => "FoldSettle",
            Stage::FoldMerge => "FoldMerge",
            Stage::FoldFiles => "FoldFiles",
            Stage::FoldPlot => "FoldPlot",
            Stage::Weights => "Weights",
            Stage::Reduce => "Reduce",
            Stage::Position => "Position",
            Stage::Finalize => "Finalize",
        }
    }

    pub fn parse(s: &str) -> Option<Stage> {
        STAGES
            .into_iter()
            .find(|st| st.name() == s || st.title().eq_ignore_ascii_case(s))
    }

    fn of(spec: &TaskSpec) -> Stage {
        match spec {
            TaskSpec::Relief { .. } => Stage::Relief,
            TaskSpec::FoldSteps { .. } => Stage::FoldSteps,
            TaskSpec::FoldPhases { .. } => Stage::FoldPhases,
            TaskSpec::FoldDetect { .. } => Stage::FoldDetect,
            TaskSpec::FoldSettle { .. } => Stage::FoldSettle,
            TaskSpec::FoldMerge { .. } => Stage::FoldMerge,
            TaskSpec::FoldFiles { .. } => Stage::FoldFiles,
            TaskSpec::FoldPlot { .. } => Stage::FoldPlot,
            TaskSpec::WeightBlock { .. } | TaskSpec::WeightWindow { .. } => Stage::Weights,
            TaskSpec::Reduce { .. } => Stage::Reduce,
            TaskSpec::Position { .. } => Stage::Position,
            TaskSpec::Finalize { .. } => Stage::Finalize,
            // Refused by `farm_graph` before any stage is asked for.
            TaskSpec::DeepTrain { .. } | TaskSpec::DeepApply { .. } => Stage::Position,
            TaskSpec::DeepFinish { .. } => Stage::Finalize,
        }
    }
}

/// One farm task: a planner task key, or a block slot (`weights/w0003/slot1of4`).
#[derive(Debug, Clone, PartialEq)]
pub struct FarmTask {
    pub key: String,
    /// Keys of the farm tasks that must succeed first.
    pub deps: Vec<String>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct FarmStage {
    pub stage: Stage,
    pub tasks: Vec<FarmTask>,
    /// Stages this one depends on (the union of its tasks' dependencies, by stage).
    pub depends_on: Vec<Stage>,
}

/// A job's whole graph for a farm, stages in graph order (stages without tasks are left out).
#[derive(Debug, Clone, PartialEq)]
pub struct FarmGraph {
    pub stages: Vec<FarmStage>,
    /// Block slots per window (only used when folds are detected in per-anchor mode).
    pub block_slots: usize,
}

impl FarmGraph {
    pub fn stage(&self, stage: Stage) -> Option<&FarmStage> {
        self.stages.iter().find(|s| s.stage == stage)
    }

    pub fn n_tasks(&self) -> usize {
        self.stages.iter().map(|s| s.tasks.len()).sum()
    }

    /// The `index`-th task (0-based) of `stage`: how farms that number their tasks (OpenCue frames, OpenJD
    /// integer ranges) name one.
    pub fn task_at(&self, stage: Stage, index: usize) -> Result<&FarmTask, JobError> {
        let s = self
            .stage(stage)
            .ok_or_else(|| JobError::Plan(format!("this job has no `{}` stage", stage.name())))?;
        s.tasks.get(index).ok_or_else(|| {
            JobError::Plan(format!(
                "stage `{}` has {} task(s) (indices 0..{}); there is no task {index}",
                stage.name(),
                s.tasks.len(),
                s.tasks.len()
            ))
        })
    }
}

/// Key of block slot `slot` of `slots` of window `window`.
pub fn slot_key(window: usize, slot: usize, slots: usize) -> String {
    format!("{}/slot{slot}of{slots}", keys::weight_window_task(window))
}

/// Parses a [`slot_key`] into (window, slot, slots).
pub fn parse_slot_key(key: &str) -> Option<(usize, usize, usize)> {
    let rest = key.strip_prefix("weights/w")?;
    let (w, slot) = rest.split_once("/slot")?;
    let (s, n) = slot.split_once("of")?;
    let (w, s, n) = (w.parse().ok()?, s.parse().ok()?, n.parse().ok()?);
    (s < n && key == slot_key(w, s, n)).then_some((w, s, n))
}

/// The farm graph of `job` over the input `info` describes.
pub fn farm_graph(
    job: &JobSpec,
    info: &InputInfo,
    block_slots: usize,
) -> Result<FarmGraph, JobError> {
    if block_slots == 0 || block_slots > 4096 {
        return Err(JobError::Plan(format!(
            "block slots must be in 1..=4096, got {block_slots}"
        )));
    }
    if let Some(deep) = &job.deep {
        return Err(JobError::Plan(format!(
            "a [deep] job ({}) cannot be exported to a render farm: its tasks run only in crease's own \
             workers (the farm export expresses deformation jobs); submit it to a coordinator or use `crease deep`",
            deep.kind()
        )));
    }
    let mut tasks: Vec<TaskDef> = plan(job, info)?;
    if let Some(merge) = tasks.iter().find(|t| t.expands).cloned() {
        // The deformation tasks do not depend on the anchor counts except for the weight blocks: expand with
        // no anchors (no blocks), then give every window its slots.
        let none = TaskOutput {
            summary: json!({ "anchors_per_frame": vec![0usize; info.n_frames] }),
            ..Default::default()
        };
        let mut rest = expand(job, info, &merge.key, &none)?;
        let per_anchor = rest
            .iter()
            .any(|t| matches!(t.spec, TaskSpec::Reduce { .. }));
        let mut slots = Vec::new();
        for t in rest.iter_mut() {
            if let TaskSpec::Reduce { window, .. } = t.spec {
                for s in 0..block_slots {
                    let key = slot_key(window, s, block_slots);
                    t.deps.push(key.clone());
                    slots.push(TaskDef {
                        key,
                        spec: TaskSpec::WeightBlock {
                            job: job.clone(),
                            window,
                            block: s,
                        },
                        deps: vec![merge.key.clone()],
                        expands: false,
                    });
                }
            }
        }
        debug_assert!(per_anchor || slots.is_empty());
        tasks.extend(slots);
        tasks.extend(rest);
    }
    let stage_of = |key: &str| -> Option<Stage> {
        tasks
            .iter()
            .find(|t| t.key == key)
            .map(|t| Stage::of(&t.spec))
    };
    let mut stages = Vec::new();
    for stage in STAGES {
        let of_stage: Vec<&TaskDef> = tasks
            .iter()
            .filter(|t| Stage::of(&t.spec) == stage)
            .collect();
        if of_stage.is_empty() {
            continue;
        }
        let mut depends_on: Vec<Stage> = Vec::new();
        for t in &of_stage {
            for d in &t.deps {
                let s = stage_of(d).ok_or_else(|| {
                    JobError::Plan(format!("task `{}` depends on unknown task `{d}`", t.key))
                })?;
                if !depends_on.contains(&s) {
                    depends_on.push(s);
                }
            }
        }
        depends_on.sort_by_key(|s| STAGES.iter().position(|x| x == s));
        stages.push(FarmStage {
            stage,
            tasks: of_stage
                .iter()
                .map(|t| FarmTask {
                    key: t.key.clone(),
                    deps: t.deps.clone(),
                })
                .collect(),
            depends_on,
        });
    }
    Ok(FarmGraph {
        stages,
        block_slots,
    })
}

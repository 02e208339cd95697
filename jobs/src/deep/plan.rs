//! The task graph of a deep job: `deep/train` alone, or `deep/apply/fNNNNNN` per frame chunk then `deep/finish`.

use super::keys;
use super::spec::DeepSpec;
use crate::plan::chunks::chunk_ranges;
use crate::plan::input::InputInfo;
use crate::plan::task::{TaskDef, TaskSpec};
use crate::spec::JobSpec;

pub fn plan(job: &JobSpec, deep: &DeepSpec, info: &InputInfo) -> Vec<TaskDef> {
    match deep {
        DeepSpec::Train { .. } => vec![TaskDef {
            key: keys::TRAIN_TASK.to_string(),
            spec: TaskSpec::DeepTrain { job: job.clone() },
            deps: vec![],
            expands: false,
        }],
        DeepSpec::Apply { .. } => {
            let mut tasks: Vec<TaskDef> =
                chunk_ranges(info.n_frames, job.partition.frames_per_chunk)
                    .into_iter()
                    .map(|r| TaskDef {
                        key: keys::apply_task(r.start),
                        spec: TaskSpec::DeepApply {
                            job: job.clone(),
                            frames: r,
                        },
                        deps: vec![],
                        expands: false,
                    })
                    .collect();
            tasks.push(TaskDef {
                key: keys::FINISH_TASK.to_string(),
                spec: TaskSpec::DeepFinish {
                    job: job.clone(),
                    frames: info.n_frames,
                },
                deps: tasks.iter().map(|t| t.key.clone()).collect(),
                expands: false,
            });
            tasks
        }
    }
}

/// Keys that must exist before the job is done: the model's files or the frames and `done.json`, then
/// `report.json`.
pub fn final_outputs(info: &InputInfo) -> Vec<String> {
    let mut out = info.output_files.clone();
    out.push(crate::storage::keys::REPORT.to_string());
    out
}

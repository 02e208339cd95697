//! DeepWrinkles jobs (`[deep]` in a job spec, docs/deepwrinkles.md): training a crease-deep model, or applying one to a
//! pose file or a coarse sequence, scheduled like every other job.
//!
//! A job with a `[deep]` section does not deform its input: `folds`, `deform` and `export` do not apply.
//! Training is one task, because every step of it needs all the frames (the subspace, the regression and the
//! cGAN's epochs); it publishes the model under `model/` with `model/manifest.json` last, so a model missing a
//! file, or holding a file of another model, is refused by whoever loads it. Apply is cut into frame chunks
//! (`partition.frames_per_chunk`), which any worker can run: every frame depends only on the inputs and the
//! model, so the chunks write exactly the bytes of a single `crease deep apply`. A last task writes `done.json`
//! and `report.json`.

pub mod inspect;
pub mod plan;
pub mod spec;

pub use spec::{ApplyFrom, DeepSpec, DeepTrainParams};

/// Task keys and storage keys of deep jobs (all relative to the job's output).
pub mod keys {
    pub const TRAIN_TASK: &str = "deep/train";
    pub const FINISH_TASK: &str = "deep/finish";
    pub fn apply_task(first_frame: usize) -> String {
        format!("deep/apply/f{first_frame:06}")
    }
    /// The model a training job publishes: `model/<file>`, `model/manifest.json` last.
    pub const MODEL_DIR: &str = "model";
    pub const MODEL_MANIFEST: &str = "model/manifest.json";
    pub fn model_file(name: &str) -> String {
        format!("{MODEL_DIR}/{name}")
    }
    /// The output layout of apply (docs/deepwrinkles.md).
    pub fn mesh(t: usize) -> String {
        format!("mesh/frame_{:04}.obj", t + 1)
    }
    pub fn normals(t: usize) -> String {
        format!("normals/frame_{:04}.png", t + 1)
    }
    pub const DONE: &str = "done.json";
}

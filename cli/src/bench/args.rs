//! The flags of `crease bench`: which cases run, at what sizes, and where results are written.

use clap::Args;
use crease_core::spacetime::WeightMode;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Mesh sizes in triangles.
    #[arg(long, value_delimiter = ',', default_value = "25000,100000,400000")]
    pub sizes: Vec<usize>,
    /// Frames per case (at least 20 for three windows).
    #[arg(long, default_value_t = 20)]
    pub frames: usize,
    /// Anchors per frame.
    #[arg(long, default_value_t = 2000)]
    pub anchors: usize,
    /// Weight modes to run.
    #[arg(long, value_delimiter = ',', default_value = "fused,per-anchor")]
    pub modes: Vec<WeightMode>,
    /// Repeats per case; medians are reported.
    #[arg(long, default_value_t = 3)]
    pub repeats: usize,
    /// Write the 100K-class matrices and our timings of the same solves here (for bench/scipy_compare.py).
    #[arg(long)]
    pub export: Option<PathBuf>,
    /// Size (triangles) of the exported case.
    #[arg(long, default_value_t = 100_000)]
    pub export_size: usize,
    /// Write all results as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Run the per-anchor case as a cluster job on loopback instead (see `--cluster-workers`).
    #[arg(long)]
    pub cluster: bool,
    /// Worker counts of the cluster benchmark.
    #[arg(long, value_delimiter = ',', default_value = "1,2,4")]
    pub cluster_workers: Vec<usize>,
    /// Mesh size (triangles) of the cluster benchmark.
    #[arg(long, default_value_t = 100_000)]
    pub cluster_triangles: usize,
    /// Anchor columns per weight block (task) in the cluster benchmark.
    #[arg(long, default_value_t = 256)]
    pub cluster_anchor_block: usize,
    /// Run only the stretch-folds stage (geometric fold estimation, Chen 2011).
    #[arg(long)]
    pub stretch_folds_only: bool,
    /// Image for the video edge stage (default: a 640x480 render of the demo's folded ground truth with the
    /// synthetic-video shading, which has folds to pair).
    #[arg(long)]
    pub edges_image: Option<PathBuf>,
    /// Run only the video edge stage.
    #[arg(long)]
    pub edges_only: bool,
    /// Detection (stretch and video) + deformation end to end through the local cluster (bench/pipeline.rs).
    #[arg(long)]
    pub pipeline: bool,
    /// Workers of the pipeline benchmark (one task each).
    #[arg(long, default_value_t = 2)]
    pub pipeline_workers: usize,
    /// Coordinator dispatch rate with many tiny tasks (bench/dispatch.rs).
    #[arg(long)]
    pub dispatch: bool,
    /// Worker configurations of the dispatch benchmark, WORKERSxCAPACITY each.
    #[arg(long, value_delimiter = ',', default_value = "1x1,2x4,4x8")]
    pub dispatch_slots: Vec<String>,
    /// Mesh size (triangles) of the dispatch benchmark.
    #[arg(long, default_value_t = 2000)]
    pub dispatch_triangles: usize,
    /// Anchors per frame of the dispatch benchmark (one weight-block task each).
    #[arg(long, default_value_t = 40)]
    pub dispatch_anchors: usize,
    /// DeepWrinkles instead: inference per frame (map rasterisation, generator forward) and cGAN training
    /// time per epoch (see bench/deep.rs).
    #[arg(long)]
    pub deep: bool,
    /// Normal map resolution of `--deep`.
    #[arg(long, default_value_t = 256)]
    pub deep_resolution: usize,
    /// Filters of the generator's (and discriminator's) first layer in `--deep`, one or more sizes timed in turn
    /// (`crease deep train --cgan-filters` default: 8; the paper's: 64).
    #[arg(long, value_delimiter = ',', default_value = "8,16")]
    pub deep_filters: Vec<usize>,
    /// A training directory (gt/) whose first frames `--deep` uses; default: a synthetic tube of the sleeve's
    /// size.
    #[arg(long)]
    pub deep_data: Option<PathBuf>,
    /// Timed cGAN training steps in `--deep` per generator size (0: inference only).
    #[arg(long, default_value_t = 3)]
    pub deep_train_steps: usize,
}

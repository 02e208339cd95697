//! Coordinator flags that bound what a job may touch and how large it may be (`crease coordinator
//! --storage-root … --max-job-frames …`). Kept apart from the other coordinator flags because they are
//! admission policy: each is checked at submit and a refused job names the flag it broke.

use anyhow::{bail, Result};
use clap::Args;
use crease_coordinator::CoordinatorConfig;

#[derive(Args, Debug, Clone, Default)]
pub struct LimitsArgs {
    /// Storage location jobs may use (repeatable; comma-separated in the environment): a local directory
    /// (must exist), `s3://bucket/prefix`, .... When given, every input, output, anchors, cameras and images
    /// location of a job must lie under one of them, else the submit is refused.
    #[arg(
        long = "storage-root",
        value_name = "URL",
        env = "CREASE_STORAGE_ROOTS",
        value_delimiter = ','
    )]
    pub storage_roots: Vec<String>,
    /// Refuse jobs whose input has more frames than this.
    #[arg(long, value_name = "N")]
    pub max_job_frames: Option<usize>,
    /// Refuse jobs whose mesh (after any subdivision) has more vertices than this.
    #[arg(long, value_name = "N")]
    pub max_job_vertices: Option<usize>,
    /// Refuse jobs whose input sequence's files add up to more than this many MiB (checked from storage
    /// metadata, before anything is downloaded).
    #[arg(long, value_name = "MIB")]
    pub max_job_input_mib: Option<u64>,
}

impl LimitsArgs {
    /// Puts the roots and limits into `config`; a root that does not parse or exist is an error naming it.
    pub fn apply(&self, config: &mut CoordinatorConfig) -> Result<()> {
        for (flag, v) in [
            ("--max-job-frames", self.max_job_frames.map(|v| v as u64)),
            (
                "--max-job-vertices",
                self.max_job_vertices.map(|v| v as u64),
            ),
            ("--max-job-input-mib", self.max_job_input_mib),
        ] {
            if v == Some(0) {
                bail!("{flag} must be at least 1 (leave it out for no limit)");
            }
        }
        config.storage_roots = crease_jobs::StorageRoots::new(&self.storage_roots)
            .map_err(|e| anyhow::anyhow!("--storage-root: {e}"))?;
        config.limits = crease_jobs::JobLimits {
            max_frames: self.max_job_frames,
            max_vertices: self.max_job_vertices,
            max_input_bytes: self
                .max_job_input_mib
                .map(crease_jobs::JobLimits::input_mib),
        };
        Ok(())
    }
}

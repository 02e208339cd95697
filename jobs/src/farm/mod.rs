//! Running a job inside the render farm a studio already has (OpenJD / Deadline Cloud, Flamenco, OpenCue)
//! instead of crease's own coordinator.
//!
//! The planner stays the single source of the task graph: [`graph`] turns it into stages a farm can schedule
//! (with fixed block slots where the graph would grow after fold detection), the writers ([`openjd`],
//! [`flamenco`], [`opencue`]) describe those stages in each farm's job format, and every farm task runs
//! `crease task run` ([`run`]), which re-plans the job, finds its task and executes it with the same code as
//! a worker. Outputs land under the same deterministic keys, so a farm retry rewrites identical bytes and the
//! finished output is the one `crease run` writes.

pub mod command;
pub mod flamenco;
pub mod graph;
pub mod opencue;
pub mod openjd;
pub mod run;

pub use command::FarmCommand;
pub use graph::{farm_graph, FarmGraph, Stage, DEFAULT_BLOCK_SLOTS};
pub use opencue::CueIdentity;
pub use run::{run_farm_task, FarmRun, FarmRunError, TaskRef};

use crate::error::JobError;
use crate::spec::JobSpec;

/// A farm's job format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Farm {
    OpenJd,
    Flamenco,
    OpenCue,
}

impl std::str::FromStr for Farm {
    type Err = JobError;
    fn from_str(s: &str) -> Result<Self, JobError> {
        match s.to_ascii_lowercase().as_str() {
            "openjd" | "deadline" => Ok(Farm::OpenJd),
            "flamenco" => Ok(Farm::Flamenco),
            "opencue" | "cue" => Ok(Farm::OpenCue),
            _ => Err(JobError::spec(
                "--to",
                format!("unknown farm `{s}`; expected openjd, flamenco or opencue"),
            )),
        }
    }
}

impl Farm {
    /// Default file name of the exported job.
    pub fn file_name(self, job: &JobSpec) -> String {
        let stem: String = job
            .display_name()
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '-' {
                    c
                } else {
                    '_'
                }
            })
            .collect();
        match self {
            Farm::OpenJd => format!("{stem}.openjd.json"),
            Farm::Flamenco => format!("crease-{stem}.js"),
            Farm::OpenCue => format!("{stem}.cuejob.xml"),
        }
    }
}

/// Writes `graph` in `farm`'s format.
pub fn export_job(
    farm: Farm,
    job: &JobSpec,
    graph: &FarmGraph,
    cmd: &FarmCommand,
    cue: &CueIdentity,
) -> String {
    let name = job.display_name();
    match farm {
        Farm::OpenJd => openjd::openjd_template(&name, graph, cmd),
        Farm::Flamenco => flamenco::flamenco_job_type(&name, graph, cmd),
        Farm::OpenCue => opencue::opencue_spec(&name, graph, cmd, cue),
    }
}

/// Farm tasks run in directories of the farm's choosing, where a relative path means something else: every
/// local path of the job must be absolute (URIs are fine).
pub fn check_farm_paths(job: &JobSpec) -> Result<(), JobError> {
    for (field, uri) in job.uris() {
        if !uri.contains("://") && !std::path::Path::new(uri).is_absolute() {
            return Err(JobError::spec(
                field,
                format!(
                    "`{uri}` is relative; farm tasks run in other directories, so give an absolute path \
                     (as the farm nodes see the shared storage) or a URI"
                ),
            ));
        }
    }
    Ok(())
}

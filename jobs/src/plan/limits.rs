//! The largest job a coordinator accepts: a farm shares its workers and its storage, so one job with a
//! million frames or a 200 GiB input should be refused at submit (naming the limit and the job's value)
//! instead of occupying the queue for days or filling the workers' caches.

use crate::error::JobError;
use crate::plan::input::InputInfo;

/// Limits checked at submit; `None` = unlimited.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct JobLimits {
    /// Frames of the input sequence (`--max-job-frames`).
    pub max_frames: Option<usize>,
    /// Vertices of the mesh the tasks deform, after any subdivision the job asks for (`--max-job-vertices`).
    pub max_vertices: Option<usize>,
    /// Bytes of the input sequence's files (`--max-job-input-mib`, in MiB).
    pub max_input_bytes: Option<u64>,
}

const MIB: u64 = 1024 * 1024;

impl JobLimits {
    /// Checked before the input is fetched: its total size, from storage metadata.
    pub fn check_input_size(&self, input: &str, bytes: u64) -> Result<(), JobError> {
        match self.max_input_bytes {
            Some(max) if bytes > max => Err(JobError::Limit {
                limit: "--max-job-input-mib".into(),
                msg: format!(
                    "the input {input} is {:.1} MiB ({bytes} bytes); this coordinator accepts at most {} MiB",
                    bytes as f64 / MIB as f64,
                    max / MIB
                ),
            }),
            _ => Ok(()),
        }
    }

    /// Checked once the input has been inspected.
    pub fn check_info(&self, info: &InputInfo) -> Result<(), JobError> {
        if let Some(max) = self.max_frames {
            if info.n_frames > max {
                return Err(JobError::Limit {
                    limit: "--max-job-frames".into(),
                    msg: format!(
                        "the job has {} frames; this coordinator accepts at most {max}",
                        info.n_frames
                    ),
                });
            }
        }
        if let Some(max) = self.max_vertices {
            if info.n_vertices > max {
                return Err(JobError::Limit {
                    limit: "--max-job-vertices".into(),
                    msg: format!(
                        "the job's mesh has {} vertices (after any subdivision); this coordinator accepts at most {max}",
                        info.n_vertices
                    ),
                });
            }
        }
        Ok(())
    }

    /// `--max-job-input-mib` as bytes.
    pub fn input_mib(mib: u64) -> u64 {
        mib.saturating_mul(MIB)
    }
}

/// Submit-time admission of a job: its locations under the storage roots, its input's size (from metadata,
/// before anything is fetched), the inspection of the input ([`crate::plan::inspect::inspect_input`]), then its frame and
/// vertex counts. The first failure is the error, naming the field or the limit.
pub async fn admit(
    spec: &crate::JobSpec,
    roots: &crate::StorageRoots,
    limits: &JobLimits,
) -> Result<InputInfo, JobError> {
    spec.validate()?;
    roots.check_all(spec.uris())?;
    if limits.max_input_bytes.is_some() {
        let bytes = crate::storage::store::input_size(&spec.input).await?;
        limits.check_input_size(&spec.input, bytes)?;
    }
    let info = crate::plan::inspect::inspect_input(spec).await?;
    limits.check_info(&info)?;
    Ok(info)
}

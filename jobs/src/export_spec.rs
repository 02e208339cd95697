//! The `[export]` table of a job: formats the finalize task writes next to the output sequence, so that a farm
//! job ends with the file the artist opens (see docs/export.md).
//!
//! ```toml
//! [export]
//! formats = ["glb", "usd"]   # any of glb, usd, mdd, pc2
//! fps = 30                   # default 30
//! first_frame = 1            # default 1
//! up_axis = "z"              # the data's up axis: "z" (default) or "y"
//! ```
//!
//! Files go to `export/<job name>.<ext>` under the output (a subdirectory, so that the output directory stays
//! readable as a sequence).

use crate::error::JobError;
use crease_core::export::{ExportFormat, ExportOptions, UpAxis};
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ExportSpec {
    pub formats: Vec<ExportFormat>,
    pub fps: f64,
    pub first_frame: f64,
    pub up_axis: UpAxis,
}

impl Default for ExportSpec {
    fn default() -> Self {
        let o = ExportOptions::default();
        ExportSpec {
            formats: Vec::new(),
            fps: o.fps,
            first_frame: o.first_frame,
            up_axis: o.up_axis,
        }
    }
}

impl ExportSpec {
    pub fn options(&self) -> ExportOptions {
        ExportOptions {
            fps: self.fps,
            first_frame: self.first_frame,
            up_axis: self.up_axis,
        }
    }

    pub fn validate(&self) -> Result<(), JobError> {
        for (i, f) in self.formats.iter().enumerate() {
            if self.formats[..i].contains(f) {
                return Err(JobError::spec(
                    "export.formats",
                    format!("`{f}` is listed twice"),
                ));
            }
        }
        self.options().validate().map_err(|e| match e {
            crease_core::Error::Param { name, msg } => {
                JobError::spec(format!("export.{name}"), msg)
            }
            e => JobError::spec("export", e.to_string()),
        })
    }
}

/// Storage key (relative to the output) of the job's export in `format`.
pub fn export_key(job_name: &str, format: ExportFormat) -> String {
    let stem: String = job_name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    let stem = if stem.is_empty() {
        "crease".into()
    } else {
        stem
    };
    format!("export/{stem}.{}", format.extension())
}

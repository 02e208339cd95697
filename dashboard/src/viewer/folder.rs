//! `crease view`'s mount: one folder on this machine, under the fixed id [`LOCAL_ID`]. A folder holding a
//! `report.json` is a crease output, and its report names the input it was made from; any other folder (or
//! a `.pc2`) is a sequence shown alone.

use super::{Locate, LocateError, Located};
use crease_core::mesh::io::detect_layout;
use crease_jobs::storage::{parse_location, Location};
use serde_json::Value;
use std::path::{Path, PathBuf};

/// The one id `crease view` serves.
pub const LOCAL_ID: &str = "local";

pub struct Folder {
    located: Located,
}

/// A path named in a report, if it is on this machine; otherwise a note.
fn named_in_report(
    report: &Value,
    key: &str,
    what: &str,
    notes: &mut Vec<String>,
) -> Option<PathBuf> {
    let uri = report[key].as_str()?;
    match parse_location(uri, key) {
        Ok(Location::Local(p)) if p.exists() => Some(p),
        Ok(Location::Local(p)) => {
            notes.push(format!(
                "the {what} named in report.json ({}) is not there any more{}",
                p.display(),
                if what == "input" {
                    "; pass --input to show it"
                } else {
                    ""
                }
            ));
            None
        }
        _ => {
            notes.push(format!(
                "the {what} named in report.json ({uri}) is not on this machine"
            ));
            None
        }
    }
}

impl Folder {
    /// Works out what `path` holds. `input`, when given, is the sequence `path` was made from (it overrides
    /// the one the report names, and makes `path` an output even without a report).
    pub fn open(path: &Path, input: Option<&Path>) -> Result<Folder, String> {
        let name = std::path::absolute(path)
            .ok()
            .and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
            .unwrap_or_else(|| path.display().to_string());
        if !path.exists() {
            return Err(format!("{} does not exist", path.display()));
        }
        if let Some(i) = input.filter(|i| !i.exists()) {
            return Err(format!("--input {} does not exist", i.display()));
        }
        let report_path = path.join("report.json");
        let mut notes = Vec::new();
        let located = if report_path.is_file() {
            let text = std::fs::read(&report_path)
                .map_err(|e| format!("{}: {e}", report_path.display()))?;
            let report: Value = serde_json::from_slice(&text)
                .map_err(|e| format!("{}: not JSON: {e}", report_path.display()))?;
            let input = match input {
                Some(i) => Some(i.to_path_buf()),
                None => named_in_report(&report, "input", "input", &mut notes),
            };
            Located {
                name,
                input,
                output: Some(path.to_path_buf()),
                output_uri: Some(path.display().to_string()),
                anchors: named_in_report(&report, "anchors_file", "anchors file", &mut Vec::new()),
                notes,
            }
        } else {
            detect_layout(path).map_err(|e| {
                format!(
                    "{} is neither a crease output (it has no report.json) nor a sequence: {e}",
                    path.display()
                )
            })?;
            match input {
                Some(i) => Located {
                    name,
                    input: Some(i.to_path_buf()),
                    output: Some(path.to_path_buf()),
                    output_uri: Some(path.display().to_string()),
                    anchors: None,
                    notes,
                },
                None => Located {
                    name,
                    input: Some(path.to_path_buf()),
                    output: None,
                    output_uri: None,
                    anchors: None,
                    notes,
                },
            }
        };
        Ok(Folder { located })
    }

    pub fn located(&self) -> &Located {
        &self.located
    }
}

impl Locate for Folder {
    fn locate(&self, id: &str) -> Result<Located, LocateError> {
        if id == LOCAL_ID {
            Ok(self.located.clone())
        } else {
            Err(LocateError::NotFound(format!(
                "`{id}` is not served here (crease view serves `{LOCAL_ID}`)"
            )))
        }
    }
}

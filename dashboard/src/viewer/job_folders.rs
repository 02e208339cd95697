//! The coordinator's mount: a job id is looked up in the queue, and its stored spec says where its input, its
//! output and its anchors file are. Only locations on the coordinator's own filesystem have frames to show;
//! a remote one is named in a note (its `report.json` is still read, through storage).

use super::{Locate, LocateError, Located};
use crease_coordinator::{ApiError, Scheduler};
use crease_jobs::storage::{parse_location, Location};
use serde_json::Value;
use std::path::PathBuf;
use std::sync::Arc;

pub struct JobFolders {
    scheduler: Arc<Scheduler>,
}

impl JobFolders {
    pub fn new(scheduler: Arc<Scheduler>) -> Self {
        JobFolders { scheduler }
    }
}

fn locate_err(e: ApiError) -> LocateError {
    match e {
        ApiError::NotFound(m) => LocateError::NotFound(m),
        ApiError::Invalid(m) | ApiError::Internal(m) => LocateError::Internal(m),
    }
}

/// `uri` as a local path, or a note saying why its frames are not read here.
fn local(uri: &str, what: &str, notes: &mut Vec<String>) -> Option<PathBuf> {
    match parse_location(uri, what) {
        Ok(Location::Local(p)) => Some(p),
        Ok(Location::Remote(_)) => {
            notes.push(format!(
                "the {what} ({uri}) is in remote storage; the viewer shows sequences on the coordinator's \
                 filesystem"
            ));
            None
        }
        Err(e) => {
            notes.push(format!("the {what}: {e}"));
            None
        }
    }
}

impl Locate for JobFolders {
    fn locate(&self, id: &str) -> Result<Located, LocateError> {
        let status = self.scheduler.status(id, false).map_err(locate_err)?;
        let spec: Value =
            serde_json::from_str(&self.scheduler.job_spec_json(id).map_err(locate_err)?).map_err(
                |e| LocateError::Internal(format!("job {id}: the stored spec is unreadable: {e}")),
            )?;
        let mut notes = Vec::new();
        let input = spec["input"]
            .as_str()
            .and_then(|uri| local(uri, "input", &mut notes));
        let anchors = match (
            spec["folds"]["kind"].as_str(),
            spec["folds"]["uri"].as_str(),
        ) {
            (Some("anchors"), Some(uri)) => local(uri, "anchors file", &mut notes),
            _ => None,
        };
        // The output counts once its report is written (finalize writes it last); before that the input is
        // shown alone.
        let output = local(&status.output, "output", &mut notes).filter(|dir| {
            let done = dir.join(crease_jobs::keys::REPORT).is_file();
            if !done {
                notes.push(format!(
                    "the output is not complete yet (job {}): the input is shown alone",
                    status.state
                ));
            }
            done
        });
        Ok(Located {
            name: status.name,
            input,
            output,
            output_uri: Some(status.output),
            anchors,
            notes,
        })
    }
}

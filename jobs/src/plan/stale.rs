//! Output hygiene: files an earlier run wrote into a job's output, and that this run will not write again, are
//! removed before the run starts, so a new "complete" result never stands beside stale frames, anchors or
//! overlays of another run (fewer frames, a different fold source, other overlay frames).
//!
//! Only files crease itself wrote are ever removed: each submit records the keys its run owns in
//! [`OWNED`] (before any task writes), and `report.json` repeats them as `manifest`. A file the user put into
//! the output directory is in neither list and is left alone, whatever its name. The alternative, staging the
//! whole output elsewhere and swapping it in, is not possible on object stores (no atomic rename of a prefix).

use crate::error::JobError;
use crate::plan::input::InputInfo;
use crate::spec::{FoldSpec, JobSpec};
use crate::storage::keys;
use crate::storage::store::Storage;
use std::collections::BTreeSet;

/// Keys (relative to the output) that the run submitted last owns, as JSON `{"owned": [...]}`.
pub const OWNED: &str = ".crease-work/owned.json";

/// Every key outside `.crease-work/` that a run of `job` may write: the final outputs and the detectors'
/// inspection images.
pub fn owned_keys(job: &JobSpec, info: &InputInfo) -> BTreeSet<String> {
    let mut keys: BTreeSet<String> = crate::plan::graph::final_outputs(job, info)
        .into_iter()
        .collect();
    match &job.folds {
        FoldSpec::Stretch { .. } => {
            keys.insert("folds.png".to_string());
        }
        FoldSpec::Video { overlay_frames, .. } => {
            keys.extend(
                overlay_frames
                    .iter()
                    .map(|&t| crease_core::folds::video::overlay_key(t)),
            );
        }
        _ => {}
    }
    keys
}

fn keys_in(doc: &serde_json::Value, field: &str) -> Vec<String> {
    doc[field]
        .as_array()
        .map(|a| {
            a.iter()
                .filter_map(|k| k.as_str().map(str::to_string))
                .collect()
        })
        .unwrap_or_default()
}

async fn read_json(out: &Storage, key: &str) -> Option<serde_json::Value> {
    let bytes = out.get(key).await.ok()?;
    serde_json::from_slice(&bytes).ok()
}

/// Claims the output for a new run of `job`: removes the files earlier runs owned that this run will not
/// write, records what this run owns, and removes `report.json` (it must not vouch for the new run while it
/// runs). Returns the removed keys.
pub async fn claim_output(
    out: &Storage,
    job: &JobSpec,
    info: &InputInfo,
) -> Result<Vec<String>, JobError> {
    let owned = owned_keys(job, info);
    let mut previous: BTreeSet<String> = BTreeSet::new();
    if let Some(doc) = read_json(out, OWNED).await {
        previous.extend(keys_in(&doc, "owned"));
    }
    if let Some(doc) = read_json(out, keys::REPORT).await {
        previous.extend(keys_in(&doc, "manifest"));
    }
    let mut removed = Vec::new();
    for key in previous.difference(&owned) {
        // A key from a damaged or hand-edited list never reaches outside the output or into the work area.
        if key == keys::REPORT
            || key.starts_with(keys::WORK_DIR)
            || crate::storage::confine::check_key(key).is_err()
        {
            continue;
        }
        out.delete(key).await?;
        removed.push(key.clone());
    }
    let doc = serde_json::json!({ "owned": owned });
    out.put(OWNED, doc.to_string()).await?;
    out.delete(keys::REPORT).await?;
    Ok(removed)
}

/// The keys recorded for the current run (finalize copies them into `report.json` as `manifest`).
pub async fn owned_now(out: &Storage) -> Vec<String> {
    match read_json(out, OWNED).await {
        Some(doc) => keys_in(&doc, "owned"),
        None => Vec::new(),
    }
}

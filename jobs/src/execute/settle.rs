//! `fold-settle` tasks ([`crate::plan::settle`]): the temporal coherence of one frame range, from the detected
//! anchors of that range widened by the settle radius, stored under [`keys::fold_settled`] in the binary anchors
//! form (the merge reads them back through [`super::fold_chunks::settled`]).

use super::env::TaskEnv;
use super::fold_chunks::{ranges, read_detected};
use super::phase_times::Lap;
use crate::error::TaskError;
use crate::plan::settle::{inputs_of, settle_radius};
use crate::storage::keys;
use crease_core::folds::anchors::binary;
use crease_core::folds::temporal::{settle_input, settle_range};
use crease_core::folds::FrameAnchors;
use serde_json::{json, Value};
use std::ops::Range;

/// A `fold-settle` task: settles `frames` from the detection chunks its input window overlaps.
pub fn settle(env: &TaskEnv, frames: Range<usize>) -> Result<(Value, Vec<String>), TaskError> {
    let mut lap = Lap::start();
    let opened = env.open_input()?;
    let n = opened.source.n_frames();
    let label = format!(
        "temporal coherence, frames {}..{}",
        frames.start, frames.end
    );
    let radius = settle_radius(env.job, n).ok_or_else(|| {
        TaskError::fatal(format!(
            "{label}: folds of kind `{}` over {n} frames have no settle tasks",
            env.job.folds.kind()
        ))
    })?;
    let (detected, ranges) = ranges(env, &opened);
    if !ranges.contains(&frames) {
        return Err(TaskError::fatal(format!(
            "{label}: not one of the job's settle ranges over {n} frames"
        )));
    }
    let need = settle_input(frames.clone(), n, radius);
    let mut input: Vec<FrameAnchors> = Vec::with_capacity(need.len());
    for c in inputs_of(&frames, n, radius, &detected) {
        input.extend(
            read_detected(env, &c)?
                .into_iter()
                .filter(|f| need.contains(&f.frame)),
        );
    }
    lap.lap("fold-settle: open input, read detected chunks");
    env.check_cancelled()?;
    let out = settle_range(
        opened.source.as_ref(),
        &input,
        need.start,
        n,
        frames.clone(),
        radius,
    )
    .map_err(|e| TaskError::from_core(&label, e))?;
    lap.lap("fold-settle: settle_range (reads its window's meshes)");
    let key = keys::fold_settled(frames.start);
    env.put(&key, binary::frames_to_binary(&out))?;
    lap.lap("fold-settle: write settled anchors");
    let counts: Vec<usize> = out.iter().map(|f| f.anchors.len()).collect();
    Ok((json!({ "anchors_per_frame": counts }), vec![key]))
}

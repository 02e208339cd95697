//! Relief tasks: the fold relief of each captured frame of a chunk
//! ([`crease_core::spacetime::shape::relief::frame_relief`]), stored for the positioning tasks, which average it
//! over time per frame. A pure function of the input frame and the job's detail scale.

use super::env::TaskEnv;
use crate::error::TaskError;
use crate::storage::keys;
use crease_core::mesh::FrameSource;
use crease_core::spacetime::shape::relief::frame_relief;
use rayon::prelude::*;
use serde_json::{json, Value};
use std::ops::Range;

/// Computes and stores the reliefs of `frames`.
pub fn relief(env: &TaskEnv, frames: Range<usize>) -> Result<(Value, Vec<String>), TaskError> {
    let label = format!("relief frames {}..{}", frames.start, frames.end);
    let opened = env.open_input()?;
    let source: &dyn FrameSource = opened.source.as_ref();
    let n = source.n_frames();
    if frames.start >= frames.end || frames.end > n {
        return Err(TaskError::fatal(format!(
            "{label}: not a frame range of the {n}-frame input"
        )));
    }
    let scales = super::position::sequence_scales(env, &opened, &label)?;
    let topo = source.topology().clone();
    let steps = env.params.relief.steps;
    env.progress().begin("relief", frames.len() as u64);
    let written: Vec<String> = frames
        .clone()
        .into_par_iter()
        .map(|t| {
            if env.ctx.progress.cancelled() {
                return Err(TaskError::cancelled());
            }
            let c = source
                .read_frame(t)
                .map_err(|e| TaskError::from_core(&label, e))?;
            let r = frame_relief(&topo, &c, scales.detail, steps);
            let key = keys::relief(t);
            env.put_npy(&key, &[r.len()], &r)?;
            env.progress().advance("relief", 1);
            Ok(key)
        })
        .collect::<Result<_, _>>()?;
    env.progress().end("relief");
    Ok((
        json!({ "frames": [frames.start, frames.end], "detail_scale": scales.detail }),
        written,
    ))
}

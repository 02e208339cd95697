//! The job's `[export]` formats, written by finalize from the stored positions (any storage, any layout) before
//! `report.json`, so a complete report always sits next to complete exports.

use super::env::{storage_err, TaskEnv};
use crate::error::TaskError;
use crate::export_spec::export_key;
use crate::storage::keys;
use crease_core::export::export;
use crease_core::mesh::{Frame, FrameSource, Topology};
use std::sync::Arc;

/// The output sequence as the positioning tasks stored it (`.crease-work/positions/fNNNNNN.npy`), read one
/// frame at a time.
struct StoredPositions<'a> {
    env: &'a TaskEnv<'a>,
    topo: Arc<Topology>,
    n: usize,
}

impl FrameSource for StoredPositions<'_> {
    fn topology(&self) -> &Arc<Topology> {
        &self.topo
    }
    fn n_frames(&self) -> usize {
        self.n
    }
    fn read_frame(&self, t: usize) -> crease_core::Result<Frame> {
        let key = keys::positions(t);
        let bad = |msg: String| crease_core::Error::format(self.env.out.describe(&key), None, msg);
        let (shape, data) = self.env.get_npy::<f64>(&key).map_err(|e| bad(e.reason))?;
        if shape != [self.topo.n_vertices(), 3] {
            return Err(bad(format!(
                "shape {shape:?}, expected ({}, 3)",
                self.topo.n_vertices()
            )));
        }
        Ok(data.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
    }
    fn describe_frame(&self, t: usize) -> String {
        self.env.out.describe(&keys::positions(t))
    }
}

/// Writes every format of the job's `[export]` table; returns the keys written.
pub fn write_exports(
    env: &TaskEnv,
    topo: &Arc<Topology>,
    n: usize,
) -> Result<Vec<String>, TaskError> {
    let spec = &env.job.export;
    if spec.formats.is_empty() {
        return Ok(Vec::new());
    }
    let source = StoredPositions {
        env,
        topo: topo.clone(),
        n,
    };
    let local = env.out.local_path().map(|p| p.to_path_buf());
    let dir = match &local {
        Some(root) => root.join("export"),
        None => env.output_dir("export")?.path,
    };
    std::fs::create_dir_all(&dir)
        .map_err(|e| TaskError::transient(format!("finalize: export: {}: {e}", dir.display())))?;
    let mut written = Vec::new();
    for &format in &spec.formats {
        env.check_cancelled()?;
        let key = export_key(&env.job.display_name(), format);
        let name = key.rsplit('/').next().unwrap_or(&key).to_string();
        let path = dir.join(&name);
        export(&source, format, &path, &spec.options(), env.progress())
            .map_err(|e| TaskError::from_core(&format!("finalize: export {format}"), e))?;
        if local.is_none() {
            env.block_on(env.out.put_file(&key, &path))
                .map_err(storage_err)?;
        }
        written.push(key);
    }
    Ok(written)
}

//! The DESIGN §7 output contract: per frame N, `OUT/mesh/frame_NNNN.obj` (the coarse mesh with `vt`, faces
//! `f v/vt`) and `OUT/normals/frame_NNNN.png` (the normal map in that layout). Every file is written atomically
//! (temporary name, then rename), so a reader never sees half a frame; `OUT/done.json` is written last, after
//! all frames, and is what says the output is complete.

use crate::normal_map::{NormalMap, Space};
use crate::uv::{write_obj_with_uv, UvLayout};
use crease_core::mesh::Topology;
use crease_core::vec3::V3;
use crease_core::Result;
use std::path::{Path, PathBuf};

/// File name stem of output frame `t` (0-based): frames are numbered from 1, four digits.
pub fn frame_stem(t: usize) -> String {
    format!("frame_{:04}", t + 1)
}

pub fn mesh_path(out: &Path, t: usize) -> PathBuf {
    out.join("mesh").join(format!("{}.obj", frame_stem(t)))
}

pub fn normals_path(out: &Path, t: usize) -> PathBuf {
    out.join("normals").join(format!("{}.png", frame_stem(t)))
}

/// Creates `OUT/mesh` and `OUT/normals`, and removes a stale completion marker (a rerun into the same folder is
/// incomplete until it finishes).
pub fn prepare(out: &Path) -> Result<()> {
    crease_core::fsutil::create_dir_all(&out.join("mesh"))?;
    crease_core::fsutil::create_dir_all(&out.join("normals"))?;
    let done = out.join("done.json");
    if done.exists() {
        std::fs::remove_file(&done).map_err(|e| crease_core::Error::io(&done, e))?;
    }
    Ok(())
}

pub fn write_frame(
    out: &Path,
    t: usize,
    topo: &Topology,
    positions: &[V3],
    layout: &UvLayout,
    map: &NormalMap,
) -> Result<()> {
    write_obj_with_uv(&mesh_path(out, t), topo, positions, layout)?;
    map.write_png(&normals_path(out, t))
}

/// Marks the output complete: frame count, map space and resolution, for people and tools.
pub fn finish(
    out: &Path,
    n_frames: usize,
    space: Space,
    resolution: usize,
    what: &str,
) -> Result<()> {
    let doc = serde_json::json!({
        "complete": true,
        "frames": n_frames,
        "space": space,
        "resolution": resolution,
        "produced_by": what,
    });
    crease_core::fsutil::write_atomic(&out.join("done.json"), doc.to_string().as_bytes())
}

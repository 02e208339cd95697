//! How a job's frames are cut into the ranges its tasks work on: positioning chunks at the windows' release
//! points, stretch tracing and step chunks sized by the mesh, and the windows and weight blocks of the
//! deformation. Every cut gives the same outputs; it only decides how the work spreads over workers.

use crate::spec::JobSpec;
use crease_core::spacetime::weights::per_anchor::plan_blocks;
use crease_core::spacetime::windows::{plan_windows, Window};
use std::ops::Range;

/// `[0, n)` cut into consecutive ranges of at most `size` frames.
pub fn chunk_ranges(n: usize, size: usize) -> Vec<Range<usize>> {
    let size = size.max(1);
    (0..n.div_ceil(size))
        .map(|c| c * size..((c + 1) * size).min(n))
        .collect()
}

/// The positioning chunks: `[0, n)` cut where the last window a frame needs changes, then into ranges of at
/// most `size` frames.
///
/// Why at the windows' release points: a frame can be positioned once the last window covering it is solved
/// (the in-process deformation positions exactly those frames beside the next window's solve). A chunk that
/// straddled a release point waited for the later window with all its frames, so with 10-frame windows shifted
/// by 7 and 4-frame chunks the per-anchor job ended with 8 frames to position after its last window instead
/// of 6, one core idle during the tail. The frames of each chunk are positioned independently, so any cut
/// gives the same outputs.
pub fn position_chunks(n: usize, windows: &[Window], size: usize) -> Vec<Range<usize>> {
    // Frame t's last window: the last one starting at or before t (windows are in frame order).
    let last_window = |t: usize| windows.iter().rposition(|w| w.start <= t);
    let mut out = Vec::new();
    let mut start = 0;
    for t in 1..=n {
        if t == n || last_window(t) != last_window(start) {
            out.extend(
                chunk_ranges(t - start, size)
                    .into_iter()
                    .map(|r| r.start + start..r.end + start),
            );
            start = t;
        }
    }
    out
}

/// Windows of a job over `n` frames.
pub fn job_windows(job: &JobSpec, n: usize) -> Vec<Window> {
    let p = job.params();
    plan_windows(n, p.window, p.shift)
}

/// Number of anchor blocks of each window, given the anchors per frame.
pub fn blocks_per_window(job: &JobSpec, counts: &[usize]) -> Vec<usize> {
    let p = job.params();
    job_windows(job, counts.len())
        .iter()
        .map(|w| {
            let anchors: usize = counts[w.start..w.end()].iter().sum();
            plan_blocks(anchors, p.anchor_block).len()
        })
        .collect()
}

/// Triangle-frames per tracing task when the job does not say: about 20 frames at 100K triangles.
const TRIANGLE_FRAMES_PER_TASK: usize = 2_000_000;

/// Frames per tracing chunk: the job's `partition.stretch_frames_per_chunk`, or (0) from the triangle count
/// (4..=64 frames), no more than half the sequence so that two workers share even a short one.
pub fn trace_frames_per_chunk(job: &JobSpec, n_frames: usize, n_triangles: usize) -> usize {
    match job.partition.stretch_frames_per_chunk {
        0 => (TRIANGLE_FRAMES_PER_TASK / n_triangles.max(1))
            .clamp(4, 64)
            .min(n_frames.div_ceil(2))
            .max(1),
        k => k,
    }
}

/// The tracing chunks of the job.
pub fn trace_chunks(job: &JobSpec, n_frames: usize, n_triangles: usize) -> Vec<Range<usize>> {
    chunk_ranges(n_frames, trace_frames_per_chunk(job, n_frames, n_triangles))
}

/// The step chunks of the job: four tracing chunks' worth of frames each, but no more than half the sequence.
/// Every later task of the job waits for the steps, so a short sequence in one step chunk kept all workers but
/// one idle at the start of the job; split in two, two workers share them. Any chunking gives the same bits.
pub fn step_chunks(job: &JobSpec, n_frames: usize, n_triangles: usize) -> Vec<Range<usize>> {
    let per_chunk = 4 * trace_frames_per_chunk(job, n_frames, n_triangles);
    chunk_ranges(n_frames, per_chunk.min(n_frames.div_ceil(2)).max(1))
}

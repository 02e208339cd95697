//! Temporal coherence of detected folds split into tasks: the detector's whole-sequence settle
//! ([`crease_core::folds::temporal`]) becomes one `fold-settle` task per frame range, between the detection
//! tasks and the expanding `fold-merge`:
//!
//! ```text
//!   fold-detect (chunks) ─► fold-settle (ranges; each reads its range ± radius) ─► fold-merge (concatenates)
//! ```
//!
//! Settling frame `t` reads only the detected anchors and meshes of frames `t ± radius`
//! ([`crease_core::folds::temporal::settle_range`]), so each range depends only on the detection tasks whose
//! chunks overlap its input window, and the ranges give the whole settle's bits for any split. The settle was
//! most of `fold-merge`, the one task every deformation task waits for; split, it runs on all workers.
//!
//! Stretch folds: the tracing chunks are what the merge's reconcile gives unless a chunk's warm-up missed the
//! true seed memory (only with `seed_memory`, which is off by default). A settle task settles the chunks as
//! traced; the merge reconciles as before and settles again, from the reconciled frames, only the ranges whose
//! input window holds a frame it traced again, so the output stays exact either way.

use crate::keys;
use crate::plan::chunk_ranges;
use crate::spec::{FoldSpec, JobSpec};
use crate::task::{TaskDef, TaskSpec};
use crease_core::folds::temporal::settle_input;
use std::ops::Range;

/// The temporal radius of the job's settle when its detector settles its anchors over time and the settle
/// changes something (`None`: no settle tasks; the merge gathers the detection's anchors as they are). It is
/// what the detector's own `settle` uses: both the stretch and the video detector call
/// [`crease_core::folds::temporal::settle`] with their parameters' `temporal_radius`.
pub fn settle_radius(job: &JobSpec, n_frames: usize) -> Option<usize> {
    let radius = match &job.folds {
        FoldSpec::Stretch { params, .. } => params.temporal_radius,
        FoldSpec::Video { params, .. } => params.temporal_radius,
        _ => return None,
    };
    (radius > 0 && n_frames >= 2).then_some(radius)
}

/// Frames per settle task: `partition.settle_frames_per_chunk`, or (0) `detect_chunk` (the detection's chunk
/// size) but at most half the sequence, so that two workers share even a short one.
fn frames_per_chunk(job: &JobSpec, n_frames: usize, detect_chunk: usize) -> usize {
    match job.partition.settle_frames_per_chunk {
        0 => detect_chunk.min(n_frames.div_ceil(2)).max(1),
        k => k,
    }
}

/// The job's settle ranges over `n_frames` frames detected in chunks of `detect_chunk` frames (empty when the
/// job has no settle tasks, see [`settle_radius`]).
pub fn settle_chunks(job: &JobSpec, n_frames: usize, detect_chunk: usize) -> Vec<Range<usize>> {
    if settle_radius(job, n_frames).is_none() {
        return Vec::new();
    }
    chunk_ranges(n_frames, frames_per_chunk(job, n_frames, detect_chunk))
}

/// The settle ranges of the job as its tasks see them: `n_triangles` is the traced (input) mesh's for stretch
/// folds (it sets the tracing chunk size), unused otherwise.
pub fn job_settle_chunks(job: &JobSpec, n_frames: usize, n_triangles: usize) -> Vec<Range<usize>> {
    let detect_chunk = match &job.folds {
        FoldSpec::Stretch { .. } => {
            crate::stretch_tasks::trace_frames_per_chunk(job, n_frames, n_triangles)
        }
        _ => job.partition.fold_frames_per_chunk,
    };
    settle_chunks(job, n_frames, detect_chunk)
}

/// The detection chunks (of `detected`, in frame order) a settle of `range` reads: those overlapping its input
/// window.
pub fn inputs_of(
    range: &Range<usize>,
    n_frames: usize,
    radius: usize,
    detected: &[Range<usize>],
) -> Vec<Range<usize>> {
    let need = settle_input(range.clone(), n_frames, radius);
    detected
        .iter()
        .filter(|c| c.start < need.end && need.start < c.end)
        .cloned()
        .collect()
}

/// The settle tasks of a job whose detection tasks are `detect` (frame range and task key, in frame order):
/// one per settle range, each depending on the detection tasks its input window overlaps.
pub fn tasks(
    job: &JobSpec,
    n_frames: usize,
    n_triangles: usize,
    detect: &[(Range<usize>, String)],
) -> Vec<TaskDef> {
    let Some(radius) = settle_radius(job, n_frames) else {
        return Vec::new();
    };
    let chunks: Vec<Range<usize>> = detect.iter().map(|(r, _)| r.clone()).collect();
    job_settle_chunks(job, n_frames, n_triangles)
        .into_iter()
        .map(|r| {
            let deps = inputs_of(&r, n_frames, radius, &chunks)
                .iter()
                .filter_map(|c| detect.iter().find(|(d, _)| d == c).map(|(_, k)| k.clone()))
                .collect();
            TaskDef {
                key: keys::fold_settle_task(r.start),
                spec: TaskSpec::FoldSettle {
                    job: job.clone(),
                    frames: r,
                },
                deps,
                expands: false,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn job(folds: &str, partition: &str) -> JobSpec {
        JobSpec::from_toml_str(&format!(
            "input = \"/in\"\noutput = \"/out\"\n[folds]\n{folds}\n[partition]\n{partition}\n"
        ))
        .unwrap()
    }

    #[test]
    fn settle_ranges_depend_on_the_detection_chunks_their_window_reads() {
        let j = job(
            "kind = \"video\"\ncameras = \"/c.json\"",
            "fold_frames_per_chunk = 4",
        );
        // 11 frames detected in chunks of 4: settle ranges of 4 (at most half the sequence), radius 2.
        assert_eq!(settle_radius(&j, 11), Some(2));
        let detect: Vec<(Range<usize>, String)> = chunk_ranges(11, 4)
            .into_iter()
            .map(|r| (r.clone(), keys::fold_detect_task(r.start)))
            .collect();
        let t = tasks(&j, 11, 0, &detect);
        let ranges: Vec<Range<usize>> = t
            .iter()
            .map(|t| match &t.spec {
                TaskSpec::FoldSettle { frames, .. } => frames.clone(),
                _ => panic!("{:?}", t.spec),
            })
            .collect();
        assert_eq!(ranges, [0..4, 4..8, 8..11]);
        // 0..4 reads 0..6 (chunks 0..4, 4..8); 4..8 reads 2..10 (all three); 8..11 reads 6..11.
        assert_eq!(t[0].deps, ["folds/f000000", "folds/f000004"]);
        assert_eq!(t[1].deps.len(), 3);
        assert_eq!(t[2].deps, ["folds/f000004", "folds/f000008"]);
        assert_eq!(t[1].key, "folds/settle/f000004");
        // A settle that changes nothing has no tasks; a given size overrides the detection's.
        let none = job(
            "kind = \"video\"\ncameras = \"/c.json\"\n[folds.params]\ntemporal_radius = 0",
            "",
        );
        assert_eq!(settle_radius(&none, 11), None);
        assert!(tasks(&none, 11, 0, &detect).is_empty());
        assert!(
            settle_chunks(&j, 1, 4).is_empty(),
            "one frame: nothing to settle"
        );
        let sized = job(
            "kind = \"video\"\ncameras = \"/c.json\"",
            "settle_frames_per_chunk = 5",
        );
        assert_eq!(settle_chunks(&sized, 11, 8), [0..5, 5..10, 10..11]);
        assert_eq!(
            settle_chunks(&job("kind = \"stretch\"", ""), 7, 3),
            [0..3, 3..6, 6..7]
        );
        assert_eq!(settle_radius(&job("kind = \"none\"", ""), 7), None);
    }
}

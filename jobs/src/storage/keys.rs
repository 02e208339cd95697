//! Deterministic names: task keys within a job and storage keys under the job's output.
//!
//! Everything a task writes is named after the job and the task alone (never a worker, an attempt or a time),
//! so a task that runs twice — after a lost worker, a coordinator restart or a late duplicate — overwrites the
//! same objects with the same bytes, and a finished task's results are found again after a restart.

/// Intermediates live here, under the output root, so they can be opened with NumPy and deleted as a whole.
pub const WORK_DIR: &str = ".crease-work";
/// Written last by the finalize task: its presence says the output is complete.
pub const REPORT: &str = "report.json";
pub const PREVIEW: &str = "preview.png";
pub const STRETCH_PLOT: &str = "stretch.png";
/// Detected anchors (fold detection jobs only).
pub const ANCHORS: &str = "anchors.json";
/// Control lines of the detected folds as OBJ polylines (fold detection jobs only).
pub const CONTROL_LINES: &str = "folds/control_lines.obj";
/// The detected anchors as the job's own tasks read them: the binary form of `anchors.json`
/// (`crease_core::folds::anchors::binary`), the same values bit for bit without a decimal round trip.
pub const ANCHORS_BIN: &str = ".crease-work/folds/anchors.bin";
/// What the detection found beyond the anchors (JSON; finalize copies it into `report.json`).
pub const FOLD_SUMMARY: &str = ".crease-work/folds/summary.json";

// Task keys.
pub fn fold_detect_task(first_frame: usize) -> String {
    format!("folds/f{first_frame:06}")
}
pub const FOLD_MERGE_TASK: &str = "folds/merge";
/// Writes the user-facing fold files (`anchors.json`, `folds/control_lines.obj`) from `anchors.bin`, beside
/// the deformation tasks rather than before them.
pub const FOLD_FILES_TASK: &str = "folds/files";
/// Draws a stretch job's `folds.png` from the tracing chunks, beside the settle, merge and deformation tasks.
pub const FOLD_PLOT_TASK: &str = "folds/plot";
pub fn fold_steps_task(first_frame: usize) -> String {
    format!("folds/steps/f{first_frame:06}")
}
pub const FOLD_PHASES_TASK: &str = "folds/phases";
/// Temporal coherence (the detector's settle) of the frames starting at `first_frame`.
pub fn fold_settle_task(first_frame: usize) -> String {
    format!("folds/settle/f{first_frame:06}")
}
pub fn weight_window_task(window: usize) -> String {
    format!("weights/w{window:04}")
}
pub fn weight_block_task(window: usize, block: usize) -> String {
    format!("weights/w{window:04}/b{block:05}")
}
pub fn reduce_task(window: usize) -> String {
    format!("reduce/w{window:04}")
}
/// The fold relief of the frames starting at `first_frame`.
pub fn relief_task(first_frame: usize) -> String {
    format!("relief/f{first_frame:06}")
}
pub fn position_task(first_frame: usize) -> String {
    format!("position/f{first_frame:06}")
}
pub const FINALIZE_TASK: &str = "finalize";

// Storage keys of intermediates.
/// Detected anchors of the frames starting at `first_frame` (`FrameAnchors` in the binary anchors form).
pub fn fold_chunk(first_frame: usize) -> String {
    format!("{WORK_DIR}/folds/f{first_frame:06}.bin")
}
/// Seconds the detection of the chunk starting at `first_frame` took (sidecar; differs between runs).
pub fn fold_chunk_timing(first_frame: usize) -> String {
    format!("{WORK_DIR}/folds/f{first_frame:06}.timings.json")
}
/// Stretch detector: step records of frame `frame`, (n_triangles, 4) f64 (forward value and angle, backward
/// value and angle).
pub fn fold_steps(frame: usize) -> String {
    format!("{WORK_DIR}/folds/steps/f{frame:06}.npy")
}
/// Stretch detector: phase codes of frame `frame` in one pass (`fwd` or `bwd`), (n_triangles,) u32.
pub fn fold_phases(pass: &str, frame: usize) -> String {
    format!("{WORK_DIR}/folds/phases/{pass}/f{frame:06}.npy")
}
/// Stretch detector: the tracing chunk starting at `first_frame` (a `TracedChunk` in the binary anchors form).
pub fn fold_trace_chunk(first_frame: usize) -> String {
    format!("{WORK_DIR}/folds/trace/f{first_frame:06}.bin")
}
/// Stretch detector: what `folds.png` draws of overlay frame `frame` (positions, fold signal, anchors as traced),
/// kept by the tracing task that traced it (`execute::stretch::overlay_to_npy`).
pub fn fold_overlay(frame: usize) -> String {
    format!("{WORK_DIR}/folds/overlay/f{frame:06}.npy")
}
/// Settled anchors of the frames starting at `first_frame` (`FrameAnchors` in the binary anchors form), as the
/// whole-sequence settle gives them for those frames.
pub fn fold_settled(first_frame: usize) -> String {
    format!("{WORK_DIR}/folds/settled/f{first_frame:06}.bin")
}
/// One anchor block's result: its partial blend and CG statistics in one object (`CREASEPB`, see
/// `execute::partial_file`).
pub fn block_partial(window: usize, block: usize) -> String {
    format!("{WORK_DIR}/weights/w{window:04}/b{block:05}.bin")
}
/// Frame `frame` of window `window`'s rotation-vector field: (n_triangles, 3) f64.
pub fn window_field(window: usize, frame: usize) -> String {
    format!("{WORK_DIR}/fields/w{window:04}/f{frame:06}.npy")
}
/// Statistics of window `window`'s weight solve (JSON `WindowStats`).
pub fn window_stats(window: usize) -> String {
    format!("{WORK_DIR}/fields/w{window:04}/stats.json")
}
/// The fold relief of captured frame `frame` (`crease_core::spacetime::shape::relief::frame_relief`):
/// (n_vertices,) f64.
pub fn relief(frame: usize) -> String {
    format!("{WORK_DIR}/relief/f{frame:06}.npy")
}
/// Output positions of frame `frame`: (n_vertices, 3) f64.
pub fn positions(frame: usize) -> String {
    format!("{WORK_DIR}/positions/f{frame:06}.npy")
}
/// Stretch accumulators of frame `frame` after positioning and each pass, then its shape accumulator (u64
/// words, see `crease_core::metrics::StretchAccumulator::to_words` and `crease_core::shape::ShapeAccumulator`).
pub fn frame_stretch(frame: usize) -> String {
    format!("{WORK_DIR}/positions/f{frame:06}.stretch.npy")
}
/// Timings of frame `frame`'s positioning (JSON; the only intermediate whose bytes differ between runs).
pub fn frame_timings(frame: usize) -> String {
    format!("{WORK_DIR}/positions/f{frame:06}.timings.json")
}

//! crease-jobs: job specs, planning (job → task graph), storage and task execution on top of crease-core.
//!
//! This crate holds everything about a job that does not depend on the transport: the coordinator calls
//! [`inspect_input`] at submit, [`plan()`] / [`expand`] to build the task graph and [`final_outputs`] before marking
//! a job done; workers call [`execute()`]. No gRPC here, so the same code runs in-process in tests.
//!
//! # Job spec
//!
//! A job is a TOML (or JSON) document. Only `input` and `output` are required; every other field defaults to
//! what `crease run` does (the paper's parameters), so a two-line job deforms exactly like `crease run`.
//!
//! ```
//! let job = crease_jobs::JobSpec::from_toml_str(r#"
//! name = "sleeve take 3"
//! input = "/data/capture/sleeve"          # plain path, file://…, s3://bucket/…
//! output = "file:///data/out/sleeve"
//! priority = 10                            # higher first; FIFO within a priority
//! client_token = "sleeve-take-3"           # submitting again with this token returns the same job
//! max_task_attempts = 3                    # attempts of one task before the job fails
//! max_task_failures_per_job = 10           # failed attempts over all tasks before the job fails
//!
//! [folds]                                  # or: kind = "none", "stretch", "video" (see FoldSpec)
//! kind = "anchors"
//! uri = "/data/capture/sleeve-anchors.json"
//!
//! [deform]                                 # any DeformParams field; these are the defaults
//! mode = "per-anchor"                      # or "fused" (default)
//! window = 10
//! shift = 7
//! cg_tolerance = 1e-3
//! stretch_passes = 2
//!
//! [partition]
//! anchor_block = 256                       # anchor columns per weight task (per-anchor mode)
//! frames_per_chunk = 4                     # at most this many frames per positioning task
//! fold_frames_per_chunk = 8                # frames per fold-detection task (per-frame detectors)
//! stretch_frames_per_chunk = 0             # frames per stretch tracing task (0: from the mesh size)
//! stretch_warm_up = 3                      # frames a stretch tracing task traces ahead (same output)
//! settle_frames_per_chunk = 0              # frames per fold-settle task (0: the detection's chunks; same output)
//!
//! [preview]
//! frames = [5, 20]                         # default: four spread over the sequence
//! size = 384
//!
//! [tuning]                                 # any tuning key (docs/tuning.md, `crease tuning`), set over
//! deform.strain_limit = 0.03               # the tables above: the same keys `crease run --set` takes
//! "#).unwrap();
//! assert_eq!(job.params().anchor_block, 256);
//! assert_eq!(job.deform.strain_limit, 0.03);
//! ```
//!
//! Errors name the field: `job spec: \`partition.anchor_block\`: …`, `input /data/x: …`.
//!
//! URIs: plain paths (relative ones resolve against the current directory of the process that reads the
//! spec), `file://…`, `s3://bucket/prefix` (S3 or any S3-compatible server, configured by the `AWS_*`
//! environment, see [`s3`]), plus `memory://<name>/…` for process-wide in-memory stores (in-process runs and
//! tests of the remote path). Remote URIs with `..`, `.`, empty or percent-encoded separator segments are
//! refused (see [`confine`]).
//! Remote inputs are fetched once into the worker's cache; remote outputs are staged there and uploaded.
//!
//! # Task graph
//!
//! See [`plan`](crate::plan()): per-anchor mode plans one `weight-block` task per (window, anchor block) and a
//! `reduce` per window that sums the blocks' partial blends in block order; fused mode plans one
//! `weight-window` task per window. Each `position` task (a chunk of frames) depends on every window covering
//! its frames; `finalize` depends on all positioning tasks. When folds are detected, `fold-detect` tasks (one per
//! frame chunk, or one for the whole sequence, as [`FoldDetector::granularity`](crease_core::folds::FoldDetector)
//! says) and a `fold-merge` task come first; `fold-merge` is marked `expands` and [`expand`] adds the rest once
//! the anchor counts are known, with a `fold-files` task that writes the user-facing anchor files beside the
//! weight tasks (finalize waits for it); a stretch job's `folds.png` is drawn by a `fold-plot` task that waits
//! only for the tracing chunks. Adding a detector is one match arm in [`detect::detector`].
//!
//! # Storage layout (all keys relative to the job's `output`)
//!
//! | key | written by | content |
//! | --- | --- | --- |
//! | `<input file names>` | position (OBJ/PLY frames), finalize (OBJ + PC2) | the output sequence in the input's layout |
//! | `anchors.json`, `folds/control_lines.obj` | fold-files | detected anchors and their control lines (detection jobs only) |
//! | `folds.png` | fold-plot | stretch jobs: the overlay frames' fold signal and anchors |
//! | `preview.png`, `stretch.png` | finalize | before/after preview, stretch per frame and pass |
//! | `export/<job name>.glb`, `.usda`, `.mdd`, `.pc2` | finalize | the `[export]` formats ([`export_spec`]) |
//! | `report.json` | finalize, **last** | `"complete": true`, parameters, per-window stats, stretch, timings |
//! | `.crease-work/folds/anchors.bin` | fold-merge | the detected anchors as the later tasks read them (binary, docs/formats.md) |
//! | `.crease-work/folds/fFFFFFF.bin`, `folds/trace/fFFFFFF.bin` | fold-detect | a detection or tracing chunk's anchors (binary) |
//! | `.crease-work/weights/wWWWW/bBBBBB.bin` | weight-block | partial blend and CG statistics (`CREASEPB`: u32 nodes, f64 values) |
//! | `.crease-work/fields/wWWWW/fFFFFFF.npy` | weight-window / reduce | window field at one frame, (triangles, 3) f64 |
//! | `.crease-work/positions/fFFFFFF.npy` | position | output positions, (vertices, 3) f64 |
//! | `.crease-work/positions/fFFFFFF.stretch.npy` | position | exact stretch accumulators (u64 words) |
//! | `.crease-work/**.json` | all | statistics and timings sidecars |
//!
//! Keys depend only on the job and the task, and every `.npy` and output file is a pure function of the
//! task's inputs, so a task that runs twice (lost worker, restart, late duplicate) writes the same bytes.
//! Timings in the `.json` sidecars, in a block result's header and in `report.json` are the only bytes that
//! differ between runs. Puts are atomic (staged file + rename locally, whole-object puts remotely; a task writes
//! a local output on its own thread, see [`Storage::put_local`]). A stale `report.json` from an earlier
//! run into the same output is removed when the job is submitted (coordinator) and again when `finalize`
//! starts; `finalize` checks that every output file exists and writes the report last, so a report is only ever
//! present next to complete outputs. Positioning tasks never delete it: a late duplicate of one after the job
//! finished rewrites identical frame bytes and leaves the report alone.
//!
//! # Failures
//!
//! Storage failures are classified ([`storage_errors`]): a full volume or quota (ENOSPC, EDQUOT, S3 `507`) is
//! "storage full at <uri>" and not retryable (the worker's own cache or staging disk excepted: another worker
//! may have room); an endpoint that cannot be reached within the configured retries is "storage unreachable
//! at <uri> (endpoint …)" and retryable. Either way `finalize` never runs or fails before its report, so a
//! half-written output is never marked complete.
//!
//! [`TaskError::kind`] is a [`FailureKind`]; its policy says whether another attempt may help (and
//! [`TaskError::retryable`] reads it): I/O and storage errors are retryable; bad
//! data (a NaN in a frame, a malformed intermediate, anchors that do not fit), bad parameters and numerical
//! failures are not, and their reason names the file, frame, window or block. A task stopped through
//! [`Progress::cancelled`](crease_core::progress::Progress::cancelled) returns [`TaskError::cancelled`]
//! (retryable: the work itself was fine, e.g. a worker handing its task back at shutdown).
//!
//! # Determinism
//!
//! Every task calls the same [`crease_core::spacetime::stages`] functions that `crease_core::spacetime::deform`
//! is built on, summing blocks in block order and windows in window order, so the output files are
//! byte-identical to a single-machine run whatever the number of workers, the order tasks ran in, or the
//! partition sizes (the anchor block size is part of the arithmetic in per-anchor mode, as it is for `deform`).
//! `jobs/tests/pipeline.rs` checks this.

pub mod confine;
pub mod deep;
pub mod detect;
pub mod error;
pub mod execute;
pub mod export_spec;
pub mod failure;
pub mod farm;
pub mod inspect;
pub mod keys;
pub mod limits;
pub mod plan;
pub mod report;
pub mod s3;
pub mod settle_tasks;
pub mod spec;
pub mod stale;
pub mod storage;
pub mod storage_errors;
pub mod stretch_tasks;
pub mod task;
pub mod tuning;

pub use confine::StorageRoots;
pub use error::{JobError, TaskError};
pub use execute::{execute, frame_cache, phase_times, window_cache, ExecContext};
pub use failure::{FailureKind, Policy};
pub use inspect::{inspect_input, InputInfo};
pub use limits::JobLimits;
pub use plan::{expand, final_outputs, plan};
pub use spec::{FoldSpec, JobSpec, Partition, PreviewOptions};
pub use storage::{fetch_input_to_cache, Storage};
pub use task::{TaskDef, TaskOutput, TaskSpec};

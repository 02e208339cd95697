//! Planning: a job becomes a graph of tasks.
//!
//! - [`inspect`] — submit-time inspection of the input, anchors and output ([`input::InputInfo`]); [`limits`]
//!   admits a job within the coordinator's limits, [`stale`] claims its output;
//! - [`graph`] — the task graph: [`graph::plan`] at submit, [`graph::expand`] once detection is done, and the
//!   outputs a finished job must have;
//! - [`task`] — the tasks themselves, as the coordinator schedules and workers execute them;
//! - [`chunks`] — how frames are cut into task ranges; [`detect`] — the fold detector of a job and its
//!   granularity; [`stretch`] and [`settle`] — the stretch detector's and the temporal settle's tasks.

pub mod chunks;
pub mod detect;
pub mod graph;
pub mod input;
pub mod inspect;
pub mod limits;
pub mod settle;
pub mod stale;
pub mod stretch;
pub mod task;

pub use graph::{expand, final_outputs, plan};
pub use input::InputInfo;
pub use inspect::inspect_input;

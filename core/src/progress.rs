//! Progress reporting from long computations, without tying core to a terminal or a network.
//!
//! The CLI implements [`Progress`] with progress bars or log lines, a cluster worker with progress messages;
//! core only calls it.

/// Receives progress of named stages. All methods have no-op defaults.
pub trait Progress: Sync {
    /// A stage begins with `total` units of work.
    fn begin(&self, _stage: &str, _total: u64) {}
    /// `n` more units of `stage` are done.
    fn advance(&self, _stage: &str, _n: u64) {}
    /// The stage is over.
    fn end(&self, _stage: &str) {}
    /// A free-form note (warnings, summaries).
    fn note(&self, _msg: &str) {}
    /// Polled between units of work; returning true stops the computation with [`crate::Error::Cancelled`].
    fn cancelled(&self) -> bool {
        false
    }
}

/// Discards all progress.
pub struct NoProgress;
impl Progress for NoProgress {}

//! Where tasks spend their time, summed over every task this process ran: the weight-block phases (opening
//! the input and finding the window in the cache, building it on a miss, the solve, encoding and writing the
//! partial blend), the reduce's (reading the partials, summing them, writing the field) and `fold-merge`'s
//! (reconciling the tracing chunks, the overlay frames, temporal coherence and `folds.png`, the binary anchors).
//!
//! Why: a cluster run of the per-anchor mode is slower than the same solve in one process, and the difference
//! is spread over hundreds of short tasks; `fold-merge` is the longest link of a stretch job's chain that is not
//! tracing. `crease bench --cluster` and `crease bench --pipeline` run their tasks in-process and print these
//! sums, so fixed costs show up phase by phase. Adding a sample is one short lock per phase, negligible next to
//! a task.

use std::sync::Mutex;
use std::time::Instant;

/// (phase, samples, seconds), in the order phases were first seen.
static SUMS: Mutex<Vec<(&'static str, u64, f64)>> = Mutex::new(Vec::new());

/// Adds `seconds` to `phase`.
pub fn add(phase: &'static str, seconds: f64) {
    let mut sums = SUMS.lock().unwrap_or_else(|p| p.into_inner());
    match sums.iter_mut().find(|(p, _, _)| *p == phase) {
        Some(s) => {
            s.1 += 1;
            s.2 += seconds;
        }
        None => sums.push((phase, 1, seconds)),
    }
}

/// The sums so far, and starts again from zero.
pub fn take() -> Vec<(&'static str, u64, f64)> {
    std::mem::take(&mut *SUMS.lock().unwrap_or_else(|p| p.into_inner()))
}

/// Times consecutive phases: each [`Lap::lap`] records the time since the previous one under its name.
pub struct Lap(Instant);

impl Lap {
    pub fn start() -> Self {
        Lap(Instant::now())
    }

    pub fn lap(&mut self, phase: &'static str) {
        let now = Instant::now();
        add(phase, (now - self.0).as_secs_f64());
        self.0 = now;
    }
}

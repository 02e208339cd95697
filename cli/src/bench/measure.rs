//! What every benchmark measures with: medians, the process's peak memory and I/O counters, the synthetic
//! paper-scale case, and scratch directories.

use anyhow::Result;
use crease_core::folds::AnchorSet;
use crease_core::mesh::Sequence;
use crease_core::synth::{self, DemoSpec};
use std::path::PathBuf;

pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    if v.is_empty() {
        return f64::NAN;
    }
    let m = v.len() / 2;
    if v.len() % 2 == 1 {
        v[m]
    } else {
        0.5 * (v[m - 1] + v[m])
    }
}

/// Peak resident set size of this process in bytes (VmHWM), if the platform reports it.
pub fn peak_rss() -> Option<u64> {
    proc_field("/proc/self/status", "VmHWM:").map(|kb| kb * 1024)
}

/// Resets the kernel's peak-RSS mark (Linux `clear_refs` 5) so the next figure is the next run's own peak.
pub fn reset_peak_rss() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

/// Bytes this process has passed through read() and write() so far (`rchar`, `wchar` of /proc/self/io):
/// storage and input traffic of the tasks it runs, whether or not the page cache served it.
pub fn io_counters() -> Option<(u64, u64)> {
    Some((
        proc_field("/proc/self/io", "rchar:")?,
        proc_field("/proc/self/io", "wchar:")?,
    ))
}

fn proc_field(file: &str, name: &str) -> Option<u64> {
    let s = std::fs::read_to_string(file).ok()?;
    let line = s.lines().find(|l| l.starts_with(name))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

pub fn case_input(
    triangles: usize,
    frames: usize,
    anchors: usize,
) -> Result<(Sequence, AnchorSet)> {
    let spec = DemoSpec {
        triangles,
        frames,
        ..Default::default()
    };
    let (seq, _) = synth::demo(&spec)?;
    let a = synth::random_anchors(&seq.topology, &seq.frames, anchors, 7)?;
    Ok((seq, a))
}

/// A scratch directory for benchmark files (under the system temporary directory).
pub fn scratch_dir() -> Result<PathBuf> {
    let dir = std::env::temp_dir().join(format!("crease-bench-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    crease_core::fsutil::create_dir_all(&dir)?;
    Ok(dir)
}

//! Parsed input frames kept per worker process, shared by the tasks that read the same opened input.
//!
//! Why: in a per-anchor job every positioning task reads its frames, the strain limiter reads every frame once
//! per process for its sequence reference, and finalize reads frames again for the previews. Each read parsed
//! the frame's file (an OBJ of 100K triangles is tens of milliseconds), where the in-process deformation reads
//! each frame once. The first read of a frame now keeps the parsed positions, and later reads through the same
//! opened input copy them.
//!
//! Safety: the cache lives inside the opened input ([`super::env::TaskEnv::open_input`]), which is reopened
//! (with an empty cache) as soon as any of the input's files changes size or modification time, so a frame is
//! never served from an input that changed on disk since a task opened it. Only frames that were read and
//! validated without error are kept; a failing read fails again the same way. A kept frame is the very vector the
//! wrapped source returned, so a task sees the same bits whether it hit or missed.
//!
//! Memory: a byte budget per opened input (`crease worker --frame-cache-mb`; 0 turns the cache off), least
//! recently read frames dropped first; the process keeps at most two opened inputs.

use crease_core::mesh::subdivide::Subdivision;
use crease_core::mesh::{Frame, FrameSource, Topology};
use crease_core::vec3::V3;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

/// Default byte budget of the frames kept for one opened input (`crease worker --frame-cache-mb`).
pub const DEFAULT_BUDGET_BYTES: u64 = 256 << 20;

static BUDGET: AtomicU64 = AtomicU64::new(DEFAULT_BUDGET_BYTES);

/// Sets the byte budget of the frames kept per opened input (0 turns the cache off). Inputs opened later use it;
/// an already opened input trims to it on its next read.
pub fn set_budget(bytes: u64) {
    BUDGET.store(bytes, Ordering::Relaxed);
}

/// The current byte budget.
pub fn budget() -> u64 {
    BUDGET.load(Ordering::Relaxed)
}

/// A frame source that keeps the frames it read (see the module docs).
pub struct CachedFrames {
    inner: Box<dyn FrameSource>,
    kept: Mutex<Kept>,
}

#[derive(Default)]
struct Kept {
    /// (frame, last use, positions), in no particular order.
    frames: Vec<(usize, u64, Arc<Frame>)>,
    bytes: u64,
    clock: u64,
    hits: u64,
    misses: u64,
}

fn frame_bytes(f: &Frame) -> u64 {
    (f.len() * std::mem::size_of::<V3>()) as u64
}

impl CachedFrames {
    pub fn new(inner: Box<dyn FrameSource>) -> Self {
        CachedFrames {
            inner,
            kept: Mutex::new(Kept::default()),
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Kept> {
        self.kept.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// (frames kept, bytes kept, hits, misses), for logs and tests.
    pub fn usage(&self) -> (usize, u64, u64, u64) {
        let k = self.lock();
        (k.frames.len(), k.bytes, k.hits, k.misses)
    }
}

impl Kept {
    /// Drops least recently used frames until `bytes` fit under `budget`.
    fn trim(&mut self, budget: u64) {
        while self.bytes > budget && !self.frames.is_empty() {
            let oldest = self
                .frames
                .iter()
                .enumerate()
                .min_by_key(|(_, (_, used, _))| *used)
                .map(|(i, _)| i)
                .unwrap_or(0);
            let (_, _, f) = self.frames.swap_remove(oldest);
            self.bytes -= frame_bytes(&f);
        }
    }
}

impl FrameSource for CachedFrames {
    fn topology(&self) -> &Arc<Topology> {
        self.inner.topology()
    }

    fn n_frames(&self) -> usize {
        self.inner.n_frames()
    }

    fn read_frame(&self, t: usize) -> crease_core::Result<Frame> {
        let budget = budget();
        {
            let mut k = self.lock();
            // A budget lowered since the last read applies now.
            k.trim(budget);
            k.clock += 1;
            let now = k.clock;
            if let Some(e) = k.frames.iter_mut().find(|(f, ..)| *f == t) {
                e.1 = now;
                let frame = Arc::clone(&e.2);
                k.hits += 1;
                drop(k);
                return Ok(Frame::clone(&frame));
            }
            k.misses += 1;
        }
        // Read outside the lock: tasks reading other frames need not wait.
        let frame = self.inner.read_frame(t)?;
        let size = frame_bytes(&frame);
        if size <= budget {
            let mut k = self.lock();
            if !k.frames.iter().any(|(f, ..)| *f == t) {
                k.clock += 1;
                let now = k.clock;
                k.frames.push((t, now, Arc::new(frame.clone())));
                k.bytes += size;
            }
            k.trim(budget);
        }
        Ok(frame)
    }

    fn describe_frame(&self, t: usize) -> String {
        self.inner.describe_frame(t)
    }

    fn subdivided_from(&self) -> Option<(&dyn FrameSource, &Subdivision)> {
        self.inner.subdivided_from()
    }
}

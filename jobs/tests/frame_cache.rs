//! The worker's frame cache (`crease_jobs::frame_cache`): parsed input frames are read once within the budget,
//! the least recently read go first, failing reads are never kept, and budget 0 keeps nothing. One test
//! function: the budget is per process.

use crease_core::mesh::{Frame, FrameSource, Topology};
use crease_core::vec3::V3;
use crease_jobs::frame_cache::{set_budget, CachedFrames, DEFAULT_BUDGET_BYTES};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

/// Four vertices, two triangles; frame t has every coordinate equal to t; frame 3 is unreadable.
struct Counting {
    topo: Arc<Topology>,
    reads: Arc<AtomicUsize>,
}

impl FrameSource for Counting {
    fn topology(&self) -> &Arc<Topology> {
        &self.topo
    }
    fn n_frames(&self) -> usize {
        4
    }
    fn read_frame(&self, t: usize) -> crease_core::Result<Frame> {
        self.reads.fetch_add(1, Ordering::Relaxed);
        if t == 3 {
            return Err(crease_core::Error::mesh("frame 3 is broken"));
        }
        Ok(vec![[t as f64; 3]; 4])
    }
    fn describe_frame(&self, t: usize) -> String {
        format!("frame {t}")
    }
}

fn counting() -> (CachedFrames, Arc<AtomicUsize>) {
    let topo = Arc::new(Topology::new(4, vec![[0, 1, 2], [0, 2, 3]]).unwrap());
    let reads = Arc::new(AtomicUsize::new(0));
    let inner = Box::new(Counting {
        topo,
        reads: reads.clone(),
    });
    (CachedFrames::new(inner), reads)
}

// One test: the budget is per process.
#[test]
fn frames_are_read_once_within_the_budget_and_errors_are_not_kept() {
    let (cache, count) = counting();
    let reads = || count.load(Ordering::Relaxed);
    let frame = 4 * std::mem::size_of::<V3>() as u64;

    set_budget(2 * frame);
    assert_eq!(cache.read_frame(0).unwrap(), vec![[0.0; 3]; 4]);
    assert_eq!(cache.read_frame(0).unwrap(), vec![[0.0; 3]; 4]);
    assert_eq!(
        reads(),
        1,
        "the second read of frame 0 is served from the cache"
    );
    assert_eq!(cache.usage(), (1, frame, 1, 1));

    // A third frame over a two-frame budget drops the least recently read one (frame 1, not 0).
    cache.read_frame(1).unwrap();
    cache.read_frame(0).unwrap();
    cache.read_frame(2).unwrap();
    assert_eq!(reads(), 3);
    assert_eq!(cache.usage().0, 2);
    assert_eq!(cache.read_frame(0).unwrap(), vec![[0.0; 3]; 4]);
    assert_eq!(cache.read_frame(2).unwrap(), vec![[2.0; 3]; 4]);
    assert_eq!(reads(), 3, "frames 0 and 2 stayed");
    assert_eq!(cache.read_frame(1).unwrap(), vec![[1.0; 3]; 4]);
    assert_eq!(reads(), 4, "frame 1 was dropped and is read again");

    // A failing read fails every time and keeps nothing.
    for _ in 0..2 {
        let e = cache.read_frame(3).unwrap_err().to_string();
        assert!(e.contains("frame 3 is broken"), "{e}");
    }
    assert_eq!(reads(), 6);
    assert!(cache.usage().1 <= 2 * frame);

    // Budget 0: nothing is kept (and what was kept is dropped on the next read).
    set_budget(0);
    cache.read_frame(0).unwrap();
    cache.read_frame(0).unwrap();
    assert_eq!(cache.usage().0, 0);
    set_budget(DEFAULT_BUDGET_BYTES);
    assert_eq!(cache.describe_frame(2), "frame 2");
    assert_eq!(cache.n_frames(), 4);
}

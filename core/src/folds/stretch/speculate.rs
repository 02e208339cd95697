//! Tracing several seeds of one frame at once, with the sequential result.
//!
//! Seeds are taken from the priority queue one at a time, and a fold consumes the seeds in its region of
//! influence, so which seeds are tried depends on the folds before them. But what one seed gives — its patch,
//! flattening, axis, control lines and region — reads only the frame. So the queue looks ahead: when the seed
//! it must trace next has not been traced yet, it also traces, in parallel, later seeds that no fold before them
//! could consume, and keeps their outcomes until their turn comes. Seeds are still committed strictly in queue
//! order, and one consumed before its turn is skipped (its outcome discarded), so folds, seeds tried and seed
//! memory are those of the one-at-a-time loop for any number of threads.
//!
//! A fold's region lies inside its seed's patch: the triangles whose centroids are within `patch_radius` edge
//! lengths of the seed's. Seeds chosen together are kept farther apart than that, so none of them can consume
//! another; only seeds passed over in between can, and those are few.

use super::params::StretchParams;
use super::symbolic::SymbolicCache;
use super::trace::{FrameField, Outcome, SeedWork};
use crate::mesh::Topology;
use crate::vec3::{self, V3};
use rayon::prelude::*;
use std::collections::{HashMap, VecDeque};
use std::sync::{Arc, Mutex};

/// Queue entry: (seed of the previous frame, priority, `Reverse(triangle)`) packed into one integer, so that
/// the frame's queue sorts by plain integer comparisons (the tuple's three-way comparisons were a twentieth of
/// tracing at 25K triangles): the flag in bit 96, the priority in bits 32..96 and `u32::MAX − triangle` below,
/// which orders exactly as the tuple does. Largest first.
pub(super) type Entry = u128;

/// The queue entry of `triangle` (see [`Entry`]).
#[inline]
pub(super) fn entry(memory: bool, priority: u64, triangle: u32) -> Entry {
    ((memory as u128) << 96) | ((priority as u128) << 32) | (u32::MAX - triangle) as u128
}

/// The triangle of a queue entry.
#[inline]
fn entry_triangle(e: Entry) -> u32 {
    u32::MAX - e as u32
}

/// Queue entries looked at past the next seed when choosing seeds to trace ahead, and seeds traced together
/// per thread. They decide only how much is traced ahead (and so how busy the threads are), never the
/// result.
const LOOKAHEAD: usize = 64;
const BATCH_PER_THREAD: usize = 2;

/// Patch patterns whose symbolic factorisation is kept ([`SymbolicCache`]), per generation.
const PATTERNS_PER_GENERATION: usize = 1024;

/// Per-thread scratch for [`SeedWork`], created on demand and reused across seeds and frames.
pub(super) struct SeedPool {
    free: Mutex<Vec<SeedWork>>,
    pub(super) patterns: Arc<SymbolicCache>,
    n_triangles: usize,
    n_vertices: usize,
    levels: usize,
}

impl SeedPool {
    pub(super) fn new(topo: &Topology, levels: usize) -> Self {
        SeedPool {
            free: Mutex::new(Vec::new()),
            patterns: Arc::new(SymbolicCache::new(PATTERNS_PER_GENERATION)),
            n_triangles: topo.n_triangles(),
            n_vertices: topo.n_vertices(),
            levels,
        }
    }

    fn take(&self) -> SeedWork {
        let work = self.free.lock().map(|mut v| v.pop()).unwrap_or(None);
        work.unwrap_or_else(|| {
            SeedWork::new(
                self.n_triangles,
                self.n_vertices,
                self.levels,
                self.patterns.clone(),
            )
        })
    }

    fn put(&self, work: SeedWork) {
        if let Ok(mut v) = self.free.lock() {
            v.push(work);
        }
    }

    /// The outcomes of `seeds`, in order; in parallel when there are several.
    fn trace(
        &self,
        f: &FrameField,
        params: &StretchParams,
        centroid: V3,
        seeds: &[usize],
    ) -> Vec<Outcome> {
        let one = |s: usize| {
            let mut work = self.take();
            let out = work.trace_seed(f, params, s, centroid);
            self.put(work);
            out
        };
        if seeds.len() == 1 {
            vec![one(seeds[0])]
        } else {
            seeds.par_iter().with_max_len(1).map(|&s| one(s)).collect()
        }
    }
}

/// The seed queue of one frame with the outcomes traced ahead of their turn.
pub(super) struct SeedQueue {
    /// The entries not taken yet, largest first.
    order: std::vec::IntoIter<Entry>,
    /// Entries taken from `order` but not yet handed out, in queue order.
    ahead: VecDeque<u32>,
    ready: HashMap<u32, Outcome>,
    /// Seeds traced together: 1 traces one seed at a time (no look-ahead).
    batch: usize,
    /// Queue entries looked at when choosing seeds to trace ahead.
    lookahead: usize,
    /// Seeds traced ahead of their turn, and those of them discarded because their seed was consumed first.
    pub traced_ahead: usize,
    pub wasted: usize,
}

impl SeedQueue {
    /// A queue handing out `order` (sorted largest first) front to back.
    pub(super) fn new(order: Vec<Entry>) -> Self {
        let threads = rayon::current_num_threads();
        SeedQueue {
            order: order.into_iter(),
            ahead: VecDeque::new(),
            ready: HashMap::new(),
            batch: if threads > 1 { BATCH_PER_THREAD * threads } else { 1 },
            lookahead: LOOKAHEAD,
            traced_ahead: 0,
            wasted: 0,
        }
    }

    /// The next seed in queue order that is not consumed yet.
    pub(super) fn next(&mut self, consumed: &[bool]) -> Option<usize> {
        loop {
            let s = match self.ahead.pop_front() {
                Some(s) => s,
                None => entry_triangle(self.order.next()?),
            };
            if !consumed[s as usize] {
                return Some(s as usize);
            }
            if self.ready.remove(&s).is_some() {
                self.wasted += 1;
            }
        }
    }

    /// What seed `s` (just handed out by [`Self::next`]) gives: traced ahead already, or now, together with
    /// later seeds that no fold before them can consume.
    pub(super) fn outcome(
        &mut self,
        s: usize,
        consumed: &[bool],
        pool: &SeedPool,
        f: &FrameField,
        params: &StretchParams,
        centroid: V3,
    ) -> Outcome {
        if let Some(out) = self.ready.remove(&(s as u32)) {
            return out;
        }
        let mut chosen = vec![s];
        if self.batch > 1 {
            while self.ahead.len() < self.lookahead {
                let Some(e) = self.order.next() else { break };
                self.ahead.push_back(entry_triangle(e));
            }
            // A seed's fold stays within its patch; a candidate closer than that to a seed before it that may
            // still give a fold (passed over, or traced ahead already) is left for its turn.
            let apart = params.patch_radius * f.h;
            let near = |a: usize, b: usize| {
                vec3::norm(vec3::sub(f.geom.centroids[a], f.geom.centroids[b])) <= apart
            };
            let mut passed: Vec<usize> = Vec::new();
            for &c in &self.ahead {
                if chosen.len() == self.batch {
                    break;
                }
                let c = c as usize;
                if consumed[c] {
                    continue;
                }
                if self.ready.contains_key(&(c as u32))
                    || chosen.iter().chain(&passed).any(|&o| near(o, c))
                {
                    passed.push(c);
                    continue;
                }
                chosen.push(c);
            }
        }
        self.traced_ahead += chosen.len() - 1;
        let mut outs = pool.trace(f, params, centroid, &chosen).into_iter();
        let mine = outs.next().expect("the seed itself");
        for (&c, out) in chosen[1..].iter().zip(outs) {
            self.ready.insert(c as u32, out);
        }
        mine
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Packed entries sort exactly as the (memory flag, priority, `Reverse(triangle)`) tuples they stand for,
    /// at the extremes of each field too, and give their triangle back.
    #[test]
    fn packed_entries_order_as_the_tuples() {
        use std::cmp::Reverse;
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let mut tuples: Vec<(bool, u64, Reverse<u32>)> = Vec::new();
        for k in 0..4000u32 {
            let r = next();
            let priority = match k % 4 {
                0 => r % 50,
                1 => u64::MAX - r % 3,
                _ => r,
            };
            let triangle = match k % 5 {
                0 => u32::MAX - (r % 2) as u32,
                1 => (r % 2) as u32,
                _ => (r >> 32) as u32,
            };
            tuples.push((r & 1 == 1, priority, Reverse(triangle)));
        }
        tuples.sort_unstable();
        tuples.dedup();
        let mut entries: Vec<Entry> = tuples
            .iter()
            .rev()
            .map(|&(m, p, Reverse(t))| entry(m, p, t))
            .collect();
        entries.sort_unstable_by(|a, b| b.cmp(a));
        let back: Vec<(bool, u64, Reverse<u32>)> = entries
            .iter()
            .map(|&e| (e >> 96 == 1, (e >> 32) as u64, Reverse(entry_triangle(e))))
            .collect();
        let want: Vec<_> = tuples.iter().rev().copied().collect();
        assert_eq!(back, want);
        assert!(back.iter().any(|e| e.1 == u64::MAX) && back.iter().any(|e| e.2 .0 == u32::MAX));
    }
}

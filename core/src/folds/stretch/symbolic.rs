//! Symbolic Cholesky factorisations of flattened patches, kept for reuse.
//!
//! Every fold seed flattens a patch ([`super::lscm`]), and the symbolic half of its sparse Cholesky (AMD
//! ordering, elimination tree, structure of L) costs as much as the numeric half. It depends only on the
//! sparsity pattern, which is fixed by the patch's triangles in local numbering and its two pins. The same
//! seeds come back frame after frame (seed memory, slowly moving shrinkage) with the same patch, and on a
//! regular mesh different seeds can have the same pattern; the cached factorisation then serves, and since it is
//! exactly the one that would be computed again, the flattening is unchanged bit for bit.
//!
//! Bounded: two generations of at most `per_generation` patterns each; a hit in the older one moves the
//! pattern to the newer, and when the newer is full the older is dropped.

use faer::sparse::linalg::cholesky::SymbolicCholesky;
use std::collections::HashMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

/// What decides a patch's pattern: vertex count, pins, triangles in local numbering.
#[derive(PartialEq, Eq)]
struct Key {
    n: usize,
    pin: (usize, usize),
    tris: Vec<[u32; 3]>,
}

struct Entry {
    key: Key,
    symbolic: Arc<SymbolicCholesky<usize>>,
}

type Generation = HashMap<u64, Vec<Entry>>;

/// A bounded, thread-safe store of symbolic factorisations keyed by patch pattern.
pub struct SymbolicCache {
    generations: Mutex<(Generation, Generation, usize)>,
    per_generation: usize,
    hits: AtomicUsize,
    misses: AtomicUsize,
}

fn hash(n: usize, pin: (usize, usize), tris: &[[u32; 3]]) -> u64 {
    // FxHash-style mixing: the key is a few thousand small integers, hashed once per patch.
    const K: u64 = 0x517c_c1b7_2722_0a95;
    let mut h = 0u64;
    let mut add = |x: u64| h = (h.rotate_left(5) ^ x).wrapping_mul(K);
    add(n as u64);
    add(pin.0 as u64);
    add(pin.1 as u64);
    for t in tris {
        add(t[0] as u64 | (t[1] as u64) << 32);
        add(t[2] as u64);
    }
    h
}

impl SymbolicCache {
    pub fn new(per_generation: usize) -> Self {
        SymbolicCache {
            generations: Mutex::new((HashMap::new(), HashMap::new(), 0)),
            per_generation: per_generation.max(1),
            hits: AtomicUsize::new(0),
            misses: AtomicUsize::new(0),
        }
    }

    /// The factorisation of the pattern of (`n`, `pin`, `tris`), from the cache or from `compute` (then kept).
    /// `None` when `compute` fails.
    pub fn get_or_compute(
        &self,
        n: usize,
        pin: (usize, usize),
        tris: &[[u32; 3]],
        compute: impl FnOnce() -> Option<SymbolicCholesky<usize>>,
    ) -> Option<Arc<SymbolicCholesky<usize>>> {
        let h = hash(n, pin, tris);
        let same = |e: &Entry| e.key.n == n && e.key.pin == pin && e.key.tris == tris;
        if let Ok(mut g) = self.generations.lock() {
            let (new, old, len) = &mut *g;
            if let Some(e) = new.get(&h).and_then(|v| v.iter().find(|e| same(e))) {
                self.hits.fetch_add(1, Ordering::Relaxed);
                return Some(e.symbolic.clone());
            }
            let moved = old.get_mut(&h).and_then(|v| {
                let k = v.iter().position(&same)?;
                Some(v.swap_remove(k))
            });
            if let Some(e) = moved {
                self.hits.fetch_add(1, Ordering::Relaxed);
                let symbolic = e.symbolic.clone();
                Self::push(new, old, len, self.per_generation, h, e);
                return Some(symbolic);
            }
        }
        self.misses.fetch_add(1, Ordering::Relaxed);
        let symbolic = Arc::new(compute()?);
        if let Ok(mut g) = self.generations.lock() {
            let (new, old, len) = &mut *g;
            let entry = Entry {
                key: Key {
                    n,
                    pin,
                    tris: tris.to_vec(),
                },
                symbolic: symbolic.clone(),
            };
            // Another thread may have added the same pattern meanwhile; one copy is enough.
            if !new.get(&h).is_some_and(|v| v.iter().any(same)) {
                Self::push(new, old, len, self.per_generation, h, entry);
            }
        }
        Some(symbolic)
    }

    fn push(
        new: &mut Generation,
        old: &mut Generation,
        len: &mut usize,
        per_generation: usize,
        h: u64,
        e: Entry,
    ) {
        if *len >= per_generation {
            *old = std::mem::take(new);
            *len = 0;
        }
        new.entry(h).or_default().push(e);
        *len += 1;
    }

    /// (hits, misses) so far.
    pub fn stats(&self) -> (usize, usize) {
        (
            self.hits.load(Ordering::Relaxed),
            self.misses.load(Ordering::Relaxed),
        )
    }
}

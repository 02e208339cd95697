//! One frame's folds (Chen 2011 §4.4): seeds in order of integrated shrinkage (absolute change), largest
//! first, one at a time; a fold takes the seeds of its region of influence out of the queue. With `seed_memory`
//! on, seeds of the previous frame go first (the thesis' seed memory; off by default, see
//! [`StretchParams::seed_memory`]). What one seed gives is [`super::trace`]'s; [`super::speculate`] traces
//! later seeds ahead on idle threads without changing the result.

use super::params::StretchParams;
use super::speculate::{entry, Entry, SeedPool, SeedQueue};
use super::trace::{FrameField, TracedFold};
use crate::mesh::Topology;
use rayon::prelude::*;

/// Result of tracing one frame.
#[derive(Debug, Clone, Default)]
pub struct FrameFolds {
    pub folds: Vec<TracedFold>,
    /// Anchors on the traced mesh ([`super::realise::anchors`]): sorted by triangle, unique.
    pub anchors: Vec<crate::folds::Anchor>,
    /// Seeds taken from the queue (each one flattened a patch), folds or not.
    pub seeds_tried: usize,
}

/// Traces frames one after the other, carrying the seed memory when it is on (O(triangles)).
pub struct FoldTracer {
    prev_seed: Vec<bool>,
    /// One [`SeedWork`] per thread tracing seeds at the same time ([`super::speculate`]).
    pool: SeedPool,
    traced_ahead: usize,
    wasted: usize,
}

/// Queue order of a seed of shrinkage `s`: rounded to 1e-9, so that seeds equal up to rounding noise (a
/// symmetric garment, the same mesh with another winding or vertex order) are taken by triangle index rather
/// than by the noise.
fn seed_priority(s: f64) -> u64 {
    ((s - 1.0).max(0.0) * 1e9).round() as u64
}

impl FoldTracer {
    /// A tracer whose control lines are realised on the traced mesh after `levels` rounds of subdivision.
    pub fn new(topo: &Topology, levels: usize) -> Self {
        FoldTracer {
            prev_seed: vec![false; topo.n_triangles()],
            pool: SeedPool::new(topo, levels),
            traced_ahead: 0,
            wasted: 0,
        }
    }

    /// The seed memory: the seeds that gave folds in the last traced frame, in increasing order.
    pub fn seeds(&self) -> Vec<u32> {
        (0..self.prev_seed.len() as u32)
            .filter(|&t| self.prev_seed[t as usize])
            .collect()
    }

    /// Seeds traced ahead of their turn so far ([`super::speculate`]), and those of them wasted because their
    /// seed was consumed first.
    pub fn traced_ahead(&self) -> (usize, usize) {
        (self.traced_ahead, self.wasted)
    }

    /// Replaces the seed memory (as if the last traced frame's folds came from `seeds`); out-of-range
    /// triangles are ignored.
    pub fn set_seeds(&mut self, seeds: &[u32]) {
        self.prev_seed.fill(false);
        for &t in seeds {
            if let Some(s) = self.prev_seed.get_mut(t as usize) {
                *s = true;
            }
        }
    }

    /// Traces the folds of one frame.
    pub fn trace(&mut self, f: &FrameField, params: &StretchParams) -> FrameFolds {
        let n_tri = f.topo.n_triangles();
        let seed_min = 1.0 + params.min_shrink;
        let prev_seed = &self.prev_seed;
        let mut order: Vec<Entry> = f
            .shrink
            .par_iter()
            .with_min_len(4096)
            .enumerate()
            .filter(|(_, &s)| s >= seed_min && s.is_finite())
            .map(|(t, &s)| {
                entry(
                    params.seed_memory && prev_seed[t],
                    seed_priority(s),
                    t as u32,
                )
            })
            .collect();
        // Largest first: the order a max-heap pops them in (the entries are distinct, one per triangle), for
        // one sort instead of a heap operation per seed on the sequential path.
        order.par_sort_unstable_by(|a, b| b.cmp(a));
        let centroid = crate::folds::video::views::centroid(f.p);
        let mut consumed = vec![false; n_tri];
        let mut new_seed = vec![false; n_tri];
        let mut folds = Vec::new();
        let mut seeds_tried = 0;
        let mut queue = SeedQueue::new(order);
        while let Some(s) = queue.next(&consumed) {
            consumed[s] = true;
            seeds_tried += 1;
            let outcome = queue.outcome(s, &consumed, &self.pool, f, params, centroid);
            if let Some((fold, region)) = outcome {
                for t in region {
                    consumed[t as usize] = true;
                }
                new_seed[s] = true;
                folds.push(fold);
            }
        }
        if params.seed_memory {
            self.prev_seed = new_seed;
        }
        self.traced_ahead += queue.traced_ahead;
        self.wasted += queue.wasted;
        FrameFolds {
            anchors: super::realise::anchors(&folds, None),
            folds,
            seeds_tried,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::mean_edge_length;
    use super::super::smooth::FrameGeometry;
    use super::*;
    use crate::vec3::{self, V3};

    /// Tracing seeds ahead on several threads gives the folds, anchors, seeds tried and seed memory of the
    /// one-at-a-time loop, frame after frame (the seed memory carries over).
    #[test]
    fn tracing_ahead_in_parallel_is_the_sequential_loop() {
        let seq = crate::synth::compressed_tube(6000, 4, 0.3, -1.0).unwrap();
        let topo = &seq.topology;
        let params = StretchParams {
            seed_memory: true,
            ..Default::default()
        };
        // A banded shrinkage along the tube with a ripple, so there are many folds and many failing seeds.
        let fields: Vec<(Vec<f64>, Vec<V3>)> = (0..seq.frames.len())
            .map(|t| {
                let geom = FrameGeometry::new(topo, &seq.frames[t]);
                let shrink = geom
                    .centroids
                    .iter()
                    .enumerate()
                    .map(|(i, c)| {
                        let band = (c[2] * 90.0 + t as f64).sin().max(0.0);
                        1.0 + 0.1 * band + 0.01 * ((i * 7919 % 97) as f64 / 97.0)
                    })
                    .collect();
                let dir = geom
                    .normals
                    .iter()
                    .map(|n| vec3::normalize(vec3::sub([0.0, 0.0, 1.0], vec3::scale(*n, n[2]))))
                    .collect();
                (shrink, dir)
            })
            .collect();
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                let mut tracer = FoldTracer::new(topo, 0);
                let mut out = Vec::new();
                for (t, (shrink, dir)) in fields.iter().enumerate() {
                    let p = &seq.frames[t];
                    let geom = FrameGeometry::new(topo, p);
                    let field = FrameField {
                        topo,
                        p,
                        geom: &geom,
                        shrink,
                        dir,
                        h: mean_edge_length(topo, &seq.frames[0]),
                    };
                    let folds = tracer.trace(&field, &params);
                    out.push(format!("{folds:?} {:?}", tracer.seeds()));
                }
                (out, tracer.traced_ahead().0)
            })
        };
        let (one, ahead_one) = run(1);
        let (four, ahead_four) = run(4);
        assert_eq!(ahead_one, 0);
        assert!(ahead_four > 0, "nothing was traced ahead");
        assert!(one.iter().all(|f| f.contains("TracedFold")), "no folds");
        for (t, (a, b)) in one.iter().zip(&four).enumerate() {
            assert!(a == b, "frame {t} differs with 4 threads");
        }
    }
}

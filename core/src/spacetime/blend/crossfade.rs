//! Turning per-window rotation-vector fields into final per-frame rotations.
//!
//! Windows overlap; [`CrossFade`] receives window fields in order, mixes the overlapping frames with the
//! linear ramp of [`crate::spacetime::windows::crossfade_weight`] (the weights are linear in the blend, so mixing the
//! rotation vectors is the same as mixing the weights), and releases every frame as soon as no later window
//! can touch it. Only the overlap tail is kept between windows, so memory is bounded by one window.

use crate::spacetime::windows::{crossfade_weight, Window};
use crate::vec3::{M3, V3};

/// Streaming cross-fade of window fields into per-frame rotation-vector fields.
pub struct CrossFade {
    windows: Vec<Window>,
    n_tri: usize,
    next: usize,
    /// Frames already weighted by earlier windows but still reachable by the next one: (frame, partial field).
    pending: Vec<(usize, Vec<V3>)>,
}

impl CrossFade {
    pub fn new(windows: Vec<Window>, n_tri: usize) -> Self {
        CrossFade {
            windows,
            n_tri,
            next: 0,
            pending: Vec::new(),
        }
    }

    /// Adds the field of the next window (frame-major, `len · n_tri` entries) and returns the frames that are now
    /// final, in order, as (frame, rotation vectors per triangle).
    pub fn push(&mut self, field: &[V3]) -> Vec<(usize, Vec<V3>)> {
        let k = self.next;
        self.next += 1;
        let w = self.windows[k];
        assert_eq!(field.len(), w.len * self.n_tri, "window field size");
        let next_start = self
            .windows
            .get(k + 1)
            .map(|n| n.start)
            .unwrap_or(usize::MAX);
        let mut done = Vec::new();
        let mut pending = Vec::new();
        let mut old = std::mem::take(&mut self.pending).into_iter().peekable();
        for lt in 0..w.len {
            let t = w.start + lt;
            let a = crossfade_weight(&self.windows, k, t);
            let src = &field[lt * self.n_tri..(lt + 1) * self.n_tri];
            let mut acc = match old.peek() {
                Some((f, _)) if *f == t => old.next().map(|(_, v)| v).unwrap_or_default(),
                _ => vec![[0.0; 3]; self.n_tri],
            };
            fade_into(&mut acc, a, src);
            if t >= next_start {
                pending.push((t, acc));
            } else {
                done.push((t, acc));
            }
        }
        self.pending = pending;
        done
    }
}

/// acc += a · src, component-wise: the one cross-fade step, shared by [`CrossFade`] and the cluster's
/// per-frame cross-fade ([`crate::spacetime::stages::crossfade_frame`]) so both produce the same bits.
pub fn fade_into(acc: &mut [V3], a: f64, src: &[V3]) {
    for (o, s) in acc.iter_mut().zip(src) {
        o[0] += a * s[0];
        o[1] += a * s[1];
        o[2] += a * s[2];
    }
}

/// Alexa blend of one frame: R_i = exp(Σ_a w_{i,a} φ_a) for every triangle.
pub fn rotations(field: &[V3]) -> Vec<M3> {
    field.iter().map(|&phi| super::so3::exp(phi)).collect()
}

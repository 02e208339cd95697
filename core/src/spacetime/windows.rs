//! Staggered time windows (Popa et al. 2009 §5.3): the weight solve runs on overlapping windows of `window`
//! frames shifted by `shift`, and the overlapping frames are cross-faded so that rotations stay smooth across
//! window boundaries. Solving window by window bounds memory and time by the window, not the sequence.

/// A half-open range of frames `[start, start + len)` solved together.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct Window {
    pub start: usize,
    pub len: usize,
}

impl Window {
    pub fn end(&self) -> usize {
        self.start + self.len
    }
}

/// Windows of `window` frames starting every `shift` frames until the sequence is covered. The last window is
/// cut at the end of the sequence; because `shift < window`, it still holds at least one frame beyond its
/// overlap with the previous window.
pub fn plan_windows(n_frames: usize, window: usize, shift: usize) -> Vec<Window> {
    assert!(window >= 1 && shift >= 1 && shift <= window);
    let mut out = Vec::new();
    let mut start = 0;
    while start < n_frames {
        let len = window.min(n_frames - start);
        out.push(Window { start, len });
        if start + len >= n_frames {
            break;
        }
        start += shift;
    }
    out
}

/// Weight of window `k` for frame `t` in the cross-fade: frames covered by one window get 1; in the overlap of
/// windows k and k+1 (m frames), the later window's weight ramps linearly (j+1)/(m+1), j = 0..m, so the two
/// weights always sum to one.
pub fn crossfade_weight(windows: &[Window], k: usize, t: usize) -> f64 {
    let w = windows[k];
    if t < w.start || t >= w.end() {
        return 0.0;
    }
    let mut weight = 1.0;
    if k > 0 {
        let prev = windows[k - 1];
        if t < prev.end() {
            let m = prev.end() - w.start;
            weight = ((t - w.start + 1) as f64) / ((m + 1) as f64);
        }
    }
    if let Some(next) = windows.get(k + 1) {
        if t >= next.start {
            let m = w.end() - next.start;
            weight = 1.0 - ((t - next.start + 1) as f64) / ((m + 1) as f64);
        }
    }
    weight
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_cover_and_overlap() {
        assert_eq!(plan_windows(5, 10, 7), vec![Window { start: 0, len: 5 }]);
        let w = plan_windows(24, 10, 7);
        assert_eq!(
            w,
            vec![
                Window { start: 0, len: 10 },
                Window { start: 7, len: 10 },
                Window { start: 14, len: 10 }
            ]
        );
        let w = plan_windows(20, 10, 7);
        assert_eq!(w.last(), Some(&Window { start: 14, len: 6 }));
        for n in 1..40 {
            let w = plan_windows(n, 10, 7);
            for t in 0..n {
                let s: f64 = (0..w.len()).map(|k| crossfade_weight(&w, k, t)).sum();
                assert!((s - 1.0).abs() < 1e-12, "n={n} t={t} sum={s}");
            }
        }
        let w = plan_windows(24, 10, 7);
        assert_eq!(crossfade_weight(&w, 1, 7), 0.25);
        assert_eq!(crossfade_weight(&w, 0, 7), 0.75);
        assert_eq!(crossfade_weight(&w, 1, 9), 0.75);
    }
}

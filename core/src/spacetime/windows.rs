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

/// Weight of window `k` for frame `t` in the cross-fade. Each window covering `t` gets a tent value (distance
/// to its nearer end, counting the end frame as 1) and the values are normalised over the covering windows. With
/// two windows overlapping on m frames this is the linear ramp (j+1)/(m+1), j = 0..m, of the later window; with
/// short shifts, where a frame lies in more than two windows, the weights still sum to one and fade smoothly.
pub fn crossfade_weight(windows: &[Window], k: usize, t: usize) -> f64 {
    let tent = |w: &Window| {
        if t < w.start || t >= w.end() {
            0.0
        } else {
            ((t - w.start + 1).min(w.end() - t)) as f64
        }
    };
    let own = tent(&windows[k]);
    if own == 0.0 {
        return 0.0;
    }
    let total: f64 = windows.iter().map(tent).sum();
    own / total
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
        for (n, window, shift) in
            (1..40).flat_map(|n| [(n, 10, 7), (n, 10, 3), (n, 5, 5), (n, 4, 1)])
        {
            let w = plan_windows(n, window, shift);
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

    #[test]
    fn crossfade_releases_every_frame_once_with_unit_weight() {
        for (n, window, shift) in [(24, 10, 7), (23, 10, 3), (9, 4, 1), (5, 10, 7)] {
            let windows = plan_windows(n, window, shift);
            let mut fade = crate::spacetime::blend::CrossFade::new(windows.clone(), 2);
            let mut seen = vec![0; n];
            for w in &windows {
                for (t, field) in fade.push(&vec![[1.0, 2.0, 3.0]; w.len * 2]) {
                    seen[t] += 1;
                    for v in field {
                        assert!(
                            (v[0] - 1.0).abs() < 1e-12 && (v[2] - 3.0).abs() < 1e-12,
                            "frame {t}: {v:?}"
                        );
                    }
                }
            }
            assert!(
                seen.iter().all(|&c| c == 1),
                "{n}/{window}/{shift}: {seen:?}"
            );
        }
    }
}

//! Anchors of the same folds from two detectors, made one set.
//!
//! The capture video and the geometry see different evidence of a fold. The images show its crest and flanks
//! wherever the light catches them, including folds the capture erased outright; the geometry (Chen's stretch
//! detector) sees where the cloth lost length, which it measures on every triangle, lit or not, and without the
//! images' shading noise. Each misses or misplaces folds the other gets right, so their errors are partly
//! independent, and a rotation field spread from both is closer to the cloth than one spread from either.
//!
//! The rule is deliberately simple: a triangle anchored by one detector keeps that anchor; a triangle both
//! anchored gets the mean of the two rotation vectors (both are estimates of the same rotation); every angle
//! is then scaled by a gain. The gain is below one because two dense sets of anchors pin the rotation field
//! on far more triangles than either alone, and where the two disagree about a crest's place, the smaller
//! rotation is the one that errs less.

use super::anchors::{Anchor, FrameAnchors};
use crate::error::{Error, Result};
use crate::vec3;

/// What [`fuse`] did, for the job's report.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FuseCounts {
    /// Anchors the first (primary) detector gave.
    pub primary: usize,
    /// Anchors the second detector gave.
    pub secondary: usize,
    /// Triangles both anchored in the same frame (their anchors became one).
    pub shared: usize,
}

/// One anchor set of `primary` and `secondary` (one entry per frame each, in frame order, as detectors return
/// them), each angle scaled by `gain` (in (0, 1]). The primary's control lines and detection figures are kept
/// and the secondary's control lines added (they are for inspection only). Frames must match one to one.
pub fn fuse(
    primary: Vec<FrameAnchors>,
    secondary: &[FrameAnchors],
    gain: f64,
) -> Result<(Vec<FrameAnchors>, FuseCounts)> {
    if !(gain > 0.0 && gain <= 1.0) {
        return Err(Error::param(
            "fused_gain",
            format!("must be in (0, 1], got {gain}"),
        ));
    }
    if primary.len() != secondary.len() {
        return Err(Error::param(
            "anchors",
            format!(
                "the two detectors gave {} and {} frames",
                primary.len(),
                secondary.len()
            ),
        ));
    }
    let mut counts = FuseCounts::default();
    let mut out = Vec::with_capacity(primary.len());
    for (mut a, b) in primary.into_iter().zip(secondary) {
        if a.frame != b.frame {
            return Err(Error::param(
                "anchors",
                format!(
                    "frame {} of one detector is paired with frame {} of the other",
                    a.frame, b.frame
                ),
            ));
        }
        counts.primary += a.anchors.len();
        counts.secondary += b.anchors.len();
        let mut first = std::mem::take(&mut a.anchors);
        let mut second = b.anchors.clone();
        first.sort_by_key(|x| x.triangle);
        second.sort_by_key(|x| x.triangle);
        let mut merged = Vec::with_capacity(first.len() + second.len());
        let (mut i, mut j) = (0, 0);
        while i < first.len() || j < second.len() {
            let next = match (first.get(i), second.get(j)) {
                (Some(x), Some(y)) if x.triangle == y.triangle => {
                    i += 1;
                    j += 1;
                    counts.shared += 1;
                    mean(x, y)
                }
                (Some(x), Some(y)) if x.triangle < y.triangle => {
                    i += 1;
                    *x
                }
                (Some(x), None) => {
                    i += 1;
                    *x
                }
                (_, Some(y)) => {
                    j += 1;
                    *y
                }
                (None, None) => unreachable!("the loop runs while either has anchors"),
            };
            // A mean of opposite rotations is no rotation: nothing to anchor.
            if next.angle != 0.0 {
                merged.push(Anchor {
                    angle: next.angle * gain,
                    ..next
                });
            }
        }
        a.anchors = merged;
        a.control_lines.extend(b.control_lines.iter().cloned());
        out.push(a);
    }
    Ok((out, counts))
}

/// The anchor whose rotation vector is the mean of `x`'s and `y`'s (same triangle).
fn mean(x: &Anchor, y: &Anchor) -> Anchor {
    let v = vec3::scale(vec3::add(x.rotation_vector(), y.rotation_vector()), 0.5);
    let angle = vec3::norm(v);
    if angle > 0.0 {
        Anchor {
            triangle: x.triangle,
            axis: vec3::scale(v, 1.0 / angle),
            angle,
        }
    } else {
        Anchor {
            triangle: x.triangle,
            axis: x.axis,
            angle: 0.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn anchor(triangle: u32, axis: [f64; 3], angle: f64) -> Anchor {
        Anchor {
            triangle,
            axis,
            angle,
        }
    }

    fn frame(frame: usize, anchors: Vec<Anchor>) -> FrameAnchors {
        FrameAnchors {
            frame,
            anchors,
            ..Default::default()
        }
    }

    #[test]
    fn shared_triangles_take_the_mean_and_every_angle_the_gain() {
        let images = vec![
            frame(
                0,
                vec![
                    anchor(3, [1.0, 0.0, 0.0], 0.4),
                    anchor(7, [0.0, 0.0, 1.0], 0.2),
                ],
            ),
            frame(1, vec![]),
        ];
        let geometry = vec![
            frame(
                0,
                vec![
                    anchor(1, [0.0, 1.0, 0.0], 0.3),
                    anchor(3, [0.0, 1.0, 0.0], 0.4),
                ],
            ),
            frame(1, vec![anchor(5, [1.0, 0.0, 0.0], -0.5)]),
        ];
        let (fused, counts) = fuse(images, &geometry, 0.5).unwrap();
        assert_eq!(
            counts,
            FuseCounts {
                primary: 2,
                secondary: 3,
                shared: 1
            }
        );
        let f0 = &fused[0].anchors;
        assert_eq!(
            f0.iter().map(|a| a.triangle).collect::<Vec<_>>(),
            [1, 3, 7],
            "sorted by triangle, one anchor per triangle"
        );
        assert!((f0[0].angle - 0.15).abs() < 1e-12);
        // Triangle 3: the mean of 0.4 about x and 0.4 about y is 0.2·√2 about (x + y)/√2, then halved.
        let h = std::f64::consts::FRAC_1_SQRT_2;
        assert!(
            (f0[1].angle - 0.1 * 2f64.sqrt()).abs() < 1e-12,
            "{:?}",
            f0[1]
        );
        assert!((f0[1].axis[0] - h).abs() < 1e-12 && (f0[1].axis[1] - h).abs() < 1e-12);
        assert!((f0[2].angle - 0.1).abs() < 1e-12);
        assert_eq!(fused[1].anchors, vec![anchor(5, [1.0, 0.0, 0.0], -0.25)]);
    }

    #[test]
    fn opposite_rotations_cancel_and_leave_no_anchor() {
        let a = vec![frame(0, vec![anchor(2, [0.0, 0.0, 1.0], 0.3)])];
        let b = vec![frame(0, vec![anchor(2, [0.0, 0.0, -1.0], 0.3)])];
        let (fused, counts) = fuse(a, &b, 1.0).unwrap();
        assert!(fused[0].anchors.is_empty());
        assert_eq!(counts.shared, 1);
    }

    #[test]
    fn mismatched_inputs_and_gains_are_refused() {
        let a = vec![frame(0, vec![])];
        assert!(fuse(a.clone(), &[], 0.7).is_err());
        assert!(fuse(a.clone(), &[frame(1, vec![])], 0.7).is_err());
        for g in [0.0, -0.1, 1.5, f64::NAN] {
            let e = fuse(a.clone(), &[frame(0, vec![])], g).unwrap_err();
            assert!(e.to_string().contains("fused_gain"), "{e}");
        }
    }
}

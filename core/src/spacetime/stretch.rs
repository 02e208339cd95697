//! Stretch reduction (Popa et al. 2009 §5.5).
//!
//! Blended rotations are not the gradient of any surface, so the positioned triangles are a least-squares
//! compromise and some of them stretch. A pass replaces each triangle's rotation by the one that takes its
//! original normal to the normal it got, and positions again with the frame's factor: the folds keep the
//! orientation they took, while the in-plane twist that the blend added (and the positioning could not honour
//! without stretching) is dropped.

use super::position::FramePositioner;
use super::so3;
use crate::mesh::{geometry, Frame};
use crate::vec3::{self, M3};

/// For each triangle, the rotation taking its original normal to its normal in `current` (identity for a
/// triangle that collapsed to zero area, which has no normal to follow).
pub fn normal_rotations(fp: &FramePositioner, current: &[crate::vec3::V3]) -> Vec<M3> {
    let n_new = geometry::triangle_normals(fp.topology(), current);
    fp.rest_normals()
        .iter()
        .zip(&n_new)
        .map(|(n0, n1)| {
            if vec3::norm(*n1) == 0.0 {
                vec3::IDENTITY
            } else {
                so3::exp(so3::rotation_between(*n0, *n1))
            }
        })
        .collect()
}

/// One stretch-reduction pass on `current`, reusing the frame's factorisation.
pub fn pass(fp: &FramePositioner, current: &[crate::vec3::V3]) -> Frame {
    fp.solve(&normal_rotations(fp, current))
}

//! Cameras: a look-at perspective camera for framing previews, and a calibrated pinhole camera in the OpenCV
//! convention for rendering from captured (calibrated) viewpoints. Both reduce to [`CalibratedCamera`].

use crate::vec3::{self, M3, V3};

/// Anything the rasterizer can render from. Every camera reduces to a calibrated pinhole camera.
pub trait Projection {
    /// The equivalent calibrated pinhole camera (OpenCV convention).
    fn calibrated(&self) -> CalibratedCamera;
}

/// A calibrated pinhole camera in the OpenCV convention, without lens distortion.
///
/// Camera axes are x right, y down, z forward. A world point `p` has camera coordinates `q = r p + t` and
/// projects to pixel `(fx q.x / q.z + cx, fy q.y / q.z + cy)`, where pixel `(0, 0)` is the *centre* of the
/// top-left pixel (so the image spans `[-0.5, width - 0.5] x [-0.5, height - 0.5]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CalibratedCamera {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    /// World → camera rotation, row-major.
    pub r: M3,
    /// World → camera translation.
    pub t: V3,
    pub width: u32,
    pub height: u32,
}

impl CalibratedCamera {
    /// Camera coordinates of a world point.
    #[inline]
    pub fn to_camera(&self, p: V3) -> V3 {
        vec3::add(vec3::mat_vec(&self.r, p), self.t)
    }

    /// Pixel coordinates of a world point, or `None` when it is not strictly in front of the camera (or the result
    /// is not finite). The point may fall outside the image.
    pub fn project(&self, p: V3) -> Option<[f64; 2]> {
        let q = self.to_camera(p);
        if q[2].is_nan() || q[2] <= 0.0 {
            return None;
        }
        let uv = [
            self.fx * q[0] / q[2] + self.cx,
            self.fy * q[1] / q[2] + self.cy,
        ];
        (uv[0].is_finite() && uv[1].is_finite()).then_some(uv)
    }

    /// Back-projection: the unit world-space direction of the viewing ray through pixel `uv` (same pixel
    /// convention as [`CalibratedCamera::project`]); the ray starts at [`CalibratedCamera::center`]. Every point
    /// `center + s · ray_direction(uv)` with `s > 0` projects back to `uv`.
    pub fn ray_direction(&self, uv: [f64; 2]) -> V3 {
        let q = [
            (uv[0] - self.cx) / self.fx,
            (uv[1] - self.cy) / self.fy,
            1.0,
        ];
        vec3::normalize(vec3::mat_vec(&vec3::transpose(&self.r), q))
    }

    /// Camera centre in world coordinates (`-rᵀ t`).
    pub fn center(&self) -> V3 {
        vec3::scale(vec3::mat_vec(&vec3::transpose(&self.r), self.t), -1.0)
    }

    /// All parameters finite and focal lengths non-zero.
    pub(crate) fn is_usable(&self) -> bool {
        [self.fx, self.fy, self.cx, self.cy]
            .iter()
            .all(|v| v.is_finite())
            && self.fx != 0.0
            && self.fy != 0.0
            && self.r.iter().all(|row| vec3::is_finite(*row))
            && vec3::is_finite(self.t)
    }
}

impl Projection for CalibratedCamera {
    fn calibrated(&self) -> CalibratedCamera {
        *self
    }
}

/// A perspective pinhole camera at `eye` looking at `target`, with `up` pointing up in the image (it need not be
/// orthogonal to the viewing direction), square pixels and the principal point at the image centre.
///
/// A degenerate camera (`eye == target`, non-finite values) renders only the background.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    pub eye: V3,
    pub target: V3,
    pub up: V3,
    /// Vertical field of view in degrees (clamped to `[0.001, 179]`).
    pub fov_y_deg: f64,
    pub width: u32,
    pub height: u32,
}

impl Camera {
    /// Field of view used by [`Camera::fit`].
    pub const FIT_FOV_Y_DEG: f64 = 30.0;
    /// Fraction of the half-width / half-height that [`Camera::fit`] lets the box occupy (the rest is margin).
    pub const FIT_FILL: f64 = 0.9;

    /// Frames the axis-aligned box `[bbox_lo, bbox_hi]` seen along `view_dir` (the direction the camera looks
    /// in, from the eye towards the box), with `up` up in the image. The camera looks at the box centre from the
    /// closest distance at which all eight corners fall inside the image with a 5% margin on each side.
    ///
    /// Never fails: a non-finite box frames the unit box at the origin, a zero `view_dir` looks along -z, and an
    /// `up` parallel to `view_dir` is replaced by another axis.
    pub fn fit(bbox_lo: V3, bbox_hi: V3, view_dir: V3, up: V3, width: u32, height: u32) -> Camera {
        let ok_box = vec3::is_finite(bbox_lo)
            && vec3::is_finite(bbox_hi)
            && (0..3).all(|k| bbox_lo[k] <= bbox_hi[k]);
        let (centre, mut half) = if ok_box {
            (
                vec3::scale(vec3::add(bbox_lo, bbox_hi), 0.5),
                vec3::scale(vec3::sub(bbox_hi, bbox_lo), 0.5),
            )
        } else {
            ([0.0; 3], [0.5; 3])
        };
        if !vec3::is_finite(half) || vec3::norm(half) <= 0.0 {
            half = [0.5; 3];
        }
        let mut dir = vec3::normalize(view_dir);
        if !vec3::is_finite(dir) || vec3::norm(dir) == 0.0 {
            dir = [0.0, 0.0, -1.0];
        }
        // `dir` is a unit vector, so a basis always exists.
        let r = look_at_rotation(dir, up).unwrap_or(vec3::IDENTITY);
        let tan_y = (Self::FIT_FOV_Y_DEG.to_radians() * 0.5).tan();
        let aspect = width.max(1) as f64 / height.max(1) as f64;
        let tan_x = tan_y * aspect;
        let size = vec3::norm(half);
        let mut dist: f64 = 0.0;
        for corner in 0..8 {
            let rel = [
                if corner & 1 == 0 { -half[0] } else { half[0] },
                if corner & 2 == 0 { -half[1] } else { half[1] },
                if corner & 4 == 0 { -half[2] } else { half[2] },
            ];
            let q = vec3::mat_vec(&r, rel);
            dist = dist
                .max(q[0].abs() / (Self::FIT_FILL * tan_x) - q[2])
                .max(q[1].abs() / (Self::FIT_FILL * tan_y) - q[2])
                .max(q[2] + 0.05 * size);
        }
        Camera {
            eye: vec3::sub(centre, vec3::scale(dir, dist)),
            target: centre,
            // The image-up direction actually used (minus the camera's y-down axis).
            up: vec3::scale(r[1], -1.0),
            fov_y_deg: Self::FIT_FOV_Y_DEG,
            width,
            height,
        }
    }

    /// Pixel coordinates of a world point; see [`CalibratedCamera::project`].
    pub fn project(&self, p: V3) -> Option<[f64; 2]> {
        self.calibrated().project(p)
    }
}

impl Projection for Camera {
    fn calibrated(&self) -> CalibratedCamera {
        let r = look_at_rotation(vec3::sub(self.target, self.eye), self.up)
            .unwrap_or([[f64::NAN; 3]; 3]);
        let fov = if self.fov_y_deg.is_finite() {
            self.fov_y_deg.clamp(1e-3, 179.0)
        } else {
            45.0
        };
        let fy = 0.5 * self.height as f64 / (fov.to_radians() * 0.5).tan();
        CalibratedCamera {
            fx: fy,
            fy,
            cx: (self.width as f64 - 1.0) * 0.5,
            cy: (self.height as f64 - 1.0) * 0.5,
            r,
            t: vec3::scale(vec3::mat_vec(&r, self.eye), -1.0),
            width: self.width,
            height: self.height,
        }
    }
}

/// World → camera rotation (rows: right, down, forward) for a camera looking along `forward` with `up` up.
/// `None` when `forward` is zero or not finite. An `up` parallel to `forward` is replaced by the world y axis
/// (or z when looking along y).
fn look_at_rotation(forward: V3, up: V3) -> Option<M3> {
    let f = vec3::normalize(forward);
    if !vec3::is_finite(f) || vec3::norm(f) == 0.0 {
        return None;
    }
    let mut right = vec3::normalize(vec3::cross(f, up));
    if !vec3::is_finite(right) || vec3::norm(right) < 0.5 {
        let alt = if f[1].abs() < 0.9 {
            [0.0, 1.0, 0.0]
        } else {
            [0.0, 0.0, 1.0]
        };
        right = vec3::normalize(vec3::cross(f, alt));
    }
    let down = vec3::cross(f, right);
    Some([right, down, f])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: [f64; 2], b: [f64; 2]) -> bool {
        (a[0] - b[0]).abs() < 1e-9 && (a[1] - b[1]).abs() < 1e-9
    }

    #[test]
    fn opencv_camera_projects_known_points() {
        let cam = CalibratedCamera {
            fx: 100.0,
            fy: 120.0,
            cx: 50.0,
            cy: 40.0,
            r: vec3::IDENTITY,
            t: [0.0, 0.0, 5.0],
            width: 100,
            height: 80,
        };
        // Camera coordinates (1, 0.5, 5): u = 100 * 0.2 + 50, v = 120 * 0.1 + 40.
        assert!(close(cam.project([1.0, 0.5, 0.0]).unwrap(), [70.0, 52.0]));
        assert!(cam.project([0.0, 0.0, -5.0]).is_none());
        assert!(cam.project([0.0, 0.0, -6.0]).is_none());
        assert_eq!(cam.center(), [0.0, 0.0, -5.0]);
        // Back-projection inverts projection.
        let d = cam.ray_direction([70.0, 52.0]);
        let p = vec3::add(cam.center(), vec3::scale(d, 3.7));
        assert!(close(cam.project(p).unwrap(), [70.0, 52.0]));

        // A rotation mapping world z to camera x and world x to camera -z.
        let r = [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]];
        let cam = CalibratedCamera {
            r,
            t: [0.0, 0.0, 4.0],
            ..cam
        };
        // World (-2, 0.4, 0.8) → camera (0.8, 0.4, 2 + 4 = 6).
        let uv = cam.project([-2.0, 0.4, 0.8]).unwrap();
        assert!(
            close(uv, [100.0 * 0.8 / 6.0 + 50.0, 120.0 * 0.4 / 6.0 + 40.0]),
            "{uv:?}"
        );
    }

    #[test]
    fn look_at_camera_orientation() {
        let cam = Camera {
            eye: [0.0, 0.0, 5.0],
            target: [0.0; 3],
            up: [0.0, 1.0, 0.0],
            fov_y_deg: 40.0,
            width: 101,
            height: 81,
        };
        assert!(close(cam.project([0.0; 3]).unwrap(), [50.0, 40.0]));
        let up = cam.project([0.0, 1.0, 0.0]).unwrap();
        assert!(up[1] < 40.0 && (up[0] - 50.0).abs() < 1e-9);
        let right = cam.project([1.0, 0.0, 0.0]).unwrap();
        assert!(right[0] > 50.0 && (right[1] - 40.0).abs() < 1e-9);
        // The vertical half field of view maps to half the image height.
        let h = 5.0 * (20f64).to_radians().tan();
        assert!((cam.project([0.0, h, 0.0]).unwrap()[1] - (40.0 - 40.5)).abs() < 1e-9);
        assert_eq!(cam.calibrated().center(), [0.0, 0.0, 5.0]);
    }

    #[test]
    fn fit_keeps_box_in_view() {
        let lo = [-1.0, 0.0, -0.3];
        let hi = [1.0, 1.8, 0.4];
        for (dir, up) in [
            ([0.0, 0.0, -1.0], [0.0, 1.0, 0.0]),
            ([1.0, -0.3, 0.2], [0.0, 1.0, 0.0]),
            ([0.0, -1.0, 0.0], [0.0, 1.0, 0.0]),
        ] {
            let cam = Camera::fit(lo, hi, dir, up, 320, 200);
            for c in 0..8 {
                let p = [
                    if c & 1 == 0 { lo[0] } else { hi[0] },
                    if c & 2 == 0 { lo[1] } else { hi[1] },
                    if c & 4 == 0 { lo[2] } else { hi[2] },
                ];
                let [u, v] = cam.project(p).unwrap();
                assert!(
                    (-0.5..=319.5).contains(&u) && (-0.5..=199.5).contains(&v),
                    "{dir:?}: {u} {v}"
                );
            }
        }
        // Garbage in, a usable camera out.
        let cam = Camera::fit([f64::NAN; 3], [1.0; 3], [0.0; 3], [0.0; 3], 10, 10);
        assert!(cam.calibrated().is_usable());
    }
}

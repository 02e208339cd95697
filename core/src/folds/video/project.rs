//! Projecting paired fold edges onto the frame mesh and turning them into anchors (Popa et al. 2009 §5.1).
//!
//! Every edge point's viewing ray (back-projection through the calibrated camera) is cast against the frame's
//! triangles with a BVH (parry3d); the first hit is the surface the camera saw there. Pairs where an edge falls
//! off the garment (rays miss) or onto its silhouette (rays graze the hit triangle) are discarded. The triangles
//! the edges cross become anchors, rotated counter-clockwise about the edge so that the darker, left side goes
//! deeper: with `d` the edge's world direction (dark side on the left as seen from the camera) and `n` the
//! camera-facing normal, the left side is `n × d`, and the rotation about `-d` by `θ > 0` turns `n` towards it
//! (`n ↦ n cos θ + (n × d) sin θ`), lowering the left side. The angle is inversely proportional to the pair's
//! width on one scale for the whole sequence: 60° at `narrow_width` mean edge lengths down to 30° at
//! `wide_width`.

use super::pairing::Pair;
use super::params::VideoParams;
use crate::error::{Error, Result};
use crate::folds::Anchor;
use crate::mesh::{geometry, Topology};
use crate::render::CalibratedCamera;
use crate::vec3::{self, V3};
use parry3d::math::Vector;
use parry3d::query::{Ray, RayCast};
use parry3d::shape::TriMesh;

/// A ray hit on the mesh.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    pub triangle: u32,
    pub point: V3,
    /// |cos| of the angle between the ray and the triangle normal (0 = grazing, on the silhouette).
    pub facing: f64,
}

/// A BVH over one frame's triangles, seen from one camera. Coordinates are stored relative to the camera centre
/// (parry3d works in `f32`; this keeps the precision where the rays start).
pub struct MeshCaster {
    mesh: TriMesh,
    origin: V3,
    normals: Vec<V3>,
    /// Triangles on the garment's border (an edge without a neighbour): a fold edge there is the border's
    /// outline (cuff, collar, hem), which like the silhouette is not a fold.
    border: Vec<bool>,
    /// Whether hits on border triangles count as off the garment ([`VideoParams::skip_border`]).
    pub skip_border: bool,
    camera: CalibratedCamera,
}

impl MeshCaster {
    pub fn new(topo: &Topology, positions: &[V3], camera: &CalibratedCamera) -> Result<Self> {
        let origin = camera.center();
        let verts: Vec<Vector> = positions
            .iter()
            .map(|&p| {
                let q = vec3::sub(p, origin);
                Vector::new(q[0] as f32, q[1] as f32, q[2] as f32)
            })
            .collect();
        let mesh = TriMesh::new(verts, topo.triangles().to_vec())
            .map_err(|e| Error::mesh(format!("cannot build the ray-casting BVH: {e:?}")))?;
        let border = topo
            .tri_adj()
            .iter()
            .map(|adj| adj.contains(&crate::mesh::NONE))
            .collect();
        Ok(MeshCaster {
            mesh,
            origin,
            normals: geometry::triangle_normals(topo, positions),
            border,
            skip_border: false,
            camera: *camera,
        })
    }

    /// The first surface point seen at pixel `uv`, if any. A ray exactly through a shared mesh edge can slip
    /// between the two triangles in `f32`; a miss is retried with rays a hundredth of a pixel aside.
    pub fn cast(&self, uv: [f64; 2]) -> Option<Hit> {
        [[0.0, 0.0], [0.011, 0.007], [-0.011, -0.007]]
            .iter()
            .find_map(|o| self.cast_exact([uv[0] + o[0], uv[1] + o[1]]))
    }

    fn cast_exact(&self, uv: [f64; 2]) -> Option<Hit> {
        let d = self.camera.ray_direction(uv);
        let ray = Ray::new(
            Vector::ZERO,
            Vector::new(d[0] as f32, d[1] as f32, d[2] as f32),
        );
        let hit = self
            .mesh
            .cast_local_ray_and_get_normal(&ray, f32::MAX, true)?;
        let triangle = hit.subshape;
        let s = hit.time_of_impact as f64;
        let n = self.normals.get(triangle as usize)?;
        Some(Hit {
            triangle,
            point: vec3::add(self.origin, vec3::scale(d, s)),
            facing: vec3::dot(*n, d).abs(),
        })
    }

    /// |cos| of the angle between triangle `tri`'s normal and this camera's viewing ray to `point` (1 = seen
    /// head-on, 0 = edge-on), whether or not the camera actually sees the point.
    pub fn facing(&self, tri: u32, point: V3) -> f64 {
        let d = vec3::normalize(vec3::sub(point, self.origin));
        self.normals
            .get(tri as usize)
            .map_or(0.0, |n| vec3::dot(*n, d).abs())
    }

    /// [`Self::facing`] where the camera sees `point` on triangle `tri`: the point lies inside the image and the
    /// first surface along its viewing ray is `tri` or lies within `tol` of the point. `None` when the point is
    /// outside the image, behind the camera or hidden by other cloth.
    pub fn visible_facing(&self, tri: u32, point: V3, tol: f64) -> Option<f64> {
        let uv = self.camera.project(point)?;
        let (w, h) = (self.camera.width as f64, self.camera.height as f64);
        if uv[0] < -0.5 || uv[1] < -0.5 || uv[0] >= w - 0.5 || uv[1] >= h - 0.5 {
            return None;
        }
        let hit = self.cast(uv)?;
        let near = vec3::norm(vec3::sub(hit.point, point)) <= tol;
        (hit.triangle == tri || near).then(|| self.facing(tri, point))
    }

    /// Casts the points of an image polyline, sampled every `step` pixels. Returns the hits on the garment away
    /// from the silhouette (and the border if asked), in order, and the fraction of samples that missed, grazed
    /// or hit the border.
    pub fn cast_polyline(
        &self,
        points: &[[f64; 2]],
        step: f64,
        silhouette_cos: f64,
    ) -> (Vec<Hit>, f64) {
        let samples = resample(points, step);
        let mut hits = Vec::with_capacity(samples.len());
        let mut bad = 0usize;
        for uv in &samples {
            match self.cast(*uv) {
                Some(h)
                    if h.facing >= silhouette_cos
                        && !(self.skip_border && self.border[h.triangle as usize]) =>
                {
                    hits.push(h)
                }
                _ => bad += 1,
            }
        }
        (hits, bad as f64 / samples.len().max(1) as f64)
    }
}

/// Points along a polyline every `step` (always including both ends).
pub fn resample(points: &[[f64; 2]], step: f64) -> Vec<[f64; 2]> {
    let mut out = vec![points[0]];
    for w in points.windows(2) {
        let (a, b) = (w[0], w[1]);
        let len = (b[0] - a[0]).hypot(b[1] - a[1]);
        let n = (len / step).ceil().max(1.0) as usize;
        for k in 1..=n {
            let t = k as f64 / n as f64;
            out.push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
        }
    }
    out
}

/// A pair of fold edges on the surface.
#[derive(Debug, Clone)]
pub struct ProjectedPair {
    pub pair: Pair,
    pub a: Vec<Hit>,
    pub b: Vec<Hit>,
    /// Mean distance (world units) from `a`'s surface points to `b`'s.
    pub width: f64,
}

/// Casts both edges of `pair`; `None` when either edge leaves the garment or runs onto its silhouette for more
/// than `max_off_garment` of its length.
pub fn project_pair(
    caster: &MeshCaster,
    pair: &Pair,
    params: &VideoParams,
) -> Option<ProjectedPair> {
    let (a, off_a) = caster.cast_polyline(&pair.a, 0.5, params.silhouette_cos);
    let (b, off_b) = caster.cast_polyline(&pair.b, 0.5, params.silhouette_cos);
    if off_a > params.max_off_garment
        || off_b > params.max_off_garment
        || a.len() < 2
        || b.len() < 2
    {
        return None;
    }
    let width = a
        .iter()
        .map(|h| {
            b.iter()
                .map(|g| vec3::norm(vec3::sub(h.point, g.point)))
                .fold(f64::INFINITY, f64::min)
        })
        .sum::<f64>()
        / a.len() as f64;
    Some(ProjectedPair {
        pair: pair.clone(),
        a,
        b,
        width,
    })
}

/// Anchor angle (radians) for a pair of `width` (world units) on a mesh of mean edge length `h`: inversely
/// proportional to the width, `narrow_angle_deg` at `narrow_width · h`, `wide_angle_deg` at `wide_width · h`,
/// clamped beyond.
pub fn pair_angle(width: f64, h: f64, params: &VideoParams) -> f64 {
    angle_for(
        width,
        params.narrow_width * h,
        params.wide_width * h,
        params,
    )
}

/// Anchor angle (radians) for a pair of `width` on the scale `[narrow, wide]`: inversely proportional to the
/// width, `narrow_deg` at `narrow` and `wide_deg` at `wide`.
pub fn angle_for(width: f64, narrow: f64, wide: f64, params: &VideoParams) -> f64 {
    let f = if wide - narrow > 1e-12 {
        ((width - narrow) / (wide - narrow)).clamp(0.0, 1.0)
    } else {
        0.5
    };
    let (a0, a1) = (params.narrow_angle_deg, params.wide_angle_deg);
    let deg = if a0 > 0.0 && a1 > 0.0 {
        a0 * a1 / (a1 + f * (a0 - a1))
    } else {
        a0 + f * (a1 - a0)
    };
    deg.to_radians()
}

/// The anchors of one edge's hits: every crossed triangle once, axis = minus the edge direction projected into
/// the triangle's plane.
pub fn edge_anchors(hits: &[Hit], normals: &[V3], angle: f64) -> Vec<Anchor> {
    let mut out: Vec<Anchor> = Vec::new();
    for k in 0..hits.len() {
        let tri = hits[k].triangle;
        if out.last().is_some_and(|a| a.triangle == tri) || out.iter().any(|a| a.triangle == tri) {
            continue;
        }
        let p0 = hits[k.saturating_sub(1)].point;
        let p1 = hits[(k + 1).min(hits.len() - 1)].point;
        let d = vec3::sub(p1, p0);
        let n = normals[tri as usize];
        let d = vec3::normalize(vec3::sub(d, vec3::scale(n, vec3::dot(n, d))));
        if !vec3::is_finite(d) || vec3::norm(d) < 0.5 {
            continue;
        }
        out.push(Anchor {
            triangle: tri,
            axis: vec3::scale(d, -1.0),
            angle,
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth;

    /// A 1 x 1 sheet in the plane z = 0 seen from (0.5, 0.5, 2) looking down -z.
    fn setup() -> (std::sync::Arc<Topology>, Vec<V3>, CalibratedCamera) {
        let (topo, frame) = synth::sheet(20, 20, 0.05).unwrap();
        // Camera looking along -z: x right, y down in the image = world -y.
        let cam = CalibratedCamera {
            fx: 400.0,
            fy: 400.0,
            cx: 199.5,
            cy: 199.5,
            r: [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]],
            t: [-0.5, 0.5, 2.0],
            width: 400,
            height: 400,
        };
        (topo, frame, cam)
    }

    #[test]
    fn projected_edge_lands_on_the_expected_triangles() {
        let (topo, frame, cam) = setup();
        let caster = MeshCaster::new(&topo, &frame, &cam).unwrap();
        // A world segment on the sheet at y = 0.52, x from 0.2 to 0.8, projected to the image and back.
        let world: Vec<V3> = (0..=58)
            .map(|i| [0.206 + 0.01 * i as f64, 0.52, 0.0])
            .collect();
        let image: Vec<[f64; 2]> = world.iter().map(|&p| cam.project(p).unwrap()).collect();
        let (hits, off) = caster.cast_polyline(&image, 0.5, 0.2);
        assert_eq!(off, 0.0);
        // Expected: the triangles containing the segment's points (brute force over the sheet).
        let tris = topo.triangles();
        let contains = |t: [u32; 3], p: V3| {
            let [a, b, c] = t.map(|v| frame[v as usize]);
            let s =
                |p: V3, q: V3, r: V3| (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]);
            let (d1, d2, d3) = (s(a, b, p), s(b, c, p), s(c, a, p));
            // Hits are computed in f32: allow points a few 1e-7 outside (on a shared edge).
            let neg = d1 < -1e-7 || d2 < -1e-7 || d3 < -1e-7;
            let pos = d1 > 1e-7 || d2 > 1e-7 || d3 > 1e-7;
            !(neg && pos)
        };
        for h in &hits {
            assert!(
                h.point[2].abs() < 1e-5 && (h.point[1] - 0.52).abs() < 1e-4,
                "{h:?}"
            );
            assert!(contains(tris[h.triangle as usize], h.point), "{h:?}");
            assert!(h.facing > 0.9);
        }
        let mut expected: Vec<u32> = (0..tris.len() as u32)
            .filter(|&t| world.iter().any(|&p| contains(tris[t as usize], p)))
            .collect();
        let mut got: Vec<u32> = hits.iter().map(|h| h.triangle).collect();
        got.sort();
        got.dedup();
        expected.sort();
        // Every crossed triangle the samples found is one the segment passes through, and (sampled every
        // half pixel, triangles ~20 px wide) no crossed triangle is missed.
        let crossed: Vec<u32> = (0..tris.len() as u32)
            .filter(|&t| {
                (0..=580).any(|i| contains(tris[t as usize], [0.206 + 0.001 * i as f64, 0.52, 0.0]))
            })
            .collect();
        assert_eq!(got, crossed);
        assert!(expected.iter().all(|t| got.contains(t)));
        // Rays beside the sheet miss.
        assert!(caster.cast(cam.project([1.5, 0.5, 0.0]).unwrap()).is_none());
    }

    #[test]
    fn anchors_turn_the_darker_left_side_deeper() {
        let (topo, frame, cam) = setup();
        let caster = MeshCaster::new(&topo, &frame, &cam).unwrap();
        // An image edge walking down (+v); its left in the image is +u, i.e. world +x.
        let image: Vec<[f64; 2]> = (0..40).map(|i| [200.0, 120.0 + 4.0 * i as f64]).collect();
        let (hits, _) = caster.cast_polyline(&image, 0.5, 0.2);
        let normals = geometry::triangle_normals(&topo, &frame);
        let anchors = edge_anchors(&hits, &normals, 0.5);
        assert!(anchors.len() >= 5);
        let to_cam = [0.0, 0.0, 1.0];
        for a in &anchors {
            // Rodrigues: rotate the camera-facing normal by the anchor.
            let (s, c) = a.angle.sin_cos();
            let k = a.axis;
            let r = vec3::add(
                vec3::add(
                    vec3::scale(to_cam, c),
                    vec3::scale(vec3::cross(k, to_cam), s),
                ),
                vec3::scale(k, vec3::dot(k, to_cam) * (1.0 - c)),
            );
            // Tilted towards world +x (the left side): the surface descends (away from the camera) to the left.
            assert!(r[0] > 0.4 && r[1].abs() < 1e-6, "{a:?} {r:?}");
        }
    }

    #[test]
    fn angle_is_inversely_proportional_to_width() {
        let p = VideoParams::default();
        assert!((angle_for(1.0, 1.0, 3.0, &p).to_degrees() - 60.0).abs() < 1e-9);
        assert!((angle_for(3.0, 1.0, 3.0, &p).to_degrees() - 30.0).abs() < 1e-9);
        assert!((angle_for(2.0, 1.0, 3.0, &p).to_degrees() - 40.0).abs() < 1e-9);
    }
}

//! Which camera a triangle's anchors come from when every camera is analysed
//! ([`super::VideoParams::all_views`], off by default).
//!
//! Popa et al. pick one front and one back view. That covers a sheet, but not a tube: with cameras in a ring
//! around a sleeve, the front and back cameras see its sides edge-on, where pairs are dropped as silhouette, so
//! about half of the tube gets no anchors. With `all_views`, every camera that sees the garment is analysed and
//! each triangle keeps only the anchors of the camera that sees it most squarely among those that see it at all
//! (not hidden by other cloth, inside the image): there its fold edges are the least foreshortened, so the
//! pair's width (which sets the angle) and direction are measured best, and two cameras never stack their
//! rotations on one triangle. The choice does not depend on the order of the cameras.

use super::project::MeshCaster;
use crate::mesh::Topology;
use crate::vec3::{self, V3};

/// The per-frame ownership test over the analysed views.
pub struct Ownership<'a> {
    casters: &'a [MeshCaster],
    centroids: Vec<V3>,
    /// Distance within which another camera's first hit still counts as seeing the triangle (an `f32` ray cast
    /// along a shared edge may land on the neighbour).
    tol: f64,
}

impl<'a> Ownership<'a> {
    /// `casters[v]` casts the rays of view `v` on the frame `positions`; `h` is the frame's mean edge length.
    pub fn new(topo: &Topology, positions: &[V3], casters: &'a [MeshCaster], h: f64) -> Self {
        let centroids = topo
            .triangles()
            .iter()
            .map(|t| {
                let s = t
                    .iter()
                    .fold([0.0; 3], |a, &i| vec3::add(a, positions[i as usize]));
                vec3::scale(s, 1.0 / 3.0)
            })
            .collect();
        Ownership {
            casters,
            centroids,
            tol: 0.25 * h,
        }
    }

    /// Whether view `v` may anchor triangle `tri`: no other view that sees the triangle's centroid sees it more
    /// squarely (ties go to the lower view index).
    pub fn owns(&self, v: usize, tri: u32) -> bool {
        let (Some(caster), Some(&c)) = (self.casters.get(v), self.centroids.get(tri as usize))
        else {
            return false;
        };
        let mine = caster.facing(tri, c);
        self.casters.iter().enumerate().all(|(k, other)| {
            k == v
                || match other.visible_facing(tri, c, self.tol) {
                    Some(f) => f < mine || (f == mine && v < k),
                    None => true,
                }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::{Camera, Projection};

    /// An open tube along x and four cameras in a ring around it: away from the diagonals, every triangle is
    /// owned by exactly one camera, the one facing its outward side most squarely; the camera on the far side
    /// (which sees the triangle's back through nothing but cloth) never sees it; all four sides are covered.
    #[test]
    fn each_triangle_belongs_to_the_camera_facing_it_most_squarely() {
        let (nu, nv) = (48usize, 12usize);
        let mut p = Vec::new();
        for j in 0..=nv {
            for i in 0..nu {
                let a = std::f64::consts::TAU * i as f64 / nu as f64;
                p.push([0.1 * j as f64, 0.3 * a.cos(), 0.3 * a.sin()]);
            }
        }
        let mut tris = Vec::new();
        for j in 0..nv {
            for i in 0..nu {
                let (a, b) = ((j * nu + i) as u32, (j * nu + (i + 1) % nu) as u32);
                let (c, d) = (a + nu as u32, b + nu as u32);
                tris.push([a, b, d]);
                tris.push([a, d, c]);
            }
        }
        let topo = Topology::new(p.len(), tris).unwrap();
        let dirs: [V3; 4] = [
            [0.0, 0.0, 1.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, -1.0],
            [0.0, -1.0, 0.0],
        ];
        let (lo, hi) = crate::mesh::geometry::bounding_box(&p);
        // Each camera sits on the side `d` and looks along -d.
        let cams: Vec<_> = dirs
            .iter()
            .map(|&d| {
                Camera::fit(lo, hi, vec3::scale(d, -1.0), [1.0, 0.0, 0.0], 400, 400).calibrated()
            })
            .collect();
        let casters: Vec<MeshCaster> = cams
            .iter()
            .map(|c| MeshCaster::new(&topo, &p, c).unwrap())
            .collect();
        let h = crate::folds::stretch::mean_edge_length(&topo, &p);
        let own = Ownership::new(&topo, &p, &casters, h);
        let mut per_camera = [0usize; 4];
        for t in 0..topo.n_triangles() {
            let c = own.centroids[t];
            let out = vec3::normalize([0.0, c[1], c[2]]);
            // Signed: a camera on the other side of the tube scores below zero.
            let score = |k: usize| vec3::dot(out, vec3::normalize(vec3::sub(cams[k].center(), c)));
            let best = (0..4)
                .max_by(|&a, &b| score(a).total_cmp(&score(b)))
                .unwrap();
            let margin = (0..4)
                .filter(|&k| k != best)
                .map(|k| score(best) - score(k))
                .fold(f64::INFINITY, f64::min);
            if margin > 0.05 {
                let owners: Vec<usize> = (0..4).filter(|&v| own.owns(v, t as u32)).collect();
                assert_eq!(owners, vec![best], "triangle {t}");
                per_camera[best] += 1;
            }
            for k in (0..4).filter(|&k| score(k) < -0.5) {
                assert!(
                    casters[k].visible_facing(t as u32, c, 0.25 * h).is_none(),
                    "triangle {t} is seen through the tube by camera {k}"
                );
            }
        }
        assert!(per_camera.iter().all(|&n| n > 100), "{per_camera:?}");
    }
}

//! Which camera a triangle's anchors come from when every camera is analysed
//! ([`super::Views::All`], not the default).
//!
//! Popa et al. pick one front and one back view. That covers a sheet, but not a tube: with cameras in a ring
//! around a sleeve, the front and back cameras see its sides edge-on, where pairs are dropped as silhouette, so
//! about half of the tube gets no anchors. With `views = all`, every camera that sees the garment is analysed and
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

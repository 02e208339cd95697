//! Which cameras a frame's anchors come from when the views are chosen by coverage
//! ([`super::Views::Cover`], the default).
//!
//! Popa et al. analyse one front and one back view. That covers a sheet, whose two faces those views see
//! head-on, but not a tube in a ring of cameras: the front and back cameras see its sides edge-on, where fold
//! pairs are foreshortened or dropped as silhouette, so part of the tube gets no anchors. Analysing every camera
//! and letting the squarest one own each triangle ([`super::ownership`]) helps the tube but hurts the sheet, where
//! an oblique camera that found nothing takes triangles from the front view that found a fold.
//!
//! So the views are chosen as a set cover. A camera sees a triangle *squarely* when the triangle is visible to it
//! (inside the image, not hidden by other cloth) and its normal is within `acos(square_cos)` of the viewing ray
//! (the default 0.5, 60°, is where a fold's width shrinks to half in the image). The front and back views come
//! first; then, greedily, the camera that sees squarely the most garment area no chosen view sees squarely is
//! added, while that area is at least `min_cover_gain` of the garment. The primary views keep every triangle
//! one of them sees squarely, exactly as with two views; a triangle they see only obliquely (or not at all) is
//! owned by the chosen camera that sees it most squarely. A sheet keeps its front and back views alone; a tube
//! gets the extra views only on its sides.

use super::project::MeshCaster;
use crate::mesh::{geometry, Topology};
use crate::vec3::{self, V3};

/// The views of one frame chosen by coverage, and which of them may anchor each triangle.
#[derive(Debug, Clone, PartialEq)]
pub struct Cover {
    /// Camera indices: the primary views (front, back) first, then the added ones in the order they were added.
    pub cameras: Vec<usize>,
    /// How many of `cameras` are primary views.
    pub primary: usize,
    /// Per triangle: `None` when a primary view sees it squarely (or no chosen view sees it), so the primary
    /// views anchor it as with two views; else the camera that owns it.
    owner: Vec<Option<usize>>,
    /// Fraction of the garment's area the primary views see squarely.
    pub primary_fraction: f64,
    /// Fraction of the garment's area some chosen view sees squarely.
    pub covered_fraction: f64,
}

/// Per camera, per triangle: |cos| between the triangle's normal and the viewing ray to its centroid, where the
/// camera sees the centroid on the triangle; `None` where it does not.
pub fn visibility(
    topo: &Topology,
    positions: &[V3],
    caster: &MeshCaster,
    tol: f64,
) -> Vec<Option<f64>> {
    topo.triangles()
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let s = t
                .iter()
                .fold([0.0; 3], |a, &v| vec3::add(a, positions[v as usize]));
            caster.visible_facing(i as u32, vec3::scale(s, 1.0 / 3.0), tol)
        })
        .collect()
}

/// Chooses the views of a frame. `seen[k]` is [`visibility`] for camera `candidates[k]`; `primary` lists the
/// front and back cameras (each must be a candidate to count); `areas` are the triangle areas.
pub fn choose(
    candidates: &[usize],
    seen: &[Vec<Option<f64>>],
    primary: &[usize],
    areas: &[f64],
    square_cos: f64,
    min_cover_gain: f64,
) -> Cover {
    let nt = areas.len();
    let total: f64 = areas.iter().sum::<f64>().max(f64::MIN_POSITIVE);
    let square =
        |k: usize, t: usize| seen[k].get(t).copied().flatten().unwrap_or(-1.0) >= square_cos;
    let index = |c: usize| candidates.iter().position(|&x| x == c);
    let mut chosen: Vec<usize> = Vec::new();
    for &c in primary {
        if let Some(k) = index(c) {
            if !chosen.contains(&k) {
                chosen.push(k);
            }
        }
    }
    let n_primary = chosen.len();
    let mut covered: Vec<bool> = (0..nt)
        .map(|t| chosen.iter().any(|&k| square(k, t)))
        .collect();
    let fraction = |covered: &[bool]| {
        covered
            .iter()
            .zip(areas)
            .filter(|(c, _)| **c)
            .map(|(_, a)| a)
            .sum::<f64>()
            / total
    };
    let primary_fraction = fraction(&covered);
    loop {
        // Ties go to the lower camera index, so the choice does not depend on the candidates' order.
        let best = (0..candidates.len())
            .filter(|k| !chosen.contains(k))
            .map(|k| {
                let gain: f64 = (0..nt)
                    .filter(|&t| !covered[t] && square(k, t))
                    .map(|t| areas[t])
                    .sum();
                (k, gain / total)
            })
            .max_by(|a, b| {
                a.1.total_cmp(&b.1)
                    .then(candidates[b.0].cmp(&candidates[a.0]))
            });
        match best {
            Some((k, gain)) if gain >= min_cover_gain && gain > 0.0 => {
                chosen.push(k);
                for (t, c) in covered.iter_mut().enumerate() {
                    *c = *c || square(k, t);
                }
            }
            _ => break,
        }
    }
    let covered_fraction = fraction(&covered);
    let owner = (0..nt)
        .map(|t| {
            if chosen[..n_primary].iter().any(|&k| square(k, t)) {
                return None;
            }
            // The squarest chosen view that sees the triangle; ties to the lower camera index.
            chosen
                .iter()
                .filter_map(|&k| seen[k].get(t).copied().flatten().map(|f| (k, f)))
                .max_by(|a, b| {
                    a.1.total_cmp(&b.1)
                        .then(candidates[b.0].cmp(&candidates[a.0]))
                })
                .map(|(k, _)| candidates[k])
        })
        .collect();
    Cover {
        cameras: chosen.iter().map(|&k| candidates[k]).collect(),
        primary: n_primary,
        owner,
        primary_fraction,
        covered_fraction,
    }
}

impl Cover {
    /// Whether `camera`'s anchors may stay on triangle `tri`.
    pub fn allows(&self, camera: usize, tri: u32) -> bool {
        match self.owner.get(tri as usize) {
            Some(Some(owner)) => *owner == camera,
            _ => self.cameras[..self.primary].contains(&camera),
        }
    }

    /// The cameras added to the primary views.
    pub fn added(&self) -> &[usize] {
        &self.cameras[self.primary..]
    }
}

/// [`choose`] over the cameras of `casters` (camera index, its caster for this frame).
pub fn cover_frame(
    topo: &Topology,
    positions: &[V3],
    casters: &[(usize, &MeshCaster)],
    primary: &[usize],
    square_cos: f64,
    min_cover_gain: f64,
) -> Cover {
    let h = crate::folds::stretch::mean_edge_length(topo, positions);
    let seen: Vec<Vec<Option<f64>>> = casters
        .iter()
        .map(|(_, c)| visibility(topo, positions, c, 0.25 * h))
        .collect();
    let candidates: Vec<usize> = casters.iter().map(|(c, _)| *c).collect();
    let areas = geometry::triangle_areas(topo, positions);
    choose(
        &candidates,
        &seen,
        primary,
        &areas,
        square_cos,
        min_cover_gain,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::{Camera, Projection};

    /// Cameras framing the box `[lo, hi]`, one per viewing direction.
    fn cameras(lo: V3, hi: V3, dirs: &[V3], up: V3) -> Vec<crate::render::CalibratedCamera> {
        dirs.iter()
            .map(|&d| Camera::fit(lo, hi, d, up, 320, 320).calibrated())
            .collect()
    }

    fn cover_of(
        topo: &Topology,
        p: &[V3],
        cams: &[crate::render::CalibratedCamera],
        primary: &[usize],
    ) -> Cover {
        let casters: Vec<MeshCaster> = cams
            .iter()
            .map(|c| MeshCaster::new(topo, p, c).unwrap())
            .collect();
        let refs: Vec<(usize, &MeshCaster)> = casters.iter().enumerate().collect();
        cover_frame(topo, p, &refs, primary, 0.5, 0.1)
    }

    /// A sheet seen head-on by its front and back views needs no other camera, even with oblique cameras that
    /// see it too: the front and back anchor every triangle, as with Popa's two views.
    #[test]
    fn a_sheet_keeps_its_front_and_back_views_only() {
        let (topo, mut p) = crate::synth::sheet(21, 21, 0.05).unwrap();
        // A gentle pleat (slopes under 30°), as a hanging sheet has.
        for q in p.iter_mut() {
            q[2] = 0.03 * (2.0 * std::f64::consts::PI * q[0] / 0.5).sin();
        }
        let (lo, hi) = geometry::bounding_box(&p);
        let dirs = [
            [0.1, 0.0, -1.0],
            [0.8, 0.2, -1.0],
            [-0.1, 0.1, 1.0],
            [-0.7, -0.3, 1.0],
        ];
        let cams = cameras(lo, hi, &dirs, [0.0, 1.0, 0.0]);
        let cover = cover_of(&topo, &p, &cams, &[0, 2]);
        assert_eq!(cover.cameras, vec![0, 2], "{cover:?}");
        assert!(cover.added().is_empty());
        assert!(cover.primary_fraction > 0.99, "{}", cover.primary_fraction);
        for t in 0..topo.n_triangles() as u32 {
            assert!(cover.allows(0, t) && cover.allows(2, t));
            assert!(!cover.allows(1, t) && !cover.allows(3, t));
        }
    }

    /// A tube in a ring of four cameras 90° apart: the front and back views see its sides edge-on, so the two
    /// side cameras are added, and each anchors only the side it faces; the front and back keep the rest.
    #[test]
    fn a_tube_in_a_ring_of_cameras_gets_every_side_covered() {
        let seq = crate::synth::compressed_tube(6000, 1, 0.0, 0.0).unwrap();
        let topo = seq.topology.clone();
        let p = seq.frames[0].clone();
        let (lo, hi) = geometry::bounding_box(&p);
        // Cameras at +x, +y, -x, -y looking at the tube's axis (z); front = +x, back = -x.
        let dirs = [
            [-1.0, 0.0, 0.0],
            [0.0, -1.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        let cams = cameras(lo, hi, &dirs, [0.0, 0.0, 1.0]);
        let cover = cover_of(&topo, &p, &cams, &[0, 2]);
        let mut added = cover.added().to_vec();
        added.sort();
        assert_eq!(added, vec![1, 3], "{cover:?}");
        // Front and back see about two thirds of the tube within 60° (a little less: the cameras are at a finite
        // distance, and the tube's columns are 14° wide); with the sides, all of it.
        assert!(
            cover.primary_fraction > 0.55 && cover.primary_fraction < 0.7,
            "{}",
            cover.primary_fraction
        );
        assert!(cover.covered_fraction > 0.99, "{}", cover.covered_fraction);
        let normals = geometry::triangle_normals(&topo, &p);
        let centroid = |t: usize| {
            let s = topo.triangles()[t]
                .iter()
                .fold([0.0; 3], |a, &v| vec3::add(a, p[v as usize]));
            vec3::scale(s, 1.0 / 3.0)
        };
        let (mut sides, mut fronts) = (0, 0);
        for (t, &n) in normals.iter().enumerate() {
            let c = centroid(t);
            let allowed: Vec<usize> = (0..4).filter(|&k| cover.allows(k, t as u32)).collect();
            if n[0].abs() >= 0.7 {
                // Seen squarely by the front or the back view: both primary views may anchor it.
                assert_eq!(allowed, vec![0, 2], "triangle {t} n {n:?}");
                fronts += 1;
            } else if n[0].abs() <= 0.3 {
                // A side: only the side camera on its side.
                let want = if c[1] > 0.0 { 1 } else { 3 };
                assert_eq!(allowed, vec![want], "triangle {t} n {n:?}");
                sides += 1;
            }
        }
        assert!(sides > topo.n_triangles() / 8 && fronts > topo.n_triangles() / 3);
    }

    /// The choice depends on the cameras, not on the order they are listed in.
    #[test]
    fn the_choice_does_not_depend_on_the_camera_order() {
        let seq = crate::synth::compressed_tube(3000, 1, 0.0, 0.0).unwrap();
        let topo = seq.topology.clone();
        let p = seq.frames[0].clone();
        let (lo, hi) = geometry::bounding_box(&p);
        let dirs = [
            [-1.0, 0.0, 0.0],
            [0.0, -1.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        let cams = cameras(lo, hi, &dirs, [0.0, 0.0, 1.0]);
        let casters: Vec<MeshCaster> = cams
            .iter()
            .map(|c| MeshCaster::new(&topo, &p, c).unwrap())
            .collect();
        let forward: Vec<(usize, &MeshCaster)> = casters.iter().enumerate().collect();
        let backward: Vec<(usize, &MeshCaster)> = forward.iter().rev().copied().collect();
        let a = cover_frame(&topo, &p, &forward, &[0, 2], 0.5, 0.1);
        let b = cover_frame(&topo, &p, &backward, &[0, 2], 0.5, 0.1);
        assert_eq!(a, b);
    }
}

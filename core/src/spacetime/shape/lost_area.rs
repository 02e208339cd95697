//! How much surface the capture lost, and no more output than gives it back (Chen 2011's integrated shrinkage,
//! used as a bound).
//!
//! The relief ([`super::relief`]) undoes a generic low-pass whose strength crease cannot know, and the anchors
//! of a detector turn triangles wherever it sees shrinkage. On a capture that kept its folds (a sharp scan, a
//! capture with noise but no smoothing) both would add folds that are already there, and the output would be
//! further from the cloth than the input. Cloth barely stretches, so a capture that lost a fold shows it as lost
//! surface: the region's captured area is smaller than in the frames where the same cloth lies open. A capture
//! that kept its folds shows none, whatever its noise: area is a sum over many triangles, and noise, which
//! moves vertices both ways, changes it only at second order.
//!
//! Per vertex, the **rest area** is the largest area its neighbourhood shows over the whole sequence (the
//! vertex's share of its triangles, averaged over a few rings so that one frame's noise cannot set it). In
//! frame t the **lost fraction** is 1 − a_t / a_rest, and the output's **added fraction** is how much the
//! neighbourhood's area grew from the captured frame to the output. Where the output adds more than was lost,
//! its displacement is scaled by lost / added (the area a displacement adds grows about with its square, so
//! the scaled one gives back at most that share of what was lost: a bound, not a fit); where it adds less, it
//! is left as it is. A capture that lost nothing comes back as captured. Lost fractions within the capture's
//! own noise (measured over time, as the relief measures its noise) do not count. On the public data the lost fraction
//! separates the captures cleanly: its mean is 1–3 % for the ground truth with or without reconstruction
//! noise, 6–14 % for every smoothed capture.
//!
//! Per vertex that is not enough: real cloth also loses some surface without folding (it compresses), and on a
//! capture that kept its folds the deformation would sharpen them within that allowance. The frame as a whole
//! tells the two apart ([`trust`]): where the capture lost folds, most of the surface the deformation adds is
//! surface it lost; where it kept them, little is. A frame below [`TRUST_NONE`] comes back as captured.
//!
//! The same measure says where the capture kept no trace of the surface it lost ([`RestAreas::trace`]): the
//! relief gives back what a capture damped, so where it gives back almost none of what was lost there, the
//! capture erased the fold outright and only the anchors can make it; the positioning's shape screen may then
//! let go there (`deform.release_share`), the shading refinement of video jobs follows the images further there
//! ([`crate::shading_refine::ShadingRefineParams::erased_stay`]), and the report gives each frame's share so a
//! user can tell.
//!
//! Everything is measured on the captured frames and the frame's own output; the result is a pure function of
//! the input sequence and that frame.

use crate::mesh::{geometry, FrameSource, Topology};
use crate::vec3;
use crate::{Error, Result};
use rayon::prelude::*;

/// A frame's deformation is given back whole only where at least this share of the surface it adds is surface
/// the capture lost ([`trust`]).
pub const TRUST_FULL: f64 = 0.25;

/// Below this share the frame comes back as captured: what the deformation adds lands where nothing was lost,
/// so the capture kept its folds and anything added is a fold drawn twice.
pub const TRUST_NONE: f64 = 0.1;

/// Smoothing rounds (half the vertex, half its one-ring mean) of the per-vertex areas: a few rings, so that the
/// area of a neighbourhood, not of one triangle, is compared over time.
const AREA_ROUNDS: usize = 16;

/// Per vertex, the largest smoothed area over the sequence's frames, and how much of a lost fraction is the
/// capture's noise.
#[derive(Debug, Clone, PartialEq)]
pub struct RestAreas {
    rings: Rings,
    rest: Vec<f64>,
    /// Lost fractions up to this are not counted: [`NOISE_MARGIN`] times the spread, measured over time, of
    /// the smoothed areas' part that is new in each frame.
    floor: f64,
}

/// The floor is this many standard deviations of the areas' frame-to-frame noise (the rest area is a maximum
/// over frames, so an open region's lost fraction scatters up to a few of them).
const NOISE_MARGIN: f64 = 3.0;

impl RestAreas {
    /// Reads every frame of `source` (a few at a time, in parallel). Frames that fail validation (they fail
    /// their own positioning with a message naming them) are left out of the maximum.
    ///
    /// The noise of the areas is measured as the relief measures its own: for noise independent between
    /// frames, the second temporal difference a_t − (a_{t−1} + a_{t+1}) / 2 has 3/2 of its variance, while an
    /// area that folds and unfolds at video rates barely changes over one frame. Per frame, the median absolute
    /// relative difference over the vertices; over the sequence, the median of those.
    pub fn of_sequence(source: &dyn FrameSource) -> Result<Self> {
        let topo = source.topology();
        let n = topo.n_vertices();
        let chunk = (2 * rayon::current_num_threads()).max(1);
        let rings = Rings::new(topo);
        let mut rest = vec![0.0f64; n];
        let mut previous: Vec<Vec<f64>> = Vec::new();
        let mut spreads = Vec::new();
        for start in (0..source.n_frames()).step_by(chunk) {
            let end = (start + chunk).min(source.n_frames());
            let parts: Vec<Option<Vec<f64>>> = (start..end)
                .into_par_iter()
                .map(|t| match source.read_frame(t) {
                    Ok(p) => Ok(Some(rings.smoothed_areas(topo, &p))),
                    Err(Error::Mesh { .. } | Error::Format { .. }) => Ok(None),
                    Err(e) => Err(e),
                })
                .collect::<Vec<Result<_>>>()
                .into_iter()
                .collect::<Result<_>>()?;
            for part in parts {
                let Some(a) = part else {
                    previous.clear();
                    continue;
                };
                for (r, x) in rest.iter_mut().zip(&a) {
                    if x.is_finite() && *x > *r {
                        *r = *x;
                    }
                }
                if previous.len() == 2 {
                    spreads.extend(median_new_fraction(&previous[0], &previous[1], &a));
                    previous.remove(0);
                }
                previous.push(a);
            }
        }
        spreads.sort_by(|a, b| a.total_cmp(b));
        let floor = match spreads.get(spreads.len() / 2) {
            // Median of |N(0, s²)| is 0.6745 s; the second difference has 3/2 of the noise's variance.
            Some(m) => NOISE_MARGIN * m / 0.6745 / 1.5f64.sqrt(),
            None => 0.0,
        };
        Ok(RestAreas { rings, rest, floor })
    }

    /// From per-vertex rest areas measured elsewhere (tests, or a caller that has them).
    pub fn from_areas(topo: &Topology, rest: Vec<f64>, floor: f64) -> Self {
        RestAreas {
            rings: Rings::new(topo),
            rest,
            floor,
        }
    }

    /// What the relief of captured frame `captured` gives back of the surface the capture lost there
    /// (`relieved`: that frame with the fold relief added along its normals); `None` where the frames do not
    /// have the rest areas' vertex count.
    pub fn trace(
        &self,
        topo: &Topology,
        captured: &[vec3::V3],
        relieved: &[vec3::V3],
    ) -> Option<Trace> {
        let (before, fractions) = self.fractions(topo, captured, relieved)?;
        let vertices = fractions
            .iter()
            .zip(&before)
            .map(|(f, a0)| {
                f.filter(|(lost, _)| *lost > 0.0)
                    .map(|(l, g)| (l, g.max(0.0), *a0))
            })
            .collect();
        Some(Trace { vertices })
    }

    /// The captured frame's smoothed areas and, per vertex, its lost fraction against the rest areas and the
    /// fraction `other` adds to its area (None where an area is degenerate); `None` where the frames do not have
    /// the rest areas' vertex count.
    #[allow(clippy::type_complexity)]
    fn fractions(
        &self,
        topo: &Topology,
        captured: &[vec3::V3],
        other: &[vec3::V3],
    ) -> Option<(Vec<f64>, Vec<Option<(f64, f64)>>)> {
        if self.rest.len() != captured.len() || other.len() != captured.len() {
            return None;
        }
        let before = self.rings.smoothed_areas(topo, captured);
        let after = self.rings.smoothed_areas(topo, other);
        let fractions = (0..captured.len())
            .map(|v| {
                let (rest, a0, a1) = (self.rest[v], before[v], after[v]);
                (rest > 0.0 && a0 > 0.0 && a1.is_finite())
                    .then(|| ((1.0 - a0 / rest - self.floor).max(0.0), a1 / a0 - 1.0))
            })
            .collect();
        Some((before, fractions))
    }

    /// The lost fraction below which nothing counts as lost (the capture's noise), for reports and tests.
    pub fn floor(&self) -> f64 {
        self.floor
    }

    /// `out`'s displacement from `captured` scaled down, per vertex, where it adds more area than the frame
    /// lost against the rest areas, and as a whole by the frame's [`trust`]. Returns the share of the added
    /// surface that was lost (1 where nothing was added); `None`, with `out` untouched, where the frames do not
    /// have the rest areas' vertex count (nothing was judged).
    pub fn limit(
        &self,
        topo: &Topology,
        captured: &[vec3::V3],
        out: &mut [vec3::V3],
    ) -> Option<f64> {
        // Per vertex: the lost and the added fraction (None where an area is degenerate).
        let (before, shares) = self.fractions(topo, captured, out)?;
        // The share of the added surface (in area, not per vertex) that the capture had lost.
        let (mut justified, mut added_area) = (0.0, 0.0);
        for (share, a0) in shares.iter().zip(&before) {
            if let Some((lost, added)) = *share {
                let added = added.max(0.0);
                justified += lost.min(added) * a0;
                added_area += added * a0;
            }
        }
        let lost_share = if added_area > 0.0 {
            justified / added_area
        } else {
            1.0
        };
        let whole = trust(lost_share);
        for ((o, c), share) in out.iter_mut().zip(captured).zip(&shares) {
            let scale = match *share {
                None => 0.0,
                Some((lost, added)) if added > lost => whole * lost / added,
                Some(_) => whole,
            };
            if scale != 1.0 {
                *o = vec3::add(*c, vec3::scale(vec3::sub(*o, *c), scale));
            }
        }
        Some(lost_share)
    }
}

/// What a frame's relief gives back of the surface its capture lost ([`RestAreas::trace`]): per vertex that lost
/// surface, the lost and the given-back fractions and the captured area.
#[derive(Debug, Clone, PartialEq)]
pub struct Trace {
    vertices: Vec<Option<(f64, f64, f64)>>,
}

impl Trace {
    /// The share of the frame's lost surface (in area) that the relief gives back, at most all of it at each
    /// vertex; `None` where the frame lost none. A capture that blurred its folds keeps an attenuated copy for
    /// the relief to sharpen (a quarter to three fifths, per sequence, on every smoothed capture measured); one
    /// that erased them keeps nothing of them (about a hundredth).
    pub fn share(&self) -> Option<f64> {
        let (mut lost, mut given) = (0.0, 0.0);
        for &(l, g, a) in self.vertices.iter().flatten() {
            lost += l * a;
            given += g.min(l) * a;
        }
        (lost > 0.0).then(|| given / lost)
    }

    /// Per vertex, the share of the surface lost there that the relief gives back (at most 1); `None` where the
    /// vertex lost none.
    pub fn given_back(&self) -> Vec<Option<f64>> {
        self.vertices
            .iter()
            .map(|v| v.map(|(lost, given, _)| (given / lost).min(1.0)))
            .collect()
    }

    /// Per vertex, how far the positioning's shape screen and projection hold (1: fully, 0: not at all): 1 where
    /// the capture lost no surface or the relief gives back at least `share` of what it lost there, falling in
    /// proportion to 0 where the relief gives back none of it. `None` when `share` is 0 (the screen holds
    /// everywhere).
    ///
    /// Why: the screen holds long wavelengths to the capture, and a fold the capture erased outright (its
    /// footprint kept, its height gone) is a rise as wide as the band that lost length, which the screen cannot
    /// tell from a drift of the garment. Where the capture kept an attenuated copy, the relief restores it and
    /// the screen rightly keeps the anchors' less precise folds small; where it kept nothing, the anchors are the
    /// only source of the fold and the lost-area bound ([`RestAreas::limit`]) still caps what they add.
    pub fn hold(&self, share: f64) -> Option<Vec<f64>> {
        (share > 0.0).then(|| {
            self.vertices
                .iter()
                .map(|v| {
                    v.map_or(1.0, |(lost, given, _)| {
                        (given / lost / share).clamp(0.0, 1.0)
                    })
                })
                .collect()
        })
    }
}

/// How much of a frame's deformation stands, from the share of the surface it adds that the capture had lost:
/// none below [`TRUST_NONE`], all from [`TRUST_FULL`], linear between.
///
/// The per-vertex bound alone lets through as much surface as each neighbourhood lost, and real cloth loses
/// some surface without folding (it compresses: the public sleeve's own ground truth loses up to a quarter of a
/// neighbourhood's area at the elbow, 5 % at the 90th percentile). On a capture that kept its folds the
/// deformation then sharpens folds that are already there, within that allowance. The frame as a whole tells
/// the two apart: a capture that lost its folds lost surface exactly where the folds go back, so most of what the
/// deformation adds is surface it lost (a third to nine tenths, per frame, on every smoothed capture measured);
/// on one that kept them, what is added lands where nothing was lost (about a twentieth).
pub fn trust(lost_share: f64) -> f64 {
    ((lost_share - TRUST_NONE) / (TRUST_FULL - TRUST_NONE)).clamp(0.0, 1.0)
}

/// The median over vertices of |b − (a + c) / 2| / b: the part of the middle frame's smoothed areas that is
/// new in it, relative to them.
fn median_new_fraction(a: &[f64], b: &[f64], c: &[f64]) -> Option<f64> {
    let mut d: Vec<f64> = (0..b.len())
        .filter(|&v| b[v] > 0.0 && (a[v] + c[v]).is_finite())
        .map(|v| (b[v] - 0.5 * (a[v] + c[v])).abs() / b[v])
        .collect();
    if d.is_empty() {
        return None;
    }
    let mid = d.len() / 2;
    let (_, m, _) = d.select_nth_unstable_by(mid, |x, y| x.total_cmp(y));
    Some(*m)
}

/// Every vertex's one ring, once (compressed rows): the areas are smoothed over it many times a frame.
#[derive(Debug, Clone, PartialEq)]
struct Rings {
    start: Vec<usize>,
    neighbours: Vec<u32>,
}

impl Rings {
    fn new(topo: &Topology) -> Self {
        let mut start = Vec::with_capacity(topo.n_vertices() + 1);
        let mut neighbours = Vec::new();
        start.push(0);
        for v in 0..topo.n_vertices() {
            neighbours.extend(topo.vertex_neighbors(v));
            start.push(neighbours.len());
        }
        Rings { start, neighbours }
    }

    /// Each vertex's third of its triangles' areas, averaged over [`AREA_ROUNDS`] rounds of half itself, half
    /// its one-ring mean.
    fn smoothed_areas(&self, topo: &Topology, p: &[vec3::V3]) -> Vec<f64> {
        let mut area = vec![0.0; p.len()];
        for (tri, a) in topo
            .triangles()
            .iter()
            .zip(geometry::triangle_areas(topo, p))
        {
            for &v in tri {
                area[v as usize] += a / 3.0;
            }
        }
        let mut next = vec![0.0; p.len()];
        for _ in 0..AREA_ROUNDS {
            for (v, x) in next.iter_mut().enumerate() {
                let ring = &self.neighbours[self.start[v]..self.start[v + 1]];
                *x = if ring.is_empty() {
                    area[v]
                } else {
                    let sum: f64 = ring.iter().map(|&u| area[u as usize]).sum();
                    0.5 * area[v] + 0.5 * sum / ring.len() as f64
                };
            }
            std::mem::swap(&mut area, &mut next);
        }
        area
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::heat::tests::waved_grid;
    use crate::spacetime::shape::relief::add_heights;

    fn smoothed_areas(topo: &Topology, p: &[vec3::V3]) -> Vec<f64> {
        Rings::new(topo).smoothed_areas(topo, p)
    }

    fn ripple(topo: &Topology, flat: &[vec3::V3], amp: f64) -> Vec<vec3::V3> {
        let h: Vec<f64> = flat.iter().map(|p| amp * (p[0] * 1.1).sin()).collect();
        add_heights(topo, flat, flat, &h)
    }

    #[test]
    fn a_capture_that_lost_no_area_comes_back_and_one_that_lost_more_keeps_the_folds() {
        let (topo, flat) = waved_grid(24, 24, 8.0, 0.0);
        let folded = ripple(&topo, &flat, 0.2);
        // Rest = the flat frame's own areas: nothing lost, so nothing may be added.
        let mut out = folded.clone();
        RestAreas::from_areas(&topo, smoothed_areas(&topo, &flat), 0.0)
            .limit(&topo, &flat, &mut out);
        assert_eq!(out, flat);
        // Rest = 1.5 × the frame's areas: a third was lost, more than the ripple adds, so it stays whole.
        let mut out = folded.clone();
        let larger = smoothed_areas(&topo, &flat)
            .iter()
            .map(|a| 1.5 * a)
            .collect();
        RestAreas::from_areas(&topo, larger, 0.0).limit(&topo, &flat, &mut out);
        assert_eq!(out, folded);
    }

    /// The rest areas of a frame that lost `share` of what `folded` adds to `flat`, at every vertex.
    fn rest_losing(
        topo: &Topology,
        flat: &[vec3::V3],
        folded: &[vec3::V3],
        share: f64,
    ) -> Vec<f64> {
        let a0 = smoothed_areas(topo, flat);
        let a1 = smoothed_areas(topo, folded);
        a0.iter()
            .zip(&a1)
            .map(|(a, b)| a / (1.0 - share * (b / a - 1.0)))
            .collect()
    }

    fn assert_scaled(out: &[vec3::V3], flat: &[vec3::V3], folded: &[vec3::V3], scale: f64) {
        for ((o, f), p) in out.iter().zip(folded).zip(flat) {
            let want = vec3::add(*p, vec3::scale(vec3::sub(*f, *p), scale));
            assert!(vec3::norm(vec3::sub(*o, want)) < 1e-9, "{o:?} vs {want:?}");
        }
    }

    #[test]
    fn the_bound_scales_the_displacement_to_the_lost_share() {
        let (topo, flat) = waved_grid(24, 24, 8.0, 0.0);
        let folded = ripple(&topo, &flat, 0.3);
        // Lost: half of what the ripple adds, at every vertex; the frame is trusted whole.
        let rest = rest_losing(&topo, &flat, &folded, 0.5);
        let mut out = folded.clone();
        let share = RestAreas::from_areas(&topo, rest, 0.0)
            .limit(&topo, &flat, &mut out)
            .unwrap();
        assert!((share - 0.5).abs() < 1e-9, "lost share {share}");
        assert_scaled(&out, &flat, &folded, 0.5);
    }

    /// The screen holds where nothing was lost and where the relief gives the lost surface back, and lets go in
    /// proportion where it gives back less than the share.
    #[test]
    fn the_screen_lets_go_only_where_the_relief_gives_back_little_of_what_was_lost() {
        let (topo, flat) = waved_grid(24, 24, 8.0, 0.0);
        let folded = ripple(&topo, &flat, 0.3);
        let a0 = smoothed_areas(&topo, &flat);
        let patch = |v: usize| flat[v][0] < 8.0;
        // The patch lost what the full ripple adds; elsewhere nothing was lost.
        let rest: Vec<f64> = rest_losing(&topo, &flat, &folded, 1.0)
            .into_iter()
            .enumerate()
            .map(|(v, r)| if patch(v) { r } else { a0[v] })
            .collect();
        let areas = RestAreas::from_areas(&topo, rest, 0.0);
        let trace = |relieved: &[vec3::V3]| areas.trace(&topo, &flat, relieved).unwrap();
        // The relief gives back nothing: the patch lets go entirely, the rest holds.
        assert_eq!(trace(&flat).share(), Some(0.0));
        let hold = trace(&flat).hold(0.1).unwrap();
        for (v, h) in hold.iter().enumerate() {
            assert_eq!(*h, if patch(v) { 0.0 } else { 1.0 }, "vertex {v}");
        }
        // A relief a quarter as high gives back about a sixteenth of the lost surface: over half the share 0.1.
        let quarter = trace(&ripple(&topo, &flat, 0.075));
        let share = quarter.share().unwrap();
        assert!((0.04..0.09).contains(&share), "share {share}");
        let hold = quarter.hold(0.1).unwrap();
        let inner: Vec<f64> = (0..flat.len())
            .filter(|&v| patch(v) && flat[v][0] > 1.0 && flat[v][1] > 1.0 && flat[v][1] < 22.0)
            .map(|v| hold[v])
            .collect();
        let mean = inner.iter().sum::<f64>() / inner.len() as f64;
        assert!((0.4..0.8).contains(&mean), "mean hold {mean}");
        // The full ripple gives back all of it: everything holds; a share of 0 is no release at all.
        let full = trace(&folded);
        assert!(full.share().unwrap() > 0.99);
        assert!(full.hold(0.1).unwrap().iter().all(|&h| h == 1.0));
        assert!(trace(&flat).hold(0.0).is_none());
        assert!(areas.trace(&topo, &flat[1..], &flat[1..]).is_none());
        // A frame that lost nothing has no share.
        let open = RestAreas::from_areas(&topo, a0.clone(), 0.0);
        assert_eq!(open.trace(&topo, &flat, &folded).unwrap().share(), None);
    }

    /// A frame in which most of what the deformation adds was never lost is trusted less as a whole, down to
    /// nothing: even the part of it that the bound alone would let through goes.
    #[test]
    fn a_frame_whose_added_surface_was_mostly_not_lost_is_given_back() {
        let (topo, flat) = waved_grid(24, 24, 8.0, 0.0);
        let folded = ripple(&topo, &flat, 0.3);
        let between = 0.5 * (TRUST_NONE + TRUST_FULL);
        let rest = rest_losing(&topo, &flat, &folded, between);
        let mut out = folded.clone();
        let share = RestAreas::from_areas(&topo, rest, 0.0)
            .limit(&topo, &flat, &mut out)
            .unwrap();
        assert!((share - between).abs() < 1e-9, "lost share {share}");
        assert_scaled(&out, &flat, &folded, between * 0.5);

        // Lost: everything the ripple adds, but only on a small patch; elsewhere nothing.
        let a0 = smoothed_areas(&topo, &flat);
        let patch = |v: usize| flat[v][0] < 1.5 && flat[v][1] < 1.5;
        let rest: Vec<f64> = rest_losing(&topo, &flat, &folded, 1.0)
            .into_iter()
            .enumerate()
            .map(|(v, r)| if patch(v) { r } else { a0[v] })
            .collect();
        assert!((0..flat.len()).any(patch) && !(0..flat.len()).all(patch));
        let mut out = folded.clone();
        let share = RestAreas::from_areas(&topo, rest, 0.0)
            .limit(&topo, &flat, &mut out)
            .unwrap();
        assert!(share < TRUST_NONE, "lost share {share}");
        assert_eq!(out, flat);
        assert_eq!(trust(TRUST_NONE), 0.0);
        assert_eq!(trust(TRUST_FULL), 1.0);
    }
}

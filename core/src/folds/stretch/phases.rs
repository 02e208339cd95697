//! Phase detection and stretch integration, streamed one frame at a time (Chen 2011 §4.3, §6.1).
//!
//! Each step (previous frame → current frame, in the pass's direction of time) yields a smoothed tensor per
//! triangle. The triangle stays in its phase while consecutive steps agree (eq. 4.2): the dominant directions
//! differ by less than θ0 (compared as angles in the triangle's local frame) and the state — shrinkage or
//! stretch — is unchanged. Isometric steps (|v| < 1 + `isometry`) neither start nor break a phase for up to
//! `max_hold` consecutive frames: that is a fold holding its shape at its peak. Within a phase the shrinkage
//! is not summed step by step but recomputed against the phase's first frame (the *reference*), so noise does
//! not accumulate.
//!
//! Memory is O(triangles): per triangle only the reference layout (3 numbers), the last direction and state,
//! and the hold counter are kept — the thesis' "reference triangle per triangle" — and frames are streamed.
//! A backward pass (time reversed) turns vanishing folds into emerging ones, so only shrinkage is a fold
//! signal in either pass.

use super::params::StretchParams;
use super::smooth::{remove_outliers, smooth, FrameGeometry};
use super::tensor::{
    absolute_change, axial_angle, axial_difference, jacobian, shape, Shape, Tensor,
};
use crate::mesh::Topology;
use crate::vec3::V3;
use rayon::prelude::*;

/// Fold signal of one frame from one pass: integrated shrinkage (absolute change, 1 = none) and its unit
/// direction on the current triangle.
#[derive(Debug, Clone, Default)]
pub struct Signal {
    pub shrink: Vec<f64>,
    pub dir: Vec<V3>,
}

#[derive(Debug, Clone, Copy)]
struct TriState {
    reference: Shape,
    /// Angle of the last non-isometric step's dominant direction in the triangle's local frame.
    last_dir: f64,
    /// −1 shrinkage, +1 stretch, 0 no phase open.
    state: i8,
    hold: u16,
}

/// One pass over the sequence (forward or backward in time).
pub struct PhaseTracker {
    tris: Vec<TriState>,
}

fn triangle(topo: &Topology, p: &[V3], t: usize) -> [V3; 3] {
    topo.triangles()[t].map(|v| p[v as usize])
}

/// The per-triangle tensors of the maps `from → to` (current = `to`), cleaned and smoothed (§4.2).
pub fn smoothed_field(
    topo: &Topology,
    geom: &FrameGeometry,
    shapes: impl Fn(usize) -> Shape + Sync,
    to: &[V3],
    params: &StretchParams,
) -> Vec<Tensor> {
    let mut field: Vec<Option<Tensor>> = (0..topo.n_triangles())
        .into_par_iter()
        .with_min_len(2048)
        .map(|t| jacobian(shapes(t), triangle(topo, to, t)))
        .collect();
    remove_outliers(
        &mut field,
        &geom.normals,
        params.max_change,
        params.tail_fraction,
    );
    smooth(topo, geom, &field, params.smooth_iterations)
}

impl PhaseTracker {
    /// Starts a pass at `first` (the first frame in the pass's time order): no phase is open.
    pub fn new(topo: &Topology, first: &[V3]) -> Self {
        let tris = (0..topo.n_triangles())
            .map(|t| TriState {
                reference: shape(triangle(topo, first, t)),
                last_dir: 0.0,
                state: 0,
                hold: 0,
            })
            .collect();
        PhaseTracker { tris }
    }

    /// Advances the pass by one step, `prev → cur`, and returns the integrated shrinkage at `cur`.
    pub fn step(
        &mut self,
        topo: &Topology,
        prev: &[V3],
        cur: &[V3],
        geom: &FrameGeometry,
        params: &StretchParams,
    ) -> Signal {
        let theta0 = params.theta0_deg.to_radians();
        let step = smoothed_field(topo, geom, |t| shape(triangle(topo, prev, t)), cur, params);
        // Continuity test (eq. 4.2) and reference update, per triangle.
        self.tris
            .par_iter_mut()
            .with_min_len(2048)
            .enumerate()
            .for_each(|(t, st)| {
                let (v, d) = step[t].dominant(geom.normals[t]);
                let change = absolute_change(v);
                if change < 1.0 + params.isometry {
                    st.hold = st.hold.saturating_add(1);
                    if st.state != 0 && st.hold as usize > params.max_hold {
                        // Held too long: the phase is over; the next one starts from here.
                        st.state = 0;
                    }
                    if st.state == 0 {
                        st.reference = shape(triangle(topo, cur, t));
                    }
                    return;
                }
                let s: i8 = if v < 1.0 { -1 } else { 1 };
                let angle = axial_angle(d, geom.e1[t], geom.e2[t]);
                let continuous = st.state == s && axial_difference(angle, st.last_dir) < theta0;
                if !continuous {
                    // Phase boundary: the new phase starts at the previous frame.
                    st.reference = shape(triangle(topo, prev, t));
                    st.state = s;
                }
                st.last_dir = angle;
                st.hold = 0;
            });
        // Integrated tensor: the current triangle against its phase's first frame.
        let tris = &self.tris;
        let integrated = smoothed_field(topo, geom, |t| tris[t].reference, cur, params);
        let (shrink, dir) = integrated
            .par_iter()
            .with_min_len(2048)
            .enumerate()
            .map(|(t, ten)| {
                let (v, d) = ten.dominant(geom.normals[t]);
                if tris[t].state == -1 && v < 1.0 {
                    (1.0 / v, d)
                } else {
                    (1.0, d)
                }
            })
            .unzip();
        Signal { shrink, dir }
    }
}

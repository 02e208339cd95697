//! What the positioning ends with, so that the output keeps the captured shape and gives back the folds the
//! capture damped — without any model of how the capture was made.
//!
//! - [`projection`] — the shape projection: the displacement loses its long wavelengths;
//! - [`relief`] — the fold relief: what a generic deconvolution adds to the captured surface along its normal,
//!   coherent over time and above the capture's noise (estimated from the sequence);
//! - [`lost_area`] — the bound on the relief: no more surface than the capture lost against the sequence's
//!   own rest areas.
//!
//! Both work at one length the sequence is measured by, the **detail scale** ℓ ([`relief::ReliefParams`]): by
//! default five mean edge lengths of the input's first frame, or a length the user gives in the input's units.
//! The shape projection and the positioning's shape screen work at a multiple of it ([`SHAPE_SCALES`]).

pub mod lost_area;
pub mod projection;
pub mod relief;

use crate::heat::{self, SurfaceOperator};
use crate::mesh::Topology;
use crate::vec3::{self, V3};

/// The shape scale (the cutoff of the positioning's screen and the wavelength the projection's low-pass halves)
/// in detail scales, by default.
pub const SHAPE_SCALES: f64 = 2.0;

/// The ending of one sequence's positioning, with its lengths resolved.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShapeEnding {
    /// Fraction of the displacement's low-pass removed (0: no projection).
    pub projection: f64,
    /// Wavelength the projection's low-pass halves, in the input's units.
    pub shape_scale: f64,
    /// Below this share of its lost surface given back by the relief, a vertex's screen and projection let go
    /// (0: they hold everywhere; see [`lost_area::Trace::hold`]).
    pub release_share: f64,
}

impl ShapeEnding {
    /// The projection of a positioned frame `out` of the captured frame `rest`, held per vertex by `hold` where
    /// given ([`lost_area::Trace::hold`]), then the relief `heights` (one per vertex, along the captured
    /// normals; `None`: no relief).
    pub fn finish(
        &self,
        topo: &Topology,
        rest: &[V3],
        out: &[V3],
        heights: Option<&[f64]>,
        hold: Option<&[f64]>,
    ) -> Vec<V3> {
        let projected = if self.projection > 0.0 && out != rest {
            let op = SurfaceOperator::with_rims_along_themselves(topo, rest);
            let low = heat::low_pass(&op, self.shape_scale);
            let projected = projection::project(&op, &low, rest, out, self.projection);
            match hold {
                Some(hold) => out
                    .iter()
                    .zip(&projected)
                    .zip(hold)
                    .map(|((o, p), &k)| vec3::add(*o, vec3::scale(vec3::sub(*p, *o), k)))
                    .collect(),
                None => projected,
            }
        } else {
            out.to_vec()
        };
        match heights {
            Some(h) => relief::add_heights(topo, rest, &projected, h),
            None => projected,
        }
    }

    /// Whether [`ShapeEnding::finish`] can change a frame the positioning left in place.
    pub fn is_active(&self, heights: Option<&[f64]>) -> bool {
        heights.is_some_and(|h| h.iter().any(|&x| x != 0.0))
    }
}

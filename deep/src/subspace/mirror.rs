//! Mirror augmentation of the training data: each training sequence also enters the subspace and the regressions
//! reflected in a coordinate plane through the origin, with its poses reflected to match.
//!
//! A scene that is symmetric under a reflection (the sleeve and its arm under y → −y: gravity is along −z, the
//! arm along x) moves the reflected cloth the reflected way when its driver moves the reflected way, so every
//! training sequence gives a second, equally valid one: a twist of −69° becomes one of +69°. With two training
//! sequences of three motion cycles each, the regressions see twice the motions; over the three
//! leave-one-sequence-out splits of sleeve-train the pose-only error fell by about 0.6 mm
//! (docs/deepwrinkles.md).
//!
//! The reflection S negates coordinate `axis`. A reflected frame keeps the template's vertex order: vertex v
//! takes the reflected position of the vertex nearest to S·p_v on the first training frame (the cloth at rest,
//! as symmetric as the scene). A pose block of location and Euler angles reflects as S·T·S: the location's
//! `axis` component and the angles about the two other axes change sign (S R_a(φ) S = R_a(φ) about the
//! mirror's normal a, R_b(−φ) about any other axis b, and S (Rz Ry Rx) S = (S Rz S)(S Ry S)(S Rx S)).
//! Reflecting needs both: rigid pose names ([`crate::regression::pose_features`]) and a first frame that is symmetric
//! (mean distance of a reflected vertex to its match at most [`MAX_ASYMMETRY`] edge lengths).

use crate::registration::kdtree::KdTree;
use crease_core::mesh::Topology;
use crease_core::vec3::V3;
use crease_core::{Error, Result};
use serde::{Deserialize, Serialize};

/// Largest mean distance (in mean edge lengths) between a reflected vertex of the first training frame and the
/// vertex it is matched to for the frame to count as symmetric. On sleeve-train it is 0.25–0.36 in y (gravity
/// and a 0.2 % jitter break the symmetry a little) and several edge lengths in x and z.
pub const MAX_ASYMMETRY: f64 = 0.5;

/// `--mirror`: which reflection augments the training data.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum MirrorMode {
    /// The coordinate plane in which the first training frame is most symmetric, if it is symmetric in one
    /// and the poses have rigid names; otherwise none.
    #[default]
    Auto,
    None,
    X,
    Y,
    Z,
}

impl std::str::FromStr for MirrorMode {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "auto" => Ok(MirrorMode::Auto),
            "none" => Ok(MirrorMode::None),
            "x" => Ok(MirrorMode::X),
            "y" => Ok(MirrorMode::Y),
            "z" => Ok(MirrorMode::Z),
            _ => Err(format!("`{s}`: expected auto, none, x, y or z")),
        }
    }
}

/// A reflection of the template onto itself.
#[derive(Debug, Clone, PartialEq)]
pub struct Reflection {
    /// The coordinate that changes sign (0 = x, 1 = y, 2 = z).
    pub axis: usize,
    /// Per vertex: the vertex whose reflected position it takes.
    pub source: Vec<usize>,
    /// Mean distance between reflected vertices and their matches on the first frame, in mean edge lengths.
    pub asymmetry: f64,
}

const AXES: [&str; 3] = ["x", "y", "z"];

impl Reflection {
    /// Matches the reflected vertices of `rest` (the first training frame) to its own vertices.
    pub fn find(topo: &Topology, rest: &[V3], axis: usize) -> Result<Self> {
        if rest.len() != topo.n_vertices() || rest.is_empty() {
            return Err(Error::mesh(format!(
                "mirror: a frame of {} vertices for a topology of {}",
                rest.len(),
                topo.n_vertices()
            )));
        }
        let edge = mean_edge_length(topo, rest);
        let tree = KdTree::new(rest);
        let mut source = Vec::with_capacity(rest.len());
        let mut dist = 0.0;
        for p in rest {
            let mut q = *p;
            q[axis] = -q[axis];
            let (i, d2) = tree.nearest(q).expect("non-empty frame");
            source.push(i);
            dist += d2.sqrt();
        }
        Ok(Reflection {
            axis,
            source,
            asymmetry: dist / rest.len() as f64 / edge.max(1e-300),
        })
    }

    /// The reflection `mode` asks for, or `None`. `rigid` says whether the poses have the rigid layout that
    /// [`reflect_pose`] needs; `source` names the training data in errors.
    pub fn choose(
        mode: MirrorMode,
        topo: &Topology,
        rest: &[V3],
        rigid: bool,
        source: &str,
    ) -> Result<Option<Self>> {
        let axis = match mode {
            MirrorMode::None => return Ok(None),
            MirrorMode::Auto => {
                if !rigid {
                    return Ok(None);
                }
                let mut best: Option<Reflection> = None;
                for axis in 0..3 {
                    let r = Reflection::find(topo, rest, axis)?;
                    if best.as_ref().is_none_or(|b| r.asymmetry < b.asymmetry) {
                        best = Some(r);
                    }
                }
                return Ok(best.filter(|b| b.asymmetry <= MAX_ASYMMETRY));
            }
            MirrorMode::X => 0,
            MirrorMode::Y => 1,
            MirrorMode::Z => 2,
        };
        if !rigid {
            return Err(Error::param(
                "mirror",
                format!(
                    "reflecting the poses needs `pose_vector_names` of the form OBJ.location.x … \
                     OBJ.rotation_euler.z per object, which {source} does not have"
                ),
            ));
        }
        let r = Reflection::find(topo, rest, axis)?;
        if r.asymmetry > MAX_ASYMMETRY {
            return Err(Error::param(
                "mirror",
                format!(
                    "the first frame of {source} is not symmetric in the plane {} = 0: a reflected vertex \
                     is {:.2} edge lengths from the nearest vertex on average (at most {MAX_ASYMMETRY})",
                    AXES[axis], r.asymmetry
                ),
            ));
        }
        Ok(Some(r))
    }

    /// The reflected frame, in the template's vertex order.
    pub fn reflect_frame(&self, frame: &[V3]) -> Vec<V3> {
        self.source
            .iter()
            .map(|&i| {
                let mut p = frame[i];
                p[self.axis] = -p[self.axis];
                p
            })
            .collect()
    }

    pub fn axis_name(&self) -> &'static str {
        AXES[self.axis]
    }
}

/// A pose of rigid blocks (location x, y, z, rotation_euler x, y, z) reflected in the plane `axis` = 0.
pub fn reflect_pose(pose: &[f64], axis: usize) -> Vec<f64> {
    let mut out = pose.to_vec();
    for block in out.chunks_exact_mut(6) {
        block[axis] = -block[axis];
        for b in 0..3 {
            if b != axis {
                block[3 + b] = -block[3 + b];
            }
        }
    }
    out
}

fn mean_edge_length(topo: &Topology, p: &[V3]) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for t in topo.triangles() {
        for k in 0..3 {
            let (a, b) = (p[t[k] as usize], p[t[(k + 1) % 3] as usize]);
            s += ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
            n += 1;
        }
    }
    s / n.max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Euler XYZ (Blender: R = Rz · Ry · Rx), column vectors.
    fn rot(a: [f64; 3]) -> [[f64; 3]; 3] {
        let (sx, cx) = a[0].sin_cos();
        let (sy, cy) = a[1].sin_cos();
        let (sz, cz) = a[2].sin_cos();
        let rx = [[1.0, 0.0, 0.0], [0.0, cx, -sx], [0.0, sx, cx]];
        let ry = [[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]];
        let rz = [[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]];
        mul(mul(rz, ry), rx)
    }

    fn mul(a: [[f64; 3]; 3], b: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
        let mut c = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                c[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
            }
        }
        c
    }

    #[test]
    fn reflected_pose_is_the_conjugated_transform() {
        let pose = [0.45, 0.02, -0.03, 0.7, -0.2, 0.4];
        for axis in 0..3 {
            let r = reflect_pose(&pose, axis);
            let m = rot([pose[3], pose[4], pose[5]]);
            let mr = rot([r[3], r[4], r[5]]);
            // S M S: entries (i, j) change sign when exactly one of i, j is the axis.
            for i in 0..3 {
                for j in 0..3 {
                    let sign = if (i == axis) != (j == axis) {
                        -1.0
                    } else {
                        1.0
                    };
                    assert!(
                        (mr[i][j] - sign * m[i][j]).abs() < 1e-12,
                        "axis {axis} ({i},{j})"
                    );
                }
                let sign = if i == axis { -1.0 } else { 1.0 };
                assert_eq!(r[i], sign * pose[i]);
            }
        }
    }

    #[test]
    fn a_symmetric_ring_maps_onto_itself_and_a_lopsided_one_is_refused() {
        // A ring of 12 vertices in the yz-plane (symmetric in y and z), fanned to a centre vertex.
        let ring = |bulge: f64| -> Vec<V3> {
            let mut p: Vec<V3> = (0..12)
                .map(|i| {
                    let a = std::f64::consts::TAU * (i as f64 + 0.5) / 12.0;
                    let r = 1.0 + bulge * a.cos().max(0.0);
                    [0.0, r * a.cos(), r * a.sin()]
                })
                .collect();
            p.push([0.0, 0.0, 0.0]);
            p
        };
        let tris: Vec<[u32; 3]> = (0..12u32).map(|i| [i, (i + 1) % 12, 12]).collect();
        let topo = Topology::new(13, tris).unwrap();
        let sym = ring(0.0);
        let r = Reflection::find(&topo, &sym, 1).unwrap();
        assert!(r.asymmetry < 1e-9, "{}", r.asymmetry);
        // y → −y maps angle a to π − a: vertex i to 5 − i (mod 12).
        for i in 0..12 {
            assert_eq!(r.source[i], (17 - i) % 12);
        }
        let f = r.reflect_frame(&sym);
        assert_eq!(f[0], [0.0, -sym[5][1], sym[5][2]]);
        let auto = Reflection::choose(MirrorMode::Auto, &topo, &sym, true, "d").unwrap();
        assert!(auto.is_some());
        assert_eq!(
            Reflection::choose(MirrorMode::Auto, &topo, &sym, false, "d").unwrap(),
            None
        );
        // Bulging towards +y: not symmetric in y.
        let lop = ring(1.5);
        let e = Reflection::choose(MirrorMode::Y, &topo, &lop, true, "seed_9")
            .unwrap_err()
            .to_string();
        assert!(e.contains("seed_9") && e.contains("y = 0"), "{e}");
        let e = Reflection::choose(MirrorMode::Y, &topo, &sym, false, "seed_9")
            .unwrap_err()
            .to_string();
        assert!(e.contains("pose_vector_names"), "{e}");
    }
}

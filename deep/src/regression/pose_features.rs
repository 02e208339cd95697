//! Pose features for the regression: what the raw pose numbers become before they are normalised.
//!
//! A pose file's vector is, per driving object, a location (x, y, z) and Euler angles (`pose_vector_names`:
//! `OBJ.location.x` … `OBJ.rotation_euler.z`). Points carried by a rotating object move with the sine and cosine
//! of its angles, not linearly in them, and how the cloth between a moving and a fixed ring twists depends on how
//! far the object has travelled: on sleeve-train the cuff's 70° twist and 15 cm travel interact. So the
//! **rigid** features of an object are its location, the sine and cosine of each angle, the products of the
//! location components with each other and with those sines and cosines (33 numbers per object). Velocity and
//! acceleration are then taken of these features ([`crate::regression::pose::ControlSpec`]), which puts products such as
//! cos θ · θ̇ into the control vector. Constant features (a component that never moves, cos 0 = 1) and ones
//! that repeat an earlier feature on the training data get a zero scale in the control spec, so the ridge is
//! not shared out over copies. Over the three leave-one-sequence-out splits of sleeve-train the pose-only
//! linear map went from 7.57 mm (raw pose + velocity + acceleration) to about 5 mm with these features
//! (docs/deepwrinkles.md).
//!
//! A pose file without names, or with names of another layout, keeps the **raw** features (the numbers as
//! they are), as every model before format 5 did.

use crease_core::{Error, Result};
use serde::{Deserialize, Serialize};

/// Names of one object's six pose numbers, in pose-file order, after `OBJ.`.
const RIGID_NAMES: [&str; 6] = [
    "location.x",
    "location.y",
    "location.z",
    "rotation_euler.x",
    "rotation_euler.y",
    "rotation_euler.z",
];

/// Features per rigid object: 3 locations, 3 sines, 3 cosines, 6 location products, 9 location × sine and 9
/// location × cosine products.
pub const RIGID_FEATURES: usize = 33;

/// How raw pose vectors become regression features; stored in the model's control spec.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase", tag = "kind")]
pub enum PoseFeatures {
    /// The pose numbers as they are (models before format 5, pose files without rigid names).
    #[default]
    Raw,
    /// `objects` blocks of location x, y, z and rotation_euler x, y, z (radians).
    Rigid { objects: usize },
}

/// The feature choice for training (`--pose-features`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum PoseFeatureMode {
    /// Rigid when the pose file names its numbers as location/rotation_euler blocks, raw otherwise.
    #[default]
    Auto,
    Raw,
    /// Rigid, and an error when the pose file's names do not have that layout.
    Rigid,
}

impl std::str::FromStr for PoseFeatureMode {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "auto" => Ok(PoseFeatureMode::Auto),
            "raw" => Ok(PoseFeatureMode::Raw),
            "rigid" => Ok(PoseFeatureMode::Rigid),
            _ => Err(format!("`{s}`: expected auto, raw or rigid")),
        }
    }
}

/// Object names of a rigid layout (`OBJ.location.x` … `OBJ.rotation_euler.z` per object), or `None` when the
/// names have another layout.
pub fn rigid_objects(names: &[String]) -> Option<Vec<String>> {
    if names.is_empty() || !names.len().is_multiple_of(6) {
        return None;
    }
    names
        .chunks(6)
        .map(|block| {
            let object = block[0].strip_suffix(RIGID_NAMES[0])?.strip_suffix('.')?;
            block
                .iter()
                .zip(RIGID_NAMES)
                .all(|(n, want)| {
                    n.strip_prefix(object).and_then(|r| r.strip_prefix('.')) == Some(want)
                })
                .then(|| object.to_string())
        })
        .collect()
}

impl PoseFeatures {
    /// The features for training data whose pose names are `names` (`None`: the file has none).
    pub fn choose(mode: PoseFeatureMode, names: Option<&[String]>, source: &str) -> Result<Self> {
        let rigid = names.and_then(rigid_objects);
        match (mode, rigid) {
            (PoseFeatureMode::Raw, _) | (PoseFeatureMode::Auto, None) => Ok(PoseFeatures::Raw),
            (_, Some(objects)) => Ok(PoseFeatures::Rigid {
                objects: objects.len(),
            }),
            (PoseFeatureMode::Rigid, None) => Err(Error::param(
                "pose_features",
                format!(
                    "rigid features need `pose_vector_names` of the form OBJ.location.x, OBJ.location.y, \
                     OBJ.location.z, OBJ.rotation_euler.x, OBJ.rotation_euler.y, OBJ.rotation_euler.z per object; \
                     {source} has {}",
                    match names {
                        Some(n) => format!("{n:?}"),
                        None => "no `pose_vector_names`".into(),
                    }
                ),
            )),
        }
    }

    /// Length of the raw pose vector these features are computed from (`raw_dim` for raw ones).
    pub fn input_dim(&self, raw_dim: usize) -> usize {
        match self {
            PoseFeatures::Raw => raw_dim,
            PoseFeatures::Rigid { objects } => 6 * objects,
        }
    }

    /// Number of features for a raw pose of `input_dim` numbers.
    pub fn output_dim(&self, input_dim: usize) -> usize {
        match self {
            PoseFeatures::Raw => input_dim,
            PoseFeatures::Rigid { objects } => RIGID_FEATURES * objects,
        }
    }

    /// The features of one pose vector (its length checked by the caller).
    pub fn expand(&self, pose: &[f64]) -> Vec<f64> {
        match self {
            PoseFeatures::Raw => pose.to_vec(),
            PoseFeatures::Rigid { objects } => {
                let mut out = Vec::with_capacity(RIGID_FEATURES * objects);
                for block in pose.chunks_exact(6).take(*objects) {
                    let loc = &block[..3];
                    let sin: Vec<f64> = block[3..].iter().map(|a| a.sin()).collect();
                    let cos: Vec<f64> = block[3..].iter().map(|a| a.cos()).collect();
                    out.extend_from_slice(loc);
                    out.extend_from_slice(&sin);
                    out.extend_from_slice(&cos);
                    for i in 0..3 {
                        for j in i..3 {
                            out.push(loc[i] * loc[j]);
                        }
                    }
                    for l in loc {
                        out.extend(sin.iter().map(|s| l * s));
                    }
                    for l in loc {
                        out.extend(cos.iter().map(|c| l * c));
                    }
                }
                out
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(objects: &[&str]) -> Vec<String> {
        objects
            .iter()
            .flat_map(|o| RIGID_NAMES.iter().map(move |n| format!("{o}.{n}")))
            .collect()
    }

    #[test]
    fn rigid_layout_is_recognised_only_from_its_names() {
        assert_eq!(
            rigid_objects(&names(&["cuff_ctrl", "hand.L"])),
            Some(vec!["cuff_ctrl".to_string(), "hand.L".to_string()])
        );
        let mut swapped = names(&["cuff_ctrl"]);
        swapped.swap(3, 4);
        assert_eq!(rigid_objects(&swapped), None);
        let mut mixed = names(&["a", "b"]);
        mixed[7] = "a.location.y".into();
        assert_eq!(rigid_objects(&mixed), None);
        assert_eq!(rigid_objects(&names(&["a"])[..5]), None);
        let raw = PoseFeatures::choose(PoseFeatureMode::Auto, None, "pose.json").unwrap();
        assert_eq!(raw, PoseFeatures::Raw);
        let e = PoseFeatures::choose(PoseFeatureMode::Rigid, Some(&swapped), "seed_1/pose.json")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("seed_1/pose.json") && e.contains("pose_vector_names"),
            "{e}"
        );
        let n = names(&["cuff_ctrl"]);
        assert_eq!(
            PoseFeatures::choose(PoseFeatureMode::Raw, Some(&n), "p").unwrap(),
            PoseFeatures::Raw
        );
        assert_eq!(
            PoseFeatures::choose(PoseFeatureMode::Auto, Some(&n), "p").unwrap(),
            PoseFeatures::Rigid { objects: 1 }
        );
    }

    #[test]
    fn rigid_features_carry_sines_cosines_and_products() {
        let f = PoseFeatures::Rigid { objects: 1 };
        let (x, theta) = (0.4, 0.7f64);
        let v = f.expand(&[x, 0.0, 0.0, theta, 0.0, 0.0]);
        assert_eq!(v.len(), RIGID_FEATURES);
        assert_eq!(f.output_dim(6), RIGID_FEATURES);
        assert_eq!(v[0], x);
        assert_eq!(v[3], theta.sin());
        assert_eq!(v[6], theta.cos());
        assert_eq!(v[9], x * x); // loc_x · loc_x
        assert_eq!(v[15], x * theta.sin()); // loc_x · sin θ_x
        assert_eq!(v[24], x * theta.cos()); // loc_x · cos θ_x
        assert_eq!(PoseFeatures::Raw.expand(&[1.0, 2.0]), vec![1.0, 2.0]);
    }
}

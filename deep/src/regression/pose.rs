//! Pose files (`pose.json`: one pose vector per frame) and the control vectors built from them.
//!
//! The cloth's shape depends on its history, not only on the current pose (sleeve-train README: equal poses,
//! meshes 18 mm apart), so the control vector Θ_t (Lähner et al. §3.3) holds the pose, its velocity and
//! acceleration, and the pose at a few earlier lags. Everything is normalised with statistics of the training
//! data; constant dimensions (4 of the sleeve's 6) are guarded against a zero variance.

use crate::regression::pose_features::PoseFeatures;
use crate::regression::pose_history::DecayedHistory;
use crease_core::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Reads `pose_vectors` from a pose file. Every vector must have the same length and only finite numbers; the
/// error names the file, the frame (1-based) and the component. `expect_frames` checks the count.
pub fn read_pose_file(path: &Path, expect_frames: Option<usize>) -> Result<Vec<Vec<f64>>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let value: serde_json::Value = match serde_json::from_str(&text) {
        Ok(v) => v,
        // Python's json module writes NaN/Infinity, which is not JSON: read them as null so the error can
        // name the frame instead of a byte offset.
        Err(first) => serde_json::from_str(&replace_non_finite(&text)).map_err(|_| {
            Error::format(path, Some(first.line()), format!("invalid JSON: {first}"))
        })?,
    };
    let vectors = value
        .get("pose_vectors")
        .and_then(|v| v.as_array())
        .ok_or_else(|| Error::format(path, None, "no `pose_vectors` array"))?;
    if vectors.is_empty() {
        return Err(Error::format(path, None, "`pose_vectors` is empty"));
    }
    let mut out = Vec::with_capacity(vectors.len());
    for (i, v) in vectors.iter().enumerate() {
        let arr = v.as_array().ok_or_else(|| {
            Error::format(
                path,
                None,
                format!("frame {}: `pose_vectors[{i}]` is not an array", i + 1),
            )
        })?;
        let mut row = Vec::with_capacity(arr.len());
        for (j, x) in arr.iter().enumerate() {
            match x.as_f64() {
                Some(f) if f.is_finite() => row.push(f),
                _ => {
                    return Err(Error::format(
                        path,
                        None,
                        format!(
                            "frame {}: `pose_vectors[{i}][{j}]` is not a finite number ({x})",
                            i + 1
                        ),
                    ))
                }
            }
        }
        if let Some(first) = out.first().map(|r: &Vec<f64>| r.len()) {
            if row.len() != first {
                return Err(Error::format(
                    path,
                    None,
                    format!(
                        "frame {}: pose vector has {} numbers, frame 1 has {first}",
                        i + 1,
                        row.len()
                    ),
                ));
            }
        }
        out.push(row);
    }
    if let Some(n) = expect_frames {
        if out.len() != n {
            return Err(Error::format(
                path,
                None,
                format!("{} pose vectors for a sequence of {n} frames", out.len()),
            ));
        }
    }
    Ok(out)
}

/// The pose file's `pose_vector_names` (what each number of a pose vector is), if it has them; a file read
/// by [`read_pose_file`] already. Names that are not a list of strings as long as the vectors are an error naming
/// the file.
pub fn read_pose_names(path: &Path) -> Result<Option<Vec<String>>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let value: serde_json::Value = serde_json::from_str(&replace_non_finite(&text))
        .map_err(|e| Error::format(path, Some(e.line()), format!("invalid JSON: {e}")))?;
    let Some(names) = value.get("pose_vector_names") else {
        return Ok(None);
    };
    let names: Vec<String> = names
        .as_array()
        .and_then(|a| a.iter().map(|n| n.as_str().map(String::from)).collect())
        .ok_or_else(|| Error::format(path, None, "`pose_vector_names` is not a list of strings"))?;
    let dim = value
        .get("pose_vectors")
        .and_then(|v| v.get(0))
        .and_then(|v| v.as_array())
        .map(|a| a.len());
    if dim.is_some_and(|d| d != names.len()) {
        return Err(Error::format(
            path,
            None,
            format!(
                "`pose_vector_names` has {} names for pose vectors of {} numbers",
                names.len(),
                dim.unwrap_or(0)
            ),
        ));
    }
    Ok(Some(names))
}

fn replace_non_finite(text: &str) -> String {
    let mut s = text.replace("-Infinity", "null");
    s = s.replace("Infinity", "null");
    s.replace("NaN", "null")
}

/// How control vectors are built; stored in the model so apply builds them the same way.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ControlSpec {
    /// Earlier frames whose pose joins the control vector (frame t − lag, clamped at the first frame).
    pub lags: Vec<usize>,
    /// Per pose dimension: mean and scale (1 / std, or 0 for a constant dimension).
    pub mean: Vec<f64>,
    pub scale: Vec<f64>,
    /// Exponentially decayed pose history features ([`DecayedHistory`]); absent in models before format 3.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub history: Option<DecayedHistory>,
    /// What the raw pose numbers become before they are normalised ([`PoseFeatures`]); raw in models before
    /// format 5. `mean` and `scale` are per feature.
    #[serde(default)]
    pub features: PoseFeatures,
}

impl ControlSpec {
    /// Statistics from all training poses (raw features).
    pub fn fit(sequences: &[&[Vec<f64>]], lags: Vec<usize>) -> Result<Self> {
        Self::fit_features(sequences, lags, PoseFeatures::Raw)
    }

    /// Statistics of `features` of all training poses. A feature that is constant, or that repeats an earlier
    /// feature on the training poses, gets scale 0: it adds nothing, and a copy would halve the ridge on the
    /// feature it copies.
    pub fn fit_features(
        sequences: &[&[Vec<f64>]],
        lags: Vec<usize>,
        features: PoseFeatures,
    ) -> Result<Self> {
        let dim = sequences
            .iter()
            .find_map(|s| s.first().map(|r| r.len()))
            .ok_or_else(|| Error::param("poses", "no training poses"))?;
        let raw: Vec<&Vec<f64>> = sequences.iter().flat_map(|s| s.iter()).collect();
        if let Some(r) = raw.iter().find(|r| r.len() != dim) {
            return Err(Error::param(
                "poses",
                format!("pose vectors of length {} and {dim}", r.len()),
            ));
        }
        if features.input_dim(dim) != dim {
            return Err(Error::param(
                "poses",
                format!(
                    "pose vectors of length {dim}; the pose features need {}",
                    features.input_dim(dim)
                ),
            ));
        }
        let expanded: Vec<Vec<f64>> = raw.iter().map(|r| features.expand(r)).collect();
        let all: Vec<&Vec<f64>> = expanded.iter().collect();
        let dim = features.output_dim(dim);
        let n = all.len() as f64;
        let mean: Vec<f64> = (0..dim)
            .map(|j| all.iter().map(|r| r[j]).sum::<f64>() / n)
            .collect();
        let mut scale: Vec<f64> = (0..dim)
            .map(|j| {
                let var = all.iter().map(|r| (r[j] - mean[j]).powi(2)).sum::<f64>() / n;
                if var > 1e-12 {
                    1.0 / var.sqrt()
                } else {
                    0.0
                }
            })
            .collect();
        // Copies: the same standardised column up to rounding (x · cos 0 repeats x).
        for j in 0..dim {
            let copies = (0..j).any(|i| {
                scale[i] != 0.0
                    && scale[j] != 0.0
                    && all.iter().all(|r| {
                        ((r[j] - mean[j]) * scale[j] - (r[i] - mean[i]) * scale[i]).abs() < 1e-9
                    })
            });
            if copies {
                scale[j] = 0.0;
            }
        }
        Ok(ControlSpec {
            lags,
            mean,
            scale,
            history: None,
            features,
        })
    }

    /// Adds decayed pose history features with these time constants (frames; none: no history features),
    /// standardised on the training poses.
    pub fn with_history(
        mut self,
        sequences: &[&[Vec<f64>]],
        time_constants: &[f64],
    ) -> Result<Self> {
        if time_constants.is_empty() {
            self.history = None;
            return Ok(self);
        }
        let normed: Vec<Vec<Vec<f64>>> = sequences.iter().map(|s| self.normalise(s)).collect();
        self.history = Some(DecayedHistory::fit(&normed, time_constants)?);
        Ok(self)
    }

    fn normalise(&self, poses: &[Vec<f64>]) -> Vec<Vec<f64>> {
        poses
            .iter()
            .map(|p| {
                self.features
                    .expand(p)
                    .iter()
                    .enumerate()
                    .map(|(j, x)| (x - self.mean[j]) * self.scale[j])
                    .collect()
            })
            .collect()
    }

    /// Length of the raw pose vectors this spec reads.
    pub fn pose_dim(&self) -> usize {
        self.features.input_dim(self.mean.len())
    }

    /// Number of pose features (after [`PoseFeatures::expand`]) per frame.
    pub fn feature_dim(&self) -> usize {
        self.mean.len()
    }

    /// Length of a control vector: pose, velocity, acceleration, one pose per lag, the decayed history, and a
    /// constant 1.
    pub fn len(&self) -> usize {
        self.feature_dim() * (3 + self.lags.len())
            + self
                .history
                .as_ref()
                .map_or(0, |h| h.len(self.feature_dim()))
            + 1
    }

    pub fn is_empty(&self) -> bool {
        false
    }

    /// Control vectors Θ_t for every frame of one sequence.
    pub fn controls(&self, poses: &[Vec<f64>]) -> Result<Vec<Vec<f64>>> {
        if let Some((i, r)) = poses
            .iter()
            .enumerate()
            .find(|(_, r)| r.len() != self.pose_dim())
        {
            return Err(Error::param(
                "pose",
                format!(
                    "frame {}: pose vector has {} numbers, the model expects {}",
                    i + 1,
                    r.len(),
                    self.pose_dim()
                ),
            ));
        }
        let normed = self.normalise(poses);
        let history = self.history.as_ref().map(|h| h.features(&normed));
        let at = |t: isize| -> &Vec<f64> { &normed[t.max(0) as usize] };
        // Velocity and acceleration in units of one frame, scaled up so they are comparable to the pose.
        const DYN: f64 = 10.0;
        Ok((0..poses.len() as isize)
            .map(|t| {
                let (p0, p1, p2) = (at(t), at(t - 1), at(t - 2));
                let mut c = Vec::with_capacity(self.len());
                c.extend(p0.iter().copied());
                c.extend(p0.iter().zip(p1).map(|(a, b)| DYN * (a - b)));
                c.extend((0..p0.len()).map(|j| DYN * DYN * (p0[j] - 2.0 * p1[j] + p2[j])));
                for &lag in &self.lags {
                    c.extend(at(t - lag as isize).iter().copied());
                }
                if let Some(h) = &history {
                    c.extend(h[t as usize].iter().copied());
                }
                c.push(1.0);
                c
            })
            .collect())
    }
}

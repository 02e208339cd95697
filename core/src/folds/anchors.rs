//! Anchor triangles and the anchors file.
//!
//! An anchor says "rotate triangle `triangle` of frame `frame` by `angle` radians about the world-space unit
//! `axis`" (Popa et al. 2009 §5.1). Fold estimators (video, geometry) and artists produce anchors; the
//! space-time solve spreads them. The JSON file is the hand-off point between the two, so it is validated
//! strictly: a typo in a hand-edited file must not silently produce a different garment.
//!
//! Format (documented in the README):
//! ```json
//! { "version": 1,
//!   "frames": [ { "frame": 0, "anchors": [ {"triangle": 12, "axis": [0,0,1], "angle": 0.8} ],
//!                 "control_lines": [ [[x,y,z], ...] ] } ] }
//! ```
//! `frame` is the 0-based position in the sequence. Frames without anchors may be omitted.

pub mod binary;

use crate::error::{Error, Result};
use crate::vec3::{self, V3};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// One anchor triangle with its target rotation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Anchor {
    pub triangle: u32,
    /// World-space rotation axis; normalised on load.
    pub axis: V3,
    /// Rotation angle in radians, in [-π, π].
    pub angle: f64,
}

impl Anchor {
    /// The anchor's rotation vector φ = axis · angle = log R (the principal logarithm, since |angle| ≤ π).
    pub fn rotation_vector(&self) -> V3 {
        vec3::scale(self.axis, self.angle)
    }
}

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameAnchors {
    pub frame: usize,
    #[serde(default)]
    pub anchors: Vec<Anchor>,
    /// Polylines on the surface that produced the anchors, kept only for inspection and overlays.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub control_lines: Vec<Vec<V3>>,
    /// What the detector did on this frame, for report.json (`fold_detection.per_frame`). It travels with the
    /// anchors from a detection task to the merge, but anchors files never hold it: [`AnchorSet`] drops it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub detection: Option<FrameDetection>,
}

/// Per-frame detection figures: how many folds were found and, for detectors that search seeds, how many seeds
/// were tried to find them.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameDetection {
    /// Folds traced (stretch) or edge pairs projected onto the mesh (video) in this frame.
    pub folds: usize,
    /// Seeds taken from the queue, folds or not (stretch); none for detectors without seeds.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seeds_tried: Option<usize>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct AnchorsFile {
    version: u32,
    frames: Vec<FrameAnchors>,
}

/// Anchors of a whole sequence, indexed by frame. Each frame's anchors are sorted by triangle and unique.
#[derive(Debug, Clone, Default)]
pub struct AnchorSet {
    frames: Vec<FrameAnchors>,
}

impl AnchorSet {
    /// An anchor set with no anchors for `n_frames` frames.
    pub fn empty(n_frames: usize) -> Self {
        AnchorSet {
            frames: (0..n_frames)
                .map(|f| FrameAnchors {
                    frame: f,
                    ..Default::default()
                })
                .collect(),
        }
    }

    /// Builds a validated set from per-frame lists (index = frame).
    pub fn from_frames(
        lists: Vec<Vec<Anchor>>,
        n_triangles: usize,
        path: Option<&Path>,
    ) -> Result<Self> {
        let frames = lists
            .into_iter()
            .enumerate()
            .map(|(frame, anchors)| FrameAnchors {
                frame,
                anchors,
                ..Default::default()
            })
            .collect();
        let mut set = AnchorSet { frames };
        set.validate(n_triangles, path)?;
        Ok(set)
    }

    /// Assembles a validated set from detector output: `frames` must hold frames `0..n` in order, as
    /// [`crate::folds::FoldDetector::detect`] chunks concatenated in frame order do.
    pub fn from_frame_anchors(
        frames: Vec<FrameAnchors>,
        n_triangles: usize,
        path: Option<&Path>,
    ) -> Result<Self> {
        if let Some((i, fa)) = frames.iter().enumerate().find(|(i, fa)| fa.frame != *i) {
            return Err(Error::Anchors {
                path: path.map(Path::to_path_buf),
                msg: format!(
                    "detector output out of order: entry {i} is frame {} (expected {i})",
                    fa.frame
                ),
            });
        }
        let mut set = AnchorSet {
            frames: frames
                .into_iter()
                .map(|f| FrameAnchors {
                    detection: None,
                    ..f
                })
                .collect(),
        };
        set.validate(n_triangles, path)?;
        Ok(set)
    }

    pub fn n_frames(&self) -> usize {
        self.frames.len()
    }
    pub fn frame(&self, t: usize) -> &[Anchor] {
        self.frames
            .get(t)
            .map(|f| f.anchors.as_slice())
            .unwrap_or(&[])
    }
    pub fn control_lines(&self, t: usize) -> &[Vec<V3>] {
        self.frames
            .get(t)
            .map(|f| f.control_lines.as_slice())
            .unwrap_or(&[])
    }
    pub fn set_control_lines(&mut self, t: usize, lines: Vec<Vec<V3>>) {
        if let Some(f) = self.frames.get_mut(t) {
            f.control_lines = lines;
        }
    }
    pub fn total(&self) -> usize {
        self.frames.iter().map(|f| f.anchors.len()).sum()
    }

    /// Parses and validates an anchors file for a sequence of `n_frames` frames and `n_triangles` triangles.
    pub fn read(path: &Path, n_frames: usize, n_triangles: usize) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Self::parse(&text, Some(path), n_frames, n_triangles)
    }

    /// Parses anchors JSON; `path` only labels errors.
    pub fn parse(
        text: &str,
        path: Option<&Path>,
        n_frames: usize,
        n_triangles: usize,
    ) -> Result<Self> {
        let err = |msg: String| Error::Anchors {
            path: path.map(Path::to_path_buf),
            msg,
        };
        let file: AnchorsFile = serde_json::from_str(text)
            .map_err(|e| err(format!("line {} column {}: {e}", e.line(), e.column())))?;
        if file.version != 1 {
            return Err(err(format!(
                "unsupported version {} (expected 1)",
                file.version
            )));
        }
        let mut frames: Vec<FrameAnchors> = (0..n_frames)
            .map(|f| FrameAnchors {
                frame: f,
                ..Default::default()
            })
            .collect();
        let mut seen = vec![false; n_frames];
        for fa in file.frames {
            if fa.frame >= n_frames {
                return Err(err(format!(
                    "frame {} is out of range: the sequence has {n_frames} frames (0-based)",
                    fa.frame
                )));
            }
            if std::mem::replace(&mut seen[fa.frame], true) {
                return Err(err(format!("frame {} is listed twice", fa.frame)));
            }
            let f = fa.frame;
            frames[f] = fa;
        }
        let mut set = AnchorSet { frames };
        set.validate(n_triangles, path)?;
        Ok(set)
    }

    /// Checks indices, axes and angles, normalises axes and sorts each frame by triangle.
    fn validate(&mut self, n_triangles: usize, path: Option<&Path>) -> Result<()> {
        let err = |msg: String| Error::Anchors {
            path: path.map(Path::to_path_buf),
            msg,
        };
        for fa in &mut self.frames {
            let f = fa.frame;
            for (k, a) in fa.anchors.iter_mut().enumerate() {
                if a.triangle as usize >= n_triangles {
                    return Err(err(format!(
                        "frame {f} anchor {k}: triangle {} is out of range (the mesh has {n_triangles} triangles)",
                        a.triangle
                    )));
                }
                if !vec3::is_finite(a.axis) || !a.angle.is_finite() {
                    return Err(err(format!(
                        "frame {f} anchor {k}: axis and angle must be finite numbers"
                    )));
                }
                // Scaled by the largest component first: the squared length of an axis such as
                // [0, 0, 1e200] overflows, and dividing by an infinite length would silently zero the axis.
                let big = a.axis.iter().fold(0.0f64, |m, c| m.max(c.abs()));
                let unit_ish = if big > 0.0 {
                    vec3::scale(a.axis, 1.0 / big)
                } else {
                    a.axis
                };
                let n = vec3::norm(unit_ish);
                if big * n < 1e-9 {
                    return Err(err(format!("frame {f} anchor {k}: axis has zero length")));
                }
                if a.angle.abs() > std::f64::consts::PI + 1e-9 {
                    return Err(err(format!(
                        "frame {f} anchor {k}: angle {} rad is outside [-π, π]",
                        a.angle
                    )));
                }
                a.axis = vec3::scale(unit_ish, 1.0 / n);
            }
            fa.anchors.sort_by_key(|a| a.triangle);
            for w in fa.anchors.windows(2) {
                if w[0].triangle == w[1].triangle {
                    return Err(err(format!(
                        "frame {f}: triangle {} is anchored twice",
                        w[0].triangle
                    )));
                }
            }
            for (l, line) in fa.control_lines.iter().enumerate() {
                if line.iter().any(|p| !vec3::is_finite(*p)) {
                    return Err(err(format!("frame {f} control line {l}: non-finite point")));
                }
            }
        }
        Ok(())
    }

    /// The control lines as OBJ polylines (`v` + `l`), one `o frame_N` object per frame with lines, for viewing
    /// in any DCC tool. Frames without lines are left out.
    pub fn control_lines_obj(&self) -> String {
        // Floats as `Display` writes them (crate::float_text), into one buffer: tens of MB at paper scale.
        let mut s: Vec<u8> = Vec::new();
        let mut next = 1usize;
        for t in 0..self.n_frames() {
            let lines = self.control_lines(t);
            if lines.is_empty() {
                continue;
            }
            s.extend_from_slice(b"o frame_");
            crate::float_text::push_u64(&mut s, t as u64);
            s.push(b'\n');
            for line in lines {
                for p in line {
                    s.push(b'v');
                    for &c in p {
                        s.push(b' ');
                        crate::float_text::push_f64(&mut s, c);
                    }
                    s.push(b'\n');
                }
                s.extend_from_slice(b"l ");
                for (k, i) in (next..next + line.len()).enumerate() {
                    if k > 0 {
                        s.push(b' ');
                    }
                    crate::float_text::push_u64(&mut s, i as u64);
                }
                s.push(b'\n');
                next += line.len();
            }
        }
        String::from_utf8(s).expect("control lines are ASCII")
    }

    /// Serialises the set (frames without anchors or lines are omitted).
    pub fn to_json(&self) -> String {
        let file = AnchorsFile {
            version: 1,
            frames: self
                .frames
                .iter()
                .filter(|f| !f.anchors.is_empty() || !f.control_lines.is_empty())
                .cloned()
                .collect(),
        };
        serde_json::to_string(&file).expect("anchors serialise")
    }

    pub fn write(&self, path: &Path) -> Result<()> {
        crate::fsutil::write_atomic(path, self.to_json().as_bytes())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The control-line OBJ as it was written with `write!` and `Display` before `crate::float_text`.
    fn control_lines_obj_with_display(set: &AnchorSet) -> String {
        use std::fmt::Write as _;
        let mut s = String::new();
        let mut next = 1usize;
        for t in 0..set.n_frames() {
            let lines = set.control_lines(t);
            if lines.is_empty() {
                continue;
            }
            let _ = writeln!(s, "o frame_{t}");
            for line in lines {
                for p in line {
                    let _ = writeln!(s, "v {} {} {}", p[0], p[1], p[2]);
                }
                let idx: Vec<String> = (next..next + line.len()).map(|i| i.to_string()).collect();
                let _ = writeln!(s, "l {}", idx.join(" "));
                next += line.len();
            }
        }
        s
    }

    #[test]
    fn control_lines_obj_keeps_its_bytes() {
        let frames: Vec<FrameAnchors> = (0..4)
            .map(|f| FrameAnchors {
                frame: f,
                anchors: vec![],
                control_lines: match f {
                    1 => vec![],
                    2 => vec![vec![], vec![[1e-17, -0.0, 12.0]]],
                    _ => (0..3)
                        .map(|l| {
                            (0..l + 2)
                                .map(|i| {
                                    let x = (f * 31 + l * 7 + i) as f64;
                                    [x.sin() * 1e3, 1.0 / (x + 1.0), -x * 1e-9]
                                })
                                .collect()
                        })
                        .collect(),
                },
                detection: None,
            })
            .collect();
        let set = AnchorSet::from_frame_anchors(frames, 10, None).unwrap();
        let obj = set.control_lines_obj();
        assert!(obj.contains("o frame_3") && !obj.contains("o frame_1"));
        assert_eq!(obj, control_lines_obj_with_display(&set));
    }

    /// Fuzzing found an axis whose squared length overflows ([1, 2, 5.9e182]): it was divided by an infinite
    /// length and silently became [0, 0, 0], so the anchor asked for no rotation at all and the set no longer
    /// read back from its own JSON.
    #[test]
    fn huge_axes_normalise_instead_of_vanishing() {
        let text = r#"{"version":1,"frames":[{"frame":0,"anchors":[
            {"triangle":1,"axis":[1,2,5.9e182],"angle":0.2},{"triangle":2,"axis":[-1e308,1e308,0],"angle":0.1}]}]}"#;
        let s = AnchorSet::parse(text, None, 1, 10).unwrap();
        let [a, b] = [s.frame(0)[0], s.frame(0)[1]];
        assert!(a.axis[2] == 1.0 && a.axis[0] > 0.0 && a.axis[1] == 2.0 * a.axis[0]);
        let h = std::f64::consts::FRAC_1_SQRT_2;
        assert!((b.axis[0] + h).abs() < 1e-15 && (b.axis[1] - h).abs() < 1e-15 && b.axis[2] == 0.0);
        let back = AnchorSet::parse(&s.to_json(), None, 1, 10).unwrap();
        assert_eq!(back.frame(0), s.frame(0));
        let tiny = r#"{"version":1,"frames":[{"frame":0,"anchors":[{"triangle":1,"axis":[1e-300,0,0],"angle":0.2}]}]}"#;
        assert!(AnchorSet::parse(tiny, None, 1, 10)
            .unwrap_err()
            .to_string()
            .contains("zero length"));
    }

    #[test]
    fn parse_and_validate() {
        let ok = r#"{"version":1,"frames":[{"frame":1,"anchors":[{"triangle":3,"axis":[0,0,2],"angle":0.5}]}]}"#;
        let s = AnchorSet::parse(ok, None, 2, 10).unwrap();
        assert_eq!(s.frame(0).len(), 0);
        assert_eq!(s.frame(1)[0].axis, [0.0, 0.0, 1.0]);
        let cases = [
            (
                r#"{"version":1,"frames":[{"frame":5,"anchors":[]}]}"#,
                "frame 5 is out of range",
            ),
            (
                r#"{"version":1,"frames":[{"frame":0,"anchors":[{"triangle":10,"axis":[1,0,0],"angle":0.1}]}]}"#,
                "triangle 10 is out of range",
            ),
            (
                r#"{"version":1,"frames":[{"frame":0,"anchors":[{"triangle":1,"axis":[0,0,0],"angle":0.1}]}]}"#,
                "zero length",
            ),
            (
                r#"{"version":1,"frames":[{"frame":0,"anchors":[{"triangle":1,"axis":[1,0,0],"angle":4}]}]}"#,
                "outside [-π, π]",
            ),
            (
                r#"{"version":1,"frames":[{"frame":0,"anchors":[{"triangle":1,"axis":[1,0,0],"angle":1},{"triangle":1,"axis":[1,0,0],"angle":1}]}]}"#,
                "anchored twice",
            ),
            (r#"{"version":2,"frames":[]}"#, "unsupported version"),
            (
                r#"{"version":1,"frames":[{"frame":0,"anchors":[{"triangle":1,"axis":[1,0,0],"angle":1,"x":1}]}]}"#,
                "unknown field",
            ),
            (
                r#"{"version":1,"frames":[{"frame":0},{"frame":0}]}"#,
                "listed twice",
            ),
            (r#"{"version":1,"frames":["#, "line 1"),
        ];
        for (text, want) in cases {
            let e = AnchorSet::parse(text, Some(Path::new("a.json")), 2, 10)
                .unwrap_err()
                .to_string();
            assert!(e.contains(want) && e.contains("a.json"), "{text}: {e}");
        }
    }
}

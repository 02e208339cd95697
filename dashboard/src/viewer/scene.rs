//! An output folder and its input opened for viewing: one mesh both are drawn on, the anchors, where the
//! camera starts, and each frame with its overlays on request. Frames are read when asked for, never all at
//! once, so opening a long sequence costs one frame.

use super::frame_buffer::{self, FrameParts};
use super::Located;
use crease_core::folds::anchors::AnchorSet;
use crease_core::mesh::io::open_sequence;
use crease_core::mesh::subdivide::SubdividedSource;
use crease_core::mesh::{geometry, Frame, FrameSource, Topology};
use crease_core::metrics::per_triangle_stretch;
use crease_core::vec3::{self, V3};
use crease_core::{preview, shape, view};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Outputs subdivided more often than this are not matched to their input (each level is 4× the triangles).
const MAX_SUBDIVISION: usize = 4;

/// Where the detected anchors of a fold-detection job are kept in its output, in the order they are looked for:
/// the binary form the job's own tasks read (exact and fast), then the JSON written for people.
const ANCHORS_IN_OUTPUT: [&str; 2] = [".crease-work/folds/anchors.bin", "anchors.json"];

/// How the overlays are defined, for the page's legend: the same words as `report.json`'s `stretch_reference`
/// and `shape_kept`.
const STRETCH_DEFINITION: &str =
    "per triangle, max(s1 - 1, 1 - s2) of the output triangle against the input triangle of the same frame";
const DISPLACEMENT_DEFINITION: &str = "per vertex, |output - input| in the data's units";

#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SceneError {
    /// Nothing to show (no input or output could be opened): the reasons.
    Unavailable(String),
    /// A frame number past the end.
    OutOfRange(String),
    /// A frame file that cannot be read or does not match the sequence (the message names the file).
    Unreadable(String),
}

impl std::fmt::Display for SceneError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SceneError::Unavailable(m) | SceneError::OutOfRange(m) | SceneError::Unreadable(m) => {
                f.write_str(m)
            }
        }
    }
}

struct Part {
    source: Box<dyn FrameSource>,
    path: PathBuf,
    layout: &'static str,
}

pub struct Scene {
    input: Option<Part>,
    output: Option<Part>,
    topology: Arc<Topology>,
    frames: usize,
    origin: V3,
    anchors: Option<AnchorSet>,
    meta: Value,
}

fn open_part(path: &Path) -> Result<Part, String> {
    let opened = open_sequence(path).map_err(|e| e.to_string())?;
    Ok(Part {
        layout: opened.layout.kind(),
        source: opened.source,
        path: path.to_path_buf(),
    })
}

fn same_mesh(a: &Topology, b: &Topology) -> bool {
    a.n_vertices() == b.n_vertices() && a.triangles() == b.triangles()
}

/// The input as the output's mesh: itself, or midpoint-subdivided as often as the output was (a `--subdivide`
/// job keeps the input's vertices first and splits every triangle in four per level). How often is found
/// from the triangle counts, then checked triangle by triangle.
fn input_on_output_mesh(input: Part, out: &Topology) -> Result<Part, String> {
    let inp = input.source.topology().clone();
    if same_mesh(&inp, out) {
        return Ok(input);
    }
    let mismatch = || {
        format!(
            "the output's mesh ({} vertices, {} triangles) is neither the input's ({} vertices, {} triangles) \
             nor a subdivision of it",
            out.n_vertices(),
            out.n_triangles(),
            inp.n_vertices(),
            inp.n_triangles()
        )
    };
    let levels = (1..=MAX_SUBDIVISION)
        .find(|&l| inp.n_triangles() << (2 * l) == out.n_triangles())
        .ok_or_else(mismatch)?;
    let sub = SubdividedSource::owned(input.source, levels).map_err(|e| e.to_string())?;
    if !same_mesh(sub.topology(), out) {
        return Err(mismatch());
    }
    Ok(Part {
        source: Box::new(sub),
        path: input.path,
        layout: input.layout,
    })
}

/// The anchors to draw: the output's own, else the file the job was given. A set that cannot be read is a
/// note, not a failure: the meshes are still worth seeing.
fn read_anchors(
    loc: &Located,
    frames: usize,
    triangles: usize,
    notes: &mut Vec<String>,
) -> Option<(AnchorSet, PathBuf)> {
    let mut candidates: Vec<PathBuf> = Vec::new();
    if let Some(out) = &loc.output {
        candidates.extend(ANCHORS_IN_OUTPUT.iter().map(|k| out.join(k)));
    }
    candidates.extend(loc.anchors.iter().cloned());
    for path in candidates.into_iter().filter(|p| p.is_file()) {
        let read = if path.extension().is_some_and(|e| e == "bin") {
            std::fs::read(&path)
                .map_err(|e| format!("{}: {e}", path.display()))
                .and_then(|b| {
                    AnchorSet::from_binary(&b, &path, frames, triangles).map_err(|e| e.to_string())
                })
        } else {
            AnchorSet::read(&path, frames, triangles).map_err(|e| e.to_string())
        };
        match read {
            Ok(set) => return Some((set, path)),
            Err(e) => notes.push(format!("anchors not shown: {e}")),
        }
    }
    None
}

fn point_list(p: V3) -> Value {
    json!([p[0], p[1], p[2]])
}

impl Scene {
    /// Opens what `loc` names. The output comes first: it fixes the mesh; an input that does not fit it is left
    /// out with a note saying why, and so is an output whose frame count is not the input's.
    pub fn open(loc: &Located) -> Result<Scene, SceneError> {
        let mut notes = loc.notes.clone();
        let mut output = None;
        if let Some(path) = &loc.output {
            match open_part(path) {
                Ok(p) => output = Some(p),
                Err(e) => notes.push(format!("output not shown: {e}")),
            }
        }
        let mut input = None;
        if let Some(path) = &loc.input {
            match open_part(path) {
                Ok(p) => input = Some(p),
                Err(e) => notes.push(format!("input not shown: {e}")),
            }
        }
        if let (true, Some(out)) = (input.is_some(), &output) {
            let inp = input.take().expect("checked above");
            let out_topo = out.source.topology().clone();
            let (ni, no) = (inp.source.n_frames(), out.source.n_frames());
            if ni != no {
                notes.push(format!(
                    "input not shown: it has {ni} frames, the output {no} (is {} the input of this output?)",
                    inp.path.display()
                ));
            } else {
                match input_on_output_mesh(inp, &out_topo) {
                    Ok(p) => input = Some(p),
                    Err(e) => notes.push(format!("input not shown: {e}")),
                }
            }
        }
        let first = match (&output, &input) {
            (Some(p), _) | (None, Some(p)) => p,
            (None, None) => {
                return Err(SceneError::Unavailable(if notes.is_empty() {
                    format!("{}: nothing to show", loc.name)
                } else {
                    notes.join("; ")
                }))
            }
        };
        let topology = first.source.topology().clone();
        let frames = first.source.n_frames();
        let frame0 = first
            .source
            .read_frame(0)
            .map_err(|e| SceneError::Unreadable(e.to_string()))?;
        let (lo, hi) = geometry::bounding_box(&frame0);
        let origin = vec3::scale(vec3::add(lo, hi), 0.5);
        let radius = 0.5 * vec3::norm(vec3::sub(hi, lo));
        let anchors = read_anchors(loc, frames, topology.n_triangles(), &mut notes);
        let focus = anchors.as_ref().and_then(|(set, _)| {
            preview::fold_focus(&topology, &frame0, set.frame(0).iter().map(|a| a.triangle))
        });
        let (direction, up) = view::view_for(&frame0, focus);
        let part_meta = |p: &Option<Part>| {
            p.as_ref()
                .map(|p| json!({ "path": p.path.display().to_string(), "layout": p.layout }))
        };
        let both = input.is_some() && output.is_some();
        let anchors_meta = anchors.as_ref().map(|(set, path)| {
            json!({
                "source": path.display().to_string(),
                "total": set.total(),
                "per_frame": (0..frames).map(|t| set.frame(t).len()).collect::<Vec<_>>(),
                "control_lines_per_frame": (0..frames).map(|t| set.control_lines(t).len()).collect::<Vec<_>>(),
            })
        });
        let meta = json!({
            "name": loc.name,
            "frames": frames,
            "vertices": topology.n_vertices(),
            "triangles": topology.n_triangles(),
            "input": part_meta(&input),
            "output": part_meta(&output),
            "origin": point_list(origin),
            "radius": radius,
            "mean_edge": shape::mean_edge_length(&topology, &frame0),
            "camera": { "direction": point_list(direction), "up": point_list(up) },
            "anchors": anchors_meta,
            "overlays": {
                "stretch": both,
                "displacement": both,
                "anchors": anchors.as_ref().is_some_and(|(s, _)| s.total() > 0),
                "control_lines": anchors.as_ref().is_some_and(|(s, _)| (0..frames).any(|t| !s.control_lines(t).is_empty())),
            },
            "stretch_definition": STRETCH_DEFINITION,
            "displacement_definition": DISPLACEMENT_DEFINITION,
            "frame_format": { "magic": "CRVF", "version": frame_buffer::VERSION },
            "notes": notes,
        });
        Ok(Scene {
            input,
            output,
            topology,
            frames,
            origin,
            anchors: anchors.map(|(s, _)| s),
            meta,
        })
    }

    pub fn meta(&self) -> &Value {
        &self.meta
    }

    pub fn frames(&self) -> usize {
        self.frames
    }

    /// The shared triangle list as little-endian `u32` triples.
    pub fn index_bytes(&self) -> Vec<u8> {
        self.topology
            .triangles()
            .iter()
            .flatten()
            .flat_map(|i| i.to_le_bytes())
            .collect()
    }

    /// Frame `t` with its overlays, in the [`frame_buffer`] layout. Input and output are read side by side.
    pub fn frame_bytes(&self, t: usize) -> Result<Vec<u8>, SceneError> {
        if t >= self.frames {
            return Err(SceneError::OutOfRange(format!(
                "frame {t} is past the end: the sequence has {} frames (0 to {})",
                self.frames,
                self.frames - 1
            )));
        }
        let read = |p: &Option<Part>| -> Result<Option<Frame>, SceneError> {
            p.as_ref()
                .map(|p| p.source.read_frame(t))
                .transpose()
                .map_err(|e| SceneError::Unreadable(e.to_string()))
        };
        let (input, output) = std::thread::scope(|s| {
            let inp = s.spawn(|| read(&self.input));
            let out = read(&self.output);
            (inp.join().expect("input frame reader panicked"), out)
        });
        let (input, output) = (input?, output?);
        let (displacement, stretch) = match (&input, &output) {
            (Some(i), Some(o)) => (
                Some(
                    i.iter()
                        .zip(o)
                        .map(|(a, b)| vec3::norm(vec3::sub(*b, *a)))
                        .collect::<Vec<_>>(),
                ),
                Some(per_triangle_stretch(&self.topology, i, o)),
            ),
            _ => (None, None),
        };
        let anchors: Vec<u32> = self
            .anchors
            .as_ref()
            .map(|s| s.frame(t).iter().map(|a| a.triangle).collect())
            .unwrap_or_default();
        let lines = self
            .anchors
            .as_ref()
            .map(|s| s.control_lines(t))
            .unwrap_or(&[]);
        Ok(frame_buffer::encode(&FrameParts {
            frame: t,
            n_vertices: self.topology.n_vertices(),
            n_triangles: self.topology.n_triangles(),
            origin: self.origin,
            input: input.as_deref(),
            output: output.as_deref(),
            displacement: displacement.as_deref(),
            stretch: stretch.as_deref(),
            anchors: &anchors,
            lines,
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::viewer::frame_buffer::decode;
    use crease_core::mesh::io::{write_obj, write_pc2, write_ply_frame};
    use crease_core::mesh::subdivide::Subdivision;

    /// A 3 × 3 vertex sheet in the xy plane (8 triangles).
    fn sheet() -> (Topology, Frame) {
        let mut p = Vec::new();
        for j in 0..3 {
            for i in 0..3 {
                p.push([i as f64, j as f64, 0.0]);
            }
        }
        let mut tris = Vec::new();
        for j in 0..2u32 {
            for i in 0..2u32 {
                let a = 3 * j + i;
                tris.push([a, a + 1, a + 4]);
                tris.push([a, a + 4, a + 3]);
            }
        }
        (Topology::new(9, tris).unwrap(), p)
    }

    fn write_frames(dir: &Path, topo: &Topology, frames: &[Frame]) -> PathBuf {
        std::fs::create_dir_all(dir).unwrap();
        for (t, f) in frames.iter().enumerate() {
            write_obj(&dir.join(format!("frame_{:04}.obj", t + 1)), topo, f).unwrap();
        }
        dir.to_path_buf()
    }

    fn located(input: Option<PathBuf>, output: Option<PathBuf>) -> Located {
        Located {
            name: "test".into(),
            input,
            output,
            output_uri: None,
            anchors: None,
            notes: vec![],
        }
    }

    /// Three frames sliding along x, with the middle vertex raised by 0.25 in the output.
    fn pair(d: &Path) -> (Topology, Vec<Frame>, Vec<Frame>) {
        let (topo, base) = sheet();
        let input: Vec<Frame> = (0..3)
            .map(|t| {
                base.iter()
                    .map(|p| [p[0] + 0.1 * t as f64, p[1], p[2]])
                    .collect()
            })
            .collect();
        let output: Vec<Frame> = input
            .iter()
            .map(|f| {
                let mut f = f.clone();
                f[4][2] += 0.25;
                f
            })
            .collect();
        write_frames(&d.join("in"), &topo, &input);
        write_frames(&d.join("out"), &topo, &output);
        (topo, input, output)
    }

    #[test]
    fn a_frame_carries_both_sequences_and_overlays_by_the_core_definitions() {
        let d = tempfile::tempdir().unwrap();
        let (topo, input, output) = pair(d.path());
        let scene = Scene::open(&located(
            Some(d.path().join("in")),
            Some(d.path().join("out")),
        ))
        .unwrap();
        let meta = scene.meta();
        assert_eq!(meta["frames"], 3);
        assert_eq!(meta["vertices"], 9);
        assert_eq!(meta["overlays"]["stretch"], true);
        assert_eq!(meta["overlays"]["anchors"], false);
        // The output's frame 0 spans 0..2 in x and y and 0..0.25 in z: its box centre is the origin positions
        // are sent from.
        assert_eq!(meta["origin"], json!([1.0, 1.0, 0.125]));
        let f = decode(&scene.frame_bytes(2).unwrap()).unwrap();
        assert_eq!(f.frame, 2);
        let want: Vec<f32> = input[2]
            .iter()
            .flat_map(|p| [p[0] - 1.0, p[1] - 1.0, p[2] - 0.125].map(|x| x as f32))
            .collect();
        assert_eq!(f.input.unwrap(), want);
        assert_eq!(f.output.as_ref().unwrap()[3 * 4 + 2], 0.125);
        let disp = f.displacement.unwrap();
        assert_eq!(disp[4], 0.25);
        assert!(disp.iter().enumerate().all(|(i, &x)| i == 4 || x == 0.0));
        let stretch: Vec<f32> = per_triangle_stretch(&topo, &input[2], &output[2])
            .iter()
            .map(|&x| x as f32)
            .collect();
        assert!(stretch.iter().any(|&s| s > 0.0));
        assert_eq!(f.stretch.unwrap(), stretch);
        assert_eq!(scene.index_bytes().len(), 8 * 3 * 4);
        match scene.frame_bytes(3) {
            Err(SceneError::OutOfRange(m)) => assert!(m.contains("3 frames"), "{m}"),
            other => panic!("frame 3 of 3: {other:?}"),
        }
    }

    #[test]
    fn obj_ply_and_pc2_outputs_are_shown_alike() {
        let d = tempfile::tempdir().unwrap();
        let (topo, base) = sheet();
        // Steps of a quarter: exact in the f32 of PLY and PC2 files, so every layout holds the same values.
        let input: Vec<Frame> = (0..3)
            .map(|t| {
                base.iter()
                    .map(|p| [p[0] + 0.25 * t as f64, p[1], p[2]])
                    .collect()
            })
            .collect();
        let output: Vec<Frame> = input
            .iter()
            .map(|f| f.iter().map(|p| [p[0], p[1], p[2] + 0.25 * p[0]]).collect())
            .collect();
        write_frames(&d.path().join("in"), &topo, &input);
        write_frames(&d.path().join("obj"), &topo, &output);
        let ply = d.path().join("ply");
        std::fs::create_dir(&ply).unwrap();
        for (t, f) in output.iter().enumerate() {
            write_ply_frame(&ply.join(format!("frame_{:04}.ply", t + 1)), &topo, f, true).unwrap();
        }
        let pc2 = d.path().join("pc2");
        std::fs::create_dir(&pc2).unwrap();
        write_obj(&pc2.join("sheet.obj"), &topo, &output[0]).unwrap();
        write_pc2(&pc2.join("sheet.pc2"), &output, 0.0, 1.0).unwrap();
        let frames = |out: &str| {
            let scene = Scene::open(&located(
                Some(d.path().join("in")),
                Some(d.path().join(out)),
            ))
            .unwrap();
            assert!(scene.meta()["input"].is_object(), "{out}: {}", scene.meta());
            let layout = scene.meta()["output"]["layout"]
                .as_str()
                .unwrap()
                .to_string();
            let frames: Vec<_> = (0..3)
                .map(|t| decode(&scene.frame_bytes(t).unwrap()).unwrap())
                .collect();
            (layout, frames)
        };
        let (layout, obj) = frames("obj");
        assert_eq!(layout, "obj-frames");
        assert!(obj[2].stretch.as_ref().unwrap().iter().any(|&s| s > 0.0));
        for (out, want) in [("ply", "ply-frames"), ("pc2", "obj+pc2")] {
            let (layout, got) = frames(out);
            assert_eq!(layout, want);
            assert_eq!(got, obj, "{out}");
        }
    }

    #[test]
    fn a_subdivided_output_is_shown_on_the_subdivided_input() {
        let d = tempfile::tempdir().unwrap();
        let (topo, base) = sheet();
        write_frames(&d.path().join("in"), &topo, &[base.clone(), base.clone()]);
        let sub = Subdivision::new(&topo, 1).unwrap();
        let fine = sub.apply(&base);
        write_frames(&d.path().join("out"), sub.topology(), &[fine.clone(), fine]);
        let scene = Scene::open(&located(
            Some(d.path().join("in")),
            Some(d.path().join("out")),
        ))
        .unwrap();
        assert_eq!(scene.meta()["triangles"], 32);
        assert!(scene.meta()["input"].is_object(), "{}", scene.meta());
        let f = decode(&scene.frame_bytes(1).unwrap()).unwrap();
        assert_eq!(f.input, f.output);
        assert!(f.displacement.unwrap().iter().all(|&x| x == 0.0));
    }

    #[test]
    fn an_input_that_does_not_fit_the_output_is_left_out_with_the_reason() {
        let d = tempfile::tempdir().unwrap();
        let (topo, input, _) = pair(d.path());
        write_frames(&d.path().join("short"), &topo, &input[..2]);
        let scene = Scene::open(&located(
            Some(d.path().join("short")),
            Some(d.path().join("out")),
        ))
        .unwrap();
        assert!(scene.meta()["input"].is_null());
        assert_eq!(scene.meta()["overlays"]["stretch"], false);
        let notes = scene.meta()["notes"].to_string();
        assert!(notes.contains("2 frames, the output 3"), "{notes}");
        let f = decode(&scene.frame_bytes(0).unwrap()).unwrap();
        assert!(f.input.is_none() && f.output.is_some());
    }

    #[test]
    fn an_input_alone_is_shown_without_overlays() {
        let d = tempfile::tempdir().unwrap();
        let (_, input, _) = pair(d.path());
        let scene = Scene::open(&located(Some(d.path().join("in")), None)).unwrap();
        assert!(scene.meta()["output"].is_null() && scene.meta()["input"].is_object());
        assert_eq!(scene.meta()["overlays"]["displacement"], false);
        let f = decode(&scene.frame_bytes(1).unwrap()).unwrap();
        assert_eq!(f.input.unwrap()[0], (input[1][0][0] - 1.0) as f32);
        assert!(f.output.is_none() && f.stretch.is_none() && f.displacement.is_none());
    }

    #[test]
    fn nothing_to_show_says_why() {
        let d = tempfile::tempdir().unwrap();
        let missing = d.path().join("nowhere");
        match Scene::open(&located(None, Some(missing))) {
            Err(SceneError::Unavailable(m)) => {
                assert!(
                    m.contains("output not shown") && m.contains("nowhere"),
                    "{m}"
                )
            }
            other => panic!("{:?}", other.map(|s| s.meta().clone())),
        }
    }

    #[test]
    fn a_broken_frame_is_an_error_naming_its_file() {
        let d = tempfile::tempdir().unwrap();
        pair(d.path());
        let scene = Scene::open(&located(None, Some(d.path().join("out")))).unwrap();
        std::fs::write(d.path().join("out/frame_0002.obj"), "v 0 0 0\nf 1 2 3\n").unwrap();
        match scene.frame_bytes(1) {
            Err(SceneError::Unreadable(m)) => assert!(m.contains("frame_0002.obj"), "{m}"),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn the_outputs_anchors_and_control_lines_are_sent_per_frame() {
        let d = tempfile::tempdir().unwrap();
        pair(d.path());
        std::fs::write(
            d.path().join("out/anchors.json"),
            r#"{"version": 1, "frames": [
                {"frame": 1, "anchors": [{"triangle": 3, "axis": [0, 0, 1], "angle": 0.5}],
                 "control_lines": [[[1, 1, 0], [2, 1, 0], [2, 2, 0]]]}]}"#,
        )
        .unwrap();
        let scene = Scene::open(&located(
            Some(d.path().join("in")),
            Some(d.path().join("out")),
        ))
        .unwrap();
        let a = &scene.meta()["anchors"];
        assert_eq!(a["per_frame"], json!([0, 1, 0]));
        assert_eq!(a["control_lines_per_frame"], json!([0, 1, 0]));
        assert_eq!(scene.meta()["overlays"]["control_lines"], true);
        let f = decode(&scene.frame_bytes(1).unwrap()).unwrap();
        assert_eq!(f.anchors, [3]);
        assert_eq!(f.line_lengths, [3]);
        // Relative to the origin, the output's frame-0 box centre (1, 1, 0.125).
        assert_eq!(
            f.line_points,
            [0.0, 0.0, -0.125, 1.0, 0.0, -0.125, 1.0, 1.0, -0.125]
        );
        assert!(decode(&scene.frame_bytes(0).unwrap())
            .unwrap()
            .anchors
            .is_empty());
    }

    #[test]
    fn anchors_that_do_not_fit_are_a_note_not_a_failure() {
        let d = tempfile::tempdir().unwrap();
        pair(d.path());
        std::fs::write(
            d.path().join("out/anchors.json"),
            r#"{"version": 1, "frames": [{"frame": 0, "anchors": [{"triangle": 99, "axis": [0, 0, 1], "angle": 0.5}]}]}"#,
        )
        .unwrap();
        let scene = Scene::open(&located(None, Some(d.path().join("out")))).unwrap();
        assert!(scene.meta()["anchors"].is_null());
        let notes = scene.meta()["notes"].to_string();
        assert!(
            notes.contains("anchors not shown") && notes.contains("anchors.json"),
            "{notes}"
        );
    }
}

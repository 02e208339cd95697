//! Fold estimation from the capture video (Popa et al. 2009 §3.1, §4, anchors as in §5.1).
//!
//! Per frame: pick the best front and back cameras ([`views`]); take out of each chosen image the shading the
//! captured mesh explains under lighting fitted to it ([`shading`]); in what remains, find Canny edges at several
//! resolutions and radii, fit and split them with quadrics ([`edges`], [`quadric`]), orient them dark-on-the-left
//! and drop unclear or hue edges ([`orient`]), merge broken contours ([`merge`]), pair parallel edges of opposite
//! orientation and unite the levels ([`pairing`]); cast the pairs onto the frame mesh and turn the crossed
//! triangles into anchors ([`project`]), and the cloth beside them into anchors tilted as its lighting residual
//! shows ([`flanks`]). [`overlay`] draws the stages like the paper's Figure 4.
//!
//! Each frame is processed on its own, so any frame range gives the same per-frame answer
//! ([`Granularity::PerFrame`]); the automatic front/back vertices always come from frame 0 of the sequence.

pub mod blur;
pub mod cameras;
pub mod canny;
pub mod cover;
pub mod edges;
pub mod flanks;
pub mod merge;
pub mod orient;
pub mod overlay;
pub mod ownership;
pub mod pairing;
pub mod params;
pub mod project;
pub mod quadric;
pub mod resample;
pub mod scratch;
pub mod shading;
pub mod views;

pub use cameras::{CameraRig, Photo};
pub use params::{VideoParams, Views};

use super::{Anchor, Artifact, FoldDetector, FrameAnchors, Granularity};
use crate::error::{Error, Result};
use crate::mesh::{geometry, FrameSource, Topology};
use crate::progress::Progress;
use crate::vec3::V3;
use edges::{Level, LevelEdges};
use orient::Edge;
use pairing::Pair;
use project::ProjectedPair;
use rayon::prelude::*;
use std::collections::HashSet;
use std::ops::Range;

/// The video fold detector.
pub struct VideoFolds {
    pub rig: CameraRig,
    pub params: VideoParams,
    /// Image frame number of each sequence frame (`frame_0001.png` for sequence frame 0 of a sample numbered
    /// from 1).
    pub image_numbers: Vec<u64>,
    /// Tracked front and back vertices; `None` chooses them from frame 0 ([`views::auto_vertices`]).
    pub vertices: Option<(usize, usize)>,
    /// Frames whose fold-edge overlay (`overlays/frame_NNNN.png`, like the paper's Figure 4) is drawn by
    /// [`FoldDetector::detect_with_artifacts`].
    pub overlay_frames: Vec<usize>,
}

/// Storage key of the overlay of frame `t`.
pub fn overlay_key(t: usize) -> String {
    format!("overlays/frame_{t:04}.png")
}

/// Results of one level of one view.
#[derive(Debug, Clone)]
pub struct LevelResult {
    pub level: Level,
    /// Raw Canny chains (full-resolution pixels).
    pub chains: Vec<Vec<[f64; 2]>>,
    /// Oriented, merged edges.
    pub edges: Vec<Edge>,
    pub pairs: Vec<Pair>,
}

/// Results of one view of one frame.
#[derive(Debug, Clone)]
pub struct ViewResult {
    pub camera: usize,
    /// `front` or `back`.
    pub role: &'static str,
    pub photo: Photo,
    pub levels: Vec<LevelResult>,
    /// Pairs united over levels.
    pub union: Vec<Pair>,
    /// United pairs that project onto the garment.
    pub projected: Vec<ProjectedPair>,
    /// The lighting fitted to the captured mesh in this view (`photo` then holds its residual); `None` with
    /// raw darkness or when too little of the garment is seen for a fit.
    pub shading: Option<shading::ViewShading>,
}

/// Everything computed for one frame.
#[derive(Debug, Clone)]
pub struct FrameAnalysis {
    pub frame: usize,
    pub views: Vec<ViewResult>,
    pub anchors: FrameAnchors,
    pub notes: Vec<String>,
}

/// All the fold pairs of one image, before projection: per-level results and their union.
pub fn image_pairs(photo: &Photo, params: &VideoParams) -> (Vec<LevelResult>, Vec<Pair>) {
    let mask = if photo.has_alpha {
        photo.eroded_mask(params.silhouette_margin)
    } else {
        photo.mask.clone()
    };
    // Levels are independent until the union; they run in parallel and are collected in level order, so the
    // result is the same as a sequential loop.
    let levels: Vec<Level> = edges::levels(params);
    let results: Vec<LevelResult> = levels
        .into_par_iter()
        .enumerate()
        .map(|(li, level)| {
            let le: LevelEdges = edges::extract(photo, &mask, level, params);
            let oriented: Vec<Edge> = le
                .edges
                .iter()
                .filter_map(|e| orient::orient(e, &le, photo, params).ok())
                .collect();
            // The level image is only needed for orientation; its buffer serves the next level or frame.
            scratch::recycle(le.smoothed);
            let merged = merge::merge(
                oriented,
                params.merge_gap,
                // `fit_tolerance` is in pixels of the level's resolution; merged edges are in full-resolution pixels.
                params.fit_tolerance / level.scale,
                params.max_curvature,
            );
            let pairs = pairing::pair_edges(&merged, params, li);
            LevelResult {
                level,
                chains: le.chains,
                edges: merged,
                pairs,
            }
        })
        .collect();
    let union = pairing::union(results.iter().map(|r| r.pairs.clone()).collect());
    (results, union)
}

impl VideoFolds {
    pub fn new(rig: CameraRig, params: VideoParams, image_numbers: Vec<u64>) -> Result<Self> {
        params.validate()?;
        Ok(VideoFolds {
            rig,
            params,
            image_numbers,
            vertices: None,
            overlay_frames: Vec::new(),
        })
    }

    /// The tracked vertices: given, or chosen from frame 0 of `source`.
    pub fn tracked_vertices(&self, source: &dyn FrameSource) -> Result<(usize, usize)> {
        let nv = source.topology().n_vertices();
        if let Some((f, b)) = self.vertices {
            for (name, v) in [("front_vertex", f), ("back_vertex", b)] {
                if v >= nv {
                    return Err(Error::param(
                        name,
                        format!("vertex {v} is out of range (the mesh has {nv} vertices)"),
                    ));
                }
            }
            return Ok((f, b));
        }
        let first = source.read_frame(0)?;
        Ok(views::auto_vertices(source.topology(), &first, &self.rig))
    }

    fn check_source(&self, source: &dyn FrameSource) -> Result<()> {
        if self.image_numbers.len() != source.n_frames() {
            return Err(Error::param(
                "image_numbers",
                format!(
                    "{} image numbers for a sequence of {} frames",
                    self.image_numbers.len(),
                    source.n_frames()
                ),
            ));
        }
        Ok(())
    }

    /// The sequence's width scale for anchor angles: the mean edge length of frame 0.
    pub fn width_scale(&self, source: &dyn FrameSource) -> Result<f64> {
        let first = source.read_frame(0)?;
        Ok(super::stretch::mean_edge_length(source.topology(), &first))
    }

    /// Analyses frame `t` with positions `positions`; `h` is the sequence's [`Self::width_scale`].
    pub fn analyze(
        &self,
        topo: &Topology,
        positions: &[V3],
        t: usize,
        vertices: (usize, usize),
        h: f64,
    ) -> Result<FrameAnalysis> {
        let choice = views::select(
            &self.rig,
            topo,
            positions,
            vertices,
            self.params.stable_normal_rings,
            t,
        );
        let mut notes = choice.notes.clone();
        let number = *self.image_numbers.get(t).ok_or_else(|| {
            Error::param("image_numbers", format!("no image number for frame {t}"))
        })?;
        let mut roles: Vec<(&'static str, usize)> =
            [("front", choice.front), ("back", choice.back)]
                .into_iter()
                .filter_map(|(role, cam)| Some((role, cam?)))
                .collect();
        let seeing = |cam: usize| views::coverage(&self.rig, cam, positions) > 0.0;
        let mut cover = None;
        let mut ready: Vec<Option<project::MeshCaster>> =
            (0..self.rig.cameras.len()).map(|_| None).collect();
        if self.params.views == Views::All {
            for cam in 0..self.rig.cameras.len() {
                if !roles.iter().any(|r| r.1 == cam) && seeing(cam) {
                    roles.push(("side", cam));
                }
            }
        } else if self.params.views == Views::Cover {
            for (cam, slot) in ready.iter_mut().enumerate() {
                if seeing(cam) {
                    *slot = Some(project::MeshCaster::new(
                        topo,
                        positions,
                        &self.rig.cameras[cam].camera,
                    )?);
                }
            }
            let candidates: Vec<(usize, &project::MeshCaster)> = ready
                .iter()
                .enumerate()
                .filter_map(|(c, m)| Some((c, m.as_ref()?)))
                .collect();
            let primary: Vec<usize> = roles.iter().map(|r| r.1).collect();
            let chosen = cover::cover_frame(
                topo,
                positions,
                &candidates,
                &primary,
                self.params.square_cos,
                self.params.min_cover_gain,
            );
            for &cam in chosen.added() {
                roles.push(("side", cam));
            }
            cover = Some(chosen);
        }
        let mut views = Vec::new();
        let mut casters = Vec::new();
        for (role, cam) in roles {
            let photo = self.rig.load(cam, t, number)?;
            if photo.has_alpha && !photo.mask.iter().any(|&m| m) {
                notes.push(format!(
                    "camera {} frame {t}: the image shows no garment (all transparent)",
                    self.rig.cameras[cam].name
                ));
                continue;
            }
            let (photo, lit) = if self.params.lighting_residual {
                let camera = &self.rig.cameras[cam].camera;
                match shading::fit_view(&photo, topo, positions, camera) {
                    Some(lit) => (shading::residual_of(&photo, &lit), Some(lit)),
                    None => {
                        notes.push(format!(
                            "camera {} frame {t}: too little of the garment is seen to fit its lighting; \
                             fold edges are looked for in the raw image",
                            self.rig.cameras[cam].name
                        ));
                        (photo, None)
                    }
                }
            } else {
                (photo, None)
            };
            let (levels, union) = image_pairs(&photo, &self.params);
            let mut caster = match ready[cam].take() {
                Some(c) => c,
                None => project::MeshCaster::new(topo, positions, &self.rig.cameras[cam].camera)?,
            };
            caster.skip_border = self.params.skip_border;
            let projected: Vec<ProjectedPair> = union
                .iter()
                .filter_map(|p| project::project_pair(&caster, p, &self.params))
                .collect();
            casters.push(caster);
            views.push(ViewResult {
                camera: cam,
                role,
                photo,
                levels,
                union,
                projected,
                shading: lit,
            });
        }
        let owners = (self.params.views == Views::All).then(|| {
            let h_frame = crate::folds::stretch::mean_edge_length(topo, positions);
            ownership::Ownership::new(topo, positions, &casters, h_frame)
        });
        let keep = |v: usize, tri: u32| match (&owners, &cover) {
            (Some(o), _) => o.owns(v, tri),
            (None, Some(c)) => c.allows(views[v].camera, tri),
            (None, None) => true,
        };
        let anchors = self.frame_anchors(topo, positions, t, &views, h, &keep);
        Ok(FrameAnalysis {
            frame: t,
            views,
            anchors,
            notes,
        })
    }

    /// Anchors of a frame from its projected pairs (best pairs first; a triangle keeps its first anchor). View
    /// `v`'s anchor on triangle `tri` is kept only where `keep(v, tri)` ([`ownership`], [`cover`]).
    fn frame_anchors(
        &self,
        topo: &Topology,
        positions: &[V3],
        t: usize,
        views: &[ViewResult],
        h: f64,
        keep: &dyn Fn(usize, u32) -> bool,
    ) -> FrameAnchors {
        let normals = geometry::triangle_normals(topo, positions);
        let all: Vec<(usize, &ProjectedPair)> = views
            .iter()
            .enumerate()
            .flat_map(|(v, view)| view.projected.iter().map(move |p| (v, p)))
            .collect();
        let mut seen = HashSet::new();
        let mut anchors: Vec<Anchor> = Vec::new();
        let mut control_lines = Vec::new();
        for &(v, p) in &all {
            let angle = project::pair_angle(p.width, h, &self.params);
            for hits in [&p.a, &p.b] {
                for a in project::edge_anchors(hits, &normals, angle) {
                    if !keep(v, a.triangle) {
                        continue;
                    }
                    if seen.insert(a.triangle) {
                        anchors.push(a);
                    }
                }
                control_lines.push(hits.iter().map(|h| h.point).collect());
            }
        }
        if let Some(settings) = self.flank_settings() {
            // Flanks after every edge anchor: a triangle an edge crosses keeps the edge's anchor.
            let pixels: Vec<Option<flanks::TrianglePixels>> = views
                .iter()
                .map(|view| {
                    let lit = view.shading.as_ref()?;
                    Some(flanks::TrianglePixels::new(
                        lit,
                        &view.photo.mask,
                        topo.n_triangles(),
                    ))
                })
                .collect();
            for &(v, p) in &all {
                let (Some(lit), Some(px)) = (&views[v].shading, &pixels[v]) else {
                    continue;
                };
                let angle = project::pair_angle(p.width, h, &self.params);
                for a in flanks::pair_flanks(
                    topo,
                    positions,
                    &normals,
                    p,
                    lit,
                    &views[v].photo.gray,
                    px,
                    &settings,
                    angle,
                ) {
                    if keep(v, a.triangle) && seen.insert(a.triangle) {
                        anchors.push(a);
                    }
                }
            }
        }
        anchors.sort_by_key(|a| a.triangle);
        FrameAnchors {
            frame: t,
            anchors,
            control_lines,
            detection: Some(super::FrameDetection {
                folds: all.len(),
                seeds_tried: None,
            }),
        }
    }
}

impl VideoFolds {
    /// The flank settings ([`flanks`]), `None` when flanks are off.
    fn flank_settings(&self) -> Option<flanks::FlankSettings> {
        let p = &self.params;
        p.flank_tilt.then(|| flanks::FlankSettings {
            band: p.flank_band,
            min_tilt: p.flank_min_tilt_deg.to_radians(),
            prior: p.flank_prior_deg.to_radians(),
            min_pixels: 4,
        })
    }
}

impl FoldDetector for VideoFolds {
    fn name(&self) -> &'static str {
        "video"
    }

    fn granularity(&self) -> Granularity {
        Granularity::PerFrame
    }

    fn detect(
        &self,
        source: &dyn FrameSource,
        frames: Range<usize>,
        progress: &dyn Progress,
    ) -> Result<Vec<FrameAnchors>> {
        Ok(self.detect_with_artifacts(source, frames, progress)?.0)
    }

    /// Also draws the overlays of the range's `overlay_frames` from the analysis the anchors came from.
    fn detect_with_artifacts(
        &self,
        source: &dyn FrameSource,
        frames: Range<usize>,
        progress: &dyn Progress,
    ) -> Result<(Vec<FrameAnchors>, Vec<Artifact>)> {
        self.check_source(source)?;
        if frames.end > source.n_frames() {
            return Err(Error::param(
                "frames",
                format!(
                    "range {frames:?} exceeds the sequence's {} frames",
                    source.n_frames()
                ),
            ));
        }
        let vertices = self.tracked_vertices(source)?;
        let h = self.width_scale(source)?;
        let topo = source.topology().clone();
        let names: Vec<String> = self.rig.cameras.iter().map(|c| c.name.clone()).collect();
        progress.begin("video folds", frames.len() as u64);
        let out: Result<Vec<(FrameAnchors, Option<Artifact>)>> = frames
            .clone()
            .into_par_iter()
            .map(|t| {
                if progress.cancelled() {
                    return Err(Error::Cancelled);
                }
                let positions = source.read_frame(t)?;
                let a = self.analyze(&topo, &positions, t, vertices, h)?;
                for n in &a.notes {
                    progress.note(n);
                }
                let art = if self.overlay_frames.contains(&t) {
                    let key = overlay_key(t);
                    let img = overlay::frame_overlay(&a, &names);
                    let bytes = crate::render::png_bytes(&img, std::path::Path::new(&key))?;
                    Some(Artifact { key, bytes })
                } else {
                    None
                };
                progress.advance("video folds", 1);
                Ok((a.anchors, art))
            })
            .collect();
        progress.end("video folds");
        let (anchors, arts): (Vec<FrameAnchors>, Vec<Option<Artifact>>) = out?.into_iter().unzip();
        Ok((anchors, arts.into_iter().flatten().collect()))
    }

    /// Anchors matched over frames, angles smoothed in time, single-frame folds dropped.
    fn settle(
        &self,
        source: &dyn FrameSource,
        frames: Vec<FrameAnchors>,
    ) -> Result<Vec<FrameAnchors>> {
        super::temporal::settle(source, frames, self.params.temporal_radius)
    }

    /// The cameras and the tracked vertices (and whether they were chosen automatically).
    fn summary(&self, source: &dyn FrameSource) -> Result<serde_json::Value> {
        let (front, back) = self.tracked_vertices(source)?;
        Ok(serde_json::json!({
            "cameras": self.rig.cameras.len(),
            "tracked_vertices": { "front": front, "back": back, "automatic": self.vertices.is_none() },
            "parameters": self.params,
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::folds::video::cameras::{NamedCamera, DEFAULT_IMAGE_PATTERN};
    use crate::render::CalibratedCamera;
    use std::collections::HashMap;

    /// A 1 x 1 sheet (5 cm edges) in z = 0 under a camera looking down -z.
    fn setup() -> (std::sync::Arc<Topology>, Vec<V3>, CalibratedCamera) {
        let (topo, frame) = crate::synth::sheet(21, 21, 0.05).unwrap();
        let cam = CalibratedCamera {
            fx: 400.0,
            fy: 400.0,
            cx: 199.5,
            cy: 199.5,
            r: [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]],
            t: [-0.5, 0.5, 2.0],
            width: 400,
            height: 400,
        };
        (topo, frame, cam)
    }

    /// A projected pair of two vertical world lines at x = `x0` and `x0 + width`.
    fn pair(
        caster: &project::MeshCaster,
        cam: &CalibratedCamera,
        x0: f64,
        width: f64,
    ) -> ProjectedPair {
        let line = |x: f64| -> Vec<[f64; 2]> {
            (0..30)
                .map(|i| cam.project([x, 0.2 + 0.02 * i as f64, 0.0]).unwrap())
                .collect()
        };
        let (a, _) = caster.cast_polyline(&line(x0), 0.5, 0.2);
        let (b, _) = caster.cast_polyline(&line(x0 + width), 0.5, 0.2);
        let pair = Pair {
            a: line(x0),
            b: line(x0 + width),
            ridge: false,
            width: 0.0,
            length: 0.0,
            midline: Vec::new(),
            level: 0,
        };
        ProjectedPair { pair, a, b, width }
    }

    /// Before, angles were spread between the frame's narrowest and widest pair: a fold of constant width got
    /// 45° alone and 30° as soon as a narrower fold appeared beside it. On one scale its angle cannot change.
    #[test]
    fn a_fold_of_constant_width_keeps_its_angle_across_frames() {
        let (topo, p, cam) = setup();
        let rig = CameraRig {
            cameras: vec![NamedCamera {
                name: "cam00".into(),
                camera: cam,
            }],
            images_dir: "unused".into(),
            image_pattern: DEFAULT_IMAGE_PATTERN.to_string(),
        };
        let det = VideoFolds::new(rig, VideoParams::default(), vec![1, 2, 3]).unwrap();
        let caster = project::MeshCaster::new(&topo, &p, &cam).unwrap();
        let h = crate::folds::stretch::mean_edge_length(&topo, &p);
        let view = |pairs: Vec<ProjectedPair>| bare_view(0, pairs);
        let fold = || pair(&caster, &cam, 0.3, 0.15);
        let frames = [
            vec![fold()],
            vec![fold(), pair(&caster, &cam, 0.7, 0.06)],
            vec![fold(), pair(&caster, &cam, 0.7, 0.4)],
        ];
        let mut angles = Vec::new();
        for (t, pairs) in frames.into_iter().enumerate() {
            let fa = det.frame_anchors(&topo, &p, t, &[view(pairs)], h, &|_, _| true);
            // The fold's triangles lie left of x = 0.5.
            let mine: Vec<f64> = fa
                .anchors
                .iter()
                .filter(|a| {
                    let tri = topo.triangles()[a.triangle as usize];
                    tri.iter().all(|&v| p[v as usize][0] < 0.5)
                })
                .map(|a| a.angle)
                .collect();
            assert!(mine.len() >= 4, "frame {t}: {:?}", fa.anchors);
            angles.push(mine[0]);
            assert!(mine.iter().all(|&a| a == mine[0]));
        }
        assert!(angles.iter().all(|&a| a == angles[0]), "{angles:?}");
        // Between 60° (1.5 edge lengths) and 30° (6), inversely proportional.
        let w = 0.15 / h;
        assert!(w > 1.5 && w < 6.0);
        let want = 60.0 * 30.0 / (30.0 + (w - 1.5) / (6.0 - 1.5) * 30.0);
        assert!((angles[0].to_degrees() - want).abs() < 1e-6, "{angles:?}");
    }

    /// A view holding only `pairs` (frame_anchors reads nothing else).
    fn bare_view(camera: usize, pairs: Vec<ProjectedPair>) -> ViewResult {
        ViewResult {
            camera,
            role: "front",
            photo: Photo {
                width: 1,
                height: 1,
                gray: vec![0.0],
                rgb: vec![[0.0; 3]],
                mask: vec![true],
                has_alpha: false,
            },
            levels: Vec::new(),
            union: Vec::new(),
            projected: pairs,
            shading: None,
        }
    }

    /// With every camera analysed, each triangle keeps only the anchors of the view that sees it most squarely,
    /// whichever view comes first.
    #[test]
    fn each_triangle_keeps_the_anchors_of_the_squarest_view() {
        use crate::render::{Camera, Projection};
        let (topo, p, square_cam) = setup();
        let (lo, hi) = geometry::bounding_box(&p);
        let slanted_cam =
            Camera::fit(lo, hi, [1.2, 0.0, -1.0], [0.0, 1.0, 0.0], 400, 400).calibrated();
        let named = |name: &str, camera| NamedCamera {
            name: name.into(),
            camera,
        };
        let rig = CameraRig {
            cameras: vec![named("square", square_cam), named("slanted", slanted_cam)],
            images_dir: "unused".into(),
            image_pattern: DEFAULT_IMAGE_PATTERN.to_string(),
        };
        let det = VideoFolds::new(rig, VideoParams::default(), vec![1]).unwrap();
        let h = crate::folds::stretch::mean_edge_length(&topo, &p);
        let caster = |c: &CalibratedCamera| project::MeshCaster::new(&topo, &p, c).unwrap();
        // Both views see the edge at x = 0.3; the slanted view pairs it with a nearer edge, so its angle differs.
        let square = pair(&caster(&square_cam), &square_cam, 0.3, 0.15);
        let slanted = pair(&caster(&slanted_cam), &slanted_cam, 0.3, 0.06);
        let (a_square, a_slanted) = (
            project::pair_angle(square.width, h, &det.params),
            project::pair_angle(slanted.width, h, &det.params),
        );
        assert!((a_square - a_slanted).abs() > 0.1, "{a_square} {a_slanted}");
        let alone = |v: ViewResult| -> HashMap<u32, f64> {
            det.frame_anchors(&topo, &p, 0, &[v], h, &|_, _| true)
                .anchors
                .iter()
                .map(|a| (a.triangle, a.angle))
                .collect()
        };
        let only_square = alone(bare_view(0, vec![square.clone()]));
        let only_slanted = alone(bare_view(1, vec![slanted.clone()]));
        let shared: Vec<u32> = only_square
            .keys()
            .filter(|t| only_slanted.contains_key(t))
            .copied()
            .collect();
        assert!(shared.len() >= 4, "{shared:?}");

        let casters_ab = [caster(&square_cam), caster(&slanted_cam)];
        let casters_ba = [caster(&slanted_cam), caster(&square_cam)];
        let own_ab = ownership::Ownership::new(&topo, &p, &casters_ab, h);
        let own_ba = ownership::Ownership::new(&topo, &p, &casters_ba, h);
        let ab = [
            bare_view(0, vec![square.clone()]),
            bare_view(1, vec![slanted.clone()]),
        ];
        let ba = [bare_view(1, vec![slanted]), bare_view(0, vec![square])];
        let fa = det.frame_anchors(&topo, &p, 0, &ab, h, &|v, t| own_ab.owns(v, t));
        let fb = det.frame_anchors(&topo, &p, 0, &ba, h, &|v, t| own_ba.owns(v, t));
        assert_eq!(fa.anchors, fb.anchors);
        // The square camera sees the whole flat sheet more squarely: its anchors are kept, the slanted
        // camera's are dropped, also on the triangles only the slanted camera anchored.
        let got: HashMap<u32, f64> = fa.anchors.iter().map(|a| (a.triangle, a.angle)).collect();
        assert_eq!(got, only_square);
        assert!(only_slanted.keys().any(|t| !only_square.contains_key(t)));
        // Without the ownership test the first view wins, as with Popa's two views.
        let first = det.frame_anchors(&topo, &p, 0, &ba, h, &|_, _| true);
        assert!(shared.iter().all(|t| first
            .anchors
            .iter()
            .any(|a| a.triangle == *t && a.angle == a_slanted)));
    }
}

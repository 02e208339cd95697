//! `crease run` and `crease demo`.

use crate::folds_stretch::StretchArgs;
use crate::local::LocalCluster;
use crate::progress::CliProgress;
use anyhow::{bail, Context, Result};
use clap::Args;
use crease_coordinator::JobClient;
use crease_core::folds::AnchorSet;
use crease_core::fsutil;
use crease_core::mesh::io::{open_sequence, write_obj_sequence};
use crease_core::mesh::FrameSource;
use crease_core::spacetime::position::stretch::StretchRotation;
use crease_core::spacetime::{deform, Coefficients, DeformParams, Pinning, WeightMode};
use crease_core::synth::{self, DemoSpec};
use serde_json::json;
use std::path::{Path, PathBuf};

/// Deformation parameters shared by `run` and `bench` (defaults from Popa et al. 2009).
#[derive(Args, Clone, Debug)]
pub struct DeformArgs {
    /// Weight solve: `fused` (3 right-hand sides) or `per-anchor` (one CG column per anchor, in blocks).
    #[arg(long, default_value = "fused")]
    pub mode: WeightMode,
    /// Spatial smoothness weight c_s.
    #[arg(long, default_value_t = 0.9, allow_hyphen_values = true)]
    pub c_s: f64,
    /// Temporal smoothness weight c_t.
    #[arg(long, default_value_t = 0.5, allow_hyphen_values = true)]
    pub c_t: f64,
    /// Mitigation weight c_i pulling non-anchors towards the identity.
    #[arg(long, default_value_t = 0.1, allow_hyphen_values = true)]
    pub c_i: f64,
    /// Anchor weight c_a.
    #[arg(long, default_value_t = 10.0, allow_hyphen_values = true)]
    pub c_a: f64,
    /// Frames per time window.
    #[arg(long, default_value_t = 10)]
    pub window: usize,
    /// Frames between window starts (window - shift frames are cross-faded).
    #[arg(long, default_value_t = 7)]
    pub shift: usize,
    /// CG relative residual tolerance.
    #[arg(long, default_value_t = 1e-3)]
    pub cg_tol: f64,
    /// CG iteration limit (an error names the window if it is reached).
    #[arg(long, default_value_t = 2000)]
    pub cg_max_iter: usize,
    /// Anchor columns per block in per-anchor mode.
    #[arg(long, default_value_t = 256)]
    pub anchor_block: usize,
    /// Stretch-reduction passes (each reuses the frame's factor).
    #[arg(long, default_value_t = 2)]
    pub stretch_passes: usize,
    /// Rotation of each stretch pass: `anchored` (halfway between `polar` and the folds' blended rotation, so
    /// the passes keep the folds), `polar` (closest to the triangle's deformation) or `normal` (the paper's
    /// original-to-new normal).
    #[arg(long, default_value = "anchored")]
    pub stretch_rotation: StretchRotation,
    /// Shape screen cutoff wavelength in detail scales: longer displacements keep the captured shape,
    /// shorter ones (folds) are free. `off` (or 0): the unscreened system, with --pinning.
    #[arg(long, default_value = "2", value_parser = parse_shape_cutoff)]
    pub shape_cutoff: f64,
    /// Only with --shape-cutoff off. `centroid`: keep each component's mean position; `vertex`: keep its
    /// lowest-index vertex fixed.
    #[arg(long, default_value = "centroid", value_parser = parse_pinning)]
    pub pinning: Pinning,
    /// Detail scale, in the input's length unit: the wavelength the modelled capture halves (the fold relief
    /// and the shape screen work at it). 0 = five mean edge lengths of the first frame.
    #[arg(long, default_value_t = 0.0)]
    pub detail_scale: f64,
    /// Fold relief: Van Cittert steps of the deconvolution (0 = no relief).
    #[arg(long, default_value_t = 8)]
    pub relief_steps: u32,
    /// Shape projection: the fraction of the capture filter's low-pass of the positioned displacement removed
    /// before the fold restoration, so folds add only what the capture smoothed away and the garment, its
    /// rims included, keeps the captured shape. 0 = off, at most 1; only with the shape screen on.
    #[arg(long, default_value_t = crease_core::spacetime::shape::projection::DEFAULT_SHAPE_PROJECTION)]
    pub shape_projection: f64,
    /// Frames per positioning operator: 1 factorises every frame's own system (exact); k > 1 positions each
    /// block of k frames with the first frame's factor (one factorisation per k frames; 7 keeps the public
    /// cases within the quality targets, docs/benchmarks.md "issue14-fused (second stop)").
    #[arg(long, default_value_t = 1)]
    pub operator_block: usize,

    /// Strain limit: the positioning's last step shortens every edge longer than (1 + this) times its
    /// reference length back to it (Provot-style, Gauss–Seidel over the edges; compression, which folds are
    /// made of, is free against the sequence reference). A fraction (0.05 = 5%); `off` (or 0) turns it off.
    /// docs/fidelity.md, "Strain limiting". Default 0.05 against the sequence reference; the built-in demo,
    /// whose input is its own rest state, uses 0.02.
    #[arg(long, value_parser = parse_strain_limit)]
    pub strain_limit: Option<f64>,
    /// Gauss–Seidel sweeps of the strain limit (it stops once a sweep moves nothing).
    #[arg(long, default_value_t = crease_core::spacetime::position::strain_limit::DEFAULT_STRAIN_LIMIT_SWEEPS)]
    pub strain_limit_sweeps: usize,
    /// The strain limit's reference lengths: `sequence` (per edge, its longest captured length over the
    /// sequence; the default with --input) or `frame` (the frame's own captured lengths: an input that is its
    /// own rest state; the default of the built-in demo).
    #[arg(long)]
    pub strain_reference: Option<crease_core::spacetime::position::strain_limit::StrainReference>,
}

fn parse_strain_limit(s: &str) -> Result<f64, String> {
    if s == "off" {
        return Ok(0.0);
    }
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        _ => Err(format!(
            "`{s}` is not a strain limit (a fraction ≥ 0, 0.05 = 5%) or `off`"
        )),
    }
}

fn parse_shape_cutoff(s: &str) -> Result<f64, String> {
    if s == "off" {
        return Ok(0.0);
    }
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        _ => Err(format!(
            "`{s}` is not a wavelength in mean edge lengths (a number ≥ 0) or `off`"
        )),
    }
}

fn parse_pinning(s: &str) -> Result<Pinning, String> {
    match s {
        "centroid" => Ok(Pinning::Centroid),
        "vertex" => Ok(Pinning::Vertex),
        _ => Err(format!("`{s}` is not one of: centroid, vertex")),
    }
}

impl DeformArgs {
    pub fn params(&self) -> DeformParams {
        DeformParams {
            coefficients: Coefficients {
                c_s: self.c_s,
                c_t: self.c_t,
                c_i: self.c_i,
                c_a: self.c_a,
            },
            window: self.window,
            shift: self.shift,
            cg_tolerance: self.cg_tol,
            cg_max_iterations: self.cg_max_iter,
            mode: self.mode,
            anchor_block: self.anchor_block,
            stretch_passes: self.stretch_passes,
            stretch_rotation: self.stretch_rotation,
            shape_cutoff: self.shape_cutoff,
            pinning: self.pinning,
            relief: crease_core::spacetime::shape::relief::ReliefParams {
                scale: self.detail_scale,
                steps: self.relief_steps,
                ..Default::default()
            },
            shape_projection: self.shape_projection,
            operator_block: self.operator_block,

            strain_limit: self
                .strain_limit
                .unwrap_or(crease_core::spacetime::position::strain_limit::DEFAULT_STRAIN_LIMIT),
            strain_limit_sweeps: self.strain_limit_sweeps,
            strain_reference: self.strain_reference.unwrap_or_default(),
        }
    }
}

/// Where the folds come from.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Folds {
    /// An anchors file (--anchors).
    Anchors,
    /// The geometry alone (Chen 2011 ch. 4): --stretch-* flags, --subdivide.
    Stretch,
    /// The capture video (Popa et al. 2009 §4): --cameras, --images.
    Video,
}

#[derive(Args, Debug)]
pub struct RunArgs {
    /// Input sequence: a directory of numbered OBJ or PLY frames, or OBJ + PC2. Omit to run the built-in demo.
    #[arg(long)]
    pub input: Option<PathBuf>,
    /// Anchors file (JSON, see docs/formats.md). Required with --input unless --folds detects them.
    #[arg(long)]
    pub anchors: Option<PathBuf>,
    /// Where the folds come from: `anchors` (the --anchors file; the default), `stretch` (estimated from the
    /// geometry alone, Chen 2011 ch. 4) or `video` (from the capture video, Popa et al. 2009 §4). Detectors
    /// write anchors.json and their overlays to --out.
    #[arg(long, value_enum)]
    pub folds: Option<Folds>,
    #[command(flatten)]
    pub stretch: StretchArgs,
    #[command(flatten)]
    pub video: Box<crate::folds_video::VideoArgs>,
    /// Output directory (the wrinkled sequence, report.json, preview.png, stretch.png).
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[command(flatten)]
    pub deform: DeformArgs,
    /// Frames to show in preview.png (default: four spread over the sequence).
    #[arg(long, value_delimiter = ',')]
    pub preview_frames: Vec<usize>,
    /// Preview tile size in pixels.
    #[arg(long, default_value_t = 384)]
    pub preview_size: u32,
    /// Demo size in triangles when no --input is given.
    #[arg(long, default_value_t = 40_000)]
    pub demo_triangles: usize,
    /// Demo length in frames when no --input is given.
    #[arg(long, default_value_t = 36)]
    pub demo_frames: usize,
    /// No progress bars or log lines.
    #[arg(long)]
    pub quiet: bool,
    /// Workers of the single-node cluster (each a gRPC server on 127.0.0.1).
    #[arg(long, default_value_t = 1)]
    pub local_workers: usize,
    /// Tasks each local worker runs at the same time.
    #[arg(long, default_value_t = 2)]
    pub local_capacity: u32,
}

#[derive(Args, Debug)]
pub struct DemoArgs {
    /// Directory to write `input/` (numbered OBJ frames) and `anchors.json` into.
    #[arg(long)]
    pub out: PathBuf,
    /// Triangles of the demo garment (approximately).
    #[arg(long, default_value_t = 40_000)]
    pub triangles: usize,
    /// Frames of the demo sequence (at least 2).
    #[arg(long, default_value_t = 36)]
    pub frames: usize,
    /// Also write a synthetic capture video: the ground-truth folded sequence (`gt/`, the input deformed with
    /// its anchors) rendered from a ring of calibrated cameras (`cameras.json`, `images/<camera>/frame_NNNN.png`).
    #[arg(long)]
    pub with_video: bool,
    /// Cameras on the ring (with --with-video).
    #[arg(long, default_value_t = 4)]
    pub video_cameras: usize,
    /// Image width in pixels (with --with-video).
    #[arg(long, default_value_t = 480)]
    pub video_width: u32,
    /// Image height in pixels (with --with-video).
    #[arg(long, default_value_t = 640)]
    pub video_height: u32,
}

/// Writes the demo input; returns (input dir, anchors file).
fn write_demo(out: &Path, triangles: usize, frames: usize) -> Result<(PathBuf, PathBuf)> {
    if frames < 2 {
        bail!("--frames must be at least 2, got {frames}");
    }
    if triangles < 500 {
        bail!("--triangles must be at least 500, got {triangles}");
    }
    let spec = DemoSpec {
        triangles,
        frames,
        ..Default::default()
    };
    let (seq, anchors) = synth::demo(&spec)?;
    let (input, anchors_path) = synth::write_demo(out, &seq, &anchors)?;
    eprintln!(
        "demo: {} frames, {} vertices, {} triangles, {} anchors -> {}",
        frames,
        seq.topology.n_vertices(),
        seq.topology.n_triangles(),
        anchors.total(),
        out.display()
    );
    Ok((input, anchors_path))
}

pub fn demo(a: DemoArgs) -> Result<()> {
    write_demo(&a.out, a.triangles, a.frames)?;
    if a.with_video {
        write_demo_video(&a)?;
    }
    Ok(())
}

/// `crease demo --with-video`: the ground truth (`gt/`) and its rendered video from a ring of cameras.
fn write_demo_video(a: &DemoArgs) -> Result<()> {
    if a.video_cameras == 0 || a.video_width < 16 || a.video_height < 16 {
        bail!("--video-cameras must be at least 1 and the image at least 16x16 pixels");
    }
    let spec = DemoSpec {
        triangles: a.triangles,
        frames: a.frames,
        ..Default::default()
    };
    let (seq, anchors) = synth::demo(&spec)?;
    let mut sink = crease_core::mesh::MemorySink::default();
    // The synthetic ground truth is the anchors' full effect: the shape screen is part of crease's
    // reconstruction from a capture, not of the cloth, so the truth is made without it.
    let truth = DeformParams {
        shape_cutoff: 0.0,
        // Popa's stretch passes, not crease's fold-keeping default: the truth stays what it was whatever the
        // reconstruction's defaults become.
        stretch_rotation: StretchRotation::Polar,
        // Nor is the fold relief: it reads the captured surface, which the truth is made from.
        relief: crease_core::spacetime::shape::relief::ReliefParams {
            steps: 0,
            ..Default::default()
        },
        // Nor the strain limit, a step of the reconstruction.
        strain_limit: 0.0,
        ..DeformParams::default()
    };
    deform(
        &seq,
        &anchors,
        &truth,
        &mut sink,
        &crease_core::progress::NoProgress,
        &[],
    )?;
    let gt: Vec<Vec<[f64; 3]>> = sink.frames.into_values().collect();
    let gt_dir = a.out.join("gt");
    fsutil::create_dir_all(&gt_dir)?;
    let width = a.frames.to_string().len().max(4);
    write_obj_sequence(
        &gt_dir,
        &seq.topology,
        gt.iter()
            .enumerate()
            .map(|(t, f)| (format!("frame_{:0width$}.obj", t + 1), f.as_slice())),
    )?;
    let rig = crease_core::synth_video::write_video(
        &a.out,
        &seq.topology,
        &gt,
        a.video_cameras,
        a.video_width,
        a.video_height,
        1,
    )?;
    eprintln!(
        "demo video: gt/ and {} cameras x {} frames of {}x{} images -> {}",
        rig.cameras.len(),
        a.frames,
        a.video_width,
        a.video_height,
        a.out.join("images").display()
    );
    Ok(())
}

/// `crease run`: single-node mode. The job goes through an in-process coordinator and workers on 127.0.0.1
/// (see [`crate::local`]), the same path a farm runs, so a laptop run and a cluster run write the same bytes.
pub fn run(a: RunArgs) -> Result<()> {
    let mut params = a.deform.params();
    if a.input.is_none() && a.deform.strain_reference.is_none() {
        // The demo's input is its own rest state in every frame: its stretch is measured against the input
        // frame's triangles, and so is its strain limit.
        params.strain_reference = crease_core::spacetime::position::strain_limit::StrainReference::Frame;
        if a.deform.strain_limit.is_none() {
            params.strain_limit = crease_core::spacetime::position::strain_limit::REST_STATE_STRAIN_LIMIT;
        }
    }
    params.validate()?;
    let folds = a.folds.unwrap_or(Folds::Anchors);
    let stretch = folds == Folds::Stretch;
    let stretch_params = if stretch {
        Some(a.stretch.validated()?)
    } else {
        None
    };
    if folds == Folds::Video {
        if a.input.is_none() {
            bail!("--folds video needs --input (e.g. `crease demo --with-video` writes one)");
        }
        if a.anchors.is_some() {
            bail!("--anchors and --folds video exclude each other: the video detector writes its own anchors");
        }
    }
    let (input, anchors_path, out) = match (&a.input, &a.anchors) {
        (None, _) if stretch => bail!("--folds stretch needs --input (a captured sequence)"),
        (_, Some(_)) if stretch => {
            bail!("--anchors and --folds stretch exclude each other: the stretch detector writes its own anchors")
        }
        (None, _) => {
            let root = a
                .out
                .clone()
                .unwrap_or_else(|| PathBuf::from("crease-demo"));
            let (input, anchors) = write_demo(&root, a.demo_triangles, a.demo_frames)?;
            (input, Some(anchors), root.join("output"))
        }
        (Some(i), None) if folds != Folds::Anchors => (
            i.clone(),
            None,
            a.out.clone().unwrap_or_else(|| PathBuf::from("crease-out")),
        ),
        (Some(_), None) => {
            bail!("--anchors is required with --input unless --folds stretch or --folds video (see docs/formats.md: anchors file)")
        }
        (Some(i), Some(an)) => (
            i.clone(),
            Some(an.clone()),
            a.out.clone().unwrap_or_else(|| PathBuf::from("crease-out")),
        ),
    };
    if a.local_workers == 0 || a.local_capacity == 0 {
        bail!("--local-workers and --local-capacity must be at least 1");
    }
    if a.stretch.subdivide > 0 && !stretch {
        bail!("--subdivide applies to --folds stretch only");
    }
    // Read the header of the input and the anchors here too: the banner needs the sizes, and errors in them
    // read the same as before the cluster existed. Everything else (detector inputs, subdivision) is checked
    // by the job's submit-time inspection, the same for `crease submit`.
    let opened = open_sequence(&input).with_context(|| format!("opening {}", input.display()))?;
    let source: &dyn FrameSource = opened.source.as_ref();
    let topo = source.topology().clone();
    let n = source.n_frames();
    if same_dir(&input, &out) {
        bail!(
            "--out {} is the input directory; choose another so the input is not overwritten",
            out.display()
        );
    }
    for &f in &a.preview_frames {
        if f >= n {
            bail!("--preview-frames: frame {f} is out of range (the sequence has {n} frames, 0-based)");
        }
    }
    let anchors = match &anchors_path {
        Some(p) => Some(AnchorSet::read(p, n, topo.n_triangles())?),
        None => None,
    };
    fsutil::create_dir_all(&out)?;
    // A report from an earlier run must not vouch for what this run may leave half-written.
    let report_path = out.join("report.json");
    match std::fs::remove_file(&report_path) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
        Err(e) => {
            return Err(e).with_context(|| format!("removing stale {}", report_path.display()))
        }
    }
    let progress = CliProgress::new(a.quiet);
    let abs = |p: &Path| {
        std::path::absolute(p)
            .with_context(|| format!("resolving {}", p.display()))
            .map(|p| p.display().to_string())
    };
    let fold_spec = match (folds, &anchors_path, &stretch_params) {
        (_, _, Some(params)) => {
            progress.println(&format!(
                "crease: estimating folds from the geometry (Chen 2011) on {} frames, {} triangles{}",
                n,
                topo.n_triangles() * 4usize.pow(a.stretch.subdivide as u32),
                if a.stretch.subdivide > 0 { " (subdivided)" } else { "" }
            ));
            json!({ "kind": "stretch", "params": params, "subdivide": a.stretch.subdivide })
        }
        (Folds::Video, _, _) => a.video.fold_spec(n, &abs)?,
        (_, Some(p), _) => json!({ "kind": "anchors", "uri": abs(p)? }),
        (_, None, _) => bail!("--anchors is required with --input unless --folds stretch or --folds video (see docs/formats.md: anchors file)"),
    };
    match &anchors {
        Some(set) => progress.println(&format!(
            "crease: {} frames, {} vertices, {} triangles, {} anchors, mode {}",
            n,
            topo.n_vertices(),
            topo.n_triangles(),
            set.total(),
            params.mode
        )),
        None => progress.println(&format!(
            "crease: {} frames, {} vertices, {} triangles, folds detected ({}), mode {}",
            n,
            topo.n_vertices(),
            topo.n_triangles(),
            fold_spec["kind"].as_str().unwrap_or("?"),
            params.mode
        )),
    }
    drop(opened);
    let spec = json!({
        "name": input.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default(),
        "input": abs(&input)?,
        "output": abs(&out)?,
        "folds": fold_spec,
        "deform": params,
        "partition": { "anchor_block": params.anchor_block },
        "preview": { "frames": a.preview_frames, "size": a.preview_size },
    });
    let cache = std::env::temp_dir().join(format!("crease-local-cache-{}", std::process::id()));
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("starting the async runtime")?;
    let status = rt.block_on(async {
        let cluster = LocalCluster::start(a.local_workers, a.local_capacity, cache.clone()).await?;
        let result = async {
            let (id, _) = cluster.client.submit(spec.to_string(), "json").await?;
            crate::cluster::follow(&cluster.client, &id, (!a.quiet).then_some(&progress)).await
        }
        .await;
        cluster.stop().await;
        result
    });
    let _ = std::fs::remove_dir_all(&cache);
    let status = status?;
    if status.state != "done" {
        bail!("{}", status.message);
    }
    let report: serde_json::Value = serde_json::from_slice(
        &std::fs::read(&report_path)
            .with_context(|| format!("reading {}", report_path.display()))?,
    )
    .with_context(|| format!("parsing {}", report_path.display()))?;
    print_fold_detection(&report["fold_detection"], &out, &progress);
    let stretch = &report["report"]["stretch"];
    let pick =
        |i: Option<&serde_json::Value>, k: &str| i.and_then(|v| v[k].as_f64()).unwrap_or(f64::NAN);
    let passes = stretch.as_array().map(Vec::as_slice).unwrap_or(&[]);
    let (first, last) = (passes.first(), passes.last());
    progress.println(&format!(
        "stretch after positioning: L2 {:.6}, max {:.2}% | after {} pass(es): L2 {:.6}, max {:.2}%, p99 {:.2}%",
        pick(first, "l2"),
        pick(first, "max") * 100.0,
        params.stretch_passes,
        pick(last, "l2"),
        pick(last, "max") * 100.0,
        pick(last, "p99") * 100.0
    ));
    let vs_rest = &report["summary"]["stretch_vs_rest"]["final"];
    progress.println(&format!(
        "edge tension against the least-compressed input edge lengths: p99 {:.2}%, max {:.2}%, mean {:.3}%",
        pick(Some(vs_rest), "p99") * 100.0,
        pick(Some(vs_rest), "max") * 100.0,
        pick(Some(vs_rest), "mean") * 100.0
    ));
    progress.println(&format!(
        "wrote {} frames, report.json, preview.png, stretch.png to {} ({} tasks, {:.2}s of work)",
        n,
        out.display(),
        status.tasks_total,
        status.work_seconds
    ));
    Ok(())
}

/// The lines the direct detection path printed, from the job's report (`fold_detection`).
fn print_fold_detection(d: &serde_json::Value, out: &Path, progress: &CliProgress) {
    match d["source"].as_str() {
        Some("video") => {
            let tv = &d["tracked_vertices"];
            progress.println(&format!(
                "video folds: {} cameras, tracked vertices front {} back {}{}",
                d["cameras"],
                tv["front"],
                tv["back"],
                if tv["automatic"] == true {
                    " (automatic)"
                } else {
                    ""
                }
            ));
        }
        Some(_) => {}
        None => return,
    }
    progress.println(&format!(
        "{} folds: {} anchors -> {}",
        d["source"].as_str().unwrap_or("?"),
        d["anchors"],
        out.join("anchors.json").display()
    ));
}

fn same_dir(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    }
}

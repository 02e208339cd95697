//! `crease run` and `crease demo`.
//!
//! `crease run` takes what changes from shot to shot as flags (input, output, the fold source and its files,
//! the weight mode, the strain limit) and everything else as tuning keys (`--set key=value`, the registry in
//! [`crease_jobs::tuning`]). It builds the job ([`crate::run_spec`]), runs it through the single-node cluster
//! and prints the figures of its report ([`crease_jobs::report::JobReport`]).

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
use crease_core::spacetime::{deform, DeformParams, WeightMode};
use crease_core::synth::{self, DemoSpec};
use crease_jobs::report::{FoldDetection, JobReport};
use std::path::{Path, PathBuf};

const IO: &str = "Input and output";
const FOLDS: &str = "Folds";
const SOLVE: &str = "Deformation";
const DEMO: &str = "Built-in demo (without --input)";
const LOCAL: &str = "Single-node cluster";

/// Where the folds come from.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Folds {
    /// An anchors file (--anchors).
    Anchors,
    /// The geometry alone (Chen 2011 ch. 4); --subdivide, `stretch.*` tuning keys.
    Stretch,
    /// The capture video (Popa et al. 2009 §4): --cameras, --images; `video.*` tuning keys.
    Video,
}

#[derive(Args, Debug)]
#[command(
    after_help = "Every other setting is a tuning key, set with --set KEY=VALUE (repeatable) or in a job \
spec's [tuning] table: `crease tuning` lists them with their defaults, ranges and meanings (docs/tuning.md)."
)]
pub struct RunArgs {
    /// Input sequence: a directory of numbered OBJ or PLY frames, or OBJ + PC2. Omit to run the built-in demo.
    #[arg(long, help_heading = IO)]
    pub input: Option<PathBuf>,
    /// Output directory (the wrinkled sequence, report.json, preview.png, stretch.png).
    #[arg(long, help_heading = IO)]
    pub out: Option<PathBuf>,
    /// Frames to show in preview.png (default: four spread over the sequence).
    #[arg(long, value_delimiter = ',', help_heading = IO)]
    pub preview_frames: Vec<usize>,
    /// Preview tile size in pixels.
    #[arg(long, default_value_t = 384, help_heading = IO)]
    pub preview_size: u32,
    /// No progress bars or log lines.
    #[arg(long, help_heading = IO)]
    pub quiet: bool,
    /// Where the folds come from: `anchors` (the --anchors file; the default), `stretch` (estimated from the
    /// geometry alone, Chen 2011 ch. 4) or `video` (from the capture video, Popa et al. 2009 §4). Detectors
    /// write anchors.json and their overlays to --out.
    #[arg(long, value_enum, help_heading = FOLDS)]
    pub folds: Option<Folds>,
    /// Anchors file (JSON, see docs/formats.md). Required with --input unless --folds detects them.
    #[arg(long, help_heading = FOLDS)]
    pub anchors: Option<PathBuf>,
    /// --folds video: the camera calibration (JSON, OpenCV convention; see docs/folds.md).
    #[arg(long, help_heading = FOLDS)]
    pub cameras: Option<PathBuf>,
    /// --folds video: directory holding `<camera>/frame_NNNN.png` (default: the cameras file's
    /// `image_pattern`, relative to it).
    #[arg(long, help_heading = FOLDS)]
    pub images: Option<PathBuf>,
    /// --folds stretch: levels of midpoint subdivision before detection (0 to 4); the output is then on the
    /// subdivided mesh, original vertices first.
    #[arg(long, default_value_t = 0, help_heading = FOLDS)]
    pub subdivide: u32,
    /// Detail scale, in the input's length unit (0.03 = 3 cm on a mesh in metres): the fold width a capture is
    /// taken to blur; the fold relief undoes a generic low-pass at it, and the shape is held at twice it
    /// [default: five mean edge lengths of the first frame].
    #[arg(long, value_name = "LENGTH", help_heading = FOLDS)]
    pub detail_scale: Option<f64>,
    /// Weight solve: `fused` (3 right-hand sides per window) or `per-anchor` (one CG column per anchor, in
    /// blocks) [default: fused].
    #[arg(long, help_heading = SOLVE)]
    pub mode: Option<WeightMode>,
    /// Strain limit: the positioning's last step shortens every edge longer than (1 + this) times its
    /// reference length (a fraction, 0.05 = 5%; `off` or 0 turns it off) [default: 0.05; the built-in demo,
    /// whose input is its own rest state, 0.02].
    #[arg(long, value_parser = parse_strain_limit, help_heading = SOLVE)]
    pub strain_limit: Option<f64>,
    /// A tuning key, KEY=VALUE (repeatable; lists as `1,1.5,2.5`): `crease tuning` lists every key with its
    /// default, range and meaning.
    #[arg(long = "set", value_name = "KEY=VALUE", help_heading = SOLVE)]
    pub set: Vec<String>,
    /// Demo size in triangles.
    #[arg(long, default_value_t = 40_000, help_heading = DEMO)]
    pub demo_triangles: usize,
    /// Demo length in frames.
    #[arg(long, default_value_t = 36, help_heading = DEMO)]
    pub demo_frames: usize,
    /// Workers of the single-node cluster (each a gRPC server on 127.0.0.1).
    #[arg(long, default_value_t = 1, help_heading = LOCAL)]
    pub local_workers: usize,
    /// Tasks each local worker runs at the same time.
    #[arg(long, default_value_t = 2, help_heading = LOCAL)]
    pub local_capacity: u32,
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
    let folds = a.folds.unwrap_or(Folds::Anchors);
    crate::run_spec::check_flags(&a, folds)?;
    let (input, anchors_path, out) = match (&a.input, &a.anchors) {
        (Some(i), an) => (
            i.clone(),
            an.clone(),
            a.out.clone().unwrap_or_else(|| PathBuf::from("crease-out")),
        ),
        (None, _) => {
            let root = a
                .out
                .clone()
                .unwrap_or_else(|| PathBuf::from("crease-demo"));
            let (input, anchors) = write_demo(&root, a.demo_triangles, a.demo_frames)?;
            (input, Some(anchors), root.join("output"))
        }
    };
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
    let anchors = match &anchors_path {
        Some(p) => Some(AnchorSet::read(p, n, topo.n_triangles())?),
        None => None,
    };
    let spec = crate::run_spec::job_spec(&a, folds, &input, anchors_path.as_deref(), &out, n)?;
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
    let mode = spec.deform.mode;
    match (&anchors, folds) {
        (Some(set), _) => progress.println(&format!(
            "crease: {} frames, {} vertices, {} triangles, {} anchors, mode {mode}",
            n,
            topo.n_vertices(),
            topo.n_triangles(),
            set.total(),
        )),
        (None, detected) => {
            if detected == Folds::Stretch {
                progress.println(&format!(
                    "crease: estimating folds from the geometry (Chen 2011) on {} frames, {} triangles{}",
                    n,
                    topo.n_triangles() * 4usize.pow(a.subdivide),
                    if a.subdivide > 0 { " (subdivided)" } else { "" }
                ));
            }
            progress.println(&format!(
                "crease: {} frames, {} vertices, {} triangles, folds detected ({}), mode {mode}",
                n,
                topo.n_vertices(),
                topo.n_triangles(),
                spec.folds.kind(),
            ))
        }
    }
    drop(opened);
    let spec_json = serde_json::to_string(&spec).context("writing the job spec")?;
    let cache = std::env::temp_dir().join(format!("crease-local-cache-{}", std::process::id()));
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("starting the async runtime")?;
    let status = rt.block_on(async {
        let cluster = LocalCluster::start(a.local_workers, a.local_capacity, cache.clone()).await?;
        let result = async {
            let (id, _) = cluster.client.submit(spec_json, "json").await?;
            crate::watch::follow(&cluster.client, &id, (!a.quiet).then_some(&progress)).await
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
    let text = std::fs::read(&report_path)
        .with_context(|| format!("reading {}", report_path.display()))?;
    let report = JobReport::from_text(&text, &report_path.display().to_string())
        .map_err(anyhow::Error::msg)?;
    if let Some(d) = &report.fold_detection {
        print_fold_detection(d, &out, &progress);
    }
    let passes = &report.report.stretch;
    let nan = crease_core::metrics::StretchStats {
        l2: f64::NAN,
        max: f64::NAN,
        p99: f64::NAN,
        mean: f64::NAN,
    };
    let (first, last) = (
        passes.first().unwrap_or(&nan),
        passes.last().unwrap_or(&nan),
    );
    progress.println(&format!(
        "stretch after positioning: L2 {:.6}, max {:.2}% | after {} pass(es): L2 {:.6}, max {:.2}%, p99 {:.2}%",
        first.l2,
        first.max * 100.0,
        report.parameters.stretch_passes,
        last.l2,
        last.max * 100.0,
        last.p99 * 100.0
    ));
    let vs_rest = &report.summary.stretch_vs_rest.output;
    progress.println(&format!(
        "edge tension against the least-compressed input edge lengths: p99 {:.2}%, max {:.2}%, mean {:.3}%",
        vs_rest.p99 * 100.0,
        vs_rest.max * 100.0,
        vs_rest.mean * 100.0
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

/// The lines the direct detection path printed, from the job's report.
fn print_fold_detection(d: &FoldDetection, out: &Path, progress: &CliProgress) {
    if let (Some(cameras), Some(tv)) = (d.cameras, d.tracked_vertices) {
        progress.println(&format!(
            "video folds: {cameras} cameras, tracked vertices front {} back {}{}",
            tv.front,
            tv.back,
            if tv.automatic { " (automatic)" } else { "" }
        ));
    }
    progress.println(&format!(
        "{} folds: {} anchors -> {}",
        d.source,
        d.anchors,
        out.join("anchors.json").display()
    ));
}

fn same_dir(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    }
}

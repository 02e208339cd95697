//! `crease run` and `crease demo`.

use crate::folds_stretch::{self, ObjFramesSink, StretchArgs};
use crate::progress::CliProgress;
use anyhow::{bail, Context, Result};
use clap::Args;
use crease_core::folds::AnchorSet;
use crease_core::mesh::io::{create_sink, open_sequence, write_obj_sequence};
use crease_core::mesh::subdivide::SubdividedSource;
use crease_core::mesh::FrameSource;
use crease_core::spacetime::{deform, Coefficients, DeformParams, Pinning, WeightMode};
use crease_core::synth::{self, DemoSpec};
use crease_core::{fsutil, preview, render};
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
    /// Stretch-reduction passes.
    #[arg(long, default_value_t = 2)]
    pub stretch_passes: usize,
    /// `centroid`: keep each component's mean position; `vertex`: keep its lowest-index vertex fixed.
    #[arg(long, default_value = "centroid", value_parser = parse_pinning)]
    pub pinning: Pinning,
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
            pinning: self.pinning,
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
    /// Anchors file (JSON, see README). Required with --input unless --folds detects them.
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
    /// Demo size when no --input is given.
    #[arg(long, default_value_t = 40_000)]
    pub demo_triangles: usize,
    #[arg(long, default_value_t = 36)]
    pub demo_frames: usize,
    /// No progress bars or log lines.
    #[arg(long)]
    pub quiet: bool,
}

#[derive(Args, Debug)]
pub struct DemoArgs {
    /// Directory to write `input/` (numbered OBJ frames) and `anchors.json` into.
    #[arg(long)]
    pub out: PathBuf,
    #[arg(long, default_value_t = 40_000)]
    pub triangles: usize,
    #[arg(long, default_value_t = 36)]
    pub frames: usize,
    /// Also write a synthetic capture video: the ground-truth folded sequence (`gt/`, the input deformed with
    /// its anchors) rendered from a ring of calibrated cameras (`cameras.json`, `images/<camera>/frame_NNNN.png`).
    #[arg(long)]
    pub with_video: bool,
    /// Cameras on the ring (with --with-video).
    #[arg(long, default_value_t = 4)]
    pub video_cameras: usize,
    /// Image size (with --with-video).
    #[arg(long, default_value_t = 480)]
    pub video_width: u32,
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
    let input = out.join("input");
    fsutil::create_dir_all(&input)?;
    let width = frames.to_string().len().max(4);
    write_obj_sequence(
        &input,
        &seq.topology,
        seq.frames
            .iter()
            .enumerate()
            .map(|(t, f)| (format!("frame_{:0width$}.obj", t + 1), f.as_slice())),
    )?;
    let anchors_path = out.join("anchors.json");
    anchors.write(&anchors_path)?;
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
    deform(
        &seq,
        &anchors,
        &DeformParams::default(),
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

pub fn run(a: RunArgs) -> Result<()> {
    let params = a.deform.params();
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
            bail!("--anchors is required with --input unless --folds stretch or --folds video (see README: anchors file format)")
        }
        (Some(i), Some(an)) => (
            i.clone(),
            Some(an.clone()),
            a.out.clone().unwrap_or_else(|| PathBuf::from("crease-out")),
        ),
    };
    let opened = open_sequence(&input).with_context(|| format!("opening {}", input.display()))?;
    let subdivided = match a.stretch.subdivide {
        0 => None,
        levels if stretch => Some(SubdividedSource::new(opened.source.as_ref(), levels)?),
        _ => bail!("--subdivide applies to --folds stretch only"),
    };
    let source: &dyn FrameSource = match &subdivided {
        Some(s) => s,
        None => opened.source.as_ref(),
    };
    let topo = source.topology().clone();
    let n = source.n_frames();
    if same_dir(&input, &out) {
        bail!(
            "--out {} is the input directory; choose another so the input is not overwritten",
            out.display()
        );
    }
    let keep: Vec<usize> = if a.preview_frames.is_empty() {
        let mut k: Vec<usize> = (1..=4).map(|i| (i * n / 5).min(n - 1)).collect();
        k.dedup();
        k
    } else {
        for &f in &a.preview_frames {
            if f >= n {
                bail!("--preview-frames: frame {f} is out of range (the sequence has {n} frames, 0-based)");
            }
        }
        a.preview_frames.clone()
    };
    let anchors_in = match &anchors_path {
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
    let mut sink: Box<dyn crease_core::mesh::FrameSink> = if subdivided.is_some() {
        // The subdivided frames keep the input's file names: never next to the input files.
        for f in opened.layout.input_files() {
            if f.parent().is_some_and(|d| same_dir(d, &out)) {
                bail!(
                    "--out {} holds the input sequence; choose another directory",
                    out.display()
                );
            }
        }
        Box::new(ObjFramesSink::new(
            &out,
            &opened.layout.input_files(),
            n,
            topo.clone(),
        )?)
    } else {
        create_sink(&opened.layout, &out)?
    };
    let progress = CliProgress::new(a.quiet);
    let (anchors, anchors_path, fold_detection) = match (anchors_in, anchors_path) {
        (Some(set), Some(path)) => (set, path, serde_json::Value::Null),
        _ if folds == Folds::Video => {
            let set =
                crate::folds_video::detect(&a.video, source, &opened.layout, &out, &progress)?;
            (set, out.join("anchors.json"), json!({ "method": "video" }))
        }
        _ => {
            let params = stretch_params.clone().expect("stretch mode");
            progress.println(&format!(
                "crease: estimating folds from the geometry (Chen 2011) on {} frames, {} triangles",
                n,
                topo.n_triangles()
            ));
            let (set, path, summary) =
                folds_stretch::detect(source, params, &out, &keep, a.preview_size, &progress)?;
            progress.println(&format!(
                "stretch folds: {} folds, {} anchors -> {}",
                summary["folds"],
                set.total(),
                path.display()
            ));
            (set, path, summary)
        }
    };
    progress.println(&format!(
        "crease: {} frames, {} vertices, {} triangles, {} anchors, mode {}",
        n,
        topo.n_vertices(),
        topo.n_triangles(),
        anchors.total(),
        params.mode
    ));
    let (report, kept) = deform(source, &anchors, &params, sink.as_mut(), &progress, &keep)?;
    let files = sink.finish()?;

    let t_preview = std::time::Instant::now();
    let preview_path = out.join("preview.png");
    let focus = kept.frames.first().and_then(|(_, rest, _)| {
        let anchored = kept
            .frames
            .iter()
            .flat_map(|(t, _, _)| anchors.frame(*t).iter().map(|a| a.triangle));
        preview::fold_focus(&topo, rest, anchored)
    });
    let img = preview::before_after(&topo, &kept.frames, a.preview_size, 0.10, focus);
    render::save_png(&img, &preview_path)?;
    let plot_path = out.join("stretch.png");
    render::save_png(
        &preview::stretch_plot(&report.frame_stretch, 900, 420),
        &plot_path,
    )?;
    let preview_seconds = t_preview.elapsed().as_secs_f64();

    let last = report.stretch.last().copied().unwrap_or_default();
    let first = report.stretch.first().copied().unwrap_or_default();
    let per_frame = |s: f64| s / n as f64;
    let t = &report.timings;
    let doc = json!({
        "complete": true,
        "crease_version": env!("CARGO_PKG_VERSION"),
        "input": input,
        "input_layout": opened.layout.kind(),
        "anchors_file": anchors_path,
        "fold_detection": fold_detection,
        "output_files": files,
        "preview": [preview_path, plot_path],
        "parameters": params,
        "summary": {
            "frames": n,
            "vertices": topo.n_vertices(),
            "triangles": topo.n_triangles(),
            "anchors": anchors.total(),
            "stretch_after_positioning": first,
            "stretch_final": last,
            "seconds_per_frame": {
                "weights": per_frame(t.weights),
                "blend": per_frame(t.blend),
                "factor": per_frame(t.factor),
                "position": per_frame(t.position),
                "stretch_passes": t.stretch_passes.iter().map(|s| per_frame(*s)).collect::<Vec<_>>(),
                "wall": per_frame(t.wall),
            },
            "preview_seconds": preview_seconds,
        },
        "report": report,
    });
    let text = serde_json::to_string_pretty(&doc)?;
    fsutil::write_atomic(&report_path, text.as_bytes())?;
    progress.println(&format!(
        "stretch after positioning: L2 {:.6}, max {:.2}% | after {} pass(es): L2 {:.6}, max {:.2}%, p99 {:.2}%",
        first.l2,
        first.max * 100.0,
        params.stretch_passes,
        last.l2,
        last.max * 100.0,
        last.p99 * 100.0
    ));
    progress.println(&format!(
        "wrote {} frames, report.json, preview.png, stretch.png to {} ({:.2}s/frame wall)",
        n,
        out.display(),
        per_frame(t.wall)
    ));
    Ok(())
}

fn same_dir(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    }
}

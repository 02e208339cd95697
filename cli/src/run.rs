//! `crease run` and `crease demo`.
//!
//! `crease run` takes what changes from shot to shot as flags (input, output, the fold source and its files,
//! the weight mode, the strain limit) and everything else as tuning keys (`--set key=value`, the registry in
//! [`crease_jobs::tuning`]). It builds the job ([`crate::run_spec`]), runs it through the single-node cluster
//! and prints the figures of its report ([`crease_jobs::report::JobReport`]).

use crate::local::LocalCluster;
use crate::progress::CliProgress;
pub use crate::run_args::{Folds, RunArgs};
use anyhow::{bail, Context, Result};
use clap::Args;
use crease_coordinator::JobClient;
use crease_core::folds::AnchorSet;
use crease_core::fsutil;
use crease_core::mesh::io::{open_sequence, write_obj_sequence};
use crease_core::mesh::FrameSource;
use crease_core::spacetime::position::stretch::StretchRotation;
use crease_core::spacetime::{deform, DeformParams};
use crease_core::synth::{self, DemoSpec};
use crease_jobs::report::{FoldDetection, JobReport};
use std::path::{Path, PathBuf};

/// Below this median share of its lost surface given back by the relief, a capture erased its folds rather than
/// blurred them: every smoothed capture measured keeps over a quarter, an erased fold about a hundredth.
const ERASED_TRACE: f64 = 0.1;

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
        // Nor the strain limit or the lost-area bound, steps of the reconstruction.
        strain_limit: 0.0,
        lost_area_bound: false,
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
    if let Some(l) = &report.summary.scales {
        // The one length crease cannot know of the capture: say which it used and where it came from.
        progress.println(&format!(
            "detail scale: {:.4} input units, {:.1} mean edge lengths of the first frame ({})",
            l.detail,
            l.detail / l.mean_edge,
            if l.detail_given {
                "given"
            } else {
                "taken from the mesh; give --detail-scale when the mesh is much finer than the detail the \
                 capture resolves"
            }
        ));
    }
    if let Some(j) = &report.summary.lost_area {
        // A capture that kept its folds gives most frames back: say so, or the unchanged output looks like a fault.
        progress.println(&format!(
            "lost-area bound: {} frame(s) kept whole, {} scaled, {} given back as captured (median lost share {:.2})",
            j.frames_kept, j.frames_scaled, j.frames_given_back, j.median_share
        ));
        if let Some(r) = j.median_relief_share {
            progress.println(&format!(
                "capture trace: the fold relief gives back a median {:.0}% of the surface the capture lost",
                r * 100.0
            ));
            if r < ERASED_TRACE {
                progress.println(match folds {
                    Folds::Video => {
                        "  the capture kept almost no trace of its folds (erased, not blurred): the shading \
                         refinement followed the images further there (`video.refine_erased_stay`), and the \
                         geometry's folds were left out (`video.geometry_min_trace`)"
                    }
                    _ => {
                        "  the capture kept almost no trace of its folds (erased, not blurred): from the geometry \
                         alone their places are only roughly known; with the capture's calibrated images \
                         (`--folds video`) the shading refinement brings them back (docs/fidelity.md)"
                    }
                });
            }
        }
    }
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

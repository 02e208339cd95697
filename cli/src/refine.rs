//! `crease refine`: shading-based refinement of a sequence from its calibrated images, as a step of its own
//! after `crease run` (or on a capture directly). Each frame is independent, so a farm can run ranges of it.

use crate::progress::CliProgress;
use anyhow::{bail, Context, Result};
use clap::Args;
use crease_core::folds::video::cameras::CameraRig;
use crease_core::mesh::io::{create_sink, open_sequence};
use crease_core::mesh::seams::Seams;
use crease_core::progress::Progress;
use crease_core::shading_refine::{refine_frame, RefineView, ShadingRefineParams};
use rayon::prelude::*;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct RefineArgs {
    /// The sequence to refine (any layout `crease run` reads; e.g. a `crease run` output folder).
    #[arg(long)]
    pub input: PathBuf,
    /// Camera calibration (the JSON `crease run --cameras` reads).
    #[arg(long)]
    pub cameras: PathBuf,
    /// Folder the cameras' image pattern is relative to.
    #[arg(long)]
    pub images: Option<PathBuf>,
    /// Image number of the first frame (default: each frame file's own number, 1 onwards for a point cache).
    #[arg(long)]
    pub first_image_number: Option<u64>,
    /// Where to write the refined sequence (same layout as the input).
    #[arg(long)]
    pub out: PathBuf,
    /// Gauss–Newton rounds; 0 copies the input.
    #[arg(long, default_value_t = ShadingRefineParams::default().rounds)]
    pub rounds: usize,
    /// Weight of the offsets' squared Laplacian (offsets in mean edge lengths, residuals in the images' grain).
    #[arg(long, default_value_t = ShadingRefineParams::default().smoothness)]
    pub smoothness: f64,
    /// Weight of staying at the input shape (same units).
    #[arg(long, default_value_t = ShadingRefineParams::default().stay)]
    pub stay: f64,
    /// Largest offset along the normal, in mean edge lengths.
    #[arg(long, default_value_t = ShadingRefineParams::default().max_offset_edges)]
    pub max_offset: f64,
    /// Wavelength (in the sequence's units) below which the refinement's offsets are kept; longer ones move the
    /// garment and are removed. 0: the deformation's default shape scale (ten mean edge lengths).
    #[arg(long, default_value_t = 0.0)]
    pub shape_scale: f64,
    /// No progress bars or log lines.
    #[arg(long)]
    pub quiet: bool,
}

pub fn refine(a: RefineArgs) -> Result<()> {
    let params = ShadingRefineParams {
        rounds: a.rounds,
        smoothness: a.smoothness,
        stay: a.stay,
        max_offset_edges: a.max_offset,
        shape_scale: a.shape_scale,
        ..ShadingRefineParams::default()
    };
    params.validate()?;
    let opened =
        open_sequence(&a.input).with_context(|| format!("--input {}", a.input.display()))?;
    let rig = CameraRig::read(&a.cameras, a.images.as_deref())
        .with_context(|| format!("--cameras {}", a.cameras.display()))?;
    let src = &opened.source;
    let n = src.n_frames();
    let numbers = crease_jobs::plan::detect::image_numbers(&opened.layout, n, a.first_image_number);
    let frames: Vec<(usize, u64)> = numbers.iter().copied().enumerate().collect();
    rig.check_images(&frames)?;
    let topo = src.topology().clone();
    let progress = CliProgress::new(a.quiet);
    progress.begin("refine", n as u64);
    let results: Vec<crease_core::Result<_>> = (0..n)
        .into_par_iter()
        .map(|t| {
            let positions = src.read_frame(t)?;
            let photos = (0..rig.cameras.len())
                .map(|c| rig.load(c, t, numbers[t]))
                .collect::<crease_core::Result<Vec<_>>>()?;
            let views = rig
                .cameras
                .iter()
                .zip(&photos)
                .map(|(c, p)| RefineView {
                    camera: &c.camera,
                    photo: p,
                })
                .collect();
            let mut r = refine_frame(&topo, &positions, views, &params)?;
            // The input's unwelded seams stay closed, as in `crease run`.
            Seams::of_frame(&topo, &positions).close(&mut r.positions);
            progress.advance("refine", 1);
            Ok(r)
        })
        .collect();
    progress.end("refine");
    let mut sink = create_sink(&opened.layout, &a.out)?;
    let (mut before, mut after, mut moved) = (0.0, 0.0, 0.0);
    for (t, r) in results.into_iter().enumerate() {
        let r = r.with_context(|| format!("frame {t} ({})", src.describe_frame(t)))?;
        before += r.residual_first;
        after += r.residual_last;
        moved += r.offsets.iter().map(|o| o.abs()).sum::<f64>() / r.offsets.len().max(1) as f64;
        sink.write_frame(t, &r.positions)?;
    }
    sink.finish()?;
    if n == 0 {
        bail!("--input {} has no frames", a.input.display());
    }
    let k = n as f64;
    println!(
        "refined {n} frames: shading residual {:.2} → {:.2} grey levels (linear; first and last round, mean over frames), mean |offset| {:.3e} (the input's units)",
        before / k,
        after / k,
        moved / k
    );
    Ok(())
}

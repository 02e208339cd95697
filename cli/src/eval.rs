//! `crease eval`: fold fidelity of a result against ground truth (docs/fidelity.md), with the captured baseline
//! beside every figure, so a claim about folds can be reproduced with one command.

use crate::progress::CliProgress;
use anyhow::{bail, Context, Result};
use clap::Args;
use crease_core::eval::{evaluate, signal_picture, EvalParams, EvalReport};
use crease_core::mesh::io::open_sequence;
use crease_core::render::save_png;
use crease_core::{fsutil, mesh::FrameSource};
use std::path::{Path, PathBuf};

#[derive(Args, Debug)]
pub struct EvalArgs {
    /// The result to judge (any layout `crease run` reads; a subdivided result keeps the input's vertices first).
    #[arg(long)]
    pub output: PathBuf,
    /// Ground truth with folds, same connectivity and frames as the input.
    #[arg(long)]
    pub gt: PathBuf,
    /// The captured input the result was made from.
    #[arg(long)]
    pub input: PathBuf,
    /// Fold-region threshold on the fold signal, in degrees.
    #[arg(long, default_value_t = 10.0, allow_hyphen_values = true)]
    pub threshold: f64,
    /// Where to write the figures as JSON (default: OUTPUT/eval.json).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Where to write the fold-signal picture (default: OUTPUT/eval.png).
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// Frames to picture (default: three spread over the sequence).
    #[arg(long, value_delimiter = ',')]
    pub frames: Vec<usize>,
    /// Picture tile size in pixels.
    #[arg(long, default_value_t = 320)]
    pub size: u32,
    /// No progress bars or log lines.
    #[arg(long)]
    pub quiet: bool,
}

fn open(path: &Path, what: &str) -> Result<Box<dyn FrameSource>> {
    Ok(open_sequence(path)
        .with_context(|| format!("--{what} {}", path.display()))?
        .source)
}

fn fmt(x: Option<f64>, digits: usize) -> String {
    x.map_or_else(|| "undefined".to_string(), |v| format!("{v:.digits$}"))
}

fn table(r: &EvalReport) -> String {
    let (o, b) = (&r.output, &r.captured_baseline);
    let rows = [
        (
            "fold-signal correlation",
            fmt(o.correlation, 3),
            fmt(b.correlation, 3),
        ),
        ("fold-region kappa", fmt(o.kappa, 3), fmt(b.kappa, 3)),
        (
            "normal error vs GT (deg)",
            format!("{:.2}", o.normal_error_deg),
            format!("{:.2}", b.normal_error_deg),
        ),
        (
            "fold-region IoU, dilated",
            fmt(o.iou_dilated, 3),
            fmt(b.iou_dilated, 3),
        ),
        (
            "temporal popping (GT = 1)",
            fmt(o.popping, 2),
            fmt(b.popping, 2),
        ),
        (
            "fold-region fraction",
            format!("{:.3}", o.fold_fraction),
            format!("{:.3}", b.fold_fraction),
        ),
    ];
    let mut s = format!(
        "{} frames x {} vertices; fold region: signal > {}°; ground truth fold fraction {:.3}\n",
        r.frames, r.vertices, r.threshold_deg, r.gt_fold_fraction
    );
    s += &format!(
        "{:<28} {:>10} {:>18}\n",
        "metric", "output", "captured baseline"
    );
    for (name, a, c) in rows {
        s += &format!("{name:<28} {a:>10} {c:>18}\n");
    }
    let (so, sg) = (&r.shape.output, &r.shape.ground_truth);
    s += &format!(
        "shape kept (mean edge lengths; extent: % of the largest)\n{:<28} {:>10} {:>18}\n",
        "metric", "output", "ground truth"
    );
    let shape_rows = [
        (
            "displacement mean",
            so.displacement_mean,
            sg.displacement_mean,
        ),
        ("displacement p99", so.displacement_p99, sg.displacement_p99),
        ("displacement max", so.displacement_max, sg.displacement_max),
        ("drift mean", so.drift_mean, sg.drift_mean),
        ("drift max", so.drift_max, sg.drift_max),
        (
            "extent change (%)",
            100.0 * so.extent_change,
            100.0 * sg.extent_change,
        ),
    ];
    for (name, a, c) in shape_rows {
        s += &format!("{name:<28} {a:>10.3} {c:>18.3}\n");
    }
    let st = &r.stretch;
    let (ro, rg) = (&st.vs_rest.output, &st.vs_rest.ground_truth);
    s += &format!(
        "stretch (%; vs rest: {})\n{:<28} {:>10} {:>18}\n",
        st.rest_reference, "metric", "output", "ground truth"
    );
    let pct = |x: Option<f64>| fmt(x.map(|v| 100.0 * v), 2);
    let (fo, fg) = (
        st.vs_captured_frame.output,
        st.vs_captured_frame.ground_truth,
    );
    let stretch_rows = [
        ("vs rest p99", Some(ro.p99), Some(rg.p99)),
        ("vs rest max", Some(ro.max), Some(rg.max)),
        ("vs rest mean", Some(ro.mean), Some(rg.mean)),
        (
            "vs captured frame p99",
            fo.map(|f| f.p99),
            fg.map(|f| f.p99),
        ),
        (
            "vs captured frame max",
            fo.map(|f| f.max),
            fg.map(|f| f.max),
        ),
    ];
    for (name, a, c) in stretch_rows {
        // The per-triangle accumulator's histogram ends at 100%: a p99 beyond it is only known to be beyond.
        let cap = |x: Option<f64>| match x {
            Some(v) if name.ends_with("p99") && name.contains("frame") && v > 1.0 => {
                "> 100".to_string()
            }
            _ => pct(x),
        };
        s += &format!("{name:<28} {:>10} {:>18}\n", cap(a), cap(c));
    }
    s
}

pub fn eval(a: EvalArgs) -> Result<()> {
    let params = EvalParams {
        threshold_deg: a.threshold,
    };
    params.validate()?;
    let input = open(&a.input, "input")?;
    let gt = open(&a.gt, "gt")?;
    let output = open(&a.output, "output")?;
    let n = input.n_frames();
    let keep: Vec<usize> = if a.frames.is_empty() {
        let mut k: Vec<usize> = (1..=3)
            .map(|i| (i * n / 4).min(n.saturating_sub(1)))
            .collect();
        k.dedup();
        k
    } else {
        if let Some(f) = a.frames.iter().find(|&&f| f >= n) {
            bail!("--frames: frame {f} is out of range (the sequence has {n} frames, 0-based)");
        }
        a.frames.clone()
    };
    let progress = CliProgress::new(a.quiet);
    let (report, kept) = evaluate(&*output, &*gt, &*input, &params, &keep, &progress)?;
    print!("{}", table(&report));
    // A PC2 output is named by its file; its pictures go beside it.
    let out_dir = if a.output.is_dir() {
        a.output.clone()
    } else {
        a.output.parent().map(PathBuf::from).unwrap_or_default()
    };
    let json_path = a.json.unwrap_or_else(|| out_dir.join("eval.json"));
    let text = serde_json::to_string_pretty(&report)?;
    fsutil::write_atomic(&json_path, text.as_bytes())?;
    let png_path = a.png.unwrap_or_else(|| out_dir.join("eval.png"));
    let img = signal_picture(input.topology(), &kept, a.size, 3.0 * a.threshold);
    save_png(&img, &png_path)?;
    progress.println(&format!(
        "wrote {} and {}",
        json_path.display(),
        png_path.display()
    ));
    Ok(())
}

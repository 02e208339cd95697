//! `crease export`: a sequence (typically a crease output directory) as GLB, USD, MDD or PC2. See
//! docs/export.md.

use crate::progress::CliProgress;
use anyhow::{Context, Result};
use clap::Args;
use crease_core::export::{export, ExportFormat, ExportOptions, UpAxis};
use crease_core::mesh::io::open_sequence;
use std::path::{Path, PathBuf};

#[derive(Args, Debug)]
pub struct ExportArgs {
    /// The sequence: a crease output directory, numbered OBJ/PLY frames, or OBJ + PC2.
    #[arg(long)]
    input: PathBuf,
    /// glb, usd, mdd or pc2.
    #[arg(long)]
    format: String,
    /// Output file (default: `export/<name>.<ext>` inside the input directory).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Frames per second.
    #[arg(long, default_value_t = 30.0)]
    fps: f64,
    /// Frame number of the first frame (USD time code, PC2 start frame).
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
    first_frame: f64,
    /// The data's up axis: z (crease's sample data) or y.
    #[arg(long, default_value = "z", value_parser = parse_up)]
    up_axis: UpAxis,
    /// No progress lines.
    #[arg(long)]
    quiet: bool,
}

fn parse_up(s: &str) -> Result<UpAxis, String> {
    match s.to_ascii_lowercase().as_str() {
        "y" => Ok(UpAxis::Y),
        "z" => Ok(UpAxis::Z),
        _ => Err(format!("`{s}` is not one of: y, z")),
    }
}

pub fn export_cmd(a: ExportArgs) -> Result<()> {
    let format: ExportFormat = a.format.parse()?;
    let opened = open_sequence(&a.input)
        .with_context(|| format!("opening the sequence {}", a.input.display()))?;
    let out = match a.out {
        Some(o) => o,
        None => {
            let dir = if a.input.is_dir() {
                a.input.clone()
            } else {
                a.input.parent().unwrap_or(Path::new(".")).to_path_buf()
            };
            let stem = std::path::absolute(&a.input)
                .ok()
                .and_then(|p| {
                    if p.is_dir() {
                        p.file_name().map(|n| n.to_string_lossy().into_owned())
                    } else {
                        p.file_stem().map(|n| n.to_string_lossy().into_owned())
                    }
                })
                .unwrap_or_else(|| "crease".into());
            dir.join("export")
                .join(format!("{stem}.{}", format.extension()))
        }
    };
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        crease_core::fsutil::create_dir_all(parent)?;
    }
    let opts = ExportOptions {
        fps: a.fps,
        first_frame: a.first_frame,
        up_axis: a.up_axis,
    };
    let progress = CliProgress::new(a.quiet);
    let clock = std::time::Instant::now();
    let s = export(opened.source.as_ref(), format, &out, &opts, &progress)?;
    progress.println(&format!(
        "wrote {} ({format}: {} frames of {} vertices, {} bytes) in {:.3}s",
        s.path.display(),
        s.frames,
        s.vertices,
        s.bytes,
        clock.elapsed().as_secs_f64()
    ));
    Ok(())
}

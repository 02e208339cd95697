//! The job `crease run` submits, built from its flags as a [`JobSpec`] value: the fold source from `--folds` and
//! its files, the weight mode and strain limit from their flags, every other setting from `--set` as tuning
//! keys, checked by the same registry as a job spec's `[tuning]` table.

use crate::run_args::{Folds, RunArgs};
use anyhow::{anyhow, bail, Context, Result};
use crease_core::spacetime::position::strain_limit::{StrainReference, REST_STATE_STRAIN_LIMIT};
use crease_jobs::tuning::{key_of_field, Tuning};
use crease_jobs::{FoldSpec, JobError, JobSpec, PreviewOptions};
use serde_json::Value;
use std::path::Path;

/// Where the spec's files are (absolute paths, or placeholders to check the flags before any file exists).
struct Files {
    input: String,
    output: String,
    anchors: Option<String>,
    cameras: Option<String>,
    images: Option<String>,
}

/// Flag combinations and tuning keys, checked before anything is written (the demo's input included).
pub fn check_flags(a: &RunArgs, folds: Folds) -> Result<()> {
    match folds {
        Folds::Video => {
            if a.input.is_none() {
                bail!("--folds video needs --input (e.g. `crease demo --with-video` writes one)");
            }
            if a.anchors.is_some() {
                bail!("--anchors and --folds video exclude each other: the video detector writes its own anchors");
            }
            if a.cameras.is_none() {
                bail!("--folds video needs --cameras (the calibration JSON, see docs/folds.md)");
            }
        }
        Folds::Stretch => {
            if a.input.is_none() {
                bail!("--folds stretch needs --input (a captured sequence)");
            }
            if a.anchors.is_some() {
                bail!("--anchors and --folds stretch exclude each other: the stretch detector writes its own anchors");
            }
        }
        Folds::Anchors => {
            if a.input.is_some() && a.anchors.is_none() {
                bail!("--anchors is required with --input unless --folds stretch or --folds video (see docs/formats.md: anchors file)");
            }
        }
    }
    if folds != Folds::Video && (a.cameras.is_some() || a.images.is_some()) {
        bail!("--cameras and --images apply to --folds video only");
    }
    if a.subdivide > 0 && folds != Folds::Stretch {
        bail!("--subdivide applies to --folds stretch only");
    }
    if a.local_workers == 0 || a.local_capacity == 0 {
        bail!("--local-workers and --local-capacity must be at least 1");
    }
    let placeholder =
        |p: &Option<std::path::PathBuf>, name: &str| p.as_ref().map(|_| format!("/{name}"));
    build(
        a,
        folds,
        Files {
            input: "/input".into(),
            output: "/output".into(),
            anchors: Some("/anchors.json".into()),
            cameras: placeholder(&a.cameras, "cameras.json"),
            images: placeholder(&a.images, "images"),
        },
    )
    .map(drop)
}

/// The job for `input` (`n` frames) into `out`, folds from `anchors` or from the detector `folds` names.
pub fn job_spec(
    a: &RunArgs,
    folds: Folds,
    input: &Path,
    anchors: Option<&Path>,
    out: &Path,
    n: usize,
) -> Result<JobSpec> {
    let abs = |p: &Path| {
        std::path::absolute(p)
            .with_context(|| format!("resolving {}", p.display()))
            .map(|p| p.display().to_string())
    };
    let mut spec = build(
        a,
        folds,
        Files {
            input: abs(input)?,
            output: abs(out)?,
            anchors: anchors.map(abs).transpose()?,
            cameras: a.cameras.as_deref().map(abs).transpose()?,
            images: a.images.as_deref().map(abs).transpose()?,
        },
    )?;
    spec.name = input
        .file_name()
        .map(|f| f.to_string_lossy().into_owned())
        .unwrap_or_default();
    // Frame numbers only the input's length can check.
    for &f in &a.preview_frames {
        if f >= n {
            bail!("--preview-frames: frame {f} is out of range (the sequence has {n} frames, 0-based)");
        }
    }
    if let FoldSpec::Video { overlay_frames, .. } = &spec.folds {
        if let Some(f) = overlay_frames.iter().find(|&&f| f >= n) {
            bail!("video.overlay_frames: frame {f} is out of range (the sequence has {n} frames, 0-based)");
        }
    }
    Ok(spec)
}

fn build(a: &RunArgs, folds: Folds, files: Files) -> Result<JobSpec> {
    let mut spec = JobSpec::new(files.input, files.output);
    spec.folds = match folds {
        Folds::Anchors => FoldSpec::Anchors {
            uri: files.anchors.context("--anchors is required")?,
        },
        Folds::Stretch => FoldSpec::Stretch {
            params: Default::default(),
            subdivide: a.subdivide,
        },
        Folds::Video => FoldSpec::Video {
            cameras: files.cameras.context("--folds video needs --cameras")?,
            images: files.images,
            params: Default::default(),
            front_vertex: None,
            back_vertex: None,
            first_image_number: None,
            overlay_frames: Vec::new(),
        },
    };
    if a.input.is_none() {
        // The demo's input is its own rest state in every frame: its stretch is measured against the input
        // frame's triangles, and so is its strain limit (a tuning key or --strain-limit still wins).
        spec.deform.strain_reference = StrainReference::Frame;
        spec.deform.strain_limit = REST_STATE_STRAIN_LIMIT;
        // Its anchors are placed on purpose on a garment that never lost the surface of its folds (they were
        // never there): the lost-area bound would give the input back.
        spec.deform.lost_area_bound = false;
    }
    spec.preview = PreviewOptions {
        frames: a.preview_frames.clone(),
        size: a.preview_size,
    };
    spec.tuning = tuning(a)?;
    let named = spec.clone();
    spec.resolved().map_err(|e| spec_error(&named, a, e))
}

/// The tuning keys of the flags and of every `--set`.
fn tuning(a: &RunArgs) -> Result<Tuning> {
    let mut t = Tuning::default();
    let flag = |r: Result<(), String>| r.map_err(anyhow::Error::msg);
    if let Some(m) = a.mode {
        flag(t.insert("deform.mode", Value::from(m.to_string())))?;
    }
    if let Some(l) = a.strain_limit {
        flag(t.insert("deform.strain_limit", Value::from(l)))?;
    }
    if let Some(l) = a.detail_scale {
        flag(t.insert("deform.relief.scale", Value::from(l)))?;
    }
    for item in &a.set {
        let (key, text) = item.split_once('=').ok_or_else(|| {
            anyhow!("--set {item}: write KEY=VALUE (`crease tuning` lists the keys)")
        })?;
        t.set_text(key.trim(), text)
            .map_err(|m| anyhow!("--set {item}: {m}"))?;
    }
    Ok(t)
}

/// A spec error in the words of the command line: the flag or tuning key behind the field.
fn spec_error(spec: &JobSpec, a: &RunArgs, e: JobError) -> anyhow::Error {
    let JobError::Spec { field, msg } = e else {
        return e.into();
    };
    let name = match field.as_str() {
        "folds.subdivide" => "--subdivide".to_string(),
        "preview.size" => "--preview-size".to_string(),
        "preview.frames" => "--preview-frames".to_string(),
        f => match key_of_field(spec, f).or_else(|| f.strip_prefix("tuning.")) {
            Some("deform.mode") if a.mode.is_some() => "--mode".to_string(),
            Some("deform.strain_limit") if a.strain_limit.is_some() => "--strain-limit".to_string(),
            Some("deform.relief.scale") if a.detail_scale.is_some() => "--detail-scale".to_string(),
            Some(key) => key.to_string(),
            None => f.to_string(),
        },
    };
    anyhow!("{name}: {msg}")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::threads;
    use crate::Cli;
    use clap::{CommandFactory, FromArgMatches};

    fn args(extra: &[&str]) -> RunArgs {
        let mut v = vec!["crease", "run"];
        v.extend_from_slice(extra);
        let m = threads::add_to(Cli::command())
            .try_get_matches_from(v)
            .unwrap();
        match Cli::from_arg_matches(&m).unwrap().command {
            crate::Command::Run(a) => a,
            _ => unreachable!(),
        }
    }

    fn spec_of(extra: &[&str]) -> Result<JobSpec> {
        let a = args(extra);
        let folds = a.folds.unwrap_or(Folds::Anchors);
        check_flags(&a, folds)?;
        // Without --input, `crease run` writes the demo and its anchors first.
        let demo_anchors = a.input.is_none().then(|| Path::new("/demo/anchors.json"));
        job_spec(
            &a,
            folds,
            Path::new("/data/sleeve"),
            a.anchors.as_deref().or(demo_anchors),
            Path::new("/data/out"),
            10,
        )
    }

    /// `--set` on the command line and `[tuning]` in a job file give the same job, and the flags that are
    /// tuning keys (`--mode`, `--strain-limit`) set the same fields.
    #[test]
    fn set_gives_the_spec_a_tuning_table_gives() {
        let cli = spec_of(&[
            "--input",
            "/data/sleeve",
            "--folds",
            "video",
            "--cameras",
            "/data/cameras.json",
            "--mode",
            "per-anchor",
            "--strain-limit",
            "0.03",
            "--set",
            "video.max_distance=24",
            "--set",
            "video.views=all",
            "--set",
            "deform.window=12",
            "--set",
            "video.overlay_frames=1,3",
        ])
        .unwrap();
        let file = JobSpec::from_toml_str(
            r#"
            name = "sleeve"
            input = "/data/sleeve"
            output = "/data/out"
            [folds]
            kind = "video"
            cameras = "/data/cameras.json"
            [tuning]
            deform.mode = "per-anchor"
            deform.strain_limit = 0.03
            deform.window = 12
            video.max_distance = 24
            video.views = "all"
            video.overlay_frames = [1, 3]
            "#,
        )
        .unwrap();
        assert_eq!(cli, file);
    }

    /// Mistakes name the flag or the key.
    #[test]
    fn errors_name_the_flag_or_key() {
        let input = ["--input", "/data/sleeve", "--anchors", "/a.json"];
        let cases: &[(&[&str], &str)] = &[
            (&["--set", "deform.c_a=-1"], "deform.c_a"),
            (&["--set", "deform.shift=20"], "deform.shift:"),
            (&["--set", "deform.cg_tolerance=2"], "deform.cg_tolerance"),
            (&["--set", "nonsense"], "KEY=VALUE"),
            (&["--set", "stretch.alpha=2"], "stretch folds only"),
            (&["--set", "deform.mode=fused", "--mode", "fused"], "twice"),
            (&["--strain-limit", "2"], "--strain-limit:"),
            (&["--preview-frames", "10"], "--preview-frames"),
            (&["--preview-size", "8"], "--preview-size"),
            (&["--cameras", "/c.json"], "--folds video only"),
        ];
        for (extra, want) in cases {
            let mut v = input.to_vec();
            v.extend_from_slice(extra);
            let e = format!("{:#}", spec_of(&v).unwrap_err());
            assert!(e.contains(want), "{extra:?}: {e}");
        }
        let stretch = ["--input", "/data/sleeve", "--folds", "stretch"];
        for (extra, want) in [
            (
                &["--set", "stretch.min_shrink=3"][..],
                "stretch.min_shrink:",
            ),
            (&["--subdivide", "5"][..], "--subdivide:"),
        ] {
            let mut v = stretch.to_vec();
            v.extend_from_slice(extra);
            let e = format!("{:#}", spec_of(&v).unwrap_err());
            assert!(e.contains(want), "{extra:?}: {e}");
        }
        let video = [
            "--input",
            "/data/sleeve",
            "--folds",
            "video",
            "--cameras",
            "/c.json",
        ];
        for (extra, want) in [
            (
                &["--set", "video.front_vertex=3"][..],
                "video.front_vertex:",
            ),
            (
                &["--set", "video.overlay_frames=12"][..],
                "video.overlay_frames:",
            ),
        ] {
            let mut v = video.to_vec();
            v.extend_from_slice(extra);
            let e = format!("{:#}", spec_of(&v).unwrap_err());
            assert!(e.contains(want), "{extra:?}: {e}");
        }
    }

    /// The demo's strain and bound defaults (its input is its own rest state) give way to an explicit setting.
    #[test]
    fn the_demo_defaults_give_way_to_explicit_settings() {
        let demo = spec_of(&[]).unwrap();
        assert_eq!(demo.deform.strain_limit, REST_STATE_STRAIN_LIMIT);
        assert_eq!(demo.deform.strain_reference, StrainReference::Frame);
        assert!(!demo.deform.lost_area_bound);
        let set = spec_of(&[
            "--strain-limit",
            "0.04",
            "--set",
            "deform.strain_reference=sequence",
            "--set",
            "deform.lost_area_bound=true",
        ])
        .unwrap();
        assert!(set.deform.lost_area_bound);
        assert_eq!(set.deform.strain_limit, 0.04);
        assert_eq!(set.deform.strain_reference, StrainReference::Sequence);
    }
}

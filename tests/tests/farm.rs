#![allow(clippy::needless_range_loop)]
//! Farms run crease's task graph: `crease export-job` writes an OpenJD template that `openjd check` accepts and
//! `openjd run` executes end to end through `crease task run`, with outputs byte-identical to `crease run`.

use crease_e2e::tools;

use crease_core::mesh::io::{open_sequence, read_pc2_header, read_pc2_sample_from};
use crease_e2e::*;
use std::path::Path;
use std::process::Command;

fn crease(args: &[&str]) -> std::process::Output {
    Command::new(crease_e2e::bin()).args(args).output().unwrap()
}

/// Exports `job` for OpenJD, checks it, runs every step locally, and returns the run log.
fn openjd_export_check_run(dir: &Path, job: &Path, extra: &[&str]) -> String {
    let template = dir.join("job.openjd.json");
    let mut args = vec![
        "export-job",
        "--to",
        "openjd",
        job.to_str().unwrap(),
        "--out",
        template.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let o = crease(&args);
    assert!(o.status.success(), "export-job: {}", stderr(&o));
    let openjd = tools::tool("openjd");
    let o = Command::new(&openjd)
        .arg("check")
        .arg(&template)
        .output()
        .unwrap();
    let check = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(o.status.success(), "openjd check: {check}");
    let o = Command::new(&openjd)
        .arg("run")
        .arg(&template)
        .args(["--step", "Finalize", "--run-dependencies"])
        .args([
            "--job-param",
            &format!("CreaseExe={}", crease_e2e::bin().display()),
        ])
        .output()
        .unwrap();
    let log = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    std::fs::write(dir.join("openjd-run.log"), &log).unwrap();
    assert!(o.status.success(), "openjd run failed:\n{log}");
    log
}

#[test]
fn openjd_template_runs_to_the_same_bytes_as_crease_run() {
    let (dir, anchors) = setup();
    let input = fixture();
    let reference = dir.path().join("reference");
    local_run(&input, &anchors, &reference, "per-anchor", "2");
    let out = dir.path().join("farm-out");
    let job = job_file(
        dir.path(),
        "farm",
        &input,
        &anchors,
        &out,
        "per-anchor",
        "[export]\nformats = [\"glb\", \"usd\", \"mdd\", \"pc2\"]",
    );
    let log = openjd_export_check_run(dir.path(), &job, &[]);
    // Every stage ran as its own step, in dependency order.
    let at = |s: &str| {
        log.find(s)
            .unwrap_or_else(|| panic!("`{s}` missing from the openjd log:\n{log}"))
    };
    assert!(at("'Weights'") < at("'Reduce'"), "{log}");
    assert!(at("'Reduce'") < at("'Position'") && at("'Position'") < at("'Finalize'"));
    assert_complete_and_identical(&reference, &out);

    // The job's [export] formats were written by finalize, from the same positions as the output frames.
    for ext in ["glb", "usda", "mdd", "pc2"] {
        let p = out.join("export").join(format!("farm.{ext}"));
        assert!(p.is_file(), "{} missing", p.display());
    }
    let frames = open_sequence(&out).unwrap();
    let cache = out.join("export/farm.pc2");
    let h = read_pc2_header(&cache).unwrap();
    assert_eq!(h.num_samples, frames.source.n_frames());
    let mut f = std::fs::File::open(&cache).unwrap();
    for t in 0..h.num_samples {
        let want = frames.source.read_frame(t).unwrap();
        let got = read_pc2_sample_from(&cache, &mut f, &h, t).unwrap();
        for (a, b) in want.iter().zip(&got) {
            for c in 0..3 {
                assert_eq!(a[c] as f32, b[c] as f32, "frame {t}");
            }
        }
    }
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    let listed = report["output_files"].to_string();
    assert!(
        listed.contains("export/farm.glb") && listed.contains("export/farm.usda"),
        "{listed}"
    );

    // A farm retry of a finished task rewrites the same bytes and leaves the report in place.
    let before = output_files(&out);
    let o = crease(&[
        "task",
        "run",
        "--job",
        job.to_str().unwrap(),
        "--task",
        "position/f000002",
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(before, output_files(&out));
    assert!(out.join("report.json").is_file());
}

#[test]
fn detected_folds_run_through_block_slots_to_the_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let input = fixture();
    let reference = dir.path().join("reference");
    let o = crease(&[
        "run",
        "--input",
        input.to_str().unwrap(),
        "--folds",
        "stretch",
        "--out",
        reference.to_str().unwrap(),
        "--mode",
        "per-anchor",
        "--set",
        "deform.window=3",
        "--set",
        "deform.shift=2",
        "--set",
        "partition.anchor_block=8",
        "--preview-size",
        "64",
        "--threads",
        "2",
    ]);
    assert!(o.status.success(), "crease run: {}", stderr(&o));
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(reference.join("report.json")).unwrap()).unwrap();
    let blocks: Vec<u64> = report["report"]["windows"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w["blocks"].as_u64().unwrap())
        .collect();
    assert!(
        blocks.iter().any(|&b| b > 2),
        "the case must have more blocks than slots in some window to test the striding: {blocks:?}"
    );
    let out = dir.path().join("farm-out");
    let job = dir.path().join("job.toml");
    std::fs::write(
        &job,
        format!(
            "name = \"detected\"\ninput = \"{}\"\noutput = \"{}\"\n[folds]\nkind = \"stretch\"\n\
             [deform]\nmode = \"per-anchor\"\nwindow = 3\nshift = 2\n[partition]\nanchor_block = 8\n\
             frames_per_chunk = 2\nstretch_frames_per_chunk = 1\nstretch_warm_up = 0\n\
             [preview]\nsize = 64\n",
            input.display(),
            out.display()
        ),
    )
    .unwrap();
    // Stretch detection in one-frame tracing chunks without warm-up (the merge reconciles them), against
    // `crease run`'s default chunking.
    openjd_export_check_run(dir.path(), &job, &["--block-slots", "2"]);
    assert_complete_and_identical(&reference, &out);
    assert_eq!(
        std::fs::read(reference.join("anchors.json")).unwrap(),
        std::fs::read(out.join("anchors.json")).unwrap()
    );
}

#[test]
fn bad_task_references_and_relative_paths_are_named() {
    let (dir, anchors) = setup();
    let out = dir.path().join("out");
    let job = job_file(dir.path(), "bad", &fixture(), &anchors, &out, "fused", "");
    let o = crease(&[
        "task",
        "run",
        "--job",
        job.to_str().unwrap(),
        "--task",
        "weights/w0099",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(
        e.contains("`weights/w0099` is not in this job's graph") && e.contains("not retryable"),
        "{e}"
    );
    let o = crease(&[
        "task",
        "run",
        "--job",
        job.to_str().unwrap(),
        "--stage",
        "position",
        "--index",
        "9",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("stage `position` has 4 task(s)"),
        "{}",
        stderr(&o)
    );
    // A later stage before its inputs exist: the missing intermediate is named.
    let o = crease(&[
        "task",
        "run",
        "--job",
        job.to_str().unwrap(),
        "--task",
        "finalize",
    ]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains(".crease-work"), "{}", stderr(&o));
    let rel = dir.path().join("rel.toml");
    std::fs::write(&rel, "input = \"frames\"\noutput = \"/tmp/x\"\n").unwrap();
    let o = crease(&["export-job", "--to", "openjd", rel.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("`input`") && stderr(&o).contains("relative"),
        "{}",
        stderr(&o)
    );
    let o = crease(&["export-job", "--to", "slurm", job.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("unknown farm `slurm`"),
        "{}",
        stderr(&o)
    );
}

//! The 3D viewer in a real browser: headless Chromium (Debian's package, WebGL through SwiftShader) driven by
//! Playwright for Python (tests/tests/browser/viewer.py). Three servers on 127.0.0.1: a coordinator's dashboard
//! with client tokens and a finished fold-detection job on a small demo sequence (anchors and control lines),
//! `crease view` on a `crease run` output with `crease eval`'s figures beside it, and `crease view` on the input
//! folder alone. The script reads the canvas back as pixels: it is drawn, frames 1 and N differ, input and
//! output differ, every overlay changes the picture and switching it off restores it; the report shows its
//! tables, charts and raw JSON. Screenshots land in target/test-artifacts/viewer/. Chromium and Playwright come
//! from scripts/setup-tools; without them this test fails and says so.

mod dashboard_support;
mod viewer_support;

use crease_e2e::*;
use dashboard_support::*;
use std::path::Path;
use std::process::Command;
use viewer_support::view;

fn crease(args: &[&str]) {
    let o = Command::new(bin()).args(args).output().unwrap();
    assert!(o.status.success(), "crease {args:?}: {}", stderr(&o));
}

/// A stretch-detection job on the demo input (it writes anchors.json with control lines).
fn stretch_job(d: &Path, input: &Path) -> std::path::PathBuf {
    let path = d.join("stretch-job.toml");
    std::fs::write(
        &path,
        format!(
            "name = \"demo-folds\"\ninput = \"{}\"\noutput = \"{}\"\n\n[folds]\nkind = \"stretch\"\n\n[preview]\nsize = 96\n",
            input.display(),
            d.join("job-out").display()
        ),
    )
    .unwrap();
    path
}

#[test]
fn a_browser_sees_a_job_and_local_folders_in_the_viewer() {
    let python = playwright_python();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let demo = d.join("demo");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    crease(&[
        "demo",
        "--out",
        &s(&demo),
        "--triangles",
        "3000",
        "--frames",
        "6",
        "--with-video",
        "--video-cameras",
        "1",
        "--video-width",
        "32",
        "--video-height",
        "32",
    ]);
    let input = demo.join("input");

    let port = free_port();
    let c = start(d, port, &[]);
    let _w = c.worker("w-viewer", &[]);
    let id = c.submit(&stretch_job(d, &input));
    c.wait_state(&id, &["done"]);

    let run_out = d.join("run-out");
    crease(&[
        "run",
        "--input",
        &s(&input),
        "--anchors",
        &s(&demo.join("anchors.json")),
        "--out",
        &s(&run_out),
        "--preview-size",
        "96",
        "--quiet",
    ]);
    crease(&[
        "eval",
        "--output",
        &s(&run_out),
        "--gt",
        &s(&demo.join("gt")),
        "--input",
        &s(&input),
        "--quiet",
    ]);
    let view_out = view(&run_out, &[]);
    let view_input = view(&input, &[]);

    let artifacts = workspace().join("target/test-artifacts/viewer");
    let _ = std::fs::remove_dir_all(&artifacts);
    let mut cmd = Command::new(python);
    cmd.arg(workspace().join("tests/tests/browser/viewer.py"))
        .args(["--dashboard", &format!("http://127.0.0.1:{port}")])
        .args(["--token-file", &s(&d.join("client-tokens"))])
        .args(["--job", &id])
        .args(["--view", &view_out.url])
        .args(["--view-input", &view_input.url])
        .args(["--out", &s(&artifacts)]);
    let r = browser_script(cmd);
    eprintln!("viewer browser test: {r}");
    assert_eq!(r["job_frames"], 6);
    assert_eq!(r["input_alone_frames"], 6);
    assert!(r["job"]["covered"].as_f64().unwrap() > 0.05);
    assert!(r["job"]["control_lines_toggle"].as_f64().unwrap() > 0.0);
    assert!(r["view"]["anchors_toggle"].as_f64().unwrap() > 0.0);
    assert!(
        r["view_charts"].as_u64().unwrap() >= 4,
        "stretch, anchors and two eval charts"
    );
    for shot in [
        "job-00-page.png",
        "job-01-side-by-side.png",
        "job-02-stretch.png",
        "job-03-wipe.png",
        "job-04-report.png",
        "job-05-charts.png",
        "view-01-side-by-side.png",
        "view-04-report.png",
        "input-alone.png",
    ] {
        let bytes = std::fs::read(artifacts.join(shot)).unwrap_or_else(|e| panic!("{shot}: {e}"));
        assert!(
            bytes.starts_with(b"\x89PNG\r\n\x1a\n"),
            "{shot} is not a PNG"
        );
    }
}

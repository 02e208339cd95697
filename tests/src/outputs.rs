//! Inputs and outputs of the end-to-end jobs: the sleeve fixture and its anchors, job files, the single-node
//! reference run, and the byte-for-byte comparison every cluster output must pass.

use crate::binary::bin;
use crate::process::stderr;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The captured sleeve frames (kept with the CLI's own tests, which read them too).
pub fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/sleeve")
}

/// Anchors on the sleeve fixture: 40 per frame, so per-anchor mode with 8-column blocks has 5+ blocks per
/// window.
pub fn write_anchors(path: &Path) {
    let frames: Vec<String> = (0..4)
        .map(|f| {
            let list: Vec<String> = (0..40)
                .map(|k| {
                    format!(
                        r#"{{"triangle":{},"axis":[0,0,{}],"angle":0.6}}"#,
                        6000 + 2 * k,
                        if k < 20 { 1 } else { -1 }
                    )
                })
                .collect();
            format!(r#"{{"frame":{f},"anchors":[{}]}}"#, list.join(","))
        })
        .collect();
    std::fs::write(
        path,
        format!(r#"{{"version":1,"frames":[{}]}}"#, frames.join(",")),
    )
    .unwrap();
}

/// Parameters shared by the job files and the reference `crease run`: short windows so there are several
/// windows, cross-fades and reduce tasks on four frames.
pub const MODE_ARGS: [&str; 6] = [
    "--set",
    "deform.window=3",
    "--set",
    "deform.shift=2",
    "--set",
    "partition.anchor_block=8",
];

pub fn job_file(
    dir: &Path,
    name: &str,
    input: &Path,
    anchors: &Path,
    out: &Path,
    mode: &str,
    extra: &str,
) -> PathBuf {
    let path = dir.join(format!("{name}.toml"));
    let text = format!(
        r#"name = "{name}"
input = "{}"
output = "{}"
{extra}
[folds]
kind = "anchors"
uri = "{}"

[deform]
mode = "{mode}"
window = 3
shift = 2

[partition]
anchor_block = 8
frames_per_chunk = 1

[preview]
size = 64
"#,
        input.display(),
        out.display(),
        anchors.display()
    );
    std::fs::write(&path, text).unwrap();
    path
}

/// `crease run` (local single-node mode) into `out`.
pub fn local_run(input: &Path, anchors: &Path, out: &Path, mode: &str, workers: &str) {
    let o = Command::new(bin())
        .args(["run", "--input", input.to_str().unwrap()])
        .args(["--anchors", anchors.to_str().unwrap()])
        .args(["--out", out.to_str().unwrap(), "--mode", mode])
        .args(MODE_ARGS)
        .args([
            "--preview-size",
            "64",
            "--local-workers",
            workers,
            "--threads",
            "2",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "crease run: {}", stderr(&o));
}

/// Every file of an output (the frames, previews), except `report.json` (it holds timings), hidden files
/// (intermediates) and directories.
pub fn output_files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    try_output_files(dir).unwrap_or_else(|e| panic!("reading {}: {e}", dir.display()))
}

/// [`output_files`] for callers that report errors instead of failing a test (the soak harness).
pub fn try_output_files(dir: &Path) -> std::io::Result<BTreeMap<String, Vec<u8>>> {
    let mut m = BTreeMap::new();
    for e in std::fs::read_dir(dir)? {
        let e = e?;
        let name = e.file_name().to_string_lossy().into_owned();
        if name == "report.json" || name.starts_with('.') || e.path().is_dir() {
            continue;
        }
        m.insert(name, std::fs::read(e.path())?);
    }
    Ok(m)
}

pub fn assert_complete_and_identical(reference: &Path, out: &Path) {
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["complete"], true, "{}", out.display());
    let a = output_files(reference);
    let b = output_files(out);
    assert!(a.len() >= 6, "reference has only {:?}", a.keys());
    assert_eq!(
        a.keys().collect::<Vec<_>>(),
        b.keys().collect::<Vec<_>>(),
        "{} vs {}",
        reference.display(),
        out.display()
    );
    for (k, v) in &a {
        assert!(
            v == &b[k],
            "{k} differs between {} and {}",
            reference.display(),
            out.display()
        );
    }
}

pub fn tasks(status: &serde_json::Value) -> Vec<serde_json::Value> {
    status["tasks"].as_array().cloned().unwrap_or_default()
}

pub fn setup() -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let anchors = dir.path().join("anchors.json");
    write_anchors(&anchors);
    (dir, anchors)
}

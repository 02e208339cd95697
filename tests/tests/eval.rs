//! `crease eval` end to end on four frames of the shared sleeve sample (captured and ground truth).

use std::path::{Path, PathBuf};
use std::process::Command;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures")
        .join(name)
}

/// Runs `crease eval`, returning (success, stdout, stderr, eval.json if written).
fn eval(
    output: &Path,
    gt: &Path,
    input: &Path,
    dir: &Path,
) -> (bool, String, String, serde_json::Value) {
    let json = dir.join("eval.json");
    let o = Command::new(crease_e2e::bin())
        .args(["eval", "--quiet", "--output"])
        .arg(output)
        .arg("--gt")
        .arg(gt)
        .arg("--input")
        .arg(input)
        .arg("--json")
        .arg(&json)
        .arg("--png")
        .arg(dir.join("eval.png"))
        .args(["--size", "64"])
        .output()
        .expect("run crease");
    let report = std::fs::read_to_string(&json)
        .ok()
        .and_then(|s| serde_json::from_str(&s).ok())
        .unwrap_or(serde_json::Value::Null);
    (
        o.status.success(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
        report,
    )
}

#[test]
fn ground_truth_scores_perfectly_and_captured_is_the_baseline() {
    let dir = tempfile::tempdir().unwrap();
    let (captured, gt) = (fixture("sleeve"), fixture("sleeve-gt"));

    let (ok, stdout, stderr, r) = eval(&gt, &gt, &captured, dir.path());
    assert!(ok, "{stderr}");
    assert!(stdout.contains("fold-signal correlation"), "{stdout}");
    assert!((r["output"]["correlation"].as_f64().unwrap() - 1.0).abs() < 1e-9);
    assert!((r["output"]["kappa"].as_f64().unwrap() - 1.0).abs() < 1e-9);
    assert_eq!(r["output"]["normal_error_deg"].as_f64(), Some(0.0));
    let gt_fraction = r["gt_fold_fraction"].as_f64().unwrap();
    assert!(gt_fraction > 0.05 && gt_fraction < 0.95, "{gt_fraction}");
    assert!(r["captured_baseline"]["normal_error_deg"].as_f64().unwrap() > 1.0);
    assert_eq!(r["per_frame"].as_array().unwrap().len(), 4);
    assert!(dir.path().join("eval.png").is_file());

    let (ok, _, stderr, r) = eval(&captured, &gt, &captured, dir.path());
    assert!(ok, "{stderr}");
    assert!(r["output"]["correlation"].is_null());
    assert!(r["output"]["kappa"].as_f64().unwrap().abs() < 1e-12);
    assert_eq!(
        r["output"]["normal_error_deg"],
        r["captured_baseline"]["normal_error_deg"]
    );
}

#[test]
fn mismatched_inputs_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let short = dir.path().join("short");
    std::fs::create_dir(&short).unwrap();
    for f in ["frame_0020.obj", "frame_0021.obj"] {
        std::fs::copy(fixture("sleeve-gt").join(f), short.join(f)).unwrap();
    }
    let (ok, _, stderr, _) = eval(&fixture("sleeve"), &short, &fixture("sleeve"), dir.path());
    assert!(!ok);
    assert!(
        stderr.contains("gt") && stderr.contains("2 frames"),
        "{stderr}"
    );
    assert!(!dir.path().join("eval.json").exists());

    let missing = dir.path().join("nowhere");
    let (ok, _, stderr, _) = eval(
        &missing,
        &fixture("sleeve-gt"),
        &fixture("sleeve"),
        dir.path(),
    );
    assert!(!ok);
    assert!(
        stderr.contains("--output") && stderr.contains("nowhere"),
        "{stderr}"
    );
}

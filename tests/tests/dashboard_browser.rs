//! The dashboard in a real browser: headless Chromium (Debian's package) driven by Playwright for Python
//! (tests/tests/browser/dashboard.py) against a real coordinator and worker on 127.0.0.1 with client tokens on.
//! The script signs in, submits a job and watches its progress bar move to done without polling, opens the
//! job and sees preview.png load, cancels a second job and sees its state change, and saves screenshots to
//! target/test-artifacts/dashboard/. Chromium and Playwright come from scripts/setup-tools; without them this
//! test fails and says so.

mod dashboard_support;

use crease_e2e::*;
use dashboard_support::*;
use std::process::Command;

#[test]
fn a_browser_watches_a_job_finish_sees_its_preview_and_cancels_another() {
    let python = playwright_python();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let port = free_port();
    let c = start(d, port, &[]);
    // Slow positioning a little so the bar has steps to show, and the second job is still running when the
    // browser cancels it.
    let _w = c.worker("w-browser", &[("CREASE_TEST_TASK_DELAY", "position=600")]);
    let (job1, _) = job(d, "sleeve-folds");
    let (job2, _) = job(d, "to-cancel");
    let artifacts = workspace().join("target/test-artifacts/dashboard");
    let _ = std::fs::remove_dir_all(&artifacts);
    let mut cmd = Command::new(python);
    cmd.arg(workspace().join("tests/tests/browser/dashboard.py"))
        .args(["--url", &format!("http://127.0.0.1:{port}")])
        .args([
            "--coordinator",
            &c.url(),
            "--crease",
            bin().to_str().expect("utf-8 binary path"),
        ])
        .args(["--token-file", d.join("client-tokens").to_str().unwrap()])
        .args(["--worker-token", WORKER_TOKEN])
        .args(["--job", job1.to_str().unwrap()])
        .args(["--job2", job2.to_str().unwrap()])
        .args(["--out", artifacts.to_str().unwrap()]);
    let result = browser_script(cmd);
    assert!(result["preview_natural_width"].as_u64().unwrap() > 0);
    assert_eq!(c.status(result["job"].as_str().unwrap())["state"], "done");
    assert_eq!(
        c.status(result["cancelled"].as_str().unwrap())["state"],
        "cancelled"
    );
    for shot in [
        "01-login-refused-worker-token.png",
        "02-jobs-running.png",
        "03-jobs-done.png",
        "04-job-done.png",
        "05-jobs-cancelled.png",
        "06-workers.png",
    ] {
        let bytes = std::fs::read(artifacts.join(shot)).unwrap_or_else(|e| panic!("{shot}: {e}"));
        assert!(
            bytes.starts_with(b"\x89PNG\r\n\x1a\n"),
            "{shot} is not a PNG"
        );
    }
}

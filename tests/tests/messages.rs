//! Messages a user gets for bad input: they name the flag, field or file, and read as sentences.

use crease_e2e::*;
use std::process::Command;
use std::time::{Duration, Instant};

fn crease(args: &[&str]) -> std::process::Output {
    Command::new(bin()).args(args).output().unwrap()
}

#[test]
fn negative_counts_and_zero_threads_get_a_sentence() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("d");
    let o = crease(&["demo", "--out", out.to_str().unwrap(), "--frames", "-3"]);
    assert_eq!(o.status.code(), Some(2));
    assert_eq!(
        stderr(&o).trim(),
        "error: --frames takes a number ≥ 0, got -3"
    );
    let o = crease(&["demo", "--out", out.to_str().unwrap(), "--frames=-3"]);
    assert!(
        stderr(&o).contains("--frames takes a number ≥ 0, got -3"),
        "{}",
        stderr(&o)
    );
    let o = crease(&["run", "--threads", "0"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--threads"), "{}", stderr(&o));
    let o = crease(&["status", "--threads", "2"]);
    assert!(!o.status.success(), "client verbs take no --threads");
}

#[test]
fn a_url_without_a_scheme_is_refused_at_once() {
    for args in [
        vec!["worker", "--coordinator", "127.0.0.1:7070"],
        vec!["status", "--coordinator", "127.0.0.1:7070"],
        vec!["worker", "--advertise", "10.0.0.1:5000"],
    ] {
        let start = Instant::now();
        let o = crease(&args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(
            err.contains("has no scheme") && err.contains("http://"),
            "{err}"
        );
        assert!(start.elapsed() < Duration::from_secs(10));
    }
}

#[test]
fn spec_errors_name_the_file_and_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let c = Coordinator::start(d, &[]);
    let no_output = d.join("no-output.toml");
    std::fs::write(
        &no_output,
        format!("name = \"x\"\ninput = \"{}\"\n", fixture().display()),
    )
    .unwrap();
    let o = c.cli(&["submit", no_output.to_str().unwrap()]);
    let err = stderr(&o);
    assert!(!o.status.success());
    assert!(err.contains(&no_output.display().to_string()), "{err}");
    assert!(err.contains("`output`"), "{err}");
    assert!(!err.contains("`name`"), "{err}");
    let bad_c = d.join("my-coefficients.toml");
    std::fs::write(
        &bad_c,
        format!(
            "input = \"{}\"\noutput = \"{}\"\n[deform]\nc_s = -1.0\n",
            fixture().display(),
            d.join("o").display()
        ),
    )
    .unwrap();
    let o = c.cli(&["submit", bad_c.to_str().unwrap()]);
    let err = stderr(&o);
    assert!(
        err.contains("my-coefficients.toml") && err.contains("`deform.c_s`"),
        "{err}"
    );
    assert!(!err.contains("job.toml"), "{err}");
}

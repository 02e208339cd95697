//! Replays the committed fuzz corpora and crash regressions (`fuzz/corpus/<target>/`,
//! `fuzz/regressions/<target>/`) of the crease-jobs job spec parsers through the same harness the fuzz targets run
//! (`fuzz/harness/jobs.rs`), so a parser change that panics on an input the fuzzer once found fails
//! `cargo test` on stable, without cargo-fuzz.

#[path = "../../fuzz/harness/jobs.rs"]
mod harness;

use std::path::{Path, PathBuf};

/// Every file of `fuzz/<kind>/<target>/`, sorted; none when the directory does not exist.
fn inputs(kind: &str, target: &str) -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fuzz")
        .join(kind)
        .join(target);
    let mut files: Vec<PathBuf> = match std::fs::read_dir(&dir) {
        Ok(entries) => entries
            .map(|e| e.expect("read a corpus directory entry").path())
            .filter(|p| p.is_file())
            .collect(),
        Err(_) => Vec::new(),
    };
    files.sort();
    files
}

/// Runs `run` on every corpus and regression input of `target`, naming the input that panics.
fn replay(target: &str, run: fn(&[u8])) {
    let corpus = inputs("corpus", target);
    assert!(
        !corpus.is_empty(),
        "no corpus for fuzz target {target} under fuzz/corpus/{target}"
    );
    let mut failed = Vec::new();
    for file in corpus.iter().chain(&inputs("regressions", target)) {
        let data = std::fs::read(file).expect("read a corpus file");
        if std::panic::catch_unwind(|| run(&data)).is_err() {
            failed.push(file.display().to_string());
        }
    }
    assert!(
        failed.is_empty(),
        "{target}: inputs that panic: {failed:#?}"
    );
}

#[test]
fn spec_toml_corpus_never_panics() {
    replay("spec_toml", harness::spec_toml);
}

#[test]
fn spec_json_corpus_never_panics() {
    replay("spec_json", harness::spec_json);
}

//! Replays the committed fuzz corpora and crash regressions (`fuzz/corpus/<target>/`,
//! `fuzz/regressions/<target>/`) of the crease-core parsers through the same harness the fuzz targets run
//! (`fuzz/harness/core.rs`), so a parser change that panics on an input the fuzzer once found fails
//! `cargo test` on stable, without cargo-fuzz.

#[path = "../../fuzz/harness/core.rs"]
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
fn obj_corpus_never_panics() {
    replay("obj", harness::obj);
}

#[test]
fn ply_corpus_never_panics() {
    replay("ply", harness::ply);
}

#[test]
fn pc2_corpus_never_panics() {
    replay("pc2", harness::pc2);
}

#[test]
fn anchors_corpus_never_panics() {
    replay("anchors", harness::anchors);
}

#[test]
fn cameras_corpus_never_panics() {
    replay("cameras", harness::cameras);
}

//! Replays the committed fuzz corpora and crash regressions (`fuzz/corpus/<target>/`,
//! `fuzz/regressions/<target>/`) of the crease-core parsers through the same harness the fuzz targets run
//! (`fuzz/harness/core.rs`), so a parser change that panics on an input the fuzzer once found fails
//! `cargo test` on stable, without cargo-fuzz.

#[path = "../../fuzz/harness/core.rs"]
mod harness;

#[path = "../../fuzz/harness/replay.rs"]
mod replay;

use replay::replay;

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

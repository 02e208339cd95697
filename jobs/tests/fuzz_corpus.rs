//! Replays the committed fuzz corpora and crash regressions (`fuzz/corpus/<target>/`,
//! `fuzz/regressions/<target>/`) of the crease-jobs job spec parsers through the same harness the fuzz targets run
//! (`fuzz/harness/jobs.rs`), so a parser change that panics on an input the fuzzer once found fails
//! `cargo test` on stable, without cargo-fuzz.

#[path = "../../fuzz/harness/jobs.rs"]
mod harness;

#[path = "../../fuzz/harness/replay.rs"]
mod replay;

use replay::replay;

#[test]
fn spec_toml_corpus_never_panics() {
    replay("spec_toml", harness::spec_toml);
}

#[test]
fn spec_json_corpus_never_panics() {
    replay("spec_json", harness::spec_json);
}

//! What each crease-jobs fuzz target does with one input, shared (through `#[path]`) by the libFuzzer targets
//! in `fuzz/fuzz_targets/` and the corpus replay test `jobs/tests/fuzz_corpus.rs`.

// Each fuzz target uses one function of this file; the replay test uses all of them.
#![allow(dead_code)]

use crease_jobs::{JobError, JobSpec};

/// A rejected spec must name the field (or the URI) at fault.
fn assert_named(e: &JobError) {
    match e {
        JobError::Spec { field, .. } => assert!(!field.is_empty(), "no field named: {e}"),
        JobError::Input { uri, .. }
        | JobError::Storage { uri, .. }
        | JobError::Full { uri, .. }
        | JobError::Unreachable { uri, .. } => {
            assert!(!uri.is_empty(), "no URI named: {e}")
        }
        JobError::Limit { limit, .. } => assert!(!limit.is_empty(), "no limit named: {e}"),
        JobError::Plan(msg) => assert!(!msg.is_empty()),
    }
}

/// What the coordinator does with an accepted spec: it stores it as JSON and reads it back (with
/// `serde_json::from_str`) whenever it plans or resumes the job, so every accepted spec must survive that trip
/// unchanged, whatever format it was submitted in.
fn use_spec(spec: &JobSpec) {
    let _ = spec.display_name();
    let _ = spec.params();
    let _ = spec.folds.kind();
    let _ = spec.folds.subdivide();
    let json = serde_json::to_string(spec).expect("an accepted spec serialises");
    let back: JobSpec = serde_json::from_str(&json)
        .unwrap_or_else(|e| panic!("an accepted spec does not read back from {json}: {e}"));
    assert_eq!(&back, spec, "the spec changed on its way through JSON");
}

/// A `job.toml` as `crease submit` reads it.
pub fn spec_toml(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    match JobSpec::from_toml_str(text) {
        Ok(spec) => use_spec(&spec),
        Err(e) => assert_named(&e),
    }
}

/// A JSON job spec as the coordinator receives it.
pub fn spec_json(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    match JobSpec::from_json_str(text) {
        Ok(spec) => use_spec(&spec),
        Err(e) => assert_named(&e),
    }
}

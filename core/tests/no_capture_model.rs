//! Nothing in crease models how its sample data's captures were made: no product source names the Taubin
//! filter that made the public `captured/` folders (it was `TaubinFilter::capture` and its 80 steps) or uses its
//! μ of −0.53, except the fixed drift ruler of `crease eval` (`core/src/eval.rs`), which is a measuring
//! instrument and not part of any run.

use std::path::{Path, PathBuf};

fn rust_sources(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            // Tests may build any capture they like to test against.
            if p.file_name().is_some_and(|n| n == "tests" || n == "target") {
                continue;
            }
            rust_sources(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

#[test]
fn no_product_source_carries_the_sample_data_capture_filter() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut files = Vec::new();
    for krate in [
        "core",
        "jobs",
        "cli",
        "deep",
        "coordinator",
        "worker",
        "dashboard",
    ] {
        rust_sources(&root.join(krate).join("src"), &mut files);
    }
    assert!(files.len() > 50, "found only {} sources", files.len());
    let ruler = root.join("core/src/eval.rs");
    let mut hits = Vec::new();
    for f in &files {
        let text = std::fs::read_to_string(f).unwrap();
        let in_tests = text.find("#[cfg(test)]").unwrap_or(text.len());
        for (i, line) in text[..in_tests].lines().enumerate() {
            let named = line.contains("TaubinFilter::capture") || line.contains("CAPTURE_STEPS");
            let constant = line.contains("-0.53") || line.contains("−0.53");
            if named || (constant && f.canonicalize().ok() != ruler.canonicalize().ok()) {
                hits.push(format!("{}:{}: {}", f.display(), i + 1, line.trim()));
            }
        }
    }
    assert!(
        hits.is_empty(),
        "the capture filter in product code:\n{}",
        hits.join("\n")
    );
}

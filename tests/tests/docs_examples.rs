//! The documentation's code blocks, run or validated as written (the convention is in docs/README.md): every
//! `sh`/`toml` block in README.md and docs/*.md carries a marker; `sh runnable` blocks run against the built
//! binary; `toml runnable-spec` blocks are parsed and validated as job specs.

use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Files whose runnable blocks have a test below; a file with runnable blocks missing here fails
/// `every_block_is_marked_and_specs_validate`.
const RUN_TESTED: &[&str] = &[
    "README.md",
    "docs/formats.md",
    "docs/folds.md",
    "docs/cluster.md",
    "docs/fidelity.md",
    "docs/benchmarks.md",
    "docs/export.md",
];

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

struct Block {
    file: String,
    line: usize,
    lang: String,
    marker: String,
    text: String,
}

fn blocks(rel: &str) -> Vec<Block> {
    let path = root().join(rel);
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut out = Vec::new();
    let mut open: Option<Block> = None;
    for (i, line) in text.lines().enumerate() {
        let Some(info) = line.strip_prefix("```") else {
            if let Some(b) = open.as_mut() {
                b.text.push_str(line);
                b.text.push('\n');
            }
            continue;
        };
        match open.take() {
            Some(b) => out.push(b),
            None => {
                let info = info.trim();
                let (lang, marker) = info.split_once(' ').unwrap_or((info, ""));
                open = Some(Block {
                    file: rel.to_string(),
                    line: i + 1,
                    lang: lang.to_string(),
                    marker: marker.trim().to_string(),
                    text: String::new(),
                });
            }
        }
    }
    assert!(open.is_none(), "{rel}: a code block is never closed");
    out
}

fn doc_files() -> Vec<String> {
    let mut files = vec!["README.md".to_string()];
    let mut docs: Vec<String> = std::fs::read_dir(root().join("docs"))
        .expect("docs/")
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".md"))
        .map(|n| format!("docs/{n}"))
        .collect();
    docs.sort();
    files.extend(docs);
    files
}

fn validate_spec(b: &Block, text: &str) {
    if let Err(e) = crease_jobs::JobSpec::from_toml_str(text) {
        panic!(
            "{}:{}: the job spec does not validate: {e}\n{text}",
            b.file, b.line
        );
    }
}

#[test]
fn every_block_is_marked_and_specs_validate() {
    let mut verbs = std::collections::BTreeSet::new();
    let mut specs = 0;
    for file in doc_files() {
        for b in blocks(&file) {
            let at = format!("{}:{}", b.file, b.line);
            match (b.lang.as_str(), b.marker.as_str()) {
                ("sh", "runnable") => assert!(
                    RUN_TESTED.contains(&b.file.as_str()),
                    "{at}: a runnable block in a file that no test runs: add it to RUN_TESTED"
                ),
                ("sh", "synopsis") => {
                    for line in b.text.lines() {
                        let mut words = line.split_whitespace();
                        while let Some(w) = words.next() {
                            if w == "crease" {
                                if let Some(v) = words.next() {
                                    if v.chars().all(|c| c.is_ascii_lowercase()) {
                                        verbs.insert(v.to_string());
                                    }
                                }
                            }
                        }
                    }
                }
                ("sh" | "toml", m) if m.starts_with("not-runnable:") => assert!(
                    m["not-runnable:".len()..].trim().len() >= 10,
                    "{at}: say why the block cannot run"
                ),
                ("toml", "runnable-spec") => {
                    validate_spec(&b, &b.text);
                    specs += 1;
                }
                ("toml", "runnable-spec-fragment") => {
                    validate_spec(
                        &b,
                        &format!("input = \"/in\"\noutput = \"/out\"\n{}", b.text),
                    );
                    specs += 1;
                }
                ("sh" | "toml", m) => panic!(
                    "{at}: `{}` block without a known marker (`{m}`): see docs/README.md",
                    b.lang
                ),
                _ => {}
            }
        }
    }
    assert!(specs >= 3, "the job spec examples were not found ({specs})");
    assert!(verbs.len() >= 8, "synopsis verbs: {verbs:?}");
    for verb in &verbs {
        let o = Command::new(crease_e2e::bin())
            .args([verb, "--help"])
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "a synopsis names `crease {verb}`, which is not a verb"
        );
    }
}

/// Runs the file's runnable blocks in order in one scratch directory, each in its own process group (killed
/// afterwards, so a block that fails half-way leaves no server behind).
fn run_blocks(file: &str) {
    let runnable: Vec<Block> = blocks(file)
        .into_iter()
        .filter(|b| b.lang == "sh" && b.marker == "runnable")
        .collect();
    assert!(!runnable.is_empty(), "{file}: no runnable blocks");
    let dir = tempfile::tempdir().unwrap();
    let bin_dir = crease_e2e::bin().parent().unwrap();
    let path = format!(
        "{}:{}",
        bin_dir.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    // Output goes to files, not pipes: a server a failed block left running would hold a pipe open.
    let logs = tempfile::tempdir().unwrap();
    for b in runnable {
        let script = b.text.replace("cargo run --release --", "crease");
        let (out_path, err_path) = (logs.path().join("stdout"), logs.path().join("stderr"));
        let mut child = Command::new("bash")
            .args(["-e", "-o", "pipefail", "-c", &script])
            .current_dir(dir.path())
            .env("PATH", &path)
            .env_remove("CREASE_COORDINATOR")
            .process_group(0)
            .stdout(std::fs::File::create(&out_path).unwrap())
            .stderr(std::fs::File::create(&err_path).unwrap())
            .spawn()
            .expect("bash");
        let pgid = child.id();
        let status = child.wait().unwrap();
        let _ = Command::new("kill")
            .args(["-KILL", "--", &format!("-{pgid}")])
            .stderr(std::process::Stdio::null())
            .status();
        let read =
            |p: &Path| String::from_utf8_lossy(&std::fs::read(p).unwrap_or_default()).into_owned();
        assert!(
            status.success(),
            "{}:{}: the block failed ({status}):\n{script}\n--- stdout\n{}\n--- stderr\n{}",
            b.file,
            b.line,
            read(&out_path),
            read(&err_path)
        );
    }
}

#[test]
fn readme_blocks_run() {
    run_blocks("README.md");
}

#[test]
fn formats_blocks_run() {
    run_blocks("docs/formats.md");
}

#[test]
fn folds_blocks_run() {
    run_blocks("docs/folds.md");
}

#[test]
fn cluster_blocks_run() {
    run_blocks("docs/cluster.md");
}

#[test]
fn fidelity_blocks_run() {
    run_blocks("docs/fidelity.md");
}

#[test]
fn benchmarks_blocks_run() {
    run_blocks("docs/benchmarks.md");
}

#[test]
fn export_blocks_run() {
    run_blocks("docs/export.md");
}

/// The relative links of the documentation point at files of the repository, and the pages name nothing outside
/// it: no developer machine paths, no design notes that are not part of the repository.
#[test]
fn links_resolve_and_nothing_outside_the_repository_is_named() {
    let root = root();
    let mut files = doc_files();
    files.push("bench/results/README.md".to_string());
    for file in files {
        let text = std::fs::read_to_string(root.join(&file)).unwrap();
        for (n, line) in text.lines().enumerate() {
            let at = format!("{file}:{}", n + 1);
            assert!(!line.contains("/work/"), "{at}: a machine path: {line}");
            let design_notes = ["DES", "IGN"].concat();
            assert!(
                !line.contains(&design_notes),
                "{at}: names a file outside the repository: {line}"
            );
            let mut rest = line;
            while let Some(i) = rest.find("](") {
                rest = &rest[i + 2..];
                let Some(end) = rest.find(')') else { break };
                let target = &rest[..end];
                rest = &rest[end..];
                if target.contains("://")
                    || target.starts_with('#')
                    || target.starts_with("mailto:")
                {
                    continue;
                }
                let path = target.split('#').next().unwrap();
                let base = Path::new(&file).parent().unwrap();
                assert!(
                    root.join(base).join(path).exists(),
                    "{at}: the link `{target}` points at no file"
                );
            }
        }
    }
}

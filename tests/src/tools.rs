//! The non-Rust tools the farm and export tests drive, installed by `scripts/setup-tools` under `.tools/`
//! (PATH is searched first); a clear failure when missing, never a skip.

use std::path::{Path, PathBuf};

pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

/// `name` in `.tools/venv/bin` or on PATH.
pub fn tool(name: &str) -> PathBuf {
    let local = repo().join(".tools/venv/bin").join(name);
    if local.is_file() {
        return local;
    }
    if let Some(path) = std::env::var_os("PATH") {
        for dir in std::env::split_paths(&path) {
            let p = dir.join(name);
            if p.is_file() {
                return p;
            }
        }
    }
    panic!(
        "{name} was not found in {} or on PATH: run scripts/setup-tools once (or scripts/test, which does)",
        repo().join(".tools/venv/bin").display()
    );
}

/// The venv's Python (with `pxr` from usd-core).
pub fn python() -> PathBuf {
    tool("python3")
}

/// `.tools/node_modules`, where setup-tools installs gltf-validator.
pub fn node_modules() -> PathBuf {
    let d = repo().join(".tools/node_modules");
    assert!(
        d.join("gltf-validator").is_dir(),
        "gltf-validator is not installed in {}: run scripts/setup-tools",
        d.display()
    );
    d
}

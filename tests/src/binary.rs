//! Where the `crease` executable under test is. Cargo only hands `CARGO_BIN_EXE_<name>` to the tests of the
//! package that owns the binary, and this crate is not the CLI package, so the kit finds it itself: the
//! `crease` in the test executable's own `target/<profile>/`. `cargo test --workspace` builds it in the same
//! run; when it is missing or older than any source of the crates it is built from (a lone
//! `cargo test -p crease-e2e` after an edit), the kit runs `cargo build -p crease --bin crease` into that
//! directory once per test process (with `--features deep` when this crate's `deep` feature is on, as
//! `--all-features` turns it on), so a test never runs a stale binary. `CREASE_BIN` overrides all this with
//! a given executable (an installed build, a CI artifact).

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

/// The `crease` executable, built on first use (see the module docs).
pub fn bin() -> &'static Path {
    static BIN: OnceLock<PathBuf> = OnceLock::new();
    BIN.get_or_init(|| {
        if let Some(p) = std::env::var_os("CREASE_BIN") {
            return PathBuf::from(p);
        }
        let profile_dir = profile_dir();
        let exe = profile_dir.join(format!("crease{}", std::env::consts::EXE_SUFFIX));
        if !is_fresh(&exe) {
            build(&profile_dir);
        }
        assert!(
            exe.is_file(),
            "cargo built crease but {} does not exist",
            exe.display()
        );
        exe
    })
}

/// `target/<profile>` of the running test executable (`target/<profile>/deps/<test>-<hash>`).
fn profile_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("the test executable's path");
    let deps = exe.parent().expect("the test executable's directory");
    let dir = if deps.file_name().is_some_and(|n| n == "deps") {
        deps.parent().expect("target/<profile>")
    } else {
        deps
    };
    dir.to_path_buf()
}

fn build(profile_dir: &Path) {
    let profile = match profile_dir.file_name().and_then(|n| n.to_str()) {
        Some("debug") => "dev".to_string(),
        Some(other) => other.to_string(),
        None => panic!("no profile in {}", profile_dir.display()),
    };
    let target_dir = profile_dir.parent().expect("the target directory");
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR")).join("../Cargo.toml");
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let status = Command::new(&cargo)
        .args(["build", "--quiet", "-p", "crease", "--bin", "crease"])
        .args(if cfg!(feature = "deep") {
            &["--features", "deep"][..]
        } else {
            &[]
        })
        .args(["--profile", &profile])
        .arg("--manifest-path")
        .arg(&manifest)
        .arg("--target-dir")
        .arg(target_dir)
        .status()
        .unwrap_or_else(|e| {
            panic!("cannot run {cargo:?} to build crease: {e} (or set CREASE_BIN)")
        });
    assert!(
        status.success(),
        "building crease ({profile} profile) failed: {status}"
    );
}

/// The crates the `crease` binary is built from, relative to the workspace root.
const SOURCES: [&str; 11] = [
    "cli",
    "core",
    "jobs",
    "coordinator",
    "worker",
    "net",
    "proto",
    "telemetry",
    "dashboard",
    "deep",
    "Cargo.lock",
];

/// Whether `exe` exists and is newer than every source file it is built from.
fn is_fresh(exe: &Path) -> bool {
    let Ok(built) = std::fs::metadata(exe).and_then(|m| m.modified()) else {
        return false;
    };
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    SOURCES
        .iter()
        .all(|s| newest(&root.join(s)).is_none_or(|t| t <= built))
}

/// The newest modification time under `path` (sources only: `Cargo.toml`, `build.rs`, `src/`, `proto/`).
fn newest(path: &Path) -> Option<std::time::SystemTime> {
    let meta = std::fs::metadata(path).ok()?;
    if meta.is_file() {
        return meta.modified().ok();
    }
    ["Cargo.toml", "build.rs", "src", "proto"]
        .iter()
        .filter_map(|p| newest_in(&path.join(p)))
        .max()
}

fn newest_in(path: &Path) -> Option<std::time::SystemTime> {
    let meta = std::fs::metadata(path).ok()?;
    if meta.is_file() {
        return meta.modified().ok();
    }
    std::fs::read_dir(path)
        .ok()?
        .filter_map(|e| newest_in(&e.ok()?.path()))
        .max()
}

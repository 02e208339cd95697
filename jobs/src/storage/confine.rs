//! Keeping a job inside the storage its coordinator was given.
//!
//! Two guards, because names come from two places:
//! - **Keys** ([`check_key`]): every object name crease builds under a root (a task's intermediate, an output
//!   frame named after an input file, a listed object copied into the worker cache) must be a plain relative
//!   path. `..`, `.`, empty segments, absolute keys, backslashes and percent-encoded dots, slashes or
//!   backslashes are refused outright rather than normalised, so that no later layer (a filesystem, a
//!   server that decodes `%2e%2e`) can turn them into a step out of the prefix.
//! - **URIs** ([`StorageRoots`]): when the coordinator is started with `--storage-root` (or
//!   `CREASE_STORAGE_ROOTS`), every location in a job spec must lie under one of the roots. Remote URIs are
//!   compared segment by segment on the raw text (so `s3://b/data-evil` is not under `s3://b/data`, and a
//!   `..` that a URL parser would silently resolve is refused instead); local paths are compared as canonical
//!   paths, component by component, so a symlink inside a root that points out of it does not pass.

use crate::error::JobError;
use std::path::{Component, Path, PathBuf};

/// Why `key` is not a safe relative object key, if it is not.
pub fn check_key(key: &str) -> Result<(), String> {
    if key.is_empty() {
        return Err("empty key".into());
    }
    if key.starts_with('/') {
        return Err(format!(
            "`{key}` is absolute; keys are relative to their root"
        ));
    }
    for segment in key.split('/') {
        check_segment(segment).map_err(|e| format!("`{key}`: {e}"))?;
    }
    Ok(())
}

/// One path segment: not empty, not `.`/`..` (also percent-encoded, once or twice), no backslash, no encoded
/// separator, no control character.
fn check_segment(segment: &str) -> Result<(), String> {
    if segment.is_empty() {
        return Err("empty path segment (`//`)".into());
    }
    if segment.chars().any(|c| c.is_control()) {
        return Err("control character in a path segment".into());
    }
    if segment.contains('\\') {
        return Err("backslash in a path segment".into());
    }
    // URL syntax: `LocalFileSystem` maps keys to files through a URL, where `?` and `#` would end the path
    // and let what precedes them (`%2e%2e?`) be read as a `..` segment.
    if segment.contains(['?', '#']) {
        return Err("`?` or `#` in a path segment".into());
    }
    // Decoded once and twice: a server or filesystem layer may decode what another layer encoded.
    let once = percent_decode(segment);
    let twice = percent_decode(&once);
    for decoded in [&once, &twice] {
        if decoded.contains('/') || decoded.contains('\\') {
            return Err(format!(
                "`{segment}` hides a path separator in percent-encoding"
            ));
        }
        if decoded == "." || decoded == ".." {
            return Err(format!("`{segment}` segments are not allowed"));
        }
    }
    Ok(())
}

/// `%XX` sequences decoded (invalid ones kept as they are); lossy outside UTF-8, which is enough to spot dots
/// and separators.
fn percent_decode(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' && i + 2 < b.len() {
            if let (Some(h), Some(l)) = (hex(b[i + 1]), hex(b[i + 2])) {
                out.push(h * 16 + l);
                i += 3;
                continue;
            }
        }
        out.push(b[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

fn hex(c: u8) -> Option<u8> {
    (c as char).to_digit(16).map(|d| d as u8)
}

/// A remote URI split into what confinement compares: `scheme://authority` and the path segments.
#[derive(Debug, Clone, PartialEq, Eq)]
struct RemoteName {
    origin: String,
    segments: Vec<String>,
}

/// Splits `scheme://authority/seg/seg` on the raw text (no URL normalisation) and checks every segment.
fn split_remote(uri: &str) -> Result<RemoteName, String> {
    let (scheme, rest) = uri
        .split_once("://")
        .ok_or_else(|| format!("`{uri}` is not a URI"))?;
    if rest.contains(['?', '#']) {
        return Err(format!(
            "`{uri}`: query strings and fragments are not part of a storage URI"
        ));
    }
    let (authority, path) = rest.split_once('/').unwrap_or((rest, ""));
    if authority.is_empty() {
        return Err(format!("`{uri}` names no bucket or host"));
    }
    let authority_ok = authority
        .chars()
        .all(|c| c.is_ascii_alphanumeric() || matches!(c, '.' | '-' | '_' | ':'));
    if !authority_ok {
        return Err(format!("`{uri}`: unexpected characters in `{authority}`"));
    }
    // One trailing slash names the same directory-like prefix.
    let path = path.strip_suffix('/').unwrap_or(path);
    let mut segments = Vec::new();
    if !path.is_empty() {
        for s in path.split('/') {
            check_segment(s).map_err(|e| format!("`{uri}`: {e}"))?;
            segments.push(s.to_string());
        }
    }
    Ok(RemoteName {
        origin: format!(
            "{}://{}",
            scheme.to_ascii_lowercase(),
            authority.to_ascii_lowercase()
        ),
        segments,
    })
}

/// Checks that a remote URI in a job spec has a clean path (no `..`, encoded separators, empty segments): such
/// URIs are refused whether or not storage roots are configured, since the URL parser would otherwise resolve
/// them silently to another location than the one written.
pub fn check_remote_uri(field: &str, uri: &str) -> Result<(), JobError> {
    if !uri.contains("://") || uri.starts_with("file://") {
        return Ok(());
    }
    split_remote(uri)
        .map(|_| ())
        .map_err(|e| JobError::spec(field, e))
}

#[derive(Debug, Clone, PartialEq, Eq)]
enum Root {
    /// Canonical path of a local root.
    Local(PathBuf),
    Remote(RemoteName),
}

/// The locations a coordinator accepts jobs for. Empty: anything goes (local single-user use).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct StorageRoots {
    roots: Vec<Root>,
    shown: Vec<String>,
}

impl StorageRoots {
    /// Parses the roots (`--storage-root`): local roots must exist (they are canonicalised now, once).
    pub fn new<S: AsRef<str>>(uris: &[S]) -> Result<Self, String> {
        let mut roots = StorageRoots::default();
        for uri in uris {
            let uri = uri.as_ref().trim();
            if uri.is_empty() {
                continue;
            }
            let root = if uri.contains("://") && !uri.starts_with("file://") {
                Root::Remote(split_remote(uri).map_err(|e| format!("storage root {e}"))?)
            } else {
                let path = match crate::storage::location::parse_location(uri, "storage root") {
                    Ok(crate::storage::location::Location::Local(p)) => p,
                    Ok(crate::storage::location::Location::Remote(_)) => {
                        return Err(format!("storage root `{uri}` is not a local path"))
                    }
                    Err(e) => return Err(e.to_string()),
                };
                let canonical = path
                    .canonicalize()
                    .map_err(|e| format!("storage root `{uri}`: {e} (local roots must exist)"))?;
                Root::Local(canonical)
            };
            roots.roots.push(root);
            roots.shown.push(uri.to_string());
        }
        Ok(roots)
    }

    pub fn is_empty(&self) -> bool {
        self.roots.is_empty()
    }

    /// Whether `uri` (from spec field `field`) lies under one of the roots; the error names the field.
    pub fn check(&self, field: &str, uri: &str) -> Result<(), JobError> {
        if self.roots.is_empty() {
            return Ok(());
        }
        let outside = || {
            JobError::spec(
                field,
                format!(
                    "`{uri}` is outside the storage roots this coordinator accepts ({})",
                    self.shown.join(", ")
                ),
            )
        };
        if uri.contains("://") && !uri.starts_with("file://") {
            let name = split_remote(uri).map_err(|e| JobError::spec(field, e))?;
            let inside = self.roots.iter().any(|r| match r {
                Root::Remote(root) => {
                    root.origin == name.origin && name.segments.starts_with(&root.segments)
                }
                Root::Local(_) => false,
            });
            return if inside { Ok(()) } else { Err(outside()) };
        }
        let path = match crate::storage::location::parse_location(uri, field)? {
            crate::storage::location::Location::Local(p) => p,
            crate::storage::location::Location::Remote(_) => return Err(outside()),
        };
        let canonical = canonical_lenient(&path).map_err(|e| JobError::spec(field, e))?;
        let inside = self.roots.iter().any(|r| match r {
            Root::Local(root) => canonical.starts_with(root),
            Root::Remote(_) => false,
        });
        if inside {
            Ok(())
        } else {
            Err(outside())
        }
    }

    /// Checks every location of a job (`(field, uri)` pairs, as `JobSpec::uris` lists them).
    pub fn check_all<'a>(
        &self,
        uris: impl IntoIterator<Item = (&'static str, &'a str)>,
    ) -> Result<(), JobError> {
        for (field, uri) in uris {
            self.check(field, uri)?;
        }
        Ok(())
    }
}

/// The canonical form of `path`, which need not exist yet (an output): its longest existing ancestor
/// canonicalised (resolving every symlink there), then the remaining components, which must be plain names.
fn canonical_lenient(path: &Path) -> Result<PathBuf, String> {
    if path
        .components()
        .any(|c| matches!(c, Component::ParentDir | Component::CurDir))
    {
        return Err(format!(
            "`{}`: `..` and `.` are not allowed in a confined path",
            path.display()
        ));
    }
    let mut existing = path.to_path_buf();
    let mut tail: Vec<std::ffi::OsString> = Vec::new();
    loop {
        match existing.canonicalize() {
            Ok(c) => {
                let mut out = c;
                for t in tail.iter().rev() {
                    out.push(t);
                }
                return Ok(out);
            }
            Err(_) => {
                let name = existing.file_name().map(|n| n.to_os_string());
                match (name, existing.parent()) {
                    (Some(n), Some(p)) => {
                        tail.push(n);
                        existing = p.to_path_buf();
                    }
                    _ => return Err(format!("`{}` cannot be resolved", path.display())),
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_that_leave_their_root_are_refused() {
        for bad in [
            "",
            "/etc/passwd",
            "..",
            "../x",
            "a/../../x",
            "a/./b",
            "a//b",
            "a/",
            "%2e%2e/x",
            "%2E%2e/x",
            "a%2f..%2fb",
            "a%2F..",
            "a\\..\\b",
            "..\\x",
            "%5c",
            "%252e%252e/x",
            "a/\u{0}b",
            ".%2e/x",
            "%2e%2e?/x",
            "x#/../y",
            ".\t./x",
        ] {
            assert!(check_key(bad).is_err(), "{bad:?} accepted");
        }
        for good in [
            "report.json",
            ".crease-work/weights/w0001/b00002.npy",
            "frame_0001.obj",
            "a..b/c...d",
            "100%",
        ] {
            check_key(good).unwrap_or_else(|e| panic!("{good:?}: {e}"));
        }
    }

    #[test]
    fn remote_roots_compare_whole_segments() {
        let roots = StorageRoots::new(&["s3://b/data", "memory://m/"]).unwrap();
        roots.check("output", "s3://b/data").unwrap();
        roots.check("output", "s3://b/data/").unwrap();
        roots.check("output", "s3://b/data/job/out").unwrap();
        roots.check("input", "memory://m/anything").unwrap();
        for bad in [
            "s3://b/data-evil",
            "s3://b/data-evil/x",
            "s3://b/dat",
            "s3://b",
            "s3://other/data/x",
            "s3://b/data/../secret",
            "s3://b/data/%2e%2e/secret",
            "s3://b/data/x%2f..%2f..%2fsecret",
            "s3://b/data//x",
            "s3://b/data/x?versionId=1",
            "/tmp/x",
            "memory://m2/x",
        ] {
            let e = roots.check("output", bad).unwrap_err().to_string();
            assert!(e.contains("`output`"), "{bad}: {e}");
        }
    }

    #[test]
    fn local_roots_compare_canonical_paths() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join("data");
        let outside = dir.path().join("data-evil");
        std::fs::create_dir_all(root.join("in")).unwrap();
        std::fs::create_dir_all(&outside).unwrap();
        #[cfg(unix)]
        std::os::unix::fs::symlink(&outside, root.join("escape")).unwrap();
        let roots = StorageRoots::new(&[root.display().to_string()]).unwrap();
        roots
            .check("input", &root.join("in").display().to_string())
            .unwrap();
        roots
            .check("output", &root.join("new/job").display().to_string())
            .unwrap();
        roots
            .check("output", &format!("file://{}", root.join("x").display()))
            .unwrap();
        for bad in [
            outside.join("x"),
            root.join("../data-evil/x"),
            root.join("in/../../data-evil"),
            #[cfg(unix)]
            root.join("escape/x"),
            #[cfg(unix)]
            root.join("escape"),
        ] {
            let bad = bad.display().to_string();
            let e = roots.check("output", &bad).unwrap_err().to_string();
            assert!(e.contains("`output`"), "{bad}: {e}");
        }
        assert!(roots.check("input", "s3://b/data").is_err());
        assert!(StorageRoots::new(&[dir.path().join("missing").display().to_string()]).is_err());
    }

    /// Property-style: random names built from the pieces path attacks are made of. Whatever `check_key`
    /// accepts, written through a local `Storage`, lands inside the root; nothing is ever created beside it.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn nasty_names_never_leave_the_root() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join("root");
        let storage = crate::storage::store::Storage::open(&root.display().to_string()).unwrap();
        let pieces = [
            ".",
            "..",
            "/",
            "\\",
            "%2e",
            "%2E",
            "%2f",
            "%2F",
            "%5c",
            "%252e",
            "%25",
            "%",
            "a",
            "b.obj",
            "~",
            " ",
            "\u{0}",
            "\n",
            ":",
            "*",
            "?",
            "#",
            "frame_0001.obj",
            ".crease-work",
            "é",
        ];
        let mut seed = 0x9e3779b97f4a7c15u64;
        let mut next = |n: usize| {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 33) as usize) % n
        };
        let (mut accepted, mut refused) = (0, 0);
        for _ in 0..2000 {
            let len = 1 + next(6);
            let name: String = (0..len).map(|_| pieces[next(pieces.len())]).collect();
            let ok = check_key(&name).is_ok();
            match storage.put(&name, b"x".to_vec()).await {
                Ok(()) => assert!(ok, "{name:?} was written although check_key refuses it"),
                // An accepted key may still fail as storage (a file where a directory is needed).
                Err(e) => assert!(ok || e.to_string().contains("invalid key"), "{name:?}: {e}"),
            }
            if ok {
                accepted += 1;
            } else {
                refused += 1;
            }
            if ok {
                // Lexically too: decoding and resolving the accepted key never climbs above the root.
                let mut depth = 0i32;
                for seg in percent_decode(&percent_decode(&name)).split('/') {
                    match seg {
                        ".." => depth -= 1,
                        "." | "" => {}
                        _ => depth += 1,
                    }
                    assert!(depth >= 0, "{name:?} climbs out");
                }
            }
        }
        assert!(
            accepted > 50 && refused > 50,
            "{accepted} accepted, {refused} refused"
        );
        for entry in std::fs::read_dir(dir.path()).unwrap() {
            assert_eq!(
                entry.unwrap().path(),
                root,
                "something was created beside the root"
            );
        }
        // Keys built from task and frame numbers are plain keys for any number.
        for n in [0usize, 1, 9999, 1 << 20, usize::MAX] {
            for key in [
                crate::storage::keys::fold_chunk(n),
                crate::storage::keys::fold_chunk_timing(n),
                crate::storage::keys::block_partial(n, n),
                crate::storage::keys::window_field(n, n),
                crate::storage::keys::window_stats(n),
                crate::storage::keys::positions(n),
                crate::storage::keys::frame_stretch(n),
                crate::storage::keys::frame_timings(n),
            ] {
                check_key(&key).unwrap_or_else(|e| panic!("{key}: {e}"));
            }
        }
    }
}

//! Inputs, intermediates and outputs through `object_store` URLs (bulk data travels through object storage;
//! gRPC carries only task descriptions and small results).
//!
//! A [`Storage`] is a directory-like root (the job's output location, an input directory) addressed by a URI:
//! a plain path, `file://…`, or any scheme `object_store` was built with. Objects under it are named by
//! relative keys (`report.json`, `.crease-work/weights/w0003.npy`). Keys are deterministic functions of the job
//! and the task (see [`crate::storage::keys`]), so a task that runs twice writes the same object twice, with the same
//! bytes. `put` is atomic on every backend: `LocalFileSystem` stages into a temporary file and renames it, object
//! stores publish whole objects, so a reader never sees half an object under a final key.

use super::location::{parse_location, remote_store, Location};
use crate::error::JobError;
use bytes::Bytes;
use futures::TryStreamExt;
use object_store::local::LocalFileSystem;
use object_store::path::Path as ObjectPath;
use object_store::{ObjectStore, ObjectStoreExt, PutPayload};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A storage root: an object store plus the prefix of the root inside it.
#[derive(Clone)]
pub struct Storage {
    uri: String,
    store: Arc<dyn ObjectStore>,
    prefix: ObjectPath,
    local: Option<PathBuf>,
}

impl std::fmt::Debug for Storage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Storage").field("uri", &self.uri).finish()
    }
}

impl Storage {
    /// Opens the root at `uri`. A local root is created if it does not exist (outputs); use
    /// [`Storage::open_existing`] for inputs.
    pub fn open(uri: &str) -> Result<Self, JobError> {
        Self::open_inner(uri, true)
    }

    /// Opens the root at `uri`, which must already exist when local.
    pub fn open_existing(uri: &str) -> Result<Self, JobError> {
        Self::open_inner(uri, false)
    }

    fn open_inner(uri: &str, create: bool) -> Result<Self, JobError> {
        match parse_location(uri, "uri")? {
            Location::Local(dir) => {
                if create {
                    std::fs::create_dir_all(&dir).map_err(|e| {
                        JobError::storage(uri, format!("cannot create {}: {e}", dir.display()))
                    })?;
                }
                if !dir.is_dir() {
                    return Err(JobError::storage(
                        uri,
                        format!("{} is not a directory", dir.display()),
                    ));
                }
                let store = LocalFileSystem::new_with_prefix(&dir)
                    .map_err(|e| JobError::storage(uri, e))?;
                Ok(Storage {
                    uri: uri.to_string(),
                    store: Arc::new(store),
                    prefix: ObjectPath::default(),
                    local: Some(dir),
                })
            }
            Location::Remote(url) => {
                let (store, prefix) =
                    remote_store(&url).map_err(|e| JobError::storage_failure(uri, &e))?;
                Ok(Storage {
                    uri: uri.to_string(),
                    store,
                    prefix,
                    local: None,
                })
            }
        }
    }

    pub fn uri(&self) -> &str {
        &self.uri
    }

    /// The root as a local directory, when it is one (crease-core then reads and writes it directly).
    pub fn local_path(&self) -> Option<&Path> {
        self.local.as_deref()
    }

    /// Removes the staging files that puts killed half way left under a local root (`LocalFileSystem` writes
    /// `key#N` and renames it; a worker killed in between leaves `key#N` behind, and no other file can have that
    /// name: keys with `#` are refused). Called by the job's last task, when no live attempt writes under the
    /// root any more (an abandoned attempt that still does loses its rename and fails, which is harmless: its
    /// bytes were the same). Returns the files removed; a remote root has none to remove.
    pub fn remove_put_leftovers(&self) -> std::io::Result<Vec<PathBuf>> {
        let mut removed = Vec::new();
        if let Some(root) = &self.local {
            remove_put_leftovers_under(root, &mut removed)?;
        }
        Ok(removed)
    }

    /// `uri/key`, for messages.
    pub fn describe(&self, key: &str) -> String {
        format!("{}/{}", self.uri.trim_end_matches('/'), key)
    }

    /// The object path of `key` under the root. Keys are relative and cannot leave the root (see
    /// [`crate::storage::confine::check_key`]); a key that tries is refused, not normalised.
    fn path(&self, key: &str) -> Result<ObjectPath, JobError> {
        crate::storage::confine::check_key(key)
            .map_err(|e| JobError::storage(self.describe(key), format!("invalid key: {e}")))?;
        let rel = ObjectPath::parse(key)
            .map_err(|e| JobError::storage(self.describe(key), format!("invalid key: {e}")))?;
        Ok(self.prefix.parts().chain(rel.parts()).collect())
    }

    /// Reads the whole object at `key`.
    pub async fn get(&self, key: &str) -> Result<Bytes, JobError> {
        let path = self.path(key)?;
        let got = self
            .store
            .get(&path)
            .await
            .map_err(|e| JobError::storage_failure(self.describe(key), &e))?;
        got.bytes()
            .await
            .map_err(|e| JobError::storage_failure(self.describe(key), &e))
    }

    /// Writes `bytes` to `key` atomically (replacing any previous object).
    pub async fn put(&self, key: &str, bytes: impl Into<Bytes>) -> Result<(), JobError> {
        let path = self.path(key)?;
        self.store
            .put(&path, PutPayload::from(bytes.into()))
            .await
            .map_err(|e| JobError::storage_failure(self.describe(key), &e))?;
        Ok(())
    }

    /// Reads `key` of a local root on the calling thread; `None` for a remote root or a key with characters
    /// outside `[A-Za-z0-9._/-]` (which [`Storage::get`] handles).
    ///
    /// Why: a task runs on a blocking thread and reaches the async [`Storage::get`] through `block_on`, and
    /// `LocalFileSystem` then hands the read to yet another blocking thread. For the many small objects of a
    /// per-anchor job (a partial blend per block, read back by the reduce) those hand-offs cost more than the
    /// I/O on a loaded machine. The bytes and errors are the same: a missing object is a storage error naming
    /// the key, a full disk "storage full at …".
    pub fn get_local(&self, key: &str) -> Option<Result<Bytes, JobError>> {
        let path = self.local_file(key)?;
        Some(
            std::fs::read(&path)
                .map(Bytes::from)
                .map_err(|e| JobError::storage_failure(self.describe(key), &e)),
        )
    }

    /// Writes `key` of a local root on the calling thread, atomically as `LocalFileSystem` does (a staging
    /// file `key#N` renamed over the key, removed on failure; [`Storage::remove_put_leftovers`] sweeps those a
    /// killed worker left); `None` for a remote root or a key [`Storage::get_local`] does not take.
    pub fn put_local(&self, key: &str, bytes: &[u8]) -> Option<Result<(), JobError>> {
        let path = self.local_file(key)?;
        Some(
            write_staged(&path, bytes)
                .map_err(|e| JobError::storage_failure(self.describe(key), &e)),
        )
    }

    /// The file of `key` under a local root, for the keys the job's own tasks name (plain ASCII, confined).
    fn local_file(&self, key: &str) -> Option<PathBuf> {
        let root = self.local.as_ref()?;
        let plain = !key.is_empty()
            && key
                .bytes()
                .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'.' | b'_' | b'/' | b'-'));
        (plain && crate::storage::confine::check_key(key).is_ok()).then(|| root.join(key))
    }

    /// Uploads the local file `file` to `key`. Files of at least `CREASE_STORAGE_MULTIPART_MIB` (default 64)
    /// going to a remote store are streamed in parts of that size instead of read whole into memory (a point
    /// cache of a long take can be gigabytes; S3 takes at most 5 GiB in one PUT). A multipart upload that
    /// fails is aborted, and S3 publishes the object only when the upload completes, so the key never holds
    /// part of the file.
    pub async fn put_file(&self, key: &str, file: &Path) -> Result<(), JobError> {
        let path = self.path(key)?;
        let read_err = |e: std::io::Error| {
            JobError::storage_failure(format!("{} (upload source)", file.display()), &e)
        };
        let len = std::fs::metadata(file).map_err(read_err)?.len();
        let part = multipart_part_bytes();
        if self.local.is_some() || len < part as u64 {
            let bytes = std::fs::read(file).map_err(read_err)?;
            return self.put(key, bytes).await;
        }
        let fail = |e: object_store::Error| JobError::storage_failure(self.describe(key), &e);
        let upload = self.store.put_multipart(&path).await.map_err(fail)?;
        let mut writer = object_store::WriteMultipart::new_with_chunk_size(upload, part);
        let streamed: Result<(), JobError> = async {
            use std::io::Read;
            let mut f = std::fs::File::open(file).map_err(read_err)?;
            let mut buf = vec![0u8; part.min(8 << 20)];
            loop {
                let n = f.read(&mut buf).map_err(read_err)?;
                if n == 0 {
                    return Ok(());
                }
                writer.wait_for_capacity(4).await.map_err(fail)?;
                writer.write(&buf[..n]);
            }
        }
        .await;
        match streamed {
            Ok(()) => writer.finish().await.map(|_| ()).map_err(fail),
            Err(e) => {
                let _ = writer.abort().await;
                Err(e)
            }
        }
    }

    /// Whether an object exists at `key`.
    pub async fn exists(&self, key: &str) -> Result<bool, JobError> {
        let path = self.path(key)?;
        match self.store.head(&path).await {
            Ok(_) => Ok(true),
            Err(object_store::Error::NotFound { .. }) => Ok(false),
            Err(e) => Err(JobError::storage_failure(self.describe(key), &e)),
        }
    }

    /// Removes the object at `key`; a missing object is not an error.
    pub async fn delete(&self, key: &str) -> Result<(), JobError> {
        let path = self.path(key)?;
        match self.store.delete(&path).await {
            Ok(()) | Err(object_store::Error::NotFound { .. }) => Ok(()),
            Err(e) => Err(JobError::storage_failure(self.describe(key), &e)),
        }
    }

    /// Keys (relative to the root, sorted) of every object under `key_prefix` (`""` for all).
    pub async fn list(&self, key_prefix: &str) -> Result<Vec<String>, JobError> {
        let prefix = if key_prefix.is_empty() {
            self.prefix.clone()
        } else {
            self.path(key_prefix)?
        };
        let root_parts = self.prefix.parts().count();
        let metas: Vec<_> = self
            .store
            .list(Some(&prefix))
            .try_collect()
            .await
            .map_err(|e| JobError::storage_failure(self.describe(key_prefix), &e))?;
        let mut keys: Vec<String> = metas
            .into_iter()
            .map(|m| {
                m.location
                    .parts()
                    .skip(root_parts)
                    .map(|p| p.as_ref().to_string())
                    .collect::<Vec<_>>()
                    .join("/")
            })
            .collect();
        keys.sort();
        Ok(keys)
    }
}

/// Makes the input at `uri` readable by crease-core from a local path. A local input is used in place (no
/// copy); a remote one is downloaded once into `cache_dir/<hash of the URI>/` (objects already there and
/// unchanged — same size, modification time and e-tag — are kept) and the local copy's path is returned. Works
/// for directories and single files (a `.pc2` is fetched with its sibling `.obj`).
pub async fn fetch_input_to_cache(uri: &str, cache_dir: &Path) -> Result<PathBuf, JobError> {
    match parse_location(uri, "input")? {
        Location::Local(p) => Ok(p),
        Location::Remote(url) => {
            let local = cache_dir.join(format!("{:016x}", fnv1a(url.as_str().as_bytes())));
            let (store, prefix) = remote_store(&url).map_err(|e| input_err(uri, &e))?;
            let (metas, base_parts, single) =
                list_input_objects(store.as_ref(), &prefix, uri).await?;
            if metas.is_empty() {
                return Err(JobError::input(uri, "no such object or directory"));
            }
            for m in &metas {
                let rel_key = m
                    .location
                    .parts()
                    .skip(base_parts)
                    .map(|p| p.as_ref().to_string())
                    .collect::<Vec<_>>()
                    .join("/");
                // A listed name is data from the store: it must stay inside this input's cache directory.
                crate::storage::confine::check_key(&rel_key).map_err(|e| {
                    JobError::input(uri, format!("object `{rel_key}` cannot be cached: {e}"))
                })?;
                let dest = local.join(&rel_key);
                // A cached copy is reused only if the object is unchanged: size, modification time and
                // e-tag are recorded in a hidden sidecar (hidden files are not part of a sequence).
                let stamp = format!("{} {} {:?}", m.size, m.last_modified.to_rfc3339(), m.e_tag);
                let sidecar = dest.with_file_name(format!(
                    ".{}.crease-cache",
                    dest.file_name().unwrap_or_default().to_string_lossy()
                ));
                if dest.is_file() && std::fs::read_to_string(&sidecar).is_ok_and(|s| s == stamp) {
                    continue;
                }
                let bytes = store
                    .get(&m.location)
                    .await
                    .map_err(|e| input_err(uri, &e))?
                    .bytes()
                    .await
                    .map_err(|e| input_err(uri, &e))?;
                if let Some(parent) = dest.parent() {
                    std::fs::create_dir_all(parent).map_err(|e| cache_err(uri, parent, &e))?;
                }
                crease_core::fsutil::write_atomic(&dest, &bytes)
                    .and_then(|()| crease_core::fsutil::write_atomic(&sidecar, stamp.as_bytes()))
                    .map_err(|e| cache_err(uri, &dest, &e))?;
            }
            Ok(if single {
                local.join(prefix.filename().unwrap_or_default())
            } else {
                local
            })
        }
    }
}

/// Part size of multipart uploads and the size from which they are used: `CREASE_STORAGE_MULTIPART_MIB`
/// (default 64, at least 5, S3's smallest part).
fn multipart_part_bytes() -> usize {
    let mib = std::env::var("CREASE_STORAGE_MULTIPART_MIB")
        .ok()
        .and_then(|v| v.trim().parse::<usize>().ok())
        .unwrap_or(64)
        .clamp(5, 4096);
    mib << 20
}

/// A failure reading the input at `uri`: unreachable or full storage named as such, anything else an input error.
fn input_err(uri: &str, e: &(dyn std::error::Error + 'static)) -> JobError {
    JobError::input_failure(uri, e)
}

/// A failure writing the worker's cache while fetching `uri` (a full local disk is "storage full at <cache>").
fn cache_err(uri: &str, path: &Path, e: &(dyn std::error::Error + 'static)) -> JobError {
    match super::errors::kind(e) {
        super::errors::Kind::Full => {
            JobError::storage_failure(format!("{} (worker cache)", path.display()), e)
        }
        _ => JobError::input(uri, format!("cache {}: {e}", path.display())),
    }
}

/// Total size in bytes of the input at `uri` as [`fetch_input_to_cache`] would fetch it (a directory's
/// objects, or a file with its same-stem siblings), found from metadata alone so that a job too large for
/// the coordinator's `--max-job-input-mib` is refused before anything is downloaded.
pub async fn input_size(uri: &str) -> Result<u64, JobError> {
    match parse_location(uri, "input")? {
        Location::Local(p) => {
            let meta = std::fs::metadata(&p).map_err(|e| JobError::input(uri, e))?;
            if meta.is_dir() {
                let mut total = 0;
                for entry in std::fs::read_dir(&p).map_err(|e| JobError::input(uri, e))? {
                    let entry = entry.map_err(|e| JobError::input(uri, e))?;
                    let m = entry.metadata().map_err(|e| JobError::input(uri, e))?;
                    if m.is_file() {
                        total += m.len();
                    }
                }
                return Ok(total);
            }
            let stem = p.file_stem().map(|s| s.to_os_string());
            let mut total = meta.len();
            if let (Some(dir), Some(stem)) = (p.parent(), stem) {
                for entry in std::fs::read_dir(dir).map_err(|e| JobError::input(uri, e))? {
                    let entry = entry.map_err(|e| JobError::input(uri, e))?;
                    let q = entry.path();
                    if q != p && q.file_stem() == Some(stem.as_os_str()) && q.is_file() {
                        total += entry.metadata().map(|m| m.len()).unwrap_or(0);
                    }
                }
            }
            Ok(total)
        }
        Location::Remote(url) => {
            let (store, prefix) = remote_store(&url).map_err(|e| input_err(uri, &e))?;
            let (metas, _, _) = list_input_objects(store.as_ref(), &prefix, uri).await?;
            Ok(metas.iter().map(|m| m.size).sum())
        }
    }
}

/// The objects that make up the remote input at `prefix`: everything under it (a directory) or, for a single
/// object (a file URI), the objects of the same stem beside it, so a `.pc2` travels with its `.obj`. Returns
/// them (possibly none) with the number of leading path parts that make keys relative to the input, and whether
/// it was a single object.
async fn list_input_objects(
    store: &dyn ObjectStore,
    prefix: &ObjectPath,
    uri: &str,
) -> Result<(Vec<object_store::ObjectMeta>, usize, bool), JobError> {
    let parts = prefix.parts().count();
    let metas: Vec<_> = store
        .list(Some(prefix))
        .try_collect()
        .await
        .map_err(|e| input_err(uri, &e))?;
    if !metas.is_empty() {
        return Ok((metas, parts, false));
    }
    let parent: ObjectPath = prefix.parts().take(parts.saturating_sub(1)).collect();
    let stem = prefix
        .filename()
        .and_then(|f| f.rsplit_once('.').map(|(s, _)| s.to_string()))
        .unwrap_or_default();
    let all: Vec<_> = store
        .list(Some(&parent))
        .try_collect()
        .await
        .map_err(|e| input_err(uri, &e))?;
    let same_stem = all
        .into_iter()
        .filter(|m| {
            m.location.parts().count() == parts
                && m.location
                    .filename()
                    .is_some_and(|f| f.rsplit_once('.').map(|(s, _)| s) == Some(&stem))
        })
        .collect();
    Ok((same_stem, parts.saturating_sub(1), true))
}

/// FNV-1a, to name cache directories after URIs without a hashing dependency (stable across processes, unlike
/// `DefaultHasher`'s contract).
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf29ce484222325u64, |h, &b| {
        (h ^ b as u64).wrapping_mul(0x100000001b3)
    })
}

/// Writes `bytes` to `path` through a staging file `path#N` (the first N free, parents created as needed)
/// renamed over it: what `LocalFileSystem::put` does, without its hop to another thread. The staging file is
/// removed when the write or the rename fails.
fn write_staged(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    use std::io::Write;
    let mut n = 1u32;
    let mut made_parents = false;
    let (mut file, staging) = loop {
        let mut name = path.as_os_str().to_owned();
        name.push(format!("#{n}"));
        let staging = PathBuf::from(name);
        match std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&staging)
        {
            Ok(f) => break (f, staging),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => n += 1,
            // The key's directories do not exist yet: made once (a directory that vanishes again is an error).
            Err(e) if e.kind() == std::io::ErrorKind::NotFound && !made_parents => {
                let dir = path.parent().ok_or(e)?;
                std::fs::create_dir_all(dir)?;
                made_parents = true;
            }
            Err(e) => return Err(e),
        }
    };
    let written = file
        .write_all(bytes)
        .and_then(|()| std::fs::rename(&staging, path));
    if written.is_err() {
        let _ = std::fs::remove_file(&staging);
    }
    written
}

/// Whether `name` is a `LocalFileSystem` staging name: `key#N`, N decimal.
fn is_put_leftover(name: &str) -> bool {
    name.rsplit_once('#').is_some_and(|(key, n)| {
        !key.is_empty() && !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit())
    })
}

fn remove_put_leftovers_under(dir: &Path, removed: &mut Vec<PathBuf>) -> std::io::Result<()> {
    let entries = match std::fs::read_dir(dir) {
        Ok(e) => e,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(e),
    };
    for e in entries {
        let e = e?;
        let kind = e.file_type()?;
        let path = e.path();
        if kind.is_dir() {
            remove_put_leftovers_under(&path, removed)?;
        } else if kind.is_file() && is_put_leftover(&e.file_name().to_string_lossy()) {
            match std::fs::remove_file(&path) {
                Ok(()) => removed.push(path),
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                Err(e) => return Err(e),
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod put_leftover_tests {
    use super::*;

    #[test]
    fn only_staging_names_are_leftovers() {
        assert!(is_put_leftover("report.json#1"));
        assert!(is_put_leftover("frame_0003.obj#12"));
        assert!(!is_put_leftover("report.json"));
        assert!(!is_put_leftover("report.json#"));
        assert!(!is_put_leftover("#1"));
        assert!(!is_put_leftover("a#b"));
    }

    #[test]
    fn a_killed_put_leaves_nothing_after_the_sweep() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path();
        std::fs::create_dir_all(root.join(".crease-work/weights")).unwrap();
        for f in [
            "report.json#1",
            "frame_0001.obj",
            "frame_0001.obj#2",
            ".crease-work/weights/w0.npy#1",
        ] {
            std::fs::write(root.join(f), b"x").unwrap();
        }
        let storage = Storage::open(root.to_str().unwrap()).unwrap();
        let mut removed = storage.remove_put_leftovers().unwrap();
        removed.sort();
        assert_eq!(removed.len(), 3, "{removed:?}");
        assert!(root.join("frame_0001.obj").exists());
        assert!(!root.join("report.json#1").exists());
        assert!(!root.join(".crease-work/weights/w0.npy#1").exists());
    }
}

#[cfg(test)]
mod local_tests {
    use super::*;

    /// The thread-local path reads and writes what the object store path does, under the same names, and says
    /// which object is missing.
    #[tokio::test(flavor = "multi_thread", worker_threads = 1)]
    async fn local_reads_and_writes_match_the_object_store() {
        let dir = tempfile::tempdir().unwrap();
        let storage = Storage::open(dir.path().to_str().unwrap()).unwrap();
        let key = ".crease-work/weights/w0001/b00002.bin";
        storage.put_local(key, b"abc").unwrap().unwrap();
        assert_eq!(&storage.get(key).await.unwrap()[..], b"abc");
        storage.put(key, &b"defg"[..]).await.unwrap();
        assert_eq!(&storage.get_local(key).unwrap().unwrap()[..], b"defg");
        // Overwrites replace the whole object and leave no staging file.
        storage.put_local(key, b"h").unwrap().unwrap();
        assert_eq!(std::fs::read(dir.path().join(key)).unwrap(), b"h");
        assert!(storage.remove_put_leftovers().unwrap().is_empty());
        let missing = storage
            .get_local(".crease-work/nothing.bin")
            .unwrap()
            .unwrap_err()
            .to_string();
        assert!(missing.contains(".crease-work/nothing.bin"), "{missing}");
        // A parent that is a file is an error naming the key, and nothing is left beside it.
        std::fs::write(dir.path().join("blocked"), b"file").unwrap();
        let e = storage
            .put_local("blocked/x.npy", b"1")
            .unwrap()
            .unwrap_err();
        assert!(e.to_string().contains("blocked/x.npy"), "{e}");
        // Keys the fast path does not take go through the object store (which refuses or maps them).
        assert!(storage.put_local("a b.obj", b"1").is_none());
        assert!(storage.get_local("../x").is_none());
        let remote = Storage::open("memory://local-tests/out").unwrap();
        assert!(remote.put_local("x.npy", b"1").is_none());
        assert!(remote.get_local("x.npy").is_none());
    }
}

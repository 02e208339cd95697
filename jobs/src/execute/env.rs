//! What every task opens the same way: the job's output storage, its input sequence and its anchors.

use super::{frame_cache, ExecContext};
use crate::error::{JobError, TaskError};
use crate::spec::{FoldSpec, JobSpec};
use crate::storage::keys;
use crate::storage::store::{fetch_input_to_cache, Storage};
use bytes::Bytes;
use crease_core::folds::AnchorSet;
use crease_core::mesh::io::{detect_layout, open_layout, OpenedSequence};
use crease_core::mesh::subdivide::SubdividedSource;
use crease_core::mesh::FrameSource;
use crease_core::npy::{self, NpyElement};
use crease_core::progress::Progress;
use crease_core::spacetime::windows::Window;
use crease_core::spacetime::DeformParams;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// Recently parsed anchors files (see [`TaskEnv::anchors`]).
#[allow(clippy::type_complexity)]
static ANCHORS: Mutex<Vec<(PathBuf, u64, Arc<AnchorSet>)>> = Mutex::new(Vec::new());

/// Recently read detected anchors (see [`TaskEnv::anchors`]), keyed by the stored file and a hash of its bytes.
#[allow(clippy::type_complexity)]
static DETECTED: Mutex<Vec<(PathBuf, u64, Arc<AnchorSet>)>> = Mutex::new(Vec::new());

/// Size and modification time of a file, hashed: what the per-process caches key on.
fn file_stamp(path: &Path) -> u64 {
    let m = std::fs::metadata(path).ok();
    let len = m.as_ref().map_or(0, |m| m.len());
    let mtime = m
        .and_then(|m| m.modified().ok())
        .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
        .map_or(0, |d| d.as_nanos() as u64);
    fnv(&[len.to_le_bytes(), mtime.to_le_bytes()].concat())
}

/// Recently opened inputs (see [`TaskEnv::open_input`]).
#[allow(clippy::type_complexity)]
static OPENED: Mutex<Vec<(PathBuf, u64, Arc<OpenedSequence>)>> = Mutex::new(Vec::new());

/// A task's view of its job, used from the blocking thread the task runs on.
pub struct TaskEnv<'a> {
    pub job: &'a JobSpec,
    pub params: DeformParams,
    pub out: Storage,
    pub ctx: &'a ExecContext,
    handle: tokio::runtime::Handle,
}

/// Storage and input problems may pass (a flaky mount, a store outage): retryable; full storage is not
/// (see [`TaskError::from_job`]).
pub fn storage_err(e: JobError) -> TaskError {
    TaskError::from_job(&e)
}

impl<'a> TaskEnv<'a> {
    pub fn new(
        job: &'a JobSpec,
        ctx: &'a ExecContext,
        handle: tokio::runtime::Handle,
    ) -> Result<Self, TaskError> {
        let out = Storage::open(&job.output).map_err(storage_err)?;
        Ok(TaskEnv {
            job,
            params: job.params(),
            out,
            ctx,
            handle,
        })
    }

    pub fn progress(&self) -> &dyn Progress {
        self.ctx.progress.as_ref()
    }

    /// Stops with [`TaskError::cancelled`] when the worker or the job asked to stop.
    pub fn check_cancelled(&self) -> Result<(), TaskError> {
        if self.ctx.progress.cancelled() {
            Err(TaskError::cancelled())
        } else {
            Ok(())
        }
    }

    /// Reads `key` of the job's output (a local output on this thread: see [`Storage::get_local`]).
    pub fn get(&self, key: &str) -> Result<Bytes, TaskError> {
        match self.out.get_local(key) {
            Some(r) => r,
            None => self.handle.block_on(self.out.get(key)),
        }
        .map_err(storage_err)
    }

    /// Writes `key` of the job's output atomically (a local output on this thread: see
    /// [`Storage::put_local`]).
    pub fn put(&self, key: &str, bytes: impl Into<Bytes>) -> Result<(), TaskError> {
        let bytes = bytes.into();
        match self.out.put_local(key, &bytes) {
            Some(r) => r,
            None => self.handle.block_on(self.out.put(key, bytes)),
        }
        .map_err(storage_err)
    }

    pub fn delete(&self, key: &str) -> Result<(), TaskError> {
        self.handle
            .block_on(self.out.delete(key))
            .map_err(storage_err)
    }

    pub fn block_on<F: std::future::Future>(&self, f: F) -> F::Output {
        self.handle.block_on(f)
    }

    /// Writes an array as `.npy` under `key`.
    pub fn put_npy<T: NpyElement>(
        &self,
        key: &str,
        shape: &[usize],
        data: &[T],
    ) -> Result<(), TaskError> {
        self.put(key, npy::to_bytes(shape, data))
    }

    /// Reads an `.npy` array written by a dependency; a malformed one is fatal (it would be read again as is).
    pub fn get_npy<T: NpyElement>(&self, key: &str) -> Result<(Vec<usize>, Vec<T>), TaskError> {
        let bytes = self.get(key)?;
        npy::from_bytes::<T>(Path::new(&self.out.describe(key)), &bytes)
            .map_err(|e| TaskError::fatal(e.to_string()))
    }

    /// Reads a JSON sidecar written by a dependency.
    pub fn get_json<T: serde::de::DeserializeOwned>(&self, key: &str) -> Result<T, TaskError> {
        let bytes = self.get(key)?;
        serde_json::from_slice(&bytes)
            .map_err(|e| TaskError::fatal(format!("{}: malformed: {e}", self.out.describe(key))))
    }

    pub fn put_json<T: serde::Serialize>(&self, key: &str, value: &T) -> Result<(), TaskError> {
        let text = serde_json::to_vec_pretty(value)
            .map_err(|e| TaskError::fatal(format!("{}: {e}", self.out.describe(key))))?;
        self.put(key, text)
    }

    /// Local path of the input sequence (remote inputs are fetched into the cache once).
    pub fn input_path(&self) -> Result<PathBuf, TaskError> {
        self.block_on(fetch_input_to_cache(&self.job.input, &self.ctx.cache_dir))
            .map_err(storage_err)
    }

    /// Local copies of the detector's own input files (cameras, images), fetched once into the cache.
    pub fn fold_inputs(&self) -> Result<crate::plan::detect::FoldInputs, TaskError> {
        self.block_on(crate::plan::detect::fetch_fold_inputs(
            &self.job.folds,
            &self.ctx.cache_dir,
        ))
        .map_err(storage_err)
    }

    /// Opens the input sequence (topology read and validated; frames are read on demand, then kept up to the
    /// frame cache's budget; midpoint-subdivided when the job says so). The tasks of a job
    /// running on one worker share the opened input through a small per-process cache, keyed by the input's
    /// path and the size and modification time of each of its files, so an input changed in place is reopened.
    pub fn open_input(&self) -> Result<Arc<OpenedSequence>, TaskError> {
        let path = self.input_path()?;
        let err = |e| TaskError::from_core(&format!("input {}", self.job.input), e);
        let layout = detect_layout(&path).map_err(err)?;
        let levels = self.job.folds.subdivide();
        let stamp = layout
            .input_files()
            .iter()
            .fold(0xcbf29ce484222325u64 ^ levels as u64, |h, f| {
                (h ^ file_stamp(f)).wrapping_mul(0x100000001b3)
            });
        let mut cache = OPENED.lock().unwrap_or_else(|p| p.into_inner());
        if let Some((_, _, o)) = cache.iter().find(|(p, s, _)| *p == path && *s == stamp) {
            return Ok(o.clone());
        }
        // Parsed frames are kept with the opened input, so the tasks of a job on this worker parse each frame
        // once (see `frame_cache`); a changed input is reopened above, with an empty cache. A subdividing job
        // keeps both its input frames (what stretch detection reads through `subdivided_from`) and its
        // subdivided frames (what the deformation reads).
        let cached = |s: Box<dyn FrameSource>| -> Box<dyn FrameSource> {
            if frame_cache::budget() > 0 {
                Box::new(frame_cache::CachedFrames::new(s))
            } else {
                s
            }
        };
        let mut source = cached(open_layout(&layout).map_err(err)?);
        // Subdivision happens here and nowhere else, so every task of a subdividing job (detection, weights,
        // positioning, finalize) sees the same subdivided sequence.
        if levels > 0 {
            source = cached(Box::new(
                SubdividedSource::owned(source, levels).map_err(err)?,
            ));
        }
        let opened = Arc::new(OpenedSequence { source, layout });
        cache.insert(0, (path, stamp, opened.clone()));
        cache.truncate(2);
        Ok(opened)
    }

    /// The job's anchors: none, the anchors file, or the detected `anchors.json`.
    pub fn anchors(&self, n_frames: usize, n_triangles: usize) -> Result<AnchorSet, TaskError> {
        match &self.job.folds {
            FoldSpec::None => Ok(AnchorSet::empty(n_frames)),
            FoldSpec::Anchors { uri } => {
                let path = self
                    .block_on(fetch_input_to_cache(uri, &self.ctx.cache_dir))
                    .map_err(storage_err)?;
                // The weight tasks of a job on one worker parse the file once (keyed like the input cache).
                let stamp = file_stamp(&path) ^ ((n_frames as u64) << 32) ^ n_triangles as u64;
                let mut cache = ANCHORS.lock().unwrap_or_else(|p| p.into_inner());
                if let Some((_, _, a)) = cache.iter().find(|(p, s, _)| *p == path && *s == stamp) {
                    return Ok(AnchorSet::clone(a));
                }
                let set = AnchorSet::read(&path, n_frames, n_triangles)
                    .map_err(|e| TaskError::from_core(&format!("anchors {uri}"), e))?;
                cache.insert(0, (path, stamp, Arc::new(set.clone())));
                cache.truncate(2);
                Ok(set)
            }
            #[allow(unreachable_patterns)]
            _ => {
                let (bytes, stamp) = self.detected_anchors_bytes()?;
                let label = PathBuf::from(self.out.describe(keys::ANCHORS_BIN));
                let stamp = stamp ^ ((n_frames as u64) << 32) ^ n_triangles as u64;
                // Keyed by the stored bytes' hash, not a time: object stores have none worth trusting.
                let mut cache = DETECTED.lock().unwrap_or_else(|p| p.into_inner());
                if let Some((_, _, a)) = cache.iter().find(|(p, s, _)| *p == label && *s == stamp) {
                    return Ok(AnchorSet::clone(a));
                }
                let set = AnchorSet::from_binary(&bytes, &label, n_frames, n_triangles)
                    .map_err(|e| TaskError::fatal(format!("detected anchors: {e}")))?;
                cache.insert(0, (label, stamp, Arc::new(set.clone())));
                cache.truncate(2);
                Ok(set)
            }
        }
    }

    /// The binary detected anchors `fold-merge` stored, and a hash of their bytes.
    fn detected_anchors_bytes(&self) -> Result<(Bytes, u64), TaskError> {
        let bytes = self.get(keys::ANCHORS_BIN)?;
        let stamp = fnv_words(&bytes);
        Ok((bytes, stamp))
    }

    /// A fingerprint of the job's anchors as they are now: the anchors file's size and modification time, or
    /// the bytes of the detected anchors (what the window cache keys on besides the spec and input).
    pub fn anchors_fingerprint(&self) -> Result<u64, TaskError> {
        match &self.job.folds {
            FoldSpec::None => Ok(0),
            FoldSpec::Anchors { uri } => {
                let path = self
                    .block_on(fetch_input_to_cache(uri, &self.ctx.cache_dir))
                    .map_err(storage_err)?;
                Ok(file_stamp(&path))
            }
            #[allow(unreachable_patterns)]
            _ => Ok(self.detected_anchors_bytes()?.1),
        }
    }

    /// The job's time windows over `n` frames.
    pub fn windows(&self, n: usize) -> Vec<Window> {
        crate::plan::chunks::job_windows(self.job, n)
    }

    /// Window `k` of `n` frames, or a fatal error naming it.
    pub fn window(&self, n: usize, k: usize) -> Result<(Vec<Window>, Window), TaskError> {
        let windows = self.windows(n);
        let w = *windows.get(k).ok_or_else(|| {
            TaskError::fatal(format!(
                "window {k} does not exist: the job has {} windows over {n} frames",
                windows.len()
            ))
        })?;
        Ok((windows, w))
    }
}

/// A local directory where a task writes output files with crease-core: the output itself when it is local,
/// or a staging directory in the cache whose files [`OutputDir::upload`] copies to the remote output.
pub struct OutputDir {
    pub path: PathBuf,
    staged: bool,
}

impl TaskEnv<'_> {
    /// The directory `stage` writes output files into (see [`OutputDir`]).
    pub fn output_dir(&self, stage: &str) -> Result<OutputDir, TaskError> {
        if let Some(p) = self.out.local_path() {
            return Ok(OutputDir {
                path: p.to_path_buf(),
                staged: false,
            });
        }
        let d = self
            .ctx
            .cache_dir
            .join("outputs")
            .join(format!("{:016x}", fnv(self.job.output.as_bytes())))
            .join(stage.replace('/', "_"));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).map_err(|e| staging_err(&d, e))?;
        Ok(OutputDir {
            path: d,
            staged: true,
        })
    }
}

impl OutputDir {
    /// Uploads a staging directory's files (nothing to do for a local output).
    pub fn upload(&self, env: &TaskEnv) -> Result<(), TaskError> {
        if self.staged {
            upload_dir(env, &self.path)?;
        }
        Ok(())
    }
}

/// Uploads every plain, non-hidden file of a staging directory under its file name.
fn upload_dir(env: &TaskEnv, dir: &Path) -> Result<(), TaskError> {
    let entries = std::fs::read_dir(dir).map_err(|e| staging_err(dir, e))?;
    let mut files: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.is_file()
                && !p
                    .file_name()
                    .is_some_and(|n| n.to_string_lossy().starts_with('.'))
        })
        .collect();
    files.sort();
    for f in files {
        let name = f
            .file_name()
            .unwrap_or_default()
            .to_string_lossy()
            .into_owned();
        env.block_on(env.out.put_file(&name, &f))
            .map_err(storage_err)?;
    }
    Ok(())
}

/// A failure of the worker's local staging area: retryable (another worker may have room), named as full
/// storage when it is.
fn staging_err(path: &Path, e: std::io::Error) -> TaskError {
    if crate::storage::errors::is_full_io(&e) {
        TaskError {
            location: Some(path.display().to_string()),
            ..TaskError::new(
                crate::failure::FailureKind::StorageFullLocal,
                format!("storage full at {} (worker staging): {e}", path.display()),
            )
        }
    } else {
        TaskError::transient(format!("staging {}: {e}", path.display()))
    }
}

/// FNV-1a over 8-byte little-endian words (the tail zero-padded) and the length: a content hash of large
/// intermediates at a fraction of the byte-wise cost.
fn fnv_words(bytes: &[u8]) -> u64 {
    let mut chunks = bytes.chunks_exact(8);
    let mut h = (&mut chunks).fold(0xcbf29ce484222325u64, |h, c| {
        (h ^ u64::from_le_bytes(c.try_into().expect("8 bytes"))).wrapping_mul(0x100000001b3)
    });
    let mut tail = [0u8; 8];
    tail[..chunks.remainder().len()].copy_from_slice(chunks.remainder());
    h = (h ^ u64::from_le_bytes(tail)).wrapping_mul(0x100000001b3);
    (h ^ bytes.len() as u64).wrapping_mul(0x100000001b3)
}

fn fnv(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf29ce484222325u64, |h, &b| {
        (h ^ b as u64).wrapping_mul(0x100000001b3)
    })
}

//! Where a URI points: a local path or a remote object-store location, and the object store that serves a
//! remote one (`memory://` stores of this process, S3 from the `AWS_*` environment, stores registered in
//! code, or whatever `object_store` was built with).

use crate::error::JobError;
use object_store::path::Path as ObjectPath;
use object_store::ObjectStore;
use std::path::PathBuf;
use std::sync::Arc;

/// How a URI was understood: a local filesystem path, or a remote object-store location.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Location {
    /// A plain path or `file://` URI, made absolute.
    Local(PathBuf),
    /// Any other scheme, kept as a URL.
    Remote(url::Url),
}

/// Parses a URI: plain paths (relative ones against the current directory) and `file://` are local, every
/// other `scheme://` is remote. `field` names the job-spec field in errors.
pub fn parse_location(uri: &str, field: &str) -> Result<Location, JobError> {
    if uri.trim().is_empty() {
        return Err(JobError::spec(field, "is empty; give a path or a URI"));
    }
    if !uri.contains("://") {
        let p = PathBuf::from(uri);
        let abs = if p.is_absolute() {
            p
        } else {
            std::env::current_dir()
                .map_err(|e| JobError::input(uri, format!("cannot resolve a relative path: {e}")))?
                .join(p)
        };
        return Ok(Location::Local(abs));
    }
    let url = url::Url::parse(uri)
        .map_err(|e| JobError::spec(field, format!("`{uri}` is not a valid URI: {e}")))?;
    if url.scheme() == "file" {
        let p = url
            .to_file_path()
            .map_err(|_| JobError::spec(field, format!("`{uri}` is not a valid local file URI")))?;
        return Ok(Location::Local(p));
    }
    Ok(Location::Remote(url))
}

/// The object store serving `url` and the path of `url` inside it. `memory://<name>/…` URLs name process-wide
/// in-memory stores (one per `<name>`, created on first use), so in-process runs and tests exercise the
/// remote-storage path (staged outputs, cached inputs) without a network; `s3://bucket/…` (and `s3a://`)
/// go to an S3-compatible store configured from the environment (see [`super::s3`]); every other scheme goes to
/// `object_store::parse_url` (which knows the schemes the crate was built with). Stores registered with
/// [`register_store`] take precedence.
pub fn remote_store(
    url: &url::Url,
) -> Result<(Arc<dyn ObjectStore>, ObjectPath), object_store::Error> {
    let root = store_root(url);
    if let Some(store) = registered(&root) {
        return Ok((store, ObjectPath::from_url_path(url.path())?));
    }
    if url.scheme() == "memory" {
        let mut stores = STORES.lock().unwrap_or_else(|p| p.into_inner());
        let store = match stores.iter().find(|(n, _)| *n == root) {
            Some((_, s)) => s.clone(),
            None => {
                let s: Arc<dyn ObjectStore> = Arc::new(object_store::memory::InMemory::new());
                stores.push((root, s.clone()));
                s
            }
        };
        return Ok((store, ObjectPath::from_url_path(url.path())?));
    }
    if matches!(url.scheme(), "s3" | "s3a") {
        let mut stores = STORES.lock().unwrap_or_else(|p| p.into_inner());
        if let Some((_, s)) = stores.iter().find(|(n, _)| *n == root) {
            return Ok((s.clone(), ObjectPath::from_url_path(url.path())?));
        }
        let store = super::s3::store(url)?;
        stores.push((root, store.clone()));
        return Ok((store, ObjectPath::from_url_path(url.path())?));
    }
    super::s3::install_crypto_provider();
    let (store, prefix) = object_store::parse_url(url)?;
    Ok((Arc::from(store), prefix))
}

/// Stores built so far, by `scheme://host` (in-memory stores, and S3 clients, which keep their connection pool
/// between tasks).
static STORES: std::sync::Mutex<Vec<(String, Arc<dyn ObjectStore>)>> =
    std::sync::Mutex::new(Vec::new());
#[allow(clippy::type_complexity)]
static REGISTERED: std::sync::Mutex<Vec<(String, Arc<dyn ObjectStore>)>> =
    std::sync::Mutex::new(Vec::new());

fn store_root(url: &url::Url) -> String {
    format!(
        "{}://{}",
        url.scheme(),
        &url[url::Position::BeforeHost..url::Position::AfterPort]
    )
}

fn registered(root: &str) -> Option<Arc<dyn ObjectStore>> {
    let reg = REGISTERED.lock().unwrap_or_else(|p| p.into_inner());
    reg.iter().find(|(r, _)| r == root).map(|(_, s)| s.clone())
}

/// Serves every URL under `root` (`scheme://host`, e.g. `s3://bucket` or `memory://quota`) from `store` in this
/// process. For programs embedding crease-jobs with their own `ObjectStore` (a wrapper adding metrics or
/// quotas, a store configured in code) and for tests (a store that fails on purpose).
pub fn register_store(root: &str, store: Arc<dyn ObjectStore>) {
    let root = root.trim_end_matches('/').to_string();
    let mut reg = REGISTERED.lock().unwrap_or_else(|p| p.into_inner());
    reg.retain(|(r, _)| *r != root);
    reg.push((root, store));
}

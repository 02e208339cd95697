//! `GET /api/jobs/{id}/view/{name}`, the one handler both mounts route to. Opening folders and reading frames
//! is blocking file work and runs on the blocking pool, never on the server's own threads.

use super::names::ViewFile;
use super::scene::SceneError;
use super::{LocateError, Located, Viewer};
use crate::api::plausible_id;
use crate::json::{error, reply};
use axum::extract::{Path, State};
use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use crease_jobs::Storage;
use serde_json::Value;
use std::sync::Arc;

/// A report larger than this is not crease's; refuse rather than buffer it.
const MAX_JSON_BYTES: usize = 256 << 20;

fn locate_error(e: LocateError) -> Response {
    match e {
        LocateError::NotFound(m) => error(StatusCode::NOT_FOUND, m),
        LocateError::Unavailable(m) => error(StatusCode::CONFLICT, m),
        LocateError::Internal(m) => error(StatusCode::INTERNAL_SERVER_ERROR, m),
    }
}

fn scene_error(e: SceneError) -> Response {
    match e {
        SceneError::Unavailable(m) => error(StatusCode::CONFLICT, m),
        SceneError::OutOfRange(m) => error(StatusCode::NOT_FOUND, m),
        // The folder's data is at fault, not the request or the server: the message names the file.
        SceneError::Unreadable(m) => error(StatusCode::UNPROCESSABLE_ENTITY, m),
    }
}

/// Why a request found nothing to show (kept small: it crosses from the blocking pool).
enum Refused {
    Locate(LocateError),
    Scene(SceneError),
}

fn binary(bytes: Vec<u8>) -> Response {
    (
        [
            (header::CONTENT_TYPE, "application/octet-stream"),
            (header::CACHE_CONTROL, "private, no-cache"),
        ],
        bytes,
    )
        .into_response()
}

pub async fn file(
    State(v): State<Arc<Viewer>>,
    Path((id, name)): Path<(String, String)>,
) -> Response {
    let Some(what) = ViewFile::parse(&name) else {
        return error(
            StatusCode::NOT_FOUND,
            format!("`{name}` is not a file the viewer serves"),
        );
    };
    if !plausible_id(&id) {
        return error(StatusCode::NOT_FOUND, format!("job {id} not found"));
    }
    if let Some(key) = what.output_key() {
        return output_json(v, id, key).await;
    }
    let work = tokio::task::spawn_blocking(move || {
        let loc = v.locate(&id).map_err(Refused::Locate)?;
        let scene = v.scenes.get(&loc).map_err(Refused::Scene)?;
        Ok::<_, Refused>((loc, scene))
    });
    let (loc, scene) = match work.await {
        Ok(Ok(found)) => found,
        Ok(Err(Refused::Locate(e))) => return locate_error(e),
        Ok(Err(Refused::Scene(e))) => return scene_error(e),
        Err(e) => {
            return error(
                StatusCode::INTERNAL_SERVER_ERROR,
                format!("viewer: {name}: {e}"),
            )
        }
    };
    match what {
        ViewFile::Meta => {
            let mut meta = scene.meta().clone();
            meta["files"] = present(&loc).await;
            reply(StatusCode::OK, &meta)
        }
        ViewFile::Index => binary(scene.index_bytes()),
        ViewFile::Frame(t) => {
            match tokio::task::spawn_blocking(move || scene.frame_bytes(t)).await {
                Ok(Ok(b)) => binary(b),
                Ok(Err(e)) => scene_error(e),
                Err(e) => error(
                    StatusCode::INTERNAL_SERVER_ERROR,
                    format!("viewer: {name}: {e}"),
                ),
            }
        }
        ViewFile::Report | ViewFile::Eval => unreachable!("answered from storage above"),
    }
}

/// Which of the output's JSON files exist now (asked on every `meta.json`: `crease eval` may have written
/// `eval.json` since the scene was opened), so the page fetches only those.
async fn present(loc: &Located) -> Value {
    let mut files = serde_json::Map::new();
    let store = loc
        .output_uri
        .as_deref()
        .and_then(|u| Storage::open_existing(u).ok());
    for key in [ViewFile::Report, ViewFile::Eval]
        .iter()
        .filter_map(|f| f.output_key())
    {
        let here = match &store {
            Some(s) => s.exists(key).await.unwrap_or(false),
            None => false,
        };
        files.insert(key.to_string(), Value::Bool(here));
    }
    Value::Object(files)
}

/// `report.json` or `eval.json` of the output, byte for byte, read through storage (so a remote output's
/// report is one click away too).
async fn output_json(v: Arc<Viewer>, id: String, key: &'static str) -> Response {
    let located = {
        let v = v.clone();
        let id = id.clone();
        tokio::task::spawn_blocking(move || v.locate(&id)).await
    };
    let loc = match located {
        Ok(Ok(l)) => l,
        Ok(Err(e)) => return locate_error(e),
        Err(e) => return error(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()),
    };
    let Some(uri) = loc.output_uri else {
        return error(
            StatusCode::NOT_FOUND,
            format!("{} has no output, so no {key}", loc.name),
        );
    };
    let store = match Storage::open_existing(&uri) {
        Ok(s) => s,
        Err(e) => {
            return error(
                StatusCode::NOT_FOUND,
                format!("output {uri} cannot be opened: {e}"),
            )
        }
    };
    let missing = format!("{} has no {key} (yet)", store.describe(""));
    crate::files::stored(&store, key, missing, MAX_JSON_BYTES, "application/json").await
}

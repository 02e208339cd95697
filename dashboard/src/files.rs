//! Pictures of a job, read from the job's own output location by fixed names: `GET
//! /api/jobs/{id}/files/{name}` where `name` is one of [`FIXED`] or `overlay-N.png` (the fold overlay of
//! frame N, parsed as a number). The name is looked up, never joined into a path, so no request can reach
//! anything else in storage (`..%2f..%2fetc%2fpasswd` is simply not a name).

use crate::api::{api_error, plausible_id};
use crate::json::error;
use crate::AppState;
use axum::extract::{Path, State};
use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use crease_jobs::Storage;
use serde_json::{json, Value};

/// Served names and what they show; each is also its storage key under the output.
pub const FIXED: [(&str, &str); 4] = [
    ("preview.png", "before / after preview"),
    ("stretch.png", "stretch per frame and pass"),
    ("folds.png", "detected folds"),
    ("eval.png", "fold signal (crease eval)"),
];

/// Where fold overlays live (`overlays/frame_NNNN.png`, written by video fold detection).
const OVERLAY_DIR: &str = "overlays/";

/// A picture larger than this is not a crease output; refuse rather than buffer it.
const MAX_BYTES: usize = 64 << 20;

/// The storage key of a served name, or None when the name is not one the dashboard serves.
pub fn key_of(name: &str) -> Option<String> {
    if FIXED.iter().any(|(n, _)| *n == name) {
        return Some(name.to_string());
    }
    let digits = name.strip_prefix("overlay-")?.strip_suffix(".png")?;
    if digits.is_empty() || digits.len() > 9 || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    let frame: u32 = digits.parse().ok()?;
    Some(format!("{OVERLAY_DIR}frame_{frame:04}.png"))
}

/// The served name of an overlay key (`overlays/frame_0012.png` → `overlay-12.png`).
fn overlay_name(key: &str) -> Option<(u32, String)> {
    let digits = key
        .strip_prefix(OVERLAY_DIR)?
        .strip_prefix("frame_")?
        .strip_suffix(".png")?;
    let frame: u32 = digits.parse().ok()?;
    let name = format!("overlay-{frame}.png");
    // Only names that map back to this very key are offered.
    (key_of(&name).as_deref() == Some(key)).then_some((frame, name))
}

pub async fn get(State(s): State<AppState>, Path((id, name)): Path<(String, String)>) -> Response {
    let Some(key) = key_of(&name) else {
        return error(
            StatusCode::NOT_FOUND,
            format!("`{name}` is not a file the dashboard serves"),
        );
    };
    if !plausible_id(&id) {
        return error(StatusCode::NOT_FOUND, format!("job {id} not found"));
    }
    let status = match s.scheduler.status(&id, false) {
        Ok(st) => st,
        Err(e) => return api_error(e),
    };
    let store = match Storage::open_existing(&status.output) {
        Ok(st) => st,
        Err(e) => {
            return error(
                StatusCode::NOT_FOUND,
                format!("job {id}: output {} cannot be opened: {e}", status.output),
            )
        }
    };
    stored(
        &store,
        &key,
        format!("job {id} has no {name} (yet)"),
        MAX_BYTES,
        "image/png",
    )
    .await
}

/// The object at `key` as the answer, byte for byte: 404 with `missing` when it is not there, 413 past
/// `max` bytes (refused rather than buffered), 502 when storage fails. The viewer's raw JSON files are served
/// the same way.
pub async fn stored(
    store: &Storage,
    key: &str,
    missing: String,
    max: usize,
    content_type: &'static str,
) -> Response {
    match store.exists(key).await {
        Ok(true) => {}
        Ok(false) => return error(StatusCode::NOT_FOUND, missing),
        Err(e) => return error(StatusCode::BAD_GATEWAY, e.to_string()),
    }
    match store.get(key).await {
        Ok(bytes) if bytes.len() > max => error(
            StatusCode::PAYLOAD_TOO_LARGE,
            format!("{} is larger than {max} bytes", store.describe(key)),
        ),
        Ok(bytes) => (
            [
                (header::CONTENT_TYPE, content_type),
                (header::CACHE_CONTROL, "private, no-cache"),
            ],
            bytes,
        )
            .into_response(),
        Err(e) => error(StatusCode::BAD_GATEWAY, e.to_string()),
    }
}

/// The pictures a job has now (name, label, URL) and its report figures (`report.json`'s summary), for the
/// job page. Storage that cannot be read leaves both empty with a note rather than failing the page.
pub async fn outputs(id: &str, output: &str) -> (Value, Value) {
    let store = match Storage::open_existing(output) {
        Ok(s) => s,
        Err(_) => return (json!([]), Value::Null),
    };
    let url = |name: &str| format!("/api/jobs/{id}/files/{name}");
    let mut files = Vec::new();
    for (name, label) in FIXED {
        if store.exists(name).await.unwrap_or(false) {
            files.push(json!({ "name": name, "label": label, "url": url(name) }));
        }
    }
    let mut overlays: Vec<(u32, String)> = store
        .list(OVERLAY_DIR)
        .await
        .unwrap_or_default()
        .iter()
        .filter_map(|k| overlay_name(k))
        .collect();
    overlays.sort();
    for (frame, name) in overlays {
        let label = format!("fold overlay, frame {frame}");
        files.push(json!({ "name": name, "label": label, "url": url(&name) }));
    }
    let report = match store.exists(crease_jobs::keys::REPORT).await {
        Ok(true) => match store.get(crease_jobs::keys::REPORT).await {
            Ok(bytes) => match serde_json::from_slice::<Value>(&bytes) {
                Ok(doc) => json!({
                    "complete": doc["complete"],
                    "summary": doc["summary"],
                    "fold_detection": doc["fold_detection"],
                    "input": doc["input"],
                }),
                Err(e) => {
                    json!({ "error": format!("{}: {e}", store.describe(crease_jobs::keys::REPORT)) })
                }
            },
            Err(e) => json!({ "error": e.to_string() }),
        },
        _ => Value::Null,
    };
    (Value::Array(files), report)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_fixed_names_and_numbered_overlays_map_to_keys() {
        assert_eq!(key_of("preview.png").as_deref(), Some("preview.png"));
        assert_eq!(key_of("eval.png").as_deref(), Some("eval.png"));
        assert_eq!(
            key_of("overlay-7.png").as_deref(),
            Some("overlays/frame_0007.png")
        );
        assert_eq!(
            key_of("overlay-12345.png").as_deref(),
            Some("overlays/frame_12345.png")
        );
        for bad in [
            "../../etc/passwd",
            "..%2f..%2fetc%2fpasswd",
            "report.json",
            "overlay-.png",
            "overlay--1.png",
            "overlay-1/../x.png",
            "overlay-99999999999.png",
            "PREVIEW.PNG",
            "preview.png/",
            "",
        ] {
            assert_eq!(key_of(bad), None, "{bad}");
        }
    }

    #[test]
    fn overlay_keys_are_offered_under_names_that_map_back() {
        assert_eq!(
            overlay_name("overlays/frame_0003.png"),
            Some((3, "overlay-3.png".into()))
        );
        assert_eq!(overlay_name("overlays/frame_0003.txt"), None);
        assert_eq!(overlay_name("overlays/frame_x.png"), None);
        assert_eq!(overlay_name("overlays/sub/frame_0003.png"), None);
    }
}

//! The page, its scripts and its style sheet, compiled into the binary (a render farm has no CDN), plus the
//! response headers every dashboard answer carries: the page may load only its own script, style and images
//! (Content-Security-Policy), is never framed, and its types are not sniffed. The viewer's modules and the
//! vendored three.js (`assets/vendor/three`, see its README) are loaded by the page only when it shows a
//! viewer.

use axum::extract::{Path, Request};
use axum::http::{header, HeaderValue, StatusCode};
use axum::middleware::Next;
use axum::response::{Html, IntoResponse, Response};

const INDEX: &str = include_str!("../assets/index.html");
const APP_JS: &str = include_str!("../assets/app.js");
const APP_CSS: &str = include_str!("../assets/app.css");
const FAVICON: &str = include_str!("../assets/favicon.svg");
const DOM_JS: &str = include_str!("../assets/dom.js");
const VIEWER_JS: &str = include_str!("../assets/viewer.js");
const FRAMES_JS: &str = include_str!("../assets/frames.js");
const REPORT_JS: &str = include_str!("../assets/report.js");
const PLOT_JS: &str = include_str!("../assets/plot.js");
const THREE_JS: &str = include_str!("../assets/vendor/three/three.min.js");

/// Marks the page as `crease view`'s: the script then shows the one local folder instead of the queue.
const LOCAL_BODY: &str = "<body data-mode=\"local\">";

pub async fn index() -> Response {
    Html(INDEX).into_response()
}

/// The same page for `crease view`.
pub async fn local_index() -> Response {
    Html(INDEX.replacen("<body>", LOCAL_BODY, 1)).into_response()
}

/// `GET /assets/{name}`: the fixed assets; anything else is 404.
pub async fn asset(Path(name): Path<String>) -> Response {
    let (body, kind) = match name.as_str() {
        "app.js" => (APP_JS, "text/javascript; charset=utf-8"),
        "app.css" => (APP_CSS, "text/css; charset=utf-8"),
        "favicon.svg" => (FAVICON, "image/svg+xml"),
        "dom.js" => (DOM_JS, "text/javascript; charset=utf-8"),
        "viewer.js" => (VIEWER_JS, "text/javascript; charset=utf-8"),
        "frames.js" => (FRAMES_JS, "text/javascript; charset=utf-8"),
        "report.js" => (REPORT_JS, "text/javascript; charset=utf-8"),
        "plot.js" => (PLOT_JS, "text/javascript; charset=utf-8"),
        "three.min.js" => (THREE_JS, "text/javascript; charset=utf-8"),
        _ => return crate::json::error(StatusCode::NOT_FOUND, "no such asset"),
    };
    ([(header::CONTENT_TYPE, kind)], body).into_response()
}

pub async fn security_headers(req: Request, next: Next) -> Response {
    let mut r = next.run(req).await;
    let h = r.headers_mut();
    h.insert(
        header::CONTENT_SECURITY_POLICY,
        HeaderValue::from_static(
            "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self'; \
             connect-src 'self'; form-action 'self'; frame-ancestors 'none'; base-uri 'none'",
        ),
    );
    h.insert(
        header::X_CONTENT_TYPE_OPTIONS,
        HeaderValue::from_static("nosniff"),
    );
    h.insert(header::X_FRAME_OPTIONS, HeaderValue::from_static("DENY"));
    h.insert(
        header::REFERRER_POLICY,
        HeaderValue::from_static("same-origin"),
    );
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_local_page_is_the_same_page_marked_local() {
        assert!(INDEX.contains("<body>"));
        let local = INDEX.replacen("<body>", LOCAL_BODY, 1);
        assert!(local.contains(LOCAL_BODY));
        assert_eq!(local.len(), INDEX.len() + LOCAL_BODY.len() - "<body>".len());
    }
}

//! Who may use the dashboard: with client tokens configured (`--client-tokens-file`) every page, API call,
//! action and the event stream needs one, presented as `Authorization: Bearer <token>` (scripts) or as the
//! HttpOnly cookie the login form sets (browsers). The check is crease-net's, so the rules are the gRPC
//! server's: no or unknown token is 401, a worker token is 403 (a worker cannot act as a client). Without
//! client tokens the dashboard is open, like the gRPC API.
//!
//! The cookie is `SameSite=Strict` and, over TLS, `Secure`; actions are POSTs, and a POST whose `Origin` is
//! not this host is refused, so another site cannot drive the actions with the user's cookie.

use crate::json::error;
use crate::AppState;
use axum::body::Bytes;
use axum::extract::{Request, State};
use axum::http::{header, HeaderMap, HeaderValue, Method, StatusCode};
use axum::middleware::Next;
use axum::response::{Html, IntoResponse, Response};
use crease_net::Role;
use tonic::Code;

/// Name of the session cookie (holds the client token, percent-encoded).
pub const COOKIE: &str = "crease_token";

/// Why a request was refused: the status (401 or 403) and the message (never the token).
pub type Refusal = (StatusCode, String);

/// The token a request presents: the bearer header first, else the cookie.
fn presented(headers: &HeaderMap) -> Option<Vec<u8>> {
    if let Some(v) = headers.get(header::AUTHORIZATION) {
        return Some(v.as_bytes().to_vec());
    }
    headers
        .get_all(header::COOKIE)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(';'))
        .filter_map(|c| c.trim().split_once('='))
        .find(|(k, _)| *k == COOKIE)
        .and_then(|(_, v)| percent_decode(v))
        .map(|t| [b"Bearer ".as_slice(), t.as_slice()].concat())
}

/// Checks a request against the client tokens.
pub fn check(tokens: &crease_net::Tokens, headers: &HeaderMap) -> Result<(), Refusal> {
    let auth = presented(headers);
    tokens
        .check(Role::Client, "the dashboard", auth.as_deref())
        .map_err(|status| {
            let code = if status.code() == Code::PermissionDenied {
                StatusCode::FORBIDDEN
            } else {
                StatusCode::UNAUTHORIZED
            };
            (code, status.message().to_string())
        })
}

/// Whether a state-changing request comes from a page of this dashboard (or from a script, which sends no
/// `Origin`).
fn same_origin(headers: &HeaderMap) -> bool {
    let Some(origin) = headers.get(header::ORIGIN).and_then(|v| v.to_str().ok()) else {
        return true;
    };
    let host = headers.get(header::HOST).and_then(|v| v.to_str().ok());
    let origin_host = origin
        .strip_prefix("https://")
        .or_else(|| origin.strip_prefix("http://"));
    matches!((origin_host, host), (Some(o), Some(h)) if o == h)
}

/// Middleware on every guarded route: API calls are answered 401/403 with a JSON error; the page itself
/// sends a browser to the login form instead.
pub async fn require_client(State(s): State<AppState>, req: Request, next: Next) -> Response {
    if req.method() == Method::POST && !same_origin(req.headers()) {
        tracing::warn!(path = %req.uri().path(), "dashboard: refused a cross-site request");
        return error(StatusCode::FORBIDDEN, "cross-site requests are refused");
    }
    match check(&s.tokens, req.headers()) {
        Ok(()) => next.run(req).await,
        Err((code, message)) => {
            let path = req.uri().path().to_string();
            tracing::warn!(path = %path, "dashboard: refused ({code}): {message}");
            if path.starts_with("/api/") {
                error(code, message)
            } else {
                (StatusCode::SEE_OTHER, [(header::LOCATION, "/login")]).into_response()
            }
        }
    }
}

const LOGIN_PAGE: &str = include_str!("../assets/login.html");

fn login_form(status: StatusCode, message: &str) -> Response {
    let note = if message.is_empty() {
        String::new()
    } else {
        format!(
            "<p class=\"refused\" id=\"login-error\">{}</p>",
            html_escape(message)
        )
    };
    (status, Html(LOGIN_PAGE.replace("<!--MESSAGE-->", &note))).into_response()
}

pub async fn login_page(State(s): State<AppState>) -> Response {
    if s.tokens.client.is_none() {
        return (StatusCode::SEE_OTHER, [(header::LOCATION, "/")]).into_response();
    }
    login_form(StatusCode::OK, "")
}

/// `POST /login` with a form field `token`: sets the cookie and goes to the jobs list, or shows the form
/// again with the refusal (401, or 403 for a worker token).
pub async fn login(State(s): State<AppState>, headers: HeaderMap, body: Bytes) -> Response {
    if !same_origin(&headers) {
        return login_form(StatusCode::FORBIDDEN, "cross-site requests are refused");
    }
    if s.tokens.client.is_none() {
        return (StatusCode::SEE_OTHER, [(header::LOCATION, "/")]).into_response();
    }
    let token = form_value(&body, "token").unwrap_or_default();
    let token = String::from_utf8_lossy(&token).trim().to_string();
    let mut h = HeaderMap::new();
    if let Ok(v) = HeaderValue::from_str(&format!("Bearer {token}")) {
        h.insert(header::AUTHORIZATION, v);
    }
    match check(&s.tokens, &h) {
        Ok(()) => {
            let cookie = format!(
                "{COOKIE}={}; Path=/; HttpOnly; SameSite=Strict{}",
                percent_encode(token.as_bytes()),
                if s.https { "; Secure" } else { "" }
            );
            tracing::info!("dashboard: a client logged in");
            let mut r = (StatusCode::SEE_OTHER, [(header::LOCATION, "/")]).into_response();
            if let Ok(v) = HeaderValue::from_str(&cookie) {
                r.headers_mut().insert(header::SET_COOKIE, v);
            }
            r
        }
        Err((code, message)) => {
            tracing::warn!("dashboard: refused a login ({code}): {message}");
            let shown = if code == StatusCode::FORBIDDEN {
                "that is a worker token: a worker token cannot act as a client".to_string()
            } else if token.is_empty() {
                "give a client token".to_string()
            } else {
                "that token is not a client token of this coordinator".to_string()
            };
            login_form(code, &shown)
        }
    }
}

/// `POST /logout`: forgets the cookie.
pub async fn logout() -> Response {
    let mut r = (StatusCode::SEE_OTHER, [(header::LOCATION, "/login")]).into_response();
    r.headers_mut().insert(
        header::SET_COOKIE,
        HeaderValue::from_static("crease_token=; Path=/; HttpOnly; SameSite=Strict; Max-Age=0"),
    );
    r
}

/// The value of `name` in an `application/x-www-form-urlencoded` body.
fn form_value(body: &[u8], name: &str) -> Option<Vec<u8>> {
    let text = std::str::from_utf8(body).ok()?;
    text.split('&')
        .filter_map(|kv| kv.split_once('='))
        .find(|(k, _)| *k == name)
        .and_then(|(_, v)| percent_decode(&v.replace('+', " ")))
}

fn percent_decode(s: &str) -> Option<Vec<u8>> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' {
            let hex = std::str::from_utf8(b.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    Some(out)
}

/// Cookie values may not hold `;`, `,`, `"`, `\`, `%` or spaces: those are escaped.
fn percent_encode(b: &[u8]) -> String {
    b.iter()
        .map(|&c| {
            if c.is_ascii_alphanumeric() || b"-._~!$&'()*+/:<=>?@[]^`{|}".contains(&c) {
                (c as char).to_string()
            } else {
                format!("%{c:02X}")
            }
        })
        .collect()
}

pub fn html_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crease_net::{Secret, Tokens};
    use std::sync::Arc;

    fn tokens() -> Tokens {
        Tokens {
            client: Some(Arc::new(vec![Secret::new("c;tok%1")])),
            worker: Some(Arc::new(vec![Secret::new("w-tok")])),
        }
    }

    fn with(name: header::HeaderName, value: &str) -> HeaderMap {
        let mut h = HeaderMap::new();
        h.insert(name, HeaderValue::from_str(value).unwrap());
        h
    }

    #[test]
    fn bearer_and_cookie_are_both_accepted_and_worker_tokens_are_forbidden() {
        let t = tokens();
        assert!(check(&t, &with(header::AUTHORIZATION, "Bearer c;tok%1")).is_ok());
        let cookie = format!("a=b; {COOKIE}={}", percent_encode(b"c;tok%1"));
        assert!(check(&t, &with(header::COOKIE, &cookie)).is_ok());
        assert_eq!(
            check(&t, &HeaderMap::new()).unwrap_err().0,
            StatusCode::UNAUTHORIZED
        );
        assert_eq!(
            check(&t, &with(header::AUTHORIZATION, "Bearer nope"))
                .unwrap_err()
                .0,
            StatusCode::UNAUTHORIZED
        );
        let (code, msg) = check(&t, &with(header::COOKIE, &format!("{COOKIE}=w-tok"))).unwrap_err();
        assert_eq!(code, StatusCode::FORBIDDEN);
        assert!(!msg.contains("w-tok"), "{msg}");
        assert!(check(&Tokens::default(), &HeaderMap::new()).is_ok());
    }

    #[test]
    fn form_values_are_decoded_and_cookie_values_round_trip() {
        assert_eq!(
            form_value(b"x=1&token=a%3Bb+c", "token").unwrap(),
            b"a;b c".to_vec()
        );
        assert_eq!(form_value(b"token=%zz", "token"), None);
        let raw = b"we;ird,\"tok%en\\";
        let enc = percent_encode(raw);
        assert!(!enc.contains(';') && !enc.contains(',') && !enc.contains('"'));
        assert_eq!(percent_decode(&enc).unwrap(), raw.to_vec());
    }

    #[test]
    fn cross_site_posts_are_told_apart_from_the_dashboards_own() {
        let mut h = with(header::HOST, "127.0.0.1:8080");
        assert!(same_origin(&h));
        h.insert(
            header::ORIGIN,
            HeaderValue::from_static("http://127.0.0.1:8080"),
        );
        assert!(same_origin(&h));
        h.insert(
            header::ORIGIN,
            HeaderValue::from_static("https://evil.example"),
        );
        assert!(!same_origin(&h));
        h.insert(header::ORIGIN, HeaderValue::from_static("null"));
        assert!(!same_origin(&h));
    }
}

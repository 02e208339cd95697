//! Telling storage failures apart, so that a user reads "storage full at …" or "storage unreachable at …"
//! instead of a backend's error chain, and the retry policy can treat them differently (an outage may pass,
//! a full volume will not free itself within a retry's backoff).
//!
//! The classification walks the error's `source()` chain: the local filesystem reports `io::Error`s
//! (ENOSPC, EDQUOT), object stores report HTTP statuses (507 Insufficient Storage) and connection errors
//! (`object_store::client::HttpError` of kind connect / timeout, or an `io::Error` such as connection
//! refused underneath `reqwest`).

use std::error::Error;
use std::io::ErrorKind;

/// ENOSPC and EDQUOT on Linux (the same numbers on every Linux architecture crease builds for).
const ENOSPC: i32 = 28;
const EDQUOT: i32 = 122;

/// Whether an `io::Error` says the volume or a quota is full.
pub fn is_full_io(e: &std::io::Error) -> bool {
    matches!(e.kind(), ErrorKind::StorageFull | ErrorKind::QuotaExceeded)
        || matches!(e.raw_os_error(), Some(ENOSPC) | Some(EDQUOT))
}

fn is_unreachable_io(e: &std::io::Error) -> bool {
    matches!(
        e.kind(),
        ErrorKind::ConnectionRefused
            | ErrorKind::ConnectionReset
            | ErrorKind::ConnectionAborted
            | ErrorKind::NotConnected
            | ErrorKind::TimedOut
            | ErrorKind::HostUnreachable
            | ErrorKind::NetworkUnreachable
            | ErrorKind::AddrNotAvailable
    )
}

/// What a storage error amounts to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Full,
    Unreachable,
    Other,
}

/// Classifies an error by its whole source chain (the first decisive link wins).
pub fn kind(e: &(dyn Error + 'static)) -> Kind {
    let mut next: Option<&(dyn Error + 'static)> = Some(e);
    while let Some(err) = next {
        if let Some(io) = err.downcast_ref::<std::io::Error>() {
            if is_full_io(io) {
                return Kind::Full;
            }
            if is_unreachable_io(io) {
                return Kind::Unreachable;
            }
        }
        if let Some(http) = err.downcast_ref::<object_store::client::HttpError>() {
            use object_store::client::HttpErrorKind as K;
            if matches!(http.kind(), K::Connect | K::Timeout) {
                return Kind::Unreachable;
            }
        }
        // Messages, for the links that carry no type to match: an HTTP status in object_store's retry error,
        // a quota error in an S3-compatible server's response body.
        let text = err.to_string().to_ascii_lowercase();
        if text.contains("status code: 507")
            || text.contains("insufficient storage")
            || text.contains("no space left")
            || text.contains("quotaexceeded")
            || text.contains("disk quota exceeded")
        {
            return Kind::Full;
        }
        // reqwest's words for a request that never got a response (refused or dropped connection). Some
        // object_store paths (a PUT after its retries) keep only this text, not the typed connect error.
        if text.contains("error sending request") {
            return Kind::Unreachable;
        }
        next = err.source();
    }
    Kind::Other
}

/// Where an object store reached over the network lives, for messages: the endpoint of S3 URLs (from
/// `AWS_ENDPOINT_URL` / `AWS_ENDPOINT`, the AWS default otherwise). Never credentials.
pub fn endpoint_of(uri: &str) -> Option<String> {
    let scheme = uri.split_once("://")?.0;
    if !matches!(scheme, "s3" | "s3a") {
        return None;
    }
    let endpoint = ["AWS_ENDPOINT_URL_S3", "AWS_ENDPOINT_URL", "AWS_ENDPOINT"]
        .iter()
        .find_map(|v| std::env::var(v).ok().filter(|s| !s.is_empty()))
        .unwrap_or_else(|| "AWS S3".to_string());
    // An endpoint given with credentials in it (`http://user:pw@host`) is shown without them.
    Some(match url::Url::parse(&endpoint) {
        Ok(mut u) if !u.username().is_empty() || u.password().is_some() => {
            let _ = u.set_username("");
            let _ = u.set_password(None);
            u.to_string()
        }
        _ => endpoint,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn enospc_and_quota_are_full() {
        let e = std::io::Error::from_raw_os_error(ENOSPC);
        assert_eq!(kind(&e), Kind::Full);
        let e = std::io::Error::from_raw_os_error(EDQUOT);
        assert_eq!(kind(&e), Kind::Full);
        let e = std::io::Error::new(ErrorKind::StorageFull, "x");
        assert_eq!(kind(&e), Kind::Full);
    }

    #[test]
    fn wrapped_errors_are_classified_through_the_chain() {
        let inner = std::io::Error::from_raw_os_error(ENOSPC);
        let e = object_store::Error::Generic {
            store: "LocalFileSystem",
            source: Box::new(inner),
        };
        assert_eq!(kind(&e), Kind::Full);
        let refused = std::io::Error::new(ErrorKind::ConnectionRefused, "refused");
        let e = object_store::Error::Generic {
            store: "S3",
            source: Box::new(refused),
        };
        assert_eq!(kind(&e), Kind::Unreachable);
        let e = object_store::Error::Generic {
            store: "S3",
            source: "Server returned non-2xx status code: 507 Insufficient Storage: ".into(),
        };
        assert_eq!(kind(&e), Kind::Full);
        let e = object_store::Error::NotFound {
            path: "x".into(),
            source: "missing".into(),
        };
        assert_eq!(kind(&e), Kind::Other);
    }
}

//! What a request is answered when it cannot be served: the scheduler's errors keep their meaning as HTTP
//! statuses, and an id that cannot name a job is refused before the store is asked.

use crate::json::error;
use axum::http::StatusCode;
use axum::response::Response;
use crease_coordinator::ApiError;

pub fn api_error(e: ApiError) -> Response {
    match e {
        ApiError::NotFound(m) => error(StatusCode::NOT_FOUND, m),
        ApiError::Invalid(m) => error(StatusCode::BAD_REQUEST, m),
        ApiError::Internal(m) => error(StatusCode::INTERNAL_SERVER_ERROR, m),
    }
}

/// Job ids are what the store hands out; anything longer or with other characters cannot name a job, so it
/// is answered 404 before the store is asked.
pub fn plausible_id(id: &str) -> bool {
    !id.is_empty()
        && id.len() <= 64
        && id
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_')
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_id_shaped_strings_reach_the_store() {
        assert!(plausible_id("j1"));
        assert!(plausible_id("0f3a-b_c"));
        for bad in ["", "..", "../etc", "a/b", "a%2fb", "a b", &"x".repeat(65)] {
            assert!(!plausible_id(bad), "{bad}");
        }
    }
}

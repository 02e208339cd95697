//! S3-compatible object stores (`s3://bucket/prefix`), configured the way every S3 tool is: from the standard
//! `AWS_*` environment (`AWS_ACCESS_KEY_ID`, `AWS_SECRET_ACCESS_KEY`, `AWS_SESSION_TOKEN`, `AWS_REGION`,
//! `AWS_ENDPOINT_URL` for MinIO, Ceph, moto and other S3-compatible servers, `AWS_ALLOW_HTTP=true` for a
//! plain-HTTP endpoint, or instance / web-identity credentials), so a render farm's existing secrets work
//! unchanged. Requests are path-style (`endpoint/bucket/key`) unless `AWS_VIRTUAL_HOSTED_STYLE_REQUEST=true`,
//! which is what custom endpoints expect.
//!
//! Retries and timeouts are crease's own (object_store's default retry budget is three minutes per request,
//! which turns an unreachable endpoint into a task that hangs): a failed request is retried
//! `CREASE_STORAGE_RETRIES` times (default 3) within `CREASE_STORAGE_TIMEOUT_SECS` (default 60) in all, a
//! connection attempt gives up after `CREASE_STORAGE_CONNECT_TIMEOUT_SECS` (default 5), and one request (a
//! whole frame or point cache) after `CREASE_STORAGE_REQUEST_TIMEOUT_SECS` (default 300). Then the
//! operation fails with "storage unreachable at <uri> (endpoint …)". Output files of
//! `CREASE_STORAGE_MULTIPART_MIB` (default 64) or more are uploaded in parts of that size (see
//! [`crate::Storage::put_file`]).
//!
//! TLS is rustls with ring, the crypto provider the rest of crease (gRPC, the dashboard, `crease certs`) uses:
//! the HTTP client is built without a provider of its own, so this module makes ring the process default
//! before the first client exists.

use object_store::aws::AmazonS3Builder;
use object_store::{BackoffConfig, ClientOptions, ObjectStore, RetryConfig};
use std::sync::Arc;
use std::time::Duration;

/// Retry and timeout settings of network object stores.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    pub retries: usize,
    /// Budget of one operation including its retries.
    pub retry_timeout: Duration,
    pub connect_timeout: Duration,
    pub request_timeout: Duration,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            retries: 3,
            retry_timeout: Duration::from_secs(60),
            connect_timeout: Duration::from_secs(5),
            request_timeout: Duration::from_secs(300),
        }
    }
}

impl Settings {
    /// The defaults, overridden by the `CREASE_STORAGE_*` variables; a malformed value is an error naming the
    /// variable (a typo must not silently fall back to minutes of retries).
    pub fn from_env() -> Result<Self, String> {
        Self::from_lookup(|k| std::env::var(k).ok())
    }

    fn from_lookup(get: impl Fn(&str) -> Option<String>) -> Result<Self, String> {
        let mut s = Settings::default();
        let secs = |var: &str| -> Result<Option<Duration>, String> {
            match get(var) {
                None => Ok(None),
                Some(v) => match v.trim().parse::<f64>() {
                    Ok(x) if x.is_finite() && x > 0.0 && x <= 86_400.0 => {
                        Ok(Some(Duration::from_secs_f64(x)))
                    }
                    _ => Err(format!(
                        "{var}={v:?}: expected a number of seconds between 0 and 86400"
                    )),
                },
            }
        };
        if let Some(d) = secs("CREASE_STORAGE_TIMEOUT_SECS")? {
            s.retry_timeout = d;
        }
        if let Some(d) = secs("CREASE_STORAGE_CONNECT_TIMEOUT_SECS")? {
            s.connect_timeout = d;
        }
        if let Some(d) = secs("CREASE_STORAGE_REQUEST_TIMEOUT_SECS")? {
            s.request_timeout = d;
        }
        if let Some(v) = get("CREASE_STORAGE_RETRIES") {
            s.retries = v
                .trim()
                .parse::<usize>()
                .ok()
                .filter(|&n| n <= 100)
                .ok_or_else(|| {
                    format!("CREASE_STORAGE_RETRIES={v:?}: expected a whole number from 0 to 100")
                })?;
        }
        Ok(s)
    }
}

/// An S3 client for the bucket of `url`, configured from the environment (see the module documentation).
pub fn store(url: &url::Url) -> Result<Arc<dyn ObjectStore>, object_store::Error> {
    install_crypto_provider();
    let settings = Settings::from_env().map_err(|msg| object_store::Error::Generic {
        store: "S3",
        source: msg.into(),
    })?;
    let mut builder = AmazonS3Builder::new()
        .with_client_options(
            ClientOptions::new()
                .with_timeout(settings.request_timeout)
                .with_connect_timeout(settings.connect_timeout),
        )
        .with_retry(RetryConfig {
            backoff: BackoffConfig {
                init_backoff: Duration::from_millis(100),
                max_backoff: Duration::from_secs(5),
                base: 2.0,
            },
            max_retries: settings.retries,
            retry_timeout: settings.retry_timeout,
        });
    // What `AmazonS3Builder::from_env` does, applied after crease's client options so that `AWS_ALLOW_HTTP`
    // and the other client keys add to them instead of being replaced.
    for (key, value) in std::env::vars_os() {
        if let (Some(key), Some(value)) = (key.to_str(), value.to_str()) {
            if key.starts_with("AWS_") {
                if let Ok(k) = key.to_ascii_lowercase().parse() {
                    builder = builder.with_config(k, value);
                }
            }
        }
    }
    Ok(Arc::new(builder.with_url(url.as_str()).build()?))
}

/// Makes ring rustls' process-wide provider, once; a provider some other part of the process installed first
/// (the same ring, as the build has no other) is kept.
pub(crate) fn install_crypto_provider() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let _ = rustls::crypto::ring::default_provider().install_default();
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_default_and_override() {
        let none = Settings::from_lookup(|_| None).unwrap();
        assert_eq!(none, Settings::default());
        let s = Settings::from_lookup(|k| match k {
            "CREASE_STORAGE_TIMEOUT_SECS" => Some("2.5".into()),
            "CREASE_STORAGE_RETRIES" => Some("0".into()),
            _ => None,
        })
        .unwrap();
        assert_eq!(s.retry_timeout, Duration::from_millis(2500));
        assert_eq!(s.retries, 0);
        let e = Settings::from_lookup(|k| (k == "CREASE_STORAGE_RETRIES").then(|| "many".into()))
            .unwrap_err();
        assert!(e.contains("CREASE_STORAGE_RETRIES"), "{e}");
        let e =
            Settings::from_lookup(|k| (k == "CREASE_STORAGE_TIMEOUT_SECS").then(|| "-1".into()))
                .unwrap_err();
        assert!(e.contains("CREASE_STORAGE_TIMEOUT_SECS"), "{e}");
    }
}

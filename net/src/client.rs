//! The client side: an endpoint with TLS when the URL is https, and the bearer token put on every call.

use crate::secret::Secret;
use crate::tls::ClientTls;
use crate::{mib, NetError, DEFAULT_MAX_MESSAGE_MIB};
use tonic::metadata::{Ascii, MetadataValue};
use tonic::service::interceptor::InterceptedService;
use tonic::transport::{Channel, Endpoint};

/// A channel that presents the configured token (if any) on every call.
pub type AuthChannel = InterceptedService<Channel, Bearer>;

/// Interceptor adding `authorization: Bearer <token>`; a no-op without a token. Debug is redacted.
#[derive(Clone, Default)]
pub struct Bearer(Option<MetadataValue<Ascii>>);

impl std::fmt::Debug for Bearer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(if self.0.is_some() {
            "Bearer(<redacted>)"
        } else {
            "Bearer(none)"
        })
    }
}

impl tonic::service::Interceptor for Bearer {
    fn call(&mut self, mut req: tonic::Request<()>) -> Result<tonic::Request<()>, tonic::Status> {
        if let Some(v) = &self.0 {
            req.metadata_mut().insert("authorization", v.clone());
        }
        Ok(req)
    }
}

/// How a client connects: TLS trust, the token it presents, and its message limit.
#[derive(Clone, Debug)]
pub struct ClientSecurity {
    pub tls: Option<ClientTls>,
    pub token: Option<Secret>,
    pub max_message_bytes: usize,
}

impl Default for ClientSecurity {
    fn default() -> Self {
        ClientSecurity {
            tls: None,
            token: None,
            max_message_bytes: mib(DEFAULT_MAX_MESSAGE_MIB),
        }
    }
}

impl ClientSecurity {
    /// An endpoint for `url`: https needs a CA (`--tls-ca`), and a configured CA refuses plain http rather
    /// than send the token in the clear.
    pub fn endpoint(&self, url: &str) -> Result<Endpoint, NetError> {
        let endpoint = Endpoint::from_shared(url.to_string())
            .map_err(|e| NetError::Config(format!("`{url}` is not a valid URL: {e}")))?;
        let https = endpoint.uri().scheme_str() == Some("https");
        match (&self.tls, https) {
            (Some(tls), true) => endpoint.tls_config(tls.config()).map_err(|e| {
                NetError::Config(format!(
                    "TLS for `{url}` (--tls-ca {}): {}",
                    tls.ca_path.display(),
                    error_chain(&e)
                ))
            }),
            (None, true) => Err(NetError::Config(format!(
                "`{url}` is https but no CA is configured: give --tls-ca (CREASE_TLS_CA)"
            ))),
            (Some(tls), false) => Err(NetError::Config(format!(
                "`{url}` is plain http but TLS is configured (--tls-ca {}): use an https:// URL",
                tls.ca_path.display()
            ))),
            (None, false) => Ok(endpoint),
        }
    }

    pub fn bearer(&self) -> Bearer {
        Bearer(self.token.as_ref().and_then(|t| {
            let mut v: MetadataValue<Ascii> = format!("Bearer {}", t.expose()).parse().ok()?;
            v.set_sensitive(true);
            Some(v)
        }))
    }

    /// `endpoint` connected lazily and wrapped with the token.
    pub fn connect_lazy(&self, url: &str) -> Result<AuthChannel, NetError> {
        Ok(InterceptedService::new(
            self.endpoint(url)?.connect_lazy(),
            self.bearer(),
        ))
    }
}

/// An error and its sources on one line (tonic's transport errors say only "transport error" at the top).
pub fn error_chain(e: &(dyn std::error::Error + 'static)) -> String {
    let mut s = e.to_string();
    let mut cur = e.source();
    while let Some(c) = cur {
        let m = c.to_string();
        if !s.contains(&m) {
            s.push_str(": ");
            s.push_str(&m);
        }
        cur = c.source();
    }
    s
}

/// Explains a failed call whose status says little by itself (a refused TLS handshake, an over-size message).
pub fn explain(status: &tonic::Status) -> String {
    let mut msg = status.message().to_string();
    if let Some(src) = std::error::Error::source(status) {
        let chain = error_chain(src);
        if !msg.contains(&chain) {
            msg = format!("{msg}: {chain}");
        }
    }
    match status.code() {
        tonic::Code::OutOfRange if msg.contains("message length too large") => {
            format!("the message is larger than the gRPC message limit (--max-message-mib): {msg}")
        }
        _ => msg,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bearer_debug_is_redacted() {
        let s = ClientSecurity {
            token: Some(Secret::new("tok-123")),
            ..ClientSecurity::default()
        };
        let d = format!("{:?} {:?}", s, s.bearer());
        assert!(!d.contains("tok-123"), "{d}");
    }

    #[test]
    fn https_without_ca_and_http_with_ca_are_refused() {
        let s = ClientSecurity::default();
        let e = s
            .endpoint("https://127.0.0.1:7070")
            .unwrap_err()
            .to_string();
        assert!(e.contains("--tls-ca"), "{e}");
        assert!(s.endpoint("http://127.0.0.1:7070").is_ok());
    }
}

//! Transport security and limits for crease's gRPC connections, kept apart from scheduling: TLS (rustls) for
//! servers and client channels, bearer tokens by role, and the message-size limit every server and client
//! applies. With nothing configured everything is plaintext and unauthenticated, as in local single-node mode.
//!
//! [`secret`] keeps tokens out of logs, [`tokens`] reads token files, [`tls`] reads PEM files, [`auth`] is the
//! server-side check (a tower layer that sees the gRPC method and the peer), [`client`] is the client side
//! (TLS endpoint and the token presented on every call).

pub mod auth;
pub mod client;
pub mod secret;
pub mod tls;
pub mod tokens;

pub use auth::{AuthLayer, Role, Tokens};
pub use client::{AuthChannel, Bearer, ClientSecurity};
pub use secret::Secret;
pub use tls::{ClientTls, ServerTls};

use std::path::PathBuf;

/// Default gRPC message limit (decode and encode), in MiB. tonic's own default (4 MiB) is too small for the
/// planning payloads of long sequences.
pub const DEFAULT_MAX_MESSAGE_MIB: u32 = 64;

/// Bytes of `mib` MiB.
pub fn mib(mib: u32) -> usize {
    (mib as usize).saturating_mul(1024 * 1024)
}

/// A configuration error: names the flag and the file, never a secret.
#[derive(Debug, thiserror::Error)]
pub enum NetError {
    #[error("{flag} {}: {message}", path.display())]
    File {
        flag: &'static str,
        path: PathBuf,
        message: String,
    },
    #[error("{0}")]
    Config(String),
}

impl NetError {
    pub(crate) fn file(
        flag: &'static str,
        path: &std::path::Path,
        message: impl Into<String>,
    ) -> Self {
        NetError::File {
            flag,
            path: path.to_path_buf(),
            message: message.into(),
        }
    }
}

/// Settings of one gRPC server: TLS, the tokens it accepts, and the message limit.
#[derive(Clone, Debug)]
pub struct ServerSecurity {
    pub tls: Option<ServerTls>,
    pub tokens: Tokens,
    pub max_message_bytes: usize,
    /// Whether users call this server (the coordinator) or only cluster members (a worker); decides whether
    /// a missing client token file is worth a warning.
    pub accepts_clients: bool,
}

impl Default for ServerSecurity {
    fn default() -> Self {
        ServerSecurity {
            tls: None,
            tokens: Tokens::default(),
            max_message_bytes: mib(DEFAULT_MAX_MESSAGE_MIB),
            accepts_clients: true,
        }
    }
}

impl ServerSecurity {
    /// A tonic server builder with TLS applied when configured.
    pub fn builder(&self) -> Result<tonic::transport::Server, NetError> {
        let server = tonic::transport::Server::builder();
        match &self.tls {
            Some(tls) => server.tls_config(tls.config()).map_err(|e| {
                NetError::Config(format!(
                    "--tls-cert {} / --tls-key {}: {}",
                    tls.cert_path.display(),
                    tls.key_path.display(),
                    client::error_chain(&e)
                ))
            }),
            None => Ok(server),
        }
    }

    /// The authentication layer for a server whose methods need the roles `policy` gives them.
    pub fn auth_layer(&self, policy: fn(&str) -> Role) -> AuthLayer {
        AuthLayer::new(self.tokens.clone(), policy)
    }

    /// Warnings for a half-secured server (`what` names it in the message).
    pub fn warnings(&self, what: &str) -> Vec<String> {
        let mut w = Vec::new();
        let any_token = self.tokens.client.is_some() || self.tokens.worker.is_some();
        if self.tls.is_some() && !any_token {
            w.push(format!(
                "{what}: TLS is on but no token is required: the cluster is encrypted but unauthenticated"
            ));
        }
        if self.tls.is_none() && any_token {
            w.push(format!(
                "{what}: tokens are required but TLS is off: the cluster is unencrypted and tokens travel in plaintext"
            ));
        }
        if any_token && self.tokens.client.is_none() && self.accepts_clients {
            w.push(format!(
                "{what}: no --client-tokens-file: user calls (submit, status, cancel, ...) are unauthenticated"
            ));
        }
        if any_token && self.tokens.worker.is_none() {
            w.push(format!(
                "{what}: no --worker-token-file: worker calls are unauthenticated"
            ));
        }
        w
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    fn tokens(client: bool, worker: bool) -> Tokens {
        let t = || Some(Arc::new(vec![Secret::new("t")]));
        Tokens {
            client: if client { t() } else { None },
            worker: if worker { t() } else { None },
        }
    }

    #[test]
    fn half_secured_servers_are_warned_about() {
        let none = ServerSecurity::default();
        assert!(none.warnings("coordinator").is_empty());
        let tokens_only = ServerSecurity {
            tokens: tokens(true, true),
            ..ServerSecurity::default()
        };
        let w = tokens_only.warnings("coordinator").join("\n");
        assert!(w.contains("unencrypted"), "{w}");
        let client_only = ServerSecurity {
            tokens: tokens(true, false),
            ..ServerSecurity::default()
        };
        let w = client_only.warnings("coordinator").join("\n");
        assert!(w.contains("worker calls are unauthenticated"), "{w}");
        let worker_only = ServerSecurity {
            tokens: tokens(false, true),
            ..ServerSecurity::default()
        };
        let w = worker_only.warnings("coordinator").join("\n");
        assert!(w.contains("user calls"), "{w}");
        let worker_server = ServerSecurity {
            tokens: tokens(false, true),
            accepts_clients: false,
            ..ServerSecurity::default()
        };
        assert_eq!(worker_server.warnings("worker").len(), 1);
    }
}

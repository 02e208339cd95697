//! Server-side bearer-token check, as a tower layer so it sees the gRPC method (the request path) and the
//! peer address, which a tonic interceptor does not. Each method needs one role; a role with no tokens
//! configured is open. A refusal is answered with `UNAUTHENTICATED` (no or unknown token) or
//! `PERMISSION_DENIED` (a valid token of the other role) and logged with method and peer, never the token.

use crate::secret::{any_matches, Secret};
use futures::future::{Either, Ready};
use std::sync::Arc;
use std::task::{Context, Poll};
use tonic::transport::server::{TcpConnectInfo, TlsConnectInfo};
use tonic::{Code, Status};

/// Who may call a method.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    /// Users: submit, status, watch, cancel, list, logs.
    Client,
    /// Cluster members: workers registering and heartbeating, the coordinator calling workers.
    Worker,
}

impl Role {
    fn name(self) -> &'static str {
        match self {
            Role::Client => "client",
            Role::Worker => "worker",
        }
    }
}

/// Tokens a server accepts, by role. `None` leaves that role's methods open.
#[derive(Clone, Debug, Default)]
pub struct Tokens {
    pub client: Option<Arc<Vec<Secret>>>,
    pub worker: Option<Arc<Vec<Secret>>>,
}

impl Tokens {
    fn of(&self, role: Role) -> Option<&[Secret]> {
        match role {
            Role::Client => self.client.as_deref().map(Vec::as_slice),
            Role::Worker => self.worker.as_deref().map(Vec::as_slice),
        }
    }

    /// Decides one call: Ok, or the status to answer with.
    pub fn check(
        &self,
        role: Role,
        method: &str,
        authorization: Option<&[u8]>,
    ) -> Result<(), Status> {
        let Some(accepted) = self.of(role) else {
            return Ok(());
        };
        let Some(presented) = authorization.and_then(bearer_token) else {
            return Err(Status::unauthenticated(format!(
                "{method} needs a {} bearer token and none was sent",
                role.name()
            )));
        };
        if any_matches(accepted, presented) {
            return Ok(());
        }
        let other = match role {
            Role::Client => Role::Worker,
            Role::Worker => Role::Client,
        };
        if self.of(other).is_some_and(|t| any_matches(t, presented)) {
            return Err(Status::permission_denied(format!(
                "{method} needs a {} token; a {} token may not call it",
                role.name(),
                other.name()
            )));
        }
        Err(Status::unauthenticated(format!(
            "{method}: the bearer token is not valid"
        )))
    }
}

/// The token of an `authorization: Bearer <token>` header (scheme case-insensitive).
fn bearer_token(value: &[u8]) -> Option<&[u8]> {
    let prefix = b"bearer ";
    if value.len() > prefix.len() && value[..prefix.len()].eq_ignore_ascii_case(prefix) {
        let t = value[prefix.len()..].trim_ascii();
        (!t.is_empty()).then_some(t)
    } else {
        None
    }
}

/// Peer address from tonic's connection info (plain TCP or TLS).
fn peer<B>(req: &http::Request<B>) -> String {
    let ext = req.extensions();
    ext.get::<TcpConnectInfo>()
        .and_then(TcpConnectInfo::remote_addr)
        .or_else(|| {
            ext.get::<TlsConnectInfo<TcpConnectInfo>>()
                .and_then(|i| i.get_ref().remote_addr())
        })
        .map(|a| a.to_string())
        .unwrap_or_else(|| "unknown".into())
}

/// Layer checking every call against [`Tokens`] with the role `policy` gives the method path.
#[derive(Clone)]
pub struct AuthLayer {
    tokens: Tokens,
    policy: fn(&str) -> Role,
}

impl AuthLayer {
    pub fn new(tokens: Tokens, policy: fn(&str) -> Role) -> Self {
        AuthLayer { tokens, policy }
    }
}

impl<S> tower::Layer<S> for AuthLayer {
    type Service = AuthService<S>;

    fn layer(&self, inner: S) -> Self::Service {
        AuthService {
            inner,
            tokens: self.tokens.clone(),
            policy: self.policy,
        }
    }
}

#[derive(Clone)]
pub struct AuthService<S> {
    inner: S,
    tokens: Tokens,
    policy: fn(&str) -> Role,
}

impl<S, B, R> tower::Service<http::Request<B>> for AuthService<S>
where
    S: tower::Service<http::Request<B>, Response = http::Response<R>>,
    R: Default,
{
    type Response = http::Response<R>;
    type Error = S::Error;
    type Future = Either<Ready<Result<http::Response<R>, S::Error>>, S::Future>;

    fn poll_ready(&mut self, cx: &mut Context<'_>) -> Poll<Result<(), Self::Error>> {
        self.inner.poll_ready(cx)
    }

    fn call(&mut self, req: http::Request<B>) -> Self::Future {
        let path = req.uri().path();
        let method = path.rsplit('/').next().unwrap_or(path);
        let role = (self.policy)(method);
        let auth = req
            .headers()
            .get(http::header::AUTHORIZATION)
            .map(|v| v.as_bytes());
        match self.tokens.check(role, method, auth) {
            Ok(()) => Either::Right(self.inner.call(req)),
            Err(status) => {
                let kind = if status.code() == Code::PermissionDenied {
                    "permission denied"
                } else {
                    "unauthenticated"
                };
                tracing::warn!(
                    method = %path,
                    peer = %peer(&req),
                    "refused gRPC call ({kind}): {}",
                    status.message()
                );
                Either::Left(futures::future::ready(Ok(status.into_http())))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tokens() -> Tokens {
        Tokens {
            client: Some(Arc::new(vec![Secret::new("c-old"), Secret::new("c-new")])),
            worker: Some(Arc::new(vec![Secret::new("w-secret")])),
        }
    }

    #[test]
    fn roles_are_enforced() {
        let t = tokens();
        assert!(t
            .check(Role::Client, "SubmitJob", Some(b"Bearer c-new"))
            .is_ok());
        assert!(t
            .check(Role::Client, "SubmitJob", Some(b"bearer c-old"))
            .is_ok());
        assert!(t
            .check(Role::Worker, "Heartbeat", Some(b"Bearer w-secret"))
            .is_ok());
        let c = |r, a: Option<&[u8]>| t.check(r, "M", a).unwrap_err().code();
        assert_eq!(c(Role::Client, None), Code::Unauthenticated);
        assert_eq!(c(Role::Client, Some(b"Bearer ")), Code::Unauthenticated);
        assert_eq!(c(Role::Client, Some(b"Basic c-new")), Code::Unauthenticated);
        assert_eq!(
            c(Role::Client, Some(b"Bearer wrong")),
            Code::Unauthenticated
        );
        assert_eq!(
            c(Role::Worker, Some(b"Bearer c-new")),
            Code::PermissionDenied
        );
        assert_eq!(
            c(Role::Client, Some(b"Bearer w-secret")),
            Code::PermissionDenied
        );
    }

    #[test]
    fn a_role_without_tokens_is_open_and_messages_hold_no_token() {
        let t = Tokens {
            client: None,
            worker: Some(Arc::new(vec![Secret::new("w-secret")])),
        };
        assert!(t.check(Role::Client, "SubmitJob", None).is_ok());
        let e = t
            .check(Role::Worker, "RegisterWorker", Some(b"Bearer guess"))
            .unwrap_err();
        assert!(!e.message().contains("guess") && !e.message().contains("w-secret"));
        assert!(Tokens::default()
            .check(Role::Worker, "Execute", None)
            .is_ok());
    }
}

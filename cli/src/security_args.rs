//! Flags for TLS, tokens and message limits, flattened into the cluster commands and turned into crease-net
//! settings here, so cluster.rs only passes them on. Every flag is optional: without them the cluster runs
//! plaintext and unauthenticated, as in local single-node mode.

use anyhow::{bail, Result};
use clap::Args;
use crease_net::{
    mib, tokens, ClientSecurity, ClientTls, Secret, ServerSecurity, ServerTls, Tokens,
};
use std::path::PathBuf;
use std::sync::Arc;

/// gRPC message limits above this cannot be framed (gRPC lengths are 32-bit).
const MAX_MESSAGE_MIB: u32 = 4095;

fn message_bytes(v: u32) -> Result<usize> {
    if v == 0 || v > MAX_MESSAGE_MIB {
        bail!("--max-message-mib must be between 1 and {MAX_MESSAGE_MIB}, got {v}");
    }
    Ok(mib(v))
}

#[derive(Args, Debug, Clone)]
pub struct ServerTlsArgs {
    /// Serve gRPC over TLS with this certificate chain (PEM; with --tls-key).
    #[arg(long, env = "CREASE_TLS_CERT")]
    pub tls_cert: Option<PathBuf>,
    /// Private key (PEM) of --tls-cert.
    #[arg(long, env = "CREASE_TLS_KEY")]
    pub tls_key: Option<PathBuf>,
}

impl ServerTlsArgs {
    fn load(&self) -> Result<Option<ServerTls>> {
        Ok(ServerTls::from_flags(
            self.tls_cert.as_deref(),
            self.tls_key.as_deref(),
        )?)
    }
}

fn worker_tokens(path: &Option<PathBuf>) -> Result<Option<Vec<Secret>>> {
    Ok(match path {
        Some(p) => Some(tokens::load("--worker-token-file", p)?),
        None => None,
    })
}

#[derive(Args, Debug, Clone)]
pub struct CoordinatorSecurityArgs {
    #[command(flatten)]
    pub tls: ServerTlsArgs,
    /// User tokens, one per line (several during a rotation); required on submit/status/watch/cancel/jobs/logs.
    #[arg(long, env = "CREASE_CLIENT_TOKENS_FILE")]
    pub client_tokens_file: Option<PathBuf>,
    /// The cluster secret (first line; more lines are also accepted, for rotation): required of workers to
    /// register and heartbeat, and presented by the coordinator when it calls workers.
    #[arg(long, env = "CREASE_WORKER_TOKEN_FILE")]
    pub worker_token_file: Option<PathBuf>,
    /// CA that signs the workers' certificates; needed to call workers that advertise https:// URLs.
    #[arg(long, env = "CREASE_TLS_CA")]
    pub tls_ca: Option<PathBuf>,
    /// Name the coordinator expects in worker certificates (workers are reached by IP).
    #[arg(
        long,
        env = "CREASE_WORKER_TLS_DOMAIN",
        default_value = "crease-worker"
    )]
    pub worker_tls_domain: String,
    /// Largest gRPC message accepted or sent, in MiB (a bigger job spec is refused).
    #[arg(long, env = "CREASE_MAX_MESSAGE_MIB", default_value_t = crease_net::DEFAULT_MAX_MESSAGE_MIB)]
    pub max_message_mib: u32,
}

impl CoordinatorSecurityArgs {
    /// (the server's settings, the settings of its calls to workers).
    pub fn load(&self) -> Result<(ServerSecurity, ClientSecurity)> {
        let limit = message_bytes(self.max_message_mib)?;
        let client = match &self.client_tokens_file {
            Some(p) => Some(Arc::new(tokens::load("--client-tokens-file", p)?)),
            None => None,
        };
        let worker = worker_tokens(&self.worker_token_file)?;
        let server = ServerSecurity {
            tls: self.tls.load()?,
            tokens: Tokens {
                client,
                worker: worker.clone().map(Arc::new),
            },
            max_message_bytes: limit,
            accepts_clients: true,
        };
        let to_workers = ClientSecurity {
            tls: match &self.tls_ca {
                Some(ca) => Some(ClientTls::load(ca, Some(self.worker_tls_domain.clone()))?),
                None => None,
            },
            token: worker.and_then(|t| t.into_iter().next()),
            max_message_bytes: limit,
        };
        Ok((server, to_workers))
    }
}

#[derive(Args, Debug, Clone)]
pub struct WorkerSecurityArgs {
    #[command(flatten)]
    pub tls: ServerTlsArgs,
    /// CA that signs the coordinator's certificate (for an https:// --coordinator).
    #[arg(long, env = "CREASE_TLS_CA")]
    pub tls_ca: Option<PathBuf>,
    /// The cluster secret: presented to the coordinator, and required on the coordinator's calls to this
    /// worker.
    #[arg(long, env = "CREASE_WORKER_TOKEN_FILE")]
    pub worker_token_file: Option<PathBuf>,
    /// Largest gRPC message accepted or sent, in MiB.
    #[arg(long, env = "CREASE_MAX_MESSAGE_MIB", default_value_t = crease_net::DEFAULT_MAX_MESSAGE_MIB)]
    pub max_message_mib: u32,
}

impl WorkerSecurityArgs {
    pub fn load(&self) -> Result<crease_worker::WorkerSecurity> {
        let limit = message_bytes(self.max_message_mib)?;
        let worker = worker_tokens(&self.worker_token_file)?;
        Ok(crease_worker::WorkerSecurity {
            server: ServerSecurity {
                tls: self.tls.load()?,
                tokens: Tokens {
                    client: None,
                    worker: worker.clone().map(Arc::new),
                },
                max_message_bytes: limit,
                accepts_clients: false,
            },
            coordinator: ClientSecurity {
                tls: match &self.tls_ca {
                    Some(ca) => Some(ClientTls::load(ca, None)?),
                    None => None,
                },
                token: worker.and_then(|t| t.into_iter().next()),
                max_message_bytes: limit,
            },
        })
    }
}

#[derive(Args, Debug, Clone)]
pub struct ClientSecurityArgs {
    /// CA that signs the coordinator's certificate (for an https:// --coordinator).
    #[arg(long, env = "CREASE_TLS_CA")]
    pub tls_ca: Option<PathBuf>,
    /// File holding your token (first non-comment line); or set CREASE_TOKEN.
    #[arg(long, env = "CREASE_TOKEN_FILE")]
    pub token_file: Option<PathBuf>,
}

impl ClientSecurityArgs {
    pub fn load(&self) -> Result<ClientSecurity> {
        let token = match &self.token_file {
            Some(p) => tokens::load("--token-file", p)?.into_iter().next(),
            None => match std::env::var("CREASE_TOKEN") {
                Ok(v) => Some(tokens::from_env("CREASE_TOKEN", &v)?),
                Err(_) => None,
            },
        };
        Ok(ClientSecurity {
            tls: match &self.tls_ca {
                Some(ca) => Some(ClientTls::load(ca, None)?),
                None => None,
            },
            token,
            ..ClientSecurity::default()
        })
    }
}

//! How a client command reaches the coordinator: its URL and security flags, and the async runtime the
//! command's calls run on.

use anyhow::{Context, Result};
use clap::Args;
use crease_coordinator::RemoteClient;

pub(crate) const DEFAULT_COORDINATOR: &str = "http://127.0.0.1:7070";

pub(crate) fn runtime() -> Result<tokio::runtime::Runtime> {
    tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("starting the async runtime")
}

#[derive(Args, Debug)]
pub struct ClientArgs {
    /// Coordinator URL (http:// or https://).
    #[arg(long, env = "CREASE_COORDINATOR", default_value = DEFAULT_COORDINATOR, value_parser = crate::urls::parse)]
    pub coordinator: String,
    #[command(flatten)]
    pub security: crate::security_args::ClientSecurityArgs,
}

impl ClientArgs {
    /// Connects with the TLS and token flags.
    pub async fn connect(&self) -> Result<RemoteClient> {
        Ok(RemoteClient::connect_with(&self.coordinator, &self.security.load()?).await?)
    }
}

//! The coordinator's web dashboard (`crease coordinator --http-listen ADDR`): a jobs list with stacked
//! progress, a job page (tasks by stage of the task graph, per-attempt log tails, the finished job's pictures
//! and report figures), a workers page, and cancel / resubmit. The page is plain HTML/CSS/JS compiled into the
//! binary ([`assets`]) and reads the JSON API ([`api`]) it shares with scripts; changes are pushed to it over
//! server-sent events ([`events`]), never polled.
//!
//! It is a thin face over [`Scheduler`]: every figure comes from the same calls the gRPC service makes. With
//! client tokens configured every route but the login form and the static assets needs a client token
//! ([`auth`]); with `--tls-cert`/`--tls-key` it serves HTTPS only ([`tls`]). Files come from a job's output
//! location by fixed names only ([`files`]). The job page's 3D before/after viewer reads its frames from
//! [`viewer`], which `crease view` also mounts on a local folder without a coordinator ([`local`]).

pub mod api;
pub mod assets;
pub mod auth;
pub mod events;
pub mod files;
pub mod json;
pub mod local;
pub mod tls;
pub mod viewer;

use axum::extract::FromRef;
use axum::routing::{get, post};
use axum::Router;
use crease_coordinator::Scheduler;
use std::net::SocketAddr;
use std::sync::Arc;

/// What every handler shares.
#[derive(Clone)]
pub struct AppState {
    pub scheduler: Arc<Scheduler>,
    pub tokens: crease_net::Tokens,
    /// Served over TLS: cookies are marked `Secure`.
    pub https: bool,
    /// The viewer's data, looked up by job id in the queue.
    pub viewer: Arc<viewer::Viewer>,
}

impl AppState {
    pub fn new(scheduler: Arc<Scheduler>, tokens: crease_net::Tokens, https: bool) -> Self {
        let viewer = viewer::Viewer::new(viewer::job_folders::JobFolders::new(scheduler.clone()));
        AppState {
            scheduler,
            tokens,
            https,
            viewer,
        }
    }
}

impl FromRef<AppState> for Arc<viewer::Viewer> {
    fn from_ref(s: &AppState) -> Self {
        s.viewer.clone()
    }
}

/// The dashboard's routes over `scheduler`; nothing outside them is served.
pub fn router(state: AppState) -> Router {
    let guarded = Router::new()
        .route("/", get(assets::index))
        .route("/api/jobs", get(api::jobs))
        .route("/api/jobs/{id}", get(api::job))
        .route("/api/jobs/{id}/cancel", post(api::cancel))
        .route("/api/jobs/{id}/resubmit", post(api::resubmit))
        .route("/api/jobs/{id}/files/{name}", get(files::get))
        .route("/api/jobs/{id}/view/{name}", get(viewer::routes::file))
        .route("/api/workers", get(api::workers))
        .route("/api/events", get(events::stream))
        .route_layer(axum::middleware::from_fn_with_state(
            state.clone(),
            auth::require_client,
        ));
    Router::new()
        .merge(guarded)
        .route("/login", get(auth::login_page).post(auth::login))
        .route("/logout", post(auth::logout))
        .route("/assets/{name}", get(assets::asset))
        .fallback(api::not_found)
        .layer(axum::middleware::from_fn(assets::security_headers))
        .with_state(state)
}

/// Binds `addr` and serves the dashboard in a background task until the runtime stops; HTTPS when the
/// coordinator has TLS. Returns the bound address (port 0 picks a free port).
pub async fn serve(
    scheduler: Arc<Scheduler>,
    addr: SocketAddr,
) -> std::io::Result<(SocketAddr, tokio::task::JoinHandle<()>)> {
    let security = scheduler.config().server_security.clone();
    let state = AppState::new(scheduler, security.tokens.clone(), security.tls.is_some());
    let app = router(state);
    let listener = tokio::net::TcpListener::bind(addr).await?;
    let bound = listener.local_addr()?;
    let handle = match &security.tls {
        Some(server_tls) => {
            let listener = tls::TlsListener::new(listener, server_tls)?;
            tokio::spawn(async move {
                if let Err(e) = axum::serve(listener, app).await {
                    tracing::error!(error = %e, "dashboard server stopped");
                }
            })
        }
        None => tokio::spawn(async move {
            if let Err(e) = axum::serve(listener, app).await {
                tracing::error!(error = %e, "dashboard server stopped");
            }
        }),
    };
    Ok((bound, handle))
}

//! The observability HTTP server: `GET /metrics` (Prometheus/OpenMetrics text), `GET /healthz` (liveness:
//! answers while the process serves) and `GET /readyz` (200 when the owner says it is ready, else 503).
//! Separate from the gRPC port so probes and scrapes need neither TLS client certificates nor tokens.

use axum::http::{header, StatusCode};
use axum::response::IntoResponse;
use axum::routing::get;
use axum::Router;
use std::net::SocketAddr;
use std::sync::Arc;

/// Renders the metrics text at scrape time (so gauges can be read from live state then).
pub type RenderFn = Arc<dyn Fn() -> String + Send + Sync>;
/// Whether the process should receive work now (readiness probe).
pub type ReadyFn = Arc<dyn Fn() -> bool + Send + Sync>;

/// Content type of the OpenMetrics text format that prometheus-client writes.
pub const OPENMETRICS: &str = "application/openmetrics-text; version=1.0.0; charset=utf-8";

/// Binds `addr` and serves the three endpoints in a background task until the runtime stops. Returns the
/// bound address (port 0 picks a free port).
pub async fn serve(
    addr: SocketAddr,
    render: RenderFn,
    ready: ReadyFn,
) -> std::io::Result<(SocketAddr, tokio::task::JoinHandle<()>)> {
    let listener = tokio::net::TcpListener::bind(addr).await?;
    let bound = listener.local_addr()?;
    let app = Router::new()
        .route(
            "/metrics",
            get(move || {
                let render = Arc::clone(&render);
                async move { ([(header::CONTENT_TYPE, OPENMETRICS)], render()) }
            }),
        )
        .route("/healthz", get(|| async { "ok\n" }))
        .route(
            "/readyz",
            get(move || {
                let ready = Arc::clone(&ready);
                async move {
                    if ready() {
                        (StatusCode::OK, "ready\n").into_response()
                    } else {
                        (StatusCode::SERVICE_UNAVAILABLE, "not ready\n").into_response()
                    }
                }
            }),
        );
    let handle = tokio::spawn(async move {
        if let Err(e) = axum::serve(listener, app).await {
            tracing::error!(error = %e, "metrics server stopped");
        }
    });
    Ok((bound, handle))
}

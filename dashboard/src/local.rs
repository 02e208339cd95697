//! The dashboard's page without a coordinator: `crease view FOLDER` serves the viewer and the report of one
//! local folder with the same page, assets and viewer handler as the job page ([`crate::viewer::routes`]),
//! under the fixed id [`LOCAL_ID`]. Nothing else is routed: no queue, no actions, no event stream.

use crate::viewer::folder::{Folder, LOCAL_ID};
use crate::viewer::Viewer;
use crate::{api, assets, viewer};
use axum::routing::get;
use axum::Router;
use std::net::SocketAddr;
use std::sync::Arc;

/// The routes of a local viewer.
pub fn router(viewer: Arc<Viewer>) -> Router {
    Router::new()
        .route("/", get(assets::local_index))
        .route("/assets/{name}", get(assets::asset))
        .route("/api/jobs/{id}/view/{name}", get(viewer::routes::file))
        .fallback(api::not_found)
        .layer(axum::middleware::from_fn(assets::security_headers))
        .with_state(viewer)
}

/// The page's URL for a server bound at `addr`.
pub fn url(addr: SocketAddr) -> String {
    format!("http://{addr}/#/view/{LOCAL_ID}")
}

/// Binds `addr` and serves `folder` until the runtime stops; returns the bound address (port 0 picks one).
pub async fn serve(
    folder: Folder,
    addr: SocketAddr,
) -> std::io::Result<(SocketAddr, tokio::task::JoinHandle<()>)> {
    let app = router(Viewer::new(folder));
    let listener = tokio::net::TcpListener::bind(addr).await?;
    let bound = listener.local_addr()?;
    let handle = tokio::spawn(async move {
        if let Err(e) = axum::serve(listener, app).await {
            tracing::error!(error = %e, "viewer server stopped");
        }
    });
    Ok((bound, handle))
}

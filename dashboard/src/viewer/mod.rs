//! The 3D before/after viewer's data: a finished output folder (or an input alone) as what a WebGL page needs,
//! served under `/api/jobs/{id}/view/{name}` by the coordinator's dashboard and by `crease view` alike (one
//! handler, [`routes::file`], two mounts; only how an id becomes folders differs, [`Locate`]).
//!
//! A page cannot read OBJ, PLY or PC2 cheaply, and a 100K-triangle sequence is tens of megabytes of text per
//! frame. So the server parses each frame once with crease-core's own readers and sends it as little-endian
//! `f32` positions in one binary buffer per frame ([`frame_buffer`]), with one shared index buffer: the page
//! opens on the first frame after two small requests and fetches the others while it is already showing.
//! The overlays that need the mesh maths (per-triangle stretch of output against input, displacement per
//! vertex) are computed here, with the very definitions `report.json` quotes, so the colours and the report's
//! figures measure the same thing.

pub mod folder;
pub mod frame_buffer;
pub mod job_folders;
pub mod locate;
pub mod names;
pub mod routes;
pub mod scene;
mod scenes;

pub use locate::{Locate, LocateError, Located};

use std::sync::Arc;

/// What both mounts share: how ids become folders, and the scenes opened so far.
pub struct Viewer {
    locate: Box<dyn Locate>,
    scenes: scenes::Scenes,
}

impl Viewer {
    pub fn new(locate: impl Locate + 'static) -> Arc<Self> {
        Arc::new(Viewer {
            locate: Box::new(locate),
            scenes: scenes::Scenes::default(),
        })
    }

    pub fn locate(&self, id: &str) -> Result<Located, LocateError> {
        self.locate.locate(id)
    }
}

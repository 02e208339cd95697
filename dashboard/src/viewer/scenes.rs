//! Scenes opened so far, so the page's dozens of frame requests do not each reopen the folders. A scene is
//! found again by what it was opened from and a stamp of it (`report.json`'s size and time, rewritten last by
//! every run), so a rerun's output is opened afresh. Requests that arrive while a scene opens wait for that one
//! opening instead of starting their own.

use super::scene::{Scene, SceneError};
use super::Located;
use std::path::Path;
use std::sync::{Arc, Mutex, OnceLock};
use std::time::SystemTime;

/// Scenes kept open (each holds a mesh topology and its anchors, not its frames).
const KEPT: usize = 4;

type Slot = Arc<OnceLock<Result<Arc<Scene>, SceneError>>>;

#[derive(Default)]
pub(super) struct Scenes {
    open: Mutex<Vec<(Key, Slot)>>,
}

#[derive(Debug, Clone, PartialEq)]
struct Key {
    located: Located,
    stamp: Option<(u64, SystemTime)>,
}

fn stamp(loc: &Located) -> Option<(u64, SystemTime)> {
    let path = match (&loc.output, &loc.input) {
        (Some(out), _) => out.join("report.json"),
        (None, Some(inp)) => inp.clone(),
        (None, None) => return None,
    };
    let m = std::fs::metadata(Path::new(&path)).ok()?;
    Some((m.len(), m.modified().ok()?))
}

impl Scenes {
    /// The scene of `loc`, opened now or earlier. A failed opening is not kept: the next request tries again.
    pub(super) fn get(&self, loc: &Located) -> Result<Arc<Scene>, SceneError> {
        let key = Key {
            located: loc.clone(),
            stamp: stamp(loc),
        };
        let slot = {
            let mut open = self.open.lock().unwrap_or_else(|p| p.into_inner());
            match open.iter().position(|(k, _)| *k == key) {
                Some(i) => {
                    let entry = open.remove(i);
                    let slot = entry.1.clone();
                    open.insert(0, entry);
                    slot
                }
                None => {
                    let slot = Slot::default();
                    open.insert(0, (key.clone(), slot.clone()));
                    open.truncate(KEPT);
                    slot
                }
            }
        };
        let got = slot.get_or_init(|| Scene::open(loc).map(Arc::new)).clone();
        if got.is_err() {
            let mut open = self.open.lock().unwrap_or_else(|p| p.into_inner());
            open.retain(|(k, s)| !(*k == key && Arc::ptr_eq(s, &slot)));
        }
        got
    }
}

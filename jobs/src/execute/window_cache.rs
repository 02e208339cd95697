//! What the weight-block tasks of one window share, kept between tasks on a worker.
//!
//! A per-anchor window is split into many block tasks, and a worker usually runs several blocks of the same
//! window in a row. Without this cache each of them rebuilt the window's anchor list and operator and
//! allocated (and page-faulted in) a fresh block workspace of about 29 bytes per window node — 29 MB at
//! paper scale — which is a large share of a 100 ms block.
//!
//! An entry holds the window's [`WindowProblem`] (anchor list and operator) together with the opened input
//! whose topology the operator borrows, and the spare workspaces of finished blocks. It is keyed by a
//! fingerprint of everything the window's arithmetic depends on: the job spec (serialized), the input's
//! identity (the opened input is reopened when any of its files changes size or modification time, and an
//! entry only matches the very same opened input), the anchors' fingerprint (the anchors file's stamp, or the
//! bytes of detected anchors) and the window index. A resubmitted job whose inputs changed therefore never
//! meets an old entry; it builds its own and the old one ages out.
//!
//! Memory is bounded by a byte budget (least recently used entries are dropped first; an entry larger than
//! the whole budget is used once and not kept). A workspace is returned to its entry only after its block
//! succeeded: a failed block may leave it half-written, so it is dropped instead.

use crease_core::mesh::io::OpenedSequence;
use crease_core::mesh::Topology;
use crease_core::spacetime::weights::per_anchor::BlockWorkspace;
use crease_core::spacetime::weights::WindowProblem;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

/// Default byte budget of a worker's window cache (`crease worker --window-cache-mb`).
pub const DEFAULT_BUDGET_BYTES: u64 = 512 << 20;

static BUDGET: AtomicU64 = AtomicU64::new(DEFAULT_BUDGET_BYTES);
static CACHE: Mutex<Vec<Slot>> = Mutex::new(Vec::new());
static CLOCK: AtomicU64 = AtomicU64::new(0);

/// Sets the byte budget of this process's window cache (0 turns it off) and trims it to fit.
pub fn set_budget(bytes: u64) {
    BUDGET.store(bytes, Ordering::Relaxed);
    let mut slots = lock();
    trim(&mut slots, bytes);
}

/// The current byte budget.
pub fn budget() -> u64 {
    BUDGET.load(Ordering::Relaxed)
}

/// Entries and bytes currently held (for logs and tests).
pub fn usage() -> (usize, u64) {
    let slots = lock();
    (slots.len(), slots.iter().map(|s| s.entry.bytes()).sum())
}

fn lock() -> std::sync::MutexGuard<'static, Vec<Slot>> {
    CACHE.lock().unwrap_or_else(|p| p.into_inner())
}

struct Slot {
    key: u64,
    used: u64,
    entry: Arc<WindowEntry>,
}

/// One window's shared state. The problem borrows `topology` (the input's), which the entry keeps alive; `input`
/// is kept for identity: an entry only serves tasks that opened the very same input.
pub struct WindowEntry {
    // Field order matters: `problem` borrows from `_topology` and must be dropped first.
    problem: WindowProblem<'static>,
    _topology: Arc<Topology>,
    input: Arc<OpenedSequence>,
    workspace_bytes: u64,
    fixed_bytes: u64,
    spare: Mutex<Vec<BlockWorkspace>>,
}

impl WindowEntry {
    /// Builds the entry: `make` receives the topology (borrowed from `input`) and returns the window problem.
    pub fn build<E>(
        input: Arc<OpenedSequence>,
        make: impl for<'t> FnOnce(&'t Topology) -> Result<WindowProblem<'t>, E>,
    ) -> Result<Self, E> {
        let topology = Arc::clone(input.source.topology());
        let topo: *const Topology = Arc::as_ptr(&topology);
        // SAFETY: `topo` points into the `Arc<Topology>` this entry holds (`topology`) for its whole life, and
        // an `Arc`'s contents never move nor are handed out mutably while it is shared. `problem` is declared
        // before `topology`, so it is dropped first. Nothing outside the entry sees the `'static` lifetime:
        // `problem()` reborrows it with the entry's own lifetime.
        let problem = make(unsafe { &*topo })?;
        let n = problem.op.n_nodes() as u64;
        let fixed_bytes = n * 8 + problem.anchors.len() as u64 * 32;
        Ok(WindowEntry {
            problem,
            _topology: topology,
            input,
            workspace_bytes: n * 29,
            fixed_bytes,
            spare: Mutex::new(Vec::new()),
        })
    }

    pub fn problem(&self) -> &WindowProblem<'_> {
        &self.problem
    }

    /// Whether this entry was built from exactly this opened input.
    pub fn same_input(&self, input: &Arc<OpenedSequence>) -> bool {
        Arc::ptr_eq(&self.input, input)
    }

    /// A workspace for one block: a spare one when there is one, else a new one.
    pub fn take_workspace(&self) -> BlockWorkspace {
        let spare = self.spare.lock().unwrap_or_else(|p| p.into_inner()).pop();
        spare.unwrap_or_else(|| BlockWorkspace::new(self.problem.op.n_nodes()))
    }

    /// Gives back the workspace of a block that succeeded (it is clean again; see the module docs), then trims
    /// the cache, which this workspace may have pushed over its budget.
    pub fn give_back(&self, ws: BlockWorkspace) {
        self.spare
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .push(ws);
        trim(&mut lock(), budget());
    }

    /// Approximate heap bytes held: operator diagonal, anchor list and the spare workspaces.
    pub fn bytes(&self) -> u64 {
        let spare = self.spare.lock().unwrap_or_else(|p| p.into_inner()).len() as u64;
        self.fixed_bytes + spare * self.workspace_bytes
    }

    /// Bytes the entry holds while one block runs (for the admission check).
    fn working_bytes(&self) -> u64 {
        self.fixed_bytes + self.workspace_bytes
    }
}

/// The entry under `key` built from `input`, or a new one from `build`. Returns whether it was a hit.
pub fn get_or_build<E>(
    key: u64,
    input: &Arc<OpenedSequence>,
    build: impl FnOnce() -> Result<WindowEntry, E>,
) -> Result<(Arc<WindowEntry>, bool), E> {
    let now = CLOCK.fetch_add(1, Ordering::Relaxed);
    {
        let mut slots = lock();
        if let Some(s) = slots
            .iter_mut()
            .find(|s| s.key == key && s.entry.same_input(input))
        {
            s.used = now;
            return Ok((s.entry.clone(), true));
        }
    }
    // Built outside the lock: another window's tasks need not wait. Two tasks of one window that miss at the
    // same time both build; the second insert replaces the first, which is equal.
    let entry = Arc::new(build()?);
    let budget = budget();
    if entry.working_bytes() <= budget {
        let mut slots = lock();
        slots.retain(|s| s.key != key);
        slots.push(Slot {
            key,
            used: now,
            entry: entry.clone(),
        });
        trim(&mut slots, budget);
    }
    Ok((entry, false))
}

/// Drops least recently used entries until the cache fits `budget`.
fn trim(slots: &mut Vec<Slot>, budget: u64) {
    loop {
        let total: u64 = slots.iter().map(|s| s.entry.bytes()).sum();
        if total <= budget || slots.is_empty() {
            return;
        }
        let oldest = slots
            .iter()
            .enumerate()
            .min_by_key(|(_, s)| s.used)
            .map(|(i, _)| i)
            .unwrap_or(0);
        slots.swap_remove(oldest);
    }
}

/// FNV-1a over several byte strings (length-prefixed so that concatenations cannot collide trivially).
pub fn fingerprint(parts: &[&[u8]]) -> u64 {
    let mut h = 0xcbf29ce484222325u64;
    for p in parts {
        for &b in (p.len() as u64).to_le_bytes().iter().chain(p.iter()) {
            h = (h ^ b as u64).wrapping_mul(0x100000001b3);
        }
    }
    h
}

//! One coordinator per queue file. Two coordinators on one queue would each recover the other's running
//! tasks and dispatch them again, so the first takes an exclusive OS lock on `<queue>.lock` beside the queue
//! file and writes its pid and listen address there; a second one finds the lock taken and refuses, naming
//! that holder. The OS drops the lock when the holder's process ends however it ends (even SIGKILL), so a
//! crashed coordinator never leaves a stale lock behind: the file may remain, the lock does not.

use std::fs::{File, OpenOptions, TryLockError};
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// The held lock; dropping it (or the process ending) releases it.
#[derive(Debug)]
pub struct QueueLock {
    file: File,
    path: PathBuf,
}

/// Why the lock could not be taken.
#[derive(Debug, thiserror::Error)]
pub enum LockError {
    #[error(
        "queue file {db} is in use by another coordinator ({holder}; lock {lock}): stop that coordinator first, \
         or give this one another --db"
    )]
    Held {
        db: String,
        lock: String,
        holder: String,
    },
    #[error("queue file {db}: cannot use the lock file {lock}: {source}")]
    Io {
        db: String,
        lock: String,
        source: std::io::Error,
    },
}

/// `<queue file>.lock`, beside it.
pub fn lock_path(db: &Path) -> PathBuf {
    let mut name = db.file_name().unwrap_or_default().to_os_string();
    name.push(".lock");
    db.with_file_name(name)
}

impl QueueLock {
    /// Takes the lock of queue file `db` for this process, recording `listen` as where it serves.
    pub fn acquire(db: &Path, listen: &str) -> Result<Self, LockError> {
        let path = lock_path(db);
        let io = |source| LockError::Io {
            db: db.display().to_string(),
            lock: path.display().to_string(),
            source,
        };
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .map_err(io)?;
        match file.try_lock() {
            Ok(()) => {}
            Err(TryLockError::WouldBlock) => {
                let mut text = String::new();
                let _ = file.read_to_string(&mut text);
                return Err(LockError::Held {
                    db: db.display().to_string(),
                    lock: path.display().to_string(),
                    holder: describe_holder(&text),
                });
            }
            Err(TryLockError::Error(e)) => return Err(io(e)),
        }
        let mut lock = QueueLock {
            file,
            path: path.clone(),
        };
        lock.record(listen).map_err(io)?;
        Ok(lock)
    }

    /// Rewrites the holder's line once the real listen address is known (a `:0` port is bound).
    pub fn record(&mut self, listen: &str) -> std::io::Result<()> {
        self.file.set_len(0)?;
        self.file.seek(SeekFrom::Start(0))?;
        writeln!(self.file, "pid={}\nlisten={listen}", std::process::id())?;
        self.file.sync_data()
    }

    pub fn path(&self) -> &Path {
        &self.path
    }
}

/// "pid 123, listening on 127.0.0.1:7070" from the lock file's lines (what an older or odd file lacks is
/// said to be unknown).
fn describe_holder(text: &str) -> String {
    let field = |k: &str| {
        text.lines()
            .find_map(|l| l.strip_prefix(k)?.strip_prefix('='))
            .map(str::trim)
            .filter(|v| !v.is_empty())
            .unwrap_or("unknown")
            .to_string()
    };
    format!("pid {}, listening on {}", field("pid"), field("listen"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_lock_on_the_same_queue_is_refused_naming_the_holder_and_freed_on_drop() {
        let dir = tempfile::tempdir().unwrap();
        let db = dir.path().join("queue.sqlite");
        let mut first = QueueLock::acquire(&db, "127.0.0.1:0").unwrap();
        first.record("127.0.0.1:7070").unwrap();
        let e = QueueLock::acquire(&db, "127.0.0.1:7071")
            .unwrap_err()
            .to_string();
        let me = format!("pid {}", std::process::id());
        assert!(
            e.contains(&me) && e.contains("127.0.0.1:7070") && e.contains("queue.sqlite"),
            "{e}"
        );
        assert_eq!(first.path(), lock_path(&db));
        drop(first);
        QueueLock::acquire(&db, "127.0.0.1:7071").unwrap();
    }
}

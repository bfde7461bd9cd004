//! The lock on a run directory (`DIR/.tissuefit.lock`): one `tissuefit run` (or sweep) at a time
//! writes into a folder, so a second run cannot delete or overwrite the stages of the first.
//!
//! It is an advisory lock on an open file (`flock` on unix, `LockFileEx` on Windows, through
//! [`std::fs::File::try_lock`]), held for the whole run. The operating system releases it when the
//! process ends, however it ends (Ctrl-C, SIGTERM, kill -9, a cluster's time limit, a crash), so a
//! stale lock is impossible: a lock that is held belongs to a live process. The file itself stays
//! (removing it would let two processes lock two different files of one name); it records the
//! process id of the last exclusive holder, which the refusal names so the user can check it
//! (`ps -p PID`). Sweeps take the sweep folder's lock shared for job-array tasks (`--index`, which
//! run side by side, each into its own run folder, locked exclusively) and exclusive otherwise.
//!
//! Advisory locks on network file systems depend on the server (NFSv4 and Lustre honour them; some
//! older NFS mounts do not): there the lock may not protect.

use super::PipelineError;
use std::fs::{File, TryLockError};
use std::io::{Read, Seek, Write};
use std::path::{Path, PathBuf};

/// Name of the lock file inside a run or sweep directory.
pub const LOCK_FILE: &str = ".tissuefit.lock";

/// A held lock; released when dropped (or when the process ends).
#[derive(Debug)]
pub struct DirLock {
    _file: File,
    pub path: PathBuf,
}

impl DirLock {
    /// Locks `dir` (created if missing) for this process alone, or fails at once naming the holder.
    pub fn exclusive(dir: &Path) -> Result<DirLock, PipelineError> {
        acquire(dir, false)
    }

    /// Locks `dir` shared: other shared holders may run beside it, an exclusive one may not.
    pub fn shared(dir: &Path) -> Result<DirLock, PipelineError> {
        acquire(dir, true)
    }
}

fn acquire(dir: &Path, shared: bool) -> Result<DirLock, PipelineError> {
    let io = |path: &Path, e: std::io::Error| PipelineError::Io { path: path.to_path_buf(), message: e.to_string() };
    std::fs::create_dir_all(dir).map_err(|e| io(dir, e))?;
    let path = dir.join(LOCK_FILE);
    crate::io::check_target("the lock file", &path)
        .map_err(|e| PipelineError::Io { path: path.clone(), message: e.to_string() })?;
    let mut file = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .create(true)
        .truncate(false)
        .open(&path)
        .map_err(|e| io(&path, e))?;
    let locked = if shared { file.try_lock_shared() } else { file.try_lock() };
    match locked {
        Ok(()) => {}
        Err(TryLockError::WouldBlock) => {
            let mut holder = String::new();
            let _ = file.read_to_string(&mut holder);
            let holder = holder.trim();
            let who = if holder.is_empty() || shared {
                "another tissuefit process".to_string()
            } else {
                format!("another tissuefit process (process id {holder}, the last to lock it exclusively)")
            };
            let check = if holder.is_empty() { String::new() } else { format!(" (`ps -p {holder}`)") };
            return Err(PipelineError::Locked {
                dir: dir.to_path_buf(),
                message: format!(
                    "{who} is writing into it, and two runs into one folder would overwrite each other. Wait for \
                     it to finish, stop it, or choose another --out. To see whether it is alive{check}: the lock \
                     {} is released the moment that process ends, even by kill -9, so a held lock always belongs \
                     to a live process",
                    path.display()
                ),
            });
        }
        Err(TryLockError::Error(e)) => return Err(io(&path, e)),
    }
    if !shared {
        // Our process id, for the message a second run gets.
        let written =
            file.set_len(0).and_then(|()| file.rewind()).and_then(|()| writeln!(file, "{}", std::process::id()));
        written.map_err(|e| io(&path, e))?;
    }
    Ok(DirLock { _file: file, path })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_lock_fails_at_once_naming_the_holder_and_a_dropped_lock_is_free() {
        let dir = tempfile::tempdir().unwrap();
        let first = DirLock::exclusive(dir.path()).unwrap();
        let e = DirLock::exclusive(dir.path()).unwrap_err().to_string();
        assert!(e.contains(&dir.path().display().to_string()), "{e}");
        assert!(e.contains(&format!("process id {}", std::process::id())) && e.contains("kill -9"), "{e}");
        assert!(DirLock::shared(dir.path()).is_err());
        drop(first);
        let a = DirLock::shared(dir.path()).unwrap();
        let _b = DirLock::shared(dir.path()).unwrap();
        assert!(DirLock::exclusive(dir.path()).is_err());
        drop(a);
    }
}

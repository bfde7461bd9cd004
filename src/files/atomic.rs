//! Crash-safe output: write to a temporary sibling, then rename over the target, so a crash or an
//! error never leaves a half-written file that looks complete.

use super::FileError;
use super::output::OutputGroup;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

/// Writes `path` through `write`, atomically: the data goes to `path.tmp-<pid>` first and is renamed
/// into place only when `write` succeeded and the data is flushed. On error the temporary is removed.
/// The output policy applies ([`super::output`]): a target that is a directory, a device, a FIFO or
/// a socket is refused, never replaced.
pub fn write_atomically<F>(path: &Path, write: F) -> Result<(), FileError>
where
    F: FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
{
    let mut group = OutputGroup::new();
    group.write(path, write)?;
    group.commit()
}

/// Whether `name` is a temporary of [`write_atomically`]: `<file>.tmp-<process id>`.
fn is_temporary(name: &str) -> bool {
    name.rsplit_once(".tmp-")
        .is_some_and(|(file, pid)| !file.is_empty() && !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit()))
}

/// Removes the temporaries of [`write_atomically`] that a killed process left in `dir` (not its
/// subfolders); returns how many. A missing `dir` has none.
pub fn remove_stale_temporaries(dir: &Path) -> Result<usize, FileError> {
    remove_temporaries_where(dir, |_| true)
}

/// [`remove_stale_temporaries`] for the files named `names` only (`manifest.json` →
/// `manifest.json.tmp-<process id>`): for a folder that also holds the user's files.
pub fn remove_stale_temporaries_of(dir: &Path, names: &[&str]) -> Result<usize, FileError> {
    remove_temporaries_where(dir, |file| names.contains(&file))
}

/// Removes the temporaries in `dir` whose target file name passes `target`.
fn remove_temporaries_where(dir: &Path, target: impl Fn(&str) -> bool) -> Result<usize, FileError> {
    let entries = match std::fs::read_dir(dir) {
        Ok(entries) => entries,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(0),
        Err(source) => return Err(FileError::Open { path: dir.to_path_buf(), source }),
    };
    let mut removed = 0;
    for entry in entries.flatten() {
        let path = entry.path();
        let name = entry.file_name();
        let ours =
            name.to_str().is_some_and(|n| is_temporary(n) && n.rsplit_once(".tmp-").is_some_and(|(f, _)| target(f)));
        if ours && path.is_file() {
            std::fs::remove_file(&path).map_err(|source| FileError::Write { path: path.clone(), source })?;
            removed += 1;
        }
    }
    Ok(removed)
}

/// Convenience for writers that produce the whole file in memory.
pub fn write_bytes_atomically(path: &Path, bytes: &[u8]) -> Result<(), FileError> {
    write_atomically(path, |w| w.write_all(bytes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stale_temporaries_are_removed_and_nothing_else() {
        let dir = tempfile::tempdir().unwrap();
        for name in ["frame_000002.vtp.tmp-13026", "a.tmp-1", "frame_000001.vtp", "notes.tmp-x", ".tmp-12", "b.tmp-"] {
            std::fs::write(dir.path().join(name), b"x").unwrap();
        }
        assert_eq!(remove_stale_temporaries(dir.path()).unwrap(), 2);
        let mut left: Vec<String> =
            std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
        left.sort();
        assert_eq!(left, [".tmp-12", "b.tmp-", "frame_000001.vtp", "notes.tmp-x"]);
        assert_eq!(remove_stale_temporaries(&dir.path().join("missing")).unwrap(), 0);
        for name in ["manifest.json.tmp-7", "notes.txt.tmp-7", "manifest.json"] {
            std::fs::write(dir.path().join(name), b"x").unwrap();
        }
        assert_eq!(remove_stale_temporaries_of(dir.path(), &["manifest.json", "results.csv"]).unwrap(), 1);
        assert!(dir.path().join("notes.txt.tmp-7").exists() && dir.path().join("manifest.json").exists());
    }
}

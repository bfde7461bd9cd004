//! Reading a whole input file into memory with a size cap. A regular file's size is known and
//! checked before reading; anything else (a pipe, a terminal, `/dev/zero`, a symlink to one) is
//! read up to a smaller cap, [`UNSIZED_CAP`], and refused when it yields more, so that a path to an
//! endless stream is a clear error instead of reading until memory runs out.

use std::io::Read;
use std::path::Path;

/// Largest tissue file read (bytes): 4 GiB, ~40 times a 1000-cell tissue of 2000 nodes each in ASCII.
pub const MAX_TISSUE_FILE: u64 = 4 << 30;
/// Largest text configuration file read (parameters, pipeline, fit, sweep; bytes): 64 MiB.
pub const MAX_CONFIG_FILE: u64 = 64 << 20;
/// Most bytes read from a file whose size is not known in advance (a pipe, a device): 256 MiB.
/// Copy larger data into a regular file.
pub const UNSIZED_CAP: u64 = 256 << 20;

/// The bytes of `path`, at most `cap` of them (and at most [`UNSIZED_CAP`] from a file that is not
/// a regular file); a larger input is an `InvalidData` error saying which limit it broke. The
/// error does not name the path: callers add it, as for any other read error.
pub fn read_capped(path: &Path, cap: u64) -> std::io::Result<Vec<u8>> {
    let file = std::fs::File::open(path)?;
    let meta = file.metadata()?;
    if meta.is_dir() {
        return Err(std::io::Error::new(std::io::ErrorKind::IsADirectory, "is a directory, not a file"));
    }
    let (cap, regular) = if meta.is_file() { (cap, true) } else { (cap.min(UNSIZED_CAP), false) };
    if regular && meta.len() > cap {
        return Err(too_large(meta.len(), cap, true));
    }
    let mut bytes = Vec::with_capacity(if regular { meta.len() as usize } else { 0 });
    file.take(cap.saturating_add(1)).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > cap {
        return Err(too_large(bytes.len() as u64, cap, regular));
    }
    Ok(bytes)
}

/// Like [`read_capped`], for UTF-8 text.
pub fn read_text_capped(path: &Path, cap: u64) -> std::io::Result<String> {
    String::from_utf8(read_capped(path, cap)?)
        .map_err(|_| std::io::Error::new(std::io::ErrorKind::InvalidData, "stream did not contain valid UTF-8"))
}

fn too_large(size: u64, cap: u64, regular: bool) -> std::io::Error {
    let message = if regular {
        format!(
            "the file has {size} bytes, more than the {cap} bytes read for this kind of input; is it the right file?"
        )
    } else {
        format!(
            "not a regular file (a pipe or device?) and it gave more than {cap} bytes, the most read from a stream of \
             unknown size; give a regular file"
        )
    };
    std::io::Error::new(std::io::ErrorKind::InvalidData, message)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regular_files_are_read_up_to_the_cap() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.toml");
        std::fs::write(&path, "x = 1\n").unwrap();
        assert_eq!(read_text_capped(&path, 6).unwrap(), "x = 1\n");
        let err = read_capped(&path, 5).unwrap_err();
        assert!(err.to_string().contains("6 bytes, more than the 5"), "{err}");
        assert!(read_capped(dir.path(), 100).is_err());
    }

    #[cfg(unix)]
    #[test]
    fn an_endless_device_stops_at_the_cap() {
        let dir = tempfile::tempdir().unwrap();
        let link = dir.path().join("zero.vtk");
        std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
        let err = read_capped(&link, 1 << 20).unwrap_err();
        assert!(err.to_string().contains("not a regular file") && err.to_string().contains("1048576"), "{err}");
    }
}

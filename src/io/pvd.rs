//! ParaView collection (`.pvd`): the index of a time series of `.vtp` frames, so that ParaView opens the
//! whole series as one dataset with a time axis. Rewritten (atomically) after every frame, so a
//! running or crashed simulation always leaves a valid index of the frames written so far.

use super::vtp::escape_xml;
use super::{IoError, write_atomically};
use crate::geometry::Real;
use std::fmt::Write as _;
use std::io::{self, Write};
use std::path::{Path, PathBuf};

/// One frame of a series.
#[derive(Clone, Debug, PartialEq)]
pub struct PvdEntry {
    /// Simulated time of the frame (s).
    pub time: Real,
    /// Path of the `.vtp` file relative to the `.pvd`'s folder.
    pub file: PathBuf,
}

/// Writes the collection file `path` listing `entries` in the given order, atomically.
pub fn write_pvd(path: &Path, entries: &[PvdEntry]) -> Result<(), IoError> {
    let invalid = |message: String| IoError::Write {
        path: path.to_path_buf(),
        source: io::Error::new(io::ErrorKind::InvalidInput, message),
    };
    let mut s = String::with_capacity(256 + 96 * entries.len());
    s.push_str("<?xml version=\"1.0\"?>\n");
    s.push_str("<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n");
    s.push_str("  <Collection>\n");
    for (k, entry) in entries.iter().enumerate() {
        if !entry.time.is_finite() {
            return Err(invalid(format!("entry {k}: time {} is not finite", entry.time)));
        }
        let file = entry
            .file
            .to_str()
            .ok_or_else(|| invalid(format!("entry {k}: file name {} is not valid UTF-8", entry.file.display())))?;
        let file = if std::path::MAIN_SEPARATOR == '/' {
            file.to_owned()
        } else {
            file.replace(std::path::MAIN_SEPARATOR, "/")
        };
        // `{:e}` prints the shortest digits that read back to the same f64.
        let _ = writeln!(
            s,
            "    <DataSet timestep=\"{:e}\" group=\"\" part=\"0\" file=\"{}\"/>",
            entry.time,
            escape_xml(&file)
        );
    }
    s.push_str("  </Collection>\n</VTKFile>\n");
    write_atomically(path, |w| w.write_all(s.as_bytes())).map_err(IoError::from)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn collection_lists_entries_in_order() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("series.pvd");
        let entries = vec![
            PvdEntry { time: 0.0, file: PathBuf::from("frames/frame_0000.vtp") },
            PvdEntry { time: 1.0 / 3.0 * 1e-3, file: PathBuf::from("frames/frame_0001.vtp") },
            PvdEntry { time: 2.5e-3, file: PathBuf::from("frames/a&b <\"2\">.vtp") },
        ];
        write_pvd(&path, &entries).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let doc = roxmltree::Document::parse(&text).unwrap();
        let root = doc.root_element();
        assert_eq!(root.attribute("type"), Some("Collection"));
        let sets: Vec<_> = doc.descendants().filter(|n| n.has_tag_name("DataSet")).collect();
        assert_eq!(sets.len(), entries.len());
        for (node, entry) in sets.iter().zip(&entries) {
            assert_eq!(node.attribute("file"), entry.file.to_str());
            let t: f64 = node.attribute("timestep").unwrap().parse().unwrap();
            assert_eq!(t.to_bits(), entry.time.to_bits());
            assert_eq!(node.attribute("part"), Some("0"));
            assert_eq!(node.parent_element().unwrap().tag_name().name(), "Collection");
        }
        // Rewriting with more entries replaces the file.
        write_pvd(&path, &entries[..1]).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(text.matches("<DataSet").count(), 1);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn non_finite_time_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("series.pvd");
        let entries = [PvdEntry { time: Real::NAN, file: PathBuf::from("a.vtp") }];
        let err = write_pvd(&path, &entries).unwrap_err();
        assert!(err.to_string().contains("series.pvd"), "{err}");
        assert!(!path.exists());
    }
}

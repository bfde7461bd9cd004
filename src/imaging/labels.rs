//! The one entry point for reading a label volume, whatever its format: [`read_labels`] looks at the
//! content (TIFF magic bytes, the `\x93NUMPY` magic, the HDF5 signature, a folder or a Zarr metadata
//! file; `FILE.h5/DATASET` for a dataset inside an HDF5 file) and hands the path to the reader of
//! that format; the extension is only a fallback for a file whose content says nothing (a truncated
//! or empty file), so that its error comes from the reader it was meant for.
//! A new format is one reader file in this module plus one arm here.
//!
//! Every reader reports where the voxel size came from ([`VoxelSizeSource`]): the caller's override
//! ([`LabelReadOptions::voxel_size`]), the file's metadata (TIFF ImageJ/OME, OME-Zarr multiscales,
//! HDF5 `element_size_um`), or — with a warning — [`LabelReadOptions::fallback_voxel_size`] (a
//! `.npy` never has one).

use super::metadata::VoxelSizeSource;
use super::{ImagingError, LabelRead, LabelReadOptions};
use crate::geometry::Real;
use std::io::Read;
use std::path::Path;

/// The formats [`read_labels`] reads, as named in errors.
pub const SUPPORTED_FORMATS: &str = "TIFF stacks (.tif/.tiff), OME-Zarr label or image groups (a .zarr folder, \
                                     NGFF 0.4 on Zarr v2 or 0.5 on Zarr v3), HDF5 datasets (.h5/.hdf5, as PlantSeg \
                                     writes them; FILE.h5/DATASET names one) and NumPy arrays (.npy)";

/// A label volume format.
#[derive(Copy, Clone, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LabelFormat {
    /// Multi-page TIFF (`tiff_read.rs`).
    Tiff,
    /// OME-Zarr multiscales group, NGFF 0.4 (Zarr v2) or 0.5 (Zarr v3) (`zarr_read.rs`).
    OmeZarr,
    /// NumPy `.npy` array (`npy_read.rs`).
    Npy,
    /// HDF5 dataset (`h5_read.rs`).
    Hdf5,
}

impl std::fmt::Display for LabelFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            LabelFormat::Tiff => "TIFF",
            LabelFormat::OmeZarr => "OME-Zarr",
            LabelFormat::Npy => "NumPy .npy",
            LabelFormat::Hdf5 => "HDF5",
        })
    }
}

/// Zarr metadata file names: a path naming one of them stands for the folder holding it.
pub(crate) const ZARR_METADATA_FILES: [&str; 4] = ["zarr.json", ".zattrs", ".zgroup", ".zarray"];

/// The format of `path` from its content: a folder (or a Zarr metadata file) is OME-Zarr, a file
/// starting with a TIFF, NumPy or HDF5 magic number is that, and a path inside an HDF5 file
/// (`FILE.h5/DATASET`) is HDF5. `None` when the content says nothing (a
/// missing, unreadable, empty or foreign file).
pub fn detect_label_format(path: &Path) -> Option<LabelFormat> {
    if path.is_dir() {
        return Some(LabelFormat::OmeZarr);
    }
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
    if ZARR_METADATA_FILES.contains(&name) {
        return Some(LabelFormat::OmeZarr);
    }
    if !path.exists() && super::h5_read::split_hdf5_path(path).is_some() {
        return Some(LabelFormat::Hdf5);
    }
    let mut magic = [0u8; 8];
    let mut file = std::fs::File::open(path).ok()?;
    let mut filled = 0;
    while filled < magic.len() {
        match file.read(&mut magic[filled..]) {
            Ok(0) | Err(_) => break,
            Ok(n) => filled += n,
        }
    }
    let magic = &magic[..filled];
    if magic.len() >= 4 && matches!(&magic[..4], b"II*\0" | b"MM\0*" | b"II+\0" | b"MM\0+") {
        return Some(LabelFormat::Tiff);
    }
    if magic.len() >= 6 && &magic[..6] == b"\x93NUMPY" {
        return Some(LabelFormat::Npy);
    }
    if magic == super::h5_read::HDF5_MAGIC {
        return Some(LabelFormat::Hdf5);
    }
    None
}

/// The format the extension of `path` promises (.tif/.tiff, .zarr, .npy, .h5/.hdf5/.hdf), if any.
pub fn label_format_from_extension(path: &Path) -> Option<LabelFormat> {
    let ext = path.extension().and_then(|e| e.to_str())?.to_ascii_lowercase();
    match ext.as_str() {
        "tif" | "tiff" => Some(LabelFormat::Tiff),
        "zarr" => Some(LabelFormat::OmeZarr),
        "npy" => Some(LabelFormat::Npy),
        "h5" | "hdf5" | "hdf" => Some(LabelFormat::Hdf5),
        _ => None,
    }
}

/// Whether `path` is to be read as a label volume (by content, else by extension) rather than as
/// a tissue mesh: what `measure` and `tensions` use to tell their two kinds of input apart.
pub fn is_label_volume(path: &Path) -> bool {
    detect_label_format(path).or_else(|| label_format_from_extension(path)).is_some()
}

/// Reads a label volume of any supported format (see the module documentation). Errors name the
/// file; a file of no known format gets [`ImagingError::UnknownFormat`], which lists the formats.
pub fn read_labels(path: &Path, options: &LabelReadOptions) -> Result<LabelRead, ImagingError> {
    let format = match detect_label_format(path).or_else(|| label_format_from_extension(path)) {
        Some(format) => format,
        None => {
            // A missing or unreadable file: say so, not "unknown format".
            if let Err(source) = std::fs::File::open(path) {
                return Err(ImagingError::Open { path: path.to_path_buf(), source });
            }
            return Err(ImagingError::UnknownFormat { path: path.to_path_buf() });
        }
    };
    if let (Some(level), false) = (options.zarr_level, format == LabelFormat::OmeZarr) {
        return Err(ImagingError::Unsupported {
            path: path.to_path_buf(),
            message: format!(
                "is a {format} file; a scale level ({level} asked: --zarr-level, `zarr_level`) applies to OME-Zarr \
                 stores only"
            ),
        });
    }
    match format {
        LabelFormat::Tiff => super::tiff_read::read_label_tiff(path, options),
        LabelFormat::OmeZarr => super::zarr_read::read_label_zarr(path, options),
        LabelFormat::Npy => super::npy_read::read_label_npy(path, options),
        LabelFormat::Hdf5 => super::h5_read::read_label_h5(path, options),
    }
}

/// The voxel size `[z, y, x]` and its sources: the caller's override, else what the file gives per
/// axis, else the fallback with one warning naming the axes without a size and `why`.
pub(crate) fn resolve_voxel_size(
    from_file: [Option<(Real, VoxelSizeSource)>; 3],
    options: &LabelReadOptions,
    warnings: &mut Vec<String>,
    path: &Path,
    why: &str,
) -> ([Real; 3], [VoxelSizeSource; 3]) {
    if let Some(v) = options.voxel_size {
        return (v, [VoxelSizeSource::Caller; 3]);
    }
    let mut size = [options.fallback_voxel_size; 3];
    let mut source = [VoxelSizeSource::Assumed; 3];
    let mut missing = Vec::new();
    for (a, axis) in ["z", "y", "x"].iter().enumerate() {
        match from_file[a] {
            Some((s, src)) => {
                size[a] = s;
                source[a] = src;
            }
            None => missing.push(*axis),
        }
    }
    if !missing.is_empty() {
        // Reported by the callers (every one prints the read's warnings), not here a second time.
        warnings.push(format!(
            "{}: no voxel size along {} {why}; assuming {} µm (give the voxel size explicitly)",
            path.display(),
            missing.join(", "),
            options.fallback_voxel_size * 1e6
        ));
    }
    (size, source)
}

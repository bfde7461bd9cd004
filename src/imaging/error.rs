//! Errors of the imaging module. Every file error names the file; every geometry error the cell.

use crate::mesh::CellId;
use std::path::PathBuf;

/// A label volume could not be read, written, built or voxelised.
#[derive(Debug, thiserror::Error)]
pub enum ImagingError {
    #[error("cannot open {path}: {source}")]
    Open { path: PathBuf, source: std::io::Error },
    #[error("{path}: not a readable TIFF file (corrupt or truncated?): {message}")]
    Corrupt { path: PathBuf, message: String },
    #[error("{path}: page {page} needs bytes up to offset {end}, but the file has only {file_size} bytes (truncated?)")]
    Truncated { path: PathBuf, page: usize, end: u64, file_size: u64 },
    #[error(
        "{path}: page {page} declares {width}x{height} pixels ({decoded} bytes decoded) but stores only {stored} bytes; \
         that is more than any TIFF compression can expand (corrupt header?)"
    )]
    ImplausibleSize { path: PathBuf, page: usize, width: u32, height: u32, decoded: u64, stored: u64 },
    #[error(
        "{path}: holds {bits}-bit floating-point pixels; a label volume needs integer labels (convert it to uint16 or uint32 first)"
    )]
    FloatPixels { path: PathBuf, bits: u16 },
    #[error(
        "{path}: has {samples} samples per pixel ({kind}); a label volume needs one integer label per voxel (one channel)"
    )]
    MultiSample { path: PathBuf, samples: u16, kind: String },
    #[error(
        "{path}: holds signed labels and voxel {index:?} (z,y,x) is {value}; labels must be 0 (background) or positive"
    )]
    NegativeLabel { path: PathBuf, index: [usize; 3], value: i64 },
    #[error(
        "{path}: voxel {index:?} (z,y,x) holds label {value}, larger than the largest supported label {}",
        u32::MAX
    )]
    LabelTooLarge { path: PathBuf, index: [usize; 3], value: u64 },
    #[error("{path}: {bits}-bit samples are not supported; labels must be 8, 16, 32 or 64-bit integers")]
    BitDepth { path: PathBuf, bits: u16 },
    #[error(
        "{path}: has a single {width}x{height} page, so it is a 2D image; a label volume must be 3D (a multi-page stack, one page per z slice)"
    )]
    NotAVolume { path: PathBuf, width: u32, height: u32 },
    #[error(
        "{path}: page {page} is {width}x{height} but page 0 is {first_width}x{first_height}; all z slices must have one size"
    )]
    PageSize { path: PathBuf, page: usize, width: u32, height: u32, first_width: u32, first_height: u32 },
    #[error("{path}: page {page} has a different pixel type from page 0 ({page_type} vs {first_type})")]
    PageType { path: PathBuf, page: usize, page_type: String, first_type: String },
    #[error("{path}: {message}")]
    Unsupported { path: PathBuf, message: String },
    /// Not a label volume of any format we read (by content, then by extension).
    #[error(
        "{path}: not a label volume in a format tissuefit reads; the formats read are {}",
        super::labels::SUPPORTED_FORMATS
    )]
    UnknownFormat { path: PathBuf },
    /// An OME-Zarr store that cannot be read as a label image.
    #[error("{path}: not a readable OME-Zarr label image: {message}")]
    Zarr { path: PathBuf, message: String },
    /// A NumPy `.npy` file that cannot be read as a 3-D label array.
    #[error("{path}: not a readable NumPy .npy label array: {message}")]
    Npy { path: PathBuf, message: String },
    /// An HDF5 file (or a dataset in it) that cannot be read as a 3-D label array.
    #[error("{path}: not a readable HDF5 label dataset: {message}")]
    Hdf5 { path: PathBuf, message: String },
    #[error("cannot write {path}: {message}")]
    Write { path: PathBuf, message: String },
    #[error("invalid voxel grid: {0}")]
    Grid(String),
    #[error("cell {cell}: label 0 is the background; a cell to voxelise needs a positive id")]
    BackgroundCell { cell: CellId },
    #[error("cannot generate labels: {0}")]
    Generate(String),
    /// Labels that cannot be matched across the frames of a series.
    #[error("matching labels across frames: {0}")]
    Tracking(String),
    /// A declared size beyond the memory limit (see `limits.rs`), or an unreadable limit.
    #[error("{0}")]
    Limit(String),
}

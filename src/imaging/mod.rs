//! Label volumes: the segmented image a tissue comes from, and what simulated tissues are rasterised
//! back onto for comparison.
//!
//! - [`LabelVolume`]: `u32` labels indexed `[z, y, x]` (0 = background), voxel size `[sz, sy, sx]` in
//!   metres and the position of voxel `[0, 0, 0]`'s centre; label statistics, per-label padded masks
//!   ([`LabelMask`], the mesher's input) and border tests. The coordinate convention is stated once,
//!   in `volume.rs`: voxel `[k, j, i]` has its centre at `origin + (i·sx, j·sy, k·sz)`, and mesh
//!   coordinates are `(x, y, z)` metres.
//! - TIFF in ([`read_label_tiff`]) and out ([`write_label_tiff`]) with ImageJ/OME voxel sizes.
//! - [`voxelize`]: closed cell surfaces → labels, by exact ray–triangle crossings along x.
//! - [`label_overlap`]: per-label IoU and χ = 1 − IoU of two label volumes on one grid.
//! - [`generate_labels`]: synthetic label volumes (sphere, ellipsoid, cube, doublet, aggregate).
//! - [`check_voxel_memory`]: the one memory limit every dense voxel array is checked against before
//!   it is allocated (`limits.rs`; `TISSUEFIT_MEMORY_LIMIT`).

mod error;
mod generate;
mod limits;
mod metadata;
mod overlap;
mod tiff_read;
mod tiff_write;
mod volume;
mod voxelize;

pub use error::ImagingError;
pub use generate::{GeneratedLabels, LabelPattern, LabelSpec, generate_labels, generate_nuclei};
pub use limits::{DEFAULT_MEMORY_LIMIT, MEMORY_LIMIT_ENV, check_voxel_memory, format_bytes, memory_limit, parse_bytes};
pub use metadata::VoxelSizeSource;
pub use overlap::{LabelOverlap, label_overlap};
pub use tiff_read::{
    FALLBACK_VOXEL_SIZE, LabelRead, LabelReadOptions, MAX_EXPANSION, read_label_tiff, read_label_tiff_bytes,
};
pub use tiff_write::{LabelDtype, LabelWriteOptions, TiffCompression, write_label_tiff};
pub use volume::{AnisotropyError, LabelInfo, LabelMask, LabelVolume, MAX_ANISOTROPY, VoxelGrid};
pub use voxelize::{VoxelizeStats, voxelize, voxelize_with_stats};

//! Label volumes: the segmented image a tissue comes from, and what simulated tissues are rasterised
//! back onto for comparison.
//!
//! - [`LabelVolume`]: `u32` labels indexed `[z, y, x]` (0 = background), voxel size `[sz, sy, sx]` in
//!   metres and the position of voxel `[0, 0, 0]`'s centre; label statistics, per-label padded masks
//!   ([`LabelMask`], the mesher's input) and border tests. The coordinate convention is stated once,
//!   in `volume.rs`: voxel `[k, j, i]` has its centre at `origin + (i·sx, j·sy, k·sz)`, and mesh
//!   coordinates are `(x, y, z)` metres.
//! - [`read_labels`]: the one reader every command uses; it dispatches by content to the TIFF
//!   ([`read_label_tiff`], ImageJ/OME voxel sizes), OME-Zarr (`zarr_read.rs`, NGFF multiscales) and
//!   NumPy `.npy` (`npy_read.rs`) readers. TIFF out: [`write_label_tiff`].
//! - [`write_label_properties`]: per-label results written back into an OME-Zarr label image's NGFF
//!   `image-label.properties` (`zarr_properties.rs`), for `tissuefit measure --zarr-properties`.
//! - [`voxelize`]: closed cell surfaces → labels, by exact ray–triangle crossings along x.
//! - [`label_overlap`]: per-label IoU and χ = 1 − IoU of two label volumes on one grid.
//! - [`match_labels`]: the labels of one frame of a series matched to the previous frame's tracks by
//!   overlap (`track.rs`); [`relabel`] renumbers a volume.
//! - [`generate_labels`]: synthetic label volumes (sphere, ellipsoid, cube, doublet, aggregate);
//!   [`perturb_boundaries`]: segmentation-like noise on a volume's boundaries (`noise.rs`).
//! - [`BorderPolicy`], [`DEFAULT_MIN_VOXELS`]: which labels count as cells (debris, cut cells at
//!   the border), the same for meshing a label volume and for measuring it (`label_filter.rs`).
//! - [`check_voxel_memory`]: the one memory limit every dense voxel array is checked against before
//!   it is allocated (`limits.rs`; `TISSUEFIT_MEMORY_LIMIT`).

mod error;
mod generate;
mod h5_read;
mod label_filter;
mod labels;
mod limits;
mod metadata;
mod noise;
mod npy_read;
mod overlap;
mod tiff_read;
mod tiff_write;
mod track;
mod volume;
mod voxelize;
mod zarr_properties;
mod zarr_read;

pub use error::ImagingError;
pub use generate::{GeneratedLabels, LabelPattern, LabelSpec, generate_labels, generate_nuclei};
pub use h5_read::{read_label_h5, split_hdf5_path};
pub use label_filter::{BorderPolicy, DEFAULT_MIN_VOXELS};
pub use labels::{
    LabelFormat, SUPPORTED_FORMATS, detect_label_format, is_label_volume, label_format_from_extension, read_labels,
};
pub use limits::{DEFAULT_MEMORY_LIMIT, MEMORY_LIMIT_ENV, check_voxel_memory, format_bytes, memory_limit, parse_bytes};
pub use metadata::VoxelSizeSource;
pub use noise::{BoundaryNoise, NoiseStats, boundary_roughness, denoise_labels, gaussian_blur, perturb_boundaries};
pub(crate) use overlap::check_same_grid;
pub use overlap::{LabelOverlap, label_overlap};
pub use tiff_read::{
    FALLBACK_VOXEL_SIZE, LabelRead, LabelReadOptions, MAX_EXPANSION, read_label_tiff, read_label_tiff_bytes,
};
pub use tiff_write::{LabelDtype, LabelWriteOptions, TiffCompression, write_label_tiff};
pub use track::{FrameTracks, TrackedLabel, match_labels, relabel};
pub use volume::{AnisotropyError, LabelInfo, LabelMask, LabelVolume, MAX_ANISOTROPY, VoxelGrid};
pub use voxelize::{VoxelizeStats, voxelize, voxelize_with_stats};
pub use zarr_properties::{
    LABEL_VALUE_KEY, LabelProperties, PROVENANCE_KEY, PropertiesTarget, metadata_for_hash, properties_target, utc_now,
    write_label_properties,
};

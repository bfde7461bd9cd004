//! Reading label volumes from HDF5 files (`.h5`, `.hdf5`), as PlantSeg, ilastik and many Python
//! pipelines write them: a 3-D integer dataset indexed `[z, y, x]` (or 4-D/5-D with leading axes of
//! length 1, a channel or time axis), any chunking, gzip/deflate and shuffle filters. The reader is
//! the pure-Rust `hdf5-pure` crate: no HDF5 C library is needed.
//!
//! **Which dataset.** `FILE.h5/GROUP/NAME` names one (the part after the file is the dataset's
//! path inside it). Otherwise the file's integer datasets of that shape are the candidates: the only
//! one, or the only one named `segmentation`, `label(s)` or `mask(s)` (PlantSeg writes
//! `segmentation`), is read; several without such a name are an error that lists them.
//!
//! **Voxel size.** The dataset's `element_size_um` attribute (z, y, x in micrometres: PlantSeg's
//! and ilastik's convention), else the caller's, else the fallback with a warning.

use super::labels::{LabelFormat, resolve_voxel_size};
use super::limits::check_voxel_memory;
use super::metadata::VoxelSizeSource;
use super::{ImagingError, LabelRead, LabelReadOptions, LabelVolume};
use crate::geometry::{Real, Vec3};
use hdf5_pure::{AttrValue, DType, Dataset, Group};
use ndarray::Array3;
use std::io::Read;
use std::path::{Path, PathBuf};

/// The 8 bytes an HDF5 file starts with (its superblock signature).
pub(crate) const HDF5_MAGIC: [u8; 8] = *b"\x89HDF\r\n\x1a\n";

/// Dataset names read without being named, when a file holds several candidates (the last
/// component, compared without case).
const LABEL_NAMES: [&str; 5] = ["segmentation", "label", "labels", "mask", "masks"];

/// Groups are searched this deep for candidate datasets.
const MAX_DEPTH: usize = 8;

/// Whether the file at `path` starts with the HDF5 signature.
pub(crate) fn has_hdf5_magic(path: &Path) -> bool {
    let Ok(mut file) = std::fs::File::open(path) else { return false };
    let mut magic = [0u8; 8];
    file.read_exact(&mut magic).is_ok() && magic == HDF5_MAGIC
}

/// Splits `FILE.h5/inner/path` into the HDF5 file and the dataset path inside it: the longest
/// existing prefix of `path` that is a file with the HDF5 signature, and the rest. `None` when no
/// proper prefix is one (a path naming the file itself is not split).
pub fn split_hdf5_path(path: &Path) -> Option<(PathBuf, String)> {
    let mut inner = Vec::new();
    let mut file = path;
    while let Some(parent) = file.parent() {
        inner.push(file.file_name()?.to_str()?.to_string());
        file = parent;
        if file.is_file() {
            if !has_hdf5_magic(file) {
                return None;
            }
            inner.reverse();
            return Some((file.to_path_buf(), inner.join("/")));
        }
    }
    None
}

/// Reads an integer label dataset of an HDF5 file; see the module documentation.
pub fn read_label_h5(path: &Path, options: &LabelReadOptions) -> Result<LabelRead, ImagingError> {
    let (file_path, inner) = match split_hdf5_path(path) {
        Some((file, inner)) if !path.exists() => (file, Some(inner)),
        _ => (path.to_path_buf(), None),
    };
    let bad = |message: String| ImagingError::Hdf5 { path: path.to_path_buf(), message };
    let size =
        std::fs::metadata(&file_path).map_err(|source| ImagingError::Open { path: file_path.clone(), source })?.len();
    // The reader holds the whole file in memory.
    check_voxel_memory(Some(size), 1, &format!("{}: reading this HDF5 file", file_path.display()), "crop the volume")?;
    let file =
        guarded(|| hdf5_pure::File::open(&file_path)).map_err(|e| bad(format!("cannot open it as HDF5: {e}")))?;
    let (name, dataset) = match inner {
        Some(inner) => {
            let dataset = guarded(|| file.dataset(&inner)).map_err(|e| {
                bad(format!("no dataset `{inner}` in {} ({e}); {}", file_path.display(), list_datasets(&file.root())))
            })?;
            (inner, dataset)
        }
        None => choose_dataset(&file.root()).map_err(bad)?,
    };
    let described = |message: String| bad(format!("dataset `{name}`: {message}"));
    let shape = guarded(|| dataset.shape()).map_err(|e| described(format!("unreadable shape: {e}")))?;
    let [nz, ny, nx] = volume_shape(&shape).ok_or_else(|| {
        described(format!(
            "shape {shape:?}; a label volume is a 3-D array indexed [z, y, x] (leading axes of length 1 allowed)"
        ))
    })?;
    if nz == 0 || ny == 0 || nx == 0 {
        return Err(described(format!("the array is empty (shape {shape:?})")));
    }
    let dtype = guarded(|| dataset.dtype()).map_err(|e| described(format!("unreadable data type: {e}")))?;
    let (bits, signed) = integer_type(&dtype).ok_or_else(|| {
        described(format!("data type {dtype}; labels must be 8, 16, 32 or 64-bit integers (a probability map?)"))
    })?;
    let voxels = nz.checked_mul(ny).and_then(|n| n.checked_mul(nx));
    // Up to 32 bits: read as 32-bit values (unsigned ones are the labels as they are; signed ones
    // are checked into a second u32 array); 64-bit: read as 64-bit values, then kept as u32.
    let read_bytes: u64 = if bits <= 32 { 8 } else { 12 };
    check_voxel_memory(
        voxels,
        read_bytes.saturating_add(options.work_bytes_per_voxel),
        &format!("{}: a dataset of {nz} × {ny} × {nx} voxels", path.display()),
        "crop or bin the volume",
    )?;
    let (nz, ny, nx) = (nz as usize, ny as usize, nx as usize);
    let index = |flat: usize| [flat / (ny * nx), (flat / nx) % ny, flat % nx];
    let reading = |e: String| described(format!("reading the data: {e}"));
    let signed_labels = |values: &mut dyn Iterator<Item = i64>| -> Result<Vec<u32>, ImagingError> {
        values
            .enumerate()
            .map(|(flat, v)| match u32::try_from(v) {
                Ok(v) => Ok(v),
                Err(_) if v < 0 => {
                    Err(ImagingError::NegativeLabel { path: path.to_path_buf(), index: index(flat), value: v })
                }
                Err(_) => {
                    Err(ImagingError::LabelTooLarge { path: path.to_path_buf(), index: index(flat), value: v as u64 })
                }
            })
            .collect()
    };
    let data: Vec<u32> = match (signed, bits <= 32) {
        (false, true) => guarded(|| dataset.read_u32()).map_err(reading)?,
        (true, true) => {
            let values = guarded(|| dataset.read_i32()).map_err(reading)?;
            signed_labels(&mut values.iter().map(|&v| i64::from(v)))?
        }
        (true, false) => {
            let values = guarded(|| dataset.read_i64()).map_err(reading)?;
            signed_labels(&mut values.iter().copied())?
        }
        (false, false) => {
            let values = guarded(|| dataset.read_u64()).map_err(reading)?;
            values
                .iter()
                .enumerate()
                .map(|(flat, &v)| {
                    u32::try_from(v).map_err(|_| ImagingError::LabelTooLarge {
                        path: path.to_path_buf(),
                        index: index(flat),
                        value: v,
                    })
                })
                .collect::<Result<_, _>>()?
        }
    };
    if data.len() != nz * ny * nx {
        return Err(described(format!("{} values read for shape {shape:?}", data.len())));
    }
    let labels = Array3::from_shape_vec((nz, ny, nx), data).map_err(|e| described(e.to_string()))?;
    let mut warnings = Vec::new();
    let from_file = match guarded(|| dataset.attrs()) {
        Ok(attrs) => element_size(attrs.get("element_size_um"), &mut warnings, path),
        Err(e) => {
            warnings.push(format!("{}: dataset `{name}`: its attributes could not be read ({e})", path.display()));
            [None; 3]
        }
    };
    let (voxel_size, voxel_size_source) =
        resolve_voxel_size(from_file, options, &mut warnings, path, "(no element_size_um attribute on the dataset)");
    let volume = LabelVolume::new(labels, voxel_size, options.origin.unwrap_or(Vec3::zeros()))
        .map_err(|e| ImagingError::Unsupported { path: path.to_path_buf(), message: e.to_string() })?;
    Ok(LabelRead { volume, format: LabelFormat::Hdf5, voxel_size_source, bits, signed, compression: 0, warnings })
}

/// Runs a call into the HDF5 decoder, turning a panic on a malformed file into an error (the
/// decoder is a dependency; a corrupt input must never abort the program).
fn guarded<T>(f: impl FnOnce() -> Result<T, hdf5_pure::Error>) -> Result<T, String> {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)) {
        Ok(result) => result.map_err(|e| {
            let e = e.to_string();
            if e.contains("layout version") {
                // HDF5 2.0 with libver="latest" writes data layout version 5, which hdf5-pure 0.47
                // does not read yet.
                format!(
                    "{e} (a file written by HDF5 ≥ 2.0 with libver=\"latest\"? Save it again with h5py's default \
                     libver, or as TIFF)"
                )
            } else {
                e
            }
        }),
        Err(_) => Err("the HDF5 decoder failed on it (corrupt file?)".to_string()),
    }
}

/// `[z, y, x]` of a shape with at most two leading axes of length 1.
fn volume_shape(shape: &[u64]) -> Option<[u64; 3]> {
    match shape {
        [z, y, x] | [1, z, y, x] | [1, 1, z, y, x] => Some([*z, *y, *x]),
        _ => None,
    }
}

/// (bits, signed) of an integer data type.
fn integer_type(dtype: &DType) -> Option<(u16, bool)> {
    Some(match dtype {
        DType::U8 => (8, false),
        DType::U16 => (16, false),
        DType::U32 => (32, false),
        DType::U64 => (64, false),
        DType::I8 => (8, true),
        DType::I16 => (16, true),
        DType::I32 => (32, true),
        DType::I64 => (64, true),
        _ => return None,
    })
}

/// The voxel size from an `element_size_um` attribute (z, y, x in µm); a malformed one is a
/// warning and no size.
fn element_size(
    attr: Option<&AttrValue>,
    warnings: &mut Vec<String>,
    path: &Path,
) -> [Option<(Real, VoxelSizeSource)>; 3] {
    let Some(attr) = attr else { return [None; 3] };
    let values: Option<Vec<Real>> = match attr {
        AttrValue::F64Array(v) => Some(v.clone()),
        AttrValue::F32Array(v) => Some(v.iter().map(|&x| Real::from(x)).collect()),
        AttrValue::I64Array(v) => Some(v.iter().map(|&x| x as Real).collect()),
        AttrValue::I32Array(v) => Some(v.iter().map(|&x| Real::from(x)).collect()),
        AttrValue::U64Array(v) => Some(v.iter().map(|&x| x as Real).collect()),
        AttrValue::U32Array(v) => Some(v.iter().map(|&x| Real::from(x)).collect()),
        _ => None,
    };
    match values.as_deref() {
        Some(&[z, y, x]) if [z, y, x].iter().all(|s| s.is_finite() && *s > 0.0) => {
            [z, y, x].map(|s| Some((s * 1e-6, VoxelSizeSource::Hdf5ElementSize)))
        }
        _ => {
            warnings.push(format!(
                "{}: ignored element_size_um = {attr:?} (three positive sizes z, y, x in µm expected)",
                path.display()
            ));
            [None; 3]
        }
    }
}

/// Every dataset under `group` as (path, dataset), depth first, groups up to [`MAX_DEPTH`] deep.
fn all_datasets(group: &Group, prefix: &str, depth: usize, out: &mut Vec<(String, Dataset)>) {
    if let Ok(datasets) = guarded(|| group.iter_datasets().map(|d| d.collect::<Vec<_>>())) {
        out.extend(datasets.into_iter().map(|(name, d)| (format!("{prefix}{name}"), d)));
    }
    if depth < MAX_DEPTH
        && let Ok(groups) = guarded(|| group.iter_groups().map(|g| g.collect::<Vec<_>>()))
    {
        for (name, g) in groups {
            all_datasets(&g, &format!("{prefix}{name}/"), depth + 1, out);
        }
    }
}

/// Whether a dataset could be a label volume (integer, 3-D after leading axes of length 1).
fn is_candidate(dataset: &Dataset) -> bool {
    let shape = guarded(|| dataset.shape());
    let dtype = guarded(|| dataset.dtype());
    matches!((shape, dtype), (Ok(s), Ok(t)) if volume_shape(&s).is_some() && integer_type(&t).is_some())
}

/// The dataset to read when none is named; see the module documentation.
fn choose_dataset(root: &Group) -> Result<(String, Dataset), String> {
    let mut all = Vec::new();
    all_datasets(root, "", 0, &mut all);
    let mut candidates: Vec<(String, Dataset)> = all.into_iter().filter(|(_, d)| is_candidate(d)).collect();
    if candidates.len() == 1 {
        return Ok(candidates.remove(0));
    }
    let named: Vec<usize> = (0..candidates.len())
        .filter(|&i| {
            let last = candidates[i].0.rsplit('/').next().unwrap_or("").to_ascii_lowercase();
            LABEL_NAMES.contains(&last.as_str())
        })
        .collect();
    if let [only] = named.as_slice() {
        return Ok(candidates.swap_remove(*only));
    }
    if candidates.is_empty() {
        return Err(format!("no 3-D integer dataset to read as labels; {}", list_datasets(root)));
    }
    let names: Vec<&str> = candidates.iter().map(|(n, _)| n.as_str()).collect();
    Err(format!(
        "{} 3-D integer datasets ({}); name the one to read after the file name, as in FILE.h5/{}",
        names.len(),
        names.join(", "),
        names[0]
    ))
}

/// "the file holds datasets: a (shape, type), …" for errors.
fn list_datasets(root: &Group) -> String {
    let mut all = Vec::new();
    all_datasets(root, "", 0, &mut all);
    if all.is_empty() {
        return "the file holds no dataset".to_string();
    }
    let items: Vec<String> = all
        .iter()
        .map(|(name, d)| {
            let shape = guarded(|| d.shape()).map_or_else(|_| "?".to_string(), |s| format!("{s:?}"));
            let dtype = guarded(|| d.dtype()).map_or_else(|_| "?".to_string(), |t| t.to_string());
            format!("{name} ({shape}, {dtype})")
        })
        .collect();
    format!("the file holds: {}", items.join(", "))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn volume_shapes_allow_leading_singleton_axes_only() {
        assert_eq!(volume_shape(&[4, 5, 6]), Some([4, 5, 6]));
        assert_eq!(volume_shape(&[1, 4, 5, 6]), Some([4, 5, 6]));
        assert_eq!(volume_shape(&[1, 1, 4, 5, 6]), Some([4, 5, 6]));
        assert_eq!(volume_shape(&[2, 4, 5, 6]), None);
        assert_eq!(volume_shape(&[5, 6]), None);
    }

    #[test]
    fn element_size_is_read_in_micrometres_and_a_bad_one_is_a_warning() {
        let mut warnings = Vec::new();
        let path = Path::new("x.h5");
        let sizes = element_size(Some(&AttrValue::F64Array(vec![0.5, 0.25, 0.2])), &mut warnings, path);
        assert_eq!(sizes.map(|s| s.unwrap().0), [0.5e-6, 0.25e-6, 0.2e-6]);
        assert!(warnings.is_empty());
        let sizes = element_size(Some(&AttrValue::F64Array(vec![0.5, 0.0, 0.2])), &mut warnings, path);
        assert_eq!(sizes, [None; 3]);
        assert!(warnings[0].contains("element_size_um"), "{warnings:?}");
    }
}

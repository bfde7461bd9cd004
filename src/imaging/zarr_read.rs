//! Reading label volumes from OME-Zarr: an NGFF 0.4 (Zarr v2: `.zgroup`, `.zattrs`, `.zarray`) or
//! NGFF 0.5 (Zarr v3: `zarr.json`, the OME metadata under `attributes.ome`) multiscales group —
//! a label image (`image.zarr/labels/NAME`) or an image group; the `labels` group itself is
//! followed when it lists exactly one label image. The chunks are decoded by the `zarrs` crate,
//! built with the raw, gzip, zlib and zstd codecs (plus sharding, crc32c and transpose); a store
//! using another codec (e.g. blosc, which needs a C library we do not build) is refused naming it.
//!
//! - Scale level: [`LabelReadOptions::zarr_level`] (`--zarr-level`, `[input] zarr_level`), default
//!   0 (full resolution).
//! - Voxel size: the level's `coordinateTransformations` scale times the multiscale's own (if any),
//!   in each axis' `unit` (micrometer, nanometer, …) converted to metres. An axis without a unit or a
//!   scale gets the fallback size with a warning, as a TIFF without metadata does. The translation,
//!   when present and in units, is the centre of voxel `[0, 0, 0]`.
//! - Axes: (z, y, x) after any leading time and channel axes of size 1 ((c, z, y, x), (t, c, z, y,
//!   x)); anything else is refused naming the axes.
//! - Labels: 8/16/32/64-bit integers; negative labels and labels beyond `u32::MAX` are refused naming
//!   the voxel; floating-point arrays are refused with a hint.
//! - A chunk missing from the store holds the array's fill value (the Zarr specification's rule),
//!   which is what we read for it.
//! - The volume's size is checked against the memory limit before anything is decoded, and the
//!   array is decoded one chunk row (along z) at a time into the `u32` volume.

use super::labels::{LabelFormat, ZARR_METADATA_FILES, resolve_voxel_size};
use super::limits::check_voxel_memory;
use super::metadata::{VoxelSizeSource, unit_metres};
use super::{ImagingError, LabelRead, LabelReadOptions, LabelVolume};
use crate::geometry::{Real, Vec3};
use ndarray::Array3;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use zarrs::array::{Array, ArraySubset, ElementOwned};
use zarrs::filesystem::FilesystemStore;

/// Codecs (Zarr v3 names, Zarr v2 compressor ids) this build decodes.
const SUPPORTED_CODECS: [&str; 8] =
    ["bytes", "endian", "transpose", "gzip", "zlib", "zstd", "crc32c", "sharding_indexed"];

/// A `coordinateTransformations` list's scale and translation (one value per axis), when present.
type Transforms = (Option<Vec<Real>>, Option<Vec<Real>>);

/// A Zarr group's version and the attributes holding the OME metadata.
pub(super) struct Group {
    pub(super) zarr_version: u8,
    /// v2: `.zattrs`; v3: `attributes.ome` (or `attributes` for a store that skipped the `ome` key).
    pub(super) ome: Value,
}

/// Stored label type.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
enum Dtype {
    U8,
    U16,
    U32,
    U64,
    I8,
    I16,
    I32,
    I64,
}

impl Dtype {
    fn bits(self) -> u16 {
        match self {
            Dtype::U8 | Dtype::I8 => 8,
            Dtype::U16 | Dtype::I16 => 16,
            Dtype::U32 | Dtype::I32 => 32,
            Dtype::U64 | Dtype::I64 => 64,
        }
    }

    fn signed(self) -> bool {
        matches!(self, Dtype::I8 | Dtype::I16 | Dtype::I32 | Dtype::I64)
    }
}

/// Reads an OME-Zarr label image; see the module documentation.
pub fn read_label_zarr(path: &Path, options: &LabelReadOptions) -> Result<LabelRead, ImagingError> {
    let mut warnings = Vec::new();
    let (root, group) = label_image_group(path, &mut warnings)?;
    let bad = |message: String| ImagingError::Zarr { path: root.clone(), message };
    let key = if group.zarr_version == 2 { ".zattrs" } else { "zarr.json attributes.ome" };
    let list = group.ome["multiscales"].as_array().ok_or_else(|| bad(format!("{key}: `multiscales` is not a list")))?;
    let multiscale = list.first().ok_or_else(|| bad(format!("{key}: `multiscales` is empty")))?;
    if list.len() > 1 {
        warnings.push(format!("{}: {} multiscale images; reading the first", root.display(), list.len()));
    }
    let axes = parse_axes(multiscale).map_err(|m| bad(format!("{key}: {m}")))?;
    let datasets = multiscale["datasets"]
        .as_array()
        .ok_or_else(|| bad(format!("{key}: multiscales[0] has no `datasets` list")))?;
    if datasets.is_empty() {
        return Err(bad(format!("{key}: multiscales[0].datasets is empty")));
    }
    let level = options.zarr_level.unwrap_or(0);
    let dataset = datasets.get(level).ok_or_else(|| {
        bad(format!(
            "scale level {level} asked (--zarr-level, `zarr_level`), but the store has {} level(s): 0 (full \
             resolution) to {}",
            datasets.len(),
            datasets.len() - 1
        ))
    })?;
    let array_path = dataset["path"]
        .as_str()
        .ok_or_else(|| bad(format!("{key}: multiscales[0].datasets[{level}] has no `path`")))?
        .trim_matches('/')
        .to_string();
    let n = axes.len();
    let transforms = |v: &Value, what: &str| -> Result<Transforms, ImagingError> {
        parse_transforms(v, n).map_err(|m| bad(format!("{key}: {what}: {m}")))
    };
    let (level_scale, level_translation) = transforms(&dataset["coordinateTransformations"], "datasets[level]")?;
    let (global_scale, global_translation) = transforms(&multiscale["coordinateTransformations"], "multiscales[0]")?;

    // The array: its metadata checked by us first (clear errors for dtype and codecs), then opened.
    let array_dir = root.join(&array_path);
    let meta = read_array_metadata(&array_dir, group.zarr_version)?;
    let dtype = array_dtype(&meta, &array_dir, group.zarr_version)?;
    check_codecs(&meta, &array_dir, group.zarr_version)?;
    let store = FilesystemStore::new(&root).map_err(|e| bad(e.to_string()))?;
    let array = Array::open(Arc::new(store), &format!("/{array_path}"))
        .map_err(|e| ImagingError::Zarr { path: array_dir.clone(), message: e.to_string() })?;
    let shape = array.shape().to_vec();
    if shape.len() != n {
        return Err(ImagingError::Zarr {
            path: array_dir.clone(),
            message: format!(
                "the array has {} dimensions but the multiscales axes are {}",
                shape.len(),
                axes_list(&axes)
            ),
        });
    }
    let first_space = n - 3;
    for (a, axis) in axes.iter().enumerate().take(first_space) {
        if shape[a] != 1 {
            return Err(ImagingError::Unsupported {
                path: array_dir.clone(),
                message: format!(
                    "has {} entries along the {} axis `{}` (axes {}); a label volume must have one channel and one \
                     time point (write the one you want as its own label image)",
                    shape[a],
                    axis.kind,
                    axis.name,
                    axes_list(&axes)
                ),
            });
        }
    }
    let [nz, ny, nx] = [shape[n - 3], shape[n - 2], shape[n - 1]];
    if nz == 0 || ny == 0 || nx == 0 {
        return Err(ImagingError::Zarr {
            path: array_dir,
            message: format!("the array is empty ({nz} × {ny} × {nx})"),
        });
    }
    check_voxel_memory(
        nz.checked_mul(ny).and_then(|v| v.checked_mul(nx)),
        4u64.saturating_add(options.work_bytes_per_voxel),
        &format!("{}: level {level}, {nz} × {ny} × {nx} voxels", array_dir.display()),
        "read a coarser scale level (--zarr-level) or crop the volume",
    )?;
    let slab = chunk_depth(&meta, group.zarr_version, n).clamp(1, nz);
    let (nz, ny, nx) = (nz as usize, ny as usize, nx as usize);
    let mut data: Vec<u32> = Vec::with_capacity(nz * ny * nx);
    let read = Slabs { array: &array, path: &array_dir, lead: first_space, shape: [nz, ny, nx], slab: slab as usize };
    match dtype {
        Dtype::U8 => read.append::<u8>(&mut data)?,
        Dtype::U16 => read.append::<u16>(&mut data)?,
        Dtype::U32 => read.append::<u32>(&mut data)?,
        Dtype::U64 => read.append::<u64>(&mut data)?,
        Dtype::I8 => read.append::<i8>(&mut data)?,
        Dtype::I16 => read.append::<i16>(&mut data)?,
        Dtype::I32 => read.append::<i32>(&mut data)?,
        Dtype::I64 => read.append::<i64>(&mut data)?,
    }
    let labels = Array3::from_shape_vec((nz, ny, nx), data).map_err(|e| bad(e.to_string()))?;

    // Voxel size and origin per spatial axis (z, y, x), in metres.
    let mut from_file: [Option<(Real, VoxelSizeSource)>; 3] = [None; 3];
    let mut origin = [0.0; 3];
    let mut odd = Vec::new();
    for s in 0..3 {
        let a = first_space + s;
        let axis = &axes[a];
        let unit = match axis.unit.as_deref() {
            Some(u) => match unit_metres(u) {
                Some(m) => Some(m),
                None => {
                    odd.push(format!("axis `{}` has unit `{u}`, not a length unit", axis.name));
                    None
                }
            },
            None => {
                odd.push(format!("axis `{}` has no unit", axis.name));
                None
            }
        };
        let g = global_scale.as_ref().map_or(1.0, |g| g[a]);
        let scale = level_scale.as_ref().map(|l| l[a] * g);
        if let (Some(m), Some(scale)) = (unit, scale) {
            if scale.is_finite() && scale > 0.0 {
                from_file[s] = Some((scale * m, VoxelSizeSource::OmeZarr));
            } else {
                odd.push(format!("axis `{}` has scale {scale}", axis.name));
            }
        }
        if let Some(m) = unit {
            let t = level_translation.as_ref().map_or(0.0, |t| t[a]) * g
                + global_translation.as_ref().map_or(0.0, |t| t[a]);
            origin[s] = t * m;
        }
    }
    if level_scale.is_none() {
        odd.push(format!("datasets[{level}] has no `scale` transformation"));
    }
    if !odd.is_empty() && options.voxel_size.is_none() {
        warnings.push(format!("{}: {}", root.display(), odd.join("; ")));
    }
    let (voxel_size, voxel_size_source) =
        resolve_voxel_size(from_file, options, &mut warnings, &root, "in the multiscales metadata");
    let origin = options.origin.unwrap_or_else(|| Vec3::new(origin[2], origin[1], origin[0]));
    let volume = LabelVolume::new(labels, voxel_size, origin)
        .map_err(|e| ImagingError::Unsupported { path: root.clone(), message: e.to_string() })?;
    Ok(LabelRead {
        volume,
        format: LabelFormat::OmeZarr,
        voxel_size_source,
        bits: dtype.bits(),
        signed: dtype.signed(),
        compression: 0,
        warnings,
    })
}

/// The multiscales group that `path` names (the store folder, or one of its metadata files), with
/// its Zarr version and OME attributes: the label image read by [`read_label_zarr`] and written to
/// by [`super::zarr_properties`], following a `labels` group that lists one image.
pub(super) fn label_image_group(path: &Path, warnings: &mut Vec<String>) -> Result<(PathBuf, Group), ImagingError> {
    let named_file = path.file_name().and_then(|n| n.to_str()).is_some_and(|n| ZARR_METADATA_FILES.contains(&n));
    let root = if named_file {
        match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        }
    } else {
        path.to_path_buf()
    };
    if root.exists() && !root.is_dir() {
        return Err(ImagingError::Zarr {
            path: root,
            message: "is a file; an OME-Zarr store is a folder (give the .zarr folder of the image or label group)"
                .into(),
        });
    }
    if !root.is_dir() {
        let source =
            std::io::Error::new(std::io::ErrorKind::NotFound, "no such folder (an OME-Zarr store is a folder)");
        return Err(ImagingError::Open { path: root, source });
    }
    find_multiscales(&root, warnings)
}

/// The group at `root` with its `multiscales`, following a `labels` group that lists one image.
fn find_multiscales(root: &Path, warnings: &mut Vec<String>) -> Result<(PathBuf, Group), ImagingError> {
    let group = read_group(root)?;
    if group.ome.get("multiscales").is_some() {
        if let Some(names) = label_names(&root.join("labels")) {
            warnings.push(format!(
                "{}: an image group whose label images are under labels/ ({}); reading the image itself (give \
                 {}/labels/NAME to read a label image)",
                root.display(),
                names.join(", "),
                root.display()
            ));
        }
        return Ok((root.to_path_buf(), group));
    }
    let names: Vec<String> = group.ome["labels"]
        .as_array()
        .map(|l| l.iter().filter_map(|v| v.as_str().map(str::to_string)).collect())
        .unwrap_or_default();
    let hint = if let Some(names) = label_names(&root.join("labels")) {
        format!("; its label images are {}/labels/{{{}}}", root.display(), names.join(","))
    } else {
        String::new()
    };
    match names.as_slice() {
        [one] => {
            let child = root.join(one);
            let group = read_group(&child)?;
            if group.ome.get("multiscales").is_none() {
                return Err(not_multiscales(&child, group.zarr_version, ""));
            }
            Ok((child, group))
        }
        [] => Err(not_multiscales(root, group.zarr_version, &hint)),
        several => Err(ImagingError::Zarr {
            path: root.to_path_buf(),
            message: format!(
                "a labels group holding {} label images ({}); give one of them, e.g. {}",
                several.len(),
                several.join(", "),
                root.join(&several[0]).display()
            ),
        }),
    }
}

fn not_multiscales(path: &Path, version: u8, hint: &str) -> ImagingError {
    let where_ = if version == 2 { ".zattrs (NGFF 0.4)" } else { "zarr.json attributes.ome (NGFF 0.5)" };
    ImagingError::Zarr {
        path: path.to_path_buf(),
        message: format!(
            "not a multiscales group: {where_} has no `multiscales`; give the OME-Zarr image or label group (e.g. \
             image.zarr/labels/cells){hint}"
        ),
    }
}

/// The names listed by the `labels` group at `dir`, if it is one.
fn label_names(dir: &Path) -> Option<Vec<String>> {
    let group = read_group(dir).ok()?;
    let names: Vec<String> =
        group.ome["labels"].as_array()?.iter().filter_map(|v| v.as_str().map(str::to_string)).collect();
    (!names.is_empty()).then_some(names)
}

fn read_json(path: &Path) -> Result<Option<Value>, ImagingError> {
    match std::fs::read(path) {
        Ok(bytes) => serde_json::from_slice(&bytes)
            .map(Some)
            .map_err(|e| ImagingError::Zarr { path: path.to_path_buf(), message: format!("not valid JSON: {e}") }),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(source) => Err(ImagingError::Open { path: path.to_path_buf(), source }),
    }
}

/// The group at `dir`: Zarr v3 (`zarr.json`) or v2 (`.zattrs`, `.zgroup`).
fn read_group(dir: &Path) -> Result<Group, ImagingError> {
    if let Some(meta) = read_json(&dir.join("zarr.json"))? {
        let node = meta["node_type"].as_str().unwrap_or("");
        if node != "group" {
            return Err(ImagingError::Zarr {
                path: dir.join("zarr.json"),
                message: format!(
                    "node_type is `{node}`, not `group`; give the OME-Zarr image or label group that holds the \
                     scale levels, not one array"
                ),
            });
        }
        let attributes = &meta["attributes"];
        let ome = attributes.get("ome").cloned().unwrap_or_else(|| attributes.clone());
        return Ok(Group { zarr_version: 3, ome });
    }
    if let Some(attrs) = read_json(&dir.join(".zattrs"))? {
        return Ok(Group { zarr_version: 2, ome: attrs });
    }
    if dir.join(".zgroup").is_file() {
        return Ok(Group { zarr_version: 2, ome: Value::Object(Default::default()) });
    }
    let message = if dir.join(".zarray").is_file() {
        "holds one Zarr v2 array (.zarray), not an OME-Zarr group; give the image or label group that holds the \
         scale levels"
            .to_string()
    } else {
        "no Zarr metadata: neither zarr.json (Zarr v3, NGFF 0.5) nor .zattrs/.zgroup (Zarr v2, NGFF 0.4)".to_string()
    };
    Err(ImagingError::Zarr { path: dir.to_path_buf(), message })
}

/// One multiscales axis.
#[derive(Debug)]
struct Axis {
    name: String,
    /// `space`, `time`, `channel` (from `type`, or guessed from the name).
    kind: String,
    unit: Option<String>,
}

fn axes_list(axes: &[Axis]) -> String {
    format!("({})", axes.iter().map(|a| a.name.as_str()).collect::<Vec<_>>().join(", "))
}

/// The axes, checked to end in z, y, x after only time/channel axes.
fn parse_axes(multiscale: &Value) -> Result<Vec<Axis>, String> {
    let list = multiscale["axes"].as_array().ok_or("multiscales[0] has no `axes` list")?;
    let axes: Vec<Axis> = list
        .iter()
        .map(|a| match a {
            // NGFF 0.3 wrote bare names.
            Value::String(name) => Ok(Axis { name: name.clone(), kind: guess_kind(name), unit: None }),
            Value::Object(o) => {
                let name = o.get("name").and_then(Value::as_str).ok_or("an axis without a `name`")?.to_string();
                let kind = o.get("type").and_then(Value::as_str).map_or_else(|| guess_kind(&name), str::to_string);
                let unit = o.get("unit").and_then(Value::as_str).map(str::to_string);
                Ok(Axis { name, kind, unit })
            }
            _ => Err("an axis is neither a name nor an object".to_string()),
        })
        .collect::<Result<_, String>>()?;
    let names: Vec<String> = axes.iter().map(|a| a.name.to_ascii_lowercase()).collect();
    let n = axes.len();
    let spatial_ok = n >= 3 && names[n - 3..] == ["z", "y", "x"];
    let lead_ok = axes[..n.saturating_sub(3)].iter().all(|a| a.kind == "time" || a.kind == "channel");
    if !spatial_ok || !lead_ok || n > 5 {
        return Err(format!(
            "axes {} are not a 3-D volume; tissuefit reads (z, y, x), (c, z, y, x) or (t, c, z, y, x) with one \
             channel and one time point",
            axes_list(&axes)
        ));
    }
    Ok(axes)
}

fn guess_kind(name: &str) -> String {
    match name.to_ascii_lowercase().as_str() {
        "t" => "time",
        "c" => "channel",
        _ => "space",
    }
    .to_string()
}

/// The `scale` and `translation` of a `coordinateTransformations` list (absent: none).
fn parse_transforms(v: &Value, n: usize) -> Result<Transforms, String> {
    let mut scale = None;
    let mut translation = None;
    let Some(list) = v.as_array() else {
        return if v.is_null() { Ok((None, None)) } else { Err("`coordinateTransformations` is not a list".into()) };
    };
    for t in list {
        let kind = t["type"].as_str().unwrap_or("");
        let values = |key: &str| -> Result<Vec<Real>, String> {
            let arr = t[key].as_array().ok_or(format!(
                "a `{kind}` transformation without a `{key}` list (a `path` to a file of values is not supported)"
            ))?;
            let vals: Vec<Real> = arr
                .iter()
                .map(|x| x.as_f64().ok_or(format!("`{key}` holds {x}, not a number")))
                .collect::<Result<_, _>>()?;
            if vals.len() != n {
                return Err(format!("`{key}` has {} values for {n} axes", vals.len()));
            }
            Ok(vals)
        };
        match kind {
            "scale" => scale = Some(values("scale")?),
            "translation" => translation = Some(values("translation")?),
            "identity" => {}
            other => return Err(format!("coordinate transformation `{other}` is not supported (scale, translation)")),
        }
    }
    Ok((scale, translation))
}

/// The array's metadata: `zarr.json` (v3) or `.zarray` (v2) in `dir`.
fn read_array_metadata(dir: &Path, version: u8) -> Result<Value, ImagingError> {
    let file = if version == 3 { "zarr.json" } else { ".zarray" };
    match read_json(&dir.join(file))? {
        Some(meta) => Ok(meta),
        None => Err(ImagingError::Zarr {
            path: dir.to_path_buf(),
            message: format!("the scale level's array metadata {file} is missing (is the store complete?)"),
        }),
    }
}

fn array_dtype(meta: &Value, dir: &Path, version: u8) -> Result<Dtype, ImagingError> {
    let (raw, name) = if version == 3 {
        let raw = meta["data_type"].as_str().unwrap_or("").to_string();
        (raw.clone(), raw)
    } else {
        let raw = meta["dtype"].as_str().unwrap_or("").to_string();
        let kind = raw.trim_start_matches(['<', '>', '|', '=']);
        let name = match kind {
            "u1" => "uint8",
            "u2" => "uint16",
            "u4" => "uint32",
            "u8" => "uint64",
            "i1" => "int8",
            "i2" => "int16",
            "i4" => "int32",
            "i8" => "int64",
            "f2" => "float16",
            "f4" => "float32",
            "f8" => "float64",
            _ => "",
        };
        (raw, name.to_string())
    };
    let dtype = match name.as_str() {
        "uint8" => Dtype::U8,
        "uint16" => Dtype::U16,
        "uint32" => Dtype::U32,
        "uint64" => Dtype::U64,
        "int8" => Dtype::I8,
        "int16" => Dtype::I16,
        "int32" => Dtype::I32,
        "int64" => Dtype::I64,
        f if f.starts_with("float") || f == "bfloat16" => {
            let bits = f.trim_start_matches("bfloat").trim_start_matches("float").parse().unwrap_or(0);
            return Err(ImagingError::FloatPixels { path: dir.to_path_buf(), bits });
        }
        _ => {
            return Err(ImagingError::Zarr {
                path: dir.to_path_buf(),
                message: format!(
                    "data type `{raw}` is not a label type; labels must be 8, 16, 32 or 64-bit integers (uint8 … int64)"
                ),
            });
        }
    };
    Ok(dtype)
}

/// Refuses a codec this build does not decode, naming it.
fn check_codecs(meta: &Value, dir: &Path, version: u8) -> Result<(), ImagingError> {
    let mut names = Vec::new();
    if version == 3 {
        fn collect(codecs: &Value, names: &mut Vec<String>) {
            for c in codecs.as_array().into_iter().flatten() {
                let name = c["name"].as_str().or_else(|| c.as_str()).unwrap_or("?").to_string();
                if name == "sharding_indexed" {
                    collect(&c["configuration"]["codecs"], names);
                    collect(&c["configuration"]["index_codecs"], names);
                }
                names.push(name);
            }
        }
        collect(&meta["codecs"], &mut names);
    } else {
        if let Some(id) = meta["compressor"]["id"].as_str() {
            names.push(id.to_string());
        }
        if let Some(f) = meta["filters"].as_array().and_then(|f| f.first()) {
            let id = f["id"].as_str().unwrap_or("?");
            return Err(ImagingError::Zarr {
                path: dir.to_path_buf(),
                message: format!("uses the Zarr v2 filter `{id}`; tissuefit reads stores without filters"),
            });
        }
    }
    if let Some(bad) = names.iter().find(|n| !SUPPORTED_CODECS.contains(&n.as_str())) {
        return Err(ImagingError::Zarr {
            path: dir.to_path_buf(),
            message: format!(
                "its chunks use the `{bad}` codec, which this build of tissuefit does not decode (it reads raw, gzip, \
                 zlib and zstd chunks, sharded or not); re-save the store with one of those (e.g. in Python, \
                 zarr's GZip or Zstd compressor)"
            ),
        });
    }
    Ok(())
}

/// The chunk extent along z (the slab read at a time).
fn chunk_depth(meta: &Value, version: u8, n: usize) -> u64 {
    let chunks = if version == 3 { &meta["chunk_grid"]["configuration"]["chunk_shape"] } else { &meta["chunks"] };
    chunks.as_array().and_then(|c| c.get(n - 3)).and_then(Value::as_u64).unwrap_or(u64::MAX)
}

/// The array read in slabs of whole chunk rows along z.
struct Slabs<'a, S: ?Sized> {
    array: &'a Array<S>,
    path: &'a Path,
    /// Leading singleton axes (time, channel).
    lead: usize,
    shape: [usize; 3],
    slab: usize,
}

impl<S: ?Sized + zarrs::storage::ReadableStorageTraits + 'static> Slabs<'_, S> {
    /// Appends the labels in `[z, y, x]` order, refusing negative or too-large ones.
    fn append<T: ElementOwned + Copy + Into<i128>>(&self, out: &mut Vec<u32>) -> Result<(), ImagingError> {
        let [nz, ny, nx] = self.shape;
        let mut z0 = 0;
        while z0 < nz {
            let z1 = (z0 + self.slab).min(nz);
            let mut ranges = vec![0..1u64; self.lead];
            ranges.extend([z0 as u64..z1 as u64, 0..ny as u64, 0..nx as u64]);
            let values: Vec<T> =
                self.array.retrieve_array_subset(&ArraySubset::new_with_ranges(&ranges)).map_err(|e| {
                    ImagingError::Zarr { path: self.path.to_path_buf(), message: format!("decoding z {z0}..{z1}: {e}") }
                })?;
            let index = |i: usize| [z0 + i / (ny * nx), (i / nx) % ny, i % nx];
            for (i, &v) in values.iter().enumerate() {
                let v: i128 = v.into();
                if v < 0 {
                    return Err(ImagingError::NegativeLabel {
                        path: self.path.to_path_buf(),
                        index: index(i),
                        value: v as i64,
                    });
                }
                if v > u32::MAX as i128 {
                    return Err(ImagingError::LabelTooLarge {
                        path: self.path.to_path_buf(),
                        index: index(i),
                        value: v as u64,
                    });
                }
                out.push(v as u32);
            }
            z0 = z1;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn axes_must_end_in_zyx_after_time_and_channel() {
        let ok = json!({"axes": [{"name": "t", "type": "time"}, {"name": "c", "type": "channel"},
            {"name": "z", "type": "space", "unit": "micrometer"}, "y", "x"]});
        let axes = parse_axes(&ok).unwrap();
        assert_eq!(axes.len(), 5);
        assert_eq!(axes[2].unit.as_deref(), Some("micrometer"));
        assert_eq!(axes[3].unit, None);
        for bad in
            [json!({"axes": ["y", "x"]}), json!({"axes": ["z", "x", "y"]}), json!({"axes": ["q", "z", "y", "x"]})]
        {
            let e = parse_axes(&bad).unwrap_err();
            assert!(e.contains("not a 3-D volume"), "{e}");
        }
        assert!(parse_axes(&json!({})).unwrap_err().contains("no `axes`"));
    }

    #[test]
    fn transforms_give_scale_and_translation_per_axis() {
        let t = json!([{"type": "scale", "scale": [2.0, 0.5, 0.5]}, {"type": "translation", "translation": [1, 2, 3]}]);
        let (scale, translation) = parse_transforms(&t, 3).unwrap();
        assert_eq!(scale, Some(vec![2.0, 0.5, 0.5]));
        assert_eq!(translation, Some(vec![1.0, 2.0, 3.0]));
        assert_eq!(parse_transforms(&Value::Null, 3).unwrap(), (None, None));
        let e = parse_transforms(&json!([{"type": "scale", "scale": [1.0, 1.0]}]), 3).unwrap_err();
        assert!(e.contains("2 values for 3 axes"), "{e}");
        let e = parse_transforms(&json!([{"type": "scale", "path": "s.bin"}]), 3).unwrap_err();
        assert!(e.contains("`path`"), "{e}");
        let e = parse_transforms(&json!([{"type": "affine"}]), 3).unwrap_err();
        assert!(e.contains("`affine`"), "{e}");
    }

    #[test]
    fn codecs_outside_the_build_are_named() {
        let dir = Path::new("store/0");
        let v3 = json!({"codecs": [{"name": "sharding_indexed", "configuration": {
            "codecs": [{"name": "bytes"}, {"name": "blosc"}], "index_codecs": [{"name": "bytes"}, {"name": "crc32c"}]}}]});
        let e = check_codecs(&v3, dir, 3).unwrap_err().to_string();
        assert!(e.contains("`blosc` codec") && e.contains("store/0"), "{e}");
        let ok = json!({"codecs": [{"name": "bytes"}, {"name": "zstd"}]});
        assert!(check_codecs(&ok, dir, 3).is_ok());
        assert!(check_codecs(&json!({"compressor": {"id": "gzip"}, "filters": null}), dir, 2).is_ok());
        let e = check_codecs(&json!({"compressor": null, "filters": [{"id": "delta"}]}), dir, 2).unwrap_err();
        assert!(e.to_string().contains("filter `delta`"), "{e}");
    }

    #[test]
    fn data_types_are_integers_only() {
        let dir = Path::new("s");
        assert_eq!(array_dtype(&json!({"dtype": ">i2"}), dir, 2).unwrap(), Dtype::I16);
        assert_eq!(array_dtype(&json!({"data_type": "uint64"}), dir, 3).unwrap(), Dtype::U64);
        let e = array_dtype(&json!({"data_type": "float32"}), dir, 3).unwrap_err().to_string();
        assert!(e.contains("32-bit floating-point"), "{e}");
        let e = array_dtype(&json!({"dtype": "|b1"}), dir, 2).unwrap_err().to_string();
        assert!(e.contains("`|b1`"), "{e}");
    }
}

//! The label readers behind `imaging::read_labels`: OME-Zarr (NGFF 0.4 on Zarr v2, 0.5 on Zarr v3)
//! and NumPy .npy, on fixtures written here by minimal writers (JSON + raw/gzip chunks, a .npy
//! header + data), and the same labels through TIFF, Zarr and .npy giving the same `measure` output.

use crate::support::cli::tissuefit;
use flate2::Compression;
use flate2::write::GzEncoder;
use ndarray::Array3;
use serde_json::{Value, json};
use std::io::Write;
use std::path::{Path, PathBuf};
use tissuefit::geometry::Vec3;
use tissuefit::imaging::{
    LabelFormat, LabelPattern, LabelReadOptions, LabelSpec, LabelVolume, LabelWriteOptions, VoxelSizeSource,
    generate_labels, read_labels, write_label_tiff,
};

/// A small label volume with three labels, background and a value above 255.
fn sample() -> Array3<u32> {
    Array3::from_shape_fn((5, 6, 7), |(z, y, x)| match (z + y + x) % 4 {
        0 => 0,
        1 => 3,
        2 => 1000,
        _ => (1 + z) as u32,
    })
}

/// `value` stored as the NumPy dtype `descr` (e.g. `<u2`, `>i4`, `|u1`, `<f4`).
fn encode(value: i64, descr: &str) -> Vec<u8> {
    let big = descr.starts_with('>');
    let kind = descr.trim_start_matches(['<', '>', '|']);
    let mut bytes = match kind {
        "u1" | "i1" => vec![value as u8],
        "u2" | "i2" => (value as u16).to_le_bytes().to_vec(),
        "u4" | "i4" => (value as u32).to_le_bytes().to_vec(),
        "u8" | "i8" => (value as u64).to_le_bytes().to_vec(),
        "f4" => (value as f32).to_le_bytes().to_vec(),
        "f8" => (value as f64).to_le_bytes().to_vec(),
        other => panic!("dtype {other}"),
    };
    if big {
        bytes.reverse();
    }
    bytes
}

/// Writes a `.npy` (format 1.0) of `values` (shape `shape`, C order) stored in `descr`, in C or
/// Fortran order.
fn write_npy(path: &Path, shape: &[usize], values: &[i64], descr: &str, fortran: bool) {
    let dims = shape.iter().map(|d| format!("{d}, ")).collect::<String>();
    let dict = format!(
        "{{'descr': '{descr}', 'fortran_order': {}, 'shape': ({}), }}",
        if fortran { "True" } else { "False" },
        if shape.len() == 1 { dims } else { dims.trim_end_matches(", ").to_string() }
    );
    // Magic (6) + version (2) + length (2) + header, padded with spaces to 64 bytes, ending in \n.
    let mut header = dict.into_bytes();
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(b' ');
    }
    header.push(b'\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend((header.len() as u16).to_le_bytes());
    out.extend(header);
    let n: usize = shape.iter().product();
    for k in 0..n {
        // Fortran order: the first index varies fastest; `values` is in C order.
        let c = if fortran {
            let mut rest = k;
            let mut index = vec![0; shape.len()];
            for (a, &d) in shape.iter().enumerate() {
                index[a] = rest % d;
                rest /= d;
            }
            index.iter().zip(shape).fold(0, |acc, (&i, &d)| acc * d + i)
        } else {
            k
        };
        out.extend(encode(values[c], descr));
    }
    std::fs::write(path, out).unwrap();
}

fn c_order(volume: &Array3<u32>) -> Vec<i64> {
    volume.iter().map(|&v| v as i64).collect()
}

/// How a fixture array's chunks are stored.
#[derive(Clone, Copy, PartialEq)]
enum Codec {
    Raw,
    Gzip,
    /// Declared as blosc (the chunks are not written: the reader must refuse before reading them).
    Blosc,
}

/// One level of a fixture store: C-order values of `shape` and its scale.
struct Level {
    shape: Vec<usize>,
    values: Vec<i64>,
    scale: Vec<f64>,
}

/// A fixture OME-Zarr multiscales group.
struct Store<'a> {
    zarr_version: u8,
    /// (name, type, unit).
    axes: Vec<(&'a str, &'a str, Option<&'a str>)>,
    levels: Vec<Level>,
    /// v2 dtype (`<u2`) or v3 data type (`uint16`).
    dtype: &'a str,
    codec: Codec,
    chunks: Vec<usize>,
    /// Leave out the chunks that hold only the fill value 0 (as zarr does by default).
    skip_empty: bool,
}

impl Store<'_> {
    fn write(&self, root: &Path) {
        std::fs::create_dir_all(root).unwrap();
        let axes: Vec<Value> = self
            .axes
            .iter()
            .map(|(name, kind, unit)| match unit {
                Some(u) => json!({"name": name, "type": kind, "unit": u}),
                None => json!({"name": name, "type": kind}),
            })
            .collect();
        let datasets: Vec<Value> = self
            .levels
            .iter()
            .enumerate()
            .map(|(i, l)| json!({"path": i.to_string(), "coordinateTransformations": [{"type": "scale", "scale": l.scale}]}))
            .collect();
        let multiscales = json!([{"version": if self.zarr_version == 2 { "0.4" } else { "0.5" }, "name": "cells", "axes": axes, "datasets": datasets}]);
        if self.zarr_version == 2 {
            write_json(&root.join(".zgroup"), &json!({"zarr_format": 2}));
            write_json(&root.join(".zattrs"), &json!({"multiscales": multiscales, "image-label": {"version": "0.4"}}));
        } else {
            write_json(
                &root.join("zarr.json"),
                &json!({"zarr_format": 3, "node_type": "group", "attributes": {"ome": {"version": "0.5", "multiscales": multiscales}}}),
            );
        }
        for (i, level) in self.levels.iter().enumerate() {
            self.write_array(&root.join(i.to_string()), level);
        }
    }

    fn write_array(&self, dir: &Path, level: &Level) {
        std::fs::create_dir_all(dir).unwrap();
        let chunks: Vec<usize> = self.chunks.iter().zip(&level.shape).map(|(&c, &s)| c.min(s)).collect();
        if self.zarr_version == 2 {
            let compressor = match self.codec {
                Codec::Raw => Value::Null,
                Codec::Gzip => json!({"id": "gzip", "level": 5}),
                Codec::Blosc => json!({"id": "blosc", "cname": "lz4", "clevel": 5, "shuffle": 1, "blocksize": 0}),
            };
            write_json(
                &dir.join(".zarray"),
                &json!({"zarr_format": 2, "shape": level.shape, "chunks": chunks, "dtype": self.dtype, "compressor": compressor, "fill_value": 0, "order": "C", "filters": null}),
            );
        } else {
            let mut codecs = vec![json!({"name": "bytes", "configuration": {"endian": "little"}})];
            match self.codec {
                Codec::Raw => {}
                Codec::Gzip => codecs.push(json!({"name": "gzip", "configuration": {"level": 5}})),
                Codec::Blosc => codecs.push(json!({"name": "blosc", "configuration": {"cname": "lz4", "clevel": 5, "shuffle": "shuffle", "typesize": 2, "blocksize": 0}})),
            }
            let names: Vec<&str> = self.axes.iter().map(|a| a.0).collect();
            write_json(
                &dir.join("zarr.json"),
                &json!({"zarr_format": 3, "node_type": "array", "shape": level.shape, "data_type": self.dtype,
                    "chunk_grid": {"name": "regular", "configuration": {"chunk_shape": chunks}},
                    "chunk_key_encoding": {"name": "default", "configuration": {"separator": "/"}},
                    "fill_value": 0, "codecs": codecs, "dimension_names": names}),
            );
        }
        if self.codec == Codec::Blosc {
            return;
        }
        let descr = v2_descr(self.dtype);
        let grid: Vec<usize> = level.shape.iter().zip(&chunks).map(|(&s, &c)| s.div_ceil(c)).collect();
        let count: usize = grid.iter().product();
        for k in 0..count {
            let mut rest = k;
            let mut chunk_index = vec![0; grid.len()];
            for a in (0..grid.len()).rev() {
                chunk_index[a] = rest % grid[a];
                rest /= grid[a];
            }
            // The chunk's elements in C order, past the array's edge the fill value.
            let n: usize = chunks.iter().product();
            let mut bytes = Vec::new();
            let mut all_fill = true;
            for e in 0..n {
                let mut rest = e;
                let mut index = vec![0; chunks.len()];
                for a in (0..chunks.len()).rev() {
                    index[a] = chunk_index[a] * chunks[a] + rest % chunks[a];
                    rest /= chunks[a];
                }
                let inside = index.iter().zip(&level.shape).all(|(&i, &s)| i < s);
                let v = if inside {
                    level.values[index.iter().zip(&level.shape).fold(0, |acc, (&i, &s)| acc * s + i)]
                } else {
                    0
                };
                all_fill &= v == 0;
                bytes.extend(encode(v, &descr));
            }
            if self.skip_empty && all_fill {
                continue;
            }
            let stored = match self.codec {
                Codec::Gzip => {
                    let mut gz = GzEncoder::new(Vec::new(), Compression::default());
                    gz.write_all(&bytes).unwrap();
                    gz.finish().unwrap()
                }
                _ => bytes,
            };
            let key: Vec<String> = chunk_index.iter().map(usize::to_string).collect();
            let path = if self.zarr_version == 2 { dir.join(key.join(".")) } else { dir.join("c").join(key.join("/")) };
            std::fs::create_dir_all(path.parent().unwrap()).unwrap();
            std::fs::write(path, stored).unwrap();
        }
    }
}

/// The NumPy descr of a Zarr v3 data type (v2 dtypes pass through).
fn v2_descr(dtype: &str) -> String {
    match dtype {
        "uint8" => "|u1",
        "uint16" => "<u2",
        "uint32" => "<u4",
        "uint64" => "<u8",
        "int8" => "|i1",
        "int16" => "<i2",
        "int32" => "<i4",
        "int64" => "<i8",
        "float32" => "<f4",
        other => other,
    }
    .to_string()
}

fn write_json(path: &Path, value: &Value) {
    std::fs::write(path, serde_json::to_vec_pretty(value).unwrap()).unwrap();
}

const ZYX_UM: [(&str, &str, Option<&str>); 3] =
    [("z", "space", Some("micrometer")), ("y", "space", Some("micrometer")), ("x", "space", Some("micrometer"))];

/// Every second voxel along y and x (a level-1 downsampling).
fn downsample(volume: &Array3<u32>) -> Array3<u32> {
    let (nz, ny, nx) = volume.dim();
    Array3::from_shape_fn((nz, ny.div_ceil(2), nx.div_ceil(2)), |(z, y, x)| volume[[z, 2 * y, 2 * x]])
}

fn read(path: &Path) -> tissuefit::imaging::LabelRead {
    read_labels(path, &LabelReadOptions::default()).unwrap_or_else(|e| panic!("{e}"))
}

fn assert_close(a: [f64; 3], b: [f64; 3]) {
    for k in 0..3 {
        assert!((a[k] - b[k]).abs() <= 1e-12 * b[k].abs(), "{a:?} vs {b:?}");
    }
}

#[test]
fn a_zarr_v2_store_reads_with_its_anisotropic_micrometre_scale_and_missing_chunks_as_fill() {
    let dir = tempfile::tempdir().unwrap();
    let mut labels = sample();
    // A whole chunk of background (z 0..2, y 0..4, x 0..4), left out of the store.
    labels.slice_mut(ndarray::s![0..2, 0..4, 0..4]).fill(0);
    for (dtype, codec) in [("<u2", Codec::Gzip), ("|u1", Codec::Raw), (">i4", Codec::Gzip), ("<u8", Codec::Raw)] {
        let mut store_labels = labels.clone();
        if dtype == "|u1" {
            store_labels.mapv_inplace(|v| v % 200);
        }
        let root = dir.path().join(format!("v2-{}.zarr", dtype.replace(['<', '>', '|'], "")));
        let store = Store {
            zarr_version: 2,
            axes: ZYX_UM.to_vec(),
            levels: vec![Level { shape: vec![5, 6, 7], values: c_order(&store_labels), scale: vec![2.0, 0.5, 0.25] }],
            dtype,
            codec,
            chunks: vec![2, 4, 4],
            skip_empty: true,
        };
        store.write(&root);
        assert!(!root.join("0/0.0.0").exists(), "the background chunk is left out");
        let r = read(&root);
        assert_eq!(r.format, LabelFormat::OmeZarr);
        assert_eq!(r.volume.labels(), &store_labels, "{dtype}");
        assert_close(r.volume.voxel_size(), [2e-6, 0.5e-6, 0.25e-6]);
        assert_eq!(r.voxel_size_source, [VoxelSizeSource::OmeZarr; 3]);
        assert!(r.warnings.is_empty(), "{:?}", r.warnings);
        // The metadata files name the store too.
        assert_eq!(read(&root.join(".zattrs")).volume.labels(), &store_labels);
    }
}

#[test]
fn a_zarr_v3_store_reads_in_nanometres_at_level_0_and_level_1_from_its_labels_group() {
    let dir = tempfile::tempdir().unwrap();
    let labels = sample();
    let coarse = downsample(&labels);
    let image = dir.path().join("image.zarr");
    std::fs::create_dir_all(&image).unwrap();
    write_json(&image.join("zarr.json"), &json!({"zarr_format": 3, "node_type": "group", "attributes": {}}));
    let group = image.join("labels");
    std::fs::create_dir_all(&group).unwrap();
    write_json(
        &group.join("zarr.json"),
        &json!({"zarr_format": 3, "node_type": "group", "attributes": {"ome": {"version": "0.5", "labels": ["cells"]}}}),
    );
    let nm = Some("nanometer");
    let store = Store {
        zarr_version: 3,
        axes: vec![("z", "space", nm), ("y", "space", nm), ("x", "space", nm)],
        levels: vec![
            Level { shape: vec![5, 6, 7], values: c_order(&labels), scale: vec![400.0, 200.0, 200.0] },
            Level { shape: vec![5, 3, 4], values: c_order(&coarse), scale: vec![400.0, 400.0, 400.0] },
        ],
        dtype: "uint16",
        codec: Codec::Gzip,
        chunks: vec![3, 4, 4],
        skip_empty: false,
    };
    let cells = group.join("cells");
    store.write(&cells);
    let r = read(&cells);
    assert_eq!(r.volume.labels(), &labels);
    assert_close(r.volume.voxel_size(), [400e-9, 200e-9, 200e-9]);
    assert_eq!((r.bits, r.signed), (16, false));
    // The labels group lists one image: it is followed.
    assert_eq!(read(&group).volume.labels(), &labels);
    let level1 = read_labels(&cells, &LabelReadOptions { zarr_level: Some(1), ..Default::default() }).unwrap();
    assert_eq!(level1.volume.labels(), &coarse);
    assert_close(level1.volume.voxel_size(), [400e-9, 400e-9, 400e-9]);
    let e =
        read_labels(&cells, &LabelReadOptions { zarr_level: Some(2), ..Default::default() }).unwrap_err().to_string();
    assert!(e.contains("scale level 2") && e.contains("2 level(s)"), "{e}");
    // The caller's voxel size wins over the metadata.
    let given = read_labels(&cells, &LabelReadOptions { voxel_size: Some([1e-6; 3]), ..Default::default() }).unwrap();
    assert_eq!(given.voxel_size_source, [VoxelSizeSource::Caller; 3]);
    // The image group without multiscales points at its label images.
    let e = read_labels(&image, &LabelReadOptions::default()).unwrap_err().to_string();
    assert!(e.contains("not a multiscales group") && e.contains("labels/{cells}"), "{e}");
}

#[test]
fn a_channel_axis_of_one_is_read_and_more_channels_or_other_axes_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let labels = sample();
    let axes = |c: usize| Store {
        zarr_version: 3,
        axes: vec![("c", "channel", None), ZYX_UM[0], ZYX_UM[1], ZYX_UM[2]],
        levels: vec![Level {
            shape: vec![c, 5, 6, 7],
            values: (0..c).flat_map(|_| c_order(&labels)).collect(),
            scale: vec![1.0, 1.0, 0.5, 0.5],
        }],
        dtype: "uint32",
        codec: Codec::Raw,
        chunks: vec![1, 5, 6, 7],
        skip_empty: false,
    };
    let one = dir.path().join("czyx.zarr");
    axes(1).write(&one);
    let r = read(&one);
    assert_eq!(r.volume.labels(), &labels);
    assert_close(r.volume.voxel_size(), [1e-6, 0.5e-6, 0.5e-6]);
    let two = dir.path().join("two-channels.zarr");
    axes(2).write(&two);
    let e = read_labels(&two, &LabelReadOptions::default()).unwrap_err().to_string();
    assert!(e.contains("2 entries along the channel axis `c`") && e.contains("two-channels.zarr"), "{e}");
    let yxz = dir.path().join("yxz.zarr");
    Store { axes: vec![ZYX_UM[1], ZYX_UM[2], ZYX_UM[0]], ..axes(1) }.write(&yxz);
    let mut fixed: Value = serde_json::from_slice(&std::fs::read(yxz.join("zarr.json")).unwrap()).unwrap();
    fixed["attributes"]["ome"]["multiscales"][0]["datasets"][0]["coordinateTransformations"][0]["scale"] =
        json!([1, 1, 1]);
    write_json(&yxz.join("zarr.json"), &fixed);
    let e = read_labels(&yxz, &LabelReadOptions::default()).unwrap_err().to_string();
    assert!(e.contains("axes (y, x, z) are not a 3-D volume"), "{e}");
}

#[test]
fn a_store_without_units_falls_back_to_the_assumed_size_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("nounits.zarr");
    Store {
        zarr_version: 2,
        axes: vec![("z", "space", None), ("y", "space", None), ("x", "space", None)],
        levels: vec![Level { shape: vec![5, 6, 7], values: c_order(&sample()), scale: vec![1.0, 1.0, 1.0] }],
        dtype: "<u2",
        codec: Codec::Raw,
        chunks: vec![5, 6, 7],
        skip_empty: false,
    }
    .write(&root);
    let r = read(&root);
    assert_eq!(r.voxel_size_source, [VoxelSizeSource::Assumed; 3]);
    assert!(r.warnings.iter().any(|w| w.contains("has no unit")), "{:?}", r.warnings);
    assert!(r.warnings.iter().any(|w| w.contains("assuming 1 µm")), "{:?}", r.warnings);
}

#[test]
fn npy_arrays_read_in_c_and_fortran_order_and_both_byte_orders() {
    let dir = tempfile::tempdir().unwrap();
    let labels = sample();
    for descr in ["<u2", ">u2", "|u1", "<i4", ">i8", "<u4"] {
        for fortran in [false, true] {
            let values: Vec<i64> =
                labels.iter().map(|&v| if descr == "|u1" { v as i64 % 200 } else { v as i64 }).collect();
            // No .npy extension: the magic number tells.
            let path = dir.path().join(format!("labels-{}-{fortran}.dat", descr.replace(['<', '>', '|'], "")));
            write_npy(&path, &[5, 6, 7], &values, descr, fortran);
            let r = read(&path);
            assert_eq!(r.format, LabelFormat::Npy);
            let expect: Vec<u32> = values.iter().map(|&v| v as u32).collect();
            assert_eq!(r.volume.labels().iter().copied().collect::<Vec<_>>(), expect, "{descr} fortran={fortran}");
            // No voxel size in a .npy: the fallback, with the TIFF path's warning.
            assert_eq!(r.voxel_size_source, [VoxelSizeSource::Assumed; 3]);
            assert!(r.warnings.iter().any(|w| w.contains("assuming 1 µm") && w.contains(".npy")), "{:?}", r.warnings);
            let given =
                read_labels(&path, &LabelReadOptions { voxel_size: Some([2e-6, 1e-6, 1e-6]), ..Default::default() })
                    .unwrap();
            assert_eq!(given.voxel_size_source, [VoxelSizeSource::Caller; 3]);
            assert!(given.warnings.is_empty());
        }
    }
    let negative = dir.path().join("negative.npy");
    let mut values = c_order(&labels);
    values[5 * 6 * 7 - 1] = -4;
    write_npy(&negative, &[5, 6, 7], &values, "<i2", false);
    let e = read_labels(&negative, &LabelReadOptions::default()).unwrap_err().to_string();
    assert!(e.contains("[4, 5, 6]") && e.contains("-4"), "{e}");
    let too_large = dir.path().join("large.npy");
    values[0] = 1 << 33;
    values[5 * 6 * 7 - 1] = 0;
    write_npy(&too_large, &[5, 6, 7], &values, "<u8", false);
    let e = read_labels(&too_large, &LabelReadOptions::default()).unwrap_err().to_string();
    assert!(e.contains("8589934592") && e.contains("[0, 0, 0]"), "{e}");
    let flat = dir.path().join("flat.npy");
    write_npy(&flat, &[210], &c_order(&labels), "<u2", false);
    let e = read_labels(&flat, &LabelReadOptions::default()).unwrap_err().to_string();
    assert!(e.contains("1 dimensions") && e.contains("flat.npy"), "{e}");
    let e =
        read_labels(&flat, &LabelReadOptions { zarr_level: Some(1), ..Default::default() }).unwrap_err().to_string();
    assert!(e.contains("OME-Zarr stores only"), "{e}");
}

/// The same doublet as TIFF (ImageJ voxel size), OME-Zarr v2 and v3 (multiscales scale in µm) and
/// .npy (--voxel-size): `tissuefit measure` writes the same cells.csv and contacts.csv for each.
#[test]
fn the_same_labels_through_tiff_zarr_and_npy_measure_the_same() {
    let dir = tempfile::tempdir().unwrap();
    let volume = doublet([14, 20, 24]);
    let labels = volume.labels().clone();
    let tif = dir.path().join("doublet.tif");
    write_label_tiff(&tif, &volume, &LabelWriteOptions::default()).unwrap();
    let mut inputs: Vec<(PathBuf, Vec<&str>)> = vec![(tif, vec![])];
    for version in [2u8, 3] {
        let root = dir.path().join(format!("doublet-v{version}.zarr"));
        Store {
            zarr_version: version,
            axes: ZYX_UM.to_vec(),
            levels: vec![Level { shape: vec![14, 20, 24], values: c_order(&labels), scale: vec![1.0, 0.5, 0.5] }],
            dtype: if version == 2 { "<u2" } else { "uint16" },
            codec: Codec::Gzip,
            chunks: vec![8, 8, 8],
            skip_empty: true,
        }
        .write(&root);
        inputs.push((root, vec![]));
    }
    let npy = dir.path().join("doublet.npy");
    write_npy(&npy, &[14, 20, 24], &c_order(&labels), "<u2", true);
    inputs.push((npy, vec!["--voxel-size", "1,0.5,0.5um"]));
    let mut outputs = Vec::new();
    for (k, (input, extra)) in inputs.iter().enumerate() {
        let out = dir.path().join(format!("measure-{k}"));
        let mut args = vec!["measure", input.to_str().unwrap(), "--out", out.to_str().unwrap()];
        args.extend(extra);
        let o = tissuefit(&args);
        assert!(o.status.success(), "{}: {}", input.display(), String::from_utf8_lossy(&o.stderr));
        let cells = std::fs::read_to_string(out.join("cells.csv")).unwrap();
        let contacts = std::fs::read_to_string(out.join("contacts.csv")).unwrap();
        assert!(cells.lines().count() == 3, "two cells: {cells}");
        outputs.push((input.clone(), cells, contacts));
    }
    for (input, cells, contacts) in &outputs[1..] {
        assert_eq!(cells, &outputs[0].1, "cells.csv of {} differs from the TIFF's", input.display());
        assert_eq!(contacts, &outputs[0].2, "contacts.csv of {} differs from the TIFF's", input.display());
    }
}

/// Bad stores and files: exit 2, the file named, the reason given, nothing written.
#[test]
fn bad_stores_and_npy_files_exit_2_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let base = |name: &str, dtype: &'static str, codec: Codec| {
        let root = dir.path().join(name);
        Store {
            zarr_version: 2,
            axes: ZYX_UM.to_vec(),
            levels: vec![Level { shape: vec![5, 6, 7], values: c_order(&sample()), scale: vec![1.0, 1.0, 1.0] }],
            dtype,
            codec,
            chunks: vec![5, 6, 7],
            skip_empty: false,
        }
        .write(&root);
        root
    };
    let no_multiscales = base("no-multiscales.zarr", "<u2", Codec::Raw);
    write_json(&no_multiscales.join(".zattrs"), &json!({"note": "no OME metadata"}));
    let float = base("float.zarr", "<f4", Codec::Raw);
    let blosc = base("blosc.zarr", "<u2", Codec::Blosc);
    let missing_array = base("no-array.zarr", "<u2", Codec::Raw);
    std::fs::remove_file(missing_array.join("0/.zarray")).unwrap();
    let truncated = dir.path().join("truncated.npy");
    write_npy(&truncated, &[5, 6, 7], &c_order(&sample()), "<u2", false);
    let bytes = std::fs::read(&truncated).unwrap();
    std::fs::write(&truncated, &bytes[..bytes.len() - 10]).unwrap();
    let float_npy = dir.path().join("float.npy");
    write_npy(&float_npy, &[5, 6, 7], &c_order(&sample()), "<f4", false);
    let unknown = dir.path().join("labels.dat");
    std::fs::write(&unknown, b"just some bytes").unwrap();
    let cases: [(&Path, &[&str]); 7] = [
        (&no_multiscales, &["no-multiscales.zarr", "not a multiscales group", "multiscales"]),
        (&float, &["float.zarr", "floating-point", "uint16 or uint32"]),
        (&blosc, &["blosc.zarr", "`blosc` codec", "gzip"]),
        (&missing_array, &["no-array.zarr", ".zarray is missing"]),
        (&truncated, &["truncated.npy", "truncated"]),
        (&float_npy, &["float.npy", "floating point"]),
        (&unknown, &["labels.dat", "OME-Zarr", ".npy", "TIFF"]),
    ];
    for (k, (input, says)) in cases.iter().enumerate() {
        for command in ["measure", "mesh"] {
            let out = dir.path().join(format!("out-{k}-{command}"));
            // mesh writes a file, whose folder must exist (and stay empty); measure makes its folder.
            let target = if command == "mesh" { out.join("t.vtp") } else { out.clone() };
            if command == "mesh" {
                std::fs::create_dir(&out).unwrap();
            }
            let o = tissuefit(&[command, input.to_str().unwrap(), "--out", target.to_str().unwrap()]);
            let err = String::from_utf8_lossy(&o.stderr);
            assert_eq!(o.status.code(), Some(2), "{command} {}: {err}", input.display());
            for s in *says {
                assert!(err.contains(s), "{command} {}: `{s}` not in: {err}", input.display());
            }
            let written = if command == "mesh" { std::fs::read_dir(&out).unwrap().count() > 0 } else { out.exists() };
            assert!(!written, "{command} {}: wrote {}", input.display(), out.display());
        }
    }
}

/// A pipeline with an OME-Zarr input and `[input] zarr_level` meshes that level.
#[test]
fn a_pipeline_reads_an_ome_zarr_level_from_its_input_section() {
    let dir = tempfile::tempdir().unwrap();
    let labels = doublet([14, 40, 48]).labels().clone();
    let coarse = downsample(&labels);
    let root = dir.path().join("doublet.zarr");
    Store {
        zarr_version: 3,
        axes: ZYX_UM.to_vec(),
        levels: vec![
            Level { shape: vec![14, 40, 48], values: c_order(&labels), scale: vec![1.0, 0.5, 0.5] },
            Level { shape: vec![14, 20, 24], values: c_order(&coarse), scale: vec![1.0, 1.0, 1.0] },
        ],
        dtype: "uint16",
        codec: Codec::Gzip,
        chunks: vec![8, 16, 16],
        skip_empty: true,
    }
    .write(&root);
    let pipeline = dir.path().join("pipeline.toml");
    std::fs::write(&pipeline, "[input]\nlabels = \"doublet.zarr\"\nzarr_level = 1\n").unwrap();
    let out = dir.path().join("mesh");
    let o = tissuefit(&["mesh", "--config", pipeline.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report: Value = serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["shape"], json!([14, 20, 24]), "{report}");
    let voxel: Vec<f64> = report["voxel_size"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    assert_close([voxel[0], voxel[1], voxel[2]], [1e-6, 1e-6, 1e-6]);
    // The same through the CLI flag.
    let out = dir.path().join("direct.vtp");
    let o = tissuefit(&["mesh", root.to_str().unwrap(), "--zarr-level", "1", "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report: Value = serde_json::from_slice(&std::fs::read(dir.path().join("direct.report.json")).unwrap()).unwrap();
    assert_eq!(report["shape"], json!([14, 20, 24]), "{report}");
}

#[test]
fn zarr_level_is_refused_for_a_tiff() {
    let dir = tempfile::tempdir().unwrap();
    let volume = LabelVolume::new(sample(), [1e-6; 3], Vec3::zeros()).unwrap();
    let tif = dir.path().join("l.tif");
    write_label_tiff(&tif, &volume, &LabelWriteOptions::default()).unwrap();
    let e = read_labels(&tif, &LabelReadOptions { zarr_level: Some(0), ..Default::default() }).unwrap_err().to_string();
    assert!(e.contains("TIFF file") && e.contains("OME-Zarr stores only") && e.contains("l.tif"), "{e}");
}

/// Stores and a .npy written by Python (zarr-python 3.1.6, numpy 2.4.6; tests/data/python_zarr/make.py):
/// Zarr v3 with zarr-python's default zstd codec and a channel axis, Zarr v2 with GZip and int32, a
/// Fortran-order .npy; all read as the labels make.py computes.
#[test]
fn python_written_stores_read_identically() {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/python_zarr");
    let expected = Array3::from_shape_fn((6, 10, 12), |(z, y, x)| (((3 * z + 2 * y + x) / 4) % 5 * (z + 1)) as u32);
    let v3 = read(&data.join("cells_v3.zarr"));
    assert_eq!(v3.volume.labels(), &expected);
    assert_close(v3.volume.voxel_size(), [0.8e-6, 0.25e-6, 0.25e-6]);
    assert_eq!(v3.voxel_size_source, [VoxelSizeSource::OmeZarr; 3]);
    let level1 =
        read_labels(&data.join("cells_v3.zarr"), &LabelReadOptions { zarr_level: Some(1), ..Default::default() })
            .unwrap();
    assert_eq!(level1.volume.labels(), &downsample(&expected));
    assert_close(level1.volume.voxel_size(), [0.8e-6, 0.5e-6, 0.5e-6]);
    let v2 = read(&data.join("cells_v2.zarr"));
    assert_eq!(v2.volume.labels(), &expected);
    assert_eq!((v2.bits, v2.signed), (32, true));
    assert_close(v2.volume.voxel_size(), [800e-9, 250e-9, 250e-9]);
    let npy = read(&data.join("cells_f.npy"));
    assert_eq!(npy.volume.labels(), &expected);
}

fn statuses(run: &Path) -> Vec<String> {
    let m: Value = serde_json::from_slice(&std::fs::read(run.join("manifest.json")).unwrap()).unwrap();
    m["stages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| format!("{}:{}", s["name"].as_str().unwrap(), s["status"].as_str().unwrap()))
        .collect()
}

/// `tissuefit run` on an OME-Zarr folder: the manifest hashes the store's files, so a rerun skips
/// the stages, and a changed chunk or a changed `zarr_level` re-runs the mesh.
#[test]
fn a_pipeline_run_hashes_a_zarr_store_and_reruns_when_a_chunk_or_the_level_changes() {
    let dir = tempfile::tempdir().unwrap();
    let labels = doublet([14, 20, 24]).labels().clone();
    let root = dir.path().join("doublet.zarr");
    let store = |labels: &Array3<u32>| Store {
        zarr_version: 2,
        axes: ZYX_UM.to_vec(),
        levels: vec![
            Level { shape: vec![14, 20, 24], values: c_order(labels), scale: vec![1.0, 0.5, 0.5] },
            Level { shape: vec![14, 10, 12], values: c_order(&downsample(labels)), scale: vec![1.0, 1.0, 1.0] },
        ],
        dtype: "<u2",
        codec: Codec::Gzip,
        chunks: vec![7, 10, 12],
        skip_empty: false,
    };
    store(&labels).write(&root);
    let pipeline = dir.path().join("pipeline.toml");
    std::fs::write(&pipeline, "[input]\nlabels = \"doublet.zarr\"\n").unwrap();
    let run = dir.path().join("run");
    let args = ["run", pipeline.to_str().unwrap(), "--out", run.to_str().unwrap()];
    let go = || {
        let o = tissuefit(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        statuses(&run)
    };
    assert_eq!(go(), ["mesh:complete", "measure:complete"]);
    let manifest: Value = serde_json::from_slice(&std::fs::read(run.join("manifest.json")).unwrap()).unwrap();
    let first_hash = manifest["inputs"][0]["blake3"].as_str().unwrap().to_string();
    assert!(manifest["inputs"][0]["path"].as_str().unwrap().ends_with("doublet.zarr"), "{manifest}");
    assert_eq!(go(), ["mesh:skipped", "measure:skipped"]);
    // One voxel of cell 1 given to cell 2: a chunk's bytes change, and so does the store's hash.
    let mut changed = labels.clone();
    let at = changed.indexed_iter().find(|(_, v)| **v == 1).map(|(i, _)| i).unwrap();
    changed[at] = 2;
    store(&changed).write(&root);
    assert_eq!(go(), ["mesh:complete", "measure:complete"]);
    let manifest: Value = serde_json::from_slice(&std::fs::read(run.join("manifest.json")).unwrap()).unwrap();
    assert_ne!(manifest["inputs"][0]["blake3"].as_str().unwrap(), first_hash);
    std::fs::write(&pipeline, "[input]\nlabels = \"doublet.zarr\"\nzarr_level = 1\n").unwrap();
    assert_eq!(go(), ["mesh:complete", "measure:complete"]);
}

/// `[measure] zarr_properties = true`: the measure stage (measuring the meshed tissue, whose cell
/// ids are the labels) writes its cells into the `input.labels` store's `image-label.properties`;
/// the properties are left out of the store's hash, so a second run skips every stage. A TIFF
/// `input.labels` is refused naming the key.
#[test]
fn a_pipeline_writes_zarr_properties_into_its_labels_and_a_rerun_skips_its_stages() {
    let dir = tempfile::tempdir().unwrap();
    let labels = doublet([14, 20, 24]);
    let root = dir.path().join("doublet.zarr");
    Store {
        zarr_version: 2,
        axes: ZYX_UM.to_vec(),
        levels: vec![Level { shape: vec![14, 20, 24], values: c_order(labels.labels()), scale: vec![1.0, 0.5, 0.5] }],
        dtype: "<u2",
        codec: Codec::Gzip,
        chunks: vec![7, 10, 12],
        skip_empty: false,
    }
    .write(&root);
    let pipeline = dir.path().join("pipeline.toml");
    std::fs::write(&pipeline, "[input]\nlabels = \"doublet.zarr\"\n[measure]\nzarr_properties = true\n").unwrap();
    let run = dir.path().join("run");
    let args = ["run", pipeline.to_str().unwrap(), "--out", run.to_str().unwrap()];
    let go = || {
        let o = tissuefit(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        statuses(&run)
    };
    assert_eq!(go(), ["mesh:complete", "measure:complete"]);
    let attrs: Value = serde_json::from_slice(&std::fs::read(root.join(".zattrs")).unwrap()).unwrap();
    let list = attrs["image-label"]["properties"].as_array().unwrap();
    let mut csv = csv::Reader::from_path(run.join("measure").join("cells.csv")).unwrap();
    let rows: Vec<(u64, f64)> =
        csv.records().map(|r| r.unwrap()).map(|r| (r[0].parse().unwrap(), r[3].parse().unwrap())).collect();
    assert_eq!(rows.len(), 2);
    assert_eq!(list.len(), 2, "{list:?}");
    for ((label, volume), entry) in rows.iter().zip(list) {
        assert_eq!(entry["label-value"], json!(label));
        let um3 = entry["volume_um3"].as_f64().unwrap();
        assert!((um3 - volume * 1e18).abs() <= 1e-12 * um3, "{um3} vs {volume}");
    }
    assert_eq!(attrs["image-label"]["version"], "0.4", "kept");
    assert!(attrs["tissuefit"]["outputs"].as_str().unwrap().ends_with("measure"), "{}", attrs["tissuefit"]);
    assert_eq!(attrs["tissuefit"]["input"], "../mesh/tissue.vtp");
    assert_eq!(go(), ["mesh:skipped", "measure:skipped"]);

    let volume = LabelVolume::new(labels.labels().clone(), [1e-6; 3], Vec3::zeros()).unwrap();
    write_label_tiff(&dir.path().join("doublet.tif"), &volume, &LabelWriteOptions::default()).unwrap();
    std::fs::write(&pipeline, "[input]\nlabels = \"doublet.tif\"\n[measure]\nzarr_properties = true\n").unwrap();
    let o = tissuefit(&args);
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains("measure.zarr_properties") && e.contains("doublet.tif") && e.contains("TIFF"), "{e}");
    std::fs::write(&pipeline, "[input]\nmesh = \"run/mesh/tissue.vtp\"\n[measure]\nzarr_properties = true\n").unwrap();
    let e = String::from_utf8_lossy(&tissuefit(&args).stderr).to_string();
    assert!(e.contains("measure.zarr_properties") && e.contains("input.labels"), "{e}");
}

#[test]
fn zarr_level_in_a_fit_config_needs_a_labels_input() {
    let text =
        "[observed]\ntissue = \"tissue.vtk\"\nzarr_level = 1\n[parameters.surface_tension]\nbounds = [1e-4, 1e-3]\n";
    let e = tissuefit::inference::FitConfig::from_toml_str(text, "fit.toml").unwrap_err().to_string();
    assert!(e.contains("fit.toml") && e.contains("observed.zarr_level"), "{e}");
    let text = "[input]\nmesh = \"tissue.vtp\"\nzarr_level = 1\n";
    let e =
        tissuefit::pipeline::PipelineConfig::load_text(text, Path::new("p.toml")).map(|_| ()).unwrap_err().to_string();
    assert!(e.contains("input.zarr_level") && e.contains("not to a mesh"), "{e}");
}

/// The generated two-cell label volume of `shape` (z, y, x) at 1 × 0.5 × 0.5 µm voxels.
fn doublet(shape: [usize; 3]) -> LabelVolume {
    let spec = LabelSpec {
        pattern: LabelPattern::Doublet,
        shape,
        voxel_size: [1e-6, 0.5e-6, 0.5e-6],
        cells: 2,
        seed: 0,
        lumen: false,
    };
    generate_labels(&spec).unwrap().volume
}

/// HDF5 files written by h5py 3.16 / HDF5 2.0 (tests/data/python_h5/make.py): PlantSeg's layout
/// (a float /raw beside a gzip-chunked uint16 /segmentation with element_size_um) read without
/// naming the dataset; two unnamed candidates refused with both listed and read when named
/// (`FILE.h5/a/cells`, int64 with shuffle + gzip and a leading channel axis of 1; `b/nuclei`, LZF); a float-only
/// file, a float dataset named explicitly, a missing dataset, HDF5 2.0's layout version 5, a
/// truncated file and garbage: errors naming the file and saying what to do, never a panic.
#[test]
fn hdf5_files_written_by_h5py_read_identically() {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/python_h5");
    let expected = Array3::from_shape_fn((6, 10, 12), |(z, y, x)| (((3 * z + 2 * y + x) / 4) % 5 * (z + 1)) as u32);
    let error = |path: &Path| read_labels(path, &LabelReadOptions::default()).map(|_| ()).unwrap_err().to_string();
    for path in [data.join("plantseg.h5"), data.join("plantseg.h5/segmentation")] {
        let seg = read(&path);
        assert_eq!(seg.volume.labels(), &expected);
        assert_eq!((seg.format, seg.bits, seg.signed), (LabelFormat::Hdf5, 16, false));
        assert_close(seg.volume.voxel_size(), [0.8e-6, 0.25e-6, 0.25e-6]);
        assert_eq!(seg.voxel_size_source, [VoxelSizeSource::Hdf5ElementSize; 3]);
        assert!(seg.warnings.is_empty(), "{:?}", seg.warnings);
    }
    let e = error(&data.join("two.h5"));
    assert!(e.contains("a/cells") && e.contains("b/nuclei") && e.contains("FILE.h5/"), "{e}");
    let cells = read(&data.join("two.h5/a/cells"));
    assert_eq!(cells.volume.labels(), &expected);
    assert_eq!((cells.bits, cells.signed), (64, true));
    assert_eq!(cells.voxel_size_source, [VoxelSizeSource::Assumed; 3]);
    assert!(cells.warnings.iter().any(|w| w.contains("element_size_um")), "{:?}", cells.warnings);
    assert_eq!(read(&data.join("two.h5/b/nuclei")).volume.labels(), &expected.mapv(|v| v / 2));
    let e = error(&data.join("plantseg.h5/raw"));
    assert!(e.contains("plantseg.h5/raw") && e.contains("f32") && e.contains("integers"), "{e}");
    let e = error(&data.join("probabilities.h5"));
    assert!(e.contains("no 3-D integer dataset") && e.contains("prob ([6, 10, 12], f32)"), "{e}");
    let e = error(&data.join("plantseg.h5/missing"));
    assert!(e.contains("no dataset `missing`") && e.contains("segmentation ([6, 10, 12], u16)"), "{e}");
    let e = error(&data.join("latest.h5"));
    assert!(e.contains("latest.h5") && e.contains("libver"), "{e}");
    let dir = tempfile::tempdir().unwrap();
    let bytes = std::fs::read(data.join("plantseg.h5")).unwrap();
    for (name, content) in
        [("cut.h5", &bytes[..bytes.len() / 2]), ("head.h5", &bytes[..600]), ("garbage.h5", b"not hdf5")]
    {
        let path = dir.path().join(name);
        std::fs::write(&path, content).unwrap();
        let e = error(&path);
        assert!(e.contains(name), "{e}");
    }
}

/// `tissuefit run` on a dataset inside an HDF5 file (`doublet.h5/segmentation`): the manifest hashes
/// the file and the dataset's path, so a rerun skips, and naming the other dataset of the same file
/// (`doublet.h5/copy`, the same labels as int32) re-runs the mesh.
#[test]
fn a_pipeline_run_reads_a_dataset_inside_an_hdf5_file() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/python_h5/doublet.h5"),
        dir.path().join("doublet.h5"),
    )
    .unwrap();
    let pipeline = dir.path().join("pipeline.toml");
    let run = dir.path().join("run");
    let args = ["run", pipeline.to_str().unwrap(), "--out", run.to_str().unwrap()];
    let go = |dataset: &str| {
        std::fs::write(&pipeline, format!("[input]\nlabels = \"doublet.h5/{dataset}\"\n")).unwrap();
        let o = tissuefit(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let manifest: Value = serde_json::from_slice(&std::fs::read(run.join("manifest.json")).unwrap()).unwrap();
        (statuses(&run), manifest["inputs"][0]["blake3"].as_str().unwrap().to_string())
    };
    let (first, hash) = go("segmentation");
    assert_eq!(first, ["mesh:complete", "measure:complete"]);
    let summary: Value = serde_json::from_slice(&std::fs::read(run.join("mesh/report.json")).unwrap()).unwrap();
    assert_eq!(summary["kept"], 2, "{summary}");
    // The voxel size from the dataset's element_size_um attribute.
    assert_eq!(summary["voxel_size"], json!([5e-7, 5e-7, 5e-7]), "{summary}");
    assert_eq!(go("segmentation"), (vec!["mesh:skipped".to_string(), "measure:skipped".to_string()], hash.clone()));
    let (again, other) = go("copy");
    assert_eq!(again, ["mesh:complete", "measure:complete"]);
    assert_ne!(other, hash);
}

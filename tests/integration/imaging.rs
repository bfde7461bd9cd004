//! Label volumes: TIFF round trips (dtypes, compressions, BigTIFF), metadata, bad input, voxelisation
//! accuracy and determinism, the real label files, and the `voxelize` / `generate labels` commands.

use crate::support::cli::tissuefit;
use ndarray::Array3;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use tiff::encoder::{TiffEncoder, colortype};
use tissuefit::geometry::{Real, Vec3};
use tissuefit::imaging::*;
use tissuefit::io::{ReadOptions, read_tissue};
use tissuefit::mesh::{Cell, CellId, CellKind, Tissue, shapes};

fn real(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/real").join(name)
}

fn rel_close(a: Real, b: Real, tol: Real) -> bool {
    (a - b).abs() <= tol * b.abs()
}

/// A small volume with labels spread over the dtype's range.
fn sample_volume(max_label: u32) -> LabelVolume {
    let labels = Array3::from_shape_fn((5, 7, 9), |(z, y, x)| {
        let v = (z * 63 + y * 9 + x) as u32;
        if v.is_multiple_of(5) { 0 } else { v.wrapping_mul(2_654_435_761) % max_label + 1 }
    });
    let mut labels = labels;
    labels[[4, 6, 8]] = max_label;
    LabelVolume::new(labels, [0.235e-6, 0.15e-6, 0.1e-6], Vec3::new(-3e-6, 1.5e-6, 0.47e-6)).unwrap()
}

#[test]
fn written_labels_read_back_identically_for_every_dtype_compression_and_bigtiff() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [(LabelDtype::U8, 255u32), (LabelDtype::U16, 65_535), (LabelDtype::U32, 4_000_000_000)];
    for (dtype, max) in cases {
        let volume = sample_volume(max);
        for compression in [TiffCompression::None, TiffCompression::Lzw, TiffCompression::Deflate] {
            for bigtiff in [false, true] {
                let path = dir.path().join(format!("{dtype:?}-{compression:?}-{bigtiff}.tif"));
                let options = LabelWriteOptions { dtype: Some(dtype), compression, bigtiff };
                assert_eq!(write_label_tiff(&path, &volume, &options).unwrap(), dtype);
                let read = read_label_tiff(&path, &LabelReadOptions::default()).unwrap();
                assert_eq!(read.volume.labels(), volume.labels(), "{path:?}");
                assert_eq!(read.bits, [8, 16, 32][dtype as usize]);
                assert!(!read.signed);
                let expected_code = match compression {
                    TiffCompression::None => 1,
                    TiffCompression::Lzw => 5,
                    TiffCompression::Deflate => 8,
                };
                assert_eq!(read.compression, expected_code);
                assert_eq!(read.voxel_size_source, [VoxelSizeSource::ImageJ; 3]);
                assert!(read.warnings.is_empty(), "{:?}", read.warnings);
                for (a, b) in read.volume.voxel_size().iter().zip(volume.voxel_size()) {
                    assert!(rel_close(*a, b, 1e-9), "{a} vs {b}");
                }
                // The origin travels as ImageJ xorigin/yorigin/zorigin (in voxels).
                assert!((read.volume.origin() - volume.origin()).norm() < 1e-15, "{}", read.volume.origin());
            }
        }
    }
    // The default dtype: uint16 up to 65535, uint32 beyond; a dtype too small is an error.
    let path = dir.path().join("default.tif");
    assert_eq!(write_label_tiff(&path, &sample_volume(900), &Default::default()).unwrap(), LabelDtype::U16);
    assert_eq!(write_label_tiff(&path, &sample_volume(70_000), &Default::default()).unwrap(), LabelDtype::U32);
    let small = LabelWriteOptions { dtype: Some(LabelDtype::U8), ..Default::default() };
    let err = write_label_tiff(&path, &sample_volume(300), &small).unwrap_err().to_string();
    assert!(err.contains("300") && err.contains("uint8"), "{err}");
}

#[test]
fn written_header_is_an_imagej_hyperstack() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ij.tif");
    write_label_tiff(&path, &sample_volume(1000), &Default::default()).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let text = String::from_utf8_lossy(&bytes);
    for key in [
        "ImageJ=",
        "images=5\n",
        "slices=5\n",
        "unit=micron\n",
        "spacing=0.235\n",
        "xorigin=30\n",
        "yorigin=-10\n",
        "zorigin=-2\n",
    ] {
        assert!(text.contains(key), "missing {key:?}");
    }
    // No temporary file left behind.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

/// Whether python3 can import tifffile (the reference reader of napari).
fn have_tifffile() -> bool {
    Command::new("python3").args(["-c", "import tifffile"]).output().is_ok_and(|o| o.status.success())
}

#[test]
fn tifffile_reads_our_labels_and_voxel_size() {
    if !have_tifffile() {
        // CI installs tifffile and sets the variable: there the check must run, not skip.
        assert!(
            std::env::var_os("TISSUEFIT_REQUIRE_TIFFFILE").is_none(),
            "TISSUEFIT_REQUIRE_TIFFFILE is set but python3 cannot import tifffile"
        );
        eprintln!("skipped: python3 cannot import tifffile (pip install tifffile numpy to run it)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    for (dtype, max) in [(LabelDtype::U8, 255u32), (LabelDtype::U16, 65_535), (LabelDtype::U32, 4_000_000_000)] {
        let volume = sample_volume(max);
        let path = dir.path().join(format!("{dtype:?}.tif"));
        write_label_tiff(&path, &volume, &LabelWriteOptions { dtype: Some(dtype), ..Default::default() }).unwrap();
        let script = r#"
import sys, tifffile
with tifffile.TiffFile(sys.argv[1]) as t:
    a = t.asarray()
    ij = t.imagej_metadata
    xr = t.pages[0].tags['XResolution'].value
    print(a.dtype, *a.shape, int(a.sum()), ij['spacing'], ij['unit'], xr[1] / xr[0])
"#;
        let out = Command::new("python3").args(["-c", script, path.to_str().unwrap()]).output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let text = String::from_utf8_lossy(&out.stdout);
        let f: Vec<&str> = text.split_whitespace().collect();
        assert_eq!(f[0], dtype.name());
        assert_eq!(f[1..4], ["5", "7", "9"]);
        let sum: u64 = volume.labels().iter().map(|&l| l as u64).sum();
        assert_eq!(f[4].parse::<u64>().unwrap(), sum);
        assert!(rel_close(f[5].parse::<f64>().unwrap(), 0.235, 1e-9));
        assert_eq!(f[6], "micron");
        assert!(rel_close(f[7].parse::<f64>().unwrap(), 0.1, 1e-8));
    }
}

#[test]
fn caller_voxel_size_overrides_and_missing_metadata_falls_back_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    // A plain stack written by the tiff crate: no ImageJ description, default resolution 1/1 (no unit).
    let path = dir.path().join("plain.tif");
    let page: Vec<u16> = (0..12).collect();
    write_pages::<colortype::Gray16>(&path, &[&page, &page, &page], 4, 3);
    let read = read_label_tiff(&path, &LabelReadOptions::default()).unwrap();
    assert_eq!(read.volume.shape(), [3, 3, 4]);
    assert_eq!(read.voxel_size_source, [VoxelSizeSource::Assumed; 3]);
    assert_eq!(read.volume.voxel_size(), [1e-6; 3]);
    assert_eq!(read.warnings.len(), 1);
    assert!(
        read.warnings[0].contains("assuming 1 µm") && read.warnings[0].contains("plain.tif"),
        "{:?}",
        read.warnings
    );
    let options = LabelReadOptions {
        voxel_size: Some([2e-6, 0.5e-6, 0.25e-6]),
        origin: Some(Vec3::new(1.0, 2.0, 3.0)),
        ..Default::default()
    };
    let read = read_label_tiff(&path, &options).unwrap();
    assert_eq!(read.voxel_size_source, [VoxelSizeSource::Caller; 3]);
    assert_eq!(read.volume.voxel_size(), [2e-6, 0.5e-6, 0.25e-6]);
    assert_eq!(read.volume.origin(), Vec3::new(1.0, 2.0, 3.0));
    assert!(read.warnings.is_empty());
    assert_eq!(read.volume.labels()[[2, 2, 3]], 11);
}

#[test]
fn signed_labels_are_read_when_non_negative() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("int32.tif");
    let page: Vec<i32> = vec![0, 5, 70_000, 3];
    write_pages::<colortype::GrayI32>(&path, &[&page, &page], 2, 2);
    let read = read_label_tiff(&path, &LabelReadOptions::default()).unwrap();
    assert!(read.signed && read.bits == 32);
    assert_eq!(read.volume.labels().iter().copied().collect::<Vec<_>>(), vec![0, 5, 70_000, 3, 0, 5, 70_000, 3]);
}

/// Writes `pages` (each `width`×`height`) with the tiff crate's encoder, no metadata.
fn write_pages<C: colortype::ColorType>(path: &Path, pages: &[&[C::Inner]], width: u32, height: u32)
where
    [C::Inner]: tiff::encoder::TiffValue,
{
    let mut file = std::fs::File::create(path).unwrap();
    let mut enc = TiffEncoder::new(&mut file).unwrap();
    for p in pages {
        enc.write_image::<C>(width, height, p).unwrap();
    }
}

/// A minimal little-endian TIFF with one IFD of (tag, type, count, value) entries and `data` at offset 8.
fn handmade_tiff(entries: &[(u16, u16, u32, u32)], data: &[u8]) -> Vec<u8> {
    let mut b = b"II*\0".to_vec();
    let ifd = 8 + data.len() as u32;
    b.extend_from_slice(&ifd.to_le_bytes());
    b.extend_from_slice(data);
    b.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    for &(tag, ty, count, value) in entries {
        b.extend_from_slice(&tag.to_le_bytes());
        b.extend_from_slice(&ty.to_le_bytes());
        b.extend_from_slice(&count.to_le_bytes());
        b.extend_from_slice(&value.to_le_bytes());
    }
    b.extend_from_slice(&0u32.to_le_bytes());
    b
}

#[test]
fn bad_inputs_give_clear_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let good = d.join("good.tif");
    write_label_tiff(&good, &sample_volume(1000), &Default::default()).unwrap();
    let bytes = std::fs::read(&good).unwrap();

    let truncated = d.join("truncated.tif");
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
    let header_only = d.join("header_only.tif");
    std::fs::write(&header_only, &bytes[..6]).unwrap();
    let garbage = d.join("garbage.tif");
    std::fs::write(&garbage, b"this is not a tiff file at all").unwrap();
    let empty = d.join("empty.tif");
    std::fs::write(&empty, b"").unwrap();

    let float = d.join("float.tif");
    let fpage = [0.5f32; 6];
    write_pages::<colortype::Gray32Float>(&float, &[&fpage, &fpage], 3, 2);
    let rgb = d.join("rgb.tif");
    let cpage = [7u8; 18];
    write_pages::<colortype::RGB8>(&rgb, &[&cpage, &cpage], 3, 2);
    let flat = d.join("flat.tif");
    let page = [1u16; 6];
    write_pages::<colortype::Gray16>(&flat, &[&page], 3, 2);
    let negative = d.join("negative.tif");
    let spage = [0i16, 1, 2, 3, -4, 5];
    write_pages::<colortype::GrayI16>(&negative, &[&spage, &spage], 3, 2);
    let ragged = d.join("ragged.tif");
    let big = [1u16; 12];
    write_pages::<colortype::Gray16>(&ragged, &[&page, &big], 3, 2);
    // Second page 4x3, first 3x2:
    {
        let mut file = std::fs::File::create(&ragged).unwrap();
        let mut enc = TiffEncoder::new(&mut file).unwrap();
        enc.write_image::<colortype::Gray16>(3, 2, &page).unwrap();
        enc.write_image::<colortype::Gray16>(4, 3, &big).unwrap();
    }
    let mixed = d.join("mixed.tif");
    {
        let mut file = std::fs::File::create(&mixed).unwrap();
        let mut enc = TiffEncoder::new(&mut file).unwrap();
        enc.write_image::<colortype::Gray16>(3, 2, &page).unwrap();
        enc.write_image::<colortype::Gray8>(3, 2, &[1u8; 6]).unwrap();
    }
    let huge = d.join("huge.tif");
    // 100000 x 100000 uint16 declared, 16 bytes stored.
    let entries = [
        (256, 4, 1, 100_000),
        (257, 4, 1, 100_000),
        (258, 3, 1, 16),
        (259, 3, 1, 1),
        (262, 3, 1, 1),
        (273, 4, 1, 8),
        (277, 3, 1, 1),
        (278, 4, 1, 100_000),
        (279, 4, 1, 16),
    ];
    std::fs::write(&huge, handmade_tiff(&entries, &[0u8; 16])).unwrap();
    let huge_lzw = d.join("huge_lzw.tif");
    let mut lzw_entries = entries;
    lzw_entries[3] = (259, 3, 1, 5);
    std::fs::write(&huge_lzw, handmade_tiff(&lzw_entries, &[0u8; 16])).unwrap();
    let beyond = d.join("beyond.tif");
    let mut beyond_entries = entries;
    beyond_entries[0] = (256, 4, 1, 4);
    beyond_entries[1] = (257, 4, 1, 2);
    beyond_entries[5] = (273, 4, 1, 5000);
    std::fs::write(&beyond, handmade_tiff(&beyond_entries, &[0u8; 16])).unwrap();

    let cases: [(&Path, &[&str]); 14] = [
        (&truncated, &["truncated"]),
        (&header_only, &["not a readable TIFF"]),
        (&garbage, &["not a readable TIFF"]),
        (&empty, &["not a readable TIFF"]),
        (&float, &["floating-point", "32-bit"]),
        (&rgb, &["3 samples per pixel", "RGB"]),
        (&flat, &["2D", "must be 3D", "3x2"]),
        (&negative, &["-4", "[0, 1, 1]"]),
        (&ragged, &["page 1 is 4x3", "page 0 is 3x2"]),
        (&mixed, &["page 1", "uint8", "uint16"]),
        (&huge, &["100000x100000", "stores only 16 bytes"]),
        (&huge_lzw, &["100000x100000", "stores only 16 bytes"]),
        (&beyond, &["truncated", "5016"]),
        (&d.join("absent.tif"), &["cannot open"]),
    ];
    for (path, needles) in cases {
        let result = std::panic::catch_unwind(|| read_label_tiff(path, &LabelReadOptions::default()));
        let err = result.unwrap_or_else(|_| panic!("{path:?}: panicked")).expect_err("bad input must fail");
        let msg = err.to_string();
        let name = path.file_name().unwrap().to_str().unwrap();
        assert!(msg.contains(name), "error does not name the file: {msg}");
        for n in needles {
            assert!(msg.contains(n), "{name}: `{msg}` lacks `{n}`");
        }
    }
}

#[test]
fn all_background_volume_reads_with_an_empty_label_list() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("zeros.tif");
    let grid = VoxelGrid::new([3, 4, 5], [1e-6; 3], Vec3::zeros()).unwrap();
    write_label_tiff(&path, &LabelVolume::zeros(&grid).unwrap(), &Default::default()).unwrap();
    let read = read_label_tiff(&path, &LabelReadOptions::default()).unwrap();
    assert_eq!(read.volume.shape(), [3, 4, 5]);
    assert!(read.volume.label_stats().is_empty());
    assert_eq!(read.volume.max_label(), 0);
}

fn single_cell(mesh: tissuefit::mesh::CellMesh) -> Tissue {
    Tissue::from_cells(vec![Cell::new(CellId(5), CellKind::Epithelial, 0, mesh)]).unwrap()
}

#[test]
fn voxelised_sphere_has_the_ball_volume() {
    // R = 10 µm on a 0.4 µm grid (25 voxels per radius). The icosphere (5 subdivisions) is inscribed:
    // its volume is 0.1 % below the ball's; voxel counting adds O(h/R)² ≈ 0.2 % noise. 1 % is ample.
    let r = 10e-6;
    let mesh = shapes::icosphere(r, 5, Vec3::new(1e-6, -2e-6, 3e-6));
    let mesh_volume = mesh.signed_volume();
    let tissue = single_cell(mesh);
    let grid = VoxelGrid::covering(Vec3::repeat(-10e-6), Vec3::repeat(13e-6), [0.4e-6; 3], 2).unwrap();
    let (volume, stats) = voxelize_with_stats(&tissue, &grid).unwrap();
    assert_eq!((stats.odd_rows, stats.overlapping_voxels), (0, 0));
    let n = volume.label_stats()[0].voxels as Real;
    assert_eq!(stats.voxels, vec![(CellId(5), n as u64)]);
    let v = n * volume.voxel_volume();
    let ball = 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
    assert!(rel_close(v, ball, 0.01), "{v} vs {ball}");
    assert!(rel_close(v, mesh_volume, 0.005), "{v} vs mesh {mesh_volume}");
    // Anisotropic voxels (z 3× coarser) measure the same volume within 1 %.
    let grid = VoxelGrid::covering(Vec3::repeat(-10e-6), Vec3::repeat(13e-6), [1.2e-6, 0.4e-6, 0.4e-6], 2).unwrap();
    let n = voxelize(&tissue, &grid).unwrap().label_stats()[0].voxels as Real;
    assert!(rel_close(n * 1.2e-6 * 0.4e-6 * 0.4e-6, ball, 0.01));
}

#[test]
fn voxelised_cube_is_exact() {
    // A 4 µm cube spanning 0.25..4.25 µm, faces halfway between the voxel centres at −1 + 0.5·i µm:
    // exactly the centres i = 3..=10 along each axis.
    let tissue = single_cell(shapes::subdivided_cube(4e-6, 4, Vec3::new(2.25e-6, 2.25e-6, 2.25e-6)));
    let grid = VoxelGrid::new([14, 14, 14], [0.5e-6; 3], Vec3::new(-1e-6, -1e-6, -1e-6)).unwrap();
    let (volume, stats) = voxelize_with_stats(&tissue, &grid).unwrap();
    assert_eq!(stats.voxels[0].1, 512);
    let info = volume.label_stats();
    assert_eq!((info[0].min, info[0].max), ([3, 3, 3], [10, 10, 10]));
    assert!(!volume.touches_border(5));
}

#[test]
fn voxelisation_is_identical_on_1_and_4_threads_and_keeps_the_first_of_overlapping_cells() {
    let cells = (0..6)
        .map(|i| {
            let c = Vec3::new(i as Real * 3e-6, (i % 2) as Real * 2e-6, 0.0);
            Cell::new(CellId(10 + i), CellKind::Epithelial, 0, shapes::icosphere(2e-6, 3, c))
        })
        .collect();
    let tissue = Tissue::from_cells(cells).unwrap();
    let grid = VoxelGrid::covering(Vec3::repeat(-3e-6), Vec3::new(18e-6, 5e-6, 3e-6), [0.1e-6; 3], 1).unwrap();
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| voxelize_with_stats(&tissue, &grid).unwrap())
    };
    let (a, sa) = run(1);
    let (b, sb) = run(4);
    assert_eq!(a.labels(), b.labels());
    assert_eq!(sa, sb);
    // Neighbouring spheres (radius 2, centres 3.6 apart) overlap; the overlap goes to the earlier cell.
    assert!(sa.overlapping_voxels > 0);
    assert!(sa.voxels[0].1 > sa.voxels[1].1);
    let labels: Vec<u32> = a.label_stats().iter().map(|i| i.label).collect();
    assert_eq!(labels, (10..16).collect::<Vec<_>>());
}

#[test]
fn voxelising_a_background_cell_or_on_a_bad_grid_is_an_error() {
    let tissue = Tissue::from_cells(vec![Cell::new(
        CellId(0),
        CellKind::Epithelial,
        0,
        shapes::icosphere(1.0, 1, Vec3::zeros()),
    )])
    .unwrap();
    let grid = VoxelGrid { shape: [4, 4, 4], voxel_size: [1.0; 3], origin: Vec3::repeat(-2.0) };
    assert!(matches!(voxelize(&tissue, &grid), Err(ImagingError::BackgroundCell { .. })));
    let bad = VoxelGrid { voxel_size: [1.0, 0.0, 1.0], ..grid };
    assert!(matches!(
        voxelize(&single_cell(shapes::icosphere(1.0, 1, Vec3::zeros())), &bad),
        Err(ImagingError::Grid(_))
    ));
}

#[test]
#[ignore = "needs ../shared/data/real (not committed)"]
fn reads_the_plantseg_ovule_labels() {
    let read = read_label_tiff(&real("plant-seg__sample_ovule_labels.tif"), &LabelReadOptions::default()).unwrap();
    let v = &read.volume;
    assert_eq!(v.shape(), [32, 128, 128]);
    assert_eq!(read.bits, 16);
    assert_eq!(read.voxel_size_source, [VoxelSizeSource::ImageJ; 3]);
    for (a, b) in v.voxel_size().iter().zip([0.235e-6, 0.15e-6, 0.15e-6]) {
        assert!(rel_close(*a, b, 1e-6), "{:?}", v.voxel_size());
    }
    let stats = v.label_stats();
    assert_eq!(stats.len(), 50);
    assert_eq!(stats.last().unwrap().label, 918);
    // README: background is only 13 voxels and every cell touches the crop border.
    let labelled: u64 = stats.iter().map(|i| i.voxels).sum();
    assert_eq!(labelled, 32 * 128 * 128 - 13);
    assert!(stats.iter().all(|i| i.touches_border(v.shape()) && v.touches_border(i.label)));
    // Masks of every label hold exactly its voxels.
    for info in &stats {
        let m = v.mask_of(info, 1);
        assert_eq!(m.count() as u64, info.voxels);
    }
}

#[test]
#[ignore = "needs ../shared/data/real (not committed)"]
fn reads_the_derived_cshaper_labels_and_our_voxelisation_of_its_mesh_matches_them() {
    let read =
        read_label_tiff(&real("DERIVED_cshaper_4cells_labels_from_mesh.tif"), &LabelReadOptions::default()).unwrap();
    let v = &read.volume;
    assert_eq!(v.shape(), [205, 285, 134]);
    assert_eq!(read.bits, 8);
    let stats = v.label_stats();
    assert_eq!(stats.iter().map(|i| i.label).collect::<Vec<_>>(), vec![1, 2, 3, 4]);
    // The source mesh, in voxel units; its point (i, j, k) is voxel [i, j, k], so mesh x runs along
    // the first array axis: swap x and z to put it in our (x, y, z) ↔ [z, y, x] convention.
    let mut tissue =
        read_tissue(&real("foambryo-runner__Cshaper_4_cells_min-d-3.vtk"), &ReadOptions::default()).unwrap().tissue;
    for cell in tissue.cells_mut() {
        for p in cell.positions_mut() {
            *p = Vec3::new(p.z, p.y, p.x);
        }
    }
    let grid = VoxelGrid::new(v.shape(), [1.0; 3], Vec3::zeros()).unwrap();
    let (ours, vstats) = voxelize_with_stats(&tissue, &grid).unwrap();
    assert_eq!(vstats.odd_rows, 0);
    for info in &stats {
        let (mut both, mut either) = (0u64, 0u64);
        ndarray::Zip::from(v.labels()).and(ours.labels()).for_each(|&a, &b| {
            let (a, b) = (a == info.label, b == info.label);
            both += (a && b) as u64;
            either += (a || b) as u64;
        });
        let iou = both as Real / either as Real;
        assert!(iou > 0.99, "label {}: IoU {iou}", info.label);
    }
}

fn ok(out: &Output) -> String {
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

#[test]
fn generate_labels_writes_a_seeded_aggregate_with_its_lumen() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a.tif");
    let b = dir.path().join("b.tif");
    let args = |out: &Path, seed: &str| {
        tissuefit(&[
            "generate",
            "labels",
            "--kind",
            "aggregate",
            "--cells",
            "12",
            "--lumen",
            "--shape",
            "30,40,40",
            "--voxel-size",
            "0.5um,250nm,2.5e-7",
            "--seed",
            seed,
            "--out",
            out.to_str().unwrap(),
        ])
    };
    let stdout = ok(&args(&a, "4"));
    assert!(stdout.contains("a.tif") && stdout.contains("12 cells") && stdout.contains("lumen label 13"), "{stdout}");
    ok(&args(&b, "4"));
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap(), "same seed, same file");
    let read = read_label_tiff(&a, &LabelReadOptions::default()).unwrap();
    assert_eq!(read.volume.shape(), [30, 40, 40]);
    assert_eq!(read.volume.label_stats().len(), 13);
    for (got, want) in read.volume.voxel_size().iter().zip([0.5e-6, 0.25e-6, 0.25e-6]) {
        assert!(rel_close(*got, want, 1e-9));
    }
    ok(&args(&b, "5"));
    assert_ne!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap(), "another seed, another packing");

    // Errors: exit 2 with the reason, and no output file.
    let c = dir.path().join("c.tif");
    let out = tissuefit(&["generate", "labels", "--kind", "blob", "--out", c.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("aggregate"));
    let out = tissuefit(&[
        "generate",
        "labels",
        "--kind",
        "aggregate",
        "--cells",
        "500",
        "--shape",
        "5",
        "--out",
        c.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("too coarse"), "{}", String::from_utf8_lossy(&out.stderr));
    let out = tissuefit(&[
        "generate",
        "labels",
        "--kind",
        "sphere",
        "--voxel-size",
        "1 furlong",
        "--out",
        c.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("furlong"));
    assert!(!c.exists());
}

#[test]
fn generate_noise_perturbs_boundaries_on_the_same_grid_and_refuses_bad_amplitudes() {
    let dir = tempfile::tempdir().unwrap();
    let clean = dir.path().join("clean.tif");
    let (noisy, again) = (dir.path().join("noisy.tif"), dir.path().join("again.tif"));
    let s = |p: &Path| p.to_str().unwrap().to_string();
    ok(&tissuefit(&[
        "generate",
        "labels",
        "--kind",
        "aggregate",
        "--cells",
        "6",
        "--shape",
        "40",
        "--out",
        &s(&clean),
    ]));
    let noise = |out: &Path, amplitude: &str| {
        tissuefit(&["generate", "noise", &s(&clean), "--amplitude", amplitude, "--seed", "2", "--out", &s(out)])
    };
    let stdout = ok(&noise(&noisy, "1"));
    assert!(stdout.contains("noisy.tif") && stdout.contains("changed label"), "{stdout}");
    ok(&noise(&again, "1"));
    assert_eq!(std::fs::read(&noisy).unwrap(), std::fs::read(&again).unwrap(), "same seed, same file");
    let (a, b) = (
        read_label_tiff(&clean, &LabelReadOptions::default()).unwrap().volume,
        read_label_tiff(&noisy, &LabelReadOptions::default()).unwrap().volume,
    );
    assert_eq!((a.shape(), a.voxel_size()), (b.shape(), b.voxel_size()));
    let changed = a.labels().iter().zip(b.labels()).filter(|(x, y)| x != y).count();
    assert!(changed > 100 && changed < a.labels().len() / 5, "{changed} voxels changed");
    let bad = dir.path().join("bad.tif");
    let out = noise(&bad, "50");
    assert_ne!(out.status.code(), Some(0));
    assert!(String::from_utf8_lossy(&out.stderr).contains("amplitude"), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(!bad.exists());
}

#[test]
fn voxelize_command_matches_mesh_volumes_and_reproduces_a_grid_with_like() {
    let dir = tempfile::tempdir().unwrap();
    let demo = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/demo/cell_quartet.vtk");
    let demo = demo.to_str().unwrap();
    let first = dir.path().join("first.tif");
    let stdout = ok(&tissuefit(&["voxelize", demo, "--voxel-size", "0.2um", "--out", first.to_str().unwrap()]));
    assert!(stdout.contains("first.tif") && stdout.contains("4 cells"), "{stdout}");
    let read = read_label_tiff(&first, &LabelReadOptions::default()).unwrap();
    let stats = read.volume.label_stats();
    assert_eq!(stats.len(), 4);
    let tissue = read_tissue(&PathBuf::from(demo), &ReadOptions::default()).unwrap().tissue;
    for (info, cell) in stats.iter().zip(tissue.cells()) {
        assert_eq!(info.label, cell.id().0);
        assert!(!info.touches_border(read.volume.shape()), "the automatic grid has a margin");
        // ~4.4e-16 m³ cells on a 0.2 µm grid (~55,000 voxels each): within 0.5 %.
        let v = info.voxels as Real * read.volume.voxel_volume();
        assert!(rel_close(v, cell.mesh().signed_volume(), 0.005), "{v}");
    }
    // The same grid again through --like (origin included), on 1 thread: the same file.
    let again = dir.path().join("again.tif");
    ok(&tissuefit(&[
        "voxelize",
        demo,
        "--like",
        first.to_str().unwrap(),
        "--out",
        again.to_str().unwrap(),
        "--threads",
        "1",
    ]));
    assert_eq!(std::fs::read(&first).unwrap(), std::fs::read(&again).unwrap());
    // An explicit shape centred on the tissue, anisotropic voxels.
    let shaped = dir.path().join("shaped.tif");
    ok(&tissuefit(&[
        "voxelize",
        demo,
        "--voxel-size",
        "0.4,0.2,0.2um",
        "--shape",
        "50,100,100",
        "--out",
        shaped.to_str().unwrap(),
        "--compress",
        "deflate",
    ]));
    let read = read_label_tiff(&shaped, &LabelReadOptions::default()).unwrap();
    assert_eq!(read.volume.shape(), [50, 100, 100]);
    assert_eq!(read.compression, 8);
    assert_eq!(read.volume.label_stats().len(), 4);
    // No grid given: a clear error.
    let out = tissuefit(&["voxelize", demo, "--out", dir.path().join("none.tif").to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--voxel-size"));
}

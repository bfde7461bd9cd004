//! Byte-mutation fuzzing of every parser that reads user files: label TIFFs, legacy VTK (SimuCell3D
//! and multi-material), ParaView `.vtp`, and parameter configs (TOML).
//!
//! Each target starts from valid files made in the test, applies random mutations (bit flips, byte
//! overwrites, truncation, spliced-in numbers such as `nan`, `-1` or `99999999999`, duplicated and
//! deleted chunks) and calls the reader. The reader must return `Ok` or a clear error; a panic, or an
//! error that names neither the file nor the problem, fails the test. proptest shrinks a failure to a
//! small input and records it in `proptest-regressions/fuzz_inputs.txt`, which is committed: that is
//! the corpus, replayed first on every run.
//!
//! CI runs 128 cases per target; a longer fuzzing session is the same test with more cases:
//! `TISSUEFIT_FUZZ_CASES=20000 cargo test --release --test integration fuzz_inputs::`.

use proptest::prelude::*;
use std::path::Path;
use std::sync::OnceLock;
use tissuefit::geometry::Vec3;
use tissuefit::imaging::{LabelReadOptions, LabelVolume, LabelWriteOptions, TiffCompression, write_label_tiff};
use tissuefit::io::{ReadOptions, read_tissue, write_tissue};
use tissuefit::mechanics::Parameters;
use tissuefit::mesh::shapes::icosphere;
use tissuefit::mesh::{Cell, CellId, CellKind, Tissue};

fn cases() -> u32 {
    std::env::var("TISSUEFIT_FUZZ_CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(128)
}

/// One edit of a byte string; positions are fractions of the current length.
#[derive(Clone, Debug)]
enum Mutation {
    FlipBit {
        at: f64,
        bit: u8,
    },
    SetByte {
        at: f64,
        value: u8,
    },
    Truncate {
        at: f64,
    },
    Splice {
        at: f64,
        text: &'static str,
    },
    Duplicate {
        at: f64,
        len: usize,
    },
    Delete {
        at: f64,
        len: usize,
    },
    /// Overwrite 4 or 8 bytes with a little-endian integer (huge sizes and offsets in binary headers).
    Word {
        at: f64,
        value: u64,
        wide: bool,
    },
    /// Replace one number token of a text file (counts, indices, coordinates, parameter values).
    Number {
        at: f64,
        text: &'static str,
    },
}

const SPLICES: &[&str] = &[
    "nan",
    "-nan",
    "inf",
    "-1",
    "0",
    "99999999999",
    "4294967295",
    "1e308",
    "-1e308",
    " ",
    "\n",
    "#",
    "=",
    "\"",
    "[",
    "]",
    "{",
    "<",
    ">",
    "</DataArray>",
    "POINTS",
    "CELLS",
    "42",
    "3",
    "é",
    "\0",
];

const NUMBERS: &[&str] = &[
    "nan",
    "inf",
    "-inf",
    "-1",
    "0",
    "1",
    "2",
    "99999999999",
    "18446744073709551615",
    "4294967296",
    "1e308",
    "1e-320",
    "-0",
    "0.5",
    "3.0e",
    "",
];

fn mutation() -> impl Strategy<Value = Mutation> {
    let at = 0.0..1.0f64;
    let at_number = at.clone();
    prop_oneof![
        (at.clone(), 0u8..8).prop_map(|(at, bit)| Mutation::FlipBit { at, bit }),
        (at.clone(), any::<u8>()).prop_map(|(at, value)| Mutation::SetByte { at, value }),
        at.clone().prop_map(|at| Mutation::Truncate { at }),
        (at.clone(), prop::sample::select(SPLICES)).prop_map(|(at, text)| Mutation::Splice { at, text }),
        (at.clone(), 1usize..256).prop_map(|(at, len)| Mutation::Duplicate { at, len }),
        (at.clone(), 1usize..256).prop_map(|(at, len)| Mutation::Delete { at, len }),
        (
            at,
            prop_oneof![Just(0u64), Just(u32::MAX as u64), Just(u64::MAX), Just(1 << 31), any::<u64>()],
            any::<bool>()
        )
            .prop_map(|(at, value, wide)| Mutation::Word { at, value, wide }),
        (at_number, prop::sample::select(NUMBERS)).prop_map(|(at, text)| Mutation::Number { at, text }),
    ]
}

fn apply(bytes: &mut Vec<u8>, m: &Mutation) {
    let pos = |at: f64, len: usize| ((at * len as f64) as usize).min(len);
    match *m {
        Mutation::FlipBit { at, bit } if !bytes.is_empty() => {
            let i = pos(at, bytes.len() - 1);
            bytes[i] ^= 1 << bit;
        }
        Mutation::SetByte { at, value } if !bytes.is_empty() => {
            let i = pos(at, bytes.len() - 1);
            bytes[i] = value;
        }
        Mutation::Truncate { at } => bytes.truncate(pos(at, bytes.len())),
        Mutation::Splice { at, text } => {
            let i = pos(at, bytes.len());
            bytes.splice(i..i, text.bytes());
        }
        Mutation::Duplicate { at, len } => {
            let i = pos(at, bytes.len());
            let chunk: Vec<u8> = bytes[i..(i + len).min(bytes.len())].to_vec();
            bytes.splice(i..i, chunk);
        }
        Mutation::Delete { at, len } => {
            let i = pos(at, bytes.len());
            bytes.drain(i..(i + len).min(bytes.len()));
        }
        Mutation::Word { at, value, wide } => {
            let width = if wide { 8 } else { 4 };
            if bytes.len() >= width {
                let i = pos(at, bytes.len() - width);
                bytes[i..i + width].copy_from_slice(&value.to_le_bytes()[..width]);
            }
        }
        Mutation::Number { at, text } => {
            let tokens = number_tokens(bytes);
            if !tokens.is_empty() {
                let (start, end) = tokens[pos(at, tokens.len() - 1)];
                bytes.splice(start..end, text.bytes());
            }
        }
        _ => {}
    }
}

/// Byte ranges of the maximal runs of digits, signs, dots and exponents that contain a digit.
fn number_tokens(bytes: &[u8]) -> Vec<(usize, usize)> {
    let numeric = |b: u8| b.is_ascii_digit() || b"+-.eE".contains(&b);
    let mut tokens = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        if numeric(bytes[i]) {
            let start = i;
            while i < bytes.len() && numeric(bytes[i]) {
                i += 1;
            }
            if bytes[start..i].iter().any(u8::is_ascii_digit) {
                tokens.push((start, i));
            }
        } else {
            i += 1;
        }
    }
    tokens
}

fn mutated(base: &[u8], mutations: &[Mutation]) -> Vec<u8> {
    let mut bytes = base.to_vec();
    for m in mutations {
        apply(&mut bytes, m);
    }
    bytes
}

/// An error message is useful when it names the file it is about.
fn names_file(message: &str, path: &Path) -> bool {
    message.contains(path.file_name().unwrap().to_str().unwrap())
}

// ---------------------------------------------------------------------------------------------
// Seeds

/// Small label volumes written in every layout the reader decodes.
fn tiff_seeds() -> &'static [Vec<u8>] {
    static SEEDS: OnceLock<Vec<Vec<u8>>> = OnceLock::new();
    SEEDS.get_or_init(make_tiff_seeds)
}

fn make_tiff_seeds() -> Vec<Vec<u8>> {
    let dir = tempfile::tempdir().unwrap();
    let mut labels = ndarray::Array3::<u32>::zeros((4, 5, 6));
    for ((z, y, x), v) in labels.indexed_iter_mut() {
        *v = ((x / 2 + 3 * (y / 3) + z) % 5) as u32;
    }
    let big = labels.mapv(|v| v * 70_000);
    let mut seeds = Vec::new();
    for (k, (labels, compression, bigtiff)) in [
        (&labels, TiffCompression::None, false),
        (&labels, TiffCompression::Lzw, false),
        (&labels, TiffCompression::Deflate, true),
        (&big, TiffCompression::None, true),
    ]
    .into_iter()
    .enumerate()
    {
        let volume = LabelVolume::new(labels.clone(), [0.5e-6, 0.25e-6, 0.25e-6], Vec3::zeros()).unwrap();
        let path = dir.path().join(format!("seed{k}.tif"));
        write_label_tiff(&path, &volume, &LabelWriteOptions { dtype: None, compression, bigtiff }).unwrap();
        seeds.push(std::fs::read(&path).unwrap());
    }
    seeds
}

fn two_cell_tissue() -> Tissue {
    let a = Cell::new(CellId(1), CellKind::Epithelial, 0, icosphere(1e-6, 1, Vec3::zeros()));
    let b = Cell::new(CellId(2), CellKind::Static, 1, icosphere(1e-6, 1, Vec3::new(2.1e-6, 0.0, 0.0)));
    Tissue::from_cells(vec![a, b]).unwrap()
}

/// The same tissue as `.vtk` (SimuCell3D legacy) and `.vtp`, plus a hand-written multi-material mesh
/// and three PLY files (a topomesh sheet, multi-material tetrahedra, a binary sheet).
fn tissue_seeds() -> &'static [(&'static str, Vec<u8>)] {
    static SEEDS: OnceLock<Vec<(&'static str, Vec<u8>)>> = OnceLock::new();
    SEEDS.get_or_init(make_tissue_seeds)
}

fn make_tissue_seeds() -> Vec<(&'static str, Vec<u8>)> {
    let dir = tempfile::tempdir().unwrap();
    let tissue = two_cell_tissue();
    let mut seeds = Vec::new();
    for ext in ["vtk", "vtp"] {
        let path = dir.path().join(format!("seed.{ext}"));
        write_tissue(&path, &tissue, &[]).unwrap();
        seeds.push((ext, std::fs::read(&path).unwrap()));
    }
    // Two tetrahedra sharing a face, as triangles labelled (inside, outside) in a VTK 5.1 file.
    let multimaterial = "# vtk DataFile Version 5.1\nlabels\nASCII\nDATASET POLYDATA\nPOINTS 5 float\n\
        0 0 0 1 0 0 0 1 0 0 0 1 1 1 1\nPOLYGONS 8 21\nOFFSETS vtktypeint64\n0 3 6 9 12 15 18 21\n\
        CONNECTIVITY vtktypeint64\n0 2 1 0 1 3 0 3 2 1 2 3 1 4 2 2 4 3 3 4 1\n\
        CELL_DATA 7\nFIELD FieldData 2\nlabel1 1 7 int\n1 1 1 1 2 2 2\nlabel2 1 7 int\n0 0 0 2 0 0 0\n";
    seeds.push(("vtk", multimaterial.as_bytes().to_vec()));
    // PLY: a 2.5-D sheet as a cellcomplex topomesh (faces listed by `volume` records), the
    // multi-material tetrahedra with label1/label2 per face, and the sheet in binary.
    let topomesh = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
        element face 2\nproperty list uchar int vertex_indices\nelement volume 2\nproperty list int int face_index\n\
        property int label\nend_header\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n3 1 3 2\n1 0 7\n1 1 9\n";
    seeds.push(("ply", topomesh.as_bytes().to_vec()));
    let tetrahedra = "ply\nformat ascii 1.0\nelement vertex 5\nproperty double x\nproperty double y\nproperty double z\n\
        element face 7\nproperty list uchar int vertex_indices\nproperty int label1\nproperty int label2\nend_header\n\
        0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 1 1\n3 0 2 1 1 0\n3 0 1 3 1 0\n3 0 3 2 1 0\n3 1 2 3 1 2\n3 1 4 2 2 0\n\
        3 2 4 3 2 0\n3 3 4 1 2 0\n";
    seeds.push(("ply", tetrahedra.as_bytes().to_vec()));
    let mut binary = b"ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
        property float z\nelement face 2\nproperty list uchar int vertex_indices\nproperty int label\nend_header\n"
        .to_vec();
    for p in [[0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]] {
        p.iter().for_each(|v| binary.extend(v.to_le_bytes()));
    }
    for (f, label) in [([0i32, 1, 2], 7i32), ([1, 3, 2], 9)] {
        binary.push(3);
        f.iter().for_each(|v| binary.extend(v.to_le_bytes()));
        binary.extend(label.to_le_bytes());
    }
    seeds.push(("ply", binary));
    seeds
}

/// Every seed is a file its reader accepts, so mutations start inside the parser rather than at its
/// first check (the multi-material seed lacked its label1/label2 arrays and was refused whole).
#[test]
fn seeds_are_valid_files() {
    let dir = tempfile::tempdir().unwrap();
    for (k, (ext, bytes)) in tissue_seeds().iter().enumerate() {
        let path = dir.path().join(format!("seed{k}.{ext}"));
        std::fs::write(&path, bytes).unwrap();
        read_tissue(&path, &ReadOptions::default()).unwrap_or_else(|e| panic!("tissue seed {k}: {e}"));
    }
    for (k, bytes) in tiff_seeds().iter().enumerate() {
        let path = dir.path().join(format!("seed{k}.tif"));
        std::fs::write(&path, bytes).unwrap();
        tissuefit::imaging::read_label_tiff(&path, &LabelReadOptions::default())
            .unwrap_or_else(|e| panic!("TIFF seed {k}: {e}"));
    }
    Parameters::from_toml_str(&config_seed(), "seed.toml").unwrap();
}

fn config_seed() -> String {
    Parameters::default_toml_commented()
}

// ---------------------------------------------------------------------------------------------
// Targets

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), ..ProptestConfig::default() })]

    #[test]
    fn label_tiff_reader_never_panics(seed in 0usize..4, mutations in prop::collection::vec(mutation(), 1..6)) {
        let bytes = mutated(&tiff_seeds()[seed], &mutations);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("fuzzed.tif");
        std::fs::write(&path, &bytes).unwrap();
        if let Err(e) = tissuefit::imaging::read_label_tiff(&path, &LabelReadOptions::default()) {
            let message = e.to_string();
            prop_assert!(names_file(&message, &path), "error does not name the file: {message}");
        }
    }

    #[test]
    fn tissue_readers_never_panic(seed in 0usize..6, mutations in prop::collection::vec(mutation(), 1..6)) {
        let (ext, base) = &tissue_seeds()[seed];
        let bytes = mutated(base, &mutations);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(format!("fuzzed.{ext}"));
        std::fs::write(&path, &bytes).unwrap();
        match read_tissue(&path, &ReadOptions::default()) {
            Ok(report) => {
                // Whatever was read is finite; defects in the surfaces are reported, not fatal.
                for cell in report.tissue.cells() {
                    prop_assert!(cell.mesh().positions().iter().all(|p| p.iter().all(|v| v.is_finite())));
                    let _ = cell.mesh().validate();
                }
            }
            Err(e) => {
                let message = e.to_string();
                prop_assert!(names_file(&message, &path), "error does not name the file: {message}");
            }
        }
    }

    #[test]
    fn config_parser_never_panics(mutations in prop::collection::vec(mutation(), 1..6)) {
        let bytes = mutated(config_seed().as_bytes(), &mutations);
        let text = String::from_utf8_lossy(&bytes);
        match Parameters::from_toml_str(&text, "fuzzed.toml") {
            Ok(params) => {
                // What parses is validated: no NaN or negative moduli reach a simulation.
                prop_assert!(params.numerics.time_step.is_finite() && params.numerics.time_step > 0.0);
                prop_assert!(params.numerics.min_edge_length.is_finite() && params.numerics.min_edge_length > 0.0);
            }
            Err(e) => {
                let message = e.to_string();
                prop_assert!(message.contains("fuzzed.toml"), "error does not name the file: {message}");
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Regressions: each crash the fuzzer found, as a plain test.

fn read_error(name: &str, text: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, text).unwrap();
    let message = read_tissue(&path, &ReadOptions::default()).expect_err("must be an error").to_string();
    assert!(names_file(&message, &path), "{message}");
    message
}

/// Found by `tissue_readers_never_panic`: a CELLS line declaring 4·10¹² cells made the reader
/// reserve 64 TB before reading a single record (an abort, not even a panic).
#[test]
fn huge_declared_cell_count_is_an_error_not_an_allocation() {
    let text = "# vtk DataFile Version 4.2\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 float\n\
        0 0 0 1 0 0 0 1 0 0 0 1\nCELLS 3999999999999 17\n17 4 3 0 2 1 3 0 1 3 3 0 3 2 3 1 2 3\n";
    let message = read_error("huge.vtk", text);
    assert!(message.contains("cell"), "{message}");
}

/// Found by `tissue_readers_never_panic`: a polyhedron announcing 4·10⁹ faces reserved 64 GB.
#[test]
fn huge_polyhedron_face_count_is_an_error_not_an_allocation() {
    let text = "# vtk DataFile Version 4.2\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 float\n\
        0 0 0 1 0 0 0 1 0 0 0 1\nCELLS 1 17\n17 4294967295 3 0 2 1 3 0 1 3 3 0 3 2 3 1 2 3\nCELL_TYPES 1\n42\n";
    let message = read_error("faces.vtk", text);
    assert!(message.contains("face"), "{message}");
}

/// Found by `tissue_readers_never_panic`: `FIELD FieldData 99999999999` reserved 6.4 TB of arrays.
#[test]
fn huge_field_array_count_is_an_error_not_an_allocation() {
    let text = "# vtk DataFile Version 4.2\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 float\n\
        0 0 0 1 0 0 0 1 0 0 0 1\nCELLS 1 18\n17 4 3 0 2 1 3 0 1 3 3 0 3 2 3 1 2 3\nCELL_TYPES 1\n42\n\
        CELL_DATA 1\nFIELD FieldData 99999999999\ncell_type_id 1 1 int\n0\n";
    read_error("field.vtk", text);
}

/// A declared array size whose element count overflows is an error (it wrapped around before).
#[test]
fn overflowing_array_size_is_an_error() {
    let text = "# vtk DataFile Version 4.2\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 float\n\
        0 0 0 1 0 0 0 1 0 0 0 1\nCELLS 1 18\n17 4 3 0 2 1 3 0 1 3 3 0 3 2 3 1 2 3\nCELL_TYPES 1\n42\n\
        POINT_DATA 4\nSCALARS s int 4611686018427387904\nLOOKUP_TABLE default\n1 2 3 4\n";
    let message = read_error("overflow.vtk", text);
    assert!(message.contains("array s declares"), "{message}");
}

//! Reading label volumes from NumPy `.npy` files (format versions 1.0, 2.0 and 3.0): a 3-D array
//! indexed `[z, y, x]` of 8/16/32/64-bit integers (or booleans), either byte order, C or Fortran
//! order. A `.npy` holds no voxel size: it comes from the caller ([`LabelReadOptions::voxel_size`],
//! `--voxel-size`), else the fallback is assumed with a warning, as for a TIFF without metadata.
//!
//! The header is parsed by hand (the format is a magic string, a version, a length and a Python dict
//! literal). The declared size is checked against the file size and the memory limit before the
//! data is read, and the data is converted in blocks, so the only large allocation is the volume.

use super::labels::{LabelFormat, resolve_voxel_size};
use super::limits::check_voxel_memory;
use super::{ImagingError, LabelRead, LabelReadOptions, LabelVolume};
use crate::geometry::Vec3;
use ndarray::Array3;
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::Path;

/// The header of a `.npy` file: element type, order and shape, and where the data starts.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct NpyHeader {
    /// Bytes per element (1, 2, 4 or 8).
    pub item_size: usize,
    pub signed: bool,
    pub big_endian: bool,
    pub fortran_order: bool,
    pub shape: Vec<u64>,
    /// Offset of the first data byte.
    pub data_offset: u64,
}

/// Reads a 3-D integer `.npy` label array; see the module documentation.
pub fn read_label_npy(path: &Path, options: &LabelReadOptions) -> Result<LabelRead, ImagingError> {
    let bad = |message: String| ImagingError::Npy { path: path.to_path_buf(), message };
    let file = File::open(path).map_err(|source| ImagingError::Open { path: path.to_path_buf(), source })?;
    let file_size = file.metadata().map_err(|source| ImagingError::Open { path: path.to_path_buf(), source })?.len();
    let mut reader = BufReader::with_capacity(1 << 16, file);
    let header = read_header(&mut reader, path)?;
    let [nz, ny, nx] = match header.shape.as_slice() {
        [z, y, x] => [*z, *y, *x],
        other => {
            return Err(bad(format!(
                "the array has {} dimensions ({other:?}); a label volume is a 3-D array indexed [z, y, x]",
                other.len()
            )));
        }
    };
    if nz == 0 || ny == 0 || nx == 0 {
        return Err(bad(format!("the array is empty (shape ({nz}, {ny}, {nx}))")));
    }
    let voxels = nz.checked_mul(ny).and_then(|n| n.checked_mul(nx));
    let data_bytes = voxels.and_then(|n| n.checked_mul(header.item_size as u64));
    let available = file_size.saturating_sub(header.data_offset);
    match data_bytes {
        Some(b) if b <= available => {}
        _ => {
            return Err(bad(format!(
                "the header declares shape ({nz}, {ny}, {nx}) of {}-byte elements ({} bytes), but the file holds \
                 only {available} data bytes (truncated?)",
                header.item_size,
                data_bytes.map_or_else(|| "more than 2^64".to_string(), |b| b.to_string()),
            )));
        }
    }
    check_voxel_memory(
        voxels,
        4u64.saturating_add(options.work_bytes_per_voxel),
        &format!("{}: an array of {nz} × {ny} × {nx} voxels", path.display()),
        "crop or bin the volume",
    )?;
    let (nz, ny, nx) = (nz as usize, ny as usize, nx as usize);
    let n = nz * ny * nx;
    let mut data = vec![0u32; n];
    let item = header.item_size;
    let mut block = vec![0u8; (1 << 16) / item * item];
    let mut done = 0usize;
    while done < n {
        let count = (block.len() / item).min(n - done);
        let bytes = &mut block[..count * item];
        reader.read_exact(bytes).map_err(|e| bad(format!("reading the data: {e} (truncated?)")))?;
        for (k, raw) in bytes.chunks_exact(item).enumerate() {
            let flat = done + k;
            // C order: the last index varies fastest; Fortran order: the first.
            let zyx = |flat: usize| {
                if header.fortran_order {
                    [flat % nz, (flat / nz) % ny, flat / (nz * ny)]
                } else {
                    [flat / (ny * nx), (flat / nx) % ny, flat % nx]
                }
            };
            let value = decode(raw, header.signed, header.big_endian);
            if value < 0 {
                return Err(ImagingError::NegativeLabel {
                    path: path.to_path_buf(),
                    index: zyx(flat),
                    value: value as i64,
                });
            }
            if value > u32::MAX as i128 {
                return Err(ImagingError::LabelTooLarge {
                    path: path.to_path_buf(),
                    index: zyx(flat),
                    value: value as u64,
                });
            }
            let at = if header.fortran_order {
                let [z, y, x] = zyx(flat);
                (z * ny + y) * nx + x
            } else {
                flat
            };
            data[at] = value as u32;
        }
        done += count;
    }
    let labels = Array3::from_shape_vec((nz, ny, nx), data).map_err(|e| bad(e.to_string()))?;
    let mut warnings = Vec::new();
    let (voxel_size, voxel_size_source) =
        resolve_voxel_size([None; 3], options, &mut warnings, path, "(a .npy file stores none)");
    let volume = LabelVolume::new(labels, voxel_size, options.origin.unwrap_or(Vec3::zeros()))
        .map_err(|e| ImagingError::Unsupported { path: path.to_path_buf(), message: e.to_string() })?;
    Ok(LabelRead {
        volume,
        format: LabelFormat::Npy,
        voxel_size_source,
        bits: (item * 8) as u16,
        signed: header.signed,
        compression: 0,
        warnings,
    })
}

/// One element's value.
fn decode(raw: &[u8], signed: bool, big_endian: bool) -> i128 {
    let mut b = [0u8; 8];
    let n = raw.len();
    if big_endian {
        b[..n].copy_from_slice(raw);
        b[..n].reverse();
    } else {
        b[..n].copy_from_slice(raw);
    }
    let unsigned = u64::from_le_bytes(b);
    if signed && n < 8 && (unsigned >> (8 * n - 1)) & 1 == 1 {
        unsigned as i128 - (1i128 << (8 * n))
    } else if signed {
        unsigned as i64 as i128
    } else {
        unsigned as i128
    }
}

/// Reads and parses the magic string, version, header length and header dict.
fn read_header(reader: &mut impl Read, path: &Path) -> Result<NpyHeader, ImagingError> {
    let bad = |message: String| ImagingError::Npy { path: path.to_path_buf(), message };
    let mut preamble = [0u8; 8];
    reader.read_exact(&mut preamble).map_err(|e| bad(format!("reading the header: {e} (truncated?)")))?;
    if &preamble[..6] != b"\x93NUMPY" {
        return Err(bad("it does not start with the .npy magic string \\x93NUMPY".into()));
    }
    let (major, minor) = (preamble[6], preamble[7]);
    let (len_bytes, prefix) = match major {
        1 => (2usize, 10u64),
        2 | 3 => (4, 12),
        _ => return Err(bad(format!("format version {major}.{minor} is not one of 1.0, 2.0, 3.0"))),
    };
    let mut len = [0u8; 4];
    reader
        .read_exact(&mut len[..len_bytes])
        .map_err(|e| bad(format!("reading the header length: {e} (truncated?)")))?;
    let header_len = u32::from_le_bytes(len) as u64;
    // NumPy pads headers to 64 bytes; anything near this size is not a header.
    if header_len > 1 << 20 {
        return Err(bad(format!("the header claims {header_len} bytes (corrupt?)")));
    }
    let mut text = vec![0u8; header_len as usize];
    reader.read_exact(&mut text).map_err(|e| bad(format!("reading the {header_len}-byte header: {e} (truncated?)")))?;
    let text = String::from_utf8(text).map_err(|_| bad("the header is not text".into()))?;
    if descr_of(&text).is_ok_and(|d| d.trim_start_matches(['<', '>', '|', '=']) == "O") {
        return Err(bad(object_array_hint(path)));
    }
    let mut header = parse_header_dict(&text).map_err(|m| bad(format!("header `{}`: {m}", text.trim())))?;
    header.data_offset = prefix + header_len;
    Ok(header)
}

/// What to say about a `.npy` holding pickled Python objects (dtype `|O`): most likely Cellpose's
/// `_seg.npy`, a pickled dict whose `masks` entry is the label array; the one-line conversion names
/// the file as given.
fn object_array_hint(path: &Path) -> String {
    let given = path.display().to_string();
    let masks = match given.strip_suffix("_seg.npy") {
        Some(stem) => format!("{stem}_masks.npy"),
        None => format!("{}_masks.npy", given.strip_suffix(".npy").unwrap_or(&given)),
    };
    format!(
        "it holds pickled Python objects (dtype `|O`), not a label array: this is how Cellpose saves its `_seg.npy` \
         (a dict of masks, outlines, flows, …), which tissuefit does not unpickle. Save the masks as a label array \
         with\n  python -c \"import numpy as np; d=np.load('{given}', allow_pickle=True).item(); \
         np.save('{masks}', d['masks'])\"\nand give {masks}, or run Cellpose with --save_tif and give its \
         _cp_masks.tif"
    )
}

/// The value of `key` in the header dict text.
fn value_after<'a>(text: &'a str, key: &str) -> Result<&'a str, String> {
    let quoted = [format!("'{key}'"), format!("\"{key}\"")];
    let at = quoted.iter().find_map(|q| text.find(q.as_str()).map(|i| i + q.len())).ok_or(format!("no `{key}`"))?;
    let rest = text[at..].trim_start();
    rest.strip_prefix(':').map(str::trim_start).ok_or(format!("no `:` after `{key}`"))
}

/// The `descr` string of the header dict (`<u2`, `|O`).
fn descr_of(text: &str) -> Result<&str, String> {
    let descr = value_after(text, "descr")?;
    let quote = descr.chars().next().filter(|c| *c == '\'' || *c == '"').ok_or("`descr` is not a string")?;
    Ok(&descr[1..descr[1..].find(quote).ok_or("`descr` is not a closed string")? + 1])
}

/// Parses `{'descr': '<u2', 'fortran_order': False, 'shape': (3, 4, 5), }`.
pub(crate) fn parse_header_dict(text: &str) -> Result<NpyHeader, String> {
    let value_after = |key: &str| value_after(text, key);
    let descr = descr_of(text)?;
    let (order, kind) = match descr.chars().next() {
        Some(c @ ('<' | '>' | '|' | '=')) => (c, &descr[1..]),
        _ => ('|', descr),
    };
    let big_endian = order == '>' || (order == '=' && cfg!(target_endian = "big"));
    let (signed, item_size) = match kind {
        "u1" | "b1" => (false, 1),
        "u2" => (false, 2),
        "u4" => (false, 4),
        "u8" => (false, 8),
        "i1" => (true, 1),
        "i2" => (true, 2),
        "i4" => (true, 4),
        "i8" => (true, 8),
        k if k.starts_with('f') => {
            return Err(format!(
                "dtype `{descr}` is floating point; a label volume needs integer labels (in NumPy: \
                 a.astype(np.uint32), after checking the values are whole)"
            ));
        }
        _ => {
            return Err(format!(
                "dtype `{descr}` is not a label type; give 8, 16, 32 or 64-bit integers (u1..u8, i1..i8) or booleans"
            ));
        }
    };
    let fortran = value_after("fortran_order")?;
    let fortran_order = if fortran.starts_with("True") {
        true
    } else if fortran.starts_with("False") {
        false
    } else {
        return Err("`fortran_order` is neither True nor False".into());
    };
    let shape = value_after("shape")?;
    let shape = shape.strip_prefix('(').ok_or("`shape` is not a tuple")?;
    let shape = &shape[..shape.find(')').ok_or("`shape` is not a closed tuple")?];
    let shape = shape
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.trim_end_matches('L').parse::<u64>().map_err(|_| format!("`shape` entry `{s}` is not a size")))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(NpyHeader { item_size, signed, big_endian, fortran_order, shape, data_offset: 0 })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn headers_parse() {
        let h = parse_header_dict("{'descr': '<u2', 'fortran_order': False, 'shape': (3, 4, 5), }").unwrap();
        assert_eq!((h.item_size, h.signed, h.big_endian, h.fortran_order), (2, false, false, false));
        assert_eq!(h.shape, vec![3, 4, 5]);
        let h = parse_header_dict("{'descr': '>i8', 'fortran_order': True, 'shape': (7,), }").unwrap();
        assert_eq!((h.item_size, h.signed, h.big_endian, h.fortran_order), (8, true, true, true));
        assert_eq!(h.shape, vec![7]);
        let e = parse_header_dict("{'descr': '<f4', 'fortran_order': False, 'shape': (3, 4, 5), }").unwrap_err();
        assert!(e.contains("floating point") && e.contains("astype"), "{e}");
        assert!(parse_header_dict("{'descr': '<u2', 'shape': (3, 4, 5), }").unwrap_err().contains("fortran_order"));
    }

    /// Cellpose's `_seg.npy` is a pickled dict: a 0-d object array. The error says what the file is
    /// and gives the conversion with the file's own name.
    #[test]
    fn a_cellpose_seg_file_is_named_with_the_one_line_fix() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("embryo_seg.npy");
        let dict = "{'descr': '|O', 'fortran_order': False, 'shape': (), }";
        let mut header = format!("{dict:<117}\n").into_bytes();
        assert_eq!((10 + header.len()) % 64, 0);
        let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
        bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
        bytes.append(&mut header);
        bytes.extend_from_slice(b"\x80\x04\x95pickled dict follows");
        std::fs::write(&path, &bytes).unwrap();
        let e = read_label_npy(&path, &LabelReadOptions::default()).unwrap_err().to_string();
        let shown = path.display().to_string();
        let masks = shown.replace("_seg.npy", "_masks.npy");
        assert!(e.contains("dtype `|O`") && e.contains("Cellpose"), "{e}");
        assert!(
            e.contains(&format!(
                "python -c \"import numpy as np; d=np.load('{shown}', allow_pickle=True).item(); np.save('{masks}', \
                 d['masks'])\""
            )),
            "{e}"
        );
        assert!(e.contains("--save_tif"), "{e}");
        assert!(!e.contains("not a label type"), "{e}");
        // Another object array is named the same way, its masks file after its stem.
        assert!(object_array_hint(Path::new("cells.npy")).contains("np.save('cells_masks.npy'"));
    }

    #[test]
    fn values_decode_in_both_byte_orders() {
        assert_eq!(decode(&[0xff, 0xff], true, false), -1);
        assert_eq!(decode(&[0xff, 0xfe], false, true), 0xfffe);
        assert_eq!(decode(&[0x80], true, false), -128);
        assert_eq!(decode(&[0, 0, 0, 0, 0, 0, 0, 0x80], true, false), i64::MIN as i128);
        assert_eq!(decode(&[0xff; 8], false, false), u64::MAX as i128);
        assert_eq!(decode(&[0, 1], false, true), 1);
    }
}

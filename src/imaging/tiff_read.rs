//! Reading label volumes from multi-page TIFF stacks (one page per z slice): 8/16/32/64-bit integer
//! labels (signed ones only when no label is negative), uncompressed, LZW, Deflate or PackBits, classic
//! TIFF or BigTIFF, strips or tiles. The voxel size comes from ImageJ or OME-XML metadata (see
//! `metadata.rs`), a caller's override, or an assumed fallback that is logged and recorded.
//!
//! Bad input never panics: every declared size is checked against the file size before anything
//! is allocated (uncompressed pages must be stored in full; compressed ones cannot expand more than
//! [`MAX_EXPANSION`] times), and every error names the file. Pages may share their data (a crafted
//! file of 600 pages pointing at one strip), so the headers of all pages are read first and the
//! total decoded size is checked against the memory limit ([`super::check_voxel_memory`]) before
//! the first page is decoded.

use super::labels::LabelFormat;
use super::limits::check_voxel_memory;
use super::metadata::{StackMetadata, VoxelSizeSource, parse_metadata};
use super::{ImagingError, LabelVolume};
use crate::geometry::{Real, Vec3};
use ndarray::Array3;
use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};
use tiff::decoder::{Decoder, DecodingResult, Limits, ifd::Value};
use tiff::tags::Tag;

/// Largest expansion factor of any TIFF compression we decode (LZW: 4096-byte strings from 9-bit
/// codes ≈ 3641; Deflate ≈ 1032; PackBits 64), rounded up.
pub const MAX_EXPANSION: u64 = 4096;

/// Voxel size assumed when neither the file nor the caller gives one: 1 µm.
pub const FALLBACK_VOXEL_SIZE: Real = 1e-6;

/// How to read a label volume (any format, see [`super::read_labels`]).
#[derive(Clone, Debug, PartialEq)]
pub struct LabelReadOptions {
    /// Voxel size `[sz, sy, sx]` (m) to use instead of the file's metadata.
    pub voxel_size: Option<[Real; 3]>,
    /// Centre (x, y, z m) of voxel `[0, 0, 0]` to use instead of the file's ImageJ
    /// `xorigin`/`yorigin`/`zorigin` (absent: the coordinate origin).
    pub origin: Option<Vec3>,
    /// Size (m) assumed, with a warning, for every axis that neither the file nor the caller sizes.
    /// Default [`FALLBACK_VOXEL_SIZE`] (1 µm).
    pub fallback_voxel_size: Real,
    /// Bytes per voxel the caller will need on top of the volume's own 4 (e.g. `measure`'s work
    /// arrays), so that the memory check before decoding covers the whole run. Default 0.
    pub work_bytes_per_voxel: u64,
    /// OME-Zarr only: the multiscales level to read (0 = full resolution, the default). Given for
    /// another format, it is an error.
    pub zarr_level: Option<usize>,
}

impl Default for LabelReadOptions {
    fn default() -> Self {
        Self {
            voxel_size: None,
            origin: None,
            fallback_voxel_size: FALLBACK_VOXEL_SIZE,
            work_bytes_per_voxel: 0,
            zarr_level: None,
        }
    }
}

/// A label volume as read: the volume and how it was stored.
#[derive(Clone, Debug)]
pub struct LabelRead {
    pub volume: LabelVolume,
    /// The file's format.
    pub format: LabelFormat,
    /// Where each voxel size (z, y, x) came from.
    pub voxel_size_source: [VoxelSizeSource; 3],
    /// Bits per stored label (8, 16, 32 or 64).
    pub bits: u16,
    /// Whether the labels were stored as signed integers.
    pub signed: bool,
    /// TIFF compression code of the first page (1 none, 5 LZW, 8/32946 Deflate, 32773 PackBits); 0 for
    /// the other formats.
    pub compression: u16,
    /// Things the user should know (assumed voxel sizes, ignored metadata).
    pub warnings: Vec<String>,
}

/// Pixel type of one page.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct PixelType {
    bits: u16,
    signed: bool,
}

impl std::fmt::Display for PixelType {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}int{}", if self.signed { "" } else { "u" }, self.bits)
    }
}

/// Reads a label volume from a multi-page TIFF; see the module documentation.
pub fn read_label_tiff(path: &Path, options: &LabelReadOptions) -> Result<LabelRead, ImagingError> {
    let file = File::open(path).map_err(|source| ImagingError::Open { path: path.to_path_buf(), source })?;
    let file_size = file.metadata().map_err(|source| ImagingError::Open { path: path.to_path_buf(), source })?.len();
    decode_label_tiff(BufReader::with_capacity(1 << 16, file), file_size, path, options)
}

/// [`read_label_tiff`] on a TIFF held in memory; `path` names it in errors.
pub fn read_label_tiff_bytes(bytes: &[u8], path: &Path, options: &LabelReadOptions) -> Result<LabelRead, ImagingError> {
    decode_label_tiff(std::io::Cursor::new(bytes), bytes.len() as u64, path, options)
}

/// Decodes a label TIFF of `file_size` bytes from `reader`.
fn decode_label_tiff<R: std::io::Read + std::io::Seek>(
    reader: R,
    file_size: u64,
    path: &Path,
    options: &LabelReadOptions,
) -> Result<LabelRead, ImagingError> {
    let corrupt = |e: tiff::TiffError| corrupt(path, e);
    let decoder = Decoder::new(reader).map_err(corrupt)?;
    // No tag value or compressed chunk can be larger than the file, and no decoded buffer larger than
    // the file expanded by the largest compression ratio; each page is also checked below.
    let mut limits = Limits::default();
    let cap = usize::try_from(file_size).unwrap_or(usize::MAX);
    limits.ifd_value_size = cap;
    limits.intermediate_buffer_size = cap.max(1 << 20);
    limits.decoding_buffer_size = usize::try_from(file_size.saturating_mul(MAX_EXPANSION)).unwrap_or(usize::MAX);
    let mut decoder = decoder.with_limits(limits);

    let meta = first_page_metadata(&mut decoder);
    if meta.channels.unwrap_or(1) > 1 || meta.frames.unwrap_or(1) > 1 {
        return Err(ImagingError::Unsupported {
            path: path.to_path_buf(),
            message: format!(
                "holds {} channels and {} time points; a label volume must have one channel and one time point \
                 (extract one, e.g. Fiji Image › Duplicate)",
                meta.channels.unwrap_or(1),
                meta.frames.unwrap_or(1)
            ),
        });
    }
    let compression = decoder.find_tag_unsigned::<u16>(Tag::Compression).ok().flatten().unwrap_or(1);

    // First pass, headers only: every page's size, type and stored bytes, so that the total is
    // checked against the memory limit before a single page is decoded (pages may share one strip,
    // so no per-page check bounds the total).
    let mut first: Option<(u32, u32, PixelType)> = None;
    let mut pages = 0usize;
    loop {
        let (width, height) = decoder.dimensions().map_err(corrupt)?;
        let pixel = pixel_type(&mut decoder, path)?;
        check_stored_size(&mut decoder, path, pages, file_size, width, height, pixel)?;
        match first {
            None => first = Some((width, height, pixel)),
            Some((w0, h0, p0)) => {
                if (width, height) != (w0, h0) {
                    return Err(ImagingError::PageSize {
                        path: path.to_path_buf(),
                        page: pages,
                        width,
                        height,
                        first_width: w0,
                        first_height: h0,
                    });
                }
                if pixel != p0 {
                    return Err(ImagingError::PageType {
                        path: path.to_path_buf(),
                        page: pages,
                        page_type: pixel.to_string(),
                        first_type: p0.to_string(),
                    });
                }
            }
        }
        pages += 1;
        if !decoder.more_images() {
            break;
        }
        decoder.next_image().map_err(corrupt)?;
    }
    let (width, height, pixel) = first.expect("at least one page was read");
    if pages == 1 {
        return Err(ImagingError::NotAVolume { path: path.to_path_buf(), width, height });
    }
    let voxels = (pages as u64).checked_mul(width as u64).and_then(|n| n.checked_mul(height as u64));
    check_voxel_memory(
        voxels,
        4u64.saturating_add(options.work_bytes_per_voxel),
        &format!("{}: {pages} pages of {width} × {height} voxels", path.display()),
        "crop or bin the volume (e.g. Fiji Image › Crop, Image › Scale)",
    )?;

    let page_len = width as usize * height as usize;
    let mut data: Vec<u32> = Vec::with_capacity(page_len * pages);
    for page in 0..pages {
        decoder.seek_to_image(page).map_err(corrupt)?;
        let decoded = decoder.read_image().map_err(corrupt)?;
        append_labels(decoded, page_len, &mut data, |i| [page, i / width as usize, i % width as usize], path)?;
    }
    let labels = Array3::from_shape_vec((pages, height as usize, width as usize), data)
        .map_err(|e| ImagingError::Corrupt { path: path.to_path_buf(), message: e.to_string() })?;

    let mut warnings = meta.warnings.clone();
    let (voxel_size, voxel_size_source) = resolve_voxel_size(&meta, options, &mut warnings, path);
    let [sz, sy, sx] = voxel_size;
    let from_file = |a: usize, s: Real| meta.origin_voxels[a].map_or(0.0, |o| -o * s);
    let origin = options.origin.unwrap_or_else(|| Vec3::new(from_file(0, sx), from_file(1, sy), from_file(2, sz)));
    let volume = LabelVolume::new(labels, voxel_size, origin)
        .map_err(|e| ImagingError::Unsupported { path: path.to_path_buf(), message: e.to_string() })?;
    Ok(LabelRead {
        volume,
        format: LabelFormat::Tiff,
        voxel_size_source,
        bits: pixel.bits,
        signed: pixel.signed,
        compression,
        warnings,
    })
}

fn corrupt(path: &Path, e: tiff::TiffError) -> ImagingError {
    ImagingError::Corrupt { path: path.to_path_buf(), message: e.to_string() }
}

fn first_page_metadata<R: std::io::Read + std::io::Seek>(decoder: &mut Decoder<R>) -> StackMetadata {
    let description = match decoder.find_tag(Tag::ImageDescription) {
        Ok(Some(Value::Ascii(s))) => Some(s),
        _ => None,
    };
    let rational = |v: Option<Value>| match v {
        Some(Value::Rational(n, d)) if d != 0 => Some(n as Real / d as Real),
        Some(Value::Double(x)) => Some(x),
        Some(Value::Float(x)) => Some(x as Real),
        _ => None,
    };
    let xres = rational(decoder.find_tag(Tag::XResolution).ok().flatten());
    let yres = rational(decoder.find_tag(Tag::YResolution).ok().flatten());
    let unit = decoder.find_tag_unsigned::<u16>(Tag::ResolutionUnit).ok().flatten();
    parse_metadata(description.as_deref(), (xres, yres, unit))
}

fn pixel_type<R: std::io::Read + std::io::Seek>(
    decoder: &mut Decoder<R>,
    path: &Path,
) -> Result<PixelType, ImagingError> {
    let to_path = || path.to_path_buf();
    let samples = decoder.find_tag_unsigned::<u16>(Tag::SamplesPerPixel).map_err(|e| corrupt(path, e))?.unwrap_or(1);
    let bits = match decoder.find_tag_unsigned_vec::<u16>(Tag::BitsPerSample) {
        Ok(Some(v)) => v.first().copied().unwrap_or(1),
        Ok(None) => 1,
        Err(e) => return Err(corrupt(path, e)),
    };
    let format = match decoder.find_tag_unsigned_vec::<u16>(Tag::SampleFormat) {
        Ok(Some(v)) => v.first().copied().unwrap_or(1),
        Ok(None) => 1,
        Err(e) => return Err(corrupt(path, e)),
    };
    let photometric = decoder.find_tag_unsigned::<u16>(Tag::PhotometricInterpretation).ok().flatten();
    if samples != 1 {
        let kind = match photometric {
            Some(2) if samples == 4 => "RGBA".to_string(),
            Some(2) => "RGB".to_string(),
            Some(5) => "CMYK".to_string(),
            Some(6) => "YCbCr".to_string(),
            _ => format!("{samples} channels interleaved"),
        };
        return Err(ImagingError::MultiSample { path: to_path(), samples, kind });
    }
    if matches!(photometric, Some(2) | Some(5) | Some(6)) {
        return Err(ImagingError::MultiSample { path: to_path(), samples, kind: "colour".into() });
    }
    match format {
        3 => return Err(ImagingError::FloatPixels { path: to_path(), bits }),
        1 | 2 => {}
        other => {
            return Err(ImagingError::Unsupported {
                path: to_path(),
                message: format!("sample format {other} is not an integer format"),
            });
        }
    }
    if !matches!(bits, 8 | 16 | 32 | 64) {
        return Err(ImagingError::BitDepth { path: to_path(), bits });
    }
    Ok(PixelType { bits, signed: format == 2 })
}

/// Checks the page's chunks lie inside the file and can hold the declared image.
fn check_stored_size<R: std::io::Read + std::io::Seek>(
    decoder: &mut Decoder<R>,
    path: &Path,
    page: usize,
    file_size: u64,
    width: u32,
    height: u32,
    pixel: PixelType,
) -> Result<(), ImagingError> {
    let tiled = decoder.find_tag(Tag::TileOffsets).ok().flatten().is_some();
    let (offsets_tag, counts_tag) =
        if tiled { (Tag::TileOffsets, Tag::TileByteCounts) } else { (Tag::StripOffsets, Tag::StripByteCounts) };
    let offsets = decoder.find_tag_unsigned_vec::<u64>(offsets_tag).map_err(|e| corrupt(path, e))?.unwrap_or_default();
    let counts = decoder.find_tag_unsigned_vec::<u64>(counts_tag).map_err(|e| corrupt(path, e))?.unwrap_or_default();
    if offsets.is_empty() || offsets.len() != counts.len() {
        return Err(ImagingError::Corrupt {
            path: path.to_path_buf(),
            message: format!("page {page} has {} data offsets and {} byte counts", offsets.len(), counts.len()),
        });
    }
    let mut stored = 0u64;
    for (&o, &c) in offsets.iter().zip(&counts) {
        let end = o.saturating_add(c);
        if end > file_size {
            return Err(ImagingError::Truncated { path: path.to_path_buf(), page, end, file_size });
        }
        stored = stored.saturating_add(c);
    }
    let decoded = width as u64 * height as u64 * (pixel.bits / 8) as u64;
    let compression = decoder.find_tag_unsigned::<u16>(Tag::Compression).ok().flatten().unwrap_or(1);
    // Tiles may pad the image, so uncompressed data can be larger than the image, never smaller.
    let max_decoded = if compression == 1 { stored } else { stored.saturating_mul(MAX_EXPANSION) };
    if decoded > max_decoded {
        return Err(ImagingError::ImplausibleSize { path: path.to_path_buf(), page, width, height, decoded, stored });
    }
    Ok(())
}

/// Appends one decoded page, converting to `u32` and rejecting negative or too-large labels.
fn append_labels(
    decoded: DecodingResult,
    page_len: usize,
    out: &mut Vec<u32>,
    index: impl Fn(usize) -> [usize; 3],
    path: &Path,
) -> Result<(), ImagingError> {
    let path_buf = || -> PathBuf { path.to_path_buf() };
    macro_rules! unsigned {
        ($v:expr) => {{
            let v = &$v[..page_len.min($v.len())];
            out.extend(v.iter().map(|&x| x as u32));
        }};
    }
    macro_rules! signed {
        ($v:expr) => {{
            let v = &$v[..page_len.min($v.len())];
            if let Some(i) = v.iter().position(|&x| x < 0) {
                return Err(ImagingError::NegativeLabel { path: path_buf(), index: index(i), value: v[i] as i64 });
            }
            if let Some(i) = v.iter().position(|&x| x as i64 > u32::MAX as i64) {
                return Err(ImagingError::LabelTooLarge { path: path_buf(), index: index(i), value: v[i] as u64 });
            }
            out.extend(v.iter().map(|&x| x as u32));
        }};
    }
    let before = out.len();
    match decoded {
        DecodingResult::U8(v) => unsigned!(v),
        DecodingResult::U16(v) => unsigned!(v),
        DecodingResult::U32(v) => unsigned!(v),
        DecodingResult::U64(v) => {
            let v = &v[..page_len.min(v.len())];
            if let Some(i) = v.iter().position(|&x| x > u32::MAX as u64) {
                return Err(ImagingError::LabelTooLarge { path: path_buf(), index: index(i), value: v[i] });
            }
            out.extend(v.iter().map(|&x| x as u32));
        }
        DecodingResult::I8(v) => signed!(v),
        DecodingResult::I16(v) => signed!(v),
        DecodingResult::I32(v) => signed!(v),
        DecodingResult::I64(v) => signed!(v),
        DecodingResult::F16(_) => return Err(ImagingError::FloatPixels { path: path_buf(), bits: 16 }),
        DecodingResult::F32(_) => return Err(ImagingError::FloatPixels { path: path_buf(), bits: 32 }),
        DecodingResult::F64(_) => return Err(ImagingError::FloatPixels { path: path_buf(), bits: 64 }),
    }
    if out.len() - before != page_len {
        return Err(ImagingError::Corrupt {
            path: path_buf(),
            message: format!("page {} decoded to {} pixels, expected {page_len}", index(0)[0], out.len() - before),
        });
    }
    Ok(())
}

fn resolve_voxel_size(
    meta: &StackMetadata,
    options: &LabelReadOptions,
    warnings: &mut Vec<String>,
    path: &Path,
) -> ([Real; 3], [VoxelSizeSource; 3]) {
    let from_file = std::array::from_fn(|a| match (meta.voxel_size[a], meta.source) {
        (Some(s), Some(src)) => Some((s, src)),
        _ => None,
    });
    super::labels::resolve_voxel_size(from_file, options, warnings, path, "in the file's metadata")
}

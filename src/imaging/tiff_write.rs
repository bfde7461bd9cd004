//! Writing label volumes as ImageJ hyperstack TIFFs: one page per z slice, `ImageDescription`
//! `ImageJ=… images=N slices=N unit=micron spacing=SZ`, `XResolution`/`YResolution` in pixels per
//! micron, so Fiji and tifffile/napari recover the voxel size. uint16 by default (uint32 when a label
//! exceeds 65535; ImageJ itself cannot show uint32 stacks, Fiji's Bio-Formats and tifffile can).
//! Written to a temporary name and renamed.

use super::metadata::imagej_description;
use super::{ImagingError, LabelVolume};
use crate::files::{FileError, write_atomically};
use crate::geometry::Real;
use ndarray::Axis;
use std::io::{Seek, Write};
use std::path::Path;
use tiff::encoder::{Compression, DeflateLevel, Rational, TiffEncoder, TiffKind, colortype};
use tiff::tags::{ResolutionUnit, Tag};

/// Stored label type.
#[derive(Copy, Clone, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum LabelDtype {
    U8,
    U16,
    U32,
}

impl LabelDtype {
    /// Largest label this type holds.
    pub fn max_label(self) -> u32 {
        match self {
            LabelDtype::U8 => u8::MAX as u32,
            LabelDtype::U16 => u16::MAX as u32,
            LabelDtype::U32 => u32::MAX,
        }
    }

    /// uint16, or uint32 when `max_label` does not fit.
    pub fn for_max_label(max_label: u32) -> Self {
        if max_label <= u16::MAX as u32 { LabelDtype::U16 } else { LabelDtype::U32 }
    }

    pub fn name(self) -> &'static str {
        match self {
            LabelDtype::U8 => "uint8",
            LabelDtype::U16 => "uint16",
            LabelDtype::U32 => "uint32",
        }
    }
}

/// Compression of written pages.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Default)]
pub enum TiffCompression {
    /// Opens everywhere (ImageJ's own reader included); the default.
    #[default]
    None,
    Lzw,
    Deflate,
}

/// How to write a label TIFF.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct LabelWriteOptions {
    /// Stored type; default [`LabelDtype::for_max_label`].
    pub dtype: Option<LabelDtype>,
    pub compression: TiffCompression,
    /// Write BigTIFF (64-bit offsets; needed past 4 GiB, not readable by ImageJ's own reader).
    pub bigtiff: bool,
}

/// Writes `volume` as a multi-page ImageJ TIFF at `path` (atomically); returns the stored type.
pub fn write_label_tiff(
    path: &Path,
    volume: &LabelVolume,
    options: &LabelWriteOptions,
) -> Result<LabelDtype, ImagingError> {
    let max_label = volume.max_label();
    let dtype = options.dtype.unwrap_or(LabelDtype::for_max_label(max_label));
    if max_label > dtype.max_label() {
        return Err(ImagingError::Write {
            path: path.to_path_buf(),
            message: format!("label {max_label} does not fit in {}", dtype.name()),
        });
    }
    let [nz, ny, nx] = volume.shape();
    let (Ok(width), Ok(height)) = (u32::try_from(nx), u32::try_from(ny)) else {
        return Err(ImagingError::Write {
            path: path.to_path_buf(),
            message: format!("a {ny}x{nx} slice exceeds the TIFF page size"),
        });
    };
    let [sz, sy, sx] = volume.voxel_size();
    let page = Page {
        width,
        height,
        // ImageJ: physical x = (i − xorigin)·sx, so xorigin = −origin.x / sx.
        description: imagej_description(
            nz,
            tidy(sz * 1e6),
            max_label,
            [tidy(-volume.origin().x / sx), tidy(-volume.origin().y / sy), tidy(-volume.origin().z / sz)],
        ),
        x_resolution: rational(1.0 / (sx * 1e6)),
        y_resolution: rational(1.0 / (sy * 1e6)),
    };
    let compression = match options.compression {
        TiffCompression::None => Compression::Uncompressed,
        TiffCompression::Lzw => Compression::Lzw,
        TiffCompression::Deflate => Compression::Deflate(DeflateLevel::Fast),
    };
    let result = write_atomically(path, |w| {
        let encode = |e: tiff::TiffError| std::io::Error::other(e);
        let contiguous = matches!(compression, Compression::Uncompressed);
        if options.bigtiff {
            let mut enc = TiffEncoder::new_big(w).map_err(encode)?.with_compression(compression);
            write_volume(&mut enc, volume, dtype, &page, contiguous).map_err(encode)
        } else {
            let mut enc = TiffEncoder::new(w).map_err(encode)?.with_compression(compression);
            write_volume(&mut enc, volume, dtype, &page, contiguous).map_err(encode)
        }
    });
    match result {
        Ok(()) => Ok(dtype),
        Err(FileError::Write { path, source }) => Err(ImagingError::Write { path, message: source.to_string() }),
        Err(other) => Err(ImagingError::Write { path: path.to_path_buf(), message: other.to_string() }),
    }
}

struct Page {
    width: u32,
    height: u32,
    description: String,
    x_resolution: Rational,
    y_resolution: Rational,
}

/// Uncompressed pages contiguously ([`write_pages_contiguously`]), compressed ones page by page.
fn write_volume<W: Write + Seek, K: TiffKind>(
    enc: &mut TiffEncoder<W, K>,
    volume: &LabelVolume,
    dtype: LabelDtype,
    page: &Page,
    contiguous: bool,
) -> tiff::TiffResult<()> {
    if contiguous { write_pages_contiguously(enc, volume, dtype, page) } else { write_pages(enc, volume, dtype, page) }
}

fn write_pages<W: Write + Seek, K: TiffKind>(
    enc: &mut TiffEncoder<W, K>,
    volume: &LabelVolume,
    dtype: LabelDtype,
    page: &Page,
) -> tiff::TiffResult<()> {
    for (z, slice) in volume.labels().axis_iter(Axis(0)).enumerate() {
        let first = z == 0;
        match dtype {
            LabelDtype::U8 => {
                let data: Vec<u8> = slice.iter().map(|&l| l as u8).collect();
                let mut image = enc.new_image::<colortype::Gray8>(page.width, page.height)?;
                tags(image.encoder(), page, first)?;
                image.write_data(&data)?;
            }
            LabelDtype::U16 => {
                let data: Vec<u16> = slice.iter().map(|&l| l as u16).collect();
                let mut image = enc.new_image::<colortype::Gray16>(page.width, page.height)?;
                tags(image.encoder(), page, first)?;
                image.write_data(&data)?;
            }
            LabelDtype::U32 => {
                let data: Vec<u32> = slice.iter().copied().collect();
                let mut image = enc.new_image::<colortype::Gray32>(page.width, page.height)?;
                tags(image.encoder(), page, first)?;
                image.write_data(&data)?;
            }
        }
    }
    Ok(())
}

/// Uncompressed pages as ImageJ writes them: every page's data back to back (written before the
/// first directory), then one directory per page pointing into that block. tifffile (napari) reads
/// an ImageJ file whose first page's data could hold every page before the second directory as one
/// contiguous block; with the tiff crate's data-then-directory order per page a small uint8 stack
/// met that test and was read from the bytes of the directories.
fn write_pages_contiguously<W: Write + Seek, K: TiffKind>(
    enc: &mut TiffEncoder<W, K>,
    volume: &LabelVolume,
    dtype: LabelDtype,
    page: &Page,
) -> tiff::TiffResult<()> {
    let bytes_per_voxel: u64 = match dtype {
        LabelDtype::U8 => 1,
        LabelDtype::U16 => 2,
        LabelDtype::U32 => 4,
    };
    let page_bytes = K::convert_offset(u64::from(page.width) * u64::from(page.height) * bytes_per_voxel)?;
    let mut offsets = Vec::new();
    let nz = volume.labels().len_of(Axis(0));
    for z in 0..nz {
        let mut dir = enc.image_directory()?;
        if z == 0 {
            for slice in volume.labels().axis_iter(Axis(0)) {
                let offset = match dtype {
                    LabelDtype::U8 => dir.write_data(&slice.iter().map(|&l| l as u8).collect::<Vec<u8>>()[..])?,
                    LabelDtype::U16 => dir.write_data(&slice.iter().map(|&l| l as u16).collect::<Vec<u16>>()[..])?,
                    LabelDtype::U32 => dir.write_data(&slice.iter().copied().collect::<Vec<u32>>()[..])?,
                };
                offsets.push(K::convert_offset(offset)?);
            }
        }
        dir.write_tag(Tag::ImageWidth, page.width)?;
        dir.write_tag(Tag::ImageLength, page.height)?;
        dir.write_tag(Tag::BitsPerSample, (bytes_per_voxel * 8) as u16)?;
        dir.write_tag(Tag::Compression, 1u16)?;
        dir.write_tag(Tag::PhotometricInterpretation, 1u16)?;
        dir.write_tag(Tag::SamplesPerPixel, 1u16)?;
        dir.write_tag(Tag::RowsPerStrip, page.height)?;
        dir.write_tag(Tag::SampleFormat, 1u16)?;
        dir.write_tag(Tag::StripOffsets, K::convert_slice(&offsets[z..=z]))?;
        dir.write_tag(Tag::StripByteCounts, K::convert_slice(std::slice::from_ref(&page_bytes)))?;
        tags(&mut dir, page, z == 0)?;
        dir.finish()?;
    }
    Ok(())
}

fn tags<W: Write + Seek, K: TiffKind>(
    dir: &mut tiff::encoder::DirectoryEncoder<'_, W, K>,
    page: &Page,
    first: bool,
) -> tiff::TiffResult<()> {
    if first {
        dir.write_tag(Tag::ImageDescription, page.description.as_str())?;
    }
    dir.write_tag(Tag::XResolution, page.x_resolution.clone())?;
    dir.write_tag(Tag::YResolution, page.y_resolution.clone())?;
    dir.write_tag(Tag::ResolutionUnit, ResolutionUnit::None)?;
    Ok(())
}

/// Rounds away float noise (0.23500000000000001 → 0.235) while keeping 12 significant digits.
fn tidy(v: Real) -> Real {
    if v == 0.0 || !v.is_finite() {
        return v;
    }
    let scale = 10f64.powi(11 - v.abs().log10().floor() as i32);
    (v * scale).round() / scale
}

/// The closest `n/d` with both in `u32`, for a positive resolution.
fn rational(r: Real) -> Rational {
    if !(r.is_finite() && r > 0.0) {
        return Rational { n: 1, d: 1 };
    }
    let max = u32::MAX as Real;
    if r >= 1.0 {
        let d = (max / r).floor().clamp(1.0, max);
        Rational { n: (r * d).round().clamp(1.0, max) as u32, d: d as u32 }
    } else {
        let n = (max * r).floor().clamp(1.0, max);
        Rational { n: n as u32, d: (n / r).round().clamp(1.0, max) as u32 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rationals_are_precise() {
        for r in [1.0 / 0.15, 1.0 / 0.235, 1e-3, 1.0, 3.0e6, 12345.678] {
            let q = rational(r);
            let back = q.n as f64 / q.d as f64;
            assert!((back - r).abs() <= 1e-9 * r, "{r} -> {}/{} = {back}", q.n, q.d);
        }
        assert_eq!(tidy(0.235e-6 * 1e6), 0.235);
        assert_eq!(tidy(2.0), 2.0);
    }
}

//! Arguments shared by the commands that write label TIFFs (`voxelize`, `generate labels`).

use crate::geometry::Real;
use crate::imaging::{LabelDtype, LabelVolume, LabelWriteOptions, TiffCompression};
use crate::io::{PLAUSIBLE_LENGTH, implausible_length, parse_lengths};

/// Parses a voxel size `Z,Y,X` (or one length for all three); units as in `parse_lengths`.
/// A voxel edge outside 1 nm – 1 mm is refused as a unit slip, with a hint (`0.235,0.15,0.15` →
/// `0.235,0.15,0.15um`).
pub(crate) fn parse_voxel_size(s: &str) -> Result<[Real; 3], String> {
    let v = match parse_lengths(s)?.as_slice() {
        [a] => [*a; 3],
        [z, y, x] => [*z, *y, *x],
        _ => return Err(format!("`{s}`: give one voxel size or three (z,y,x), e.g. 0.235,0.15,0.15um")),
    };
    if let Some(bad) = v.iter().find_map(|&l| implausible_length("voxel size", l)) {
        let bare = !s.chars().any(|c| c.is_alphabetic() && c != 'e' && c != 'E');
        let [lo, hi] = PLAUSIBLE_LENGTH;
        let all_um = v.iter().all(|&l| (lo..=hi).contains(&(l * 1e-6)));
        if bare && all_um {
            return Err(format!(
                "`{s}`: voxel sizes of {v:?} m lie outside the plausible range 1 nm – 1 mm for cells; did you mean \
                 {}um? (a bare number is metres)",
                s.trim()
            ));
        }
        return Err(format!("`{s}`: {bad}"));
    }
    Ok(v)
}

/// Parses a grid shape `Z,Y,X` (or one count for all three).
pub(crate) fn parse_shape(s: &str) -> Result<[usize; 3], String> {
    let n: Vec<usize> = s
        .split(',')
        .map(|p| p.trim().parse::<usize>().ok().filter(|&n| n > 0))
        .collect::<Option<_>>()
        .ok_or_else(|| format!("`{s}`: a shape is one or three positive voxel counts (z,y,x), e.g. 32,128,128"))?;
    match n.as_slice() {
        [a] => Ok([*a; 3]),
        [z, y, x] => Ok([*z, *y, *x]),
        _ => Err(format!("`{s}`: give one voxel count or three (z,y,x)")),
    }
}

/// How the label TIFF is stored.
#[derive(clap::Args, Debug, Clone)]
pub struct LabelOutputArgs {
    /// Stored label type: u8, u16 or u32 (default: u16, or u32 when a label exceeds 65535).
    #[arg(long, value_parser = ["u8", "u16", "u32"])]
    pub dtype: Option<String>,
    /// Compression: none (default; opens everywhere), lzw or deflate.
    #[arg(long, default_value = "none", value_parser = ["none", "lzw", "deflate"])]
    pub compress: String,
    /// Write BigTIFF (needed beyond 4 GiB; not readable by ImageJ's own reader).
    #[arg(long)]
    pub bigtiff: bool,
}

impl LabelOutputArgs {
    pub(crate) fn options(&self) -> LabelWriteOptions {
        let dtype = self.dtype.as_deref().map(|d| match d {
            "u8" => LabelDtype::U8,
            "u16" => LabelDtype::U16,
            _ => LabelDtype::U32,
        });
        let compression = match self.compress.as_str() {
            "lzw" => TiffCompression::Lzw,
            "deflate" => TiffCompression::Deflate,
            _ => TiffCompression::None,
        };
        LabelWriteOptions { dtype, compression, bigtiff: self.bigtiff }
    }
}

/// `32x128x128 (z,y,x), voxel 0.235 x 0.15 x 0.15 µm`.
pub(crate) fn describe_grid(v: &LabelVolume) -> String {
    v.describe_grid()
}

//! Length units of input files. tissuefit works in metres; image-tool meshes come in voxels or µm.

use crate::geometry::{Real, Vec3};
use std::fmt;
use std::str::FromStr;

/// Metres per file length unit, per axis (anisotropic voxels have different sizes along z).
///
/// Parsed from `m`, `mm`, `um` (or `µm`), `nm`, a number of metres (`2.5e-7`), a number with a unit
/// (`0.15um`), or three comma-separated values with one unit for all (`0.15,0.15,0.235um`: the x, y, z
/// voxel size of a mesh in voxel coordinates).
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct LengthScale(pub Vec3);

impl LengthScale {
    /// Lengths already in metres.
    pub const METRE: LengthScale = LengthScale(Vec3::new(1.0, 1.0, 1.0));

    /// Whether this scale changes nothing.
    pub fn is_identity(&self) -> bool {
        *self == Self::METRE
    }
}

impl Default for LengthScale {
    fn default() -> Self {
        Self::METRE
    }
}

fn unit_factor(unit: &str) -> Option<Real> {
    match unit {
        "" | "m" => Some(1.0),
        "mm" => Some(1e-3),
        "um" | "µm" | "micron" | "microns" => Some(1e-6),
        "nm" => Some(1e-9),
        _ => None,
    }
}

impl FromStr for LengthScale {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let s = s.trim();
        if !s.is_empty()
            && let Some(f) = unit_factor(s)
        {
            return Ok(LengthScale(Vec3::repeat(f)));
        }
        // Number part, then unit: the unit starts at the first letter other than an exponent `e`.
        let split = s.find(|c: char| (c.is_alphabetic() && c != 'e' && c != 'E') || c == 'µ').unwrap_or(s.len());
        let (numbers, unit) = (&s[..split], s[split..].trim());
        let factor =
            unit_factor(unit).ok_or_else(|| format!("unknown length unit `{unit}` in `{s}`; use m, mm, um or nm"))?;
        let values: Result<Vec<Real>, _> = numbers.split(',').map(|v| v.trim().parse::<Real>()).collect();
        let values = values.map_err(|_| {
            format!("cannot read `{s}` as a length scale; examples: um, 1e-6, 0.15um, 0.15,0.15,0.235um")
        })?;
        let v = match values.as_slice() {
            [a] => Vec3::repeat(*a),
            [x, y, z] => Vec3::new(*x, *y, *z),
            _ => return Err(format!("`{s}`: give one length or three (x,y,z)")),
        } * factor;
        if !v.iter().all(|c| c.is_finite() && *c > 0.0) {
            return Err(format!("`{s}`: a length scale must be positive and finite"));
        }
        Ok(LengthScale(v))
    }
}

impl fmt::Display for LengthScale {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let v = self.0;
        if v.x == v.y && v.y == v.z { write!(f, "{:e} m", v.x) } else { write!(f, "{:e},{:e},{:e} m", v.x, v.y, v.z) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_units_numbers_and_voxel_sizes() {
        assert_eq!("um".parse::<LengthScale>().unwrap(), LengthScale(Vec3::repeat(1e-6)));
        assert_eq!("µm".parse::<LengthScale>().unwrap(), LengthScale(Vec3::repeat(1e-6)));
        assert_eq!("m".parse::<LengthScale>().unwrap(), LengthScale::METRE);
        assert_eq!("2.5e-7".parse::<LengthScale>().unwrap(), LengthScale(Vec3::repeat(2.5e-7)));
        let v = "0.15,0.15,0.235um".parse::<LengthScale>().unwrap().0;
        assert!((v - Vec3::new(0.15e-6, 0.15e-6, 0.235e-6)).norm() < 1e-20);
        assert!("0.5 nm".parse::<LengthScale>().unwrap().0.x - 0.5e-9 < 1e-24);
        assert!("furlong".parse::<LengthScale>().is_err());
        assert!("-1um".parse::<LengthScale>().is_err());
        assert!("1,2um".parse::<LengthScale>().is_err());
    }
}

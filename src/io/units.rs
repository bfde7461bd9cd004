//! Length units of input files and of written files. tissuefit works in metres; image-tool meshes
//! come in voxels or µm ([`LengthScale`]), and files meant for people may be written in µm
//! ([`OutputUnit`]), so that ParaView's axes and a table's volumes read 12.3 rather than 1.23e-5.

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
        let values = parse_lengths(s).map_err(|e| {
            format!("{e}; a length scale is a unit or lengths, e.g. um, 1e-6, 0.15um, 0.15,0.15,0.235um")
        })?;
        let v = match values.as_slice() {
            [a] => Vec3::repeat(*a),
            [x, y, z] => Vec3::new(*x, *y, *z),
            _ => return Err(format!("`{s}`: give one length or three (x,y,z)")),
        };
        Ok(LengthScale(v))
    }
}

/// One length as a command line gives it (`0.1um`, `100nm`, `1e-7`; a bare number is metres), refused
/// outside the plausible range for cells (1 nm – 1 mm) as a unit slip, with a "did you mean" hint.
pub fn parse_length(s: &str) -> Result<Real, String> {
    parse_named_length("the length", s)
}

/// [`parse_length`] for the setting `key`, which a refusal names (`l_min = 4e-1 m lies outside …`).
pub fn parse_named_length(key: &str, s: &str) -> Result<Real, String> {
    match parse_lengths(s)?.as_slice() {
        [l] => match crate::files::implausible_length(key, *l) {
            Some(bad) => Err(format!("`{s}`: {bad}")),
            None => Ok(*l),
        },
        _ => Err(format!("`{s}`: give one length, e.g. 0.4um")),
    }
}

/// Parses one length or a comma-separated list of lengths in metres. Each is a number with an
/// optional unit (`m`, `mm`, `um`/`µm`/`micron`, `nm`); a unit written only after the last number
/// applies to all of them, and a number without any unit is metres: `0.235um`, `235nm`, `2.35e-7`,
/// `0.235,0.15,0.15um`, `0.235um,150nm,150nm`. Every length must be positive and finite.
pub fn parse_lengths(s: &str) -> Result<Vec<Real>, String> {
    let parts: Vec<(Real, Option<Real>)> = s
        .split(',')
        .map(|part| {
            let part = part.trim();
            // Number, then unit: the unit starts at the first letter other than an exponent `e`.
            let split =
                part.find(|c: char| (c.is_alphabetic() && c != 'e' && c != 'E') || c == 'µ').unwrap_or(part.len());
            let (number, unit) = (part[..split].trim(), part[split..].trim());
            let value = number.parse::<Real>().map_err(|_| format!("cannot read `{part}` as a length"))?;
            let factor = if unit.is_empty() {
                None
            } else {
                Some(
                    unit_factor(unit)
                        .ok_or_else(|| format!("unknown length unit `{unit}` in `{s}`; use m, mm, um or nm"))?,
                )
            };
            Ok((value, factor))
        })
        .collect::<Result<_, String>>()?;
    let trailing = parts.last().and_then(|p| p.1).unwrap_or(1.0);
    let values: Vec<Real> = parts.iter().map(|(v, f)| v * f.unwrap_or(trailing)).collect();
    if !values.iter().all(|v| v.is_finite() && *v > 0.0) {
        return Err(format!("`{s}`: lengths must be positive and finite"));
    }
    Ok(values)
}

impl fmt::Display for LengthScale {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let v = self.0;
        if v.x == v.y && v.y == v.z { write!(f, "{:e} m", v.x) } else { write!(f, "{:e},{:e},{:e} m", v.x, v.y, v.z) }
    }
}

/// The length unit of the files a command writes for people to read: SI metres (the default, and
/// what every stage reads back) or micrometres. A length column `x` becomes `x_um`, an area `x_um2`,
/// a volume `x_um3` ([`OutputUnit::column`]); a `.vtp` records its unit in the field data, where
/// tissuefit's reader finds it and converts back to metres.
#[derive(
    Copy, Clone, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize, schemars::JsonSchema,
)]
pub enum OutputUnit {
    /// Metres (SI), the default.
    #[default]
    #[serde(rename = "m")]
    Metre,
    /// Micrometres (`um`; `µm` is read too).
    #[serde(rename = "um", alias = "µm")]
    Micrometre,
}

impl OutputUnit {
    /// The unit's name in files and on the command line: `m`, `um`.
    pub fn name(self) -> &'static str {
        match self {
            OutputUnit::Metre => "m",
            OutputUnit::Micrometre => "um",
        }
    }

    /// Whether lengths are written as tissuefit holds them (metres).
    pub fn is_si(self) -> bool {
        self == OutputUnit::Metre
    }

    /// Metres per unit: 1 or 1e-6.
    pub fn metres(self) -> Real {
        match self {
            OutputUnit::Metre => 1.0,
            OutputUnit::Micrometre => 1e-6,
        }
    }

    /// The factor that turns a quantity of length dimension `power` (1 length, 2 area, 3 volume) from
    /// SI into this unit: 1, or 1e6, 1e12, 1e18 for µm (exact decimal powers, not repeated products).
    pub fn factor(self, power: i32) -> Real {
        match self {
            OutputUnit::Metre => 1.0,
            OutputUnit::Micrometre => match power {
                1 => 1e6,
                2 => 1e12,
                3 => 1e18,
                p => 1e6f64.powi(p),
            },
        }
    }

    /// The name of the column `name` holding a quantity of length dimension `power` in this unit:
    /// `name` itself in SI (the stable names), `name_um`, `name_um2`, `name_um3` in µm.
    pub fn column(self, name: &str, power: i32) -> String {
        match (self, power) {
            (OutputUnit::Metre, _) => name.to_string(),
            (_, 1) => format!("{name}_{}", self.name()),
            (_, p) => format!("{name}_{}{p}", self.name()),
        }
    }
}

impl FromStr for OutputUnit {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim() {
            "m" => Ok(OutputUnit::Metre),
            "um" | "µm" | "micron" | "microns" => Ok(OutputUnit::Micrometre),
            other => Err(format!("unknown output length unit `{other}`; use m (SI, the default) or um")),
        }
    }
}

impl fmt::Display for OutputUnit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Metres per unit of a unit name recorded in a file (`m`, `mm`, `um`, `µm`, `nm`).
pub(crate) fn metres_per_unit(unit: &str) -> Option<Real> {
    unit_factor(unit.trim()).filter(|_| !unit.trim().is_empty())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_length_with_its_unit_and_a_unit_slip_refused_with_a_hint() {
        for (text, metres) in [("0.1um", 1e-7), ("100nm", 1e-7), ("1e-7", 1e-7), ("0.5 mm", 5e-4)] {
            let l = parse_length(text).unwrap();
            assert!((l - metres).abs() <= 1e-15 * metres, "{text}: {l}");
        }
        let slip = parse_length("0.1").unwrap_err();
        assert!(slip.contains("`0.1`") && slip.contains("did you mean 0.1um?"), "{slip}");
        assert!(parse_length("0.1,0.2um").unwrap_err().contains("give one length"));
        assert!(parse_length("-1um").is_err());
    }

    #[test]
    fn output_units_scale_and_name_columns() {
        assert_eq!("um".parse::<OutputUnit>().unwrap(), OutputUnit::Micrometre);
        assert_eq!("µm".parse::<OutputUnit>().unwrap(), OutputUnit::Micrometre);
        assert_eq!("m".parse::<OutputUnit>().unwrap(), OutputUnit::Metre);
        assert!("mm".parse::<OutputUnit>().unwrap_err().contains("use m"));
        let um = OutputUnit::Micrometre;
        assert_eq!([um.factor(1), um.factor(2), um.factor(3)], [1e6, 1e12, 1e18]);
        assert_eq!(OutputUnit::Metre.factor(3), 1.0);
        assert_eq!(um.column("volume", 3), "volume_um3");
        assert_eq!(um.column("area", 2), "area_um2");
        assert_eq!(um.column("centroid_x", 1), "centroid_x_um");
        assert_eq!(OutputUnit::Metre.column("volume", 3), "volume");
        assert_eq!(metres_per_unit("um"), Some(1e-6));
        assert_eq!(metres_per_unit(""), None);
        assert_eq!(metres_per_unit("furlong"), None);
    }

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

    #[test]
    fn parses_lengths_with_units() {
        let close =
            |a: &[Real], b: &[Real]| a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() <= 1e-12 * y);
        assert!(close(&parse_lengths("0.235um").unwrap(), &[0.235e-6]));
        assert!(close(&parse_lengths("235nm").unwrap(), &[235e-9]));
        assert!(close(&parse_lengths("2.35e-7").unwrap(), &[2.35e-7]));
        assert!(close(&parse_lengths("2.35e-7m").unwrap(), &[2.35e-7]));
        assert!(close(&parse_lengths("0.235, 0.15,0.15 µm").unwrap(), &[0.235e-6, 0.15e-6, 0.15e-6]));
        assert!(close(&parse_lengths("0.235um,150nm,150nm").unwrap(), &[0.235e-6, 150e-9, 150e-9]));
        assert!(close(&parse_lengths("1,2,3").unwrap(), &[1.0, 2.0, 3.0]));
        for bad in ["", "um", "1 furlong", "0um", "-1nm", "1,,2", "nan", "inf"] {
            assert!(parse_lengths(bad).is_err(), "{bad}");
        }
    }
}

//! Plausible ranges of the lengths and surface tensions a user gives (in a config file or on the
//! command line): a value far outside them is almost certainly a unit slip (`0.235` meant as µm is
//! 0.235 m), and the message says which unit was probably meant.

use crate::geometry::Real;

/// Lengths of cells and of their images (voxel sizes, edge lengths) in metres outside this range are
/// almost certainly a unit slip (`0.235` meant as µm is 0.235 m).
pub const PLAUSIBLE_LENGTH: [Real; 2] = [1e-9, 1e-3];

/// Surface tensions of cells (N/m) outside this range (0 aside) are almost certainly a unit slip
/// (`0.5` meant as mN/m is 0.5 N/m).
pub const PLAUSIBLE_TENSION: [Real; 2] = [1e-6, 1e-1];

/// `None` when the length `value` (m) lies in [`PLAUSIBLE_LENGTH`]; otherwise why not, naming `key`,
/// with a "did you mean" hint (`0.235` → `0.235um`).
pub fn implausible_length(key: &str, value: Real) -> Option<String> {
    let [lo, hi] = PLAUSIBLE_LENGTH;
    if value.is_nan() || (lo..=hi).contains(&value) {
        return None;
    }
    let hint = if value > hi && value <= 1e3 {
        format!("; did you mean {value}um? (a bare number is metres)")
    } else if value > 1e3 && value <= 1e6 {
        format!("; did you mean {value}nm? (a bare number is metres)")
    } else {
        String::new()
    };
    Some(format!("{key} = {value:e} m lies outside the plausible range 1 nm – 1 mm for cells{hint}"))
}

/// `None` when the surface tension `value` (N/m) is 0 or lies in [`PLAUSIBLE_TENSION`]; otherwise
/// why not, naming `key`, with a "did you mean" hint (`0.5` → `0.5e-3 N/m`, given in mN/m).
pub fn implausible_tension(key: &str, value: Real) -> Option<String> {
    let [lo, hi] = PLAUSIBLE_TENSION;
    if value.is_nan() || value == 0.0 || (lo..=hi).contains(&value) {
        return None;
    }
    let hint = if value > hi && value * 1e-3 <= hi {
        format!("; did you mean {value}e-3 N/m? (tensions are in N/m; {value} mN/m = {value}e-3 N/m)")
    } else {
        String::new()
    };
    Some(format!("{key} = {value:e} N/m lies outside the plausible range 1e-6 – 0.1 N/m for cells{hint}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn implausible_lengths_and_tensions_are_named_with_a_hint() {
        assert_eq!(implausible_length("l_min", 0.3e-6), None);
        assert_eq!(implausible_length("l_min", 1e-3), None);
        let m = implausible_length("--voxel-size", 0.235).unwrap();
        assert!(m.contains("--voxel-size = 2.35e-1 m") && m.contains("did you mean 0.235um?"), "{m}");
        let m = implausible_length("l_min", 300.0).unwrap();
        assert!(m.contains("did you mean 300um?"), "{m}");
        let m = implausible_length("l_min", 1e-12).unwrap();
        assert!(m.contains("outside the plausible range") && !m.contains("did you mean"), "{m}");
        assert_eq!(implausible_tension("γ", 0.0), None);
        assert_eq!(implausible_tension("γ", 1e-3), None);
        let m = implausible_tension("γ", 0.5).unwrap();
        assert!(m.contains("did you mean 0.5e-3 N/m?"), "{m}");
        assert!(implausible_tension("γ", 1e-9).unwrap().contains("outside the plausible range"));
    }
}

//! Which labels of a volume count as cells: labels with fewer voxels than a minimum
//! ([`DEFAULT_MIN_VOXELS`] by default) are segmentation debris, and a [`BorderPolicy`] says what
//! becomes of labels that touch the image border (cut cells). Meshing a label volume
//! (`meshing::mesh_labels`) and measuring one directly (`morphology::measure_labels`) apply the
//! same rules, so they live here, below both.

use std::fmt;
use std::str::FromStr;

/// Fewest voxels of a label that counts as a cell: smaller labels are segmentation debris. The
/// default of the `min_voxels` of meshing and of measuring a label volume.
pub const DEFAULT_MIN_VOXELS: u64 = 100;

/// What to do with labels that touch the image border.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum BorderPolicy {
    /// Do not mesh them.
    Drop,
    /// Mesh them as static cells (never moved by the simulation).
    Static,
    /// Mesh them like any other cell (default).
    #[default]
    Keep,
}

impl BorderPolicy {
    pub const ALL: [BorderPolicy; 3] = [BorderPolicy::Drop, BorderPolicy::Static, BorderPolicy::Keep];

    pub fn name(self) -> &'static str {
        match self {
            BorderPolicy::Drop => "drop",
            BorderPolicy::Static => "static",
            BorderPolicy::Keep => "keep",
        }
    }
}

impl fmt::Display for BorderPolicy {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for BorderPolicy {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| format!("unknown border policy `{s}`; one of drop, static, keep"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn border_policies_parse_by_name() {
        for p in BorderPolicy::ALL {
            assert_eq!(p.name().parse::<BorderPolicy>(), Ok(p));
        }
        assert!("fixed".parse::<BorderPolicy>().is_err());
    }
}

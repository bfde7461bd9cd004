//! A whole label volume → a tissue: every label (cell) meshed by [`mesh_mask`], in parallel.
//!
//! Per label, in ascending label order:
//! 1. **Filter**: labels with fewer than [`LabelMeshingOptions::min_voxels`] voxels are segmentation
//!    debris, and with [`BorderPolicy::Drop`] labels whose bounding box reaches the image border are
//!    cut cells: both are reported as dropped, with the reason.
//! 2. **Mesh**: the label's mask (bounding box + [`MASK_MARGIN`] voxels) goes to [`mesh_mask`] with one
//!    l_min for every cell (given, or [`default_l_min`] of the median volume of the labels to mesh, so
//!    that a typical cell gets [`LabelMeshingOptions::target_nodes`] nodes and all cells share one
//!    resolution, as the simulation's remeshing needs) and a seed derived from (seed, label). A
//!    [`MeshingError`] drops that label with the error as the reason; it never aborts the others.
//! 3. **Kind**: labels in [`LabelMeshingOptions::lumen_labels`] become [`CellKind::Lumen`]; with
//!    [`BorderPolicy::Static`], border labels become [`CellKind::Static`] (boundary cells of an imaged
//!    patch, which the simulation holds fixed); the others are epithelial. Cell id = label; target
//!    volume = mesh volume.
//!
//! Labels are meshed with rayon, one task per label; results are collected in label order, and every
//! cell's mesh depends only on its mask, l_min and its own seed, so the tissue is identical whatever
//! the thread count.

use super::{DEFAULT_TARGET_NODES, MeshedCell, MeshingError, MeshingSettings, default_l_min, mesh_mask};
use crate::geometry::Real;
use crate::imaging::{LabelInfo, LabelVolume};
use crate::mesh::{Cell, CellId, CellKind, Tissue, TissueError};
use rayon::prelude::*;
use std::fmt;
use std::str::FromStr;

/// Background voxels around each label's bounding box in the mask given to the mesher.
pub const MASK_MARGIN: usize = 2;

/// Default of [`LabelMeshingOptions::min_voxels`].
pub const DEFAULT_MIN_VOXELS: u64 = 100;

/// What to do with labels that touch the image border.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
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

/// How to mesh a label volume.
#[derive(Clone, Debug, PartialEq)]
pub struct LabelMeshingOptions {
    /// Minimum edge length (m) for every cell; `None` (default): [`default_l_min`] of the median
    /// volume of the labels to mesh with [`Self::target_nodes`].
    pub l_min: Option<Real>,
    /// Nodes of a median-sized cell when l_min is chosen automatically. Default
    /// [`DEFAULT_TARGET_NODES`] (400).
    pub target_nodes: usize,
    /// Labels with fewer voxels are dropped. Default [`DEFAULT_MIN_VOXELS`] (100).
    pub min_voxels: u64,
    /// Labels touching the image border. Default [`BorderPolicy::Keep`].
    pub border: BorderPolicy,
    /// Labels meshed as lumen cells. Default none.
    pub lumen_labels: Vec<u32>,
    /// Seed of the sampling; each label gets its own stream from (seed, label). Default 0.
    pub seed: u64,
}

impl Default for LabelMeshingOptions {
    fn default() -> Self {
        Self {
            l_min: None,
            target_nodes: DEFAULT_TARGET_NODES,
            min_voxels: DEFAULT_MIN_VOXELS,
            border: BorderPolicy::Keep,
            lumen_labels: Vec::new(),
            seed: 0,
        }
    }
}

/// Errors that stop the whole volume (a single cell's failure is a dropped label instead).
#[derive(Debug, thiserror::Error)]
pub enum LabelMeshingError {
    #[error("l_min = {l_min} must be positive and finite")]
    InvalidLMin { l_min: Real },
    #[error("target_nodes must be at least 1")]
    InvalidTargetNodes,
    #[error("the volume has no labels (every voxel is background, 0)")]
    NoLabels,
    #[error(transparent)]
    Tissue(#[from] TissueError),
}

/// What happened to one label.
#[derive(Copy, Clone, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LabelStatus {
    /// Meshed as a free cell (epithelial, or lumen).
    Kept,
    /// Meshed as a static cell (border cell with [`BorderPolicy::Static`]).
    Static,
    /// Not in the tissue; see the reason.
    Dropped,
}

impl LabelStatus {
    pub fn name(self) -> &'static str {
        match self {
            LabelStatus::Kept => "kept",
            LabelStatus::Static => "static",
            LabelStatus::Dropped => "dropped",
        }
    }
}

/// One label's outcome (a row of `report.json`). Volumes in m³.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct LabelReport {
    pub label: u32,
    pub status: LabelStatus,
    /// Why the label was dropped (or, for a static cell, why it is static); `None` for kept cells.
    pub reason: Option<String>,
    /// Cell kind in the tissue; `None` when dropped.
    pub kind: Option<CellKind>,
    /// Nodes of the mesh (0 when dropped).
    pub nodes: usize,
    /// Faces of the mesh (0 when dropped).
    pub faces: usize,
    /// Volume enclosed by the mesh; `None` when dropped.
    pub volume: Option<Real>,
    /// Voxels of the label × voxel volume (for a meshed cell: of its largest 6-connected component with
    /// enclosed cavities filled, the volume the mesh represents).
    pub voxel_volume: Real,
    /// Voxels of the label in the volume.
    pub voxels: u64,
    /// Whether the label's bounding box reaches the image border.
    pub touches_border: bool,
    /// Voxels of the label outside its largest 6-connected component (left out of the mesh).
    pub dropped_voxels: usize,
}

/// A meshed volume: the tissue (cells in ascending label order) and one report per label.
#[derive(Clone, Debug)]
pub struct LabelMeshing {
    pub tissue: Tissue,
    /// One entry per label of the volume, ascending.
    pub report: Vec<LabelReport>,
    /// The l_min (m) used for every cell; `None` when no label passed the filters (and so no l_min was
    /// needed).
    pub l_min: Option<Real>,
}

impl LabelMeshing {
    /// Labels with this status.
    pub fn count(&self, status: LabelStatus) -> usize {
        self.report.iter().filter(|r| r.status == status).count()
    }
}

/// The seed of `label`'s sampling stream: a SplitMix64 mix of (seed, label), so neighbouring labels and
/// seeds give unrelated streams.
pub fn label_seed(seed: u64, label: u32) -> u64 {
    fn splitmix64(mut z: u64) -> u64 {
        z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    splitmix64(seed ^ splitmix64(u64::from(label)))
}

/// Meshes every label of `volume`; see the module documentation.
pub fn mesh_labels(volume: &LabelVolume, options: &LabelMeshingOptions) -> Result<LabelMeshing, LabelMeshingError> {
    mesh_labels_with_progress(volume, options, &|_| {})
}

/// [`mesh_labels`], calling `on_label(label)` (from a worker thread) as each label is finished.
pub fn mesh_labels_with_progress(
    volume: &LabelVolume,
    options: &LabelMeshingOptions,
    on_label: &(dyn Fn(u32) + Sync),
) -> Result<LabelMeshing, LabelMeshingError> {
    if let Some(l_min) = options.l_min
        && !(l_min.is_finite() && l_min > 0.0)
    {
        return Err(LabelMeshingError::InvalidLMin { l_min });
    }
    if options.l_min.is_none() && options.target_nodes == 0 {
        return Err(LabelMeshingError::InvalidTargetNodes);
    }
    let shape = volume.shape();
    let voxel_volume = volume.voxel_volume();
    let mut stats = volume.label_stats();
    stats.sort_by_key(|s| s.label);
    if stats.is_empty() {
        return Err(LabelMeshingError::NoLabels);
    }
    let skip_reason = |info: &LabelInfo| -> Option<String> {
        if info.voxels < options.min_voxels {
            Some(format!("{} voxels, fewer than the minimum {}", info.voxels, options.min_voxels))
        } else if options.border == BorderPolicy::Drop && info.touches_border(shape) {
            Some("touches the image border (--border drop)".into())
        } else {
            None
        }
    };
    let mut to_mesh: Vec<u64> = stats.iter().filter(|s| skip_reason(s).is_none()).map(|s| s.voxels).collect();
    let l_min = match options.l_min {
        Some(l) => Some(l),
        None if to_mesh.is_empty() => None,
        None => {
            to_mesh.sort_unstable();
            let median = to_mesh[to_mesh.len() / 2] as Real * voxel_volume;
            default_l_min(median, options.target_nodes)
        }
    };

    let results: Vec<(LabelReport, Option<Cell>)> = stats
        .par_iter()
        .map(|info| {
            let result = mesh_one(volume, info, options, skip_reason(info), l_min);
            on_label(info.label);
            result
        })
        .collect();
    let mut cells = Vec::new();
    let mut report = Vec::with_capacity(results.len());
    for (r, cell) in results {
        report.push(r);
        cells.extend(cell);
    }
    Ok(LabelMeshing { tissue: Tissue::from_cells(cells)?, report, l_min })
}

fn mesh_one(
    volume: &LabelVolume,
    info: &LabelInfo,
    options: &LabelMeshingOptions,
    skip: Option<String>,
    l_min: Option<Real>,
) -> (LabelReport, Option<Cell>) {
    let touches_border = info.touches_border(volume.shape());
    let mut report = LabelReport {
        label: info.label,
        status: LabelStatus::Dropped,
        reason: None,
        kind: None,
        nodes: 0,
        faces: 0,
        volume: None,
        voxel_volume: info.voxels as Real * volume.voxel_volume(),
        voxels: info.voxels,
        touches_border,
        dropped_voxels: 0,
    };
    if let Some(reason) = skip {
        report.reason = Some(reason);
        return (report, None);
    }
    let Some(l_min) = l_min else {
        // Unreachable in practice: l_min is only missing when no label is meshed.
        report.reason = Some("no l_min could be chosen".into());
        return (report, None);
    };
    let mask = volume.mask_of(info, MASK_MARGIN);
    let mut settings = MeshingSettings::new(l_min, volume.voxel_size());
    settings.seed = label_seed(options.seed, info.label);
    let meshed: Result<MeshedCell, MeshingError> = mesh_mask(mask.mask.view(), mask.voxel_size, mask.origin, &settings);
    match meshed {
        Err(e) => {
            report.reason = Some(format!("meshing failed: {e}"));
            (report, None)
        }
        Ok(m) => {
            let kind = if options.lumen_labels.contains(&info.label) {
                CellKind::Lumen
            } else if options.border == BorderPolicy::Static && touches_border {
                CellKind::Static
            } else {
                CellKind::Epithelial
            };
            report.status = if kind == CellKind::Static { LabelStatus::Static } else { LabelStatus::Kept };
            if kind == CellKind::Static {
                report.reason = Some("touches the image border (--border static)".into());
            }
            report.kind = Some(kind);
            report.nodes = m.mesh.node_count();
            report.faces = m.mesh.face_count();
            report.volume = Some(m.mesh.signed_volume());
            report.voxel_volume = m.voxel_volume;
            report.dropped_voxels = m.dropped_voxels;
            let cell = Cell::new(CellId(info.label), kind, 0, m.mesh);
            (report, Some(cell))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn label_seeds_differ_between_labels_and_seeds() {
        let a = label_seed(0, 1);
        assert_ne!(a, label_seed(0, 2));
        assert_ne!(a, label_seed(1, 1));
        assert_eq!(a, label_seed(0, 1));
    }

    #[test]
    fn border_policies_parse_by_name() {
        for p in BorderPolicy::ALL {
            assert_eq!(p.name().parse::<BorderPolicy>(), Ok(p));
        }
        assert!("fixed".parse::<BorderPolicy>().is_err());
    }
}

//! Re-triangulating a tissue read from a file (typically a multi-material mesh from an image tool,
//! whose cells share seams that are often non-manifold, with triangles far from [l_min, 3·l_min]):
//! every cell is voxelised on one grid of voxel edge l_min / [`VOXELS_PER_L_MIN`] and the label volume
//! is meshed by [`mesh_labels`] exactly like a segmentation.
//!
//! Voxelisation decides inside/outside per voxel centre by ray parity, so small defects of the input
//! (a non-manifold edge, a sliver, inconsistent winding) do not matter, and every new surface is
//! closed, manifold and genus 0 by construction. Neighbours that share a seam in the input get
//! abutting voxel sets and so surfaces about one voxel (l_min/2) apart or touching.
//!
//! Kinds are kept: a lumen stays a lumen (passed as a lumen label), a static cell static. An ECM (a
//! shell enclosing the tissue) cannot be a filled voxel mask and is refused.
//! Nuclei are voxelised before the other cells, so their voxels are theirs; the host's mask then has a
//! cavity, which meshing fills, so the host's new surface encloses the nucleus as before.
//! Cell ids are kept (they are the labels).

use super::{LabelMeshing, LabelMeshingError, LabelMeshingOptions, default_l_min, mesh_labels};
use crate::geometry::{Real, bounding_box};
use crate::imaging::{ImagingError, LabelVolume, VoxelGrid, voxelize_with_stats};
use crate::mesh::{CellKind, Tissue, TissueError};

/// Voxels per l_min of the intermediate grid: 2 keeps a cell of the default resolution (~400 nodes)
/// about 27 voxels across, enough for its volume within ~2 % (module doc of `meshing`), and the
/// grid small (a few ×10⁴ voxels per cell).
pub const VOXELS_PER_L_MIN: Real = 2.0;

/// Errors of re-triangulating a tissue.
#[derive(Debug, thiserror::Error)]
pub enum RetriangulateError {
    #[error("the tissue has no cell with a positive volume to choose l_min from")]
    NoVolume,
    #[error("cell {cell} is an ECM (an enclosing shell), which cannot be re-triangulated from voxels; remove it first")]
    Ecm { cell: u32 },
    #[error("voxelising the tissue: {0}")]
    Voxelize(#[from] ImagingError),
    #[error(transparent)]
    Meshing(#[from] LabelMeshingError),
    #[error(transparent)]
    Tissue(#[from] TissueError),
}

/// A re-triangulated tissue and the intermediate voxelisation.
#[derive(Debug)]
pub struct Retriangulation {
    /// The meshing of the voxelised tissue (report per input cell id).
    pub meshing: LabelMeshing,
    /// The grid the cells were voxelised on.
    pub grid: VoxelGrid,
    /// Rows where a cell's surface was crossed an odd number of times (an open input surface; the
    /// parity there may be wrong).
    pub odd_rows: u64,
    /// Voxels claimed by more than one input cell (overlapping input cells; the earlier cell keeps them).
    pub overlapping_voxels: u64,
}

/// Re-triangulates every cell of `tissue` (see the module doc). `options.l_min` (m) or, when `None`,
/// [`default_l_min`] of the median cell volume sets the resolution; `voxel_size` (m, z,y,x) overrides
/// the grid's voxel size (default l_min / [`VOXELS_PER_L_MIN`] on every axis).
pub fn retriangulate(
    tissue: &Tissue,
    options: &LabelMeshingOptions,
    voxel_size: Option<[Real; 3]>,
) -> Result<Retriangulation, RetriangulateError> {
    let l_min = match options.l_min {
        Some(l) => l,
        None => {
            let mut volumes: Vec<Real> = tissue
                .cells()
                .iter()
                .filter(|c| c.kind() != CellKind::Nucleus && c.kind() != CellKind::Ecm)
                .map(|c| c.mesh().signed_volume().abs())
                .filter(|v| v.is_finite() && *v > 0.0)
                .collect();
            volumes.sort_by(Real::total_cmp);
            let median = volumes.get(volumes.len() / 2).copied().ok_or(RetriangulateError::NoVolume)?;
            default_l_min(median, options.target_nodes).ok_or(RetriangulateError::NoVolume)?
        }
    };
    if let Some(ecm) = tissue.cells().iter().find(|c| c.kind() == CellKind::Ecm) {
        return Err(RetriangulateError::Ecm { cell: ecm.id().0 });
    }
    if !(l_min.is_finite() && l_min > 0.0) {
        return Err(LabelMeshingError::InvalidLMin { l_min }.into());
    }
    let voxel_size = voxel_size.unwrap_or([l_min / VOXELS_PER_L_MIN; 3]);
    let all: Vec<_> = tissue.cells().iter().flat_map(|c| c.mesh().positions().iter().copied()).collect();
    let (lo, hi) = bounding_box(&all).ok_or(RetriangulateError::NoVolume)?;
    let grid = VoxelGrid::covering(lo, hi, voxel_size, super::MASK_MARGIN)?;
    // Nuclei first: voxelisation gives a voxel claimed by two cells to the earlier one.
    let mut ordered: Vec<_> = tissue.cells().iter().filter(|c| c.kind() == CellKind::Nucleus).cloned().collect();
    ordered.extend(tissue.cells().iter().filter(|c| c.kind() != CellKind::Nucleus).cloned());
    let (volume, stats): (LabelVolume, _) = voxelize_with_stats(&Tissue::from_cells(ordered)?, &grid)?;
    let mut label_options = options.clone();
    label_options.l_min = Some(l_min);
    label_options.lumen_labels.extend(tissue.cells().iter().filter(|c| c.kind() == CellKind::Lumen).map(|c| c.id().0));
    let mut meshing = mesh_labels(&volume, &label_options)?;
    // Restore the input kinds (and cell types) by id.
    let mut cells = meshing.tissue.cells().to_vec();
    for cell in &mut cells {
        if let Some(old) = tissue.cell(cell.id()) {
            let volume = cell.mesh().signed_volume();
            *cell = crate::mesh::Cell::new(cell.id(), old.kind(), old.cell_type(), cell.mesh().clone())
                .with_target_volume(volume)
                .with_overrides(*old.overrides());
        }
    }
    for r in &mut meshing.report {
        if let Some(old) = tissue.cell(crate::mesh::CellId(r.label))
            && r.kind.is_some()
        {
            r.kind = Some(old.kind());
            if old.kind() == CellKind::Static {
                r.status = super::LabelStatus::Static;
            }
        }
    }
    meshing.tissue = Tissue::from_cells(cells)?;
    Ok(Retriangulation { meshing, grid, odd_rows: stats.odd_rows, overlapping_voxels: stats.overlapping_voxels })
}

//! Shape agreement between two tissues, cell by cell: the intersection over union (IoU) of the voxels
//! each cell fills on a common grid, and the deformation χ = 1 − IoU (DESIGN.md §4). Cells are
//! matched by id (= label). This is the shape term of a fit: voxelise the simulated tissue on the
//! segmentation's grid and compare ([`compare_shapes`]).
//!
//! Only cells (epithelial, static) and lumen bodies are voxelised: an ECM body encloses the tissue and
//! a nucleus lies inside its cell, so rasterising them would take voxels from the cells. Counting is
//! [`crate::imaging::label_overlap`]; voxelisation is [`crate::imaging::voxelize`] (a voxel belongs to
//! a cell when its centre is inside), both independent of the thread count.

use super::{Morphology, MorphologyError, MorphologySummary};
use crate::geometry::{Real, Vec3};
use crate::imaging::{LabelOverlap, LabelVolume, VoxelGrid, label_overlap, voxelize};
use crate::mesh::{CellKind, Tissue};
use std::collections::HashMap;

fn imaging(e: crate::imaging::ImagingError) -> MorphologyError {
    MorphologyError::Comparison { reason: e.to_string() }
}

/// The bodies of `tissue` that have a shape to compare (cells and lumens).
fn shape_bodies(tissue: &Tissue) -> Result<Tissue, MorphologyError> {
    let cells = tissue.cells().iter().filter(|c| c.kind().is_cell() || c.kind() == CellKind::Lumen).cloned().collect();
    Tissue::from_cells(cells).map_err(|e| MorphologyError::Comparison { reason: e.to_string() })
}

/// Per-label overlap of `tissue`'s cells (voxelised on `labels`' grid, labels = cell ids) with the label
/// volume `labels`, for every label found in either, ascending. `voxels_a` counts the label volume,
/// `voxels_b` the tissue. [`LabelOverlap::iou`] and [`LabelOverlap::chi`] give IoU and χ.
pub fn compare_shapes(tissue: &Tissue, labels: &LabelVolume) -> Result<Vec<LabelOverlap>, MorphologyError> {
    let rasterised = voxelize(&shape_bodies(tissue)?, &labels.grid()).map_err(imaging)?;
    label_overlap(labels, &rasterised).map_err(imaging)
}

/// Per-label overlap of two tissues voxelised on a common grid of voxel size `voxel_size` (z, y, x m)
/// covering both (one empty voxel around them). `voxels_a` counts `a`, `voxels_b` counts `b`.
pub fn compare_tissues(a: &Tissue, b: &Tissue, voxel_size: [Real; 3]) -> Result<Vec<LabelOverlap>, MorphologyError> {
    let (a, b) = (shape_bodies(a)?, shape_bodies(b)?);
    let mut lo = Vec3::repeat(Real::INFINITY);
    let mut hi = Vec3::repeat(Real::NEG_INFINITY);
    for p in a.cells().iter().chain(b.cells()).flat_map(|c| c.mesh().positions()) {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    if !(lo.iter().all(|x| x.is_finite()) && hi.iter().all(|x| x.is_finite())) {
        return Err(MorphologyError::Comparison { reason: "the tissues have no finite node positions".into() });
    }
    let grid = VoxelGrid::covering(lo, hi, voxel_size, 1).map_err(imaging)?;
    let va = voxelize(&a, &grid).map_err(imaging)?;
    let vb = voxelize(&b, &grid).map_err(imaging)?;
    label_overlap(&va, &vb).map_err(imaging)
}

impl Morphology {
    /// Writes each row's `iou` and `chi` from the overlap of its label (rows without a label in
    /// `overlaps` keep none) and recomputes the summary, whose `mean_chi` then averages the counted
    /// cells that were compared.
    pub fn set_overlap(&mut self, overlaps: &[LabelOverlap]) {
        let by_label: HashMap<u32, &LabelOverlap> = overlaps.iter().map(|o| (o.label, o)).collect();
        for row in &mut self.cells {
            let o = by_label.get(&row.cell);
            row.iou = o.map(|o| o.iou());
            row.chi = o.map(|o| o.chi());
        }
        let s = &self.summary;
        self.summary = MorphologySummary::from_rows(
            &self.cells,
            &self.contacts,
            s.contact_rule,
            s.contact_distance,
            s.include_static,
            s.exterior_rule,
        );
    }
}

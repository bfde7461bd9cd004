//! Laplace target volumes: V0 of a cell whose type asks for it balances its tension as a free sphere.

use super::SimulationError;
use crate::mechanics::CellTypeParams;
use crate::mesh::Tissue;

/// Sets the target volume of every cell whose type has `laplace_target_volume` to the one that
/// balances its tension as a free sphere of its current volume ([`CellTypeParams::laplace_volume`]).
pub(super) fn set_laplace_target_volumes(
    tissue: &mut Tissue,
    cell_params: &[CellTypeParams],
) -> Result<(), SimulationError> {
    for (cell, p) in tissue.cells_mut().iter_mut().zip(cell_params) {
        if !p.laplace_target_volume {
            continue;
        }
        let v0 = p.laplace_volume(cell.mesh().signed_volume(), p.mean_tension(cell)).map_err(|pressure| {
            SimulationError::LaplaceUnbalanced { cell: cell.id(), pressure, max_pressure: p.max_pressure }
        })?;
        cell.set_target_volume(v0);
    }
    Ok(())
}

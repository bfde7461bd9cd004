//! The scratch of a running simulation, kept apart from its state (rapier's pipeline/state split):
//! the force evaluation's buffers and caches, rebuilt from the state and never saved whole.

use super::state::CellForcesState;
use crate::mechanics::{CellForces, ContactWorkspace, CoupledPair, CouplingWorkspace, Numerics, TissueForces};
use crate::mesh::Cell;

/// The buffers and caches of the force evaluation, reused across steps. Of the last evaluation, a
/// checkpoint keeps only what a restored run cannot recompute without evaluating again (which would
/// change its results): each cell's forces, pressure and energies ([`CellForcesState`]) and the
/// coupling ties. The cells' geometry is recomputed from the positions, exactly, and the contact
/// stage (grid, pairs) is rebuilt at the next evaluation.
pub(super) struct Workspace {
    /// Forces, pressures, energies and geometry of every cell at the last evaluation, in tissue order.
    pub(super) forces: TissueForces,
    pub(super) contacts: ContactWorkspace,
    pub(super) coupling: CouplingWorkspace,
}

impl Workspace {
    /// An empty workspace for the contact model and quadrature of `numerics`.
    pub(super) fn new(numerics: &Numerics) -> Self {
        let mut contacts = ContactWorkspace::default();
        contacts.set_model(numerics.contact_model);
        contacts.set_quadrature(numerics.contact_quadrature);
        Self { forces: TissueForces::default(), contacts, coupling: CouplingWorkspace::default() }
    }

    /// A workspace holding a saved evaluation of `cells` (aligned with `forces`, whose lengths the
    /// caller checked) and its coupling ties.
    pub(super) fn restore(
        numerics: &Numerics,
        cells: &[Cell],
        forces: Vec<CellForcesState>,
        coupled: Vec<((u32, u32), (u32, u32))>,
    ) -> Self {
        let mut work = Self::new(numerics);
        for (cell, fs) in cells.iter().zip(forces) {
            let mut w = CellForces::default();
            w.geometry.update(cell.mesh());
            w.forces = fs.forces;
            w.pressure = fs.pressure;
            w.energy = fs.energy;
            work.forces.cells.push(w);
        }
        work.coupling.restore_pairs(coupled.into_iter().map(|(a, b)| CoupledPair { a, b }).collect());
        work
    }

    /// What a checkpoint keeps of the last evaluation: every cell's forces, pressure and energies.
    pub(super) fn saved_forces(&self) -> Vec<CellForcesState> {
        self.forces
            .cells
            .iter()
            .map(|w| CellForcesState { forces: w.forces.clone(), pressure: w.pressure, energy: w.energy })
            .collect()
    }

    /// The coupling ties as a checkpoint keeps them: (cell, node) of each side.
    pub(super) fn saved_ties(&self) -> Vec<((u32, u32), (u32, u32))> {
        self.coupling.pairs().iter().map(|p| (p.a, p.b)).collect()
    }
}

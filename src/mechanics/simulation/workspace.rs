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
    /// Where the run's time went (this session; a checkpoint does not keep it).
    pub(super) times: StageTimes,
}

/// Wall time (s) spent so far in each stage of a run's force evaluations and remeshing, this
/// session (not kept by checkpoints): what `tissuefit bench relax` reports per node-step. The rest
/// of a run's time is moving the nodes (FIRE or integration), residuals and bookkeeping.
#[derive(Clone, Copy, Debug, Default)]
pub struct StageTimes {
    /// Node coupling (coupling contacts only): snapping tied pairs, new ties.
    pub coupling: f64,
    /// Internal forces and cell geometry (pressure, tension, area elasticity, bending).
    pub internal: f64,
    /// Contact broad phase: topology caches, face boxes, candidate lists (includes `contact_lists`).
    pub contact_broad: f64,
    /// Of `contact_broad`: rebuilding the candidate lists.
    pub contact_lists: f64,
    /// Contact narrow phase: each node's closest faces, signs, pair records.
    pub contact_narrow: f64,
    /// Applying the contact forces.
    pub contact_apply: f64,
    /// Ray-casting polarity and polarity from contacts.
    pub polarity: f64,
    /// Remeshing (scheduled passes and out-of-turn repairs), without the force evaluations it asks
    /// for (those are in their stages).
    pub remeshing: f64,
}

impl StageTimes {
    /// The contact stage's part of [`Self::total`].
    pub fn contacts(&self) -> f64 {
        self.contact_broad + self.contact_narrow + self.contact_apply
    }

    /// The time of the force evaluations.
    pub fn evaluation(&self) -> f64 {
        self.coupling + self.internal + self.contacts() + self.polarity
    }

    /// The time of all stages.
    pub fn total(&self) -> f64 {
        self.evaluation() + self.remeshing
    }

    /// Adds the time since `started` to `remeshing`, less the force evaluations in it (counted in
    /// their own stages since `evaluation_before`, their total then).
    pub(super) fn add_remeshing(&mut self, started: std::time::Instant, evaluation_before: f64) {
        let nested = self.evaluation() - evaluation_before;
        self.remeshing += (started.elapsed().as_secs_f64() - nested).max(0.0);
    }
}

impl Workspace {
    /// An empty workspace for the contact model and quadrature of `numerics`.
    pub(super) fn new(numerics: &Numerics) -> Self {
        let mut contacts = ContactWorkspace::default();
        contacts.set_model(numerics.contact_model);
        contacts.set_quadrature(numerics.contact_quadrature);
        Self {
            forces: TissueForces::default(),
            contacts,
            coupling: CouplingWorkspace::default(),
            times: StageTimes::default(),
        }
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
        work.coupling.restore_pairs(coupled.into_iter().map(|(a, b)| CoupledPair { a, b }).collect(), cells);
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

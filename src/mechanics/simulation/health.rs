//! Health checks: after every force evaluation, a non-finite position or force or a cell whose
//! volume is not positive stops the run with [`SimulationError::Unhealthy`], naming the cell, the
//! step, the force term and what to change, and carrying the last good state.

use super::{Simulation, SimulationError};
use crate::mechanics::CellForces;
use crate::mechanics::forces::{CellTerm, TermSet};
use crate::mesh::Tissue;

/// The last healthy state of a failed run (its `Debug` is a one-line summary, not the meshes).
pub struct LastGood(pub Box<Tissue>);

impl std::fmt::Debug for LastGood {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "LastGood({} cells, {} nodes)", self.0.len(), self.0.node_count())
    }
}

impl std::ops::Deref for LastGood {
    type Target = Tissue;
    fn deref(&self) -> &Tissue {
        &self.0
    }
}

const HINT: &str = "Use a smaller numerics.time_step or a larger numerics.damping (`tissuefit config check` \
                    estimates the stable step)";

impl<'p> Simulation<'p> {
    /// The health check after an evaluation: the first cell with a non-finite position, a volume
    /// that is not positive or a non-finite force stops the run.
    ///
    /// Positions and volumes of every cell are checked before any force: a cell that collapsed
    /// (volume ≤ 0) gives itself a non-finite pressure force, which coupled contacts then share with
    /// the nodes of its neighbours, so the first cell with a non-finite force need not be the one
    /// that broke down (on the PlantSeg ovule crop a thin cut cell collapsed and the error blamed
    /// the contact term of a neighbour).
    pub(super) fn check_health(&self) -> Result<(), SimulationError> {
        let cells = self.tissue.cells().iter().zip(&self.work.forces.cells).enumerate();
        for (c, (cell, work)) in cells.clone() {
            let problem = if let Some(n) = cell.mesh().positions().iter().position(|p| !p.iter().all(|v| v.is_finite()))
            {
                Some(format!("node {n} has a non-finite position (the update diverged)"))
            } else if work.geometry.volume.is_nan() || work.geometry.volume <= 0.0 {
                Some(format!(
                    "the volume turned {} ({:e} m³): the surface folded through itself or the cell was squeezed flat",
                    if work.geometry.volume.is_nan() { "NaN" } else { "non-positive" },
                    work.geometry.volume
                ))
            } else {
                None
            };
            if let Some(what) = problem {
                return Err(self.unhealthy(c, what));
            }
        }
        // A cell whose own terms are non-finite is the origin; else the first cell with a
        // non-finite force got it from the contacts (or their coupling).
        let bad: Vec<usize> = cells.filter(|(_, (_, work))| !work.all_finite()).map(|(c, _)| c).collect();
        if let Some(&first) = bad.first() {
            let (c, term) = bad.iter().find_map(|&c| self.own_culprit(c).map(|t| (c, t))).unwrap_or((first, "contact"));
            return Err(self.unhealthy(c, format!("non-finite force from the {term} term")));
        }
        Ok(())
    }

    /// The first of cell `c`'s own force terms that is non-finite, if any.
    fn own_culprit(&self, c: usize) -> Option<&'static str> {
        let cell = &self.tissue.cells()[c];
        CellTerm::ALL.into_iter().find_map(|term| {
            let mut work = CellForces::default();
            work.compute(cell, &self.cell_params[c], TermSet::only(term));
            (!work.all_finite() || !work.energy.total().is_finite()).then(|| term.name())
        })
    }

    /// What to change when cell `c` breaks down: its adhesion when a face type's spring-contact
    /// adhesion energy reaches its tension (the surface then crumples whatever the step), else the
    /// time step or damping.
    fn hint(&self, c: usize) -> String {
        let cutoff = self.params.numerics.contact_cutoff;
        let cell_type = self.tissue.cells()[c].cell_type();
        let p = &self.cell_params[c];
        match p.faces.iter().find(|(_, f)| f.adhesion_outweighs_tension(cutoff)) {
            Some((face_type, f)) => format!(
                "Its type {:?} has adhesion energy ωc²/4 = {:.3e} J/m² on {} faces (ω = {:e} Pa/m, \
                 c = numerics.contact_cutoff = {:e} m), {:.2} × their surface tension γ = {:e} N/m: adhesion acts \
                 as a negative tension on contact faces, which crumple at any time step once it reaches γ; lower \
                 cell_types[{cell_type}].faces.{}.adhesion below {:.3e} Pa/m or lower numerics.contact_cutoff",
                p.name,
                f.adhesion_well_depth(cutoff),
                face_type.name(),
                f.adhesion,
                cutoff,
                f.adhesion_well_depth(cutoff) / f.surface_tension,
                f.surface_tension,
                face_type.name(),
                f.max_adhesion(cutoff)
            ),
            None => HINT.to_owned(),
        }
    }

    fn unhealthy(&self, c: usize, what: String) -> SimulationError {
        let mut last_good = self.tissue.clone();
        // The saved positions follow divisions and removals; cells whose mesh changed since the save
        // (remeshed) keep their current positions.
        for (cell, saved) in last_good.cells_mut().iter_mut().zip(&self.cell_data.last_good) {
            if cell.mesh().node_count() == saved.len() {
                cell.positions_mut().copy_from_slice(saved);
            }
        }
        SimulationError::Unhealthy {
            step: self.progress.step,
            cell: self.tissue.cells()[c].id(),
            what,
            hint: self.hint(c),
            last_good: LastGood(Box::new(last_good)),
        }
    }

    pub(super) fn save_good(&mut self) {
        self.cell_data.last_good.resize_with(self.tissue.len(), Vec::new);
        for (saved, cell) in self.cell_data.last_good.iter_mut().zip(self.tissue.cells()) {
            saved.clear();
            saved.extend_from_slice(cell.mesh().positions());
        }
    }
}

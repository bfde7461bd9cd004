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
    pub(super) fn check_health(&self) -> Result<(), SimulationError> {
        for (c, (cell, work)) in self.tissue.cells().iter().zip(&self.work.forces.cells).enumerate() {
            let problem = if let Some(n) = cell.mesh().positions().iter().position(|p| !p.iter().all(|v| v.is_finite()))
            {
                Some(format!("node {n} has a non-finite position (the update diverged)"))
            } else if work.geometry.volume.is_nan() || work.geometry.volume <= 0.0 {
                Some(format!(
                    "the volume turned {} ({:e} m³): the surface folded through itself",
                    if work.geometry.volume.is_nan() { "NaN" } else { "non-positive" },
                    work.geometry.volume
                ))
            } else if !work.all_finite() {
                Some(format!("non-finite force from the {} term", self.culprit(c)))
            } else {
                None
            };
            if let Some(what) = problem {
                return Err(self.unhealthy(c, what));
            }
        }
        Ok(())
    }

    /// The first force term that is non-finite for cell `c`.
    fn culprit(&self, c: usize) -> &'static str {
        let cell = &self.tissue.cells()[c];
        for term in CellTerm::ALL {
            let mut work = CellForces::default();
            work.compute(cell, self.cell_params[c], TermSet::only(term));
            if !work.all_finite() || !work.energy.total().is_finite() {
                return term.name();
            }
        }
        "contact"
    }

    /// What to change when cell `c` breaks down: its adhesion when a face type's spring-contact
    /// adhesion energy reaches its tension (the surface then crumples whatever the step), else the
    /// time step or damping.
    fn hint(&self, c: usize) -> String {
        let cutoff = self.params.numerics.contact_cutoff;
        let cell_type = self.tissue.cells()[c].cell_type();
        let p = self.cell_params[c];
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

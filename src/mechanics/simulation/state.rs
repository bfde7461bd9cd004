//! The serialisable state of a running simulation ([`SimulationState`], what a checkpoint saves)
//! and the round trip: building it from a simulation, and restoring a simulation from it so that the
//! run continues bitwise as if it had never stopped.

use super::{CheckpointRequest, Observer, Simulation, SimulationError, TopologyEvent, TopologyStats};
use crate::geometry::{Real, Vec3};
use crate::mechanics::forces::cell_parameters;
use crate::mechanics::{CellForces, ContactWorkspace, CouplingWorkspace, EnergyTerms, Fire, Parameters, TissueForces};
use crate::mesh::{Cell, CellId, FaceType, Tissue};
use serde::{Deserialize, Serialize};

/// One cell of a saved state: identity, kind, mesh and face types, target volume, lineage.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CellState {
    pub id: CellId,
    pub kind: crate::mesh::CellKind,
    pub cell_type: u32,
    pub parent: Option<CellId>,
    /// V0 (m³).
    pub target_volume: Real,
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    pub face_types: Vec<FaceType>,
}

/// The forces, pressure and energies of one cell at the last evaluation (the geometry is recomputed
/// from the positions on restore, exactly).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CellForcesState {
    pub forces: Vec<Vec3>,
    pub pressure: Real,
    /// Energies (J); encoded as the five numbers in [`EnergyTerms::NAMES`] order, as the array of
    /// format 5 was.
    pub energy: EnergyTerms,
}

/// Where in its loop the driver was saved.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub enum Phase {
    /// Relaxation to equilibrium. `fire`: the minimiser (None: integrating, by choice or after a
    /// stall); `best`: the lowest-residual state since the last remeshing; `previous`: energy and
    /// volumes of the step before (convergence history).
    Relax { fire: Option<Box<Fire>>, best: Option<Box<BestState>>, previous: Option<(Real, Vec<Real>)>, residual: Real },
    /// Time run with growth.
    Time { residual: Real },
}

/// The lowest-residual state of a relaxation, kept to end a run that does not converge at its best
/// state rather than wherever its last step left it.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct BestState {
    pub residual: Real,
    /// Total energy (J) of the state.
    pub energy: Real,
    pub step: u64,
    pub cells: Vec<CellState>,
}

/// Everything a running simulation holds that influences its results: restoring it with
/// [`Simulation::restore`] continues the run bitwise as if it had never stopped (same seed and
/// threads). Caches that only affect speed (contact grid, hinges) are rebuilt.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SimulationState {
    pub cells: Vec<CellState>,
    /// The next fresh cell id (ids of dead cells are never reused).
    pub next_id: CellId,
    pub momenta: Vec<Vec<Vec3>>,
    pub growth_rates: Vec<Real>,
    pub division_volumes: Vec<Real>,
    pub remesh_idle: Vec<u32>,
    pub last_good: Vec<Vec<Vec3>>,
    pub forces: Vec<CellForcesState>,
    /// Node pairs tied by the coupling model at the last evaluation: (cell, node) of each side.
    pub coupled: Vec<((u32, u32), (u32, u32))>,
    pub events: Vec<TopologyEvent>,
    pub topology: TopologyStats,
    pub node_evaluations: u64,
    pub force_scale: Real,
    pub energy_scale: Real,
    pub time: Real,
    pub step: u64,
    pub force_evaluations: u64,
    pub phase: Phase,
}

/// The cell a [`CellState`] describes.
fn cell_from_state(cs: CellState) -> Result<Cell, String> {
    let mesh = crate::mesh::CellMesh::from_triangles(cs.positions, cs.triangles)
        .map_err(|e| format!("cell {}: {e}", cs.id))?;
    let mut cell = Cell::new(cs.id, cs.kind, cs.cell_type, mesh)
        .with_face_types(cs.face_types)
        .map_err(|e| e.to_string())?
        .with_target_volume(cs.target_volume);
    if let Some(p) = cs.parent {
        cell = cell.with_parent(p);
    }
    Ok(cell)
}

impl<'p> Simulation<'p> {
    pub(super) fn cell_states(&self) -> Vec<CellState> {
        self.tissue
            .cells()
            .iter()
            .map(|c| CellState {
                id: c.id(),
                kind: c.kind(),
                cell_type: c.cell_type(),
                parent: c.parent(),
                target_volume: c.target_volume(),
                positions: c.mesh().positions().to_vec(),
                triangles: c.mesh().triangles().to_vec(),
                face_types: c.face_types().to_vec(),
            })
            .collect()
    }

    fn snapshot(&self, phase: Phase) -> SimulationState {
        let cells = self.cell_states();
        let forces = self
            .forces
            .cells
            .iter()
            .map(|w| CellForcesState { forces: w.forces.clone(), pressure: w.pressure, energy: w.energy })
            .collect();
        SimulationState {
            cells,
            next_id: self.tissue.next_id(),
            momenta: self.momenta.clone(),
            growth_rates: self.growth_rates.clone(),
            division_volumes: self.division_volumes.clone(),
            remesh_idle: self.remesh_idle.clone(),
            last_good: self.last_good.clone(),
            forces,
            coupled: self.coupling.pairs().iter().map(|p| (p.a, p.b)).collect(),
            events: self.events.clone(),
            topology: self.topology,
            node_evaluations: self.node_evaluations,
            force_scale: self.force_scale,
            energy_scale: self.energy_scale,
            time: self.time,
            step: self.step,
            force_evaluations: self.force_evaluations,
            phase,
        }
    }

    /// Rebuilds a simulation from a saved state; [`Self::run`] then continues where it stopped.
    /// `params` must be the parameters of the saved run.
    pub fn restore(state: SimulationState, params: &'p Parameters) -> Result<Self, SimulationError> {
        let bad = |what: String| SimulationError::BadState(what);
        let n = state.cells.len();
        let per_cell = [
            ("momenta", state.momenta.len()),
            ("growth rates", state.growth_rates.len()),
            ("division volumes", state.division_volumes.len()),
            ("remeshing counters", state.remesh_idle.len()),
            ("forces", state.forces.len()),
        ];
        if let Some((name, len)) = per_cell.iter().find(|(_, len)| *len != n) {
            return Err(bad(format!("{len} {name} for {n} cells")));
        }
        let mut cells = Vec::with_capacity(n);
        let mut forces = TissueForces::default();
        for (c, (cs, fs)) in state.cells.into_iter().zip(state.forces).enumerate() {
            let nodes = cs.positions.len();
            if state.momenta[c].len() != nodes || fs.forces.len() != nodes {
                return Err(bad(format!("cell {}: momenta or forces do not match its {nodes} nodes", cs.id)));
            }
            let cell = cell_from_state(cs).map_err(bad)?;
            let mut work = CellForces::default();
            work.geometry.update(cell.mesh());
            work.forces = fs.forces;
            work.pressure = fs.pressure;
            work.energy = fs.energy;
            forces.cells.push(work);
            cells.push(cell);
        }
        let mut tissue = Tissue::from_cells(cells).map_err(|e| bad(e.to_string()))?;
        tissue.reserve_ids_below(state.next_id);
        let cell_params = cell_parameters(&tissue, params)?;
        let mut contacts = ContactWorkspace::default();
        contacts.set_model(params.numerics.contact_model);
        contacts.set_quadrature(params.numerics.contact_quadrature);
        let mut coupling = CouplingWorkspace::default();
        coupling
            .restore_pairs(state.coupled.into_iter().map(|(a, b)| crate::mechanics::CoupledPair { a, b }).collect());
        if let Phase::Relax { fire: Some(fire), .. } = &state.phase
            && fire.velocities().len() != tissue.node_count()
        {
            return Err(bad(format!(
                "FIRE holds {} velocities for {} nodes",
                fire.velocities().len(),
                tissue.node_count()
            )));
        }
        Ok(Self {
            tissue,
            params,
            cell_params,
            forces,
            contacts,
            coupling,
            momenta: state.momenta,
            growth_rates: state.growth_rates,
            division_volumes: state.division_volumes,
            remesh_idle: state.remesh_idle,
            normal_only: false,
            fire_max_uphill: None,
            fire_contact_masses: None,
            last_good: state.last_good,
            events: state.events,
            topology: state.topology,
            node_evaluations: state.node_evaluations,
            force_scale: state.force_scale,
            energy_scale: state.energy_scale,
            time: state.time,
            step: state.step,
            force_evaluations: state.force_evaluations,
            resume: Some(state.phase),
            polarized_at: None,
            polarity_due: false,
            polarizations: 0,
        })
    }

    /// Asks the observer whether to save now; saves and (on request) stops.
    pub(super) fn maybe_checkpoint(
        &self,
        observer: &mut dyn Observer,
        phase: impl FnOnce() -> Phase,
    ) -> Result<(), SimulationError> {
        let request = observer.checkpoint_due(self.step);
        if request == CheckpointRequest::No {
            return Ok(());
        }
        observer
            .checkpoint(&self.snapshot(phase()))
            .map_err(|source| SimulationError::Observer { step: self.step, source })?;
        if request == CheckpointRequest::SaveAndStop {
            return Err(SimulationError::Interrupted { step: self.step });
        }
        Ok(())
    }

    /// Replaces every cell by a saved one (same cells, possibly other meshes) and re-evaluates.
    pub(super) fn restore_cells(&mut self, cells: Vec<CellState>) -> Result<(), SimulationError> {
        let cells =
            cells.into_iter().map(cell_from_state).collect::<Result<Vec<_>, _>>().map_err(SimulationError::BadState)?;
        if cells.len() != self.tissue.len() {
            return Err(SimulationError::BadState(format!("{} saved cells for {}", cells.len(), self.tissue.len())));
        }
        for (slot, cell) in self.tissue.cells_mut().iter_mut().zip(cells) {
            *slot = cell;
        }
        for (m, cell) in self.momenta.iter_mut().zip(self.tissue.cells()) {
            m.clear();
            m.resize(cell.mesh().node_count(), Vec3::zeros());
        }
        self.save_good();
        self.evaluate()
    }
}

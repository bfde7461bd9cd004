//! The serialisable state of a running simulation ([`SimulationState`], what a checkpoint saves)
//! and the round trip: building it from a simulation, and restoring a simulation from it so that the
//! run continues bitwise as if it had never stopped.

use super::workspace::Workspace;
use super::{CheckpointRequest, Observer, Simulation, SimulationError, TopologyEvent, TopologyStats};
use crate::geometry::{Real, Vec3};
use crate::mechanics::forces::cell_parameters;
use crate::mechanics::{EnergyTerms, Fire, Parameters};
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
    /// The cell's own tensions and adhesions (since checkpoint format 6).
    pub overrides: crate::mesh::CellOverrides,
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
///
/// The nested [`CellData`] and [`RunProgress`] are the simulation's own structs, saved whole; postcard
/// writes a nested struct as its fields in order, so the file holds the same fields in the same order
/// as when they were listed here one by one (checkpoint format 5 did not change).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SimulationState {
    pub cells: Vec<CellState>,
    /// The next fresh cell id (ids of dead cells are never reused).
    pub next_id: CellId,
    pub cell_data: CellData,
    pub forces: Vec<CellForcesState>,
    /// Node pairs tied by the coupling model at the last evaluation: (cell, node) of each side.
    pub coupled: Vec<((u32, u32), (u32, u32))>,
    pub progress: RunProgress,
    pub phase: Phase,
}

/// What the driver keeps for every cell beside its mesh, in tissue order (divisions and removals keep
/// the arrays aligned with the cells).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct CellData {
    /// Momenta of the nodes (kg·m/s; the dynamic model's, zero in the overdamped one).
    pub momenta: Vec<Vec<Vec3>>,
    /// Growth rate (m³/s).
    pub growth_rates: Vec<Real>,
    /// V_max (m³; inf: never divides).
    pub division_volumes: Vec<Real>,
    /// Remeshing passes each cell skips before its next one: a pass that could make no operation
    /// (every out-of-range edge or poor face refused) backs the cell off for
    /// [`REMESH_BACKOFF`](super::remesh::REMESH_BACKOFF) passes instead of rebuilding its working
    /// copy every step for nothing.
    pub remesh_idle: Vec<u32>,
    /// Node positions of the last good state (before the step that is being taken), for
    /// [`SimulationError::Unhealthy`]; empty before the first save and after a topology change it
    /// could not follow.
    pub last_good: Vec<Vec<Vec3>>,
}

/// The clock, counters and topology history of a run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunProgress {
    /// Divisions and removals so far, in the order they happened.
    pub events: Vec<TopologyEvent>,
    pub topology: TopologyStats,
    /// Sum over force evaluations of the number of nodes.
    pub node_evaluations: u64,
    /// γ̄·l_min (N), what residuals are measured in; fixed at the start.
    pub force_scale: Real,
    /// γ̄·A (J), what energy changes are measured against; fixed at the start.
    pub energy_scale: Real,
    /// Simulated time (s).
    pub time: Real,
    pub step: u64,
    pub force_evaluations: u64,
}

/// The cell a [`CellState`] describes.
fn cell_from_state(cs: CellState) -> Result<Cell, String> {
    let mesh = crate::mesh::CellMesh::from_triangles(cs.positions, cs.triangles)
        .map_err(|e| format!("cell {}: {e}", cs.id))?;
    let mut cell = Cell::new(cs.id, cs.kind, cs.cell_type, mesh)
        .with_face_types(cs.face_types)
        .map_err(|e| e.to_string())?
        .with_target_volume(cs.target_volume)
        .with_overrides(cs.overrides);
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
                overrides: *c.overrides(),
            })
            .collect()
    }

    /// The state to save: the tissue's cells, the simulation's own state structs whole, and what the
    /// workspace keeps of the last evaluation.
    fn snapshot(&self, phase: Phase) -> SimulationState {
        SimulationState {
            cells: self.cell_states(),
            next_id: self.tissue.next_id(),
            cell_data: self.cell_data.clone(),
            forces: self.work.saved_forces(),
            coupled: self.work.saved_ties(),
            progress: self.progress.clone(),
            phase,
        }
    }

    /// Rebuilds a simulation from a saved state; [`Self::run`] then continues where it stopped.
    /// `params` must be the parameters of the saved run.
    pub fn restore(state: SimulationState, params: &'p Parameters) -> Result<Self, SimulationError> {
        let bad = |what: String| SimulationError::BadState(what);
        let n = state.cells.len();
        let data = &state.cell_data;
        let per_cell = [
            ("momenta", data.momenta.len()),
            ("growth rates", data.growth_rates.len()),
            ("division volumes", data.division_volumes.len()),
            ("remeshing counters", data.remesh_idle.len()),
            ("forces", state.forces.len()),
        ];
        if let Some((name, len)) = per_cell.iter().find(|(_, len)| *len != n) {
            return Err(bad(format!("{len} {name} for {n} cells")));
        }
        let mut cells = Vec::with_capacity(n);
        for (c, (cs, fs)) in state.cells.into_iter().zip(&state.forces).enumerate() {
            let nodes = cs.positions.len();
            if data.momenta[c].len() != nodes || fs.forces.len() != nodes {
                return Err(bad(format!("cell {}: momenta or forces do not match its {nodes} nodes", cs.id)));
            }
            cells.push(cell_from_state(cs).map_err(bad)?);
        }
        let mut tissue = Tissue::from_cells(cells).map_err(|e| bad(e.to_string()))?;
        tissue.reserve_ids_below(state.next_id);
        let cell_params = cell_parameters(&tissue, params)?;
        let work = Workspace::restore(&params.numerics, tissue.cells(), state.forces, state.coupled);
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
            work,
            cell_data: state.cell_data,
            progress: state.progress,
            normal_only: false,
            fire_max_uphill: None,
            fire_contact_masses: None,
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
        let request = observer.checkpoint_due(self.progress.step);
        if request == CheckpointRequest::No {
            return Ok(());
        }
        observer
            .checkpoint(&self.snapshot(phase()))
            .map_err(|source| SimulationError::Observer { step: self.progress.step, source })?;
        if request == CheckpointRequest::SaveAndStop {
            return Err(SimulationError::Interrupted { step: self.progress.step });
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
        for (m, cell) in self.cell_data.momenta.iter_mut().zip(self.tissue.cells()) {
            m.clear();
            m.resize(cell.mesh().node_count(), Vec3::zeros());
        }
        self.save_good();
        self.evaluate()
    }
}

//! The simulation driver: relax a tissue to mechanical equilibrium (FIRE or integration of the
//! equations of motion) or integrate it for a time span with growth; sample it at a fixed period;
//! stop on the equilibrium criterion; and stop with a precise error when the state turns unhealthy.
//!
//! Equilibrium: the largest nodal force of the moving cells is below `force_tolerance`·γ̄·l_min
//! (γ̄: mean surface tension over their faces, the typical tension force per node), the total energy
//! changes by less than `energy_tolerance` of the tension energy scale Σ γ̄·A per step, and no cell
//! volume changes by more than `volume_tolerance` per step.
//!
//! Health: after every force evaluation, a non-finite force, a non-finite position or a cell whose
//! volume is not positive ends the run with a [`SimulationError::Unhealthy`] naming the cell, the
//! step and the force term, and carrying the last good state so the caller can save it.
//!
//! Topology (time runs; paper Methods "Cell division", "Local mesh adaptation"): after every step,
//! a cell whose volume exceeds its division volume V_max (drawn per cell id, see `growth.rs`) divides
//! through its volume centroid with its type's plane rule ([`DivisionPlaneRule`]); the daughters get
//! fresh ids, record their mother as parent, inherit the face types (the cap is lateral), get
//! V0 = the mother's V0 / 2 and their own draws of growth rate and V_max. Inherited nodes keep their
//! momenta, nodes where the plane cut a mother edge take the momentum interpolated along that edge,
//! and cap nodes start at rest (zero momentum), as in the reference program. The first daughter
//! takes the mother's place in the tissue order, the second is appended, so every per-cell array
//! stays aligned and unaffected cells keep their index (and their cached topology). A cut that
//! fails (a plane grazing the surface) is retried with a slightly tilted and shifted plane; if every
//! attempt fails the cell divides at a later step (counted as a failure, never an abort). A cell
//! whose volume falls below V_min of its type (> 0) is removed. Every event is recorded.
//!
//! Remeshing never stops a run for a remeshing reason: illegal operations are skipped and counted,
//! and a pass whose result would not be a valid surface is discarded (the cell keeps its mesh this
//! step, counted as rejected). Only a cell that is topologically broken is an error naming it.
//!
//! Layout: the [`Simulation`] struct, its construction and public API are here; `observer` (what a
//! run shows its caller), `state` (the serialisable state: checkpoints and restoring them),
//! `workspace` (the force evaluation's buffers and caches, rebuilt from the state),
//! `events` (divisions and removals), `evaluation` (force evaluation, polarity, the normal
//! projection), `health` (the checks after each evaluation and the last good state), `laplace`
//! (Laplace target volumes), `equilibrium` (the relaxation loop) and `mover` (FIRE or integration
//! within it), `integration` (time runs with growth), `remesh` (scheduled and out-of-turn
//! remeshing), `division` (division and removal), `overlap` (overlap volumes and the repulsion
//! check).

mod division;
mod equilibrium;
mod evaluation;
mod events;
mod health;
mod integration;
mod laplace;
mod mover;
mod observer;
mod overlap;
mod remesh;
mod state;
#[cfg(test)]
mod tests;
mod workspace;

pub use equilibrium::BEST_ENERGY_SLACK;
pub use events::{TopologyEvent, TopologyEventKind, TopologyStats};
pub use health::LastGood;
pub use observer::{CheckpointRequest, NoObserver, Observer, Sample};
pub use overlap::{
    OVERLAP_WARNING, REPULSION_MARGIN, REPULSION_PER_ADHESION, REPULSION_PER_PRESSURE, derived_repulsion,
};
pub use state::{BestState, CellData, CellForcesState, CellState, Phase, RunProgress, SimulationState};

use super::forces::{TissueForces, UnknownCellType, apply_configured_kinds, cell_parameters};
use super::growth::{draw_division_volumes, draw_growth_rates};
use super::{CellTypeParams, ContactWorkspace, EnergyTerms, Parameters, SimulationMode};
use crate::geometry::{Real, Vec3};
use crate::mesh::remesh::RemeshError;
use crate::mesh::{CellId, FaceType, Tissue};
use laplace::set_laplace_target_volumes;
use serde::Serialize;
pub use workspace::StageTimes;
use workspace::Workspace;

/// How a run ended.
#[derive(Clone, Debug, Serialize)]
pub struct SimulationSummary {
    pub steps: u64,
    pub force_evaluations: u64,
    /// Sum over force evaluations of the number of nodes (for costs per node-step when the node
    /// count changes).
    pub node_evaluations: u64,
    /// Divisions, removals and remeshing counts.
    pub topology: TopologyStats,
    pub converged: bool,
    /// Final largest nodal force over γ̄·l_min.
    pub residual: Real,
    /// Final simulated time (s).
    pub time: Real,
    pub energy: EnergyTerms,
    /// Volume (m³) by which cells overlap at the end, summed over contacts (see
    /// [`Simulation::overlap_volumes`]).
    pub overlap_volume: Real,
    /// Largest overlap of a moving cell with the others, as a fraction of its volume.
    pub max_overlap_fraction: Real,
    /// Why a relaxation stopped without converging (None: converged, or a time run).
    pub stop_reason: Option<String>,
    /// The step whose state the run ended at, when that is not the last step (a relaxation that did
    /// not converge ends at its lowest-residual state).
    pub ended_at_step: Option<u64>,
}

impl SimulationSummary {
    /// A warning when some cell overlaps the others by more than [`OVERLAP_WARNING`] of its volume.
    pub fn overlap_warning(&self) -> Option<String> {
        (self.max_overlap_fraction > OVERLAP_WARNING).then(|| {
            format!(
                "cells overlap by up to {:.2} % of a cell's volume at the end ({:.3e} µm³ in all): the repulsion \
                 (cell_types.faces.repulsion ξ) is too weak for the pressure; raise it",
                100.0 * self.max_overlap_fraction,
                self.overlap_volume * 1e18
            )
        })
    }
}

/// Why a run stopped early.
#[derive(Debug, thiserror::Error)]
pub enum SimulationError {
    #[error(transparent)]
    UnknownCellType(#[from] UnknownCellType),
    #[error(transparent)]
    UnknownOverrideCell(#[from] crate::mechanics::UnknownOverrideCell),
    #[error("the tissue has no moving cell: nothing to simulate")]
    NothingMoves,
    #[error(
        "cell {cell} is not a valid closed surface: {defect}. The model needs closed, outward-oriented, 2-manifold cells; \
         `tissuefit inspect` lists every defect (--orient repairs inconsistent winding)"
    )]
    InvalidCell { cell: CellId, defect: crate::mesh::MeshDefect },
    #[error(
        "the tissue is a 2.5-D cell sheet ({cells} open cell patches of one surface, as an epidermis segmented on its \
         outer wall): the model needs closed 3-D cells. `tissuefit tensions` maps a sheet's wall tensions"
    )]
    Sheet { cells: usize },
    #[error("step {step}, cell {cell}: {what}. {hint}")]
    Unhealthy { step: u64, cell: CellId, what: String, hint: String, last_good: LastGood },
    #[error("step {step}: remeshing failed: {source}")]
    Remesh { step: u64, source: Box<RemeshError> },
    #[error("step {step}: cell {cell}: {what}")]
    Topology { step: u64, cell: CellId, what: String },
    #[error("step {step}: output failed: {source}")]
    Observer { step: u64, source: Box<dyn std::error::Error + Send + Sync> },
    /// The observer asked to stop after saving the state (Ctrl-C).
    #[error("interrupted at step {step}; the state was saved")]
    Interrupted { step: u64 },
    #[error("the saved state is inconsistent: {0}")]
    BadState(String),
    #[error(
        "cell {cell}: laplace_target_volume needs the pressure 2γ̄/R = {pressure:.4e} Pa to balance its tension, above \
         its cell type's max_pressure = {max_pressure:e} Pa (or K = 0); raise max_pressure (inf: no cap) or lower the tension"
    )]
    LaplaceUnbalanced { cell: CellId, pressure: Real, max_pressure: Real },
}

/// Typical tension γ̄ (N/m): the mean surface tension over the faces of moving cells; falls back to
/// the largest tension of any type, then to 1e-3 N/m, so the force scale is never zero.
fn tension_scale(tissue: &Tissue, cell_params: &[CellTypeParams]) -> Real {
    let (mut sum, mut count) = (0.0, 0usize);
    for (cell, p) in tissue.cells().iter().zip(cell_params) {
        if cell.kind().is_immobile() {
            continue;
        }
        for t in cell.face_types() {
            sum += p.faces.get(*t).surface_tension;
            count += 1;
        }
    }
    if count > 0 && sum > 0.0 {
        return sum / count as Real;
    }
    let max =
        cell_params.iter().flat_map(|p| FaceType::ALL.map(|t| p.faces.get(t).surface_tension)).fold(0.0, Real::max);
    if max > 0.0 { max } else { 1e-3 }
}

/// A running simulation: the tissue and the simulation's own state (saved whole by a checkpoint,
/// [`SimulationState`]), the workspace of the force evaluation (rebuilt, see `workspace.rs`), and
/// per-session settings.
pub struct Simulation<'p> {
    tissue: Tissue,
    params: &'p Parameters,
    /// The parameters of every cell's type, in tissue order (derived from the tissue and `params`).
    cell_params: Vec<CellTypeParams>,
    /// Per-cell data beside the meshes (momenta, growth rates, division volumes, remeshing back-off,
    /// the last good positions).
    cell_data: CellData,
    /// Clock, counters and topology history.
    progress: RunProgress,
    /// Force buffers, contact and coupling stages.
    work: Workspace,
    /// A relaxation with `simulation.normal_relaxation`: forces are projected onto the node normals.
    normal_only: bool,
    /// Whether FIRE gives nodes in contact masses along their contact directions
    /// ([`Simulation::contact_masses`]): `None` decides from the parameters
    /// ([`Simulation::contact_masses_pay`]), `Some` is [`Simulation::set_fire_contact_masses`].
    fire_contact_masses: Option<bool>,
    /// Replaces FIRE's N_P≤0^max ([`FireSettings::max_uphill`](super::FireSettings::max_uphill)); set
    /// by tests to make FIRE stall.
    fire_max_uphill: Option<usize>,
    /// Loop state of a restored run, consumed by [`Self::run`].
    resume: Option<Phase>,
    /// Ray-casting polarity: the step of the last polarisation (a step evaluated twice, after
    /// remeshing, is not polarised twice), and whether a division asks for one now. Neither needs
    /// saving: a checkpoint is taken after a step's last evaluation, and divisions are polarised in
    /// their own step.
    polarized_at: Option<u64>,
    polarity_due: bool,
    /// Ray-casting polarisations so far (this session).
    polarizations: u64,
}

impl<'p> Simulation<'p> {
    /// Prepares a simulation; checks that every cell has a parameter set.
    /// Every cell runs as the kind its cell type declares ([`apply_configured_kinds`]; a warning
    /// names each type whose cells changed kind), with the config's `[[cell_overrides]]` laid over
    /// its own tensions and adhesions ([`Parameters::apply_cell_overrides`]; the tissue it hands back
    /// carries them).
    pub fn new(tissue: Tissue, params: &'p Parameters) -> Result<Self, SimulationError> {
        let mut tissue = tissue;
        params.apply_cell_overrides(&mut tissue)?;
        let cell_params = cell_parameters(&tissue, params)?;
        for line in apply_configured_kinds(&mut tissue, params) {
            tracing::warn!("{line}");
        }
        if tissue.cells().iter().all(|c| c.kind().is_immobile()) {
            return Err(SimulationError::NothingMoves);
        }
        if let Some((cell, defect)) = tissue.cells().iter().find_map(|c| c.mesh().validate().err().map(|d| (c.id(), d)))
        {
            if crate::morphology::sheet::is_sheet(&tissue) {
                return Err(SimulationError::Sheet { cells: tissue.len() });
            }
            return Err(SimulationError::InvalidCell { cell, defect });
        }
        set_laplace_target_volumes(&mut tissue, &cell_params)?;
        let gamma = tension_scale(&tissue, &cell_params);
        let growth_rates = draw_growth_rates(&tissue, &cell_params, params.numerics.seed);
        let division_volumes = draw_division_volumes(&tissue, &cell_params, params.numerics.seed);
        let momenta = tissue.cells().iter().map(|c| vec![Vec3::zeros(); c.mesh().node_count()]).collect();
        let energy_scale = gamma * tissue.cells().iter().map(|c| c.mesh().area()).sum::<Real>();
        let cell_data = CellData {
            momenta,
            growth_rates,
            remesh_idle: vec![0; division_volumes.len()],
            division_volumes,
            last_good: Vec::new(),
        };
        let progress = RunProgress {
            events: Vec::new(),
            topology: TopologyStats::default(),
            node_evaluations: 0,
            force_scale: gamma * params.numerics.min_edge_length,
            energy_scale,
            time: 0.0,
            step: 0,
            force_evaluations: 0,
        };
        Ok(Self {
            cell_params,
            cell_data,
            progress,
            work: Workspace::new(&params.numerics),
            normal_only: false,
            fire_max_uphill: None,
            fire_contact_masses: None,
            resume: None,
            polarized_at: None,
            polarity_due: false,
            polarizations: 0,
            tissue,
            params,
        })
    }

    /// Where this session's time went, per stage of the force evaluation and remeshing.
    pub fn stage_times(&self) -> StageTimes {
        self.work.times
    }

    /// The current tissue.
    pub fn tissue(&self) -> &Tissue {
        &self.tissue
    }

    /// Consumes the simulation, returning the tissue.
    pub fn into_tissue(self) -> Tissue {
        self.tissue
    }

    /// The forces of the last evaluation.
    pub fn forces(&self) -> &TissueForces {
        &self.work.forces
    }

    /// Whether FIRE makes nodes in contact heavier along their contact directions (see
    /// [`Simulation::contact_masses`]), overriding the choice from the parameters
    /// ([`Simulation::contact_masses_pay`]): for comparisons and tests.
    pub fn set_fire_contact_masses(&mut self, on: bool) {
        self.fire_contact_masses = Some(on);
    }

    /// The typical tension force γ̄·l_min (N) that residuals are measured in.
    pub fn force_scale(&self) -> Real {
        self.progress.force_scale
    }

    /// Divisions and removals so far, in the order they happened.
    pub fn events(&self) -> &[TopologyEvent] {
        &self.progress.events
    }

    /// Counts of divisions, removals and remeshing so far.
    pub fn topology_stats(&self) -> TopologyStats {
        self.progress.topology
    }

    /// Growth rate of every cell (m³/s), in tissue order.
    pub fn growth_rates(&self) -> &[Real] {
        &self.cell_data.growth_rates
    }

    /// Division volume V_max of every cell (m³), in tissue order.
    pub fn division_volumes(&self) -> &[Real] {
        &self.cell_data.division_volumes
    }

    /// Current simulated time (s) and step.
    pub fn time_and_step(&self) -> (Real, u64) {
        (self.progress.time, self.progress.step)
    }

    /// The contact stage of the last evaluation (which nodes touch which cell, at what distance).
    pub fn contacts(&self) -> &ContactWorkspace {
        &self.work.contacts
    }

    /// The node pairs tied by the coupling contact model at the last evaluation (empty with springs).
    pub fn coupled_pairs(&self) -> &[super::CoupledPair] {
        self.work.coupling.pairs()
    }

    /// The groups of nodes tied by the coupling contact model at the last evaluation, each a list of
    /// (cell, node) (pairs, and three or four nodes at junctions; empty with springs).
    pub fn coupled_groups(&self) -> impl Iterator<Item = &[(u32, u32)]> + '_ {
        self.work.coupling.groups()
    }

    /// Ray-casting polarisations run so far in this session (0 unless `numerics.polarity` is
    /// `"ray_casting"`).
    pub fn polarizations(&self) -> u64 {
        self.polarizations
    }

    /// Runs what `params.simulation` says. Drivers that face a user show
    /// [`Self::repulsion_shortfalls`] before and [`SimulationSummary::overlap_warning`] after (the
    /// fit's forward model does not: it would repeat them at every evaluation).
    pub fn run(&mut self, observer: &mut dyn Observer) -> Result<SimulationSummary, SimulationError> {
        let settings = &self.params.simulation;
        match (settings.mode, settings.method) {
            (SimulationMode::Time, _) => self.run_time(observer),
            (SimulationMode::Equilibrium, method) => self.relax(observer, method),
        }
    }

    fn summary(&self, converged: bool, residual: Real) -> SimulationSummary {
        let overlaps = self.overlap_volumes();
        let max_overlap_fraction = overlaps
            .iter()
            .zip(self.tissue.cells())
            .zip(&self.work.forces.cells)
            .filter(|((_, cell), _)| !cell.kind().is_immobile())
            .map(|((v, _), w)| v / w.geometry.volume)
            .fold(0.0, Real::max);
        SimulationSummary {
            overlap_volume: 0.5 * overlaps.iter().sum::<Real>(),
            max_overlap_fraction,
            stop_reason: None,
            ended_at_step: None,
            steps: self.progress.step,
            force_evaluations: self.progress.force_evaluations,
            node_evaluations: self.progress.node_evaluations,
            topology: self.progress.topology,
            converged,
            residual,
            time: self.progress.time,
            energy: self.work.forces.energy(),
        }
    }
}

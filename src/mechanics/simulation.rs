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

use super::fire::{Fire, FireSettings};
use super::forces::{TermSet, TissueForces, UnknownCellType, cell_parameters};
use super::growth::draw_growth_rates;
use super::motion::integrate_step;
use super::polarity::polarize_from_contacts;
use super::{
    CellForces, CellTypeParams, ContactModel, ContactWorkspace, CouplingWorkspace, EnergyTerms, Parameters, Polarity,
    RelaxMethod, SimulationMode,
};
use crate::geometry::{Real, Vec3};
use crate::mesh::{CellId, FaceType, Tissue};
use serde::Serialize;

/// What the driver shows an observer at each sample.
pub struct Sample<'a> {
    pub step: u64,
    /// Simulated time (s); 0 throughout a FIRE relaxation, which has no physical time.
    pub time: Real,
    pub tissue: &'a Tissue,
    pub forces: &'a TissueForces,
    /// Largest nodal force over γ̄·l_min.
    pub residual: Real,
    /// Growth rate of every cell (m³/s).
    pub growth_rates: &'a [Real],
}

/// Receives samples and progress; its errors stop the run.
pub trait Observer {
    /// Called at step 0, every sampling period, and at the end.
    fn sample(&mut self, sample: &Sample<'_>) -> Result<(), Box<dyn std::error::Error + Send + Sync>>;
    /// Called every step, cheaply.
    fn progress(&mut self, _step: u64, _residual: Real) {}
}

/// How a run ended.
#[derive(Clone, Debug, Serialize)]
pub struct SimulationSummary {
    pub steps: u64,
    pub force_evaluations: u64,
    pub converged: bool,
    /// Final largest nodal force over γ̄·l_min.
    pub residual: Real,
    /// Final simulated time (s).
    pub time: Real,
    pub energy: EnergyTerms,
}

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

/// Why a run stopped early.
#[derive(Debug, thiserror::Error)]
pub enum SimulationError {
    #[error(transparent)]
    UnknownCellType(#[from] UnknownCellType),
    #[error("the tissue has no moving cell: nothing to simulate")]
    NothingMoves,
    #[error(
        "cell {cell} is not a valid closed surface: {defect}. The model needs closed, outward-oriented, 2-manifold cells; \
         `tissuefit inspect` lists every defect (--orient repairs inconsistent winding)"
    )]
    InvalidCell { cell: CellId, defect: crate::mesh::MeshDefect },
    #[error("step {step}, cell {cell}: {what}. {hint}")]
    Unhealthy { step: u64, cell: CellId, what: String, hint: &'static str, last_good: LastGood },
    #[error("step {step}: remeshing failed: {source}")]
    Remesh { step: u64, source: Box<crate::mesh::remesh::RemeshError> },
    #[error("step {step}: output failed: {source}")]
    Observer { step: u64, source: Box<dyn std::error::Error + Send + Sync> },
}

const HINT: &str = "Use a smaller numerics.time_step or a larger numerics.damping (`tissuefit config check` \
                    estimates the stable step)";

/// Typical tension γ̄ (N/m): the mean surface tension over the faces of moving cells; falls back to
/// the largest tension of any type, then to 1e-3 N/m, so the force scale is never zero.
fn tension_scale(tissue: &Tissue, cell_params: &[&CellTypeParams]) -> Real {
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

/// A running simulation.
pub struct Simulation<'p> {
    tissue: Tissue,
    params: &'p Parameters,
    cell_params: Vec<&'p CellTypeParams>,
    forces: TissueForces,
    contacts: ContactWorkspace,
    coupling: CouplingWorkspace,
    momenta: Vec<Vec<Vec3>>,
    growth_rates: Vec<Real>,
    last_good: Vec<Vec<Vec3>>,
    force_scale: Real,
    energy_scale: Real,
    time: Real,
    step: u64,
    force_evaluations: u64,
}

impl<'p> Simulation<'p> {
    /// Prepares a simulation; checks that every cell has a parameter set.
    pub fn new(tissue: Tissue, params: &'p Parameters) -> Result<Self, SimulationError> {
        let cell_params = cell_parameters(&tissue, params)?;
        if tissue.cells().iter().all(|c| c.kind().is_immobile()) {
            return Err(SimulationError::NothingMoves);
        }
        if let Some((cell, defect)) = tissue.cells().iter().find_map(|c| c.mesh().validate().err().map(|d| (c.id(), d)))
        {
            return Err(SimulationError::InvalidCell { cell, defect });
        }
        let gamma = tension_scale(&tissue, &cell_params);
        let growth_rates = draw_growth_rates(&tissue, &cell_params, params.numerics.seed);
        let momenta = tissue.cells().iter().map(|c| vec![Vec3::zeros(); c.mesh().node_count()]).collect();
        let energy_scale = gamma * tissue.cells().iter().map(|c| c.mesh().area()).sum::<Real>();
        let mut contacts = ContactWorkspace::default();
        contacts.set_model(params.numerics.contact_model);
        Ok(Self {
            cell_params,
            forces: TissueForces::default(),
            contacts,
            coupling: CouplingWorkspace::default(),
            momenta,
            growth_rates,
            last_good: Vec::new(),
            force_scale: gamma * params.numerics.min_edge_length,
            energy_scale,
            time: 0.0,
            step: 0,
            force_evaluations: 0,
            tissue,
            params,
        })
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
        &self.forces
    }

    /// The typical tension force γ̄·l_min (N) that residuals are measured in.
    pub fn force_scale(&self) -> Real {
        self.force_scale
    }

    /// Largest nodal force of a moving cell, over γ̄·l_min.
    fn residual(&self) -> Real {
        let mut max: Real = 0.0;
        for (cell, work) in self.tissue.cells().iter().zip(&self.forces.cells) {
            if !cell.kind().is_immobile() {
                for f in &work.forces {
                    max = max.max(f.norm_squared());
                }
            }
        }
        max.sqrt() / self.force_scale
    }

    /// The contact stage of the last evaluation (which nodes touch which cell, at what distance).
    pub fn contacts(&self) -> &ContactWorkspace {
        &self.contacts
    }

    /// The node pairs tied by the coupling contact model at the last evaluation (empty with springs).
    pub fn coupled_pairs(&self) -> &[super::CoupledPair] {
        self.coupling.pairs()
    }

    /// Forces at the current positions: node coupling (which snaps tied pairs together), internal
    /// forces, contacts, and the averaging of tied pairs' forces.
    fn compute_forces(&mut self) {
        let numerics = &self.params.numerics;
        let coupling = numerics.contact_model == ContactModel::Coupling;
        if coupling {
            self.coupling.couple(&mut self.tissue, &self.cell_params, numerics.contact_cutoff);
        }
        self.forces.compute(&self.tissue, &self.cell_params, TermSet::ALL);
        self.contacts.add_contacts(&self.tissue, &self.cell_params, numerics.contact_cutoff, &mut self.forces.cells);
        if coupling {
            self.coupling.average_forces(&self.tissue, &mut self.forces.cells);
        }
    }

    /// Evaluates forces at the current positions (re-typing faces from contacts first, when
    /// polarity is on) and checks the state's health.
    fn evaluate(&mut self) -> Result<(), SimulationError> {
        self.compute_forces();
        if self.params.numerics.polarity == Polarity::Contacts
            && polarize_from_contacts(&mut self.tissue, &self.contacts) > 0
        {
            // Tensions changed with the face types: the forces must match the new types.
            self.compute_forces();
        }
        self.force_evaluations += 1;
        for (c, (cell, work)) in self.tissue.cells().iter().zip(&self.forces.cells).enumerate() {
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
        for name in EnergyTerms::INTERNAL {
            let mut work = CellForces::default();
            work.compute(cell, self.cell_params[c], TermSet::only(name));
            if !work.all_finite() || !work.energy.total().is_finite() {
                return name;
            }
        }
        "contact"
    }

    fn unhealthy(&self, c: usize, what: String) -> SimulationError {
        let mut last_good = self.tissue.clone();
        if self.last_good.len() == last_good.len() {
            for (cell, saved) in last_good.cells_mut().iter_mut().zip(&self.last_good) {
                cell.positions_mut().copy_from_slice(saved);
            }
        }
        SimulationError::Unhealthy {
            step: self.step,
            cell: self.tissue.cells()[c].id(),
            what,
            hint: HINT,
            last_good: LastGood(Box::new(last_good)),
        }
    }

    fn save_good(&mut self) {
        self.last_good.resize_with(self.tissue.len(), Vec::new);
        for (saved, cell) in self.last_good.iter_mut().zip(self.tissue.cells()) {
            saved.clear();
            saved.extend_from_slice(cell.mesh().positions());
        }
    }

    fn sample(&self, observer: &mut dyn Observer, residual: Real) -> Result<(), SimulationError> {
        let sample = Sample {
            step: self.step,
            time: self.time,
            tissue: &self.tissue,
            forces: &self.forces,
            residual,
            growth_rates: &self.growth_rates,
        };
        observer.sample(&sample).map_err(|source| SimulationError::Observer { step: self.step, source })
    }

    fn volumes(&self) -> Vec<Real> {
        self.forces.cells.iter().map(|w| w.geometry.volume).collect()
    }

    /// Runs what `params.simulation` says.
    pub fn run(&mut self, observer: &mut dyn Observer) -> Result<SimulationSummary, SimulationError> {
        let settings = &self.params.simulation;
        match (settings.mode, settings.method) {
            (SimulationMode::Time, _) => self.run_time(observer),
            (SimulationMode::Equilibrium, method) => self.relax(observer, method),
        }
    }

    /// Whether the equilibrium criterion holds, given the previous energy and volumes.
    fn relaxed(&self, residual: Real, previous: Option<(Real, &[Real])>) -> bool {
        let s = &self.params.simulation;
        let Some((e_prev, v_prev)) = previous else { return false };
        let energy = self.forces.energy().total();
        let de = (energy - e_prev).abs() / self.energy_scale.max(Real::MIN_POSITIVE);
        let dv =
            self.forces.cells.iter().zip(v_prev).map(|(w, v)| ((w.geometry.volume - v) / v).abs()).fold(0.0, Real::max);
        residual < s.force_tolerance && de < s.energy_tolerance && dv < s.volume_tolerance
    }

    fn summary(&self, converged: bool, residual: Real) -> SimulationSummary {
        SimulationSummary {
            steps: self.step,
            force_evaluations: self.force_evaluations,
            converged,
            residual,
            time: self.time,
            energy: self.forces.energy(),
        }
    }

    /// Relaxation to equilibrium (no growth) with FIRE or by integrating the equations of motion.
    /// A stalled FIRE hands over to integration, which descends with a stable step.
    fn relax(
        &mut self,
        observer: &mut dyn Observer,
        method: RelaxMethod,
    ) -> Result<SimulationSummary, SimulationError> {
        let s = self.params.simulation.clone();
        let mut mover = match method {
            RelaxMethod::Fire => Mover::fire(self),
            RelaxMethod::Integrate => Mover::Integrate,
        };
        self.save_good();
        self.evaluate()?;
        let mut residual = self.residual();
        self.sample(observer, residual)?;
        let mut previous: Option<(Real, Vec<Real>)> = None;
        while self.step < s.max_steps {
            if self.relaxed(residual, previous.as_ref().map(|(e, v)| (*e, v.as_slice()))) {
                self.sample(observer, residual)?;
                return Ok(self.summary(true, residual));
            }
            previous = Some((self.forces.energy().total(), self.volumes()));
            if mover.step(self)? == Moved::Stalled {
                // Typically slivers that only remeshing would remove.
                tracing::warn!(
                    "FIRE stalled (too many uphill steps in a row) at step {}; continuing with {:?} integration",
                    self.step,
                    self.params.numerics.dynamics
                );
                mover = Mover::Integrate;
                continue;
            }
            if s.remesh_every_steps > 0 && self.step.is_multiple_of(s.remesh_every_steps) && self.remesh()? {
                // New nodes: the minimiser starts afresh on the new layout, and the convergence
                // history restarts (energies of different meshes are not comparable step to step).
                if let Mover::Fire { .. } = mover {
                    mover = Mover::fire(self);
                }
                previous = None;
            }
            residual = self.residual();
            observer.progress(self.step, residual);
            if self.step.is_multiple_of(s.sample_every_steps) {
                self.sample(observer, residual)?;
            }
        }
        let converged = self.relaxed(residual, previous.as_ref().map(|(e, v)| (*e, v.as_slice())));
        self.sample(observer, residual)?;
        Ok(self.summary(converged, residual))
    }

    /// Integration for `duration` seconds with growth, sampled every `sampling_period`.
    fn run_time(&mut self, observer: &mut dyn Observer) -> Result<SimulationSummary, SimulationError> {
        let s = self.params.simulation.clone();
        let dt = self.params.numerics.time_step;
        let steps = (s.duration / dt).round() as u64;
        let sample_every = ((s.sampling_period / dt).round() as u64).max(1);
        self.evaluate()?;
        let mut residual = self.residual();
        self.sample(observer, residual)?;
        while self.step < steps {
            self.advance(true)?;
            if s.remesh_every_steps > 0 && self.step.is_multiple_of(s.remesh_every_steps) {
                self.remesh()?;
            }
            residual = self.residual();
            observer.progress(self.step, residual);
            if self.step.is_multiple_of(sample_every) || self.step == steps {
                self.sample(observer, residual)?;
            }
        }
        Ok(self.summary(false, residual))
    }

    /// One time step of the equations of motion (forces at the current positions are known).
    fn advance(&mut self, grow: bool) -> Result<(), SimulationError> {
        self.save_good();
        // Tied pairs share one momentum (forces are already averaged).
        self.coupling.average_momenta(&self.tissue, &mut self.momenta);
        integrate_step(
            &mut self.tissue,
            &self.forces.cells,
            &self.cell_params,
            &mut self.momenta,
            &self.params.numerics,
        );
        let dt = self.params.numerics.time_step;
        if grow {
            for (cell, (g, p)) in
                self.tissue.cells_mut().iter_mut().zip(self.growth_rates.iter().zip(&self.cell_params))
            {
                if *g != 0.0 {
                    // V0 never drops below the removal volume (as the reference clamps it).
                    let v0 = (cell.target_volume() + g * dt).max(p.min_volume);
                    cell.set_target_volume(v0);
                }
            }
        }
        self.time += dt;
        self.step += 1;
        self.evaluate()
    }

    /// Local remeshing of every moving cell (split, collapse, flip; momenta follow their nodes).
    /// Returns whether any mesh changed; then forces are re-evaluated.
    fn remesh(&mut self) -> Result<bool, SimulationError> {
        let settings = crate::mesh::remesh::RemeshSettings::new(self.params.numerics.min_edge_length);
        let mut changed = false;
        for (cell, momenta) in self.tissue.cells_mut().iter_mut().zip(self.momenta.iter_mut()) {
            if cell.kind().is_immobile() {
                continue;
            }
            let before = cell.mesh().topology_generation();
            cell.remesh(Some(momenta), &settings)
                .map_err(|e| SimulationError::Remesh { step: self.step, source: Box::new(e) })?;
            changed |= cell.mesh().topology_generation() != before;
        }
        if changed {
            self.save_good();
            self.evaluate()?;
        }
        Ok(changed)
    }

    /// Node offsets of each cell in the packed arrays, and which packed nodes may move.
    fn layout(&self) -> (Vec<usize>, Vec<bool>) {
        let mut offsets = vec![0];
        let mut mobile = Vec::new();
        for cell in self.tissue.cells() {
            let n = cell.mesh().node_count();
            offsets.push(offsets.last().unwrap() + n);
            mobile.extend(std::iter::repeat_n(!cell.kind().is_immobile(), n));
        }
        (offsets, mobile)
    }

    fn pack(&self, offsets: &[usize], x: &mut [Vec3], f: &mut [Vec3]) {
        for (c, (cell, work)) in self.tissue.cells().iter().zip(&self.forces.cells).enumerate() {
            x[offsets[c]..offsets[c + 1]].copy_from_slice(cell.mesh().positions());
            f[offsets[c]..offsets[c + 1]].copy_from_slice(&work.forces);
        }
    }

    fn unpack(&mut self, offsets: &[usize], x: &[Vec3]) {
        for (c, cell) in self.tissue.cells_mut().iter_mut().enumerate() {
            cell.positions_mut().copy_from_slice(&x[offsets[c]..offsets[c + 1]]);
        }
    }
}

/// Whether a relaxation step moved the nodes.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
enum Moved {
    Yes,
    /// FIRE is stuck; nothing moved.
    Stalled,
}

/// How a relaxation moves the nodes: FIRE on packed arrays of all nodes, or the equations of motion.
enum Mover {
    Fire { fire: Box<Fire>, offsets: Vec<usize>, mobile: Vec<bool>, x: Vec<Vec3>, f: Vec<Vec3> },
    Integrate,
}

impl Mover {
    fn fire(sim: &Simulation<'_>) -> Self {
        let (offsets, mobile) = sim.layout();
        let total = *offsets.last().unwrap_or(&0);
        let settings = FireSettings::for_scales(sim.params.numerics.min_edge_length, sim.force_scale);
        Mover::Fire {
            fire: Box::new(Fire::new(settings, total)),
            offsets,
            mobile,
            x: vec![Vec3::zeros(); total],
            f: vec![Vec3::zeros(); total],
        }
    }

    /// One step from the current, evaluated state; evaluates the forces at the new positions.
    fn step(&mut self, sim: &mut Simulation<'_>) -> Result<Moved, SimulationError> {
        match self {
            Mover::Fire { fire, offsets, mobile, x, f } => {
                sim.pack(offsets, x, f);
                sim.save_good();
                fire.step(x, f, mobile);
                if fire.stalled() {
                    return Ok(Moved::Stalled);
                }
                sim.unpack(offsets, x);
                sim.step += 1;
                sim.evaluate()?;
                // Tied pairs move as one: new pairs take their mean velocity.
                sim.coupling.average_packed(&sim.tissue, offsets, fire.velocities_mut());
            }
            Mover::Integrate => sim.advance(false)?,
        }
        Ok(Moved::Yes)
    }
}

//! Time runs: integration of the equations of motion with growth, divisions, removals and
//! remeshing, sampled at a fixed period.

use super::{Observer, Phase, Simulation, SimulationError, SimulationSummary};
use crate::mechanics::integrate_step;

impl<'p> Simulation<'p> {
    /// Integration for `duration` seconds with growth, sampled every `sampling_period`.
    pub(super) fn run_time(&mut self, observer: &mut dyn Observer) -> Result<SimulationSummary, SimulationError> {
        let s = self.params.simulation.clone();
        let dt = self.params.numerics.time_step;
        let steps = (s.duration / dt).round() as u64;
        let sample_every = ((s.sampling_period / dt).round() as u64).max(1);
        let mut residual = match self.resume.take() {
            Some(Phase::Time { residual }) => residual,
            Some(Phase::Relax { .. }) => {
                return Err(SimulationError::BadState("a relaxation's state cannot continue a time run".into()));
            }
            None => {
                self.start()?;
                let residual = self.residual();
                self.sample(observer, residual)?;
                residual
            }
        };
        while self.progress.step < steps {
            self.time_step()?;
            residual = self.residual();
            observer.progress(self.progress.step, residual);
            if self.progress.step.is_multiple_of(sample_every) || self.progress.step == steps {
                self.sample(observer, residual)?;
            }
            self.maybe_checkpoint(observer, || Phase::Time { residual })?;
        }
        Ok(self.summary(false, residual))
    }

    /// Evaluates the forces of the initial state; call once before stepping with [`Self::time_step`].
    pub fn start(&mut self) -> Result<(), SimulationError> {
        self.save_good();
        self.evaluate()
    }

    /// One step of a time run, for drivers that decide themselves when to stop: integrate with
    /// growth; then divisions, removals and (when due) remeshing of the moved surfaces; then one
    /// force evaluation of the result (so a topology change costs no extra evaluation).
    pub fn time_step(&mut self) -> Result<(), SimulationError> {
        self.save_good();
        self.move_nodes(true);
        self.divide_and_remove()?;
        let every = self.params.simulation.remesh_every_steps;
        let (started, before) = (std::time::Instant::now(), self.work.times.evaluation());
        if every > 0 && self.progress.step.is_multiple_of(every) {
            self.remesh_cells(None)?;
        } else if let Some(cells) = self.cells_needing_repair() {
            self.repair_meshes(cells)?;
        }
        self.work.times.add_remeshing(started, before);
        self.evaluate()
    }

    /// One time step of the equations of motion (forces at the current positions are known).
    pub(super) fn advance(&mut self, grow: bool) -> Result<(), SimulationError> {
        self.save_good();
        self.move_nodes(grow);
        self.evaluate()
    }

    /// Integrates positions (and momenta) over one step with the current forces, grows the target
    /// volumes when `grow`, and advances the clock; forces are not re-evaluated.
    fn move_nodes(&mut self, grow: bool) {
        // Tied pairs share one momentum (forces are already averaged).
        self.work.coupling.average_momenta(&self.tissue, &mut self.cell_data.momenta);
        integrate_step(
            &mut self.tissue,
            &self.work.forces.cells,
            &self.cell_params,
            &mut self.cell_data.momenta,
            &self.params.numerics,
        );
        let dt = self.params.numerics.time_step;
        if grow {
            for (cell, (g, p)) in
                self.tissue.cells_mut().iter_mut().zip(self.cell_data.growth_rates.iter().zip(&self.cell_params))
            {
                if *g != 0.0 {
                    // V0 never drops below the removal volume (as the reference clamps it).
                    let v0 = (cell.target_volume() + g * dt).max(p.min_volume);
                    cell.set_target_volume(v0);
                }
            }
        }
        self.progress.time += dt;
        self.progress.step += 1;
    }
}

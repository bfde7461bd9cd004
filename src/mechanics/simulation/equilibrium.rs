//! Relaxation to mechanical equilibrium: FIRE (or integration of the equations of motion), with a
//! hand-over to integration when FIRE stalls, remeshing on schedule or out of turn, and an end at
//! the lowest-residual state when the run does not converge.

use super::mover::{Moved, Mover};
use super::state::BestState;
use super::{Observer, Phase, Simulation, SimulationError, SimulationSummary};
use crate::geometry::Real;
use crate::mechanics::RelaxMethod;

/// How far (fraction of the energy scale γ̄·A) the lowest-residual state's energy may lie above the
/// last state's for a relaxation that did not converge to end there: a state much higher in energy
/// was left for a lower basin, and going back would undo progress.
pub const BEST_ENERGY_SLACK: Real = 1e-3;

/// A new lowest-residual state is kept when its residual is below this fraction of the kept one's
/// (copying the meshes on every small improvement would cost more than the steps).
pub(super) const BEST_GAIN: Real = 0.8;

impl<'p> Simulation<'p> {
    /// Whether the equilibrium criterion holds, given the previous energy and volumes.
    fn relaxed(&self, residual: Real, previous: Option<(Real, &[Real])>) -> bool {
        let s = &self.params.simulation;
        let Some((e_prev, v_prev)) = previous else { return false };
        let energy = self.work.forces.energy().total();
        let de = (energy - e_prev).abs() / self.progress.energy_scale.max(Real::MIN_POSITIVE);
        let dv = self
            .work
            .forces
            .cells
            .iter()
            .zip(v_prev)
            .map(|(w, v)| ((w.geometry.volume - v) / v).abs())
            .fold(0.0, Real::max);
        residual < s.force_tolerance && de < s.energy_tolerance && dv < s.volume_tolerance
    }

    /// Relaxation to equilibrium (no growth) with FIRE or by integrating the equations of motion.
    /// A stalled FIRE hands over to integration, which descends with a stable step. A run that does
    /// not converge ends at its lowest-residual state since the last remeshing (unless that state's
    /// energy lies more than [`BEST_ENERGY_SLACK`]·(energy scale) above the last one's: then the run
    /// went on to a lower basin), so an integration still ringing at the end does not leave its last
    /// swing in the output, and says why in [`SimulationSummary::stop_reason`].
    pub(super) fn relax(
        &mut self,
        observer: &mut dyn Observer,
        method: RelaxMethod,
    ) -> Result<SimulationSummary, SimulationError> {
        let s = self.params.simulation.clone();
        self.normal_only = s.normal_relaxation;
        let (mut mover, mut residual, mut previous, mut best) = match self.resume.take() {
            Some(Phase::Relax { fire, best, previous, residual }) => {
                let mover = match fire {
                    Some(fire) => Mover::with_fire(self, fire),
                    None => Mover::Integrate,
                };
                (mover, residual, previous, best)
            }
            Some(Phase::Time { .. }) => {
                return Err(SimulationError::BadState("a time run's state cannot continue a relaxation".into()));
            }
            None => {
                self.save_good();
                self.evaluate()?;
                let mover = match method {
                    RelaxMethod::Fire => Mover::fire(self),
                    RelaxMethod::Integrate => Mover::Integrate,
                };
                let residual = self.residual();
                self.sample(observer, residual)?;
                (mover, residual, None, None)
            }
        };
        // After a FIRE stall the run integrates the equations of motion, which may still be ringing
        // when max_steps ends it: from the stall on, the lowest-residual state is kept whatever
        // simulation.end_at_lowest_residual says (a restored run that integrates stalled before).
        let mut stalled = method == RelaxMethod::Fire && matches!(mover, Mover::Integrate);
        while self.progress.step < s.max_steps {
            if self.relaxed(residual, previous.as_ref().map(|(e, v)| (*e, v.as_slice()))) {
                self.sample(observer, residual)?;
                return Ok(self.summary(true, residual));
            }
            previous = Some((self.work.forces.energy().total(), self.volumes()));
            if mover.step(self)? == Moved::Stalled {
                // Typically slivers that only remeshing would remove.
                tracing::warn!(
                    "FIRE stalled (too many uphill steps in a row) at step {}; continuing with {:?} integration",
                    self.progress.step,
                    self.params.numerics.dynamics
                );
                mover = Mover::Integrate;
                stalled = true;
                // The state FIRE stalled in competes too (the integration may only make it worse).
                best = Some(Box::new(BestState {
                    residual,
                    energy: self.work.forces.energy().total(),
                    step: self.progress.step,
                    cells: self.cell_states(),
                }));
                continue;
            }
            // The last settle_steps run on a fixed mesh (see SimulationSettings::settle_steps).
            // (settle_steps = 0 keeps the remeshing at the last step when it falls due.)
            let settling = s.settle_steps > 0 && self.progress.step.saturating_add(s.settle_steps) >= s.max_steps;
            let scheduled =
                s.remesh_every_steps > 0 && !settling && self.progress.step.is_multiple_of(s.remesh_every_steps);
            let (started, before) = (std::time::Instant::now(), self.work.times.evaluation());
            let remeshed = if scheduled { self.remesh()? } else { self.repair_out_of_turn()? };
            self.work.times.add_remeshing(started, before);
            if remeshed {
                // New nodes: the minimiser starts afresh on the new layout (carrying FIRE's Δt, α
                // and velocities through out-of-turn passes was tried on a 64-cell spheroid: twice
                // as many edges collapsed, the residual after 3,000 steps no lower), and the
                // convergence history restarts (energies of different meshes are not comparable).
                mover.relayout(self);
                previous = None;
                // The kept best state is of another mesh; only states since the last remeshing
                // compete (a residual right after remeshing is not comparable either way).
                best = None;
            }
            residual = self.residual();
            // Kept only for simulation.end_at_lowest_residual and after a FIRE stall (copying the
            // meshes costs otherwise).
            if (s.end_at_lowest_residual || stalled)
                && best.as_deref().is_none_or(|b| residual < BEST_GAIN * b.residual)
            {
                best = Some(Box::new(BestState {
                    residual,
                    energy: self.work.forces.energy().total(),
                    step: self.progress.step,
                    cells: self.cell_states(),
                }));
            }
            observer.progress(self.progress.step, residual);
            if self.progress.step.is_multiple_of(s.sample_every_steps) {
                self.sample(observer, residual)?;
            }
            self.maybe_checkpoint(observer, || Phase::Relax {
                fire: mover.state(),
                best: best.clone(),
                previous: previous.clone(),
                residual,
            })?;
        }
        let converged = self.relaxed(residual, previous.as_ref().map(|(e, v)| (*e, v.as_slice())));
        let (mut ended_at_step, mut stop_reason) = (None, None);
        if !converged {
            let mut reason = format!(
                "max_steps = {} reached with residual {residual:.3e} (force_tolerance {:.1e}, energy and volume changes \
                 against their tolerances)",
                s.max_steps, s.force_tolerance
            );
            if stalled {
                reason.push_str(&format!(
                    "; FIRE stalled and the run went on integrating {:?}",
                    self.params.numerics.dynamics
                ));
            }
            if let Some(b) = best
                && b.residual < residual
                && b.energy <= self.work.forces.energy().total() + BEST_ENERGY_SLACK * self.progress.energy_scale
                && b.step != self.progress.step
            {
                self.restore_cells(b.cells)?;
                residual = self.residual();
                ended_at_step = Some(b.step);
                reason.push_str(&format!("; ended at the lowest-residual state, step {}", b.step));
            }
            stop_reason = Some(reason);
        }
        self.sample(observer, residual)?;
        let mut summary = self.summary(converged, residual);
        summary.stop_reason = stop_reason;
        summary.ended_at_step = ended_at_step;
        Ok(summary)
    }
}

//! What a run shows its caller: samples at a fixed period, cheap progress every step, and the
//! checkpoints it asks for.

use super::{Simulation, SimulationError, SimulationState};
use crate::geometry::Real;
use crate::mechanics::TissueForces;
use crate::mesh::Tissue;

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
    /// Called at the end of every step (after its sample, if any): whether to save the state now.
    fn checkpoint_due(&mut self, _step: u64) -> CheckpointRequest {
        CheckpointRequest::No
    }
    /// Receives the complete state when [`Self::checkpoint_due`] asked for it.
    fn checkpoint(&mut self, _state: &SimulationState) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        Ok(())
    }
}

/// An observer that keeps nothing: for relaxations whose caller reads only the final tissue and
/// summary.
pub struct NoObserver;

impl Observer for NoObserver {
    fn sample(&mut self, _: &Sample<'_>) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        Ok(())
    }
}

/// What an observer wants at a step boundary.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum CheckpointRequest {
    No,
    /// Save the state and continue.
    Save,
    /// Save the state and stop ([`SimulationError::Interrupted`]).
    SaveAndStop,
}

impl<'p> Simulation<'p> {
    pub(super) fn sample(&self, observer: &mut dyn Observer, residual: Real) -> Result<(), SimulationError> {
        let sample = Sample {
            step: self.progress.step,
            time: self.progress.time,
            tissue: &self.tissue,
            forces: &self.work.forces,
            residual,
            growth_rates: &self.cell_data.growth_rates,
        };
        observer.sample(&sample).map_err(|source| SimulationError::Observer { step: self.progress.step, source })
    }
}

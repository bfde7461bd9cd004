//! Inference: fit surface tension and adhesion so that simulated equilibrium morphology matches the
//! observed one (DESIGN.md §1 step 4, §3 dimensionless groups; paper Application 2, Fig. 4c–e).
//!
//! The forward model ([`ForwardModel`]) starts from the observed tissue, writes a candidate point of
//! the [`ParameterSpace`] into the model, relaxes to equilibrium and scores the measured morphology
//! against the observed one. Gradient-free optimisers from argmin (Nelder–Mead, particle swarm)
//! search the natural logs of the fitted parameters within bounds ([`optimise`]); an [`Evaluator`]
//! caches evaluations by their exact point, runs independent ones in parallel and records the trace
//! in request order (thread-independent). After the optimum, [`profile`] probes the objective along
//! each parameter, the common scale and the key ratios to say what the data determine. The best point
//! is then relaxed once more for its files ([`write_best_outputs`]: `best.vtp`, `best.toml`,
//! `residuals.csv`).
//!
//! What an equilibrium shape can determine: dimensionless combinations. For coupling contacts the
//! contact angle follows Young–Dupré, cos(θ) = γ_lateral/γ_apical; for spring contacts the shape is set
//! by the adhesion energy over tension, w/(2γ) = ω·c²/(4γ). The absolute scale γ̃ = γ/(K·l) enters
//! only through volume compression against the bulk modulus K. Results are reported in SI and
//! dimensionless (γ̃ = γ/(K·l), ω̃ = ω·l/K, l = ⟨V⟩^(1/3) of the observed moving cells).

mod best;
mod config;
mod forward;
mod optimise;
mod per_cell;
pub(crate) mod plot;
mod profile;
mod result;
pub mod round_trip;
mod run;
mod space;
mod trace;

pub use best::{BEST_MODEL_FILE, BEST_TISSUE_FILE, BestRelaxation, RESIDUALS_FILE, write_best_outputs};
pub use config::{
    FitConfig, FitMode, ForwardConfig, ModelErrorConfig, ObjectiveConfig, ObservedConfig, OptimizerConfig,
    OptimizerMethod, ParameterConfig, PerCellConfig, ProfileConfig, Roughen, RoughenEstimate,
};
pub use forward::{
    Evaluation, ForwardModel, MAX_ROUGHEN_VOXELS, MISSING_METRIC_MISFIT, Metric, Metrics, Observation,
    RoughnessCalibration, Status, shift_offset,
};
pub use optimise::{BOUND_PENALTY, Evaluator, Halt, OptimiserOutcome, optimise};
pub(crate) use per_cell::ratios;
pub use per_cell::{CellTensions, Iteration, PER_CELL_FILES, PerCellResult, run_per_cell, run_per_cell_from};
pub use plot::{plot_landscape, plot_objective};
pub use profile::{NOISE_STEP, NoiseFloor, Slice, profile, ratio_parts};
pub use result::{AT_BOUND_FRACTION, FitResult, POOR_FIT_OBJECTIVE, ParameterResult, RatioResult};
pub use run::{FitOptions, load_observation, observe_labels, run_fit, run_fit_observed};
pub use space::{
    ADHESION_RATIO, FitParameter, FittedParameter, PARAMETER_NAMES, ParameterSpace, resolve_adhesion_ratio,
};
pub use trace::{read_trace, recorded_elapsed_seconds, write_trace};

/// Why a fit could not run (a failed evaluation is not an error: it is penalised and recorded).
#[derive(Debug, thiserror::Error)]
pub enum InferenceError {
    #[error("fit config: {0}")]
    Config(String),
    #[error("observed tissue: {0}")]
    Observed(String),
    #[error("resuming from the trace: {0}")]
    Resume(String),
    #[error("optimiser: {0}")]
    Optimiser(String),
    #[error("writing outputs: {0}")]
    Output(String),
    /// No evaluation of the fit was usable (every one failed or ended unconverged): there is no
    /// fitted value, only the failures' summary and what to change.
    #[error("the fit failed: {0}")]
    Failed(String),
    /// The caller stopped the fit ([`crate::io::Watch::stop`]): the finished evaluations are in the
    /// trace, from which the fit resumes.
    #[error("stopped by the caller; the finished evaluations are in trace.csv, resume the fit to go on")]
    Stopped,
}

//! `result.json` (DESIGN.md §2): `{"parameters": {NAME: {"si", "dimensionless", "range": [lo, hi]}},
//! "objective", "evaluations", "converged", "wall_seconds"}` plus what the data determine.

use super::forward::Metrics;
use crate::geometry::Real;
use serde::Serialize;
use std::collections::BTreeMap;

/// A fitted value within this fraction of its search range (in log space) from a bound is reported
/// at that bound (`at_bound`), never determined: the data may prefer a value beyond it.
pub const AT_BOUND_FRACTION: Real = 0.01;

/// A best objective above this (the metrics miss the observed ones by √25 = 5 of their scales each),
/// beyond `profile.noise_sigmas` σ of the forward model's noise at the optimum, is a poor fit
/// (`poor_fit`): the model does not describe the data (a real ovule scored 1042).
pub const POOR_FIT_OBJECTIVE: Real = 25.0;

/// One parameter of the result.
#[derive(Clone, Debug, Serialize)]
pub struct ParameterResult {
    /// Best value (SI: N/m for tensions, Pa/m for adhesion).
    pub si: Real,
    /// γ̃ = γ/(K·l) for tensions, ω̃ = ω·l/K for adhesion.
    pub dimensionless: Real,
    /// Acceptable range (SI) from the profile; the search bounds where the data do not bound it; the
    /// value itself for a fixed parameter.
    pub range: [Real; 2],
    /// Fitted (true) or fixed from the config (false).
    pub fitted: bool,
    /// Whether the data determine it (closed acceptable range); `None` for a fixed parameter or
    /// without a profile.
    pub determined: Option<bool>,
    /// Search bounds (SI) of a fitted parameter.
    pub bounds: Option<[Real; 2]>,
    /// `"lower"` or `"upper"` when the best value lies at (within [`AT_BOUND_FRACTION`] of) that
    /// search bound: then it is not determined; widen the bound and fit again.
    pub at_bound: Option<String>,
}

/// A key ratio of the result.
#[derive(Clone, Debug, Serialize)]
pub struct RatioResult {
    pub value: Real,
    pub range: [Real; 2],
    pub determined: Option<bool>,
    /// `"lower"` or `"upper"` when the ratio lies at the most extreme value its parameters' search
    /// bounds allow (then it is not determined).
    pub at_bound: Option<String>,
    /// What it is, in words.
    pub meaning: String,
}

/// The whole `result.json`.
#[derive(Clone, Debug, Serialize)]
pub struct FitResult {
    pub parameters: BTreeMap<String, ParameterResult>,
    /// Best objective (see the objective's definition in the README / `inference::forward`).
    pub objective: Real,
    /// Distinct evaluations of the optimisation (the trace's rows before the profile).
    pub evaluations: usize,
    /// Whether the optimiser met its own criterion (not only the budget).
    pub converged: bool,
    /// Seconds of the whole fit: a resumed fit adds the earlier sessions' wall time up to their last
    /// recorded evaluation (the trace's `elapsed_seconds`; work in flight when a session was killed is
    /// not counted).
    pub wall_seconds: Real,
    /// Seconds of this process alone.
    pub session_wall_seconds: Real,
    /// Key ratios (γ_lateral/γ_apical, ω/γ) and whether the data determine them.
    pub ratios: BTreeMap<String, RatioResult>,
    /// Plain statements of what is and is not identifiable.
    pub identifiability: Vec<String>,
    /// The optimiser, named as in the config (`nelder_mead`, `particle_swarm`).
    pub optimizer: super::config::OptimizerMethod,
    pub stop_reason: String,
    /// Profile evaluations (after the optimum, in the trace after the optimisation rows).
    pub profile_evaluations: usize,
    /// Simulations run by this process (the rest came from an earlier trace).
    pub simulated_here: usize,
    pub observed: Metrics,
    pub best_metrics: Metrics,
    /// l = ⟨V⟩^(1/3) of the observed moving cells (m).
    pub length_scale: Real,
    /// K (Pa) of the first epithelial cell type, for the dimensionless groups.
    pub bulk_modulus: Real,
    /// Contact model of the forward simulations, named as in the model file (`spring`, `coupling`, …).
    pub contact_model: crate::mechanics::ContactModel,
    /// Contact cutoff c (m) of the forward simulations (spring adhesion energy w = ω·c²/2).
    pub contact_cutoff: Real,
    pub threads: usize,
    pub profile: Vec<super::profile::Slice>,
    /// The forward model's noise at the optimum and the profile's acceptance threshold (`None`
    /// without a usable best point).
    pub noise: Option<super::profile::NoiseFloor>,
    /// The best objective lies far above what the forward model's noise explains (see
    /// [`POOR_FIT_OBJECTIVE`]): the model does not describe the data.
    pub poor_fit: bool,
    /// The relaxation at the best point that `best.vtp` and `residuals.csv` come from, and whether
    /// it failed (then the summary line and a warning say so).
    pub best_relaxation: super::best::BestRelaxation,
    /// The boundary noise added to the simulated masks (`forward.roughen_voxels`), with the
    /// roughness of the observed and simulated masks; `None` when nothing was roughened.
    pub roughen: Option<super::forward::RoughnessCalibration>,
}

impl FitResult {
    /// One line for people: a poor fit said first, the objective, the evaluations, whether the
    /// optimiser converged, and every fitted parameter and ratio with its acceptable range and its
    /// state (determined, NOT determined, or AT A SEARCH BOUND: never "determined" there). `tissuefit
    /// fit` and the pipeline's fit stage print it.
    pub fn summary_line(&self) -> String {
        let state = |at_bound: &Option<String>, determined: Option<bool>| match (at_bound, determined) {
            (Some(side), _) => format!("AT THE {} SEARCH BOUND: widen it and fit again", side.to_uppercase()),
            (None, Some(true)) => "determined".to_string(),
            (None, Some(false)) => "NOT determined".to_string(),
            (None, None) => "no profile".to_string(),
        };
        let mut quantities: Vec<String> = self
            .parameters
            .iter()
            .filter(|(_, p)| p.fitted)
            .map(|(n, p)| {
                format!(
                    "{n} = {:.4e} [{:.3e}, {:.3e}] ({})",
                    p.si,
                    p.range[0],
                    p.range[1],
                    state(&p.at_bound, p.determined)
                )
            })
            .collect();
        quantities.extend(self.ratios.iter().map(|(n, r)| {
            format!(
                "{n} = {:.4e} [{:.3e}, {:.3e}] ({})",
                r.value,
                r.range[0],
                r.range[1],
                state(&r.at_bound, r.determined)
            )
        }));
        format!(
            "{}{}objective {:.4e} after {} evaluations ({}); {}",
            self.best_relaxation.failure().map_or(String::new(), |f| format!("BEST-POINT RELAXATION FAILED: {f}; ")),
            if self.poor_fit {
                "POOR FIT (the objective lies far above the forward model's noise: the model does not describe \
                 these data; see result.json, identifiability): "
            } else {
                ""
            },
            self.objective,
            self.evaluations,
            if self.converged { "converged".to_string() } else { format!("NOT converged: {}", self.stop_reason) },
            quantities.join("; ")
        )
    }
}

//! The fit stage: observed morphology → optimiser over relaxed simulations → `trace.csv`,
//! `result.json`, `fit.toml`, `model.toml`, the plots, and the best point's `best.vtp`, `best.toml`
//! and `residuals.csv` (DESIGN.md §2).
//!
//! `tissuefit fit` and the pipeline's `[fit]` both call [`run`]; they differ only in where the
//! observed tissue comes from ([`Observed`]): `tissuefit fit` reads `observed.tissue` or meshes
//! `observed.labels` itself, the pipeline reads back the tissue its mesh stage wrote (bit for bit,
//! so the same settings give the same observed tissue, and the same files).

use super::StageError;
use crate::geometry::Real;
use crate::imaging::{LabelVolume, read_labels};
use crate::inference::{
    FitConfig, FitOptions, FitResult, InferenceError, Observation, load_observation, observe_labels,
};
use crate::io::{LengthScale, ReadOptions, read_tissue};
use crate::mesh::Tissue;
use std::collections::BTreeMap;
use std::path::Path;

/// Every evaluation: parameters, status, objective, metrics, elapsed time.
pub const TRACE_FILE: &str = "trace.csv";
/// The fitted parameters, their ranges and what the data determine ([`FitResult`]).
pub const RESULT_FILE: &str = "result.json";
/// The files a global fit writes into its folder.
pub const OUTPUT_FILES: &[&str] = &[
    TRACE_FILE,
    RESULT_FILE,
    "objective.png",
    "landscape.png",
    "profile.png",
    "fit.toml",
    "model.toml",
    crate::inference::BEST_TISSUE_FILE,
    crate::inference::BEST_MODEL_FILE,
    crate::inference::RESIDUALS_FILE,
];

/// Every file the stage may write into its folder: a global fit's and a per-cell fit's
/// ([`crate::inference::PER_CELL_FILES`]).
pub fn output_files() -> Vec<&'static str> {
    let mut files = OUTPUT_FILES.to_vec();
    files.extend(crate::inference::PER_CELL_FILES.iter().filter(|f| !files.contains(f)).collect::<Vec<_>>());
    files
}

/// What a fit found: a global fit's result, or a per-cell map's.
#[derive(Clone, Debug)]
pub enum FitOutcome {
    Global(Box<FitResult>),
    PerCell(Box<crate::inference::PerCellResult>),
}

impl FitOutcome {
    /// One line for a terminal or log.
    pub fn summary_line(&self) -> String {
        match self {
            FitOutcome::Global(r) => r.summary_line(),
            FitOutcome::PerCell(r) => r.summary_line(),
        }
    }

    /// Converged, not a poor fit, and the best point's relaxation usable.
    pub fn succeeded(&self) -> bool {
        match self {
            FitOutcome::Global(r) => r.converged && !r.poor_fit && !r.best_relaxation.failed,
            FitOutcome::PerCell(r) => r.converged && !r.poor_fit,
        }
    }

    /// The optimiser (global) or the refinement (per cell) met its criterion.
    pub fn converged(&self) -> bool {
        match self {
            FitOutcome::Global(r) => r.converged,
            FitOutcome::PerCell(r) => r.converged,
        }
    }

    pub fn wall_seconds(&self) -> Real {
        match self {
            FitOutcome::Global(r) => r.wall_seconds,
            FitOutcome::PerCell(r) => r.wall_seconds,
        }
    }
}

fn err(message: impl Into<String>) -> StageError {
    StageError::new("fit", message)
}

/// Where the observed tissue comes from.
#[derive(Clone, Copy, Debug)]
pub enum Observed<'a> {
    /// The config's `observed`: its tissue file, or its labels meshed like `observed.meshing`.
    Config,
    /// The tissue a mesh stage wrote into this folder (its `tissue.vtp`, meshed at the l_min its
    /// `report.json` states) instead of meshing `observed.labels` again; the labels are still read,
    /// to measure the simulations like the data. Without labels (a mesh input) the observation is
    /// that tissue alone.
    MeshStage(&'a Path),
    /// A label volume in memory (the Python API), meshed like `observed.labels` with
    /// `observed.meshing` (whose `[observed]` then names no file).
    Labels(&'a LabelVolume),
    /// A tissue in memory (the Python API), observed as `observed.tissue` is.
    Tissue(&'a Tissue),
}

/// The observation of `config` from `observed`.
fn observation(config: &FitConfig, observed: Observed) -> Result<Observation, StageError> {
    let dir = match observed {
        Observed::Config => return load_observation(config).map_err(|e| err(e.to_string())),
        Observed::MeshStage(dir) => dir,
        Observed::Labels(volume) => {
            let meshing = config.observed.as_ref().map(|o| o.meshing.clone()).unwrap_or_default();
            return observe_labels(volume.clone(), &meshing, "the label volume").map_err(|e| err(e.to_string()));
        }
        Observed::Tissue(tissue) => {
            return Observation::new(tissue.clone(), None, None).map_err(|e| err(e.to_string()));
        }
    };
    let path = dir.join(super::mesh::TISSUE_FILE);
    let read = read_tissue(&path, &ReadOptions { length_scale: LengthScale::default(), orient: false })
        .map_err(|e| err(format!("reading the mesh stage's tissue {}: {e}", path.display())))?;
    let obs = config.observed().map_err(|e| err(e.to_string()))?;
    let observation = match &obs.labels {
        Some(labels) => {
            let l_min = super::mesh::read_report_l_min(&dir.join(super::mesh::REPORT_FILE))?;
            let volume = read_labels(labels, &obs.read_options())
                .map_err(|e| err(format!("reading {}: {e}", labels.display())))?
                .volume;
            let mut meshing = obs.meshing.clone();
            // Simulations are measured like the data: the meshing's options with the l_min it used.
            meshing.l_min = l_min;
            Observation::new(read.tissue, Some(volume), Some(meshing))
        }
        None => Observation::new(read.tissue, None, None),
    };
    observation.map_err(|e| err(e.to_string()))
}

/// Runs the fit of `config` on the `observed` tissue into `out` (created if needed). A fit in which
/// no evaluation succeeded is an error pointing at the trace, where every evaluation's reason is.
pub fn run(config: &FitConfig, observed: Observed, out: &Path, options: &FitOptions) -> Result<FitOutcome, StageError> {
    let observation = observation(config, observed)?;
    if config.mode == crate::inference::FitMode::PerCell {
        return crate::inference::run_per_cell(config, observation, out, options)
            .map(|r| FitOutcome::PerCell(Box::new(r)))
            .map_err(|e| err(e.to_string()));
    }
    crate::inference::run_fit_observed(config, Some(observation), out, options)
        .map(|r| FitOutcome::Global(Box::new(r)))
        .map_err(|e| match e {
            InferenceError::Failed(_) => err(format!(
                "{e} (every evaluation and its reason: {}; no {RESULT_FILE} was written)",
                out.join(TRACE_FILE).display()
            )),
            e => err(e.to_string()),
        })
}

/// What a caller needs of a finished fit's `result.json`, read back typed (the whole file is
/// [`FitResult`]).
#[derive(Clone, Debug, serde::Deserialize)]
pub struct ResultHead {
    /// Whether the optimiser met its own criterion.
    pub converged: bool,
    /// The best objective lies far above the forward model's noise.
    pub poor_fit: bool,
    pub parameters: BTreeMap<String, ParameterHead>,
    #[serde(default)]
    pub ratios: BTreeMap<String, RatioHead>,
    /// How the relaxation at the best point (`best.vtp`, `residuals.csv`) ended.
    pub best_relaxation: BestRelaxationHead,
}

/// `best_relaxation` of [`ResultHead`].
#[derive(Clone, Debug, serde::Deserialize)]
pub struct BestRelaxationHead {
    /// It failed or ended unusable: no `best.vtp`, see `reason`.
    pub failed: bool,
    pub reason: String,
}

/// A parameter of [`ResultHead`].
#[derive(Clone, Debug, serde::Deserialize)]
pub struct ParameterHead {
    /// Best value (SI).
    pub si: Option<Real>,
}

/// A ratio of [`ResultHead`].
#[derive(Clone, Debug, serde::Deserialize)]
pub struct RatioHead {
    pub value: Option<Real>,
}

impl ResultHead {
    /// The fitted value of a parameter or ratio by name (`None`: the result has no such quantity).
    pub fn value(&self, name: &str) -> Option<Real> {
        self.parameters.get(name).and_then(|p| p.si).or_else(|| self.ratios.get(name).and_then(|r| r.value))
    }
}

/// Reads a fit folder's `result.json`.
pub fn read_result(dir: &Path) -> Result<ResultHead, StageError> {
    let path = dir.join(RESULT_FILE);
    let text = crate::io::read_text_capped(&path, crate::io::MAX_CONFIG_FILE)
        .map_err(|e| err(format!("reading {}: {e}", path.display())))?;
    serde_json::from_str(&text).map_err(|e| err(format!("reading {}: {e}", path.display())))
}

//! The fit configuration (`tissuefit fit --config FIT.toml`): what was observed, the base model,
//! which parameters to fit and within which bounds, the objective's weights and scales, the
//! optimiser and the forward simulation. Every section rejects unknown keys.

use super::InferenceError;
use crate::geometry::Real;
use crate::mechanics::Parameters;
use crate::meshing::LabelMeshingOptions;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The whole fit configuration. Relative paths are resolved against the config file's folder.
#[derive(Clone, Debug, Deserialize, Serialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FitConfig {
    /// The observed tissue. Required by `tissuefit fit`; a pipeline's `[fit]` leaves it out and
    /// takes `[input]` and `[mesh]` instead.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub observed: Option<ObservedConfig>,
    /// The base model: a path to a simulation config (same schema as `simulate --config`), or absent
    /// for the built-in defaults; `[model_overrides]` then changes single keys.
    #[serde(default)]
    pub model: Option<PathBuf>,
    /// Keys of the simulation config given inline (same schema as `simulate --config`), applied on
    /// top of `model`. Default: none.
    #[serde(default)]
    #[schemars(with = "Option<BTreeMap<String, serde_json::Value>>")]
    pub model_overrides: Option<toml::Table>,
    /// The parameters to fit or fix, by name: `surface_tension` (every face type),
    /// `surface_tension_apical`, `surface_tension_lateral`, `surface_tension_basal`, `adhesion`
    /// (every face type), or instead of `adhesion` `adhesion_energy_over_tension`: the spring
    /// adhesion as w/(2γ) = ω·c²/(4γ) (dimensionless; needs a fixed `surface_tension`), whose
    /// bounds then hold whatever contact cutoff c the meshing sets. Applied to every epithelial cell
    /// type. Names not listed keep the model's value.
    /// Required by `mode = "global"`; with `mode = "per_cell"` only the fixed values (`value`) and the
    /// starts (`initial`, else the middle of the bounds) of the base model are used.
    #[serde(default)]
    pub parameters: BTreeMap<String, ParameterConfig>,
    /// What is fitted: `"global"` (default) — the named parameters, shared by every cell, by an
    /// optimiser over relaxed simulations; `"per_cell"` — every cell's own free and lateral
    /// tension, refined from the direct estimate until the simulation, measured like the data, gives
    /// the data's tension map (`[per_cell]`; the docs book, "Per-cell maps").
    #[serde(default)]
    pub mode: FitMode,
    /// Settings of `mode = "per_cell"`. Default: [`PerCellConfig::default`].
    #[serde(default)]
    pub per_cell: PerCellConfig,
    /// Objective weights and scales. Default: [`ObjectiveConfig::default`].
    #[serde(default)]
    pub objective: ObjectiveConfig,
    /// Optimiser. Default: [`OptimizerConfig::default`].
    #[serde(default)]
    pub optimizer: OptimizerConfig,
    /// Forward simulation settings. Default: [`ForwardConfig::default`].
    #[serde(default)]
    pub forward: ForwardConfig,
    /// Profile (uncertainty) settings. Default: [`ProfileConfig::default`].
    #[serde(default)]
    pub profile: ProfileConfig,
}

/// What a fit determines.
#[derive(Clone, Copy, Debug, Default, Deserialize, Serialize, PartialEq, Eq, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum FitMode {
    /// A few parameters shared by every cell (`[parameters]`), by Nelder–Mead or particle swarm.
    #[default]
    Global,
    /// Every cell's own free and lateral tension (a per-cell map), by forward refinement of the
    /// direct estimate ([`super::per_cell`]).
    PerCell,
}

/// The forward refinement of `mode = "per_cell"`: start from the direct estimate of the observed
/// tissue's tensions, relax the tissue with every cell's own tensions, measure the relaxed tissue
/// like the data and estimate its tensions the same way, correct each cell's tensions by the ratio
/// of the observed to the simulated estimate, and repeat until they agree.
#[derive(Clone, Debug, Deserialize, Serialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PerCellConfig {
    /// Most refinement iterations, each one relaxation and one measurement. Default 6.
    #[serde(default = "default_per_cell_iterations")]
    pub iterations: usize,
    /// Converged when the rms relative difference between the simulated and the observed estimate,
    /// over every determined interface (cell–cell and cell–medium), falls below this. Default 0.02.
    #[serde(default = "default_per_cell_tolerance")]
    pub tolerance: Real,
    /// The mean free-surface (cell–medium) tension of the moving cells, N/m: the scale a shape cannot
    /// tell (every tension of the map is relative to it). Default: the base model's apical tension
    /// of the first moving cell's type.
    #[serde(default)]
    pub free_tension: Option<Real>,
    /// The fraction of the logarithmic correction applied per iteration: each tension is multiplied
    /// by (observed/simulated)^step (and by at most ×/÷ 1.25). Below 1 it damps the forward model's
    /// noise (a relaxation one bit apart can move a junction); 1 takes the whole correction.
    /// Default 0.5.
    #[serde(default = "default_per_cell_step")]
    pub step: Real,
    /// Start each relaxation from the previous iteration's relaxed tissue instead of the observed
    /// one. Faster to settle, but the result then depends on the path. Default false.
    #[serde(default)]
    pub warm_start: bool,
    /// The error of the map that neither the mismatch nor the placements show (the forward model's
    /// measurement bias), added to each refined tension's `tension_sd` as a relative standard error
    /// m = √(floor² + (coefficient × voxel size / mean cell diameter)²): `cell_cell = 0.3` with no
    /// floor adds 3 % at 10 voxels per diameter, 1.5 % at 20 (a mesh input, with no voxel, gets the
    /// floor). The same form for each cell's `pressure_sd` and `lateral_tension_sd` (`pressure`,
    /// `lateral`). Defaults calibrated on Surface Evolver truths so that ±1 sd holds 68 % of them
    /// (the docs book, Per-cell maps; `docs/scripts/per-cell.sh coverage`).
    #[serde(default)]
    pub model_error: ModelErrorConfig,
    /// With spring contacts (a map of adhesions), every model error of `model_error` is multiplied
    /// by this: the spring model makes the maps less closely than the coupled one the defaults were
    /// calibrated on. Default 1.6, calibrated so that ±1 sd holds 68 % of the interfaces of 12
    /// Surface Evolver clusters (`docs/scripts/per-cell.sh adhesion`).
    #[serde(default = "default_spring_model_error")]
    pub spring_model_error: Real,
}

fn default_spring_model_error() -> Real {
    1.6
}

/// `per_cell.model_error`: relative standard errors, a coefficient per (voxel size / mean cell
/// diameter) and a floor, for cell–cell and for cell–medium interfaces. The defaults are
/// `validation/per_cell/coverage.py`'s calibration on its 36 Surface Evolver truths (clusters of
/// 4–6 cells, seeds 1–12, at 10 and 20 voxels per diameter), rounded.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ModelErrorConfig {
    /// Cell–cell interfaces: the relative error per voxel size over cell diameter.
    #[serde(default = "default_model_error_cell_cell")]
    pub cell_cell: Real,
    /// Cell–medium interfaces (free surfaces): the same.
    #[serde(default = "default_model_error_cell_medium")]
    pub cell_medium: Real,
    /// The relative error that does not shrink with the voxel size, cell–cell.
    #[serde(default = "default_model_error_cell_cell_floor")]
    pub cell_cell_floor: Real,
    /// The same, cell–medium.
    #[serde(default = "default_model_error_cell_medium_floor")]
    pub cell_medium_floor: Real,
    /// Cell pressures (`pressure_sd` of cells.csv): the relative error per voxel size over cell
    /// diameter that the sd of the tension holding the cell does not carry (the relaxed shape's
    /// curvature and volume against the data's).
    #[serde(default = "default_model_error_pressure")]
    pub pressure: Real,
    /// The same, the part that does not shrink with the voxel size.
    #[serde(default = "default_model_error_pressure_floor")]
    pub pressure_floor: Real,
    /// A cell's lateral tension (`lateral_tension_sd` of cells.csv): the relative error per voxel
    /// size over cell diameter that the least squares through the cell–cell interfaces' sds does
    /// not carry (their errors are not independent).
    #[serde(default = "default_model_error_lateral")]
    pub lateral: Real,
    /// The same, the part that does not shrink with the voxel size.
    #[serde(default = "default_model_error_lateral_floor")]
    pub lateral_floor: Real,
}

impl Default for ModelErrorConfig {
    fn default() -> Self {
        toml::from_str("").expect("all defaults")
    }
}

impl ModelErrorConfig {
    /// The relative model error of a cell–cell (`free` false) or cell–medium interface at
    /// `resolution` = voxel size / mean cell diameter (`None`: a mesh input, the floor alone).
    pub fn at(&self, free: bool, resolution: Option<Real>) -> Real {
        if free {
            combined(self.cell_medium, self.cell_medium_floor, resolution)
        } else {
            combined(self.cell_cell, self.cell_cell_floor, resolution)
        }
    }

    /// The relative model error of a cell's pressure at `resolution` (as [`Self::at`]).
    pub fn pressure_at(&self, resolution: Option<Real>) -> Real {
        combined(self.pressure, self.pressure_floor, resolution)
    }

    /// The relative model error of a cell's lateral tension at `resolution` (as [`Self::at`]).
    pub fn lateral_at(&self, resolution: Option<Real>) -> Real {
        combined(self.lateral, self.lateral_floor, resolution)
    }
}

/// √(floor² + (coefficient × resolution)²); the floor alone without a resolution (a mesh input).
fn combined(coefficient: Real, floor: Real, resolution: Option<Real>) -> Real {
    floor.hypot(coefficient * resolution.unwrap_or(0.0))
}

fn default_model_error_cell_cell() -> Real {
    0.16
}

fn default_model_error_cell_medium() -> Real {
    0.223
}

fn default_model_error_cell_cell_floor() -> Real {
    0.0289
}

fn default_model_error_cell_medium_floor() -> Real {
    0.0204
}

fn default_model_error_pressure() -> Real {
    0.273
}

fn default_model_error_pressure_floor() -> Real {
    0.00711
}

fn default_model_error_lateral() -> Real {
    0.583
}

fn default_model_error_lateral_floor() -> Real {
    0.0156
}

fn default_per_cell_step() -> Real {
    0.5
}

fn default_per_cell_iterations() -> usize {
    6
}
fn default_per_cell_tolerance() -> Real {
    0.02
}

impl Default for PerCellConfig {
    fn default() -> Self {
        toml::from_str("").expect("all defaults")
    }
}

/// The observed input: exactly one of `tissue` or `labels`.
#[derive(Clone, Debug, Deserialize, Serialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ObservedConfig {
    /// A tissue mesh file (.vtk or .vtp, lengths in `length_unit`).
    #[serde(default)]
    pub tissue: Option<PathBuf>,
    /// A label volume (TIFF stack, OME-Zarr .zarr folder, HDF5 .h5 dataset or NumPy .npy), meshed first with
    /// `[observed.meshing]`.
    #[serde(default)]
    pub labels: Option<PathBuf>,
    /// Length unit of the tissue file's coordinates (as `--length-unit`). Default "m".
    #[serde(default = "default_length_unit")]
    pub length_unit: String,
    /// With `tissue`: re-triangulate every cell through a voxelisation (as `tissuefit mesh X.vtp`)
    /// with `meshing`, `voxel_size` setting the grid (default l_min/2). Default false.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub retriangulate: bool,
    /// Voxel size `[z, y, x]` (m) of the label volume instead of its metadata (a .npy has none: give
    /// it here); with `tissue` and `retriangulate`, of the voxelisation's grid. Default: the
    /// metadata, or l_min/2.
    #[serde(default)]
    pub voxel_size: Option<[Real; 3]>,
    /// OME-Zarr `labels` only: the multiscales scale level to read (0 = full resolution). Default 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub zarr_level: Option<usize>,
    /// How the label volume is meshed (the options of `tissuefit mesh`).
    #[serde(default)]
    pub meshing: LabelMeshingOptions,
}

impl ObservedConfig {
    /// How `labels` is read: with `voxel_size` and `zarr_level` where given.
    pub fn read_options(&self) -> crate::imaging::LabelReadOptions {
        crate::imaging::LabelReadOptions {
            voxel_size: self.voxel_size,
            zarr_level: self.zarr_level,
            ..Default::default()
        }
    }
}

fn default_length_unit() -> String {
    "m".to_string()
}

/// One parameter: fitted within `bounds` (SI units), or fixed at `value`.
#[derive(Clone, Debug, Deserialize, Serialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ParameterConfig {
    /// Search interval `[lo, hi]` (SI, 0 < lo < hi); searched in log space. Absent: fixed.
    #[serde(default)]
    pub bounds: Option<[Real; 2]>,
    /// Fixed value (SI), e.g. a tension measured by micropipette aspiration; excludes `bounds`.
    #[serde(default)]
    pub value: Option<Real>,
    /// Start of the search (SI, within bounds). Default: the geometric mean of the bounds.
    #[serde(default)]
    pub initial: Option<Real>,
}

/// Objective: Σ wᵢ·((simᵢ − obsᵢ)/sᵢ)² / Σ wᵢ over the metrics defined in both tissues, plus
/// w_shape·(mean(1 − IoU)/s_shape)². A scale sᵢ is the difference one is willing to call "one unit
/// of misfit" (a measurement tolerance); the objective is then a mean squared misfit in those units,
/// and the profile's acceptance threshold ([`ProfileConfig::acceptable_increase`]) is in the same units.
#[derive(Clone, Debug, Deserialize, Serialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ObjectiveConfig {
    /// Weight of the mean sphericity. Default 1.
    #[serde(default = "one")]
    pub sphericity: Real,
    /// Weight of the mean contact-area fraction φ. Default 1.
    #[serde(default = "one")]
    pub contact_fraction: Real,
    /// Weight of the mean coordination number z. Default 1.
    #[serde(default = "one")]
    pub coordination: Real,
    /// Weight of the mean rim contact angle (where contacts have one). Default 1.
    #[serde(default = "one")]
    pub contact_angle: Real,
    /// Weight of the shape term mean(1 − IoU) of each cell against its observed voxels (needs a
    /// label-volume input). Default 0 (off).
    #[serde(default)]
    pub shape: Real,
    /// Scale of sphericity differences. Default 0.005.
    #[serde(default = "default_sphericity_scale")]
    pub sphericity_scale: Real,
    /// Scale of contact-fraction differences. Default 0.01.
    #[serde(default = "default_fraction_scale")]
    pub contact_fraction_scale: Real,
    /// Scale of coordination differences. Default 0.25 (a quarter neighbour).
    #[serde(default = "default_coordination_scale")]
    pub coordination_scale: Real,
    /// Scale of contact-angle differences (degrees). Default 1°.
    #[serde(default = "one")]
    pub contact_angle_scale: Real,
    /// Scale of the shape term. Default 0.02.
    #[serde(default = "default_shape_scale")]
    pub shape_scale: Real,
    /// Objective of a failed or unconverged simulation. Default 1e6.
    #[serde(default = "default_penalty")]
    pub failure_penalty: Real,
}

impl ObjectiveConfig {
    /// The weight of metric `m`.
    pub fn weight(&self, m: super::forward::Metric) -> Real {
        use super::forward::Metric;
        match m {
            Metric::Sphericity => self.sphericity,
            Metric::ContactFraction => self.contact_fraction,
            Metric::Coordination => self.coordination,
            Metric::ContactAngle => self.contact_angle,
            Metric::Shape => self.shape,
        }
    }

    /// The scale of metric `m`'s differences.
    pub fn scale(&self, m: super::forward::Metric) -> Real {
        use super::forward::Metric;
        match m {
            Metric::Sphericity => self.sphericity_scale,
            Metric::ContactFraction => self.contact_fraction_scale,
            Metric::Coordination => self.coordination_scale,
            Metric::ContactAngle => self.contact_angle_scale,
            Metric::Shape => self.shape_scale,
        }
    }
}

fn one() -> Real {
    1.0
}
fn default_sphericity_scale() -> Real {
    0.005
}
fn default_fraction_scale() -> Real {
    0.01
}
fn default_coordination_scale() -> Real {
    0.25
}
fn default_shape_scale() -> Real {
    0.02
}
fn default_penalty() -> Real {
    1e6
}

impl Default for ObjectiveConfig {
    fn default() -> Self {
        toml::from_str("").expect("all defaults")
    }
}

/// Which optimiser.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq, Eq, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum OptimizerMethod {
    /// argmin's Nelder–Mead on the log parameters; bounds by clamping plus a quadratic penalty.
    NelderMead,
    /// argmin's particle swarm, bounded in log space, seeded.
    ParticleSwarm,
}

/// The optimiser.
#[derive(Clone, Debug, Deserialize, Serialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct OptimizerConfig {
    /// "nelder_mead" (default) or "particle_swarm".
    #[serde(default = "default_method")]
    pub method: OptimizerMethod,
    /// Budget of distinct simulations (cache hits are free). Default 60.
    #[serde(default = "default_max_evaluations")]
    pub max_evaluations: usize,
    /// Nelder–Mead stops when the standard deviation of the simplex's objectives falls below this.
    /// Particle swarm stops when the objective falls below it. Default 1e-3.
    #[serde(default = "default_tolerance")]
    pub tolerance: Real,
    /// Seed of the swarm's random draws. Default 1.
    #[serde(default = "default_seed")]
    pub seed: u64,
    /// Particles of the swarm. Default 8.
    #[serde(default = "default_swarm")]
    pub swarm_size: usize,
    /// Nelder–Mead initial simplex edge, as a fraction of each parameter's log-range. Default 0.25.
    #[serde(default = "default_simplex")]
    pub initial_simplex: Real,
    /// Nelder–Mead: when the objectives' spread has fallen below `tolerance` but the best n + 1
    /// points still lie further apart than this fraction of a parameter's log-range (a simplex
    /// straddling the minimum), it restarts around the best point with half that width. Default 0.02.
    #[serde(default = "default_simplex_tolerance")]
    pub simplex_tolerance: Real,
}

fn default_simplex_tolerance() -> Real {
    0.02
}

fn default_method() -> OptimizerMethod {
    OptimizerMethod::NelderMead
}
fn default_max_evaluations() -> usize {
    60
}
fn default_tolerance() -> Real {
    1e-3
}
fn default_seed() -> u64 {
    1
}
fn default_swarm() -> usize {
    8
}
fn default_simplex() -> Real {
    0.25
}

impl Default for OptimizerConfig {
    fn default() -> Self {
        toml::from_str("").expect("all defaults")
    }
}

/// The forward simulation (every evaluation).
#[derive(Clone, Debug, Deserialize, Serialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ForwardConfig {
    /// Overrides simulation.max_steps of the model. Default: the model's.
    #[serde(default)]
    pub max_steps: Option<u64>,
    /// Overrides simulation.settle_steps of the model: the last steps of every relaxation pass run
    /// without remeshing, so it ends on a fixed mesh where the shape stops changing (an adhesive
    /// spring aggregate remeshed to the end keeps creeping, and then where each evaluation
    /// happened to stop, not its parameters, sets the metrics). Default: the model's.
    #[serde(default)]
    pub settle_steps: Option<u64>,
    /// An unconverged run whose final residual (max force / γ̄·l_min) is at most this is still
    /// measured and used (the coupling model's residual hovers at 0.005–0.2 while the shape has
    /// settled). Default 0: every unconverged run is penalised.
    #[serde(default)]
    pub accept_residual: Real,
    /// When the observed tissue was meshed from labels, set numerics.min_edge_length and
    /// numerics.contact_cutoff to the meshing's l_min. Default true.
    #[serde(default = "yes")]
    pub match_mesh_length: bool,
    /// When the observed input is a label volume, voxelise each relaxed tissue on its grid and mesh it
    /// again with the same options (and l_min) before measuring, so that simulated and observed
    /// morphology go through the same measurement (the biases of voxelisation and meshing — gaps at
    /// contacts, rounded rims — then cancel instead of being fitted). Default true.
    #[serde(default = "yes")]
    pub measure_like_data: bool,
    /// Corrections of the cells' target volumes V0 after the first relaxation. The first relaxation
    /// starts each moving cell at its Laplace target volume (the V0 whose pressure 2γ̄/R holds it at
    /// its observed volume; the observed volume is data, V0 is not: starting with V0 = V_observed
    /// would shrink every cell by exp(−p/K)); each pass then sets V0 from the pressure the cell has,
    /// p = K·ln(V0/V), scaled like a Laplace pressure to the wanted volume, and relaxes again from
    /// where it stopped, so the equilibrium volumes match the observed ones (measured like the data
    /// with `measure_like_data`). 0: the Laplace start only. Default 2.
    #[serde(default = "default_volume_passes")]
    pub volume_passes: usize,
    /// With `measure_like_data`: how many rigid sub-voxel shifts of each relaxed tissue are
    /// voxelised, meshed and measured, and their metrics averaged (1: the tissue as it lies). Where
    /// the tissue falls on the voxel grid changes its labels and hence the re-meshed metrics (±0.007
    /// in φ on a spring aggregate at 10 voxels per diameter); the average measures the shape. Costs
    /// one voxelisation and meshing per shift (run in parallel). Default 1.
    #[serde(default = "one_shift")]
    pub measure_shifts: usize,
    /// With `measure_like_data`: the boundary noise the observed mask carries, added to every simulated
    /// mask before it is meshed (`tissuefit generate noise` with this amplitude, each sub-voxel shift
    /// its own fixed seed), so that the roughness a segmenter left in the data is measured in the
    /// simulation too instead of being read as shape. RMS displacement of the boundaries in voxels
    /// (about 1 for a typical segmentation; 0: none), or `"auto"`: estimated before the fit, by
    /// relaxing the start point and roughening its mask until its boundaries are as rough as the
    /// observed ones (result.json's `roughen`). The profile then allows for the scatter one draw of
    /// that noise causes (result.json's `noise.mask`). Default 0.
    #[serde(default)]
    pub roughen_voxels: Roughen,
    /// Width (Gaussian σ, voxels) of the bumps of `roughen_voxels`: 0 independent from voxel to voxel,
    /// 1–2 the wavy boundaries of a smooth segmentation error. Default 1.5.
    #[serde(default = "default_roughen_correlation")]
    pub roughen_correlation: Real,
}

/// `forward.roughen_voxels`: an amplitude in voxels, or `"auto"`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, JsonSchema)]
#[serde(untagged)]
pub enum Roughen {
    /// This RMS displacement (voxels).
    Voxels(Real),
    /// Estimated from the observed mask.
    Estimate(RoughenEstimate),
}

/// The word `"auto"`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize, JsonSchema)]
#[serde(rename_all = "lowercase")]
pub enum RoughenEstimate {
    Auto,
}

impl<'de> Deserialize<'de> for Roughen {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Visitor;
        impl serde::de::Visitor<'_> for Visitor {
            type Value = Roughen;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("forward.roughen_voxels: a number of voxels (about 1 for a segmentation's error; 0: none) or \"auto\"")
            }
            fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<Roughen, E> {
                Ok(Roughen::Voxels(v))
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<Roughen, E> {
                Ok(Roughen::Voxels(v as Real))
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<Roughen, E> {
                Ok(Roughen::Voxels(v as Real))
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<Roughen, E> {
                match v {
                    "auto" => Ok(Roughen::Estimate(RoughenEstimate::Auto)),
                    other => Err(E::custom(format!(
                        "forward.roughen_voxels: expected a number of voxels or \"auto\"; got \"{other}\""
                    ))),
                }
            }
        }
        d.deserialize_any(Visitor)
    }
}

impl Default for Roughen {
    fn default() -> Self {
        Roughen::Voxels(0.0)
    }
}

fn default_roughen_correlation() -> Real {
    1.5
}

fn one_shift() -> usize {
    1
}

fn default_volume_passes() -> usize {
    2
}

fn yes() -> bool {
    true
}

impl Default for ForwardConfig {
    fn default() -> Self {
        toml::from_str("").expect("all defaults")
    }
}

/// The profile of the objective along each fitted parameter after the optimum.
#[derive(Clone, Debug, Deserialize, Serialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ProfileConfig {
    /// Points on each side of the optimum per parameter (0: no profile). Default 3.
    #[serde(default = "default_profile_points")]
    pub points: usize,
    /// Largest step from the optimum, as a factor (the points are geometric, up to ×/÷ this).
    /// Default 2.
    #[serde(default = "default_profile_span")]
    pub span: Real,
    /// A point is acceptable when its objective is at most best + this (objective units, i.e. one
    /// scale of misfit by default). Default 1.
    #[serde(default = "one")]
    pub acceptable_increase: Real,
    /// Extra evaluations at the optimum, each with every fitted parameter × (1 + k·1e-9), k = 1…n:
    /// the same model up to round-off, so their spread (with the best's) is the forward model's
    /// noise floor σ (a chaotic relaxation ends elsewhere from a one-bit change; see the docs book, "Forward-model noise").
    /// The profile's threshold becomes mean + `acceptable_increase` + `noise_sigmas`·σ, so a range
    /// narrower than the noise is never reported. 0: no estimate (σ taken as 0). Default 2.
    #[serde(default = "default_noise_replicates")]
    pub noise_replicates: usize,
    /// How many σ of forward-model noise widen the acceptance threshold (see `noise_replicates`).
    /// Default 2.
    #[serde(default = "default_noise_sigmas")]
    pub noise_sigmas: Real,
    /// Relative error of the forward model itself, added in quadrature (in log space) to both sides
    /// of every closed range of a parameter or ratio: a range from the objective alone holds only
    /// the data's and the forward model's noise, not the model's systematic difference from a real
    /// foam. Default 0.05, the size of the systematic errors (3–7 %) of the fits of the Surface
    /// Evolver doublet, triplet and tetrahedral clusters at 10–40 voxels per diameter (docs:
    /// validation, "Surface Evolver clusters"); 0: noise only.
    #[serde(default = "default_model_error")]
    pub model_error: Real,
}

fn default_model_error() -> Real {
    0.05
}

fn default_noise_replicates() -> usize {
    2
}
fn default_noise_sigmas() -> Real {
    2.0
}

fn default_profile_points() -> usize {
    3
}
fn default_profile_span() -> Real {
    2.0
}

impl Default for ProfileConfig {
    fn default() -> Self {
        toml::from_str("").expect("all defaults")
    }
}

impl FitConfig {
    /// Reads a config file; relative paths inside become relative to its folder.
    pub fn load(path: &Path) -> Result<Self, InferenceError> {
        let text = crate::io::read_text_capped(path, crate::io::MAX_CONFIG_FILE)
            .map_err(|e| InferenceError::Config(format!("reading {}: {e}", path.display())))?;
        let mut config = Self::from_toml_str(&text, &path.display().to_string())?;
        config.resolve_paths(path.parent().unwrap_or(Path::new(".")));
        Ok(config)
    }

    /// Reads a config file that may leave `[observed]` out (its input comes from elsewhere: the
    /// frames of `tissuefit fit-series`); everything else is checked as [`FitConfig::load`] does.
    pub fn load_without_observed(path: &Path) -> Result<Self, InferenceError> {
        let text = crate::io::read_text_capped(path, crate::io::MAX_CONFIG_FILE)
            .map_err(|e| InferenceError::Config(format!("reading {}: {e}", path.display())))?;
        let origin = path.display();
        let mut config: Self = toml::from_str(&text).map_err(|e| InferenceError::Config(format!("{origin}: {e}")))?;
        match config.observed {
            None => config.check_settings(),
            Some(_) => config.check(),
        }
        .map_err(|e| InferenceError::Config(format!("{origin}: {e}")))?;
        config.resolve_paths(path.parent().unwrap_or(Path::new(".")));
        Ok(config)
    }

    /// Makes the config's relative paths (observed tissue or labels, model) relative to `base`.
    pub fn resolve_paths(&mut self, base: &Path) {
        let fix = |p: &mut PathBuf| {
            if p.is_relative() {
                *p = base.join(&*p);
            }
        };
        if let Some(observed) = &mut self.observed {
            observed.tissue.as_mut().map(fix);
            observed.labels.as_mut().map(fix);
        }
        self.model.as_mut().map(fix);
    }

    /// Parses and checks TOML text; `origin` names it in errors.
    pub fn from_toml_str(text: &str, origin: &str) -> Result<Self, InferenceError> {
        let config: Self = toml::from_str(text).map_err(|e| InferenceError::Config(format!("{origin}: {e}")))?;
        config.check().map_err(|e| InferenceError::Config(format!("{origin}: {e}")))?;
        Ok(config)
    }

    /// The observed input, or an error naming the missing section.
    pub fn observed(&self) -> Result<&ObservedConfig, InferenceError> {
        self.observed
            .as_ref()
            .ok_or_else(|| InferenceError::Config("[observed]: missing; give `tissue` or `labels`".into()))
    }

    /// Consistency checks beyond the schema; the message names the key.
    fn check(&self) -> Result<(), String> {
        let Some(observed) = &self.observed else {
            return Err("[observed]: missing; give `tissue` (a mesh file) or `labels` (a label TIFF)".into());
        };
        match (&observed.tissue, &observed.labels) {
            (Some(_), Some(_)) => return Err("observed: give `tissue` or `labels`, not both".into()),
            (None, None) => return Err("observed: give `tissue` (a mesh file) or `labels` (a label TIFF)".into()),
            _ => {}
        }
        if observed.retriangulate && observed.tissue.is_none() {
            return Err("observed.retriangulate: applies to a `tissue` input (labels are meshed anyway)".into());
        }
        if observed.zarr_level.is_some() && observed.labels.is_none() {
            return Err("observed.zarr_level: applies to an OME-Zarr `labels` input, not to a tissue".into());
        }
        if let Some(v) = observed.voxel_size
            && let Some(bad) = v.iter().find_map(|&l| crate::io::implausible_length("observed.voxel_size", l))
        {
            return Err(bad);
        }
        if let Some(bad) =
            observed.meshing.l_min.and_then(|l| crate::io::implausible_length("observed.meshing.l_min", l))
        {
            return Err(bad);
        }
        self.check_settings()
    }

    /// The checks of everything but `[observed]` (parameters, objective, optimiser, forward,
    /// profile); a pipeline runs these on its `[fit]` section.
    pub fn check_settings(&self) -> Result<(), String> {
        let global = self.mode == FitMode::Global;
        if self.parameters.is_empty() && global {
            return Err("parameters: name at least one parameter to fit (or set mode = \"per_cell\")".into());
        }
        let mut fitted = 0;
        for (name, p) in &self.parameters {
            // w/(2γ): dimensionless, at most 2 (cos(θ/2) = 1 − w/(2γ) ≥ −1).
            let ratio = name == super::ADHESION_RATIO;
            let parameter = super::FitParameter::from_name(name);
            if parameter.is_none() && !ratio {
                return Err(format!(
                    "parameters.{name}: unknown parameter; one of {}, {}",
                    super::PARAMETER_NAMES.join(", "),
                    super::ADHESION_RATIO
                ));
            }
            let is_tension = parameter.is_some_and(|p| p.is_tension());
            if ratio && let Some(v) = p.bounds.map(|b| b[1]).or(p.value).filter(|&v| v > 2.0) {
                return Err(format!(
                    "parameters.{name}: w/(2γ) = {v} > 2 has no Young–Dupré angle (cos(θ/2) = 1 − w/(2γ) ≥ −1); \
                     it is dimensionless: did you give ω in Pa/m? (that is `parameters.adhesion`)"
                ));
            }
            if ratio && let Some(m) = super::space::adhesion_ratio_conflict(&self.parameters) {
                return Err(format!("parameters.{name}: {m}"));
            }
            match (p.bounds, p.value) {
                (Some(_), Some(_)) => return Err(format!("parameters.{name}: give `bounds` or `value`, not both")),
                (None, None) => return Err(format!("parameters.{name}: give `bounds` (to fit) or `value` (fixed)")),
                (Some([lo, hi]), None) => {
                    if !(lo > 0.0 && hi > lo && hi.is_finite()) {
                        return Err(format!("parameters.{name}.bounds: need 0 < lo < hi, finite; got [{lo}, {hi}]"));
                    }
                    if is_tension
                        && let Some(bad) = [lo, hi]
                            .iter()
                            .find_map(|&g| crate::io::implausible_tension(&format!("parameters.{name}.bounds"), g))
                    {
                        return Err(bad);
                    }
                    if let Some(x) = p.initial
                        && !(x >= lo && x <= hi)
                    {
                        return Err(format!("parameters.{name}.initial: {x} lies outside the bounds [{lo}, {hi}]"));
                    }
                    fitted += 1;
                }
                (None, Some(v)) => {
                    if !(v.is_finite() && v >= 0.0) {
                        return Err(format!("parameters.{name}.value: need a finite value ≥ 0; got {v}"));
                    }
                    if is_tension
                        && let Some(bad) = crate::io::implausible_tension(&format!("parameters.{name}.value"), v)
                    {
                        return Err(bad);
                    }
                    if p.initial.is_some() {
                        return Err(format!("parameters.{name}.initial: only a fitted parameter has a start"));
                    }
                }
            }
        }
        if fitted == 0 && global {
            return Err("parameters: every parameter is fixed; give `bounds` to at least one".into());
        }
        let pc = &self.per_cell;
        if pc.iterations == 0 {
            return Err("per_cell.iterations: must be at least 1".into());
        }
        if !(pc.tolerance.is_finite() && pc.tolerance > 0.0 && pc.tolerance < 1.0) {
            return Err(format!(
                "per_cell.tolerance: a relative difference in (0, 1) (0.02 = 2 %); got {}",
                pc.tolerance
            ));
        }
        if !(pc.step > 0.0 && pc.step <= 1.0) {
            return Err(format!(
                "per_cell.step: a fraction in (0, 1] of the correction per iteration; got {}",
                pc.step
            ));
        }
        let m = &pc.model_error;
        for (key, v) in [
            ("cell_cell", m.cell_cell),
            ("cell_medium", m.cell_medium),
            ("cell_cell_floor", m.cell_cell_floor),
            ("cell_medium_floor", m.cell_medium_floor),
            ("pressure", m.pressure),
            ("pressure_floor", m.pressure_floor),
            ("lateral", m.lateral),
            ("lateral_floor", m.lateral_floor),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!(
                    "per_cell.model_error.{key}: a relative error (0.02 = 2 %; the coefficients per voxel size over \
                     cell diameter: 0.3 = 3 % at 10 voxels per diameter), finite and ≥ 0; got {v}"
                ));
            }
        }
        if !(pc.spring_model_error.is_finite() && pc.spring_model_error > 0.0) {
            return Err(format!(
                "per_cell.spring_model_error: a factor > 0 on the model errors of spring maps (1 keeps the coupled \
                 calibration); got {}",
                pc.spring_model_error
            ));
        }
        if let Some(g) = pc.free_tension {
            if !(g.is_finite() && g > 0.0) {
                return Err(format!("per_cell.free_tension: a tension > 0 in N/m; got {g}"));
            }
            if let Some(bad) = crate::io::implausible_tension("per_cell.free_tension", g) {
                return Err(bad);
            }
        }
        let o = &self.objective;
        use super::forward::Metric;
        for m in Metric::ALL {
            let (key, v) = (m.name(), o.weight(m));
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!("objective.{key}: a weight must be finite and ≥ 0; got {v}"));
            }
        }
        let scales = Metric::ALL.map(|m| (format!("{}_scale", m.name()), o.scale(m)));
        for (key, v) in scales.into_iter().chain([("failure_penalty".to_string(), o.failure_penalty)]) {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("objective.{key}: must be finite and > 0; got {v}"));
            }
        }
        if Metric::ALL.iter().map(|&m| o.weight(m)).sum::<Real>() <= 0.0 {
            return Err("objective: every weight is 0".into());
        }
        if o.shape > 0.0 && self.observed.as_ref().is_some_and(|obs| obs.labels.is_none()) {
            return Err("objective.shape: the shape term compares voxels and needs `observed.labels`".into());
        }
        let opt = &self.optimizer;
        if opt.max_evaluations == 0 {
            return Err("optimizer.max_evaluations: must be at least 1".into());
        }
        if !(opt.simplex_tolerance.is_finite() && opt.simplex_tolerance >= 1e-6) {
            return Err(format!(
                "optimizer.simplex_tolerance: must be finite and ≥ 1e-6 (a fraction of each log-range); got {}",
                opt.simplex_tolerance
            ));
        }
        if !(opt.tolerance.is_finite() && opt.tolerance >= 0.0) {
            return Err(format!("optimizer.tolerance: must be finite and ≥ 0; got {}", opt.tolerance));
        }
        if opt.swarm_size < 2 {
            return Err(format!("optimizer.swarm_size: need at least 2 particles; got {}", opt.swarm_size));
        }
        if !(opt.initial_simplex > 0.0 && opt.initial_simplex <= 1.0) {
            return Err(format!("optimizer.initial_simplex: must lie in (0, 1]; got {}", opt.initial_simplex));
        }
        if !(self.forward.accept_residual.is_finite() && self.forward.accept_residual >= 0.0) {
            return Err(format!(
                "forward.accept_residual: must be finite and ≥ 0; got {}",
                self.forward.accept_residual
            ));
        }
        crate::imaging::BoundaryNoise {
            amplitude: match self.forward.roughen_voxels {
                Roughen::Voxels(a) => a,
                Roughen::Estimate(_) => 1.0,
            },
            correlation: self.forward.roughen_correlation,
            seed: 0,
        }
        .check()
        .map_err(|e| format!("forward.roughen_voxels / roughen_correlation: {e}"))?;
        if self.forward.measure_shifts == 0 {
            return Err("forward.measure_shifts: must be ≥ 1 (1: measure the relaxed tissue as it lies)".into());
        }
        if !(self.profile.span > 1.0 && self.profile.span.is_finite()) {
            return Err(format!("profile.span: must be a factor > 1; got {}", self.profile.span));
        }
        if !(self.profile.acceptable_increase > 0.0 && self.profile.acceptable_increase.is_finite()) {
            return Err(format!("profile.acceptable_increase: must be > 0; got {}", self.profile.acceptable_increase));
        }
        if !(self.profile.model_error >= 0.0 && self.profile.model_error < 1.0) {
            return Err(format!(
                "profile.model_error: must be a fraction in [0, 1) (0.05 = 5 %); got {}",
                self.profile.model_error
            ));
        }
        if !(self.profile.noise_sigmas >= 0.0 && self.profile.noise_sigmas.is_finite()) {
            return Err(format!("profile.noise_sigmas: must be ≥ 0 and finite; got {}", self.profile.noise_sigmas));
        }
        Ok(())
    }

    /// The base model: `model` (or the defaults) with `model_overrides` applied, validated.
    /// The values a parameter or key ratio (`lateral_over_apical`, `adhesion_over_tension`) can take
    /// within the search bounds and fixed values of `[parameters]`, and the config keys that set
    /// them; `None` for a name the parameters do not set.
    pub fn reachable(&self, name: &str) -> Option<([Real; 2], Vec<String>)> {
        let one = |n: &str| -> Option<([Real; 2], String)> {
            let p = self.parameters.get(n)?;
            match (p.bounds, p.value) {
                (Some(b), _) => Some((b, format!("parameters.{n}.bounds"))),
                (None, Some(v)) => Some(([v, v], format!("parameters.{n}.value"))),
                (None, None) => None,
            }
        };
        if let Some((range, key)) = one(name) {
            return Some((range, vec![key]));
        }
        let names: Vec<String> = self.parameters.keys().cloned().collect();
        let (_, num, den) = super::ratio_parts(&names).into_iter().find(|(r, _, _)| *r == name)?;
        let ((n, kn), (d, kd)) = (one(num)?, one(den)?);
        if d[0] <= 0.0 {
            return None;
        }
        Some(([n[0] / d[1], n[1] / d[0]], vec![kn, kd]))
    }

    pub fn base_parameters(&self) -> Result<Parameters, InferenceError> {
        Parameters::load_with_overrides(self.model.as_deref(), self.model_overrides.as_ref())
            .map_err(|e| InferenceError::Config(e.to_string()))
    }
}

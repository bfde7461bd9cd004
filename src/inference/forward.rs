//! The forward model of one evaluation: start from the observed tissue, write the candidate
//! parameters into the model, relax to equilibrium (the model's minimiser, FIRE by default), measure
//! the same morphology as on the observed tissue, and score the difference.
//!
//! Objective (see [`ObjectiveConfig`]): J = Σᵢ wᵢ·((simᵢ − obsᵢ)/sᵢ)² / Σᵢ wᵢ over the summary
//! metrics observed in the data (mean sphericity, mean contact-area fraction φ, mean coordination
//! number z, mean rim contact angle), plus w_shape·(mean(1 − IoU)/s_shape)² when the shape term is on
//! (the relaxed cells voxelised on the observed label grid, IoU per cell label). A metric observed but
//! undefined in the simulation (no contact left to have an angle) counts as a misfit of
//! [`MISSING_METRIC_MISFIT`] scales. A run that fails (an error of the simulation or of the
//! measurement) or ends unconverged beyond `forward.accept_residual` scores `failure_penalty`; the
//! reason is kept with the evaluation and the fit goes on.
//!
//! Target volumes: the observed volume is data, V0 is not. With V0 = V_observed every cell would
//! shrink by its pressure (V = V0·exp(−p/K); 36 % on a spring aggregate at K = 2500 Pa) and the
//! relaxation would wander far from the observed shape and back. So the first relaxation starts
//! with the V0 whose Laplace pressure 2γ̄/R holds each cell at its observed volume
//! ([`laplace_start`]), and each of `forward.volume_passes` passes then corrects V0 from the
//! pressure the cell actually has ([`volume_update`]) and relaxes on from there; the equilibrium
//! volumes then match the observed ones and the absolute tension scale drops out of the shape. With
//! `forward.measure_like_data` the simulated volume compared with the observed one is measured like
//! the data too (voxelised and meshed again): that measurement loses 9 % of a cell's volume at 10
//! voxels per diameter, and the observed volumes went through it.
//!
//! Settling: with remeshing every few steps an adhesive (spring) relaxation never converges, and its
//! end point depends on when it stopped. `simulation.settle_steps` (or `forward.settle_steps`)
//! runs the last steps of every pass on a fixed mesh, where the shape stops changing; spring
//! relaxations should also set `simulation.normal_relaxation`.
//!
//! With a label-volume input and `forward.measure_like_data`, each relaxed tissue is voxelised on the
//! observed grid and meshed again with the observed meshing options before it is measured, so
//! simulated and observed morphology pass through the same measurement.
//!
//! One contact distance: faces within δ of another cell count as contact. The surfaces of two
//! touching simulated cells do not coincide (coupled nodes are tied, the faces between them are not;
//! the spring model holds them 0 to c apart), and neither do the separately meshed surfaces of two
//! touching labels, so the contact-area fraction φ and the rim angle depend steeply on δ (on a
//! relaxed 20-cell coupling aggregate φ = 0.28, 0.39, 0.51, 0.61, 0.68 and the rim angle 49° to
//! 109° for δ = 0.05 … 0.45 µm). The default δ is a quarter of each tissue's own mean edge length,
//! and a simulated mesh, remeshed between l_min and 3·l_min, has longer edges than a fresh meshing of
//! the same labels; so every simulation is measured with the observed tissue's δ
//! ([`Observation::contact_distance`]), never its own.
//!
//! Where a relaxed tissue lies on the voxel grid changes its voxelised labels and hence the
//! re-meshed metrics although its shape is the same; `forward.measure_shifts` averages the like-data
//! measurement over rigid sub-voxel shifts ([`shift_offset`]) so that it measures the shape.
//!
//! No warm start: every evaluation starts from the observed tissue, so its result depends on its
//! parameters only (never on which evaluations ran before), which is what makes the cache, the
//! parallel evaluation and the resumption exact. A warm start ([`ForwardModel::evaluate_from`] the
//! equilibrium of a neighbouring point) was measured on the coupled doublet: it ends at another shape
//! than a cold start at the same parameters (with the Laplace start: sphericity −0.0003, but rim
//! angle 71.2° vs 62.9°, 8 scales; before it: sphericity −0.0026, rim angle −5.6°) and saves no steps (the coupling residual hovers, so every pass runs its max_steps); see
//! `tests/integration/fit.rs`, `warm_start_reaches_other_metrics_than_a_cold_start_so_evaluations_start_cold`.

use super::config::{ForwardConfig, ObjectiveConfig, Roughen};
use super::space::ParameterSpace;
use crate::geometry::{Real, Vec3};
use crate::imaging::{BoundaryNoise, LabelVolume, boundary_roughness, label_overlap, perturb_boundaries, voxelize};
use crate::io::{Heartbeat, Watch};
use crate::mechanics::{
    CellTypeParams, CheckpointRequest, ContactModel, NoObserver, Observer, Parameters, Simulation, SimulationSummary,
};
use crate::mesh::Tissue;
use crate::meshing::{LabelMeshingOptions, mesh_labels};
use crate::morphology::{Distribution, MeasureSettings, measure_tissue};
use rayon::prelude::*;
use serde::Serialize;
use std::borrow::Cow;
use std::time::Instant;

/// Seed of the first measurement's roughening noise (`forward.roughen_voxels`); measurement k uses this + k.
const ROUGHEN_SEED: u64 = 0x005e_ed0f_0000;

/// Draw `k` of the roughening noise (seed [`ROUGHEN_SEED`] + k).
fn noise_draw(amplitude: Real, correlation: Real, k: u64) -> BoundaryNoise {
    BoundaryNoise { amplitude, correlation, seed: ROUGHEN_SEED + k }
}

/// Misfit (in scales) of a metric that the data have and the simulation lacks.
pub const MISSING_METRIC_MISFIT: Real = 10.0;

/// The summary metrics compared by the objective (`None`: undefined for that tissue).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Metrics {
    pub sphericity: Option<Real>,
    pub contact_fraction: Option<Real>,
    pub coordination: Option<Real>,
    /// Mean rim contact angle (degrees).
    pub contact_angle: Option<Real>,
    /// Mean 1 − IoU of the cells against their observed voxels (only with the shape term).
    pub shape: Option<Real>,
}

/// One metric of [`Metrics`]; its name is the field's, the trace column's and the objective weight's.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Metric {
    Sphericity,
    ContactFraction,
    Coordination,
    ContactAngle,
    Shape,
}

impl Metric {
    /// Every metric, in field (and trace column) order.
    pub const ALL: [Metric; 5] =
        [Metric::Sphericity, Metric::ContactFraction, Metric::Coordination, Metric::ContactAngle, Metric::Shape];
    /// The tissue summaries the objective averages with their weights; the shape term is added apart.
    pub const SUMMARY: [Metric; 4] =
        [Metric::Sphericity, Metric::ContactFraction, Metric::Coordination, Metric::ContactAngle];

    pub const fn name(self) -> &'static str {
        match self {
            Metric::Sphericity => "sphericity",
            Metric::ContactFraction => "contact_fraction",
            Metric::Coordination => "coordination",
            Metric::ContactAngle => "contact_angle",
            Metric::Shape => "shape",
        }
    }
}

impl Metrics {
    /// Names of the metric columns, in [`Metric::ALL`] order.
    pub const NAMES: [&'static str; 5] = [
        Metric::Sphericity.name(),
        Metric::ContactFraction.name(),
        Metric::Coordination.name(),
        Metric::ContactAngle.name(),
        Metric::Shape.name(),
    ];

    pub fn get(&self, m: Metric) -> Option<Real> {
        match m {
            Metric::Sphericity => self.sphericity,
            Metric::ContactFraction => self.contact_fraction,
            Metric::Coordination => self.coordination,
            Metric::ContactAngle => self.contact_angle,
            Metric::Shape => self.shape,
        }
    }

    pub fn get_mut(&mut self, m: Metric) -> &mut Option<Real> {
        match m {
            Metric::Sphericity => &mut self.sphericity,
            Metric::ContactFraction => &mut self.contact_fraction,
            Metric::Coordination => &mut self.coordination,
            Metric::ContactAngle => &mut self.contact_angle,
            Metric::Shape => &mut self.shape,
        }
    }

    /// The values in [`Metric::ALL`] order.
    pub fn values(&self) -> [Option<Real>; 5] {
        Metric::ALL.map(|m| self.get(m))
    }

    /// The summary metrics of a tissue (not the shape term), faces within `contact_distance` δ (m) of
    /// another cell counting as contact (`None`: a quarter of the tissue's own mean edge length), and
    /// the δ used. Always the distance rule, even on an observed tissue whose faces carry interface
    /// labels: the simulated tissues carry none, and the fit compares like with like (the rule's bias,
    /// +0.2…+12 % on contact areas of a multi-material mesh, then cancels).
    pub fn measure(tissue: &Tissue, contact_distance: Option<Real>) -> Result<(Self, Real), String> {
        let settings = MeasureSettings { contact_distance, interface_labels: false, ..MeasureSettings::default() };
        let m = measure_tissue(tissue, &settings).map_err(|e| format!("measuring: {e}"))?;
        let s = &m.summary;
        let delta = s.contact_distance.ok_or("measuring: no contact distance")?;
        let metrics = Self {
            sphericity: s.mean_sphericity,
            contact_fraction: s.mean_contact_fraction,
            coordination: s.mean_coordination,
            contact_angle: s.mean_contact_angle_deg,
            shape: None,
        };
        Ok((metrics, delta))
    }
}

/// How an evaluation ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// Reached the equilibrium criterion.
    Converged,
    /// Unconverged, but the residual is within `forward.accept_residual`: measured and used.
    Accepted,
    /// Unconverged beyond `forward.accept_residual`: penalised.
    Unconverged,
    /// The simulation or the measurement failed: penalised.
    Failed,
}

impl Status {
    pub fn name(self) -> &'static str {
        match self {
            Status::Converged => "converged",
            Status::Accepted => "accepted",
            Status::Unconverged => "unconverged",
            Status::Failed => "failed",
        }
    }

    pub fn from_name(s: &str) -> Option<Self> {
        [Status::Converged, Status::Accepted, Status::Unconverged, Status::Failed].into_iter().find(|v| v.name() == s)
    }

    /// Whether the run's morphology is used (not penalised).
    pub fn usable(self) -> bool {
        matches!(self, Status::Converged | Status::Accepted)
    }
}

/// One evaluation of the forward model.
#[derive(Clone, Debug, PartialEq)]
pub struct Evaluation {
    /// The point (natural logs of the fitted parameters, clamped into the bounds).
    pub x: Vec<Real>,
    pub metrics: Metrics,
    pub objective: Real,
    pub status: Status,
    /// Why a run was penalised (empty otherwise).
    pub reason: String,
    pub steps: u64,
    /// Final residual (max force / γ̄·l_min); NaN when the run failed before ending.
    pub residual: Real,
    pub wall_seconds: Real,
    /// Seconds of the whole fit (every session of a resumed fit) when this evaluation was recorded in
    /// the trace; NaN until the evaluator records it, and in traces written before this column.
    pub elapsed_seconds: Real,
}

/// The observed data the forward model compares against.
#[derive(Clone, Debug)]
pub struct Observation {
    /// The tissue every evaluation starts from.
    pub tissue: Tissue,
    /// The observed label volume (for the shape term), when the input was one.
    pub labels: Option<LabelVolume>,
    /// Labels of the cells whose IoU the shape term averages (the moving cells).
    pub cell_labels: Vec<u32>,
    pub metrics: Metrics,
    /// Length scale l = ⟨V⟩^(1/3) of the moving cells (m), for the dimensionless groups.
    pub length_scale: Real,
    /// l_min of the meshing, when the tissue was meshed from labels.
    pub l_min: Option<Real>,
    /// How the labels were meshed (with the l_min used), to measure simulations the same way.
    pub meshing: Option<LabelMeshingOptions>,
    /// Contact distance δ (m) of the observed measurement (a quarter of its mean edge length); every
    /// simulation is measured with this same δ (see the module doc).
    pub contact_distance: Real,
}

impl Observation {
    /// Measures an observed tissue; with the label volume it was meshed from and the meshing options
    /// (l_min set to the one used) when it came from labels.
    pub fn new(
        tissue: Tissue,
        labels: Option<LabelVolume>,
        meshing: Option<LabelMeshingOptions>,
    ) -> Result<Self, super::InferenceError> {
        let l_min = meshing.as_ref().and_then(|m| m.l_min);
        if crate::morphology::sheet::is_sheet(&tissue) {
            return Err(super::InferenceError::Observed(format!(
                "the observed tissue is a 2.5-D cell sheet ({} open cell patches of one surface): the model needs \
                 closed 3-D cells to fit; `tissuefit tensions` maps a sheet's wall tensions",
                tissue.len()
            )));
        }
        let moving: Vec<&crate::mesh::Cell> =
            tissue.cells().iter().filter(|c| c.kind().is_cell() && !c.kind().is_immobile()).collect();
        if moving.is_empty() {
            return Err(super::InferenceError::Observed(no_moving_cell(&tissue, meshing.as_ref())));
        }
        let (metrics, contact_distance) = Metrics::measure(&tissue, None).map_err(super::InferenceError::Observed)?;
        let mean_volume = moving.iter().map(|c| c.mesh().signed_volume()).sum::<Real>() / moving.len() as Real;
        if mean_volume.is_nan() || mean_volume <= 0.0 {
            return Err(super::InferenceError::Observed(format!(
                "the observed cells' mean volume is {mean_volume:e} m³; cells must enclose a positive volume"
            )));
        }
        let cell_labels = moving.iter().map(|c| c.id().0).collect();
        Ok(Self {
            tissue,
            labels,
            cell_labels,
            metrics,
            length_scale: mean_volume.cbrt(),
            l_min,
            meshing,
            contact_distance,
        })
    }
}

/// Why an observed tissue without a moving cell cannot be fitted, and what to do (issue 22, item 6:
/// a crop whose every label touches the image border, meshed with `border = "static"`).
fn no_moving_cell(tissue: &Tissue, meshing: Option<&LabelMeshingOptions>) -> String {
    let mut kinds: Vec<(crate::mesh::CellKind, usize)> = Vec::new();
    for cell in tissue.cells() {
        match kinds.iter_mut().find(|(k, _)| *k == cell.kind()) {
            Some((_, n)) => *n += 1,
            None => kinds.push((cell.kind(), 1)),
        }
    }
    let counts: Vec<String> = kinds.iter().map(|(k, n)| format!("{n} {}", k.name())).collect();
    let head = format!(
        "the observed tissue has no cell the simulation moves ({}), so no parameter can change its shape and there \
         is nothing to fit",
        counts.join(", ")
    );
    let statics = kinds.iter().find(|(k, _)| *k == crate::mesh::CellKind::Static).map_or(0, |(_, n)| *n);
    match meshing {
        Some(m) if m.border == crate::meshing::BorderPolicy::Static && statics > 0 => format!(
            "{head}: the labels were meshed with border = \"static\", which makes every label touching the image \
             border a static cell, and all {statics} of them touch it (the field of view cuts every cell). To fit, \
             (a) keep the border cells as free cells (border = \"keep\" in [mesh] or observed.meshing; their cut \
             faces then count as free surface, which biases the metrics), (b) crop the volume to a region that \
             holds whole cells away from its border, or (c) use a mask in which some cells do not touch the border"
        ),
        Some(_) => format!(
            "{head}: no meshed label became a moving cell; check the mesh report (kept/static/dropped per label) \
             and the meshing options (border, lumen_labels)"
        ),
        None => format!(
            "{head}: give a tissue with epithelial cells (cell kind 0), or one whose border cells are not all \
             static; static, ECM and nucleus cells never move"
        ),
    }
}

/// Everything one evaluation needs; shared read-only by parallel evaluations.
pub struct ForwardModel {
    pub observation: Observation,
    pub base: Parameters,
    pub space: ParameterSpace,
    pub objective: ObjectiveConfig,
    pub forward: ForwardConfig,
    /// Lines in a log while an evaluation's relaxation runs (none by default; the fit turns it on
    /// with its progress, so that a log shows an evaluation of many minutes is alive).
    pub heartbeat: Option<Heartbeat>,
    /// A caller's stop request: a relaxation in progress ends at its step (the evaluation is then
    /// not recorded, see [`super::Evaluator::evaluate_batch`]).
    pub watch: Watch,
    /// The boundary noise (RMS voxels) added to every simulated mask before it is measured like the
    /// data: `forward.roughen_voxels`, or its estimate ([`ForwardModel::calibrate_roughness`]); 0: none.
    pub roughen: Real,
    /// The objective one draw of that noise adds at the truth ([`RoughnessCalibration::mask_noise`]),
    /// which the profile's threshold allows for; 0 without roughening.
    pub mask_noise: Real,
}

/// What [`ForwardModel::calibrate_roughness`] found: the estimated amplitude and the boundary
/// roughness ([`boundary_roughness`]) of the observed mask and of the start point's relaxed mask
/// roughened by it.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RoughnessCalibration {
    /// RMS boundary displacement added to the simulated masks (voxels).
    pub voxels: Real,
    /// Width of its bumps (voxels), `forward.roughen_correlation`.
    pub correlation: Real,
    /// Whether it was estimated (`roughen_voxels = "auto"`) rather than given.
    pub estimated: bool,
    /// Boundary roughness of the observed mask.
    pub observed: Real,
    /// Boundary roughness of the start point's relaxed mask, clean and roughened (mean over the
    /// measurements' noise seeds).
    pub simulated_clean: Real,
    pub simulated: Real,
    /// Why the estimate is not to be trusted, when it is not (at a limit of its range).
    pub warning: Option<String>,
    /// Standard deviation of each fitted summary metric over [`MASK_NOISE_DRAWS`] single draws of
    /// the noise on the start point's mask: how far one segmentation of the same shape can lie from
    /// another.
    pub metric_sd: std::collections::BTreeMap<&'static str, Real>,
    /// Those deviations in objective units, Σ w·(sd/s)² / Σ w: what the observed mask's own noise
    /// adds to the objective at the truth, on average. The profile's threshold adds
    /// `noise_sigmas`² times it, so reported ranges hold what another draw of the noise would give.
    pub mask_noise: Real,
}

/// The smallest roughened simulated cell meshed like the data (the observed mask's cells passed
/// `mesh.min_voxels` already; a draw of the noise must not drop one).
const SIMULATED_MIN_VOXELS: u64 = 16;

/// Draws of the roughening noise whose scatter gives [`RoughnessCalibration::mask_noise`].
pub const MASK_NOISE_DRAWS: usize = 6;

/// Largest amplitude (voxels) `roughen_voxels = "auto"` considers.
pub const MAX_ROUGHEN_VOXELS: Real = 3.0;

/// The observer of an evaluation's relaxation: a [`Heartbeat`] line (the point, step, residual)
/// when one is due (it looks at the clock every [`BEAT_STEPS`] steps only), and a stop at the end of
/// the step once the caller's [`Watch`] is stopped.
struct EvaluationBeat<'a> {
    heartbeat: Option<&'a Heartbeat>,
    watch: &'a Watch,
    /// What is relaxing ("evaluation at γ = …", "iteration 2 of 6").
    what: &'a str,
    max_steps: u64,
}

/// Steps between two looks at the clock of [`EvaluationBeat`].
const BEAT_STEPS: u64 = 256;

impl Observer for EvaluationBeat<'_> {
    fn sample(&mut self, _: &crate::mechanics::Sample<'_>) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        Ok(())
    }

    fn progress(&mut self, step: u64, residual: Real) {
        if !step.is_multiple_of(BEAT_STEPS) {
            return;
        }
        let message = || {
            format!(
                "{} running: step {step} of at most {} per pass, residual {residual:.3e}",
                self.what, self.max_steps
            )
        };
        if let Some(heartbeat) = self.heartbeat {
            heartbeat.beat(message);
        }
        // A caller listening (the Python API) hears it too, and can stop the fit from here.
        self.watch.tick("fit", step, self.max_steps, "step", message);
    }

    fn checkpoint_due(&mut self, _step: u64) -> CheckpointRequest {
        if self.watch.stopped() { CheckpointRequest::SaveAndStop } else { CheckpointRequest::No }
    }
}

/// With spring contacts, the first epithelial face whose adhesion well W = ωc²/4 reaches its tension
/// (w/(2γ) ≥ 1): its contact faces have no net tension left, so no equilibrium exists (the surfaces
/// crumple; validation warns from 0.7γ); `None` otherwise. The repulsion a point's ω raises
/// ([`ForwardModel::params_at`]) would let such a point run, for as long as it takes to fold.
fn complete_wetting(params: &Parameters) -> Option<String> {
    if params.numerics.contact_model != ContactModel::Spring {
        return None;
    }
    let c = params.numerics.contact_cutoff;
    params.cell_types.iter().enumerate().filter(|(_, t)| t.kind == crate::mesh::CellKind::Epithelial).find_map(
        |(i, t)| {
            t.faces.iter().find(|(_, f)| f.adhesion > 0.0 && f.adhesion_well_depth(c) >= f.surface_tension).map(
                |(ft, f)| {
                    format!(
                        "cell_types[{i}].faces.{}: w/(2γ) = ωc²/(4γ) = {:.3} ≥ 1 (ω = {:.3e} Pa/m, c = {:.3e} m): the \
                         adhesion cancels the tension of contact faces, which then crumple; no equilibrium to fit",
                        ft.name(),
                        f.adhesion_well_depth(c) / f.surface_tension,
                        f.adhesion,
                        c
                    )
                },
            )
        },
    )
}

/// The meshing's l_min that the forward model gives the model as numerics.min_edge_length and
/// numerics.contact_cutoff (`forward.match_mesh_length` with an observation meshed from labels).
pub fn matched_mesh_length(forward: &ForwardConfig, observation: &Observation) -> Option<Real> {
    observation.l_min.filter(|_| forward.match_mesh_length)
}

/// `config.parameters` for the model `base` and the observation: with
/// [`super::ADHESION_RATIO`] resolved into `adhesion` at the contact cutoff the forward model will use.
pub fn resolved_parameters(
    config: &super::FitConfig,
    base: &Parameters,
    observation: &Observation,
) -> Result<std::collections::BTreeMap<String, super::config::ParameterConfig>, super::InferenceError> {
    let cutoff = matched_mesh_length(&config.forward, observation).unwrap_or(base.numerics.contact_cutoff);
    super::resolve_adhesion_ratio(&config.parameters, cutoff, base.numerics.contact_model == ContactModel::Spring)
}

impl ForwardModel {
    /// The model at log point `x` (clamped into the bounds first): the fitted and fixed parameters
    /// written into the base model and, with spring contacts, the repulsion raised where it is below
    /// what holds that point's adhesion and the observed cells' Laplace pressures apart
    /// ([`Parameters::raise_repulsion_for_overrides`], never lowered), with the time step: a fitted
    /// ω many times the base model's would otherwise pull cells into each other (a Surface Evolver
    /// doublet fitted at w/(2γ) ≥ 0.5 with ξ = 1e9 Pa/m: cells detached or one vanished).
    pub fn params_at(&self, x: &[Real]) -> Parameters {
        let (x, _) = self.space.clamp(x);
        let mut params = self.space.apply(&self.base, &x);
        for d in params.raise_repulsion_for_overrides(&self.observation.tissue) {
            tracing::debug!("{} = {:.3e} (was {:.3e}): {}", d.key, d.value, d.default, d.from);
        }
        params
    }

    /// Prepares the base model: the forward settings applied to it (equilibrium mode, max steps,
    /// mesh length scale), no sampling output.
    pub fn new(
        observation: Observation,
        mut base: Parameters,
        space: ParameterSpace,
        objective: ObjectiveConfig,
        forward: ForwardConfig,
    ) -> Result<Self, super::InferenceError> {
        base.simulation.mode = crate::mechanics::SimulationMode::Equilibrium;
        // Never sample (the largest value a TOML integer holds, so the model still writes out).
        base.simulation.sample_every_steps = i64::MAX as u64;
        if let Some(n) = forward.max_steps {
            base.simulation.max_steps = n;
        }
        if let Some(n) = forward.settle_steps {
            base.simulation.settle_steps = n;
        }
        if let Some(l) = matched_mesh_length(&forward, &observation) {
            base.numerics.min_edge_length = l;
            base.numerics.contact_cutoff = l;
        }
        // The base model's warnings (unit slips, adhesion beyond the tension, the vertex quadrature's
        // bias) concern the evaluations near it.
        for w in base.validate().map_err(|e| super::InferenceError::Config(format!("model: {e}")))? {
            tracing::warn!("model: {w}");
        }
        let roughen = match forward.roughen_voxels {
            Roughen::Voxels(a) => a,
            Roughen::Estimate(_) => 0.0,
        };
        Ok(Self {
            observation,
            base,
            space,
            objective,
            forward,
            heartbeat: None,
            watch: Watch::default(),
            roughen,
            mask_noise: 0.0,
        })
    }

    /// Sets [`ForwardModel::roughen`] for `forward.roughen_voxels = "auto"`: relaxes the start point
    /// `x` once (as an evaluation would; nothing is roughened yet), then finds the amplitude whose noise makes that tissue's mask
    /// as rough as the observed one ([`boundary_roughness`], averaged over the noise of the
    /// `measure_shifts` measurements, at least 4), by bisection in [0, [`MAX_ROUGHEN_VOXELS`]]. With
    /// a given amplitude it measures both roughnesses the same way (one relaxation too), so that a
    /// user sees whether the amplitude fits the data. `None` when nothing is roughened; an error when
    /// roughening is asked for without a label input measured like the data.
    pub fn calibrate_roughness(&mut self, x: &[Real]) -> Result<Option<RoughnessCalibration>, String> {
        let obs = &self.observation;
        let auto = matches!(self.forward.roughen_voxels, Roughen::Estimate(_));
        let (Some(observed), true) = (&obs.labels, self.forward.measure_like_data && obs.meshing.is_some()) else {
            if auto || self.roughen > 0.0 {
                return Err("forward.roughen_voxels needs a label-volume input measured like the data \
                            (forward.measure_like_data = true): it roughens the simulated masks"
                    .into());
            }
            return Ok(None);
        };
        if !auto && self.roughen <= 0.0 {
            return Ok(None);
        }
        let grid = observed.grid();
        let observed_roughness = boundary_roughness(observed)
            .map_err(|e| format!("the observed mask's roughness: {e}"))?
            .ok_or("the observed mask has no boundaries")?;
        let (x, _) = self.space.clamp(x);
        let params = self.params_at(&x);
        // As an evaluation relaxes (with "auto" nothing is roughened yet).
        let (tissue, _) = self
            .relax(&params, &self.observation.tissue, &mut NoObserver)
            .map_err(|(reason, _)| format!("relaxing the start point: {reason}"))?;
        let clean = voxelize(&tissue, &grid).map_err(|e| format!("voxelising the relaxed start point: {e}"))?;
        let seeds = self.forward.measure_shifts.max(4);
        let correlation = self.forward.roughen_correlation;
        let roughness_at = |amplitude: Real| -> Result<Real, String> {
            let each: Vec<Result<Real, String>> = (0..seeds)
                .into_par_iter()
                .map(|k| {
                    let (v, _) = perturb_boundaries(&clean, &noise_draw(amplitude, correlation, k as u64))
                        .map_err(|e| e.to_string())?;
                    boundary_roughness(&v).map_err(|e| e.to_string())?.ok_or_else(|| "no boundaries".to_string())
                })
                .collect();
            let each = each.into_iter().collect::<Result<Vec<_>, _>>()?;
            Ok(each.iter().sum::<Real>() / each.len() as Real)
        };
        let simulated_clean = boundary_roughness(&clean)
            .map_err(|e| e.to_string())?
            .ok_or("the relaxed start point's mask has no boundaries")?;
        let (voxels, estimated, warning) = match self.forward.roughen_voxels {
            Roughen::Voxels(a) => (a, false, None),
            Roughen::Estimate(_) => {
                if observed_roughness <= simulated_clean {
                    (0.0, true, None)
                } else if observed_roughness >= roughness_at(MAX_ROUGHEN_VOXELS)? {
                    let w = format!(
                        "the observed mask is rougher than {MAX_ROUGHEN_VOXELS} voxels of boundary noise with bumps \
                         {correlation} voxels wide make the simulated one; its noise is wider than that \
                         (raise forward.roughen_correlation) or it is not noise"
                    );
                    (MAX_ROUGHEN_VOXELS, true, Some(w))
                } else {
                    let (mut lo, mut hi) = (0.0, MAX_ROUGHEN_VOXELS);
                    for _ in 0..8 {
                        let mid = 0.5 * (lo + hi);
                        if roughness_at(mid)? < observed_roughness {
                            lo = mid;
                        } else {
                            hi = mid;
                        }
                    }
                    (0.5 * (lo + hi), true, None)
                }
            }
        };
        self.roughen = voxels;
        if voxels > 0.0
            && let Some(options) = self.observation.meshing.as_mut()
        {
            // The noise moves a small cell's voxel count by ±10 % from draw to draw: a cell the data
            // hold must not be dropped by a draw that takes it under the observed filter.
            options.min_voxels = options.min_voxels.min(SIMULATED_MIN_VOXELS);
        }
        let simulated = if voxels > 0.0 { roughness_at(voxels)? } else { simulated_clean };
        let (metric_sd, mask_noise) = if voxels > 0.0 { self.mask_scatter(&clean)? } else { Default::default() };
        self.mask_noise = mask_noise;
        Ok(Some(RoughnessCalibration {
            voxels,
            correlation,
            estimated,
            observed: observed_roughness,
            simulated_clean,
            simulated,
            warning,
            metric_sd,
            mask_noise,
        }))
    }

    /// The scatter of the fitted summary metrics over [`MASK_NOISE_DRAWS`] draws of the roughening
    /// noise on `clean` (seeds apart from the measurements'), each measured once like the data: per
    /// metric SD, and Σ w·(sd/s)² / Σ w over the weighted metrics.
    fn mask_scatter(
        &self,
        clean: &LabelVolume,
    ) -> Result<(std::collections::BTreeMap<&'static str, Real>, Real), String> {
        let options = self.observation.meshing.as_ref().ok_or("no meshing options")?;
        let each: Vec<Result<Metrics, String>> = (0..MASK_NOISE_DRAWS)
            .into_par_iter()
            .map(|j| {
                let noise = noise_draw(self.roughen, self.forward.roughen_correlation, 10_000 + j as u64);
                let (v, _) = perturb_boundaries(clean, &noise).map_err(|e| e.to_string())?;
                self.measure_voxels(&v, options).map_err(|e| format!("draw {j} of the mask noise: {e}"))
            })
            .collect();
        let each = each.into_iter().collect::<Result<Vec<_>, _>>()?;
        let mut sd = std::collections::BTreeMap::new();
        let (mut sum, mut wsum) = (0.0, 0.0);
        for m in Metric::SUMMARY {
            let Some(s) = Distribution::of(each.iter().filter_map(|e| e.get(m))).std else { continue };
            sd.insert(m.name(), s);
            let w = self.objective.weight(m);
            if w > 0.0 && self.observation.metrics.get(m).is_some() {
                sum += w * (s / self.objective.scale(m)).powi(2);
                wsum += w;
            }
        }
        Ok((sd, if wsum > 0.0 { sum / wsum } else { 0.0 }))
    }

    /// Scores simulated metrics against the observed ones (see the module doc).
    pub fn score(&self, sim: &Metrics) -> Real {
        let o = &self.objective;
        let (mut sum, mut wsum) = (0.0, 0.0);
        for m in Metric::SUMMARY {
            let w = o.weight(m);
            let Some(ov) = self.observation.metrics.get(m) else { continue };
            if w == 0.0 {
                continue;
            }
            let misfit = match sim.get(m) {
                Some(sv) => (sv - ov) / o.scale(m),
                None => MISSING_METRIC_MISFIT,
            };
            sum += w * misfit * misfit;
            wsum += w;
        }
        let mut j = if wsum > 0.0 { sum / wsum } else { 0.0 };
        if o.shape > 0.0 {
            let misfit = sim.shape.map_or(MISSING_METRIC_MISFIT, |s| s / o.shape_scale);
            j += o.shape * misfit * misfit;
        }
        j
    }

    /// Runs one evaluation at log point `x` (clamped into the bounds first). Never fails: problems
    /// become a penalised [`Evaluation`] with its reason.
    pub fn evaluate(&self, x: &[Real]) -> Evaluation {
        self.evaluate_from(x, &self.observation.tissue).0
    }

    /// Like [`ForwardModel::evaluate`], starting the relaxation from `start` (a tissue with the
    /// observed tissue's cells in the same order, e.g. the equilibrium of an earlier evaluation: a
    /// warm start) instead of the observed tissue; also returns the relaxed tissue (`None` when the
    /// simulation failed). The fit itself always starts from the observed tissue (see the module doc).
    pub fn evaluate_from(&self, x: &[Real], start: &Tissue) -> (Evaluation, Option<Tissue>) {
        let started = Instant::now();
        let (x, _) = self.space.clamp(x);
        let params = self.params_at(&x);
        let penalty = self.objective.failure_penalty;
        let failed = |reason: String, steps: u64, residual: Real, metrics: Metrics| Evaluation {
            x: x.clone(),
            metrics,
            objective: penalty,
            status: Status::Failed,
            reason,
            steps,
            residual,
            wall_seconds: started.elapsed().as_secs_f64(),
            elapsed_seconds: Real::NAN,
        };
        if let Err(e) = params.validate() {
            return (failed(format!("invalid parameters: {e}"), 0, Real::NAN, Metrics::default()), None);
        }
        if let Some(e) = complete_wetting(&params) {
            return (failed(format!("invalid parameters: {e}"), 0, Real::NAN, Metrics::default()), None);
        }
        let relaxed = self.relax_reporting(&params, start, || {
            // The fitted parameters (the fixed ones come first in the list).
            let values = self.space.parameter_values(&x);
            let point = values[values.len() - x.len()..]
                .iter()
                .map(|(p, v)| format!("{} = {v:.4e}", p.name()))
                .collect::<Vec<_>>()
                .join(", ");
            format!("evaluation at {point}")
        });
        let (tissue, summary) = match relaxed {
            Ok(r) => r,
            Err((reason, steps)) => return (failed(reason, steps, Real::NAN, Metrics::default()), None),
        };
        let metrics = match self.measure(&tissue) {
            Ok(m) => m,
            Err(e) => return (failed(e, summary.steps, summary.residual, Metrics::default()), Some(tissue)),
        };
        let (status, reason) = if summary.converged {
            (Status::Converged, String::new())
        } else if summary.residual <= self.forward.accept_residual {
            (Status::Accepted, String::new())
        } else {
            (
                Status::Unconverged,
                format!(
                    "not converged within {} steps: residual {:.3e} > forward.accept_residual {:.3e}",
                    summary.steps, summary.residual, self.forward.accept_residual
                ),
            )
        };
        let objective = if status.usable() { self.score(&metrics) } else { penalty };
        let evaluation = Evaluation {
            x,
            metrics,
            objective,
            status,
            reason,
            steps: summary.steps,
            residual: summary.residual,
            wall_seconds: started.elapsed().as_secs_f64(),
            elapsed_seconds: Real::NAN,
        };
        (evaluation, Some(tissue))
    }

    /// [`Self::relax`] that a log (the model's [`Heartbeat`]) and a listening caller (its [`Watch`],
    /// which may also stop it) hear from while it runs: `what` names the relaxation in their lines
    /// (built only when someone listens).
    pub(crate) fn relax_reporting(
        &self,
        params: &Parameters,
        start: &Tissue,
        what: impl FnOnce() -> String,
    ) -> Result<(Tissue, SimulationSummary), (String, u64)> {
        let heartbeat = self.heartbeat.as_ref().filter(|h| h.is_on());
        if heartbeat.is_some() || self.watch.is_on() {
            let what = what();
            let max_steps = params.simulation.max_steps;
            self.relax(params, start, &mut EvaluationBeat { heartbeat, watch: &self.watch, what: &what, max_steps })
        } else {
            self.relax(params, start, &mut NoObserver)
        }
    }

    /// The relaxation of one evaluation: from `start`, the first pass and `forward.volume_passes`
    /// passes correcting V0 (see the module doc). Returns the relaxed tissue and the summary of the
    /// last pass (its steps: all passes'); on failure the reason and the steps run. `observer`
    /// sees every pass (the forward model passes a silent one; `examples/fit_aggregate.rs --probe`
    /// records them).
    pub fn relax(
        &self,
        params: &Parameters,
        start: &Tissue,
        observer: &mut dyn Observer,
    ) -> Result<(Tissue, SimulationSummary), (String, u64)> {
        let mut tissue = start.clone();
        let mut steps = 0;
        let mut summary = None;
        let cell_params = crate::mechanics::cell_parameters(&tissue, params).map_err(|e| (e.to_string(), 0))?;
        for pass in 0..=self.forward.volume_passes {
            let like = if pass > 0 {
                self.like_data_volumes(&tissue).map_err(|e| (format!("volume pass {pass}: {e}"), steps))?
            } else {
                None
            };
            for (c, (cell, observed)) in tissue.cells_mut().iter_mut().zip(self.observation.tissue.cells()).enumerate()
            {
                if !cell.kind().is_cell() || cell.kind().is_immobile() {
                    continue;
                }
                let p = &cell_params[c];
                let observed = observed.mesh().signed_volume();
                let target = if pass == 0 {
                    laplace_start(cell, p, observed)
                } else {
                    let direct = cell.mesh().signed_volume();
                    let like = like.as_ref().and_then(|l| l[c]).unwrap_or(direct);
                    volume_update(cell.target_volume(), direct, like, observed, p)
                };
                if let Some(v0) = target {
                    cell.set_target_volume(v0);
                }
            }
            let mut sim = Simulation::new(tissue, params).map_err(|e| (format!("simulation setup: {e}"), steps))?;
            let s = sim.run(observer).map_err(|e| (format!("simulation (pass {pass}): {e}"), steps))?;
            steps += s.steps;
            summary = Some(s);
            tissue = sim.into_tissue();
        }
        let mut summary = summary.expect("at least one pass");
        summary.steps = steps;
        Ok((tissue, summary))
    }

    /// The volume of each cell of a relaxed tissue as the data measure it (voxelised on the observed
    /// grid as it lies, one placement, not averaged over `measure_shifts`, and meshed again with the
    /// observed options), in the tissue's cell order; `None` without `forward.measure_like_data` or a
    /// label input, and for a cell the meshing dropped (that cell's direct volume is then compared
    /// with its observed one, and it ends about the measurement's bias too small). The observed
    /// volumes went through that measurement, which loses volume (9 % of a spring aggregate's cells
    /// at 10 voxels per diameter: the voxel boundary's samples lie inside the surface), so matching
    /// direct volumes to them would shrink every simulated cell by that bias.
    fn like_data_volumes(&self, tissue: &Tissue) -> Result<Option<Vec<Option<Real>>>, String> {
        let obs = &self.observation;
        let (Some(observed), Some(options), true) = (&obs.labels, &obs.meshing, self.forward.measure_like_data) else {
            return Ok(None);
        };
        let voxels = voxelize(tissue, &observed.grid()).map_err(|e| format!("voxelising the relaxed tissue: {e}"))?;
        let voxels = self.roughen(&voxels, 0)?;
        let meshed = mesh_labels(&voxels, options).map_err(|e| format!("meshing the relaxed tissue's voxels: {e}"))?;
        let volumes: std::collections::HashMap<_, Real> =
            meshed.tissue.cells().iter().map(|c| (c.id(), c.mesh().signed_volume())).collect();
        Ok(Some(tissue.cells().iter().map(|c| volumes.get(&c.id()).copied()).collect()))
    }

    /// The metrics of a relaxed tissue: measured directly, or voxelised on the observed grid and
    /// meshed again like the data (`forward.measure_like_data`), then averaged over
    /// `forward.measure_shifts` rigid sub-voxel shifts of the tissue (see [`shift_offset`]); plus
    /// the shape term (on the unshifted voxels) when on.
    pub fn measure(&self, tissue: &Tissue) -> Result<Metrics, String> {
        let obs = &self.observation;
        let like_data = self.forward.measure_like_data && obs.labels.is_some() && obs.meshing.is_some();
        let voxels = if like_data || self.objective.shape > 0.0 {
            let observed = obs.labels.as_ref().ok_or("the shape term needs observed labels")?;
            Some(voxelize(tissue, &observed.grid()).map_err(|e| format!("voxelising the relaxed tissue: {e}"))?)
        } else {
            None
        };
        let mut metrics = match (&voxels, &obs.meshing, &obs.labels) {
            (Some(v), Some(options), Some(observed)) if like_data => {
                let shifts = self.forward.measure_shifts.max(1);
                let size = observed.voxel_size();
                // Each shift is measured independently (in parallel) and the results are combined
                // in shift order, so the average does not depend on the thread count.
                let each: Vec<Result<Metrics, String>> = (0..shifts)
                    .into_par_iter()
                    .map(|k| {
                        if k == 0 {
                            return self.measure_voxels(&*self.roughen(v, 0)?, options);
                        }
                        let o = shift_offset(k);
                        let offset = Vec3::new(o[0] * size[0], o[1] * size[1], o[2] * size[2]);
                        let mut shifted = tissue.clone();
                        for cell in shifted.cells_mut() {
                            for p in cell.positions_mut() {
                                *p += offset;
                            }
                        }
                        let voxels = voxelize(&shifted, &observed.grid())
                            .map_err(|e| format!("voxelising the relaxed tissue (shift {k}): {e}"))?;
                        self.measure_voxels(&*self.roughen(&voxels, k)?, options)
                    })
                    .collect();
                let each = each.into_iter().collect::<Result<Vec<_>, _>>()?;
                average_metrics(&each)
            }
            _ => Metrics::measure(tissue, Some(obs.contact_distance))?.0,
        };
        if self.objective.shape > 0.0
            && let Some(v) = &voxels
        {
            metrics.shape = Some(self.shape_term(v)?);
        }
        Ok(metrics)
    }

    /// `voxels` with the observed mask's boundary noise added (`forward.roughen_voxels`), the noise of
    /// measurement `k` (the same field in every evaluation, so the objective does not jump between
    /// neighbouring parameters); borrowed unchanged without it.
    pub(crate) fn roughen<'v>(&self, voxels: &'v LabelVolume, k: usize) -> Result<Cow<'v, LabelVolume>, String> {
        if self.roughen <= 0.0 {
            return Ok(Cow::Borrowed(voxels));
        }
        perturb_boundaries(voxels, &noise_draw(self.roughen, self.forward.roughen_correlation, k as u64))
            .map(|(v, _)| Cow::Owned(v))
            .map_err(|e| format!("roughening the relaxed tissue's voxels (measurement {k}): {e}"))
    }

    /// Meshes voxels of a relaxed tissue like the data and measures them with the observed δ; an
    /// error when a moving cell was lost on the way.
    fn measure_voxels(&self, voxels: &LabelVolume, options: &LabelMeshingOptions) -> Result<Metrics, String> {
        let obs = &self.observation;
        let meshed = mesh_labels(voxels, options).map_err(|e| format!("meshing the relaxed tissue's voxels: {e}"))?;
        let lost: Vec<String> = meshed
            .report
            .iter()
            .filter(|r| r.kind.is_none() && obs.cell_labels.contains(&r.label))
            .map(|r| format!("{} ({})", r.label, r.reason.as_deref().unwrap_or("no reason given")))
            .collect();
        if !lost.is_empty() || meshed.tissue.is_empty() {
            return Err(format!("meshing the relaxed tissue's voxels dropped cells {}", lost.join(", ")));
        }
        Ok(Metrics::measure(&meshed.tissue, Some(obs.contact_distance))?.0)
    }

    /// Mean 1 − IoU of the moving cells, the relaxed tissue voxelised on the observed grid.
    fn shape_term(&self, simulated: &LabelVolume) -> Result<Real, String> {
        let observed = self.observation.labels.as_ref().ok_or("the shape term needs observed labels")?;
        let overlaps = label_overlap(observed, simulated).map_err(|e| format!("overlap: {e}"))?;
        let labels = &self.observation.cell_labels;
        let chis: Vec<Real> = overlaps.iter().filter(|o| labels.contains(&o.label)).map(|o| o.chi()).collect();
        if chis.is_empty() {
            return Err("no observed cell label found in the voxelised simulation".into());
        }
        Ok(chis.iter().sum::<Real>() / chis.len() as Real)
    }
}

/// The first target volume of a moving cell: the one whose Laplace pressure 2γ̄/R (γ̄ its
/// area-weighted mean tension, [`CellTypeParams::mean_tension`]) holds it at its observed volume
/// ([`CellTypeParams::laplace_volume`]),
/// so the first relaxation starts near its equilibrium volume instead of shrinking by exp(−p/K)
/// (36 % on a spring aggregate at K = 2500 Pa) and growing back over the volume passes. `None`
/// (keep V0) when no target volume balances it (K = 0, a capped pressure).
fn laplace_start(cell: &crate::mesh::Cell, p: &CellTypeParams, observed: Real) -> Option<Real> {
    p.laplace_volume(observed, p.mean_tension(cell)).ok().filter(|v| v.is_finite() && *v > 0.0)
}

/// The next target volume of a moving cell after a relaxation that ended at volume `direct` (as
/// measured like the data: `like`) with target `v0`, to reach the observed volume `observed`.
/// The wanted volume is V_t = direct·observed/like; the cell's pressure p = K·ln(V0/V) is taken to
/// scale like a Laplace pressure, p_t = p·(V/V_t)^(1/3), and V0 ← V_t·exp(p_t/K). Keeping p fixed
/// instead (V0 ← V0·observed/like) overshoots: a spring aggregate compressed to 0.55 of its observed
/// volume came back at 1.17. Falls back to that when the pressure is capped or K = 0.
fn volume_update(v0: Real, direct: Real, like: Real, observed: Real, p: &CellTypeParams) -> Option<Real> {
    if !(direct > 0.0 && like > 0.0 && observed > 0.0 && v0 > 0.0) {
        return None;
    }
    let wanted = direct * observed / like;
    let pressure = p.bulk_modulus * (v0 / direct).ln();
    let next = if p.bulk_modulus > 0.0 && pressure.is_finite() && pressure < p.max_pressure {
        let scaled = if pressure > 0.0 { pressure * (direct / wanted).cbrt() } else { pressure };
        wanted * (scaled / p.bulk_modulus).exp()
    } else {
        v0 * observed / like
    };
    Some(next).filter(|v| v.is_finite() && *v > 0.0)
}

/// The k-th rigid shift of a relaxed tissue before it is voxelised (in voxels, each component in
/// [−½, ½)): 0 for k = 0, then the 3-D Halton sequence (bases 2, 3, 5), which covers the voxel
/// evenly with few points. A voxelisation of one shape at different positions on the grid gives
/// different labels; re-meshed, the contact-area fraction of a spring aggregate at 10 voxels per
/// diameter scattered by ±0.007 (sphericity ±0.001) over rigid shifts alone, as much as between
/// relaxations at parameters one bit apart. Averaging over shifts measures the shape, not its
/// placement on the grid.
pub fn shift_offset(k: usize) -> [Real; 3] {
    let halton = |mut i: usize, base: usize| {
        let (mut f, mut r) = (1.0, 0.0);
        while i > 0 {
            f /= base as Real;
            r += f * (i % base) as Real;
            i /= base;
        }
        r
    };
    let wrap = |v: Real| if v >= 0.5 { v - 1.0 } else { v };
    [wrap(halton(k, 2)), wrap(halton(k, 3)), wrap(halton(k, 5))]
}

/// Mean of each metric over measurements (a metric missing from any of them is missing).
fn average_metrics(all: &[Metrics]) -> Metrics {
    let mut out = Metrics::default();
    for m in Metric::ALL {
        let values: Option<Vec<Real>> = all.iter().map(|x| x.get(m)).collect();
        *out.get_mut(m) = values.filter(|v| !v.is_empty()).map(|v| v.iter().sum::<Real>() / v.len() as Real);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// The equilibrium volume of a free cell of tension γ and target volume V0:
    /// K·ln(V0/V) = 2γ/R(V), by bisection on ln V.
    fn laplace_equilibrium(p: &CellTypeParams, gamma: Real, v0: Real) -> Real {
        let excess = |v: Real| p.bulk_modulus * (v0 / v).ln() - 2.0 * gamma / (3.0 * v / (4.0 * PI)).cbrt();
        let (mut lo, mut hi) = (0.2 * v0, v0);
        assert!(excess(lo) > 0.0 && excess(hi) < 0.0, "the physical root is bracketed");
        for _ in 0..200 {
            let mid = (lo * hi).sqrt();
            if excess(mid) > 0.0 { lo = mid } else { hi = mid }
        }
        (lo * hi).sqrt()
    }

    /// A Laplace-law cell measured with a volume bias (like = 0.91·direct, as re-meshed voxels at
    /// 10 voxels per diameter) reaches its observed volume in one update; keeping the pressure
    /// fixed overshoots, and so does ignoring the bias.
    /// K = 2500 Pa, γ = 1e-3 N/m on every face type.
    fn cell_type() -> CellTypeParams {
        let mut p = CellTypeParams { bulk_modulus: 2500.0, max_pressure: Real::INFINITY, ..Default::default() };
        for t in crate::mesh::FaceType::ALL {
            p.faces.get_mut(t).surface_tension = 1e-3;
        }
        p
    }

    #[test]
    fn every_metric_reads_its_own_field_weight_and_scale() {
        assert_eq!(Metrics::NAMES, Metric::ALL.map(Metric::name));
        // Distinct values per metric, keyed by the metric's name as the config spells it.
        let mut text = String::new();
        for (i, m) in Metric::ALL.into_iter().enumerate() {
            text += &format!("{} = {}\n{}_scale = {}\n", m.name(), i + 1, m.name(), 10 * (i + 1));
        }
        let o: super::super::config::ObjectiveConfig = toml::from_str(&text).unwrap();
        let metrics = Metrics {
            sphericity: Some(1.0),
            contact_fraction: Some(2.0),
            coordination: Some(3.0),
            contact_angle: Some(4.0),
            shape: Some(5.0),
        };
        let json = serde_json::to_value(metrics).unwrap();
        for (i, m) in Metric::ALL.into_iter().enumerate() {
            assert_eq!(o.weight(m), (i + 1) as Real, "{}", m.name());
            assert_eq!(o.scale(m), (10 * (i + 1)) as Real, "{}", m.name());
            assert_eq!(metrics.get(m), Some((i + 1) as Real), "{}", m.name());
            assert_eq!(json[m.name()].as_f64(), metrics.get(m), "{}", m.name());
        }
    }

    #[test]
    fn one_volume_update_lands_a_laplace_cell_on_its_observed_volume() {
        let p = cell_type();
        let (gamma, bias) = (1e-3, 0.91);
        let observed = 4.0 / 3.0 * PI * (2e-6 as Real).powi(3);
        // Strongly compressed: V0 = the observed volume, p = 2γ/R ≈ K/2.
        let v0 = observed;
        let direct = laplace_equilibrium(&p, gamma, v0);
        assert!(direct < 0.8 * observed, "the start is far from the target: {}", direct / observed);
        let next = volume_update(v0, direct, bias * direct, observed, &p).unwrap();
        let like = bias * laplace_equilibrium(&p, gamma, next);
        assert!((like / observed - 1.0).abs() < 0.01, "like-data volume / observed = {}", like / observed);
        let fixed_pressure = v0 * observed / (bias * direct);
        let overshoot = bias * laplace_equilibrium(&p, gamma, fixed_pressure) / observed;
        assert!(overshoot > 1.05, "keeping p fixed lands at {overshoot} of the observed volume");
        let unbiased = volume_update(v0, direct, direct, observed, &p).unwrap();
        let short = bias * laplace_equilibrium(&p, gamma, unbiased) / observed;
        assert!(short < 0.95, "matching direct volumes lands at {short} of the observed volume like the data");
    }

    /// The first target volume holds a free Laplace cell at its observed volume.
    #[test]
    fn the_laplace_start_holds_a_free_cell_at_its_observed_volume() {
        use crate::mesh::{Cell, CellId, CellKind};
        let p = cell_type();
        let mesh = crate::mesh::shapes::icosphere(2e-6, 3, Vec3::zeros());
        let observed = mesh.signed_volume();
        let cell = Cell::new(CellId(1), CellKind::Epithelial, 0, mesh);
        let gamma = 1e-3;
        let v0 = laplace_start(&cell, &p, observed).unwrap();
        let v = laplace_equilibrium(&p, gamma, v0);
        assert!((v / observed - 1.0).abs() < 1e-9, "V/V_observed = {}", v / observed);
    }
}

//! Per-cell tension maps by forward refinement (`[fit] mode = "per_cell"`, issue 25).
//!
//! The direct estimate ([`crate::morphology::tensions`]) reads every interface's tension off the
//! observed shapes, but what it reads is biased by the measurement: junctions rounded over a voxel,
//! meshes a few nodes across an interface, rims that are not the far field. The forward model makes
//! the same measurement on a simulation whose tensions are known, so the bias can be taken out:
//!
//! 1. estimate the observed tissue's map T_obs (gauge: the mean cell–medium tension), and start
//!    every moving cell i with its free tension f_i (its cell–medium tension) and a lateral tension
//!    a_i with a_i + a_j ≈ T_ij (coupled contacts add the two cells' lateral tensions), scaled so
//!    that the mean free tension is `per_cell.free_tension`;
//! 2. relax the observed tissue with those per-cell tensions ([`ForwardModel::relax`]: the volume
//!    passes, measured like the data), measure the relaxed tissue like the data (voxelised on the
//!    observed grid and meshed with the observed options, for a label input) and estimate its map
//!    T_sim with the same settings;
//! 3. stop when T_sim/T_obs − 1 has an rms below `per_cell.tolerance` over every interface
//!    determined in both (the simulated map regauged to the observed one's free interfaces); else
//!    correct multiplicatively by c = (T_obs/T_sim)^step, clamped to ×/÷ 1.25 — f_i ← f_i·c on each
//!    cell's free interface, the model's cell–cell tensions a_i + a_j ← (a_i + a_j)·c refitted to
//!    per-cell a_i by least squares (damped towards the current a_i where the interfaces leave a
//!    direction free, e.g. a doublet's split of T_12) — rescale to the free tension, and go to 2
//!    (from the observed tissue again, unless `per_cell.warm_start`).
//!
//! Each iteration costs one relaxation and one measurement, whatever the number of cells, so a map
//! of hundreds of parameters costs a few relaxations. The answer is the per-cell tensions of the
//! iteration with the smallest mismatch; the map's tensions are the model's (f_i, and a_i + a_j for
//! cell–cell interfaces), its pressures the simulation's.
//!
//! Measured (docs book, "Per-cell maps"): the forward model's own noise — relaxations that stop a
//! little apart, junctions that move by a voxel — is 2–4 % rms on small clusters at 10 voxels per
//! diameter, with single iterations off by up to 15 %, so the refinement cannot resolve biases below
//! that; it is why the correction is damped and the answer is the best iteration, not the last.
//!
//! Intervals: each interface's `tension_sd` combines, relative to the tension, the mismatch left at
//! the answer r, the spread s of one measurement over the n sub-voxel placements the relaxed tissue
//! was measured at (the observed mask is one placement, the simulated map a mean of n), and a model
//! error m for what neither shows — the measurement's bias that the relaxed tissue reproduces at
//! the wrong tensions — a floor and a part proportional to voxel size over cell diameter, calibrated
//! on Surface Evolver truths (`per_cell.model_error`): σ² = r² + s²(1 + 1/n) + m². Its coverage on
//! held-out truths is measured by `docs/scripts/per-cell.sh coverage`. A cell's pressure is
//! proportional to the tension that holds it at a given shape: its `pressure_sd` combines that
//! tension's relative sd (its free surface's; an enclosed cell's interfaces', area-weighted) and a
//! model error for the shape (`per_cell.model_error.pressure`), calibrated and measured the same way;
//! a cell's lateral tension's sd, the least squares' through the interfaces' sds and a model error
//! for their correlation (`per_cell.model_error.lateral`).

use super::InferenceError;
use super::config::{FitConfig, FitMode};
use super::forward::{ForwardModel, Observation};
use super::run::FitOptions;
use super::space::ParameterSpace;
use crate::geometry::Real;
use crate::imaging::voxelize;
use crate::io::{CellField, OutputGroup, Progress, vtp_bytes_in};
use crate::mechanics::{CellOverrideConfig, ContactModel, Parameters, PerFaceType};
use crate::mesh::Tissue;
use crate::meshing::{label_interfaces, mesh_labels};
use crate::morphology::tensions::{FieldOfView, TensionMap, TensionSettings, estimate_tensions};
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use serde::Serialize;
use std::collections::BTreeMap;
use std::io::Write;
use std::path::Path;
use std::time::Instant;

/// The files a per-cell fit writes into its folder (with `fit.toml` and `model.toml`).
pub const PER_CELL_FILES: [&str; 8] = [
    "cells.csv",
    "interfaces.csv",
    "iterations.csv",
    "tissue.vtp",
    "relaxed.vtp",
    "cell_overrides.toml",
    "map.png",
    "tension_histogram.png",
];

/// An interface of the map: two cell labels, `b` = 0 for the medium (a < b otherwise).
type Key = (u32, u32);

/// Determined tensions by interface.
type TensionsByInterface = BTreeMap<Key, Real>;

/// Interfaces whose observed tension is below this fraction of the gauge (the mean free tension) are
/// left out of the map (see [`run_per_cell`]).
const MIN_RELATIVE_TENSION: Real = 0.05;

/// A best rms mismatch above this (or 5 × `per_cell.tolerance`, if larger) is a poor fit.
pub const POOR_FIT_MISMATCH: Real = 0.10;

/// One iteration of the refinement.
#[derive(Clone, Debug, Serialize)]
pub struct Iteration {
    pub iteration: usize,
    /// "converged", "accepted" (within `forward.accept_residual`), "unconverged" or "failed".
    pub relaxation: &'static str,
    pub steps: u64,
    pub residual: Real,
    /// Rms and largest |T_sim/T_obs − 1| over the interfaces determined in both maps (NaN when the
    /// relaxation or its measurement failed).
    pub rms_mismatch: Real,
    pub max_mismatch: Real,
    /// Interfaces compared.
    pub interfaces: usize,
    pub seconds: Real,
    /// Why the relaxation or its measurement failed (empty otherwise).
    pub reason: String,
}

/// `result.json` of a per-cell fit. It carries the fields every fit's result has
/// (`converged`, `poor_fit`, `parameters`, `ratios`, `best_relaxation`), so a pipeline reads it like
/// a global fit's.
#[derive(Clone, Debug, Serialize)]
pub struct PerCellResult {
    pub mode: &'static str,
    /// The mismatch fell below `per_cell.tolerance`.
    pub converged: bool,
    /// The best mismatch is over [`POOR_FIT_MISMATCH`] (or 5 × the tolerance, if larger): the model
    /// cannot make the data's map (say, a non-additive map, or a tissue the relaxation changes).
    pub poor_fit: bool,
    pub tolerance: Real,
    /// The iteration whose tensions are the answer (1-based; the smallest mismatch).
    pub best_iteration: usize,
    pub rms_mismatch: Real,
    pub max_mismatch: Real,
    /// The direct estimate's own mismatch on the observed tissue: the rms of T_sim/T_obs − 1 at the
    /// first iteration, i.e. how far the start was (the bias the refinement took out).
    pub start_mismatch: Real,
    pub iterations: usize,
    /// The mean free tension the map is scaled to, N/m and mN/m.
    pub free_tension_n_per_m: Real,
    pub free_tension_mn_per_m: Real,
    pub cells: usize,
    pub interfaces: usize,
    /// Rms of (a_i + a_j − T_ij)/T_ij of the observed map against the start's per-cell tensions: how
    /// far the data's map is from one per-cell tensions can make.
    pub additive_residual_rms: Option<Real>,
    /// What `tension_sd` is, and where its coverage was measured.
    pub uncertainty: String,
    /// The observed mask's mean cell diameter over its voxel size (the model error scales with its
    /// inverse); `None` for a mesh input.
    pub voxels_per_diameter: Option<Real>,
    /// `per_cell.model_error` at this resolution: the relative errors added to `tension_sd`.
    pub model_error: ModelErrorAt,
    /// Empty in this mode (the answer is in cells.csv and interfaces.csv).
    pub parameters: BTreeMap<String, Real>,
    pub ratios: BTreeMap<String, Real>,
    pub best_relaxation: BestRelaxationNote,
    pub wall_seconds: Real,
    pub threads: usize,
    pub warnings: Vec<String>,
    /// The boundary noise added to the simulated masks (`forward.roughen_voxels`); `None` when
    /// nothing was roughened.
    pub roughen: Option<super::forward::RoughnessCalibration>,
    /// Cells whose start was their direct estimate times a previous time point's correction
    /// ([`run_per_cell_from`]); 0 when every cell started from the direct estimate alone.
    pub previous_frame_cells: usize,
    /// The forward model's contact model: with `coupling` a cell–cell interface's tension is the
    /// two cells' lateral tensions; with `spring` each cell has one tension and its own adhesion ω_i
    /// (cells.csv `adhesion_*`), T_ij = γ_i + γ_j − (ω_i + ω_j)·c²/4.
    pub contact_model: ContactModel,
    /// The contact cutoff c of the forward simulations (m; spring adhesion energy per side ω·c²/4).
    pub contact_cutoff_m: Real,
    /// Values a spring map raised so that the cells' adhesions and pressures do not push them into
    /// each other (the largest over the iterations, by key: repulsion in Pa/m, time step in s).
    pub raised: BTreeMap<String, Real>,
    /// Per cell, the answer over the direct estimate it started from (free and lateral): the
    /// correction of the measurement's bias the refinement found, which the next time point of a
    /// series starts with ([`run_per_cell_from`]).
    #[serde(skip)]
    pub correction: CellTensions,
}

/// `model_error` of [`PerCellResult`]: the relative model errors of this run's interfaces.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct ModelErrorAt {
    pub cell_cell: Real,
    pub cell_medium: Real,
    /// Added to every cell's `pressure_sd`.
    pub pressure: Real,
    /// Added to every cell's `lateral_tension_sd`.
    pub lateral: Real,
}

/// `best_relaxation` of [`PerCellResult`].
#[derive(Clone, Debug, Serialize)]
pub struct BestRelaxationNote {
    pub failed: bool,
    pub reason: String,
}

impl PerCellResult {
    /// One line for a terminal or log.
    pub fn summary_line(&self) -> String {
        let state = if self.converged {
            "converged".to_string()
        } else {
            format!("NOT converged (tolerance {:.3})", self.tolerance)
        };
        let poor = if self.poor_fit { "; POOR FIT: the model does not make the data's map" } else { "" };
        format!(
            "per-cell map of {} cells, {} interfaces: mismatch {:.4} rms ({:.4} max) after {} iterations \
             (start {:.4}), {state}{poor}",
            self.cells, self.interfaces, self.rms_mismatch, self.max_mismatch, self.iterations, self.start_mismatch
        )
    }
}

/// A row of `cells.csv`.
#[derive(Serialize, Default)]
struct CellRow {
    cell: u32,
    free_tension_mn_per_m: Option<Real>,
    lateral_tension_mn_per_m: Option<Real>,
    free_tension_n_per_m: Option<Real>,
    /// Empty where the cell–cell interfaces do not determine the cell's own lateral tension (a
    /// doublet's two cells, a chain's: only their sums are known, in interfaces.csv).
    lateral_tension_n_per_m: Option<Real>,
    /// Standard uncertainties: the free surface's `tension_sd`; the lateral tension's from the
    /// interfaces' `tension_sd` through the least squares a_i + a_j = T_ij (independent errors).
    free_tension_sd_mn_per_m: Option<Real>,
    lateral_tension_sd_mn_per_m: Option<Real>,
    lateral_determined: bool,
    /// Where the refinement started this cell: "direct estimate", or "corrected by previous frame"
    /// (the direct estimate times the previous time point's correction, `tissuefit fit-series`).
    start: &'static str,
    /// The direct estimate's, mN/m.
    direct_free_tension_mn_per_m: Option<Real>,
    direct_lateral_tension_mn_per_m: Option<Real>,
    direct_free_tension_n_per_m: Option<Real>,
    direct_lateral_tension_n_per_m: Option<Real>,
    /// The relaxed simulation's pressure at the answer.
    pressure_pa: Option<Real>,
    pressure_kpa: Option<Real>,
    /// The pressure's standard uncertainty, and its parts (relative) in quadrature: the sd of the
    /// tension that holds the cell ([`holding_tension_sd`]) and the model error
    /// (`per_cell.model_error.pressure`).
    pressure_sd_pa: Option<Real>,
    pressure_sd_kpa: Option<Real>,
    pressure_tension_sd: Option<Real>,
    pressure_model_error: Real,
    /// The model error (relative) in `lateral_tension_sd` (`per_cell.model_error.lateral`).
    lateral_model_error: Real,
    /// Spring contacts only, where the cell's lateral tension is determined: the cell's adhesion
    /// ω (Pa/m), the adhesion energy of its side of a contact W = ω·c²/4 = f − a (J/m² = N/m; and
    /// mN/m) with its standard uncertainty (free and lateral sds in quadrature), and
    /// W/γ = ω·c²/(4γ), the w/(2γ) of a contact between two cells alike.
    adhesion_pa_per_m: Option<Real>,
    adhesion_energy_mj_per_m2: Option<Real>,
    adhesion_energy_sd_mj_per_m2: Option<Real>,
    adhesion_energy_j_per_m2: Option<Real>,
    adhesion_over_tension: Option<Real>,
    volume_um3: Real,
}

/// A row of `interfaces.csv`.
#[derive(Serialize, Default)]
struct InterfaceRow {
    cell_a: u32,
    /// 0: the medium.
    cell_b: u32,
    /// The model's tension of the interface (f_a for the medium, a_a + a_b between cells).
    tension_mn_per_m: Option<Real>,
    /// The standard uncertainty of `tension` (see [`relative_uncertainty`]).
    tension_sd_mn_per_m: Option<Real>,
    tension_n_per_m: Option<Real>,
    tension_sd_n_per_m: Option<Real>,
    /// "placements": `tension_sd` from the spread over sub-voxel placements; "direct estimate": from
    /// the observed direct estimate's first-order uncertainty (too narrow; one placement measured).
    sd_source: &'static str,
    /// The parts of `tension_sd` (relative): the spread of one measurement over `placements`
    /// sub-voxel placements, and the model error added (`per_cell.model_error`).
    placement_sd: Option<Real>,
    placements: Option<usize>,
    model_error: Real,
    /// The direct estimate of the observed tissue, scaled to the same free tension, and its
    /// first-order uncertainty (force-balance residuals).
    direct_mn_per_m: Option<Real>,
    direct_sd_mn_per_m: Option<Real>,
    /// The direct estimates of the observed and the relaxed tissue at the answer, relative to their
    /// mean cell–medium tension; mismatch = simulated/observed − 1.
    observed_relative: Option<Real>,
    simulated_relative: Option<Real>,
    mismatch: Option<Real>,
    area_um2: Real,
}

/// Per-cell tensions (N/m) by cell label: what the refinement adjusts, a per-cell fit's answer
/// ([`PerCellResult::answer`]) and the start of the next time point's fit ([`run_per_cell_from`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CellTensions {
    /// Each cell's free (cell–medium) tension.
    pub free: BTreeMap<u32, Real>,
    /// Each cell's lateral tension a_i (a cell–cell interface's tension is a_i + a_j).
    pub lateral: BTreeMap<u32, Real>,
}

impl CellTensions {
    /// The model's tension of interface `k`.
    fn of(&self, (a, b): Key) -> Option<Real> {
        if b == 0 { self.free.get(&a).copied() } else { Some(self.lateral.get(&a)? + self.lateral.get(&b)?) }
    }

    fn overrides(&self, contacts: Contacts) -> Vec<CellOverrideConfig> {
        self.free
            .keys()
            .chain(self.lateral.keys())
            .copied()
            .collect::<std::collections::BTreeSet<u32>>()
            .into_iter()
            .map(|id| {
                let free = self.free.get(&id).copied();
                let lateral = self.lateral.get(&id).copied();
                match contacts {
                    Contacts::Lateral => CellOverrideConfig {
                        id,
                        surface_tension: PerFaceType { apical: free, lateral, basal: free },
                        adhesion: PerFaceType::default(),
                    },
                    Contacts::Adhesion { cutoff } => {
                        let omega = free.zip(lateral).map(|(f, a)| adhesion_of(f, a, cutoff));
                        CellOverrideConfig {
                            id,
                            surface_tension: PerFaceType { apical: free, lateral: free, basal: free },
                            adhesion: PerFaceType { apical: omega, lateral: omega, basal: omega },
                        }
                    }
                }
            })
            .collect()
    }

    /// With spring contacts, every lateral tension at most its cell's free tension (ω_i ≥ 0: a
    /// spring contact adheres, it cannot make an interface dearer than the two free surfaces);
    /// the cells clamped are added to `clamped`.
    fn bound_by_adhesion(&mut self, contacts: Contacts, clamped: &mut std::collections::BTreeSet<u32>) {
        if contacts == Contacts::Lateral {
            return;
        }
        for (c, a) in self.lateral.iter_mut() {
            if let Some(&f) = self.free.get(c)
                && *a > f
            {
                *a = f;
                clamped.insert(*c);
            }
        }
    }

    /// Scales every tension so that the mean free tension is `target`.
    fn rescale(&mut self, target: Real) {
        if self.free.is_empty() {
            return;
        }
        let mean = self.free.values().sum::<Real>() / self.free.len() as Real;
        let s = target / mean;
        self.free.values_mut().chain(self.lateral.values_mut()).for_each(|v| *v *= s);
    }
}

/// The largest adhesion w/(2γ) = ω·c²/(4γ) of the regime table in which spring contacts were
/// checked against Young–Dupré (docs/src/generated/spring-regime.md); a map's cell beyond it is warned about.
const SPRING_ADHESION_CHECKED: Real = 0.6;

/// Cell labels as a list for a message ("1, 4, 7", or the first eight and a count).
fn join_ids(ids: &std::collections::BTreeSet<u32>) -> String {
    let shown: Vec<String> = ids.iter().take(8).map(u32::to_string).collect();
    if ids.len() > 8 { format!("{}, … ({} cells)", shown.join(", "), ids.len()) } else { shown.join(", ") }
}

/// How the model makes a cell–cell interface's tension T_ij = a_i + a_j out of per-cell values.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Contacts {
    /// Coupled contacts (or polarity from contacts): a cell's faces against another cell are
    /// lateral and carry its lateral tension a_i; the free faces its free tension f_i.
    Lateral,
    /// Spring contacts: every face of cell i carries one tension γ_i = f_i, and the cell's own
    /// adhesion ω_i (Pa/m) deepens the well of its side of a contact by ω_i·c²/4 (J/m²), so
    /// T_ij = γ_i + γ_j − (ω_i + ω_j)·c²/4 = a_i + a_j with ω_i = 4(f_i − a_i)/c²
    /// ([`adhesion_of`]). The map's adhesions are the cells' ω_i.
    Adhesion {
        /// The contact cutoff c (m) of the forward simulations.
        cutoff: Real,
    },
}

impl Contacts {
    fn of(model: ContactModel, cutoff: Real) -> Self {
        match model {
            ContactModel::Spring => Contacts::Adhesion { cutoff },
            ContactModel::Coupling => Contacts::Lateral,
        }
    }
}

/// A cell's spring adhesion ω = 4(f − a)/c² (Pa/m) for which an interface between it and a cell
/// alike has the tension 2a (Young–Dupré with w = ω·c²/2; the spring model, Methods Eq. 2), never
/// below 0: a lateral tension above the free one is no adhesion a spring contact can make (the
/// refinement then sees the interface's mismatch; see [`run_per_cell_from`]'s warnings).
fn adhesion_of(free: Real, lateral: Real, cutoff: Real) -> Real {
    (4.0 * (free - lateral) / (cutoff * cutoff)).max(0.0)
}

/// The base model with `tensions` as every cell's own values, and `tissue` carrying them (the start
/// of a relaxation); for a spring map its repulsion raised ([`stiffen`]).
fn model_with(
    base: &Parameters,
    tensions: &CellTensions,
    contacts: Contacts,
    tissue: &Tissue,
    raised: &mut BTreeMap<String, Real>,
) -> Result<(Parameters, Tissue), InferenceError> {
    let mut params = base.clone();
    params.cell_overrides = tensions.overrides(contacts);
    let mut begin = tissue.clone();
    params.apply_cell_overrides(&mut begin).map_err(|e| InferenceError::Config(e.to_string()))?;
    stiffen(&mut params, &begin, contacts, raised);
    Ok((params, begin))
}

/// With the cells' adhesions of a spring map set, the model's repulsion raised where it is below
/// what holds those adhesions and the cells' Laplace pressures apart
/// ([`Parameters::raise_repulsion_for_overrides`]; the map's ω_i may be many times the cell type's),
/// and the time step with it. Each value raised is logged the first time it exceeds what `raised`
/// holds (the largest so far, by key).
fn stiffen(params: &mut Parameters, tissue: &Tissue, contacts: Contacts, raised: &mut BTreeMap<String, Real>) {
    if contacts == Contacts::Lateral {
        return;
    }
    for d in params.raise_repulsion_for_overrides(tissue) {
        let before = raised.get(&d.key).copied();
        let larger = if d.key.ends_with("time_step") {
            before.is_none_or(|b| d.value < b)
        } else {
            before.is_none_or(|b| d.value > b)
        };
        if larger {
            tracing::info!("{} = {:.3e} (was {:.3e}): {}", d.key, d.value, d.default, d.from);
            raised.insert(d.key.clone(), d.value);
        }
    }
}

/// `a[c] / b[c]` for every cell in both with a positive, finite ratio.
pub(crate) fn ratios(a: &BTreeMap<u32, Real>, b: &BTreeMap<u32, Real>) -> BTreeMap<u32, Real> {
    a.iter().filter_map(|(c, x)| Some((*c, x / b.get(c)?))).filter(|(_, r)| r.is_finite() && *r > 0.0).collect()
}

/// The determined tensions of a map, by interface (relative to its gauge).
fn tensions_of(map: &TensionMap) -> BTreeMap<Key, Real> {
    map.interfaces.iter().filter_map(|f| Some(((f.cell_a, f.cell_b), f.tension?))).collect()
}

/// Per-cell lateral tensions a with a_i + a_j ≈ t_ij over `rows`, by least squares damped towards
/// `prior` (weight `DAMPING` relative to one interface), so that a direction the interfaces leave
/// free keeps its prior value and a determined one moves by at most that weight off the fit.
fn lateral_fit(cells: &[u32], rows: &[(Key, Real)], prior: &BTreeMap<u32, Real>) -> BTreeMap<u32, Real> {
    const DAMPING: Real = 1e-3;
    let column: BTreeMap<u32, usize> = cells.iter().enumerate().map(|(k, &c)| (c, k)).collect();
    let n = cells.len();
    let mut normal = DMatrix::<Real>::zeros(n, n);
    let mut rhs = DVector::<Real>::zeros(n);
    for &((a, b), t) in rows {
        let (Some(&i), Some(&j)) = (column.get(&a), column.get(&b)) else { continue };
        for (p, q) in [(i, i), (i, j), (j, i), (j, j)] {
            normal[(p, q)] += 1.0;
        }
        rhs[i] += t;
        rhs[j] += t;
    }
    for (k, c) in cells.iter().enumerate() {
        normal[(k, k)] += DAMPING;
        rhs[k] += DAMPING * prior.get(c).copied().unwrap_or(0.0);
    }
    let solved = normal.cholesky().map(|ch| ch.solve(&rhs));
    cells
        .iter()
        .enumerate()
        .map(|(k, &c)| {
            let p = prior.get(&c).copied().unwrap_or(0.0);
            let v = solved.as_ref().map_or(p, |x| x[k]);
            (c, if v.is_finite() { v } else { p })
        })
        .collect()
}

/// `simulated` in the observed map's gauge: scaled so that the cell–medium interfaces determined in
/// both maps have the same summed tension. Each map's own gauge is the mean over *its* free
/// interfaces, and a relaxed tissue measured like the data may show a free patch the data do not
/// (or lose one), which would shift every tension of one map against the other.
fn regauged(observed: &BTreeMap<Key, Real>, simulated: &BTreeMap<Key, Real>) -> BTreeMap<Key, Real> {
    let (mut o, mut s) = (0.0, 0.0);
    for (k, t) in simulated.iter().filter(|((_, b), _)| *b == 0) {
        if let Some(v) = observed.get(k) {
            o += v;
            s += t;
        }
    }
    let factor = if o > 0.0 && s > 0.0 { o / s } else { 1.0 };
    simulated.iter().map(|(k, t)| (*k, t * factor)).collect()
}

/// The largest factor by which one iteration changes a tension (and its inverse the smallest): the
/// correction is clamped to it, so a noisy or wrong measurement cannot throw the next relaxation far
/// off (a tissue whose tensions halve at once may fold through itself).
const MAX_STEP: Real = 1.25;

/// The multiplicative correction (observed/simulated)^step, clamped to [1/MAX_STEP, MAX_STEP].
fn correction(observed: Real, simulated: Real, step: Real) -> Real {
    (observed / simulated).powf(step).clamp(1.0 / MAX_STEP, MAX_STEP)
}

/// The rms and largest |sim/obs − 1| over the interfaces in both maps, and how many.
fn mismatch(observed: &BTreeMap<Key, Real>, simulated: &BTreeMap<Key, Real>) -> (Real, Real, usize) {
    let r: Vec<Real> =
        observed.iter().filter_map(|(k, o)| simulated.get(k).map(|s| s / o - 1.0)).filter(|r| r.is_finite()).collect();
    if r.is_empty() {
        return (Real::NAN, Real::NAN, 0);
    }
    let rms = (r.iter().map(|x| x * x).sum::<Real>() / r.len() as Real).sqrt();
    (rms, r.iter().fold(0.0, |m: Real, x| m.max(x.abs())), r.len())
}

/// The state of the best iteration so far.
struct Best {
    iteration: usize,
    rms: Real,
    max: Real,
    tensions: CellTensions,
    relaxed: Tissue,
    simulated: BTreeMap<Key, Real>,
    pressure: BTreeMap<u32, Real>,
    /// Each interface's spread over the placements the relaxed tissue was measured at.
    spread: BTreeMap<Key, Spread>,
}

/// The observed mask's voxel size over its moving cells' mean equivalent diameter (`None` for a
/// mesh input): the resolution the model error scales with.
fn resolution(obs: &Observation) -> Option<Real> {
    let voxel = obs.labels.as_ref()?.voxel_size().iter().copied().fold(0.0, Real::max);
    let d: Vec<Real> = obs
        .tissue
        .cells()
        .iter()
        .filter(|c| obs.cell_labels.contains(&c.id().0))
        .map(|c| (6.0 * c.mesh().signed_volume().abs() / std::f64::consts::PI).cbrt())
        .collect();
    let mean = d.iter().sum::<Real>() / d.len().max(1) as Real;
    (mean > 0.0 && voxel > 0.0).then(|| voxel / mean)
}

/// The standard uncertainty of each cell's lateral tension a_i fitted to a_i + a_j = T_ij over
/// `rows` ((i, j), sd of T_ij), with independent errors: the i-th row of the pseudo-inverse A⁺
/// weighted by the sds. `None` (left out) for a cell the rows do not determine: one with a
/// component in A's null space (a doublet's two cells, the cells of a chain), whose a_i only the
/// sums fix.
fn lateral_uncertainty(cells: &[u32], rows: &[((u32, u32), Real)]) -> BTreeMap<u32, Real> {
    let column: BTreeMap<u32, usize> = cells.iter().enumerate().map(|(k, &c)| (c, k)).collect();
    let rows: Vec<(usize, usize, Real)> =
        rows.iter().filter_map(|&((a, b), sd)| Some((*column.get(&a)?, *column.get(&b)?, sd))).collect();
    if rows.is_empty() {
        return BTreeMap::new();
    }
    let mut a = DMatrix::<Real>::zeros(rows.len(), cells.len());
    for (r, &(i, j, _)) in rows.iter().enumerate() {
        a[(r, i)] = 1.0;
        a[(r, j)] = 1.0;
    }
    let svd = a.svd(true, true);
    let Some(v_t) = svd.v_t.clone() else { return BTreeMap::new() };
    let largest = svd.singular_values.iter().copied().fold(0.0, Real::max);
    let tol = 1e-9 * largest.max(1.0);
    // Rows of Vᵀ with a zero singular value span the null space (Vᵀ has min(rows, cells) rows; with
    // fewer rows than cells the rest of the space is null too).
    let rank_rows: Vec<usize> = (0..svd.singular_values.len()).filter(|&k| svd.singular_values[k] > tol).collect();
    let Ok(pinv) = svd.pseudo_inverse(tol) else { return BTreeMap::new() };
    let mut out = BTreeMap::new();
    for (k, &c) in cells.iter().enumerate() {
        // e_k lies in the row space iff its projection onto the non-null right singular vectors is e_k.
        let in_row_space: Real = rank_rows.iter().map(|&q| v_t[(q, k)].powi(2)).sum();
        if (in_row_space - 1.0).abs() > 1e-6 {
            continue;
        }
        let var: Real = rows.iter().enumerate().map(|(r, &(_, _, sd))| (pinv[(k, r)] * sd).powi(2)).sum();
        out.insert(c, var.sqrt());
    }
    out
}

/// `uncertainty` of the result: what `tension_sd` is for this run.
fn uncertainty_note(best: &Best, shifts: usize) -> String {
    let how = "tension_sd: the refined tension's standard uncertainty, σ² = r² + s²(1 + 1/n) + m² relative to it, \
               with r the interface's mismatch at the answer, s the spread of its measurement over n sub-voxel \
               placements of the relaxed tissue and m the model error (per_cell.model_error: a floor and a \
               coefficient × voxel size / mean cell diameter; the floor alone for a mesh input); pressure_sd (cells.csv): \
               the pressure's, the relative sd of the tension that holds it (the cell's free surface's, else its \
               interfaces' area-weighted) and \
               per_cell.model_error.pressure in quadrature; lateral_tension_sd: the least squares a_i + a_j = T_ij \
               through the cell-cell interfaces' sds and per_cell.model_error.lateral in quadrature";
    if best.spread.is_empty() {
        format!(
            "{how}; this run measured {shifts} placement(s), so s is the observed direct estimate's first-order \
             uncertainty instead, which is known to be too narrow (set forward.measure_shifts ≥ 2); \
             sd_source says which per interface"
        )
    } else {
        format!(
            "{how}; interfaces no two placements determined use the direct estimate's first-order uncertainty \
             instead (sd_source); coverage measured on Surface Evolver truths: the docs book, Per-cell maps"
        )
    }
}

/// Runs the per-cell fit of `config` on `observation` into `out` (created if needed).
pub fn run_per_cell(
    config: &FitConfig,
    observation: Observation,
    out: &Path,
    options: &FitOptions,
) -> Result<PerCellResult, InferenceError> {
    run_per_cell_from(config, observation, out, options, None)
}

/// [`run_per_cell`] whose start, for the cells that `carried` has factors for, is the direct
/// estimate times those factors (a previous time point's [`PerCellResult::correction`], its cells
/// labelled by track): the measurement's bias changes slowly with the shapes, so the previous
/// correction carries over while the direct estimate follows the tensions' change. Other cells
/// start from the direct estimate; the whole start is scaled to the free tension.
pub fn run_per_cell_from(
    config: &FitConfig,
    observation: Observation,
    out: &Path,
    options: &FitOptions,
    carried: Option<&CellTensions>,
) -> Result<PerCellResult, InferenceError> {
    debug_assert_eq!(config.mode, FitMode::PerCell);
    let started = Instant::now();
    if options.resume {
        tracing::info!("a per-cell fit keeps no trace to resume from: its refinement runs again from the start");
    }
    let output_err = |p: &Path, e: &dyn std::fmt::Display| InferenceError::Output(format!("{}: {e}", p.display()));
    // Fixed values and the fitted parameters' starts set the base model; nothing is searched.
    let base = config.base_parameters()?;
    let space = ParameterSpace::from_config(&super::forward::resolved_parameters(config, &base, &observation)?)?;
    let base = space.apply(&base, &space.initial_point());
    let empty = ParameterSpace::from_config(&BTreeMap::new())?;
    let mut model = ForwardModel::new(observation, base, empty, config.objective.clone(), config.forward.clone())?;
    // A log (stderr not a terminal) also hears from inside a relaxation of many minutes, and a
    // listening caller (the Python API) can stop the refinement there.
    model.heartbeat = Some(crate::io::Heartbeat::new("fit", options.progress));
    model.watch = options.watch.clone();
    let roughen = super::run::calibrate_roughness(&mut model)?;
    let model = model;
    let mut warnings = Vec::new();
    let obs = &model.observation;
    let moving: Vec<u32> = obs.cell_labels.clone();
    let first =
        obs.tissue.cells().iter().find(|c| moving.contains(&c.id().0)).expect("an observation has a moving cell");
    let type_params = model
        .base
        .parameters_of(first)
        .ok_or_else(|| InferenceError::Config(format!("cell {}: its cell type is not in the model", first.id().0)))?;
    let free_tension = config.per_cell.free_tension.unwrap_or(type_params.faces.apical.surface_tension);
    if free_tension.is_nan() || free_tension <= 0.0 {
        return Err(InferenceError::Config(format!(
            "per_cell.free_tension: the model's apical tension of cell {}'s type is {free_tension}; give \
             per_cell.free_tension (N/m), the scale of the map",
            first.id().0
        )));
    }
    let contacts = Contacts::of(model.base.numerics.contact_model, model.base.numerics.contact_cutoff);
    if contacts == Contacts::Lateral
        && model.base.numerics.polarity == crate::mechanics::Polarity::None
        && !obs.tissue.cells().iter().any(|c| c.face_types().contains(&crate::mesh::FaceType::Lateral))
    {
        return Err(InferenceError::Config(
            "the per-cell map sets each cell's lateral tension, but the model's polarity = \"none\" leaves the \
             observed tissue without lateral faces, so it would change nothing; set \
             model_overrides.numerics.polarity = \"contacts\" (faces touching another cell become lateral)"
                .into(),
        ));
    }
    let voxel = obs.labels.as_ref().map(|l| l.voxel_size().iter().copied().fold(0.0, Real::max));
    // Faces on the image border are cut, not free (the simulated tissue is voxelised on the same grid).
    let field_of_view = obs.labels.as_ref().map(FieldOfView::of_volume);
    let settings = TensionSettings { rounding_scale: voxel, field_of_view, ..Default::default() };
    // A label input: each face's neighbour read from the labels (exact, no contact distance), on a
    // copy (the simulations start from the observed tissue as meshed). Face order is kept.
    let labelled;
    let estimated = match &obs.labels {
        Some(volume) => {
            let mut t = obs.tissue.clone();
            label_interfaces(&mut t, volume)
                .map_err(|e| InferenceError::Observed(format!("reading interfaces from the labels: {e}")))?;
            labelled = t;
            &labelled
        }
        None => &obs.tissue,
    };
    let observed_map = estimate_tensions(estimated, &settings)
        .map_err(|e| InferenceError::Observed(format!("the direct estimate of the observed tissue: {e}")))?;
    warnings.extend(observed_map.warnings.iter().map(|w| format!("observed tissue: {w}")));
    let observed = tensions_of(&observed_map);
    let observed: BTreeMap<Key, Real> =
        observed.into_iter().filter(|((a, b), _)| moving.contains(a) && (*b == 0 || moving.contains(b))).collect();
    // A tension below a twentieth of the gauge is no tension the model can run with (a spurious free
    // patch of a buried cell, a sliver of an interface): such an interface is not a target, and the
    // cell keeps the start value for it.
    let (observed, spurious): (BTreeMap<Key, Real>, BTreeMap<Key, Real>) =
        observed.into_iter().partition(|(_, t)| *t >= MIN_RELATIVE_TENSION);
    for ((a, b), t) in &spurious {
        let what = if *b == 0 { format!("cell {a}'s free surface") } else { format!("interface {a}-{b}") };
        warnings.push(format!(
            "{what}: the direct estimate {t:.3} (relative to the mean free tension) is no tension a model runs \
             with (a spurious patch or sliver?); left out of the map"
        ));
    }
    for w in warnings.iter().skip(observed_map.warnings.len()) {
        tracing::warn!("{w}");
    }
    if obs.labels.is_none()
        || obs.meshing.is_none()
        || !model.forward.measure_like_data
        || model.forward.measure_shifts < 2
    {
        let w = "the intervals (tension_sd) need the spread of each measurement over sub-voxel placements, which \
                 this run does not measure (a mesh input, measure_like_data = false or forward.measure_shifts < 2): \
                 they fall back to the direct estimate's first-order uncertainty, known to be too narrow; for a \
                 label input set forward.measure_shifts ≥ 2"
            .to_string();
        tracing::warn!("{w}");
        warnings.push(w);
    }
    if observed.keys().all(|&(_, b)| b == 0) {
        return Err(InferenceError::Observed(
            "the direct estimate determined no cell–cell interface between moving cells: there is no map to refine"
                .into(),
        ));
    }
    // The start: the direct estimate, scaled to the free tension.
    let mean_free = {
        let f: Vec<Real> = observed.iter().filter(|((_, b), _)| *b == 0).map(|(_, t)| *t).collect();
        if f.is_empty() { 1.0 } else { f.iter().sum::<Real>() / f.len() as Real }
    };
    let scale = free_tension / mean_free;
    let cell_cell: Vec<(Key, Real)> =
        observed.iter().filter(|((_, b), _)| *b != 0).map(|(k, t)| (*k, t * scale)).collect();
    let half_mean = cell_cell.iter().map(|(_, t)| t).sum::<Real>() / (2 * cell_cell.len()) as Real;
    let prior: BTreeMap<u32, Real> = moving.iter().map(|&c| (c, half_mean)).collect();
    let mut tensions = CellTensions {
        free: moving.iter().map(|&c| (c, observed.get(&(c, 0)).map_or(free_tension, |t| t * scale))).collect(),
        lateral: lateral_fit(&moving, &cell_cell, &prior),
    };
    let floor = 0.02 * free_tension;
    tensions.lateral.values_mut().for_each(|a| *a = a.max(floor));
    tensions.free.values_mut().for_each(|f| *f = f.max(floor));
    let mut beyond_adhesion = std::collections::BTreeSet::new();
    tensions.bound_by_adhesion(contacts, &mut beyond_adhesion);
    let start = tensions.clone();
    let additive_residual_rms = {
        let r: Vec<Real> = cell_cell.iter().filter_map(|&(k, t)| Some(start.of(k)? / t - 1.0)).collect();
        (!r.is_empty()).then(|| (r.iter().map(|x| x * x).sum::<Real>() / r.len() as Real).sqrt())
    };
    // A previous time point's correction applied to the direct estimate where it has the cell.
    let mut previous_frame = std::collections::BTreeSet::new();
    if let Some(carried) = carried {
        for c in &moving {
            for (from, to) in [(&carried.free, &mut tensions.free), (&carried.lateral, &mut tensions.lateral)] {
                let factor = from.get(c).copied().filter(|v| v.is_finite() && *v > 0.0);
                if let (Some(factor), Some(v)) = (factor, to.get_mut(c)) {
                    *v = (*v * factor).max(floor);
                    previous_frame.insert(*c);
                }
            }
        }
        tensions.rescale(free_tension);
        tracing::info!(
            "{} of {} cells start from the direct estimate times the previous time point's correction",
            previous_frame.len(),
            moving.len()
        );
    }

    std::fs::create_dir_all(out).map_err(|e| output_err(out, &e))?;
    let resolved = toml::to_string(config).map_err(|e| InferenceError::Output(e.to_string()))?;
    crate::io::write_bytes_atomically(&out.join("fit.toml"), resolved.as_bytes()).map_err(|e| output_err(out, &e))?;

    let iterations = config.per_cell.iterations;
    let step = config.per_cell.step;
    let mut progress = Progress::new(
        "fit",
        iterations as u64,
        "iteration",
        "{elapsed_precise} [{wide_bar}] {pos}/{len} iterations, {msg}",
        options.progress,
    )
    .with_watch(options.watch.clone());
    let mut trace: Vec<Iteration> = Vec::new();
    let mut stiffened: BTreeMap<String, Real> = BTreeMap::new();
    let mut best: Option<Best> = None;
    let mut warm: Tissue = obs.tissue.clone();
    let mut converged = false;
    for iteration in 1..=iterations {
        let t0 = Instant::now();
        let (params, begin) = model_with(&model.base, &tensions, contacts, &warm, &mut stiffened)?;
        let relaxed = model.relax_reporting(&params, &begin, || format!("iteration {iteration} of {iterations}"));
        let mut row = Iteration {
            iteration,
            relaxation: "failed",
            steps: 0,
            residual: Real::NAN,
            rms_mismatch: Real::NAN,
            max_mismatch: Real::NAN,
            interfaces: 0,
            seconds: 0.0,
            reason: String::new(),
        };
        let measured = match relaxed {
            Err((reason, steps)) => {
                row.steps = steps;
                Err(reason)
            }
            Ok((tissue, summary)) => {
                row.steps = summary.steps;
                row.residual = summary.residual;
                row.relaxation = if summary.converged {
                    "converged"
                } else if summary.residual <= model.forward.accept_residual {
                    "accepted"
                } else {
                    "unconverged"
                };
                measure_map(&model, &tissue, &settings, &params).map(|m| (tissue, m))
            }
        };
        if model.watch.stopped() {
            progress.finish();
            return Err(InferenceError::Stopped);
        }
        let (tissue, Measured { map: simulated, pressure, spread }) = match measured {
            Ok(m) if row.relaxation != "unconverged" => m,
            Ok(_) => {
                row.reason = format!(
                    "not converged: residual {:.3e} > forward.accept_residual {:.3e}",
                    row.residual, model.forward.accept_residual
                );
                row.seconds = t0.elapsed().as_secs_f64();
                progress.line(iteration as u64, &format!("iteration {iteration}: {}", row.reason));
                trace.push(row);
                break;
            }
            Err(reason) => {
                row.reason = reason;
                row.seconds = t0.elapsed().as_secs_f64();
                progress.line(iteration as u64, &format!("iteration {iteration}: failed: {}", row.reason));
                trace.push(row);
                break;
            }
        };
        let simulated = regauged(&observed, &simulated);
        let (rms, max, n) = mismatch(&observed, &simulated);
        row.rms_mismatch = rms;
        row.max_mismatch = max;
        row.interfaces = n;
        row.seconds = t0.elapsed().as_secs_f64();
        progress.line(
            iteration as u64,
            &format!(
                "iteration {iteration}: mismatch {rms:.4} rms, {max:.4} max over {n} interfaces; {} steps, {:.1} s",
                row.steps, row.seconds
            ),
        );
        trace.push(row);
        if best.as_ref().is_none_or(|b| rms < b.rms) {
            best = Some(Best {
                iteration,
                rms,
                max,
                tensions: tensions.clone(),
                relaxed: tissue.clone(),
                simulated: simulated.clone(),
                pressure,
                spread,
            });
        }
        if rms <= config.per_cell.tolerance {
            converged = true;
            break;
        }
        if iteration == iterations {
            break;
        }
        // The multiplicative correction.
        for (&c, f) in tensions.free.iter_mut() {
            if let (Some(o), Some(s)) = (observed.get(&(c, 0)), simulated.get(&(c, 0))) {
                *f *= correction(*o, *s, step);
            }
        }
        let rows: Vec<(Key, Real)> = observed
            .iter()
            .filter(|((_, b), _)| *b != 0)
            .filter_map(|(&k, o)| Some((k, tensions.of(k)? * correction(*o, *simulated.get(&k)?, step))))
            .collect();
        tensions.lateral = lateral_fit(&moving, &rows, &tensions.lateral);
        tensions.lateral.values_mut().for_each(|a| *a = a.max(floor));
        tensions.free.values_mut().for_each(|f| *f = f.max(floor));
        tensions.bound_by_adhesion(contacts, &mut beyond_adhesion);
        tensions.rescale(free_tension);
        if config.per_cell.warm_start {
            warm = tissue;
        }
    }
    progress.finish();
    let Some(best) = best else {
        let last = trace.last().map(|r| r.reason.clone()).unwrap_or_default();
        return Err(InferenceError::Failed(format!(
            "the first relaxation with the direct estimate's tensions did not give a map: {last} (see {})",
            out.join("iterations.csv").display()
        )));
    };
    if !converged && trace.last().is_some_and(|r| r.relaxation == "failed" || !r.reason.is_empty()) {
        warnings.push(format!(
            "iteration {} ended the refinement: {}",
            trace.len(),
            trace.last().map(|r| r.reason.as_str()).unwrap_or("")
        ));
    }
    // What the spring map's adhesions could not do, or did beyond where they were checked.
    let mut late = Vec::new();
    if !beyond_adhesion.is_empty() {
        late.push(format!(
            "cells {}: their interfaces asked for a lateral tension above the cell's free tension, which no spring \
             adhesion makes (ω ≥ 0); held at no adhesion — their interfaces keep a mismatch (iterations.csv); \
             contact_model = \"coupling\" makes such maps",
            join_ids(&beyond_adhesion)
        ));
    }
    if let Contacts::Adhesion { .. } = contacts {
        // w/(2γ) of a contact between cells alike: ω·c²/(4γ) = 1 − a/f.
        let strong: std::collections::BTreeSet<u32> = best
            .tensions
            .free
            .iter()
            .filter(|(c, f)| best.tensions.lateral.get(c).is_some_and(|a| 1.0 - a / *f > SPRING_ADHESION_CHECKED))
            .map(|(c, _)| *c)
            .collect();
        if !strong.is_empty() {
            late.push(format!(
                "cells {}: adhesion w/(2γ) = ω·c²/(4γ) above {SPRING_ADHESION_CHECKED}, beyond the range in which \
                 spring contacts were checked against Young–Dupré (docs book, Spring contacts and Young–Dupré)",
                join_ids(&strong)
            ));
        }
        if model.base.numerics.contact_quadrature == crate::mechanics::ContactQuadrature::Vertices {
            late.push(
                "the map's adhesions run with numerics.contact_quadrature = \"vertices\", which under-adheres \
                 (contact angles 0.5–6° small at w/(2γ) = 0.3); set contact_quadrature = \"faces\""
                    .to_string(),
            );
        }
    }
    for w in &late {
        tracing::warn!("{w}");
    }
    warnings.extend(late);
    // The model that makes the answer's map (model.toml), its repulsion raised like the iterations'.
    let (params, _) = model_with(&model.base, &best.tensions, contacts, &obs.tissue, &mut stiffened)?;
    let start_mismatch = trace.first().map_or(Real::NAN, |r| r.rms_mismatch);
    let resolution = resolution(obs);
    let result = PerCellResult {
        mode: "per_cell",
        converged,
        poor_fit: best.rms > POOR_FIT_MISMATCH.max(5.0 * config.per_cell.tolerance),
        tolerance: config.per_cell.tolerance,
        best_iteration: best.iteration,
        rms_mismatch: best.rms,
        max_mismatch: best.max,
        start_mismatch,
        iterations: trace.len(),
        free_tension_n_per_m: free_tension,
        free_tension_mn_per_m: free_tension * 1e3,
        cells: moving.len(),
        interfaces: observed.len(),
        additive_residual_rms,
        uncertainty: uncertainty_note(&best, model.forward.measure_shifts),
        voxels_per_diameter: resolution.map(|r| 1.0 / r),
        model_error: {
            let m = &config.per_cell.model_error;
            let k = if contacts == Contacts::Lateral { 1.0 } else { config.per_cell.spring_model_error };
            ModelErrorAt {
                cell_cell: k * m.at(false, resolution),
                cell_medium: k * m.at(true, resolution),
                pressure: k * m.pressure_at(resolution),
                lateral: k * m.lateral_at(resolution),
            }
        },
        parameters: BTreeMap::new(),
        ratios: BTreeMap::new(),
        best_relaxation: BestRelaxationNote { failed: false, reason: String::new() },
        wall_seconds: started.elapsed().as_secs_f64(),
        threads: rayon::current_num_threads(),
        warnings,
        roughen,
        previous_frame_cells: previous_frame.len(),
        contact_model: model.base.numerics.contact_model,
        contact_cutoff_m: model.base.numerics.contact_cutoff,
        raised: stiffened,
        correction: CellTensions {
            free: ratios(&best.tensions.free, &start.free),
            lateral: ratios(&best.tensions.lateral, &start.lateral),
        },
    };
    write_outputs(
        out,
        &model,
        &params,
        &observed_map,
        &observed,
        &start,
        &previous_frame,
        &best,
        &trace,
        &result,
        scale,
        options,
    )?;
    Ok(result)
}

/// The relaxed tissue measured like the data (voxelised on the observed grid and meshed with the
/// observed options, for a label input; else as it lies), its direct estimate's determined tensions,
/// and every moving cell's pressure in the relaxed tissue (Pa).
fn measure_map(
    model: &ForwardModel,
    tissue: &Tissue,
    settings: &TensionSettings,
    params: &Parameters,
) -> Result<Measured, String> {
    let obs = &model.observation;
    let pressure: BTreeMap<u32, Real> = tissue
        .cells()
        .iter()
        .filter(|c| obs.cell_labels.contains(&c.id().0))
        .filter_map(|c| {
            let p = params.parameters_of(c)?;
            Some((c.id().0, p.pressure(c.mesh().signed_volume(), c.target_volume())))
        })
        .collect();
    let (Some(labels), Some(options), true) = (&obs.labels, &obs.meshing, model.forward.measure_like_data) else {
        let map = estimate_tensions(tissue, settings)
            .map_err(|e| format!("the direct estimate of the relaxed tissue: {e}"))?;
        return Ok(Measured { map: tensions_of(&map), pressure, spread: BTreeMap::new() });
    };
    // Like the data, at `forward.measure_shifts` sub-voxel placements (in parallel), each interface's
    // tension averaged over the placements that determine it (combined in shift order: the same on
    // any thread count).
    let size = labels.voxel_size();
    let each: Vec<Result<BTreeMap<Key, Real>, String>> = (0..model.forward.measure_shifts.max(1))
        .into_par_iter()
        .map(|k| {
            let o = super::forward::shift_offset(k);
            let offset = crate::geometry::Vec3::new(o[0] * size[0], o[1] * size[1], o[2] * size[2]);
            let mut shifted = tissue.clone();
            if k > 0 {
                for cell in shifted.cells_mut() {
                    for p in cell.positions_mut() {
                        *p += offset;
                    }
                }
            }
            let voxels =
                voxelize(&shifted, &labels.grid()).map_err(|e| format!("voxelising the relaxed tissue: {e}"))?;
            let voxels = model.roughen(&voxels, k)?;
            let mut meshed =
                mesh_labels(&voxels, options).map_err(|e| format!("meshing the relaxed tissue's voxels: {e}"))?;
            label_interfaces(&mut meshed.tissue, &voxels)
                .map_err(|e| format!("reading the relaxed tissue's interfaces from its voxels: {e}"))?;
            // The cells the image cuts are those of these voxels (as for the data's own).
            let settings = TensionSettings {
                field_of_view: settings.field_of_view.as_ref().map(|_| FieldOfView::of_volume(&voxels)),
                ..settings.clone()
            };
            let map = estimate_tensions(&meshed.tissue, &settings)
                .map_err(|e| format!("the direct estimate of the relaxed tissue (shift {k}): {e}"))?;
            Ok(tensions_of(&map))
        })
        .collect();
    let mut values: BTreeMap<Key, Vec<Real>> = BTreeMap::new();
    for map in each {
        for (k, t) in map? {
            values.entry(k).or_default().push(t);
        }
    }
    let map = values.iter().map(|(k, v)| (*k, v.iter().sum::<Real>() / v.len() as Real)).collect();
    let spread = values.iter().filter_map(|(k, v)| Some((*k, Spread::of(v)?))).collect();
    Ok(Measured { map, pressure, spread })
}

/// A relaxed tissue measured like the data: its determined tensions (each the mean over the
/// placements that determine it), its moving cells' pressures (Pa), and each interface's spread
/// over the placements (only where ≥ 2 placements determine it).
struct Measured {
    map: TensionsByInterface,
    pressure: BTreeMap<u32, Real>,
    spread: BTreeMap<Key, Spread>,
}

/// How one interface's measured tension scatters over the sub-voxel placements of one tissue.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Spread {
    /// The sample standard deviation relative to the mean.
    relative_sd: Real,
    /// Placements that determined the interface (≥ 2).
    placements: usize,
}

impl Spread {
    fn of(values: &[Real]) -> Option<Spread> {
        let n = values.len();
        if n < 2 {
            return None;
        }
        let mean = values.iter().sum::<Real>() / n as Real;
        let var = values.iter().map(|v| (v - mean).powi(2)).sum::<Real>() / (n - 1) as Real;
        let relative_sd = var.sqrt() / mean.abs();
        relative_sd.is_finite().then_some(Spread { relative_sd, placements: n })
    }
}

/// The relative standard uncertainty of an interface's refined tension, from what the refinement
/// measured at its answer: `mismatch` = simulated/observed − 1 there (a bias the last correction
/// left; it counts in full) and the spread of one measurement over sub-voxel placements. The
/// observed mask is one placement (its measurement error has the spread's sd), the simulated map
/// the mean over `placements` (sd/√n), and the answer errs by their difference:
/// σ² = r² + s²·(1 + 1/n) + m², with m the model error that neither shows
/// (`per_cell.model_error`, relative).
fn relative_uncertainty(mismatch: Real, spread: Spread, model_error: Real) -> Real {
    (mismatch.powi(2) + spread.relative_sd.powi(2) * (1.0 + 1.0 / spread.placements as Real) + model_error.powi(2))
        .sqrt()
}

/// The relative sd of the tension that holds cell `id`'s pressure: its free surface's where it has
/// one, else the area-weighted rms over its interfaces (a cell enclosed by others); `None` when no
/// interface of the cell has an sd.
fn holding_tension_sd(id: u32, interfaces: &[InterfaceRow]) -> Option<Real> {
    let relative = |r: &InterfaceRow| Some(r.tension_sd_n_per_m? / r.tension_n_per_m?);
    if let Some(free) = interfaces.iter().find(|r| r.cell_a == id && r.cell_b == 0) {
        return relative(free);
    }
    let (sum, area) = interfaces
        .iter()
        .filter(|r| r.cell_a == id || r.cell_b == id)
        .filter_map(|r| Some((relative(r)?, r.area_um2)))
        .fold((0.0, 0.0), |(s, a), (x, w)| (s + w * x * x, a + w));
    (area > 0.0).then(|| (sum / area).sqrt())
}

#[allow(clippy::too_many_arguments)]
fn write_outputs(
    out: &Path,
    model: &ForwardModel,
    params: &Parameters,
    observed_map: &TensionMap,
    observed: &BTreeMap<Key, Real>,
    start: &CellTensions,
    previous_frame: &std::collections::BTreeSet<u32>,
    best: &Best,
    trace: &[Iteration],
    result: &PerCellResult,
    scale: Real,
    options: &FitOptions,
) -> Result<(), InferenceError> {
    let io = |path: &Path, e: &dyn std::fmt::Display| InferenceError::Output(format!("{}: {e}", path.display()));
    let obs = &model.observation;
    let t = &best.tensions;
    let model_error = result.model_error;
    let contacts = Contacts::of(result.contact_model, result.contact_cutoff_m);
    let mn = |v: Option<Real>| v.map(|x| x * 1e3);
    let interfaces: Vec<InterfaceRow> = observed_map
        .interfaces
        .iter()
        .filter(|f| observed.contains_key(&(f.cell_a, f.cell_b)))
        .map(|f| {
            let k = (f.cell_a, f.cell_b);
            let tension = t.of(k);
            let o = observed.get(&k).copied();
            let s = best.simulated.get(&k).copied();
            let direct_relative_sd = f.tension_sd.zip(f.tension).map(|(sd, t)| sd / t);
            let mismatch = o.zip(s).map(|(o, s)| s / o - 1.0);
            let model_error = if f.cell_b == 0 { model_error.cell_medium } else { model_error.cell_cell };
            let spread = best.spread.get(&k).copied();
            let (relative_sd, sd_source) = match (spread, mismatch) {
                (Some(spread), Some(r)) => (Some(relative_uncertainty(r, spread, model_error)), "placements"),
                _ => (
                    direct_relative_sd.map(|d| (mismatch.unwrap_or(0.0).powi(2) + d * d + model_error.powi(2)).sqrt()),
                    "direct estimate",
                ),
            };
            let sd = tension.zip(relative_sd).map(|(t, r)| t * r);
            InterfaceRow {
                cell_a: f.cell_a,
                cell_b: f.cell_b,
                tension_mn_per_m: mn(tension),
                tension_sd_mn_per_m: mn(sd),
                tension_n_per_m: tension,
                tension_sd_n_per_m: sd,
                sd_source,
                placement_sd: spread.map(|s| s.relative_sd),
                placements: spread.map(|s| s.placements),
                model_error,
                direct_mn_per_m: mn(o.map(|o| o * scale)),
                direct_sd_mn_per_m: mn(o.zip(direct_relative_sd).map(|(o, r)| o * scale * r)),
                observed_relative: o,
                simulated_relative: s,
                mismatch,
                area_um2: f.area * 1e12,
            }
        })
        .collect();
    // Each cell's lateral tension and its sd, where the cell–cell interfaces determine it.
    let cell_cell: Vec<((u32, u32), Real)> = interfaces
        .iter()
        .filter(|r| r.cell_b != 0)
        .filter_map(|r| Some(((r.cell_a, r.cell_b), r.tension_sd_n_per_m?)))
        .collect();
    let lateral_sd = lateral_uncertainty(&obs.cell_labels, &cell_cell);
    let cells: Vec<CellRow> = obs
        .tissue
        .cells()
        .iter()
        .filter(|c| obs.cell_labels.contains(&c.id().0))
        .map(|c| {
            let id = c.id().0;
            let p = best.pressure.get(&id).copied();
            let free_sd =
                interfaces.iter().find(|r| r.cell_a == id && r.cell_b == 0).and_then(|r| r.tension_sd_n_per_m);
            // The least squares' sd takes the interfaces' errors as independent; the model error
            // adds what that misses (per_cell.model_error.lateral), relative to the tension.
            let lateral_sd = lateral_sd.get(&id).copied().map(|sd| {
                let a = t.lateral.get(&id).copied().unwrap_or(0.0).abs();
                sd.hypot(model_error.lateral * a)
            });
            let pressure_tension_sd = holding_tension_sd(id, &interfaces);
            // A Laplace pressure is proportional to the tension that holds the cell at its shape;
            // the model error adds the shape's own (curvature, volume).
            let pressure_sd = p.zip(pressure_tension_sd).map(|(p, s)| p.abs() * s.hypot(model_error.pressure));
            let free = t.free.get(&id).copied();
            let (adhesion, energy) = match contacts {
                Contacts::Adhesion { cutoff } => {
                    let lateral = lateral_sd.and(t.lateral.get(&id).copied());
                    (
                        free.zip(lateral).map(|(f, a)| adhesion_of(f, a, cutoff)),
                        free.zip(lateral).map(|(f, a)| (f - a).max(0.0)),
                    )
                }
                Contacts::Lateral => (None, None),
            };
            let energy_sd = energy.and(free_sd.zip(lateral_sd)).map(|(f, a)| f.hypot(a));
            CellRow {
                cell: id,
                free_tension_mn_per_m: mn(t.free.get(&id).copied()),
                lateral_tension_mn_per_m: mn(lateral_sd.and(t.lateral.get(&id).copied())),
                free_tension_sd_mn_per_m: mn(free_sd),
                lateral_tension_sd_mn_per_m: mn(lateral_sd),
                lateral_determined: lateral_sd.is_some(),
                start: if previous_frame.contains(&id) { "corrected by previous frame" } else { "direct estimate" },
                free_tension_n_per_m: t.free.get(&id).copied(),
                lateral_tension_n_per_m: lateral_sd.and(t.lateral.get(&id).copied()),
                direct_free_tension_mn_per_m: mn(start.free.get(&id).copied()),
                direct_lateral_tension_mn_per_m: mn(start.lateral.get(&id).copied()),
                direct_free_tension_n_per_m: start.free.get(&id).copied(),
                direct_lateral_tension_n_per_m: start.lateral.get(&id).copied(),
                pressure_pa: p,
                pressure_kpa: p.map(|p| p * 1e-3),
                pressure_sd_pa: pressure_sd,
                pressure_sd_kpa: pressure_sd.map(|p| p * 1e-3),
                pressure_tension_sd,
                pressure_model_error: model_error.pressure,
                lateral_model_error: model_error.lateral,
                adhesion_pa_per_m: adhesion,
                adhesion_energy_mj_per_m2: mn(energy),
                adhesion_energy_sd_mj_per_m2: mn(energy_sd),
                adhesion_energy_j_per_m2: energy,
                adhesion_over_tension: energy.zip(free).map(|(w, f)| w / f),
                volume_um3: c.mesh().signed_volume() * 1e18,
            }
        })
        .collect();
    // The observed tissue coloured by the refined map: each face its interface's tension (mN/m),
    // each cell its simulated pressure (Pa).
    let mut face_tension: Vec<Real> = Vec::with_capacity(obs.tissue.face_count());
    for (cell, faces) in obs.tissue.cells().iter().zip(&observed_map.face_interface) {
        if faces.len() == cell.mesh().face_count() {
            face_tension.extend(faces.iter().map(|k| {
                let Some(f) = k.map(|k| &observed_map.interfaces[k]) else { return Real::NAN };
                t.of((f.cell_a, f.cell_b)).map_or(Real::NAN, |x| x * 1e3)
            }));
        } else {
            face_tension.extend(std::iter::repeat_n(Real::NAN, cell.mesh().face_count()));
        }
    }
    let pressure_of = |tissue: &Tissue| -> Vec<Real> {
        tissue.cells().iter().map(|c| best.pressure.get(&c.id().0).copied().unwrap_or(Real::NAN)).collect()
    };
    let mut observed_tissue = obs.tissue.clone();
    params.apply_cell_overrides(&mut observed_tissue).map_err(|e| InferenceError::Output(e.to_string()))?;
    let mut relaxed = best.relaxed.clone();
    params.apply_cell_overrides(&mut relaxed).map_err(|e| InferenceError::Output(e.to_string()))?;
    let unit = options.output_unit;
    let mut group = OutputGroup::new();
    let path = out.join("cells.csv");
    crate::stages::write_csv(&mut group, &path, &cells, &CellRow::default()).map_err(|e| io(&path, &e))?;
    let path = out.join("interfaces.csv");
    crate::stages::write_csv(&mut group, &path, &interfaces, &InterfaceRow::default()).map_err(|e| io(&path, &e))?;
    let path = out.join("iterations.csv");
    group
        .write(&path, |w| {
            let mut csv = csv::Writer::from_writer(w);
            for row in trace {
                csv.serialize(row).map_err(std::io::Error::other)?;
            }
            csv.flush()
        })
        .map_err(|e| io(&path, &e))?;
    let path = out.join("tissue.vtp");
    let observed_pressure = pressure_of(&observed_tissue);
    let cell_adhesion: Vec<Real> = observed_tissue
        .cells()
        .iter()
        .map(|c| cells.iter().find(|r| r.cell == c.id().0).and_then(|r| r.adhesion_pa_per_m).unwrap_or(Real::NAN))
        .collect();
    let mut fields = vec![
        CellField { name: "tension_mn_per_m", values: &face_tension },
        CellField { name: "pressure", values: &observed_pressure },
    ];
    if contacts != Contacts::Lateral {
        fields.push(CellField { name: "adhesion_pa_per_m", values: &cell_adhesion });
    }
    let bytes = vtp_bytes_in(&path, &observed_tissue, &fields, None, unit).map_err(|e| io(&path, &e))?;
    group.write_bytes(&path, &bytes).map_err(|e| io(&path, &e))?;
    let path = out.join("relaxed.vtp");
    let relaxed_pressure = pressure_of(&relaxed);
    let fields = [CellField { name: "pressure", values: &relaxed_pressure }];
    let bytes = vtp_bytes_in(&path, &relaxed, &fields, None, unit).map_err(|e| io(&path, &e))?;
    group.write_bytes(&path, &bytes).map_err(|e| io(&path, &e))?;
    let path = out.join("cell_overrides.toml");
    #[derive(Serialize)]
    struct Entries<'a> {
        cell_overrides: &'a [CellOverrideConfig],
    }
    let what = match contacts {
        Contacts::Lateral => {
            "N/m; free tension on apical and basal faces, lateral tension\n# on lateral ones".to_string()
        }
        Contacts::Adhesion { cutoff } => format!(
            "one tension on every face, N/m, and the cell's spring adhesion, Pa/m,\n# at contact_cutoff = {cutoff:.4e} m"
        ),
    };
    let mut text = format!(
        "# Per-cell tensions of a per-cell fit ({what}; iteration {} of the refinement, mismatch {:.4} rms).\n\
         # Append to a model file to simulate the map (the docs book, Per-cell tensions and adhesions).\n\n",
        best.iteration, best.rms
    );
    text.push_str(&toml::to_string(&Entries { cell_overrides: &params.cell_overrides }).unwrap_or_default());
    group.write_bytes(&path, text.as_bytes()).map_err(|e| io(&path, &e))?;
    let path = out.join("model.toml");
    group.write_bytes(&path, params.to_toml_string().as_bytes()).map_err(|e| io(&path, &e))?;
    let path = out.join(super::super::stages::fit::RESULT_FILE);
    group
        .write(&path, |w| {
            serde_json::to_writer_pretty(&mut *w, result).map_err(std::io::Error::other)?;
            writeln!(w)
        })
        .map_err(|e| io(&path, &e))?;
    let path = out.join("map.png");
    let picture = crate::stages::map_png(&observed_tissue, face_tension, "interface tension, refined map (mN/m)")
        .map_err(|e| io(&path, &e))?;
    group.write_bytes(&path, &picture).map_err(|e| io(&path, &e))?;
    group.commit().map_err(|e| InferenceError::Output(format!("writing into {}: {e}", out.display())))?;
    let direct: Vec<Real> = interfaces.iter().filter_map(|r| r.direct_mn_per_m).collect();
    let refined: Vec<Real> = interfaces.iter().filter_map(|r| r.tension_mn_per_m).collect();
    super::plot::plot_tension_histogram(&out.join("tension_histogram.png"), &direct, &refined)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A spring map's overrides: one tension on every face and ω = 4(f − a)/c², so that the
    /// model's interface tension γ_i + γ_j − (ω_i + ω_j)c²/4 is a_i + a_j; a lateral tension above
    /// the free one is clamped to it (no adhesion) and the cell named.
    #[test]
    fn a_spring_map_turns_lateral_tensions_into_adhesions() {
        let c = 0.8e-6;
        let mut t = CellTensions {
            free: BTreeMap::from([(1, 1.0e-3), (2, 0.9e-3), (3, 1.0e-3)]),
            lateral: BTreeMap::from([(1, 0.4e-3), (2, 0.6e-3), (3, 1.2e-3)]),
        };
        let mut clamped = std::collections::BTreeSet::new();
        t.bound_by_adhesion(Contacts::Lateral, &mut clamped);
        assert!(clamped.is_empty() && t.lateral[&3] == 1.2e-3, "coupled maps keep any lateral tension");
        let contacts = Contacts::Adhesion { cutoff: c };
        t.bound_by_adhesion(contacts, &mut clamped);
        assert_eq!(clamped.into_iter().collect::<Vec<_>>(), vec![3]);
        assert_eq!(t.lateral[&3], 1.0e-3);
        let o = t.overrides(contacts);
        assert_eq!(o.len(), 3);
        let omega: Vec<Real> = o.iter().map(|e| e.adhesion.lateral.unwrap()).collect();
        for e in &o {
            let f = t.free[&e.id];
            assert_eq!(e.surface_tension, PerFaceType { apical: Some(f), lateral: Some(f), basal: Some(f) });
            assert_eq!(e.adhesion.apical, e.adhesion.lateral);
            assert_eq!(e.adhesion.basal, e.adhesion.lateral);
        }
        assert!((omega[0] - 4.0 * 0.6e-3 / (c * c)).abs() <= 1e-6 * omega[0]);
        assert_eq!(omega[2], 0.0);
        let tension = |i: usize, j: usize| t.free[&o[i].id] + t.free[&o[j].id] - (omega[i] + omega[j]) * c * c / 4.0;
        assert!((tension(0, 1) / t.of((1, 2)).unwrap() - 1.0).abs() < 1e-12);
        assert!((tension(0, 2) / t.of((1, 3)).unwrap() - 1.0).abs() < 1e-12);
        let coupled = t.overrides(Contacts::Lateral);
        assert_eq!(coupled[0].surface_tension.lateral, Some(0.4e-3));
        assert_eq!(coupled[0].adhesion, PerFaceType::default());
    }

    #[test]
    fn a_spread_needs_two_placements_and_is_relative_to_the_mean() {
        assert_eq!(Spread::of(&[]), None);
        assert_eq!(Spread::of(&[1.0]), None);
        // Mean 2, sample sd √2.
        let s = Spread::of(&[1.0, 3.0]).unwrap();
        assert_eq!(s.placements, 2);
        assert!((s.relative_sd - 2f64.sqrt() / 2.0).abs() < 1e-12, "{s:?}");
        assert_eq!(Spread::of(&[0.0, 0.0]), None, "no relative spread of a zero mean");
    }

    #[test]
    fn the_uncertainty_adds_mismatch_placements_and_model_error_in_quadrature() {
        let spread = Spread { relative_sd: 0.04, placements: 4 };
        // 0.03² + 0.04² · 1.25 + 0.05² = 0.0009 + 0.002 + 0.0025.
        let sd = relative_uncertainty(0.03, spread, 0.05);
        assert!((sd - 0.0054f64.sqrt()).abs() < 1e-12, "{sd}");
        // A sign of the mismatch does not matter; more placements narrow only the simulated part.
        assert_eq!(relative_uncertainty(-0.03, spread, 0.05), sd);
        let many = relative_uncertainty(0.0, Spread { relative_sd: 0.04, placements: 1000 }, 0.0);
        assert!((many - 0.04 * (1.001f64).sqrt()).abs() < 1e-12, "{many}");
    }

    #[test]
    fn lateral_tensions_are_uncertain_by_the_least_squares_and_left_out_where_undetermined() {
        // A triplet's three interfaces determine the three cells: a = A⁻¹T, A⁻¹ = ½[[1,1,−1],…],
        // so with equal sds σ each a_i has σ·√3/2.
        let triplet = lateral_uncertainty(&[1, 2, 3], &[((1, 2), 0.1), ((1, 3), 0.1), ((2, 3), 0.1)]);
        assert_eq!(triplet.len(), 3);
        for sd in triplet.values() {
            assert!((sd - 0.1 * 3f64.sqrt() / 2.0).abs() < 1e-12, "{triplet:?}");
        }
        // A doublet and a chain fix only sums: no cell is determined.
        assert!(lateral_uncertainty(&[1, 2], &[((1, 2), 0.1)]).is_empty());
        assert!(lateral_uncertainty(&[1, 2, 3], &[((1, 2), 0.1), ((2, 3), 0.1)]).is_empty());
        // A triangle with a tail: the tail's cell follows from its one interface and its neighbour;
        // a cell with no interface at all is not determined.
        let tail = lateral_uncertainty(&[1, 2, 3, 4, 5], &[((1, 2), 0.1), ((1, 3), 0.1), ((2, 3), 0.1), ((3, 4), 0.2)]);
        assert_eq!(tail.keys().copied().collect::<Vec<_>>(), vec![1, 2, 3, 4]);
        // a_4 = T_34 − a_3: variance 0.2² + 3·0.1²/4.
        assert!((tail[&4] - (0.04f64 + 0.0075).sqrt()).abs() < 1e-12, "{tail:?}");
    }
}

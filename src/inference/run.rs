//! The fit driver: observed data → optimiser → profile → `trace.csv`, `result.json`, plots.

use super::best::{BestRelaxation, write_best_outputs};
use super::config::FitConfig;
use super::forward::{Evaluation, ForwardModel, Observation, RoughnessCalibration, Status};
use super::optimise::{Evaluator, optimise};
use super::profile::{NoiseFloor, Slice, profile, ratio_direction, ratio_parts};
use super::result::{AT_BOUND_FRACTION, FitResult, POOR_FIT_OBJECTIVE, ParameterResult, RatioResult};
use super::space::{FitParameter, ParameterSpace};
use super::trace::{read_trace, write_trace};
use super::{InferenceError, plot};
use crate::geometry::Real;
use crate::imaging::{LabelVolume, read_labels};
use crate::io::{
    Heartbeat, LengthScale, OutputUnit, Progress, ReadOptions, Watch, read_tissue, write_bytes_atomically,
};
use crate::mechanics::{ContactModel, Polarity};
use crate::mesh::{CellKind, FaceType};
use crate::meshing::{LabelMeshingOptions, mesh_labels, retriangulate};
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Mutex;
use std::time::Instant;

/// How to run a fit.
#[derive(Clone, Debug, Default)]
pub struct FitOptions {
    /// Continue from `DIR/trace.csv`: its evaluations are reused (not re-simulated) when the
    /// optimiser asks for them again, which it does in the same order, so the result is the same.
    /// Without a trace there is nothing to resume: an error.
    pub resume: bool,
    /// Show progress on stderr: a bar on a terminal, otherwise one line per evaluation
    /// ([`crate::io::Progress`]).
    pub progress: bool,
    /// Write the PNG plots. Default false here; the CLI turns them on.
    pub plots: bool,
    /// A caller's listener and stop request (the Python API): hears each evaluation; stopping it
    /// ends the fit with [`InferenceError::Stopped`] after the trace is written.
    pub watch: Watch,
    /// Length unit of `best.vtp` (metres by default; µm records its unit and reads back in metres).
    /// The files the fit reads back (trace, result, models) are SI whatever it is.
    pub output_unit: OutputUnit,
}

/// Reads the observed input (meshing a label volume first) and measures it.
pub fn load_observation(config: &FitConfig) -> Result<Observation, InferenceError> {
    let obs = config.observed()?;
    if let Some(path) = &obs.tissue {
        let scale: LengthScale = obs
            .length_unit
            .parse()
            .map_err(|e: String| InferenceError::Config(format!("observed.length_unit: {e}")))?;
        // A tissue to re-triangulate is read as `tissuefit mesh X.vtp` reads it (cells oriented outwards).
        let read = read_tissue(path, &ReadOptions { length_scale: scale, orient: obs.retriangulate })
            .map_err(|e| InferenceError::Observed(format!("reading {}: {e}", path.display())))?;
        for w in &read.warnings {
            tracing::warn!("{}: {w}", path.display());
        }
        if !obs.retriangulate {
            return Observation::new(read.tissue, None, None);
        }
        let r = retriangulate(&read.tissue, &obs.meshing, obs.voxel_size)
            .map_err(|e| InferenceError::Observed(format!("re-triangulating {}: {e}", path.display())))?;
        return Observation::new(r.meshing.tissue, None, None);
    }
    let path = obs.labels.as_ref().ok_or_else(|| InferenceError::Config("observed: no input".into()))?;
    let read = read_labels(path, &obs.read_options())
        .map_err(|e| InferenceError::Observed(format!("reading {}: {e}", path.display())))?;
    for w in &read.warnings {
        tracing::warn!("{}: {w}", path.display());
    }
    observe_labels(read.volume, &obs.meshing, &path.display().to_string())
}

/// The observation of a label volume: meshed with `meshing`, the simulations later measured like
/// it (the same options with the l_min the meshing used). `name` names the volume in messages.
pub fn observe_labels(
    volume: LabelVolume,
    meshing: &LabelMeshingOptions,
    name: &str,
) -> Result<Observation, InferenceError> {
    let mut options = meshing.clone();
    let meshed =
        mesh_labels(&volume, &options).map_err(|e| InferenceError::Observed(format!("meshing {name}: {e}")))?;
    for r in meshed.report.iter().filter(|r| r.reason.is_some()) {
        tracing::info!("{name}: label {}: {:?}: {}", r.label, r.status, r.reason.as_deref().unwrap_or(""));
    }
    if meshed.tissue.is_empty() {
        return Err(InferenceError::Observed(format!("{name}: no label could be meshed")));
    }
    options.l_min = meshed.l_min;
    Observation::new(meshed.tissue, Some(volume), Some(options))
}

/// The best evaluation of a trace slice (lowest objective, earliest on ties).
fn best_of(trace: &[Evaluation]) -> Option<&Evaluation> {
    trace.iter().fold(None, |best: Option<&Evaluation>, e| match best {
        Some(b) if b.objective <= e.objective => Some(b),
        _ => Some(e),
    })
}

/// Runs a whole fit and writes its outputs into `out` (created if needed).
pub fn run_fit(config: &FitConfig, out: &Path, options: &FitOptions) -> Result<FitResult, InferenceError> {
    run_fit_observed(config, None, out, options)
}

/// [`run_fit`] with the observation already loaded (e.g. a pipeline's mesh stage output, so the
/// labels are not meshed again); `None` loads it from `config.observed` ([`load_observation`]).
pub fn run_fit_observed(
    config: &FitConfig,
    observation: Option<Observation>,
    out: &Path,
    options: &FitOptions,
) -> Result<FitResult, InferenceError> {
    let started = Instant::now();
    let output_err = |p: &Path, e: &dyn std::fmt::Display| InferenceError::Output(format!("{}: {e}", p.display()));
    let trace_path = out.join("trace.csv");
    let resuming = if trace_path.exists() {
        if !options.resume {
            return Err(InferenceError::Output(format!(
                "{} already holds a fit (trace.csv); pass --resume to continue it or choose another --out",
                out.display()
            )));
        }
        true
    } else if options.resume {
        // Starting afresh instead would hide a mistyped --out, or a fit that never began.
        return Err(InferenceError::Resume(format!(
            "{}: nothing to resume, there is no trace.csv (a fit writes it from its first evaluation on); check \
             --out, or run without --resume to start the fit",
            out.display()
        )));
    } else {
        false
    };
    let base = config.base_parameters()?;
    let observation = match observation {
        Some(o) => o,
        None => load_observation(config)?,
    };
    let space = ParameterSpace::from_config(&super::forward::resolved_parameters(config, &base, &observation)?)?;
    let preloaded = if resuming { read_trace(&trace_path, &space)? } else { Vec::new() };
    let mut model = ForwardModel::new(observation, base, space, config.objective.clone(), config.forward.clone())?;
    // A log (stderr not a terminal) also hears from inside an evaluation of many minutes.
    model.heartbeat = Some(Heartbeat::new("fit", options.progress));
    model.watch = options.watch.clone();
    check_fitted_parameters_act(&model)?;
    let roughness = calibrate_roughness(&mut model)?;
    std::fs::create_dir_all(out).map_err(|e| output_err(out, &e))?;
    let resolved = toml::to_string(config).map_err(|e| InferenceError::Output(e.to_string()))?;
    write_bytes_atomically(&out.join("fit.toml"), resolved.as_bytes()).map_err(|e| output_err(out, &e))?;
    let model_toml = model.base.to_toml_string();
    write_bytes_atomically(&out.join("model.toml"), model_toml.as_bytes()).map_err(|e| output_err(out, &e))?;

    let budget = config.optimizer.max_evaluations;
    // One line per evaluation when stderr is not a terminal (the rows of a resumed trace included).
    let progress = Mutex::new((
        Progress::new(
            "fit",
            budget as u64,
            "evaluation",
            "{elapsed_precise} [{wide_bar}] {pos}/{len} evaluations, {msg}",
            options.progress,
        )
        .with_watch(options.watch.clone()),
        0usize,
    ));
    let write_error: Mutex<Option<InferenceError>> = Mutex::new(None);
    let space_ref = &model.space;
    let on_record = |trace: &[Evaluation]| {
        if let Err(e) = write_trace(&trace_path, space_ref, trace) {
            tracing::warn!("{e}");
            *write_error.lock().expect("lock") = Some(e);
        }
        let mut guard = progress.lock().expect("lock");
        let (bar, shown) = &mut *guard;
        for (i, e) in trace.iter().enumerate().skip(*shown) {
            let best = best_of(&trace[..=i]).map_or(Real::NAN, |b| b.objective);
            let what = if e.status.usable() {
                format!("objective {:.4e}", e.objective)
            } else {
                format!("{} ({})", e.status.name(), e.reason)
            };
            let profile = if i >= budget { " (profile)" } else { "" };
            bar.line(
                (i + 1) as u64,
                &format!("{what}{profile}, {} steps, {:.1} s; best objective {best:.4e}", e.steps, e.wall_seconds),
            );
        }
        *shown = trace.len();
    };
    let evaluator = Evaluator::new(&model, budget, preloaded, Box::new(on_record), started);
    // A stopped fit's trace holds every finished evaluation already (each batch is written as it ends).
    let outcome = optimise(&evaluator, &config.optimizer).inspect_err(|_| progress.lock().expect("lock").0.finish())?;
    let trace = evaluator.trace();
    let evaluations = trace.len();
    let best = best_of(&trace).cloned().ok_or_else(|| InferenceError::Optimiser("no evaluation was made".into()))?;
    if !best.status.usable() {
        // Every evaluation was penalised: the "optimum" is a penalty, not a fit (the simplex of equal
        // penalties even looks converged). The trace stays, with every evaluation's reason.
        progress.lock().expect("lock").0.finish();
        write_trace(&trace_path, &model.space, &trace)?;
        return Err(InferenceError::Failed(describe_failures(&trace, config)));
    }
    progress.lock().expect("lock").0.set_message(format!("best objective {:.4e}; profiling", best.objective));
    let (slices, noise) = if best.status.usable() {
        let (slices, noise) = profile(&evaluator, &best.x, best.objective, &config.profile)
            .inspect_err(|_| progress.lock().expect("lock").0.finish())?;
        (slices, Some(noise))
    } else {
        (Vec::new(), None)
    };
    progress.lock().expect("lock").0.finish();
    let full_trace = evaluator.trace();
    write_trace(&trace_path, &model.space, &full_trace)?;
    if let Some(e) = write_error.lock().expect("lock").take() {
        return Err(e);
    }
    // The best point relaxed once more for its tissue (best.vtp), with its model and residuals.
    let best_relaxation = write_best_outputs(&model, &best, out, options.output_unit)?;
    if model.watch.stopped() {
        return Err(InferenceError::Stopped);
    }
    let mut result = assemble(
        &model,
        config,
        &best,
        evaluations,
        full_trace.len() - evaluations,
        &slices,
        noise.as_ref(),
        &outcome,
        &evaluator,
        started,
        best_relaxation,
    );
    result.roughen = roughness;
    let json = serde_json::to_string_pretty(&result).map_err(|e| InferenceError::Output(e.to_string()))?;
    write_bytes_atomically(&out.join("result.json"), json.as_bytes()).map_err(|e| output_err(out, &e))?;
    if options.plots {
        plot::plot_objective(&out.join("objective.png"), &full_trace[..evaluations])?;
        plot::plot_landscape(&out.join("landscape.png"), &model.space, &full_trace)?;
        if let Some(noise) = &noise {
            plot::plot_profiles(&out.join("profile.png"), &slices, noise)?;
        }
    }
    Ok(result)
}

/// `forward.roughen_voxels` resolved before the first evaluation (see
/// [`ForwardModel::calibrate_roughness`]), logged; `None` when nothing is roughened.
pub(crate) fn calibrate_roughness(model: &mut ForwardModel) -> Result<Option<RoughnessCalibration>, InferenceError> {
    let start = model.space.initial_point();
    let calibration = model
        .calibrate_roughness(&start)
        .map_err(|e| InferenceError::Config(format!("forward.roughen_voxels: {e}")))?;
    if let Some(c) = &calibration {
        let how = if c.estimated { "estimated" } else { "given" };
        tracing::info!(
            "fit: simulated masks roughened by {:.2} voxels RMS of boundary noise {:.1} voxels wide ({how}); boundary \
             roughness: observed {:.4}, start point {:.4} clean, {:.4} roughened",
            c.voxels,
            c.correlation,
            c.observed,
            c.simulated_clean,
            c.simulated
        );
        if let Some(w) = &c.warning {
            tracing::warn!("fit: forward.roughen_voxels = \"auto\": {w}");
        }
    }
    Ok(calibration)
}

/// Why every evaluation of a fit was penalised, summarised (each kind of reason once, with its count
/// and an example) with what to change.
fn describe_failures(trace: &[Evaluation], config: &FitConfig) -> String {
    // Reasons that differ only in their numbers (steps, residuals, values) are one kind.
    let kind = |r: &str| r.chars().map(|c| if c.is_ascii_digit() { '#' } else { c }).collect::<String>();
    let mut kinds: Vec<(String, usize, &Evaluation)> = Vec::new();
    for e in trace {
        let k = format!("{}: {}", e.status.name(), kind(&e.reason));
        match kinds.iter_mut().find(|(key, _, _)| *key == k) {
            Some(entry) => entry.1 += 1,
            None => kinds.push((k, 1, e)),
        }
    }
    kinds.sort_by_key(|k| std::cmp::Reverse(k.1));
    let shown: Vec<String> = kinds
        .iter()
        .take(3)
        .map(|(_, n, e)| {
            format!(
                "{n} × {} ({})",
                e.status.name(),
                if e.reason.is_empty() { "no reason recorded" } else { &e.reason }
            )
        })
        .collect();
    let more = if kinds.len() > 3 { format!("; and {} other kind(s)", kinds.len() - 3) } else { String::new() };
    let mut remedies = Vec::new();
    if trace.iter().any(|e| e.status == Status::Unconverged) {
        remedies.push(format!(
            "unconverged runs: raise forward.max_steps{} or forward.accept_residual (now {:e}), or check the model's \
             time step and l_min against the mesh",
            config.forward.max_steps.map_or(String::new(), |n| format!(" (now {n})")),
            config.forward.accept_residual
        ));
    }
    if trace.iter().any(|e| e.status == Status::Failed && e.reason.starts_with("invalid parameters")) {
        remedies.push(
            "invalid parameters: the model rejects the points the bounds allow; check the bounds' units (tensions \
             in N/m, e.g. 0.5e-3 for 0.5 mN/m; adhesion in Pa/m) and the model's time step"
                .to_string(),
        );
    }
    if trace.iter().any(|e| e.status == Status::Failed && !e.reason.starts_with("invalid parameters")) {
        remedies.push(
            "failed runs: simulate the observed tissue with the model at the start values (`tissuefit simulate`) \
             to see why, and check the tensions are in N/m"
                .to_string(),
        );
    }
    format!(
        "none of the {} evaluations was usable, every one scored the failure penalty {:e}, so there is no fitted \
         value: {}{more}. What to change: {}",
        trace.len(),
        config.objective.failure_penalty,
        shown.join("; "),
        remedies.join("; ")
    )
}

/// Refuses a fit before it starts when a fitted parameter cannot change the forward model: the
/// fit's parameters are written into the model's epithelial cell types only, a per-face-type tension
/// acts only on faces of that type (which, with `numerics.polarity = "none"`, are the types read
/// from the input: a meshed label volume has apical faces only), and adhesion needs a second cell.
fn check_fitted_parameters_act(model: &ForwardModel) -> Result<(), InferenceError> {
    let base = &model.base;
    let tissue = &model.observation.tissue;
    let moving: Vec<&crate::mesh::Cell> = tissue
        .cells()
        .iter()
        .filter(|c| c.kind().is_cell() && !c.kind().is_immobile())
        .filter(|c| base.cell_type(c.cell_type()).is_some_and(|t| t.kind == CellKind::Epithelial))
        .collect();
    let fitted: Vec<&str> = model.space.fitted.iter().map(|p| p.name()).collect();
    if moving.is_empty() {
        return Err(InferenceError::Config(format!(
            "parameters: {} cannot change the model: a fit writes them into the model's epithelial cell types \
             (cell_types with kind = \"epithelial\"), and no moving cell of the observed tissue has one; give the \
             observed cells an epithelial cell type",
            fitted.join(", ")
        )));
    }
    let several_cells = tissue.cells().iter().filter(|c| c.kind().is_cell()).count() > 1;
    // Which face types can exist on the moving epithelial cells during a relaxation, and why not.
    let possible = |ft: FaceType| -> Result<(), String> {
        match base.numerics.polarity {
            Polarity::None => {
                if moving.iter().any(|c| c.face_types().contains(&ft)) {
                    Ok(())
                } else {
                    Err(format!(
                        "numerics.polarity = \"none\" keeps the face types as read, and no moving epithelial cell of \
                         the observed tissue has a {} face (a meshed label volume has apical faces only); set \
                         numerics.polarity = \"contacts\" in the model (or model_overrides) so that faces between \
                         cells become lateral, or fit `surface_tension`",
                        ft.name()
                    ))
                }
            }
            Polarity::Contacts
                if ft == FaceType::Apical && !tissue.cells().iter().any(|c| c.kind() == CellKind::Lumen) =>
            {
                Err("numerics.polarity = \"contacts\" types a face apical only where it touches a lumen, and the \
                     observed tissue has no lumen; fit `surface_tension_basal` (the free surface) or `surface_tension`"
                    .to_string())
            }
            _ if ft == FaceType::Lateral && !several_cells => {
                Err("lateral faces are faces between cells, and the observed tissue has one cell".to_string())
            }
            _ => Ok(()),
        }
    };
    for p in &model.space.fitted {
        let why = match p.parameter {
            FitParameter::SurfaceTension => {
                // It sets the face types that no per-type parameter overrides.
                let open: Vec<FaceType> = FitParameter::ALL
                    .into_iter()
                    .filter(|&q| !model.space.names(q))
                    .filter_map(FitParameter::face_type)
                    .collect();
                if open.is_empty() {
                    Some(
                        "surface_tension_apical, _lateral and _basal are all given, and they override it on every face"
                            .to_string(),
                    )
                } else if open.iter().all(|ft| possible(*ft).is_err()) {
                    let reasons: Vec<String> = open.iter().filter_map(|ft| possible(*ft).err()).collect();
                    Some(format!("the face types it still sets cannot occur: {}", reasons.join("; ")))
                } else {
                    None
                }
            }
            FitParameter::Adhesion if tissue.cells().len() < 2 => {
                Some("adhesion acts between cells, and the observed tissue has one cell".to_string())
            }
            q => q.face_type().and_then(|ft| possible(ft).err()),
        };
        if let Some(why) = why {
            return Err(InferenceError::Config(format!(
                "parameters.{}: fitting it cannot change the model, so the data cannot determine it: {why}",
                p.name()
            )));
        }
    }
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn assemble(
    model: &ForwardModel,
    config: &FitConfig,
    best: &Evaluation,
    evaluations: usize,
    profile_evaluations: usize,
    slices: &[Slice],
    noise: Option<&NoiseFloor>,
    outcome: &super::optimise::OptimiserOutcome,
    evaluator: &Evaluator<'_>,
    started: Instant,
    best_relaxation: BestRelaxation,
) -> FitResult {
    let space = &model.space;
    let values = space.values(&best.x);
    let l = model.observation.length_scale;
    let k = model
        .base
        .cell_types
        .iter()
        .find(|t| t.kind == CellKind::Epithelial)
        .map_or(model.base.cell_types[0].bulk_modulus, |t| t.bulk_modulus);
    // (`values` holds the space's own names, so every name is a parameter's.)
    let dimensionless =
        |name: &str, v: Real| FitParameter::from_name(name).map_or(Real::NAN, |p| p.dimensionless(v, l, k));
    let slice = |name: &str| slices.iter().find(|s| s.name == name);
    let scale_open = space.dim() > 1 && slice("scale").is_some_and(|s| !s.determined());
    let mut parameters = BTreeMap::new();
    let mut statements = Vec::new();
    let increase = match noise {
        Some(n) if n.std > 0.0 => format!(
            "{} (+{} above the mean {:.4} of the optimum's replicates, + {}σ of forward-model noise, σ = {:.3})",
            fmt_threshold(n.threshold),
            config.profile.acceptable_increase,
            n.reference,
            config.profile.noise_sigmas,
            n.std
        ),
        _ => format!("best + {}", config.profile.acceptable_increase),
    };
    // An absolute value is pinned only relative to what was held fixed (a shape fixes ratios).
    let given = if space.fixed.is_empty() {
        String::new()
    } else {
        let fixed: Vec<&str> = space.fixed.iter().map(|(n, _)| n.name()).collect();
        format!(" given the fixed {}", fixed.join(", "))
    };
    let all_names: Vec<String> = values.keys().cloned().collect();
    // The other directions the profile probed (scale, key ratios) and how far each moves every
    // fitted parameter's log per unit offset: a parameter's range must hold every acceptable point
    // they found, or the parameter and ratio ranges contradict each other.
    let mut directions: Vec<(&Slice, Vec<Real>)> = Vec::new();
    if let Some(s) = slice("scale") {
        directions.push((s, vec![1.0; space.dim()]));
    }
    for (rname, num, den) in ratio_parts(&all_names) {
        let fitted: Vec<&str> = space.fitted.iter().map(|p| p.name()).collect();
        let Some(d) = ratio_direction(&fitted, num, den) else { continue };
        if let Some(s) = slice(rname) {
            directions.push((s, d));
        }
    }
    for (name, &v) in &values {
        let fitted = space.fitted.iter().position(|p| p.name() == name);
        let mut at_bound = None;
        let mut widened_by = Vec::new();
        let (range, determined, bounds) = match fitted.map(|k| (k, &space.fitted[k])) {
            None => ([v, v], None, None),
            Some((k, p)) => {
                at_bound = bound_hit(v, p.bounds);
                match slice(name) {
                    None => (p.bounds, None, Some(p.bounds)),
                    Some(s) => {
                        // Own slice first, then every other acceptable point of the profile.
                        let mut lo = s.lower.map(|o| v * o.exp());
                        let mut hi = s.upper.map(|o| v * o.exp());
                        for (other, d) in &directions {
                            if d[k] == 0.0 || other.name == s.name {
                                continue;
                            }
                            for (side, sign) in [(other.lower, -1.0), (other.upper, 1.0)] {
                                let (moved, down) = match side {
                                    Some(o) => (Some(v * (d[k] * o).exp()), d[k] * o < 0.0),
                                    None => (None, d[k] * sign < 0.0),
                                };
                                let slot = if down { &mut lo } else { &mut hi };
                                let before = *slot;
                                *slot = match (before, moved) {
                                    (Some(b), Some(m)) if down => Some(b.min(m)),
                                    (Some(b), Some(m)) => Some(b.max(m)),
                                    _ => None,
                                };
                                if *slot != before && !widened_by.contains(&other.name) {
                                    widened_by.push(other.name.clone());
                                }
                            }
                        }
                        // A side that closes only at or beyond a search bound is not closed: the
                        // data do not exclude the bound.
                        let inside = lo.is_some_and(|l| l > p.bounds[0]) && hi.is_some_and(|h| h < p.bounds[1]);
                        let determined = inside && !scale_open && at_bound.is_none();
                        let range = if scale_open {
                            p.bounds
                        } else {
                            [
                                lo.map_or(p.bounds[0], |l| l.max(p.bounds[0])),
                                hi.map_or(p.bounds[1], |h| h.min(p.bounds[1])),
                            ]
                        };
                        (range, Some(determined), Some(p.bounds))
                    }
                }
            }
        };
        let other_directions = if widened_by.is_empty() {
            String::new()
        } else {
            format!(" (including the acceptable points along {})", widened_by.join(", "))
        };
        if let (Some(side), Some(b)) = (at_bound, bounds) {
            statements.push(format!(
                "{name}: NOT determined: the best value {v:.4e} lies at the {side} search bound {:.4e}, so the data \
                 may prefer a value beyond it; widen parameters.{name}.bounds and fit again",
                if side == "lower" { b[0] } else { b[1] }
            ));
        } else if let Some(d) = determined {
            statements.push(if d {
                format!(
                    "{name}: determined by the data{given}: {v:.4e} SI, acceptable range [{:.4e}, {:.4e}]{other_directions}",
                    range[0], range[1]
                )
            } else if scale_open {
                format!(
                    "{name}: NOT determined by the data: scaling every fitted parameter together keeps the objective \
                     below the acceptance threshold {increase}, so only ratios are fixed (best {v:.4e}, search bounds [{:.4e}, {:.4e}])",
                    range[0], range[1]
                )
            } else {
                format!(
                    "{name}: NOT determined by the data: the objective stays below the acceptance threshold {increase} on at \
                     least one side of {v:.4e}{other_directions}; range reported [{:.4e}, {:.4e}]",
                    range[0], range[1]
                )
            });
        }
        parameters.insert(
            name.clone(),
            ParameterResult {
                si: v,
                dimensionless: dimensionless(name, v),
                range,
                fitted: fitted.is_some(),
                determined,
                bounds,
                at_bound: at_bound.map(str::to_string),
            },
        );
    }
    let names: Vec<String> = values.keys().cloned().collect();
    let mut ratios = BTreeMap::new();
    for (rname, num, den) in ratio_parts(&names) {
        let value = values[num] / values[den];
        let extreme = |lo: bool| {
            let b = |n: &str, lo: bool| {
                space
                    .fitted
                    .iter()
                    .find(|p| p.name() == n)
                    .map_or(values[n], |p| if lo { p.bounds[0] } else { p.bounds[1] })
            };
            b(num, lo) / b(den, !lo)
        };
        let s = slice(rname);
        // A ratio at the most extreme value the parameters' bounds allow hit those bounds.
        let extremes = [extreme(true), extreme(false)];
        let at_bound = if extremes[0] < extremes[1] { bound_hit(value, extremes) } else { None };
        let (range, determined) = match s {
            Some(s) => (
                // Within what the bounds allow (a probe beyond a bound was evaluated at the bound).
                [
                    s.lower.map_or(extremes[0], |o| (value * o.exp()).max(extremes[0])),
                    s.upper.map_or(extremes[1], |o| (value * o.exp()).min(extremes[1])),
                ],
                // A side that closes only at or beyond what the bounds allow is not closed.
                Some(
                    s.determined()
                        && at_bound.is_none()
                        && s.lower.is_some_and(|o| value * o.exp() > extremes[0])
                        && s.upper.is_some_and(|o| value * o.exp() < extremes[1]),
                ),
            ),
            None => (extremes, None),
        };
        let meaning = match rname {
            "lateral_over_apical" => {
                "γ_lateral/γ_apical: sets the contact angle for coupling contacts (Young–Dupré cos θ = γ_l/γ_a)"
                    .to_string()
            }
            _ => format!(
                "ω/γ (1/m): for spring contacts the shape is set by w/(2γ) = ω·c²/(4γ) = {:.4} (c = {:.3e} m)",
                value * model.base.numerics.contact_cutoff.powi(2) / 4.0,
                model.base.numerics.contact_cutoff
            ),
        };
        if let Some(side) = at_bound {
            statements.push(format!(
                "{rname} = {value:.4e}: NOT determined: it lies at the {side} end [{:.4e}, {:.4e}] of what the search \
                 bounds of {num} and {den} allow; widen those bounds and fit again",
                extremes[0], extremes[1]
            ));
        } else if let Some(d) = determined {
            statements.push(format!(
                "{rname} = {value:.4e}: {} (acceptable range [{:.4e}, {:.4e}])",
                if d { "determined by the data" } else { "NOT determined by the data" },
                range[0],
                range[1]
            ));
        }
        if rname == "adhesion_over_tension" && model.base.numerics.contact_model == ContactModel::Spring {
            // The spring model's shape is set by w/(2γ) = ω·c²/(4γ): the dimensionless form.
            let f = model.base.numerics.contact_cutoff.powi(2) / 4.0;
            ratios.insert(
                "adhesion_energy_over_tension".to_string(),
                RatioResult {
                    value: value * f,
                    range: [range[0] * f, range[1] * f],
                    determined,
                    at_bound: at_bound.map(str::to_string),
                    meaning: format!(
                        "w/(2γ) = ω·c²/(4γ), c = {:.3e} m: the spring doublet's Young–Dupré group (cos θ = 1 − w/(2γ))",
                        model.base.numerics.contact_cutoff
                    ),
                },
            );
        }
        ratios.insert(
            rname.to_string(),
            RatioResult { value, range, determined, at_bound: at_bound.map(str::to_string), meaning },
        );
    }
    statements.push(
        "An equilibrium shape fixes only dimensionless combinations; the absolute scale enters through volume \
         compression against K (γ̃ = γ/(K·l)), weakly, and through the spring model's cutoff c"
            .to_string(),
    );
    if config.profile.model_error > 0.0 && !slices.is_empty() {
        statements.push(format!(
            "every closed range includes a model error of ±{:.3} % (profile.model_error, added in quadrature to the \
             objective's range): the forward model's systematic error on outside truths (Surface Evolver clusters), \
             which the objective alone cannot see; the ranges from the objective alone are the profile's \
             noise_lower/noise_upper",
            100.0 * config.profile.model_error
        ));
    }
    if let Some(n) = noise {
        statements.push(if n.std.is_finite() {
            format!(
                "forward-model noise at the optimum: objectives {:?} at the best point and at its replicates × (1 + k·1e-9), \
                 σ = {:.3}; acceptable = objective ≤ {}",
                n.objectives.iter().map(|j| (j * 1e4).round() / 1e4).collect::<Vec<_>>(),
                n.std,
                fmt_threshold(n.threshold)
            ) + &if n.mask > 0.0 {
                format!(
                    ", which allows {:.3} (= {}² × {:.3}) for the observed mask's own boundary noise: one draw of \
                     forward.roughen_voxels' noise moves the objective at the truth by that much on average, so the \
                     data cannot place the answer closer",
                    config.profile.noise_sigmas.powi(2) * n.mask,
                    config.profile.noise_sigmas,
                    n.mask
                )
            } else {
                String::new()
            }
        } else {
            format!(
                "forward-model noise at the optimum unknown: a replicate × (1 + 1e-9) of the best point failed ({}); \
                 nothing is reported determined",
                n.reason
            )
        });
    }
    if let Some(failure) = best_relaxation.failure() {
        statements.push(format!("BEST-POINT RELAXATION FAILED: {failure}"));
    }
    if !best.status.usable() {
        statements.push(format!("no usable evaluation: the best run was {} ({})", best.status.name(), best.reason));
    }
    // The forward model's own scatter at the optimum explains objectives up to a few σ; a best
    // objective far beyond both that and POOR_FIT_OBJECTIVE means the model misses the data.
    let sigma = noise.map_or(0.0, |n| if n.std.is_finite() { n.std } else { 0.0 });
    let mask = noise.map_or(0.0, |n| n.mask);
    let poor_floor =
        POOR_FIT_OBJECTIVE + config.profile.noise_sigmas * sigma + config.profile.noise_sigmas.powi(2) * mask;
    let poor_fit = best.objective > poor_floor;
    if poor_fit {
        statements.push(format!(
            "POOR FIT: the best objective {:.4e} lies far above what the forward model's noise explains ({:.4e} = \
             {POOR_FIT_OBJECTIVE} + {}·σ, σ = {sigma:.3}): the simulated metrics miss the observed ones by about {:.1} \
             scales each (observed {:?}, best {:?}); the model or its settings (contact model, polarity, l_min, \
             static cells) do not describe these data, so do not trust the fitted values",
            best.objective,
            poor_floor,
            config.profile.noise_sigmas,
            best.objective.sqrt(),
            model.observation.metrics,
            best.metrics
        ));
    }
    let session = started.elapsed().as_secs_f64();
    FitResult {
        parameters,
        objective: best.objective,
        evaluations,
        converged: outcome.converged,
        wall_seconds: evaluator.earlier_seconds() + session,
        session_wall_seconds: session,
        ratios,
        identifiability: statements,
        optimizer: config.optimizer.method,
        stop_reason: outcome.reason.clone(),
        profile_evaluations,
        simulated_here: evaluator.simulated(),
        observed: model.observation.metrics,
        best_metrics: best.metrics,
        length_scale: l,
        bulk_modulus: k,
        contact_model: model.base.numerics.contact_model,
        contact_cutoff: model.base.numerics.contact_cutoff,
        threads: rayon::current_num_threads(),
        profile: slices.to_vec(),
        noise: noise.cloned(),
        poor_fit,
        best_relaxation,
        roughen: None,
    }
}

/// `Some("lower" | "upper")` when `v` lies within [`AT_BOUND_FRACTION`] of the log-range of
/// `bounds` from that bound.
fn bound_hit(v: Real, bounds: [Real; 2]) -> Option<&'static str> {
    let (lo, hi, x) = (bounds[0].ln(), bounds[1].ln(), v.ln());
    let tolerance = AT_BOUND_FRACTION * (hi - lo);
    if x - lo <= tolerance {
        Some("lower")
    } else if hi - x <= tolerance {
        Some("upper")
    } else {
        None
    }
}

fn fmt_threshold(t: Real) -> String {
    format!("{t:.4}")
}

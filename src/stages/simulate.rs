//! The simulate stage: a tissue mesh relaxed to equilibrium (or run over a time span) with a model,
//! into a ParaView series (`frames.pvd` + `frames/`), `stats.csv`, `events.csv`, the final tissue
//! (`final.vtp`, and `final.vtk` in SimuCell3D's legacy format, both with each cell's pressure), the
//! run summary `summary.json` (DESIGN.md §2), the resolved model `config.toml`, and the final tissue
//! measured as the measure stage measures (`cells.csv`, `contacts.csv`, `morphology.json`), and the
//! model's own parameters, pressures and interface tensions at the final state (`model_cells.csv`,
//! `model_interfaces.csv`, [`super::model_tables`]).
//! Checkpoints (`checkpoint.bin`) are saved while it runs and a run continues from one with
//! [`resume`]. `tissuefit simulate` and the pipeline's `[simulate]` both run [`run`].

use super::{StageError, write_json};
use crate::geometry::Real;
use crate::io::{
    CHECKPOINT_FILE, CellField, OutputGroup, OutputState, OutputUnit, Progress, ReadOptions, RunInfo, RunSettings,
    SimulationRecorder, Watch, checksum, read_checkpoint, read_tissue, write_bytes_atomically, write_checkpoint,
    write_events, write_simucell3d, write_tissue_in,
};
use crate::mechanics::{
    CellInside, CheckpointRequest, EnergyTerms, ExplicitNumerics, MeshFit, Observer, Parameters, RelaxMethod, Sample,
    Simulation, SimulationError, SimulationMode, SimulationState, SimulationSummary, TopologyStats,
};
use crate::mesh::{CellKind, Tissue};
use crate::morphology::{MeasureSettings, Morphology, compare_tissues, measure_tissue};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// The run summary.
pub const SUMMARY_FILE: &str = "summary.json";
/// The final tissue's morphology summary (the keys of the measure stage's `summary.json`).
pub const MORPHOLOGY_FILE: &str = "morphology.json";
/// The folder of the frames `frames.pvd` lists.
pub const FRAMES_DIR: &str = "frames";

/// The files the stage may write into its folder (besides [`FRAMES_DIR`]); an earlier run's are
/// replaced only with `force`.
pub const OUTPUT_FILES: [&str; 16] = [
    CHECKPOINT_FILE,
    "frames.pvd",
    "stats.csv",
    "stats.csv.partial",
    "final.vtk",
    "final.vtp",
    SUMMARY_FILE,
    MORPHOLOGY_FILE,
    "cells.csv",
    "contacts.csv",
    "model_cells.csv",
    "model_interfaces.csv",
    "reference.vtp",
    "config.toml",
    "last_good.vtk",
    "events.csv",
];

fn err(message: impl Into<String>) -> StageError {
    StageError::new("simulate", message)
}

/// The model of a run: parameters as loaded (the mesh-dependent numerics they leave unset are derived
/// from the input tissue by the stage), which of those the file set, and where they came from (named
/// in messages).
pub struct Model {
    pub params: Parameters,
    pub explicit: ExplicitNumerics,
    pub origin: String,
    /// Validation warnings already shown to the user (when the model was loaded): not repeated.
    pub reported: Vec<String>,
}

impl Model {
    /// The built-in defaults.
    pub fn defaults() -> Self {
        Self {
            params: Parameters::default(),
            explicit: ExplicitNumerics::default(),
            origin: "parameters".into(),
            reported: Vec::new(),
        }
    }
}

/// The nucleus-free reference relaxation of χ (paper Fig. 4f): the same input without its nuclei,
/// relaxed with the same model; χ = 1 − IoU per cell on a grid of `voxel_size` (default l_min/4).
#[derive(Clone, Copy, Debug, Default)]
pub struct NucleusFreeReference {
    pub voxel_size: Option<Real>,
}

/// When checkpoints are saved; `None` takes the model's `[simulation]` value.
#[derive(Clone, Copy, Debug, Default)]
pub struct CheckpointOptions {
    pub every_steps: Option<u64>,
    pub every_seconds: Option<f64>,
    /// Save and stop (as when interrupted) at the end of this step.
    pub stop_at_step: Option<u64>,
}

/// How the stage runs and what it writes besides the fixed files.
#[derive(Default)]
pub struct SimulateOptions {
    /// How the input tissue is read (length unit, orientation repair).
    pub read: ReadOptions,
    /// How `summary.json` names the input (default: the path as given).
    pub input_name: Option<String>,
    /// How the final tissue is measured.
    pub measure: MeasureSettings,
    /// Length unit of the frames, `final.vtp`, `reference.vtp`, `stats.csv`, `events.csv` and the final
    /// measurement (see [`super::output_unit`]); `final.vtk` (SimuCell3D), `last_good.vtk` and
    /// `summary.json` stay SI. `None`: metres for a new run, the run's own unit on resume.
    pub output_unit: Option<OutputUnit>,
    pub reference: Option<NucleusFreeReference>,
    pub checkpoints: CheckpointOptions,
    /// Replace an earlier run's outputs in the folder (otherwise they are an error).
    pub force: bool,
    /// Progress on stderr (a bar on a terminal, a line every 30 s otherwise), labelled `label`
    /// (default `simulate INPUT`).
    pub progress: bool,
    pub label: Option<String>,
    /// The numerics derived from the mesh, one `note:` line each on stderr.
    pub notes: bool,
    /// Set (e.g. by a Ctrl-C handler) to save a checkpoint at the end of the step and stop.
    pub interrupt: Option<&'static AtomicBool>,
    /// A caller's listener and stop request (the Python API): stopping it is an interrupt.
    pub watch: Watch,
}

/// `summary.json`: how the run went (DESIGN.md §2 keys, SI units).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct RunSummary {
    pub steps: u64,
    pub force_evaluations: u64,
    pub converged: bool,
    /// Volume by which cells overlap at the end (m³ and µm³; only penetrations within the contact
    /// cutoff are seen), and the largest overlap of one cell as a fraction of its volume.
    pub overlap_volume: f64,
    pub overlap_volume_um3: f64,
    pub max_overlap_fraction: f64,
    /// Why an equilibrium run did not converge (absent when it did).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stop_reason: Option<String>,
    /// The step whose state the files hold, when not the last one (a run that did not converge
    /// ends at its lowest-residual state).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ended_at_step: Option<u64>,
    pub residual: f64,
    /// Wall time of the run (s), over all its sessions when it was resumed, and the threads of the
    /// last session.
    pub wall_seconds: f64,
    pub threads: usize,
    pub cells: usize,
    pub nodes: usize,
    /// Wall time per node and step (nodes summed over evaluations: the count changes with
    /// divisions and remeshing).
    pub seconds_per_node_step: f64,
    pub mode: SimulationMode,
    pub method: RelaxMethod,
    pub simulated_time: f64,
    pub frames: usize,
    pub energy: EnergyTerms,
    pub energy_total: f64,
    pub input: String,
    /// Cells and nodes at the end (they change with divisions, removals and remeshing).
    pub final_cells: usize,
    pub final_nodes: usize,
    pub divisions: u64,
    pub removals: u64,
    /// Division and remeshing counts (skipped operations, discarded passes, failed cuts).
    pub topology: TopologyStats,
    /// The numerics derived from the input mesh (l_min, contact cutoff, time step) where the model
    /// leaves them unset, and the model's values that contradict the mesh.
    pub mesh_defaults: MeshFit,
    /// Cells whose centre lies inside another cell at the end: they passed through each other.
    pub cells_inside_others: Vec<CellInside>,
    /// The nucleus-free reference relaxation of χ, when asked for.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference: Option<ReferenceRecord>,
}

/// How the nucleus-free reference relaxation went.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ReferenceRecord {
    pub steps: u64,
    pub converged: bool,
    pub residual: Real,
    /// Bodies removed from the input (the nuclei).
    pub nuclei_removed: usize,
    /// Voxel edge of the χ comparison (m).
    pub voxel_size: Real,
}

impl RunSummary {
    /// The top-level keys `summary.json` may have.
    pub fn keys() -> Vec<String> {
        let mut keys: Vec<String> = match serde_json::to_value(Self::default()) {
            Ok(serde_json::Value::Object(map)) => map.keys().cloned().collect(),
            _ => Vec::new(),
        };
        keys.extend(["stop_reason", "ended_at_step", "reference"].map(String::from));
        keys
    }

    /// Reads a stage's `summary.json`.
    pub fn read(path: &Path) -> Result<Self, StageError> {
        let text = std::fs::read_to_string(path).map_err(|e| err(format!("reading {}: {e}", path.display())))?;
        serde_json::from_str(&text).map_err(|e| {
            err(format!("{}: not the summary of a simulation ({e}); run the simulate stage again", path.display()))
        })
    }

    /// The run reached what it was asked for: a time run always; a relaxation (and its reference)
    /// converged; and no cell passed through another.
    pub fn reached_goal(&self) -> bool {
        let time = self.mode == SimulationMode::Time;
        (time || self.converged)
            && self.reference.as_ref().is_none_or(|r| time || r.converged)
            && self.cells_inside_others.is_empty()
    }

    /// `converged` / `done` / `NOT converged (reason)`.
    pub fn verdict(&self) -> String {
        match (self.mode, self.converged) {
            (SimulationMode::Time, _) => "done".to_string(),
            (_, true) => "converged".to_string(),
            (_, false) => format!("NOT converged ({})", self.stop_reason.as_deref().unwrap_or("no reason recorded")),
        }
    }
}

/// A completed run: its summary and the final tissue's morphology.
pub struct SimulateReport {
    pub summary: RunSummary,
    pub morphology: Morphology,
}

/// How [`run`] and [`resume`] ended.
pub enum SimulateOutcome {
    Completed(Box<SimulateReport>),
    /// Stopped by an interrupt or `stop_at_step` after saving `checkpoint.bin` at `step`.
    Interrupted {
        step: u64,
    },
}

/// FIRE relaxations have no physical time: their frames are labelled by step.
fn time_is_step(params: &Parameters) -> bool {
    let s = &params.simulation;
    s.mode == SimulationMode::Equilibrium && s.method == RelaxMethod::Fire
}

/// Makes `dir` ready for a run: an earlier run's outputs there are an error, or removed with `force`.
fn prepare_output(dir: &Path, force: bool) -> Result<(), StageError> {
    let taken: Vec<&str> = OUTPUT_FILES.iter().copied().filter(|f| dir.join(f).exists()).collect();
    let frames = dir.join(FRAMES_DIR);
    if !taken.is_empty() || frames.exists() {
        if !force {
            let unfinished = if taken.contains(&CHECKPOINT_FILE) {
                format!(" (an unfinished run: continue it with `tissuefit simulate --resume {}`)", dir.display())
            } else {
                String::new()
            };
            return Err(err(format!(
                "{} already holds the outputs of a simulation ({}){unfinished}; choose another --out or pass --force",
                dir.display(),
                if taken.is_empty() { format!("{FRAMES_DIR}/") } else { taken.join(", ") }
            )));
        }
        for f in OUTPUT_FILES {
            let p = dir.join(f);
            if p.exists() {
                std::fs::remove_file(&p).map_err(|e| err(format!("removing {}: {e}", p.display())))?;
            }
        }
        if frames.exists() {
            std::fs::remove_dir_all(&frames).map_err(|e| err(format!("removing {}: {e}", frames.display())))?;
        }
    }
    std::fs::create_dir_all(dir).map_err(|e| err(format!("creating {}: {e}", dir.display())))
}

/// Derives the mesh-dependent numerics the model leaves unset from `tissue` (noted on stderr when
/// `notes`), warns where the model's contradict it, then validates (warning about what the model's
/// loading did not already report).
fn fit_and_validate(model: &mut Model, tissue: &Tissue, notes: bool) -> Result<MeshFit, StageError> {
    let fit = model.params.fit_to_tissue(&model.explicit, tissue);
    if notes {
        for line in fit.lines() {
            eprintln!("note: {line}");
        }
    }
    let origin = &model.origin;
    for w in &fit.warnings {
        tracing::warn!("{origin}: {w}");
    }
    let derived = if fit.derived.is_empty() {
        String::new()
    } else {
        format!(" with the numerics derived from the input mesh ({})", fit.lines().join("; "))
    };
    let warnings = model.params.validate().map_err(|e| err(format!("checking {origin}{derived}: {e}")))?;
    for w in warnings.iter().filter(|w| !model.reported.contains(w)) {
        tracing::warn!("{origin}: {w}");
    }
    Ok(fit)
}

/// The input tissue of `tissue` relaxed with `model` into `out` (see the module doc). Everything is
/// checked (input read, model valid for the mesh, every cell has a parameter set) before a file is
/// written. A run whose state turns unhealthy writes its last good state to `last_good.vtk`, keeps
/// `stats.csv.partial` and fails with the cell, the step and the fix.
pub fn run(
    tissue: &Path,
    mut model: Model,
    options: &SimulateOptions,
    out: &Path,
) -> Result<SimulateOutcome, StageError> {
    if options.checkpoints.stop_at_step == Some(0) {
        return Err(err("--stop-at-step 0: a run stops at the end of a step, and step 0 is the start; give K ≥ 1"));
    }
    let read = read_tissue(tissue, &options.read).map_err(|e| err(format!("reading {}: {e}", tissue.display())))?;
    for w in &read.warnings {
        tracing::warn!("{}: {w}", tissue.display());
    }
    let mesh_defaults = fit_and_validate(&mut model, &read.tissue, options.notes)?;
    let params = model.params;
    let bytes = std::fs::read(tissue).map_err(|e| err(format!("reading {}: {e}", tissue.display())))?;
    let input = options.input_name.clone().unwrap_or_else(|| tissue.display().to_string());
    let (cells, nodes) = (read.tissue.len(), read.tissue.node_count());
    // The nucleus-free input of the reference, taken before the run consumes the tissue.
    let without_nuclei = options.reference.map(|r| nucleus_free(&read.tissue, tissue, r)).transpose()?;
    let mut sim = Simulation::new(read.tissue, &params).map_err(|e| err(format!("simulating {input}: {e}")))?;
    for line in sim.repulsion_shortfalls() {
        tracing::warn!("{line}");
    }
    prepare_output(out, options.force)?;
    let parameters = params.to_toml_string();
    write_bytes_atomically(&out.join("config.toml"), parameters.as_bytes()).map_err(|e| err(e.to_string()))?;
    let unit = options.output_unit.unwrap_or_default();
    let recorder = SimulationRecorder::create(out, time_is_step(&params), unit).map_err(|e| err(e.to_string()))?;
    let c = &options.checkpoints;
    let info = RunInfo {
        version: env!("CARGO_PKG_VERSION").to_string(),
        input,
        input_hash: checksum(&bytes),
        parameters,
        initial_cells: cells as u64,
        initial_nodes: nodes as u64,
        threads: rayon::current_num_threads() as u64,
        wall_seconds: 0.0,
        mesh_defaults,
        output: OutputState { frames: Vec::new(), stats_bytes: 0 },
        settings: RunSettings {
            checkpoint_every_steps: c.every_steps.unwrap_or(params.simulation.checkpoint_every_steps),
            checkpoint_every_seconds: c.every_seconds.unwrap_or(params.simulation.checkpoint_every_seconds),
            stop_at_step: c.stop_at_step,
        },
    };
    drive(out, &params, &mut sim, recorder, info, options, without_nuclei)
}

/// The input without its nuclei, for the reference relaxation; an input without nuclei is an error.
fn nucleus_free(
    tissue: &Tissue,
    path: &Path,
    r: NucleusFreeReference,
) -> Result<(Tissue, usize, NucleusFreeReference), StageError> {
    let kept: Vec<_> = tissue.cells().iter().filter(|c| c.kind() != CellKind::Nucleus).cloned().collect();
    let removed = tissue.len() - kept.len();
    if removed == 0 {
        return Err(err(format!(
            "simulate.chi_without_nuclei: {} has no nucleus (cell kind 3) to remove; drop the option or give a \
             tissue with nuclei (e.g. input.generate with nuclei = true)",
            path.display()
        )));
    }
    Ok((Tissue::from_cells(kept).map_err(|e| err(e.to_string()))?, removed, r))
}

/// The step and the wall time (s, all sessions) of the checkpoint in `dir`, if it holds a readable one.
pub fn checkpoint_progress(dir: &Path) -> Option<(u64, f64)> {
    read_checkpoint(&dir.join(CHECKPOINT_FILE)).ok().map(|(info, state)| (state.progress.step, info.wall_seconds))
}

/// Continues the run whose checkpoint is `dir/checkpoint.bin` with its saved model and outputs. The
/// checkpoint settings of `options` replace the saved ones (each replacement noted); the final tissue
/// is measured with `options.measure`, and with `options.reference` the nucleus-free reference is
/// made from `input`, the run's input tissue (the pipeline resumes with its own settings, which its
/// stage key holds fixed).
pub fn resume(dir: &Path, options: &SimulateOptions, input: Option<&Path>) -> Result<SimulateOutcome, StageError> {
    let path = dir.join(CHECKPOINT_FILE);
    if !path.exists() {
        let done = if dir.join(SUMMARY_FILE).exists() { " (the run in it has completed)" } else { "" };
        return Err(err(format!("cannot resume: {} does not exist{done}", path.display())));
    }
    let (mut info, state) = read_checkpoint(&path).map_err(|e| err(e.to_string()))?;
    if info.version != env!("CARGO_PKG_VERSION") {
        tracing::warn!(
            "{} was written by tissuefit {}, this is {}: the continuation may differ from an uninterrupted run",
            path.display(),
            info.version,
            env!("CARGO_PKG_VERSION")
        );
    }
    match std::fs::read(&info.input) {
        Ok(bytes) if checksum(&bytes) != info.input_hash => {
            tracing::warn!("{} changed since the run started (the checkpoint holds the state; resuming)", info.input)
        }
        _ => {}
    }
    let params = Parameters::from_toml_str(&info.parameters, &path.display().to_string())
        .map_err(|e| err(format!("reading the parameters saved in {}: {e}", path.display())))?;
    let step = state.progress.step;
    resume_settings(&options.checkpoints, &mut info.settings, step)?;
    let mut sim = Simulation::restore(state, &params).map_err(|e| err(format!("resuming {}: {e}", path.display())))?;
    let recorder = SimulationRecorder::resume(dir, time_is_step(&params), &info.output, options.output_unit)
        .map_err(|e| err(format!("resuming the outputs in {}: {e}", dir.display())))?;
    let without_nuclei = match (options.reference, input) {
        (Some(r), Some(path)) => {
            let read = read_tissue(path, &options.read).map_err(|e| err(format!("reading {}: {e}", path.display())))?;
            Some(nucleus_free(&read.tissue, path, r)?)
        }
        (Some(_), None) => return Err(err("resuming a run with a nucleus-free reference needs its input tissue")),
        (None, _) => None,
    };
    eprintln!("{}: resuming {} at step {step}", dir.display(), info.input);
    drive(dir, &params, &mut sim, recorder, info, options, without_nuclei)
}

/// The saved settings of a resumed run, with those given now in their place (each replacement
/// noted). A saved stop at or before the checkpoint's step has happened.
fn resume_settings(given: &CheckpointOptions, saved: &mut RunSettings, step: u64) -> Result<(), StageError> {
    fn replace<T: PartialEq + Copy + std::fmt::Display>(flag: &str, given: Option<T>, saved: &mut T) {
        if let Some(v) = given
            && v != *saved
        {
            eprintln!("note: {flag} {v} replaces the run's {saved} (saved in its checkpoint)");
            *saved = v;
        }
    }
    replace("--checkpoint-every-steps", given.every_steps, &mut saved.checkpoint_every_steps);
    replace("--checkpoint-every-seconds", given.every_seconds, &mut saved.checkpoint_every_seconds);
    if saved.stop_at_step.is_some_and(|k| k <= step) {
        saved.stop_at_step = None;
    }
    if let Some(k) = given.stop_at_step {
        if k <= step {
            return Err(err(format!(
                "--stop-at-step {k}: the checkpoint is at step {step} already; give a later step"
            )));
        }
        if let Some(before) = saved.stop_at_step.filter(|&b| b != k) {
            eprintln!("note: --stop-at-step {k} replaces the run's stop at step {before}");
        }
        saved.stop_at_step = Some(k);
    } else if let Some(k) = saved.stop_at_step {
        eprintln!("note: the run stops at step {k}, as it was started with --stop-at-step {k}");
    }
    Ok(())
}

/// When and where checkpoints are saved, and what they record besides the simulation state.
struct Checkpoints {
    path: PathBuf,
    info: RunInfo,
    interrupt: Option<&'static AtomicBool>,
    watch: Watch,
    last: Instant,
    /// Start of this session and wall time of the earlier ones (s).
    session: Instant,
    wall_before: f64,
    /// Step of the last checkpoint saved in this session.
    saved_step: Option<u64>,
}

/// Recorder plus progress on stderr plus checkpoints.
struct RunObserver {
    recorder: SimulationRecorder,
    progress: Progress,
    checkpoints: Checkpoints,
}

impl Observer for RunObserver {
    fn sample(&mut self, sample: &Sample<'_>) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        self.recorder.sample(sample)
    }

    fn checkpoint_due(&mut self, step: u64) -> CheckpointRequest {
        let c = &self.checkpoints;
        let s = &c.info.settings;
        if c.interrupt.is_some_and(|f| f.load(Ordering::SeqCst)) || c.watch.stopped() || s.stop_at_step == Some(step) {
            CheckpointRequest::SaveAndStop
        } else if (s.checkpoint_every_steps > 0 && step.is_multiple_of(s.checkpoint_every_steps))
            || (s.checkpoint_every_seconds > 0.0 && c.last.elapsed().as_secs_f64() >= s.checkpoint_every_seconds)
        {
            CheckpointRequest::Save
        } else {
            CheckpointRequest::No
        }
    }

    fn checkpoint(&mut self, state: &SimulationState) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        let started = Instant::now();
        let c = &mut self.checkpoints;
        c.info.output = self.recorder.state()?;
        c.info.wall_seconds = c.wall_before + c.session.elapsed().as_secs_f64();
        let bytes = write_checkpoint(&c.path, &c.info, state)?;
        c.last = Instant::now();
        c.saved_step = Some(state.progress.step);
        tracing::info!(
            "checkpoint at step {}: {} ({bytes} bytes) written in {:.3} s",
            state.progress.step,
            c.path.display(),
            started.elapsed().as_secs_f64()
        );
        Ok(())
    }

    fn progress(&mut self, step: u64, residual: f64) {
        self.progress.step(step, residual);
    }
}

/// Progress only (the reference relaxation keeps no frames).
struct ProgressOnly(Progress);

impl Observer for ProgressOnly {
    fn sample(&mut self, _sample: &Sample<'_>) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        Ok(())
    }

    fn progress(&mut self, step: u64, residual: Real) {
        self.0.step(step, residual);
    }
}

/// Runs (or continues) the simulation, then writes the final outputs or explains how it stopped.
fn drive(
    out: &Path,
    params: &Parameters,
    sim: &mut Simulation<'_>,
    recorder: SimulationRecorder,
    info: RunInfo,
    options: &SimulateOptions,
    without_nuclei: Option<(Tissue, usize, NucleusFreeReference)>,
) -> Result<SimulateOutcome, StageError> {
    let s = &params.simulation;
    let label = options.label.clone().unwrap_or_else(|| format!("simulate {}", info.input));
    let progress =
        Progress::of_steps(label.clone(), params.planned_steps(), options.progress).with_watch(options.watch.clone());
    let every_seconds = info.settings.checkpoint_every_seconds;
    if !(every_seconds.is_finite() && every_seconds >= 0.0) {
        return Err(err(format!(
            "--checkpoint-every-seconds must be a finite number ≥ 0 (0: not by time), got {every_seconds}"
        )));
    }
    let (input, wall_before) = (info.input.clone(), info.wall_seconds);
    let mesh_defaults = info.mesh_defaults.clone();
    let (cells, nodes) = (info.initial_cells as usize, info.initial_nodes as usize);
    let checkpoints = Checkpoints {
        path: out.join(CHECKPOINT_FILE),
        info,
        interrupt: options.interrupt,
        watch: options.watch.clone(),
        last: Instant::now(),
        session: Instant::now(),
        wall_before,
        saved_step: None,
    };
    let mut observer = RunObserver { recorder, progress, checkpoints };

    let started = Instant::now();
    let result = sim.run(&mut observer);
    // The run's wall time: not the writing, measuring and reference relaxation after it, so that
    // seconds_per_node_step is the simulation's cost.
    let wall = wall_before + started.elapsed().as_secs_f64();
    observer.progress.finish();
    let checkpoint = out.join(CHECKPOINT_FILE);
    let summary: SimulationSummary = match result {
        Ok(summary) => summary,
        Err(SimulationError::Interrupted { step }) => {
            observer.recorder.abandon();
            return Ok(SimulateOutcome::Interrupted { step });
        }
        Err(SimulationError::Unhealthy { step, cell, what, hint, last_good }) => {
            observer.recorder.abandon();
            let saved = out.join("last_good.vtk");
            write_simucell3d(&saved, &last_good, &[]).map_err(|e| err(e.to_string()))?;
            let kept = if checkpoint.exists() {
                format!(
                    "; the last checkpoint ({}) is kept in {}",
                    observer
                        .checkpoints
                        .saved_step
                        .map_or("from an earlier session".to_string(), |k| format!("step {k}")),
                    checkpoint.display()
                )
            } else {
                String::new()
            };
            return Err(err(format!(
                "simulating {input}: step {step}, cell {cell}: {what}. {hint}. The last good state (step {}) is in \
                 {}{kept}; the statistics so far in {}. To go on with changed parameters, simulate {} with the new \
                 config",
                step.saturating_sub(1),
                saved.display(),
                out.join("stats.csv.partial").display(),
                saved.display()
            )));
        }
        Err(e) => {
            observer.recorder.abandon();
            return Err(err(format!("simulating {input}: {e}")));
        }
    };
    if let Some(warning) = summary.overlap_warning() {
        tracing::warn!("{warning}");
    }
    let inside = crate::mechanics::cells_inside_others(sim.tissue());
    if let Some(warning) = crate::mechanics::passage_warning(&inside) {
        tracing::warn!("{input}: {warning}");
    }
    let frames = observer.recorder.frames();
    let unit = observer.recorder.unit();
    observer.recorder.finish().map_err(|e| err(e.to_string()))?;
    // Tissue writers fail with an `IoError`, the output group with a `FileError`.
    fn io(e: impl std::fmt::Display) -> StageError {
        err(e.to_string())
    }
    write_events(&out.join("events.csv"), sim.events(), unit).map_err(io)?;
    let pressure: Vec<f64> = sim.forces().cells.iter().map(|w| w.pressure).collect();
    let fields = [CellField { name: "pressure", values: &pressure }];
    write_simucell3d(&out.join("final.vtk"), sim.tissue(), &fields).map_err(io)?;
    write_tissue_in(&out.join("final.vtp"), sim.tissue(), &fields, unit).map_err(io)?;
    let mut morphology =
        measure_tissue(sim.tissue(), &options.measure).map_err(|e| err(format!("measuring the final tissue: {e}")))?;
    let reference = match without_nuclei {
        Some((tissue, nuclei_removed, r)) => {
            let mut rsim = Simulation::new(tissue, params).map_err(|e| err(format!("{input} without nuclei: {e}")))?;
            let mut observer = ProgressOnly(Progress::of_steps(
                format!("{label} (without nuclei)"),
                params.planned_steps(),
                options.progress,
            ));
            let result = rsim.run(&mut observer);
            observer.0.finish();
            let rsummary = result.map_err(|e| err(format!("{input} without nuclei: {e}")))?;
            write_tissue_in(&out.join("reference.vtp"), rsim.tissue(), &[], unit).map_err(io)?;
            let voxel = r.voxel_size.unwrap_or(params.numerics.min_edge_length / 4.0);
            let overlaps = compare_tissues(sim.tissue(), rsim.tissue(), [voxel; 3])
                .map_err(|e| err(format!("comparing with the nucleus-free reference: {e}")))?;
            morphology.set_overlap(&overlaps);
            Some(ReferenceRecord {
                steps: rsummary.steps,
                converged: rsummary.converged,
                residual: rsummary.residual,
                nuclei_removed,
                voxel_size: voxel,
            })
        }
        None => None,
    };
    let run_summary = RunSummary {
        steps: summary.steps,
        force_evaluations: summary.force_evaluations,
        converged: summary.converged,
        overlap_volume: summary.overlap_volume,
        overlap_volume_um3: summary.overlap_volume * 1e18,
        max_overlap_fraction: summary.max_overlap_fraction,
        stop_reason: summary.stop_reason.clone(),
        ended_at_step: summary.ended_at_step,
        residual: summary.residual,
        wall_seconds: wall,
        threads: rayon::current_num_threads(),
        cells,
        nodes,
        seconds_per_node_step: wall / summary.node_evaluations.max(1) as f64,
        mode: s.mode,
        method: s.method,
        simulated_time: summary.time,
        frames,
        energy: summary.energy,
        energy_total: summary.energy.total(),
        input,
        final_cells: sim.tissue().len(),
        final_nodes: sim.tissue().node_count(),
        divisions: summary.topology.divisions,
        removals: summary.topology.removals,
        topology: summary.topology,
        mesh_defaults,
        cells_inside_others: inside,
        reference,
    };
    // The tables and both summaries all or nothing: summary.json last, so that a folder with one
    // holds a complete run.
    let mut group = OutputGroup::new();
    super::measure::write_tables(&mut group, out, &morphology, unit).map_err(io)?;
    let (model_cells, model_interfaces) =
        super::model_tables::model_tables(sim.tissue(), params, &pressure, &morphology);
    super::write_csv(&mut group, &out.join("model_cells.csv"), &model_cells, &Default::default()).map_err(io)?;
    super::write_csv(&mut group, &out.join("model_interfaces.csv"), &model_interfaces, &Default::default())
        .map_err(io)?;
    super::measure::write_summary(&mut group, &out.join(MORPHOLOGY_FILE), &morphology.summary, unit).map_err(io)?;
    write_json(&mut group, &out.join(SUMMARY_FILE), &run_summary).map_err(io)?;
    group.commit().map_err(io)?;
    // The run is complete: its checkpoint could only restart finished work.
    if checkpoint.exists() {
        std::fs::remove_file(&checkpoint).map_err(|e| err(format!("removing {}: {e}", checkpoint.display())))?;
    }
    Ok(SimulateOutcome::Completed(Box::new(SimulateReport { summary: run_summary, morphology })))
}

//! `tissuefit simulate TISSUE --config C.toml --out DIR`: relax to equilibrium or run a time span.
//! `tissuefit simulate --resume DIR`: continue a run from `DIR/checkpoint.bin`.
//!
//! Checkpoints: the run saves its complete state every `--checkpoint-every-steps` steps and/or every
//! `--checkpoint-every-seconds` seconds of wall time (`[simulation]` checkpoint_every_steps and
//! checkpoint_every_seconds in the config; default every 600 s), and when interrupted (Ctrl-C,
//! SIGTERM) at the end of the step in progress, then exits with status 130. A resumed run ends with
//! exactly the outputs of an uninterrupted one (same seed and threads; summary.json's wall time
//! aside, which sums the sessions). A completed run deletes its checkpoint. The checkpoint also
//! holds the run's settings (checkpoint period, `--stop-at-step`), which a resumed run keeps unless
//! the `--resume` command line gives them again (then with a note).

use super::{InputArgs, Outcome};
use crate::io::{
    CHECKPOINT_FILE, OutputPolicy, Progress, RunInfo, RunSettings, SimulationRecorder, checksum, read_checkpoint,
    read_tissue, write_bytes_atomically, write_checkpoint, write_events, write_simucell3d,
};
use crate::mechanics::{
    CellInside, CheckpointRequest, ExplicitNumerics, MeshFit, Observer, Parameters, RelaxMethod, Sample, Simulation,
    SimulationError, SimulationMode, SimulationState, SimulationSummary,
};
use crate::pipeline::{PipelineConfig, is_pipeline_file, run_simulate};
use anyhow::{Context, bail};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct SimulateArgs {
    /// Input tissue (.vtk or .vtp).
    #[arg(required_unless_present = "resume", conflicts_with = "resume")]
    pub tissue: Option<PathBuf>,
    /// Parameter file (TOML; see `tissuefit config defaults`), or a pipeline file (one with an `[input]`
    /// table): then TISSUE (its mesh stage's `tissue.vtp`) is relaxed with its `[simulate]` section
    /// and measured with its `[measure]`, exactly as `tissuefit run` does, into --out. Default:
    /// built-in defaults.
    #[arg(long, value_name = "TOML", conflicts_with = "resume")]
    pub config: Option<PathBuf>,
    /// Output folder: frames.pvd + frames/, stats.csv, final.vtk, summary.json, config.toml
    /// (and checkpoint.bin while the run is in progress).
    #[arg(long, value_name = "DIR", required_unless_present = "resume", conflicts_with = "resume")]
    pub out: Option<PathBuf>,
    /// Overrides simulation.mode: equilibrium (relax) or time (run simulation.duration).
    #[arg(long, value_parser = ["equilibrium", "time"], conflicts_with = "resume")]
    pub mode: Option<String>,
    /// Overrides simulation.method (equilibrium mode): fire or integrate.
    #[arg(long, value_parser = ["fire", "integrate"], conflicts_with = "resume")]
    pub method: Option<String>,
    /// Overrides simulation.max_steps.
    #[arg(long, conflicts_with = "resume")]
    pub max_steps: Option<u64>,
    /// Overrides simulation.duration (s).
    #[arg(long, conflicts_with = "resume")]
    pub duration: Option<f64>,
    /// Replace the outputs of an earlier run in DIR.
    #[arg(long, conflicts_with = "resume")]
    pub force: bool,
    /// Continue the run whose checkpoint is DIR/checkpoint.bin, with its parameters and outputs.
    #[arg(long, value_name = "DIR")]
    pub resume: Option<PathBuf>,
    /// Overrides simulation.checkpoint_every_steps: save a checkpoint every N steps (0: not by
    /// step count).
    #[arg(long, value_name = "N")]
    pub checkpoint_every_steps: Option<u64>,
    /// Overrides simulation.checkpoint_every_seconds: save a checkpoint every S seconds of wall
    /// time (0: not by time).
    #[arg(long, value_name = "S")]
    pub checkpoint_every_seconds: Option<f64>,
    /// Save a checkpoint and stop (exit 130, as when interrupted) at the end of step K (≥ 1, and with
    /// --resume after the checkpoint's step); continue with --resume. Splits a long run into jobs
    /// that fit a cluster's time limit.
    #[arg(long, value_name = "K")]
    pub stop_at_step: Option<u64>,
    #[command(flatten)]
    pub input: InputArgs,
}

/// `summary.json` (DESIGN.md §2 keys, SI units).
#[derive(Serialize)]
struct Summary<'a> {
    steps: u64,
    force_evaluations: u64,
    converged: bool,
    /// Volume by which cells overlap at the end (m³ and µm³; only penetrations within the contact
    /// cutoff are seen), and the largest overlap of one cell as a fraction of its volume.
    overlap_volume: f64,
    overlap_volume_um3: f64,
    max_overlap_fraction: f64,
    /// Why an equilibrium run did not converge (absent when it did).
    #[serde(skip_serializing_if = "Option::is_none")]
    stop_reason: Option<&'a str>,
    /// The step whose state the files hold, when not the last one (a run that did not converge
    /// ends at its lowest-residual state).
    #[serde(skip_serializing_if = "Option::is_none")]
    ended_at_step: Option<u64>,
    residual: f64,
    wall_seconds: f64,
    threads: usize,
    cells: usize,
    nodes: usize,
    seconds_per_node_step: f64,
    mode: SimulationMode,
    method: RelaxMethod,
    simulated_time: f64,
    frames: usize,
    energy: &'a crate::mechanics::EnergyTerms,
    energy_total: f64,
    input: String,
    /// Cells and nodes at the end (they change with divisions, removals and remeshing).
    final_cells: usize,
    final_nodes: usize,
    divisions: u64,
    removals: u64,
    /// Division and remeshing counts (skipped operations, discarded passes, failed cuts).
    topology: crate::mechanics::TopologyStats,
    /// The numerics derived from the input mesh (l_min, contact cutoff, time step) where the config
    /// leaves them unset, and the config's values that contradict the mesh.
    mesh_defaults: &'a MeshFit,
    /// Cells whose centre lies inside another cell at the end: they passed through each other (the
    /// run then exits 1).
    cells_inside_others: &'a [CellInside],
}

const OUTPUTS: [&str; 11] = [
    CHECKPOINT_FILE,
    "frames.pvd",
    "stats.csv",
    "stats.csv.partial",
    "final.vtk",
    "final.vtp",
    "summary.json",
    "simulation.json",
    "config.toml",
    "last_good.vtk",
    "events.csv",
];

/// Applies the command-line overrides (CLI > config file > defaults); also says which
/// mesh-dependent numerics the config sets. Validated by [`fit_and_validate`] once the input mesh's
/// defaults are in.
fn resolve_parameters(args: &SimulateArgs) -> anyhow::Result<(Parameters, ExplicitNumerics)> {
    let (mut params, explicit) = match &args.config {
        Some(path) => Parameters::load_explicit(path)?,
        None => (Parameters::default(), ExplicitNumerics::default()),
    };
    let s = &mut params.simulation;
    if let Some(m) = &args.mode {
        s.mode = if m == "time" { SimulationMode::Time } else { SimulationMode::Equilibrium };
    }
    if let Some(m) = &args.method {
        s.method = if m == "integrate" { RelaxMethod::Integrate } else { RelaxMethod::Fire };
    }
    if let Some(n) = args.max_steps {
        s.max_steps = n;
    }
    if let Some(d) = args.duration {
        s.duration = d;
    }
    Ok((params, explicit))
}

/// Derives the mesh-dependent numerics the config leaves unset from `tissue` (each printed as a
/// note), warns where the config's contradict it, then validates.
fn fit_and_validate(
    params: &mut Parameters,
    explicit: &ExplicitNumerics,
    tissue: &crate::mesh::Tissue,
    origin: &str,
) -> anyhow::Result<MeshFit> {
    let fit = params.fit_to_tissue(explicit, tissue);
    for line in fit.lines() {
        eprintln!("note: {line}");
    }
    for w in &fit.warnings {
        tracing::warn!("{origin}: {w}");
    }
    let derived = if fit.derived.is_empty() { "" } else { " (with the values derived from the input mesh)" };
    for w in params.validate().with_context(|| format!("checking {origin}{derived}"))? {
        tracing::warn!("{origin}: {w}");
    }
    Ok(fit)
}

fn prepare_output(dir: &Path, force: bool) -> anyhow::Result<()> {
    let taken: Vec<&str> = OUTPUTS.iter().copied().filter(|f| dir.join(f).exists()).collect();
    if !taken.is_empty() || dir.join("frames").exists() {
        if !force {
            let unfinished = if taken.contains(&CHECKPOINT_FILE) {
                format!(" (an unfinished run: continue it with `tissuefit simulate --resume {}`)", dir.display())
            } else {
                String::new()
            };
            bail!(
                "{} already holds the outputs of a simulation ({}){unfinished}; choose another --out or pass --force",
                dir.display(),
                if taken.is_empty() { "frames/".to_string() } else { taken.join(", ") }
            );
        }
        for f in OUTPUTS {
            let p = dir.join(f);
            if p.exists() {
                std::fs::remove_file(&p).with_context(|| format!("removing {}", p.display()))?;
            }
        }
        let frames = dir.join("frames");
        if frames.exists() {
            std::fs::remove_dir_all(&frames).with_context(|| format!("removing {}", frames.display()))?;
        }
    }
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))
}

/// Set by the Ctrl-C / SIGTERM handler; the run saves a checkpoint at the end of its step and stops.
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// Installs the SIGINT/SIGTERM handler once per process and clears the flag. A second interrupt
/// while the checkpoint is pending quits at once (exit 130) without saving.
fn watch_interrupts() {
    static INSTALLED: std::sync::Once = std::sync::Once::new();
    INSTALLED.call_once(|| {
        let installed = ctrlc::set_handler(|| {
            if INTERRUPTED.swap(true, Ordering::SeqCst) {
                eprintln!("interrupted again: quitting without saving");
                std::process::exit(130);
            }
            eprintln!(
                "interrupt received: saving a checkpoint at the end of this step (interrupt again to quit at once)"
            );
        });
        if let Err(e) = installed {
            tracing::warn!("cannot catch Ctrl-C ({e}); an interrupted run keeps only its periodic checkpoints");
        }
    });
    INTERRUPTED.store(false, Ordering::SeqCst);
}

/// When and where checkpoints are saved, and what they record besides the simulation state.
struct Checkpoints {
    path: PathBuf,
    info: RunInfo,
    every_steps: u64,
    every_seconds: f64,
    stop_at_step: Option<u64>,
    last: Instant,
    /// Start of this session and wall time of the earlier ones (s).
    session: Instant,
    wall_before: f64,
    /// Step of the last checkpoint saved in this session.
    saved_step: Option<u64>,
}

/// Recorder plus progress on stderr (a bar on a terminal, a line every 30 s otherwise: see
/// [`Progress`]), plus checkpoints.
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
        if INTERRUPTED.load(Ordering::SeqCst) || c.stop_at_step == Some(step) {
            CheckpointRequest::SaveAndStop
        } else if (c.every_steps > 0 && step.is_multiple_of(c.every_steps))
            || (c.every_seconds > 0.0 && c.last.elapsed().as_secs_f64() >= c.every_seconds)
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
        c.saved_step = Some(state.step);
        tracing::info!(
            "checkpoint at step {}: {} ({bytes} bytes) written in {:.3} s",
            state.step,
            c.path.display(),
            started.elapsed().as_secs_f64()
        );
        Ok(())
    }

    fn progress(&mut self, step: u64, residual: f64) {
        self.progress.step(step, residual);
    }
}

pub fn run(args: &SimulateArgs) -> anyhow::Result<Outcome> {
    if args.stop_at_step == Some(0) {
        bail!("--stop-at-step 0: a run stops at the end of a step, and step 0 is the start; give K ≥ 1");
    }
    watch_interrupts();
    if let Some(dir) = &args.resume {
        return resume(args, dir);
    }
    let (Some(tissue), Some(out)) = (&args.tissue, &args.out) else {
        bail!("simulate needs a TISSUE and --out DIR, or --resume DIR");
    };
    let mut written: Vec<&str> = OUTPUTS.to_vec();
    written.extend(["reference.vtp", "cells.csv", "contacts.csv", "frames/"]);
    OutputPolicy::new()
        .input("TISSUE", tissue)
        .input_opt("--config", args.config.as_deref())
        .folder("--out", out, &written)?;
    if let Some(pipeline) = args.config.as_deref().filter(|p| is_pipeline_file(p)) {
        return run_stage(args, tissue, pipeline, out);
    }
    let (mut params, explicit) = resolve_parameters(args)?;
    let read =
        read_tissue(tissue, &args.input.read_options()).with_context(|| format!("reading {}", tissue.display()))?;
    for w in &read.warnings {
        tracing::warn!("{}: {w}", tissue.display());
    }
    let origin = args.config.as_ref().map_or("parameters".to_string(), |p| p.display().to_string());
    let mesh_defaults = fit_and_validate(&mut params, &explicit, &read.tissue, &origin)?;
    let input_hash = checksum(&std::fs::read(tissue).with_context(|| format!("reading {}", tissue.display()))?);
    let (cells, nodes) = (read.tissue.len(), read.tissue.node_count());
    // Checked before anything is written: every cell has a parameter set, something moves.
    let mut sim = Simulation::new(read.tissue, &params).with_context(|| format!("simulating {}", tissue.display()))?;
    for line in sim.repulsion_shortfalls() {
        tracing::warn!("{line}");
    }
    prepare_output(out, args.force)?;
    let parameters = params.to_toml_string();
    write_bytes_atomically(&out.join("config.toml"), parameters.as_bytes())?;
    let recorder = SimulationRecorder::create(out, time_is_step(&params))?;
    let info = RunInfo {
        version: env!("CARGO_PKG_VERSION").to_string(),
        input: tissue.display().to_string(),
        input_hash,
        parameters,
        initial_cells: cells as u64,
        initial_nodes: nodes as u64,
        threads: rayon::current_num_threads() as u64,
        wall_seconds: 0.0,
        mesh_defaults,
        output: crate::io::OutputState { frames: Vec::new(), stats_bytes: 0 },
        settings: RunSettings {
            checkpoint_every_steps: args.checkpoint_every_steps.unwrap_or(params.simulation.checkpoint_every_steps),
            checkpoint_every_seconds: args
                .checkpoint_every_seconds
                .unwrap_or(params.simulation.checkpoint_every_seconds),
            stop_at_step: args.stop_at_step,
        },
    };
    drive(out, &params, &mut sim, recorder, info)
}

/// `simulate TISSUE --config PIPELINE.toml --out DIR`: the pipeline's simulate stage into DIR. The
/// model comes from the file only: the command-line overrides are refused rather than silently
/// making the stage differ from `tissuefit run`'s.
fn run_stage(args: &SimulateArgs, tissue: &Path, pipeline: &Path, out: &Path) -> anyhow::Result<Outcome> {
    let overrides = [
        ("--mode", args.mode.is_some()),
        ("--method", args.method.is_some()),
        ("--max-steps", args.max_steps.is_some()),
        ("--duration", args.duration.is_some()),
        ("--checkpoint-every-steps", args.checkpoint_every_steps.is_some()),
        ("--checkpoint-every-seconds", args.checkpoint_every_seconds.is_some()),
        ("--stop-at-step", args.stop_at_step.is_some()),
        ("--length-unit", args.input.length_unit != crate::io::LengthScale::default()),
        ("--orient", args.input.orient),
    ];
    let given: Vec<&str> = overrides.iter().filter(|(_, on)| *on).map(|(name, _)| *name).collect();
    if !given.is_empty() {
        bail!(
            "{} cannot be used with the pipeline file {}: its [simulate] section configures the stage (set e.g. \
             simulation.max_steps in [simulate.model_overrides.simulation]), or give a parameter file to --config",
            given.join(", "),
            pipeline.display()
        );
    }
    let config = PipelineConfig::load(pipeline)?;
    let Some(section) = &config.simulate else {
        bail!("{}: the pipeline has no [simulate] section; add one to simulate", pipeline.display());
    };
    prepare_output(out, args.force)?;
    let started = Instant::now();
    let (line, converged) = run_simulate(tissue, section, &config.measure, out, true)?;
    println!(
        "simulate ({}): {line}; {:.2} s; outputs in {}",
        pipeline.display(),
        started.elapsed().as_secs_f64(),
        out.display()
    );
    Ok(if converged { Outcome::Success } else { Outcome::CheckFailed })
}

/// FIRE relaxations have no physical time: their frames are labelled by step.
fn time_is_step(params: &Parameters) -> bool {
    let s = &params.simulation;
    s.mode == SimulationMode::Equilibrium && s.method == RelaxMethod::Fire
}

/// `--resume DIR`: continue from `DIR/checkpoint.bin` with the saved parameters and outputs.
fn resume(args: &SimulateArgs, dir: &Path) -> anyhow::Result<Outcome> {
    let path = dir.join(CHECKPOINT_FILE);
    if !path.exists() {
        let done = if dir.join("summary.json").exists() { " (the run in it has completed)" } else { "" };
        bail!("cannot resume: {} does not exist{done}", path.display());
    }
    let (info, state) = read_checkpoint(&path)?;
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
        .with_context(|| format!("reading the parameters saved in {}", path.display()))?;
    let step = state.step;
    let mut info = info;
    resume_settings(args, &mut info.settings, step)?;
    let mut sim = Simulation::restore(state, &params).with_context(|| format!("resuming {}", path.display()))?;
    let recorder = SimulationRecorder::resume(dir, time_is_step(&params), &info.output)
        .with_context(|| format!("resuming the outputs in {}", dir.display()))?;
    eprintln!("{}: resuming {} at step {step}", dir.display(), info.input);
    drive(dir, &params, &mut sim, recorder, info)
}

/// The saved settings of a resumed run, with the options of the `--resume` command line in their
/// place (each replacement noted). A saved stop at or before the checkpoint's step has happened.
fn resume_settings(args: &SimulateArgs, saved: &mut RunSettings, step: u64) -> anyhow::Result<()> {
    if let Some(n) = args.checkpoint_every_steps
        && n != saved.checkpoint_every_steps
    {
        eprintln!(
            "note: --checkpoint-every-steps {n} replaces the run's {} (saved in its checkpoint)",
            saved.checkpoint_every_steps
        );
        saved.checkpoint_every_steps = n;
    }
    if let Some(s) = args.checkpoint_every_seconds
        && s != saved.checkpoint_every_seconds
    {
        eprintln!(
            "note: --checkpoint-every-seconds {s} replaces the run's {} (saved in its checkpoint)",
            saved.checkpoint_every_seconds
        );
        saved.checkpoint_every_seconds = s;
    }
    if saved.stop_at_step.is_some_and(|k| k <= step) {
        saved.stop_at_step = None;
    }
    if let Some(k) = args.stop_at_step {
        if k <= step {
            bail!("--stop-at-step {k}: the checkpoint is at step {step} already; give a later step");
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

/// Runs (or continues) the simulation, then writes the final outputs or explains how it stopped.
fn drive(
    out: &Path,
    params: &Parameters,
    sim: &mut Simulation<'_>,
    recorder: SimulationRecorder,
    info: RunInfo,
) -> anyhow::Result<Outcome> {
    let s = &params.simulation;
    let progress = Progress::of_steps(format!("simulate {}", info.input), params.planned_steps(), true);
    let settings = info.settings.clone();
    let every_seconds = settings.checkpoint_every_seconds;
    if !(every_seconds.is_finite() && every_seconds >= 0.0) {
        bail!("--checkpoint-every-seconds must be a finite number ≥ 0 (0: not by time), got {every_seconds}");
    }
    let (input, wall_before) = (info.input.clone(), info.wall_seconds);
    let mesh_defaults = info.mesh_defaults.clone();
    let (cells, nodes) = (info.initial_cells as usize, info.initial_nodes as usize);
    let checkpoints = Checkpoints {
        path: out.join(CHECKPOINT_FILE),
        info,
        every_steps: settings.checkpoint_every_steps,
        every_seconds,
        stop_at_step: settings.stop_at_step,
        last: Instant::now(),
        session: Instant::now(),
        wall_before,
        saved_step: None,
    };
    let mut observer = RunObserver { recorder, progress, checkpoints };

    let started = Instant::now();
    let result = sim.run(&mut observer);
    let wall = wall_before + started.elapsed().as_secs_f64();
    observer.progress.finish();
    let checkpoint = out.join(CHECKPOINT_FILE);
    let summary: SimulationSummary = match result {
        Ok(summary) => summary,
        Err(SimulationError::Interrupted { step }) => {
            observer.recorder.abandon();
            eprintln!(
                "{input}: stopped at step {step}; the state is saved in {}. Continue with: tissuefit simulate --resume {}",
                checkpoint.display(),
                out.display()
            );
            return Ok(Outcome::Interrupted);
        }
        Err(SimulationError::Unhealthy { step, cell, what, hint, last_good }) => {
            observer.recorder.abandon();
            let saved = out.join("last_good.vtk");
            write_simucell3d(&saved, &last_good, &[])?;
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
            bail!(
                "simulating {input}: step {step}, cell {cell}: {what}. {hint}. The last good state (step {}) is in {}{kept}; \
                 the statistics so far in {}. To go on with changed parameters, simulate {} with the new config",
                step.saturating_sub(1),
                saved.display(),
                out.join("stats.csv.partial").display(),
                saved.display()
            );
        }
        Err(e) => {
            observer.recorder.abandon();
            return Err(e).with_context(|| format!("simulating {input}"));
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
    observer.recorder.finish()?;
    write_events(&out.join("events.csv"), sim.events())?;
    let pressure: Vec<f64> = sim.forces().cells.iter().map(|w| w.pressure).collect();
    write_simucell3d(
        &out.join("final.vtk"),
        sim.tissue(),
        &[crate::io::CellField { name: "pressure", values: &pressure }],
    )?;
    let json = Summary {
        steps: summary.steps,
        force_evaluations: summary.force_evaluations,
        converged: summary.converged,
        overlap_volume: summary.overlap_volume,
        overlap_volume_um3: summary.overlap_volume * 1e18,
        max_overlap_fraction: summary.max_overlap_fraction,
        stop_reason: summary.stop_reason.as_deref(),
        ended_at_step: summary.ended_at_step,
        residual: summary.residual,
        wall_seconds: wall,
        threads: rayon::current_num_threads(),
        cells,
        nodes,
        // Nodes summed over evaluations: the node count changes with divisions and remeshing.
        seconds_per_node_step: wall / summary.node_evaluations.max(1) as f64,
        mode: s.mode,
        method: s.method,
        simulated_time: summary.time,
        frames,
        energy: &summary.energy,
        energy_total: summary.energy.total(),
        input: input.clone(),
        final_cells: sim.tissue().len(),
        final_nodes: sim.tissue().node_count(),
        divisions: summary.topology.divisions,
        removals: summary.topology.removals,
        topology: summary.topology,
        mesh_defaults: &mesh_defaults,
        cells_inside_others: &inside,
    };
    write_bytes_atomically(&out.join("summary.json"), serde_json::to_string_pretty(&json)?.as_bytes())?;
    // The run is complete: its checkpoint could only restart finished work.
    if checkpoint.exists() {
        std::fs::remove_file(&checkpoint).with_context(|| format!("removing {}", checkpoint.display()))?;
    }
    let verdict = match (s.mode, summary.converged) {
        (SimulationMode::Time, _) => "done".to_string(),
        (_, true) => "converged".to_string(),
        (_, false) => format!("NOT converged ({})", summary.stop_reason.as_deref().unwrap_or("no reason recorded")),
    };
    eprintln!(
        "{input}: {verdict}: {} steps, {} force evaluations, residual {:.3e} (max force / γ·l_min), {:.2} s wall, {} frames in {}",
        summary.steps,
        summary.force_evaluations,
        summary.residual,
        wall,
        frames,
        out.display()
    );
    Ok(if (s.mode == SimulationMode::Equilibrium && !summary.converged) || !inside.is_empty() {
        Outcome::CheckFailed
    } else {
        Outcome::Success
    })
}

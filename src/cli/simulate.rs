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
use crate::io::{CHECKPOINT_FILE, OutputPolicy, OutputUnit, ReadOptions};
use crate::mechanics::{Parameters, RelaxMethod, SimulationMode};
use crate::pipeline::{PipelineConfig, is_pipeline_file, run_simulate};
use crate::stages::simulate::{self, CheckpointOptions, Model, SimulateOptions, SimulateOutcome};
use anyhow::bail;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct SimulateArgs {
    /// Input tissue (.vtk, .vtp or .ply).
    #[arg(required_unless_present = "resume", conflicts_with = "resume")]
    pub tissue: Option<PathBuf>,
    /// Parameter file (TOML; see `tissuefit config defaults`), or a pipeline file (one with an `[input]`
    /// table): then TISSUE (its mesh stage's `tissue.vtp`) is relaxed with its `[simulate]` section
    /// and measured with its `[measure]`, exactly as `tissuefit run` does, into --out. Default:
    /// built-in defaults.
    #[arg(long, value_name = "TOML", conflicts_with = "resume")]
    pub config: Option<PathBuf>,
    /// Output folder: frames.pvd + frames/, stats.csv, events.csv, final.vtp and final.vtk,
    /// summary.json (the run), the final tissue measured (cells.csv, contacts.csv, morphology.json),
    /// config.toml (and checkpoint.bin while the run is in progress).
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
    /// Length unit of the frames, final.vtp, stats.csv, events.csv, cells.csv, contacts.csv and
    /// morphology.json: m (SI, the default) or um (ParaView's axes read µm; columns become volume_um3,
    /// area_um2, …; each .vtp records its unit and tissuefit reads it back in metres). final.vtk
    /// (SimuCell3D) and summary.json stay SI. With --resume: the run's own unit (default), which
    /// cannot change.
    #[arg(long, value_name = "UNIT")]
    pub output_unit: Option<OutputUnit>,
}

/// The model: the config file (or the defaults) with the command-line overrides (CLI > config file
/// > defaults); the stage derives the mesh-dependent numerics it leaves unset and validates it.
fn resolve_model(args: &SimulateArgs) -> anyhow::Result<Model> {
    let mut model = match &args.config {
        Some(path) => {
            let (params, explicit) = Parameters::load_explicit(path)?;
            Model { params, explicit, origin: path.display().to_string(), reported: Vec::new() }
        }
        None => Model::defaults(),
    };
    let s = &mut model.params.simulation;
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
    Ok(model)
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

pub fn run(args: &SimulateArgs) -> anyhow::Result<Outcome> {
    // `--stop-at-step 0` is refused by the stage (a new run), or as before the checkpoint (a resume).
    let checkpoints = CheckpointOptions {
        every_steps: args.checkpoint_every_steps,
        every_seconds: args.checkpoint_every_seconds,
        stop_at_step: args.stop_at_step,
    };
    let options = |read| SimulateOptions {
        read,
        checkpoints,
        force: args.force,
        progress: true,
        notes: true,
        interrupt: Some(&INTERRUPTED),
        output_unit: args.output_unit,
        ..SimulateOptions::default()
    };
    if let Some(dir) = &args.resume {
        watch_interrupts();
        let outcome = simulate::resume(dir, &options(ReadOptions::default()), None)?;
        return Ok(report(outcome, dir));
    }
    let (Some(tissue), Some(out)) = (&args.tissue, &args.out) else {
        bail!("simulate needs a TISSUE and --out DIR, or --resume DIR");
    };
    let mut written: Vec<&str> = simulate::OUTPUT_FILES.to_vec();
    written.push("frames/");
    OutputPolicy::new()
        .input("TISSUE", tissue)
        .input_opt("--config", args.config.as_deref())
        .folder("--out", out, &written)?;
    if let Some(pipeline) = args.config.as_deref().filter(|p| is_pipeline_file(p)) {
        return run_stage(args, tissue, pipeline, out);
    }
    // (A pipeline file's stage above is stopped by Ctrl-C as `tissuefit run` is: no handler.)
    watch_interrupts();
    let model = resolve_model(args)?;
    let outcome = simulate::run(tissue, model, &options(args.input.read_options()), out)?;
    Ok(report(outcome, out))
}

/// Prints how the run ended; the exit status: a relaxation that did not converge, or cells that
/// passed through each other, is a failed check.
fn report(outcome: SimulateOutcome, out: &Path) -> Outcome {
    let r = match outcome {
        SimulateOutcome::Completed(r) => r,
        SimulateOutcome::Interrupted { step } => {
            eprintln!(
                "stopped at step {step}; the state is saved in {}. Continue with: tissuefit simulate --resume {}",
                out.join(CHECKPOINT_FILE).display(),
                out.display()
            );
            return Outcome::Interrupted;
        }
    };
    let s = &r.summary;
    eprintln!(
        "{}: {}: {} steps, {} force evaluations, residual {:.3e} (max force / γ·l_min), {:.2} s wall, {} frames in {}",
        s.input,
        s.verdict(),
        s.steps,
        s.force_evaluations,
        s.residual,
        s.wall_seconds,
        s.frames,
        out.display()
    );
    if s.reached_goal() { Outcome::Success } else { Outcome::CheckFailed }
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
        ("--output-unit", args.output_unit.is_some()),
    ];
    let given: Vec<&str> = overrides.iter().filter(|(_, on)| *on).map(|(name, _)| *name).collect();
    if !given.is_empty() {
        bail!(
            "{} cannot be used with the pipeline file {}: its [simulate] section configures the stage (set e.g. \
             simulation.max_steps in [simulate.model_overrides.simulation]; the length unit in [output]), or give a \
             parameter file to --config",
            given.join(", "),
            pipeline.display()
        );
    }
    let config = PipelineConfig::load(pipeline)?;
    let Some(section) = &config.simulate else {
        bail!("{}: the pipeline has no [simulate] section; add one to simulate", pipeline.display());
    };
    let started = Instant::now();
    let (line, converged) =
        run_simulate(tissue, section, &config.measure, &config.output, out, args.force, false, true)?;
    println!(
        "simulate ({}): {line}; {:.2} s; outputs in {}",
        pipeline.display(),
        started.elapsed().as_secs_f64(),
        out.display()
    );
    Ok(if converged { Outcome::Success } else { Outcome::CheckFailed })
}

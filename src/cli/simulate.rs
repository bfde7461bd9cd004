//! `tissuefit simulate TISSUE --config C.toml --out DIR`: relax to equilibrium or run a time span.

use super::{InputArgs, Outcome};
use crate::io::{SimulationRecorder, read_tissue, write_bytes_atomically, write_simucell3d};
use crate::mechanics::{
    Observer, Parameters, RelaxMethod, Sample, Simulation, SimulationError, SimulationMode, SimulationSummary,
};
use anyhow::{Context, bail};
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct SimulateArgs {
    /// Input tissue (.vtk or .vtp).
    pub tissue: PathBuf,
    /// Parameter file (TOML; see `tissuefit config defaults`). Default: built-in defaults.
    #[arg(long, value_name = "TOML")]
    pub config: Option<PathBuf>,
    /// Output folder: frames.pvd + frames/, stats.csv, final.vtk, summary.json, config.toml.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Overrides simulation.mode: equilibrium (relax) or time (run simulation.duration).
    #[arg(long, value_parser = ["equilibrium", "time"])]
    pub mode: Option<String>,
    /// Overrides simulation.method (equilibrium mode): fire or integrate.
    #[arg(long, value_parser = ["fire", "integrate"])]
    pub method: Option<String>,
    /// Overrides simulation.max_steps.
    #[arg(long)]
    pub max_steps: Option<u64>,
    /// Overrides simulation.duration (s).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Replace the outputs of an earlier run in DIR.
    #[arg(long)]
    pub force: bool,
    #[command(flatten)]
    pub input: InputArgs,
}

/// `summary.json` (DESIGN.md §2 keys, SI units).
#[derive(Serialize)]
struct Summary<'a> {
    steps: u64,
    force_evaluations: u64,
    converged: bool,
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
}

const OUTPUTS: [&str; 8] = [
    "frames.pvd",
    "stats.csv",
    "stats.csv.partial",
    "final.vtk",
    "summary.json",
    "config.toml",
    "last_good.vtk",
    "events.csv",
];

/// `events.csv`: one row per division or removal.
fn write_events(path: &Path, events: &[crate::mechanics::TopologyEvent]) -> anyhow::Result<()> {
    use std::fmt::Write as _;
    let mut text = String::from("step,time,event,cell,daughter_a,daughter_b,volume\n");
    for e in events {
        let (a, b) = e.daughters.map_or((String::new(), String::new()), |[a, b]| (a.to_string(), b.to_string()));
        let kind = match e.kind {
            crate::mechanics::TopologyEventKind::Division => "division",
            crate::mechanics::TopologyEventKind::Removal => "removal",
        };
        let _ = writeln!(text, "{},{:e},{kind},{},{a},{b},{:e}", e.step, e.time, e.cell, e.volume);
    }
    write_bytes_atomically(path, text.as_bytes())?;
    Ok(())
}

/// Applies the command-line overrides (CLI > config file > defaults) and validates.
fn resolve_parameters(args: &SimulateArgs) -> anyhow::Result<Parameters> {
    let mut params = match &args.config {
        Some(path) => Parameters::load(path)?,
        None => Parameters::default(),
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
    let origin = args.config.as_ref().map_or("parameters".to_string(), |p| p.display().to_string());
    for w in params.validate().with_context(|| format!("checking {origin}"))? {
        tracing::warn!("{origin}: {w}");
    }
    Ok(params)
}

fn prepare_output(dir: &Path, force: bool) -> anyhow::Result<()> {
    let taken: Vec<&str> = OUTPUTS.iter().copied().filter(|f| dir.join(f).exists()).collect();
    if !taken.is_empty() || dir.join("frames").exists() {
        if !force {
            bail!(
                "{} already holds the outputs of a simulation ({}); choose another --out or pass --force",
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

/// Recorder plus a progress bar on stderr (hidden when stderr is not a terminal).
struct Progress {
    recorder: SimulationRecorder,
    bar: ProgressBar,
}

impl Observer for Progress {
    fn sample(&mut self, sample: &Sample<'_>) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        self.recorder.sample(sample)
    }

    fn progress(&mut self, step: u64, residual: f64) {
        if step.is_multiple_of(16) {
            self.bar.set_position(step);
            self.bar.set_message(format!("residual {residual:.3e}"));
        }
    }
}

pub fn run(args: &SimulateArgs) -> anyhow::Result<Outcome> {
    let params = resolve_parameters(args)?;
    let read = read_tissue(&args.tissue, &args.input.read_options())
        .with_context(|| format!("reading {}", args.tissue.display()))?;
    for w in &read.warnings {
        tracing::warn!("{}: {w}", args.tissue.display());
    }
    let (cells, nodes) = (read.tissue.len(), read.tissue.node_count());
    // Checked before anything is written: every cell has a parameter set, something moves.
    let mut sim =
        Simulation::new(read.tissue, &params).with_context(|| format!("simulating {}", args.tissue.display()))?;
    prepare_output(&args.out, args.force)?;
    write_bytes_atomically(&args.out.join("config.toml"), params.to_toml_string().as_bytes())?;

    let s = &params.simulation;
    let total_steps = match s.mode {
        SimulationMode::Equilibrium => s.max_steps,
        SimulationMode::Time => (s.duration / params.numerics.time_step).round() as u64,
    };
    let bar = ProgressBar::with_draw_target(Some(total_steps), indicatif::ProgressDrawTarget::stderr());
    bar.set_style(
        ProgressStyle::with_template("{elapsed_precise} [{wide_bar}] {pos}/{len} steps, {msg}, ETA {eta}")
            .expect("valid template"),
    );
    let fire = s.mode == SimulationMode::Equilibrium && s.method == RelaxMethod::Fire;
    let recorder = SimulationRecorder::create(&args.out, fire)?;
    let mut observer = Progress { recorder, bar };

    let started = Instant::now();
    let result = sim.run(&mut observer);
    let wall = started.elapsed().as_secs_f64();
    observer.bar.finish_and_clear();
    let summary: SimulationSummary = match result {
        Ok(summary) => summary,
        Err(SimulationError::Unhealthy { step, cell, what, hint, last_good }) => {
            observer.recorder.abandon();
            let saved = args.out.join("last_good.vtk");
            write_simucell3d(&saved, &last_good, &[])?;
            bail!(
                "simulating {}: step {step}, cell {cell}: {what}. {hint}. The last good state (step {}) is in {}; \
                 the statistics so far in {}",
                args.tissue.display(),
                step.saturating_sub(1),
                saved.display(),
                args.out.join("stats.csv.partial").display()
            );
        }
        Err(e) => {
            observer.recorder.abandon();
            return Err(e).with_context(|| format!("simulating {}", args.tissue.display()));
        }
    };
    let frames = observer.recorder.frames();
    observer.recorder.finish()?;
    write_events(&args.out.join("events.csv"), sim.events())?;
    let pressure: Vec<f64> = sim.forces().cells.iter().map(|w| w.pressure).collect();
    write_simucell3d(
        &args.out.join("final.vtk"),
        sim.tissue(),
        &[crate::io::CellField { name: "pressure", values: &pressure }],
    )?;
    let json = Summary {
        steps: summary.steps,
        force_evaluations: summary.force_evaluations,
        converged: summary.converged,
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
        input: args.tissue.display().to_string(),
        final_cells: sim.tissue().len(),
        final_nodes: sim.tissue().node_count(),
        divisions: summary.topology.divisions,
        removals: summary.topology.removals,
        topology: summary.topology,
    };
    write_bytes_atomically(&args.out.join("summary.json"), serde_json::to_string_pretty(&json)?.as_bytes())?;
    let verdict = match (s.mode, summary.converged) {
        (SimulationMode::Time, _) => "done".to_string(),
        (_, true) => "converged".to_string(),
        (_, false) => format!("NOT converged within {} steps", s.max_steps),
    };
    eprintln!(
        "{}: {verdict}: {} steps, {} force evaluations, residual {:.3e} (max force / γ·l_min), {:.2} s wall, {} frames in {}",
        args.tissue.display(),
        summary.steps,
        summary.force_evaluations,
        summary.residual,
        wall,
        frames,
        args.out.display()
    );
    Ok(if s.mode == SimulationMode::Equilibrium && !summary.converged {
        Outcome::CheckFailed
    } else {
        Outcome::Success
    })
}

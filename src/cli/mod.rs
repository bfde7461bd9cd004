//! Command-line interface: thin subcommands that parse arguments, call the library, and print.

mod bench;
mod config;
mod convert;
mod fit;
mod fit_series;
mod generate;
mod inspect;
mod label_args;
mod measure;
mod mesh;
mod polarize;
mod render;
mod run;
mod simulate;
mod sweep;
mod tensions;
mod voxelize;

use crate::io::{LengthScale, ReadOptions};
use clap::{Parser, Subcommand};
use std::io::IsTerminal;

/// tissuefit: from a segmented 3D tissue image to the mechanical parameters of its cells.
#[derive(Parser, Debug)]
#[command(name = "tissuefit", version, about, long_about = None)]
pub struct Cli {
    /// More log output on stderr (-v info, -vv debug); RUST_LOG overrides.
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    pub verbose: u8,
    /// Only errors on stderr.
    #[arg(short, long, global = true)]
    pub quiet: bool,
    /// Worker threads (default: all cores, or RAYON_NUM_THREADS); at most 4 per available core.
    #[arg(long, global = true)]
    pub threads: Option<usize>,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Report every cell of a tissue file: kind, size, volume, area, sphericity, mesh defects.
    /// Exits with 1 when some cell is not a valid closed surface.
    Inspect(inspect::InspectArgs),
    /// Convert a tissue file: .vtk (SimuCell3D legacy or multi-material) or .vtp → .vtp or .vtk.
    Convert(convert::ConvertArgs),
    /// Measure morphology: per-cell volume, area, sphericity, neighbours, contact fraction, contact
    /// angles, layers, nuclei → DIR/cells.csv, DIR/contacts.csv, DIR/summary.json.
    Measure(measure::MeasureArgs),
    /// Estimate every interface's tension and every cell's pressure directly from the shapes (force
    /// balance at the junction lines, Young–Laplace on the interfaces), relative to a gauge →
    /// DIR/interfaces.csv, cells.csv, summary.json, tensions.vtp. Takes seconds; no simulation.
    Tensions(tensions::TensionsArgs),
    /// Mesh a label volume: every label → a closed cell surface → TISSUE.vtp/.vtk, plus a per-label
    /// report (kept/static/dropped and why); optionally nuclei from a second volume. Given a .vtk/.vtp
    /// tissue instead, re-triangulate its cells. Exits with 2 when no cell could be meshed.
    Mesh(mesh::MeshArgs),
    /// Simulate a tissue: relax it to mechanical equilibrium, or run it for a time span with growth.
    /// Exits with 1 when an equilibrium run ends unconverged or cells passed through each other.
    Simulate(simulate::SimulateArgs),
    /// Type the faces of the epithelial and static cells (apical, lateral, basal) by ray casting
    /// (paper mode 2) or from contacts (mode 1) → a .vtp to colour by face_type in ParaView; prints
    /// the counts per face type.
    Polarize(polarize::PolarizeArgs),
    /// Throughput benchmarks: print one JSON object (forces-cell, forces-tissue FILE, relax-cube,
    /// contacts-tissue FILE, growth, relax FILE).
    Bench(bench::BenchArgs),
    /// Simulation parameters: print the commented defaults, or check a config file.
    #[command(subcommand)]
    Config(config::ConfigCommand),
    /// Rasterise a tissue's cells into a label TIFF (labels = cell ids), on the grid of an existing
    /// label volume (--like) or of a given voxel size.
    Voxelize(voxelize::VoxelizeArgs),
    /// Fit surface tension and adhesion so that simulated equilibrium morphology matches the observed
    /// one → DIR/trace.csv, result.json, objective.png, landscape.png. Exits with 1 when the optimiser
    /// stopped on its budget instead of converging.
    Fit(fit::FitArgs),
    /// Map a time series of label volumes in order with the per-cell fit: cells tracked by overlap
    /// (one id through the series), each frame started with the previous frame's correction →
    /// DIR/tNNN/, tracks.csv, series_cells.csv, series_interfaces.csv, series.json. Exits with 1
    /// when a frame failed or did not converge.
    FitSeries(fit_series::FitSeriesArgs),
    /// Synthetic inputs: `generate labels` writes a label volume (sphere, ellipsoid, cube, doublet,
    /// aggregate); `generate mesh` writes a tissue (sphere, cube, vesicle, sheet, tube, spheroid).
    #[command(subcommand)]
    Generate(generate::GenerateCommand),
    /// Run a pipeline file: mesh → measure → (simulate) → (fit, or the per-cell maps of a `[series]` of
    /// frames) into a run directory with a manifest (input hashes, resolved config, timings);
    /// unchanged stages are skipped. Exits with 1 when the fit did not converge or is a poor fit, a
    /// series frame failed or did not converge, or a `[demo]` truth was not recovered.
    Run(run::RunArgs),
    /// Draw a tissue into a PNG picture (software rendering; colour by cell, kind or face type).
    Render(render::RenderArgs),
    /// Run a parameter sweep: every variant of a base pipeline (a [grid] of values or a [[runs]] list)
    /// into DIR/run-NNNN, J at a time, then DIR/results.csv and plots; `--list`, `--index I` (job
    /// arrays) and `--collect`. Exits with 1 when a run failed; a failed run never stops the others.
    Sweep(sweep::SweepArgs),
}

/// How a successful run ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    Success,
    /// The command completed but found a problem (e.g. invalid cells): exit code 1.
    CheckFailed,
    /// Stopped by Ctrl-C/SIGTERM after saving its state (exit 130, the shell's code for SIGINT).
    Interrupted,
}

/// Options shared by commands that read tissue files.
#[derive(clap::Args, Debug, Clone)]
pub struct InputArgs {
    /// Length unit of the input coordinates: m (default), mm, um, nm, metres per unit (2.5e-7), or the
    /// x,y,z voxel size for meshes in voxel coordinates (0.15,0.15,0.235um).
    #[arg(long, default_value = "m", value_name = "UNIT")]
    pub length_unit: LengthScale,
    /// Re-orient every cell's faces consistently and outward before use (repairs files whose polygons
    /// are wound both ways; multi-material meshes are always re-oriented).
    #[arg(long)]
    pub orient: bool,
}

impl InputArgs {
    pub(crate) fn read_options(&self) -> ReadOptions {
        ReadOptions { length_scale: self.length_unit, orient: self.orient }
    }
}

/// Most worker threads per available core: beyond a few per core threads only add scheduling and
/// synchronisation cost (at 1000 threads a run was already slower than with one per core).
pub const MAX_THREADS_PER_CORE: usize = 4;

/// `--threads N`, capped at [`MAX_THREADS_PER_CORE`] × the available cores with a warning.
fn capped_threads(asked: usize) -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let max = MAX_THREADS_PER_CORE * cores;
    if asked > max {
        tracing::warn!(
            "--threads {asked}: using {max} ({MAX_THREADS_PER_CORE} per available core, {cores} cores); more only slow the run down"
        );
        return max;
    }
    asked
}

/// Runs a parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<Outcome> {
    init_logging(cli.verbose, cli.quiet);
    crate::io::set_quiet(cli.quiet);
    // The command runs inside the pool, on one of its workers: every parallel loop then starts by
    // work stealing instead of waking the pool from outside (a futex round trip per loop, which
    // dominated small simulations).
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(n) = cli.threads {
        builder = builder.num_threads(capped_threads(n));
    }
    let pool = builder.build()?;
    pool.install(|| match cli.command {
        Command::Inspect(args) => inspect::run(&args),
        Command::Convert(args) => convert::run(&args),
        Command::Config(cmd) => config::run(&cmd),
        Command::Simulate(args) => simulate::run(&args),
        Command::Measure(args) => measure::run(&args),
        Command::Tensions(args) => tensions::run(&args),
        Command::Mesh(args) => mesh::run(&args),
        Command::Polarize(args) => polarize::run(&args),
        Command::Bench(args) => bench::run(&args),
        Command::Voxelize(args) => voxelize::run(&args),
        Command::Generate(cmd) => generate::run(&cmd),
        Command::Fit(args) => fit::run(&args),
        Command::FitSeries(args) => fit_series::run(&args),
        Command::Run(args) => run::run(&args),
        Command::Render(args) => render::run(&args),
        Command::Sweep(args) => sweep::run(&args),
    })
}

fn init_logging(verbose: u8, quiet: bool) {
    use tracing_subscriber::EnvFilter;
    let level = match (quiet, verbose) {
        (true, _) => "error",
        (false, 0) => "warn",
        (false, 1) => "info",
        _ => "debug",
    };
    let filter = EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new(level));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(std::io::stderr().is_terminal())
        .with_target(false)
        .try_init();
}

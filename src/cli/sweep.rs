//! `tissuefit sweep SWEEP.toml --out DIR [--jobs J] [--force] [--list | --index I | --collect]`: the
//! runs of a parameter sweep (see [`crate::pipeline::sweep`]), each an ordinary run directory
//! `DIR/run-NNNN`, then `DIR/results.csv` and `DIR/plots/`.

use super::Outcome;
use crate::io::OutputPolicy;
use crate::pipeline::{Sweep, SweepOptions, collect_results, plot_results, run_sweep};
use anyhow::{Context, bail};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct SweepArgs {
    /// Sweep file (TOML; see the docs book, "Parameter sweeps").
    pub sweep: PathBuf,
    /// Sweep directory: run-0000/, run-0001/, …, results.csv, plots/. Default: sweeps/<sweep file stem>.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Runs at a time; the threads (--threads, default all cores) are split between them. Results do
    /// not depend on it.
    #[arg(long, default_value_t = 1, value_name = "J")]
    pub jobs: usize,
    /// Run every stage of every run again, even those whose inputs and config are unchanged.
    #[arg(long)]
    pub force: bool,
    /// Print one line per run (index, then key=value pairs, tab-separated) and exit.
    #[arg(long, conflicts_with_all = ["index", "collect"])]
    pub list: bool,
    /// Run only run I into DIR/run-000I (one task of a job array); no results table.
    #[arg(long, value_name = "I", conflicts_with = "collect")]
    pub index: Option<usize>,
    /// Run nothing: build results.csv and the plots from the run directories already in DIR. Refused
    /// while a sweep, a job-array task or another collection works in DIR (collect after they end).
    #[arg(long)]
    pub collect: bool,
}

pub fn run(args: &SweepArgs) -> anyhow::Result<Outcome> {
    let sweep = Sweep::load(&args.sweep).with_context(|| format!("reading the sweep {}", args.sweep.display()))?;
    if args.list {
        for run in &sweep.runs {
            let values = sweep.describe(run);
            println!("{}{}{values}", run.index, if values.is_empty() { "" } else { "\t" });
        }
        return Ok(Outcome::Success);
    }
    if args.jobs == 0 {
        bail!("--jobs must be at least 1");
    }
    let out = args.out.clone().unwrap_or_else(|| {
        let stem = args.sweep.file_stem().map_or("sweep".into(), |s| s.to_string_lossy().into_owned());
        PathBuf::from("sweeps").join(stem)
    });
    OutputPolicy::new().input("SWEEP", &args.sweep).input("base", &sweep.base).folder(
        "--out",
        &out,
        &["results.csv", "plots/"],
    )?;
    let started = std::time::Instant::now();
    if !args.collect {
        super::run::watch_interrupts();
        let print = |line: &str| println!("{line}");
        let threads = rayon::current_num_threads();
        let options = SweepOptions {
            out: out.clone(),
            jobs: args.jobs,
            threads,
            force: args.force,
            only: args.index,
            on_event: &print,
        };
        let reports = run_sweep(&sweep, &options)?;
        let failed = reports.iter().filter(|r| r.status == "failed").count();
        let jobs = args.jobs.clamp(1, reports.len().max(1));
        println!(
            "{} run(s) in {:.2} s ({} jobs × {} threads): {} complete, {} skipped, {failed} failed",
            reports.len(),
            started.elapsed().as_secs_f64(),
            jobs,
            (threads / jobs).max(1),
            reports.iter().filter(|r| r.status == "complete").count(),
            reports.iter().filter(|r| r.status == "skipped").count(),
        );
        if args.index.is_some() {
            return Ok(if failed > 0 { Outcome::CheckFailed } else { Outcome::Success });
        }
    }
    let rows = collect_results(&sweep, &out)?;
    let plots = plot_results(&sweep, &rows, &out)?;
    let bad: Vec<String> =
        rows.iter().filter(|r| r.status != "complete").map(|r| format!("run {} {}", r.index, r.status)).collect();
    println!(
        "{} ({} rows){}",
        out.join("results.csv").display(),
        rows.len(),
        if plots.is_empty() {
            if sweep.keys.len() > 2 {
                "; no plots for more than two independent swept keys".to_string()
            } else {
                String::new()
            }
        } else {
            format!("; {} plots in {}", plots.len(), out.join("plots").display())
        }
    );
    if !bad.is_empty() {
        println!("not complete: {}", bad.join(", "));
        return Ok(Outcome::CheckFailed);
    }
    Ok(Outcome::Success)
}

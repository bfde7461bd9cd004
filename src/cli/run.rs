//! `tissuefit run PIPELINE.toml [--out DIR] [--force]`: every stage of a pipeline file into a run
//! directory (see [`crate::pipeline`]).

use super::Outcome;
use crate::io::OutputPolicy;
use crate::pipeline::{PipelineOptions, run_pipeline};
use anyhow::Context;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct RunArgs {
    /// Pipeline file (TOML; see the docs book, "Pipelines and configs").
    pub pipeline: PathBuf,
    /// Run directory. Default: runs/<pipeline file stem> in the current folder.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Run every stage again, even those whose inputs and config are unchanged.
    #[arg(long)]
    pub force: bool,
}

fn default_out(pipeline: &Path) -> PathBuf {
    let stem = pipeline.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "pipeline".into());
    Path::new("runs").join(stem)
}

/// Ctrl-C / SIGTERM: the stages in progress are marked `interrupted` in their manifests, then the
/// process exits with 130 (the lock goes with it). Without this they would stay `running`.
pub(super) fn watch_interrupts() {
    let installed = ctrlc::set_handler(|| {
        for (dir, stage) in crate::pipeline::interrupt_active_runs() {
            // What the same command does with the stage next time (the stages' resume rules).
            let next = match stage.as_str() {
                "fit" => "to resume it: the evaluations already in its trace.csv are kept",
                "simulate" => "to resume it from its last checkpoint (or from the start if it wrote none)",
                "series" => "to resume it: the frames it finished are read back, not mapped again",
                _ => "to redo it",
            };
            eprintln!(
                "interrupted: stage {stage} is marked interrupted in {}; run the same command again {next}",
                dir.join("manifest.json").display()
            );
        }
        std::process::exit(130);
    });
    if let Err(e) = installed {
        tracing::warn!("cannot catch Ctrl-C ({e}); an interrupted stage stays `running` until the next run");
    }
}

pub fn run(args: &RunArgs) -> anyhow::Result<Outcome> {
    let out = args.out.clone().unwrap_or_else(|| default_out(&args.pipeline));
    OutputPolicy::new().input("PIPELINE", &args.pipeline).folder(
        "--out",
        &out,
        &["config.resolved.toml", "manifest.json", "mesh/", "measure/", "simulate/", "fit/", "series/"],
    )?;
    watch_interrupts();
    let print = |line: &str| println!("{line}");
    let options = PipelineOptions { out: out.clone(), force: args.force, progress: true, on_event: &print };
    let started = std::time::Instant::now();
    let outcome =
        run_pipeline(&args.pipeline, &options).with_context(|| format!("running {}", args.pipeline.display()))?;
    let mut ok = true;
    if outcome.fit_converged == Some(false) {
        println!("fit: the optimiser stopped on its budget, not converged (see {}/fit/result.json)", out.display());
        ok = false;
    }
    if outcome.fit_poor == Some(true) {
        println!(
            "fit: POOR FIT: the objective lies far above the forward model's noise (see {}/fit/result.json, \
             identifiability)",
            out.display()
        );
        ok = false;
    }
    if let Some(reason) = &outcome.fit_best_failed {
        println!(
            "fit: BEST-POINT RELAXATION FAILED ({reason}): no {}/fit/best.vtp; the fitted values stand, the \
             relaxed tissue and residuals.csv's simulated columns do not",
            out.display()
        );
        ok = false;
    }
    if outcome.series_succeeded == Some(false) {
        println!(
            "series: some frame failed, did not converge or is a poor fit (see {}/series/series.json)",
            out.display()
        );
        ok = false;
    }
    if outcome.simulate_converged == Some(false) {
        println!(
            "simulate: the run ended unconverged or with cells passed through each other (see {}/simulate/summary.json)",
            out.display()
        );
    }
    if !outcome.demo.is_empty() {
        println!(
            "{:<28} {:>12} {:>12} {:>9}  within ±{:.0} %?",
            "parameter",
            "truth",
            "fitted",
            "error",
            outcome.demo[0].tolerance * 100.0
        );
        for c in &outcome.demo {
            let fitted = c.fitted.map_or("missing".to_string(), |f| format!("{f:.4e}"));
            let error = c.relative_error.map_or("n/a".to_string(), |e| format!("{:+.1} %", e * 100.0));
            println!(
                "{:<28} {:>12.4e} {:>12} {:>9}  {}",
                c.name,
                c.truth,
                fitted,
                error,
                if c.within { "yes" } else { "NO" }
            );
            ok &= c.within;
        }
    }
    let times: Vec<String> =
        outcome.manifest.stages.iter().map(|s| format!("{} {} {:.2} s", s.name, s.status, s.wall_seconds)).collect();
    println!(
        "run directory {} ({}); {:.2} s on {} threads",
        out.display(),
        times.join(", "),
        started.elapsed().as_secs_f64(),
        outcome.manifest.threads
    );
    Ok(if ok { Outcome::Success } else { Outcome::CheckFailed })
}

//! `tissuefit fit --config FIT.toml --out DIR`: fit surface tension and adhesion to observed morphology.

use super::Outcome;
use crate::inference::{FitConfig, FitOptions};
use crate::io::{OutputPolicy, OutputUnit};
use crate::pipeline::PipelineConfig;
use anyhow::Context;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct FitArgs {
    /// Fit configuration (TOML; see the docs book, "Fitting parameters"), or a pipeline file (one with an
    /// `[input]` table; its `[fit]` on the labels of `[input]` meshed like `[mesh]`, as `tissuefit run`).
    #[arg(long, value_name = "TOML")]
    pub config: PathBuf,
    /// Output folder: trace.csv, result.json, objective.png, landscape.png, profile.png (the profile of
    /// each fitted quantity, with the acceptance threshold and range), fit.toml, model.toml, and at
    /// the best point best.vtp (the relaxed tissue), best.toml (the model) and residuals.csv (observed
    /// vs simulated per cell). With `mode = "per_cell"`: cells.csv, interfaces.csv (the per-cell map),
    /// iterations.csv, tissue.vtp (coloured by tension), relaxed.vtp, cell_overrides.toml, model.toml,
    /// result.json and fit.toml.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Continue the fit in DIR from its trace.csv (evaluations already there are not re-simulated);
    /// an error when DIR holds no trace.csv. A per-cell fit runs its refinement again from the start.
    #[arg(long)]
    pub resume: bool,
    /// Overrides optimizer.max_evaluations.
    #[arg(long)]
    pub max_evaluations: Option<usize>,
    /// Overrides optimizer.seed.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Length unit of best.vtp: m (SI) or um (ParaView's axes read µm; the file records its unit and
    /// tissuefit reads it back in metres). Default: a pipeline file's `[output] length_unit`, else m.
    /// residuals.csv has both units; trace.csv, result.json and the models are SI.
    #[arg(long, value_name = "UNIT")]
    pub output_unit: Option<OutputUnit>,
}

/// A fit config, or the fit of a pipeline file (recognised by its `[input]` table) with the
/// pipeline's output unit.
pub(super) fn load_config(path: &Path) -> anyhow::Result<(FitConfig, Option<OutputUnit>)> {
    if !crate::pipeline::is_pipeline_file(path) {
        return Ok((FitConfig::load(path)?, None));
    }
    let pipeline = PipelineConfig::load(path)?;
    let fit = pipeline
        .fit
        .as_ref()
        .ok_or_else(|| anyhow::anyhow!("{}: the pipeline has no [fit] section; add one to fit", path.display()))?;
    Ok((crate::pipeline::fit_config(fit, &pipeline.input, &pipeline.mesh), Some(pipeline.output.length_unit)))
}

pub fn run(args: &FitArgs) -> anyhow::Result<Outcome> {
    let (mut config, pipeline_unit) = load_config(&args.config)?;
    let observed = config.observed().ok();
    OutputPolicy::new()
        .input("--config", &args.config)
        .input_opt("observed.tissue", observed.and_then(|o| o.tissue.as_deref()))
        .input_opt("observed.labels", observed.and_then(|o| o.labels.as_deref()))
        .folder("--out", &args.out, &crate::stages::fit::output_files())?;
    if let Some(n) = args.max_evaluations {
        anyhow::ensure!(n > 0, "--max-evaluations must be at least 1");
        config.optimizer.max_evaluations = n;
    }
    if let Some(s) = args.seed {
        config.optimizer.seed = s;
    }
    let options = FitOptions {
        resume: args.resume,
        progress: true,
        plots: true,
        output_unit: args.output_unit.or(pipeline_unit).unwrap_or_default(),
        ..Default::default()
    };
    let result = crate::stages::fit::run(&config, crate::stages::fit::Observed::Config, &args.out, &options)
        .with_context(|| format!("fitting {}", args.config.display()))?;
    eprintln!(
        "{}: {}; {:.1} s; outputs in {}",
        args.config.display(),
        result.summary_line(),
        result.wall_seconds(),
        args.out.display()
    );
    // A poor fit, or a best point whose relaxation failed, completed but found a problem, like an
    // unconverged one: exit code 1.
    Ok(if result.succeeded() { Outcome::Success } else { Outcome::CheckFailed })
}

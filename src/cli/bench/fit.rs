//! `tissuefit bench fit`: issue 24's "one 20-cell global fit", timed. The synthetic aggregate round
//! trip of [`crate::inference::round_trip`]: an aggregate of `--cells` polyhedral cells meshed at
//! `--nodes` per cell is relaxed with a known key ratio (`--ratio`: w/(2γ) for spring contacts,
//! γ_lateral/γ_apical for coupling), voxelised at `--voxels-per-diameter`, and fitted from that label
//! volume alone (`--evaluations` Nelder–Mead evaluations and the profile, `--shifts` sub-voxel
//! shifts per measurement), as `tests/slow/fit_round_trips.rs` runs it.
//!
//! Prints one JSON object: the fit's wall and CPU seconds next to the truth's, the evaluations, the
//! node-steps the fit's relaxations ran (steps × the observed tissue's nodes) and the CPU cost per
//! node-step over the whole fit, one evaluation at the truth split into relaxation and measurement
//! (CPU seconds), and the accuracy: the recovered ratio, its error and range. Exits non-zero
//! (`CheckFailed`) when the recovered ratio is more than 10 % off the truth or not determined: a
//! faster fit counts only at the same accuracy.

use super::growth::cpu_seconds;
use crate::geometry::Real;
use crate::inference::round_trip::{
    AGGREGATE_GAMMA, aggregate_fit_config, aggregate_model, aggregate_truth, fitted_truth, initial_aggregate,
    observe_aggregate,
};
use crate::inference::{FitConfig, FitOptions, ForwardModel, ParameterSpace, load_observation, run_fit};
use crate::mechanics::{ContactModel, NoObserver};
use anyhow::Context;
use serde_json::{Value, json};
use std::time::Instant;

/// Relative error of the recovered ratio within which the benchmark counts as accurate (the round
/// trip's acceptance).
pub const ACCURACY: Real = 0.10;

/// What `bench fit` runs.
pub struct FitBench {
    pub contact_model: ContactModel,
    /// The truth's key ratio.
    pub ratio: Real,
    pub cells: usize,
    pub nodes: usize,
    pub voxels_per_diameter: Real,
    pub evaluations: usize,
    pub shifts: usize,
}

/// Wall and CPU seconds of `f`.
fn timed<T>(f: impl FnOnce() -> T) -> (T, Real, Option<Real>) {
    let (cpu, started) = (cpu_seconds(), Instant::now());
    let out = f();
    let cpu = cpu_seconds().zip(cpu).map(|(b, a)| b - a);
    (out, started.elapsed().as_secs_f64(), cpu)
}

/// Runs the round trip; returns the JSON and whether the fit recovered the truth within [`ACCURACY`],
/// determined.
pub fn run_fit_bench(bench: &FitBench) -> anyhow::Result<(Value, bool)> {
    anyhow::ensure!(bench.ratio > 0.0 && bench.ratio.is_finite(), "--ratio must be a positive number");
    anyhow::ensure!(bench.voxels_per_diameter >= 4.0, "--voxels-per-diameter below 4 leaves nothing to mesh");
    let dir = ScratchDir::new()?;
    let contact = bench.contact_model;
    let (made, truth_wall, truth_cpu) = timed(|| -> anyhow::Result<_> {
        let (initial, l_min) = initial_aggregate(bench.cells, bench.nodes).map_err(anyhow::Error::msg)?;
        let (truth, key) = aggregate_truth(contact, l_min, bench.ratio);
        let observed =
            observe_aggregate(dir.path(), &truth, &initial, bench.voxels_per_diameter).map_err(anyhow::Error::msg)?;
        Ok((observed, l_min, key))
    });
    let (observed, l_min, key) = made?;
    let base = aggregate_model(contact, l_min, AGGREGATE_GAMMA, 0.0);
    std::fs::write(dir.path().join("model.toml"), base.to_toml_string())?;
    let config_path = dir.path().join("fit.toml");
    let config_text = aggregate_fit_config(contact, l_min, bench.nodes, bench.evaluations, bench.shifts);
    std::fs::write(&config_path, config_text)?;
    let config = FitConfig::load(&config_path)?;
    let out = dir.path().join("out");
    let (result, fit_wall, fit_cpu) = timed(|| run_fit(&config, &out, &FitOptions::default()));
    let result = result.context("the round trip's fit")?;
    let steps: u64 = trace_steps(&out.join("trace.csv"))?;

    // One evaluation at the truth, split into its relaxation and its measurement.
    let observation = load_observation(&config)?;
    let nodes = observation.tissue.node_count();
    let space = ParameterSpace::from_config(&config.parameters)?;
    let model = ForwardModel::new(
        observation,
        config.base_parameters()?,
        space,
        config.objective.clone(),
        config.forward.clone(),
    )?;
    let params = model.params_at(&[fitted_truth(contact, l_min, bench.ratio).ln()]);
    let (relaxed, relax_wall, relax_cpu) = timed(|| model.relax(&params, &model.observation.tissue, &mut NoObserver));
    let (tissue, summary) = relaxed.map_err(|(e, _)| anyhow::anyhow!("relaxing at the truth: {e}"))?;
    let (measured, measure_wall, measure_cpu) = timed(|| model.measure(&tissue));
    measured.map_err(|e| anyhow::anyhow!("measuring the relaxation at the truth: {e}"))?;

    let r = result.ratios.get(key).with_context(|| format!("the fit reports no {key}"))?;
    let error = (r.value - bench.ratio) / bench.ratio;
    let accurate = error.abs() <= ACCURACY && r.determined == Some(true);
    let node_steps = steps as Real * nodes as Real;
    let value = json!({
        "scenario": "fit",
        "contact_model": if contact == ContactModel::Spring { "spring" } else { "coupling" },
        "cells": bench.cells,
        "nodes": nodes,
        "nodes_per_cell": observed.nodes_per_cell,
        "voxels_per_diameter": bench.voxels_per_diameter,
        "measure_shifts": bench.shifts,
        "threads": rayon::current_num_threads(),
        "ratio": key,
        "truth": bench.ratio,
        "recovered": r.value,
        "error_percent": 100.0 * error,
        "range": r.range,
        "determined": r.determined,
        "accurate": accurate,
        "evaluations": result.evaluations,
        "profile_evaluations": result.profile_evaluations,
        "fit_wall_seconds": fit_wall,
        "fit_cpu_seconds": fit_cpu,
        "truth_wall_seconds": truth_wall,
        "truth_cpu_seconds": truth_cpu,
        "fit_steps": steps,
        "fit_node_steps": node_steps,
        "fit_cpu_microseconds_per_node_step": fit_cpu.map(|c| 1e6 * c / node_steps),
        "evaluation_at_truth": {
            "steps": summary.steps,
            "relax_wall_seconds": relax_wall,
            "relax_cpu_seconds": relax_cpu,
            "relax_cpu_microseconds_per_node_step": relax_cpu.map(|c| 1e6 * c / (summary.steps as Real * nodes as Real)),
            "measure_wall_seconds": measure_wall,
            "measure_cpu_seconds": measure_cpu,
        },
    });
    Ok((value, accurate))
}

/// Total relaxation steps of a fit (its trace's `steps` column; the profile's evaluations included).
fn trace_steps(path: &std::path::Path) -> anyhow::Result<u64> {
    let mut reader = csv::Reader::from_path(path).with_context(|| format!("reading {}", path.display()))?;
    let column = reader
        .headers()?
        .iter()
        .position(|h| h == "steps")
        .with_context(|| format!("{} has no steps column", path.display()))?;
    let mut total = 0;
    for record in reader.records() {
        let record = record?;
        total += record[column]
            .parse::<u64>()
            .with_context(|| format!("{}: steps `{}`", path.display(), &record[column]))?;
    }
    Ok(total)
}

/// A folder of its own under the system's temporary folder, removed with everything in it when
/// dropped (also when the benchmark fails).
struct ScratchDir(std::path::PathBuf);

impl ScratchDir {
    fn new() -> anyhow::Result<Self> {
        let path = std::env::temp_dir().join(format!("tissuefit-bench-fit-{}", std::process::id()));
        // A folder left by an earlier process with the same id (killed before it cleaned up) would
        // hold its trace, which the fit refuses to overwrite.
        if path.exists() {
            std::fs::remove_dir_all(&path).with_context(|| format!("removing the stale {}", path.display()))?;
        }
        std::fs::create_dir_all(&path).with_context(|| format!("creating {}", path.display()))?;
        Ok(Self(path))
    }

    fn path(&self) -> &std::path::Path {
        &self.0
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

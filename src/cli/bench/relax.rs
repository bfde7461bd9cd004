//! `tissuefit bench relax FILE [--config CFG] [--steps N]`: the cost of a relaxation as `simulate`
//! runs it (the same parameters: the config, or the defaults, with the mesh-dependent numerics
//! derived from the input), for N steps, with no output written. Prints one JSON object: wall and
//! CPU seconds, node-steps (force evaluations × nodes), the cost per node-step, and where the time
//! went per stage (coupling, internal forces, contact broad phase with its candidate-list rebuilds,
//! narrow phase, force application, polarity, remeshing; the rest is moving the nodes and
//! bookkeeping), each as seconds per node-step. This is issue 24's scenario benchmark on the
//! 64-cell aggregate (`docs/scripts/profile.sh`).

use super::growth::cpu_seconds;
use crate::geometry::Real;
use crate::io::{ReadOptions, read_tissue};
use crate::mechanics::{ExplicitNumerics, NoObserver, Parameters, Simulation, StageTimes};
use anyhow::Context;
use serde_json::{Value, json};
use std::path::Path;
use std::time::Instant;

/// Runs `steps` steps of the relaxation of `file` with `config` (or the defaults).
pub fn run_relax(file: &Path, config: Option<&Path>, steps: u64) -> anyhow::Result<Value> {
    let tissue =
        read_tissue(file, &ReadOptions::default()).with_context(|| format!("reading {}", file.display()))?.tissue;
    let (mut params, explicit) = match config {
        Some(path) => Parameters::load_explicit(path)?,
        None => (Parameters::default(), ExplicitNumerics::default()),
    };
    params.fit_to_tissue(&explicit, &tissue);
    params.simulation.max_steps = steps;
    params.validate().with_context(|| {
        format!(
            "checking {} with the numerics derived from the input",
            config.map_or("the defaults".into(), |p| p.display().to_string())
        )
    })?;
    let cells = tissue.len();
    let nodes = tissue.node_count();
    let mut sim = Simulation::new(tissue, &params)?;
    let cpu_start = cpu_seconds();
    let started = Instant::now();
    let summary = sim.run(&mut NoObserver)?;
    let wall = started.elapsed().as_secs_f64();
    let cpu = cpu_seconds().zip(cpu_start).map(|(now, start)| now - start);
    let t = sim.stage_times();
    // A fresh run: its counters are this session's, as the stage times are.
    let node_steps = summary.node_evaluations.max(1) as Real;
    let per = |s: Real| s / node_steps;
    Ok(json!({
        "scenario": "relax",
        "file": file.display().to_string(),
        "config": config.map(|p| p.display().to_string()),
        "threads": rayon::current_num_threads(),
        "cells": cells,
        "nodes": nodes,
        "nodes_at_end": sim.tissue().node_count(),
        "steps": summary.steps,
        "force_evaluations": summary.force_evaluations,
        "node_steps": summary.node_evaluations,
        "converged": summary.converged,
        "residual": summary.residual,
        "wall_seconds": wall,
        "cpu_seconds": cpu,
        "seconds_per_node_step": per(wall),
        "cpu_seconds_per_node_step": cpu.map(per),
        "candidate_rebuilds": sim.contacts().candidate_rebuilds,
        "candidate_updates": sim.contacts().candidate_updates,
        "breakdown_seconds_per_node_step": breakdown(&t, wall, node_steps),
    }))
}

/// The stage times of a run per node-step (s), the key `breakdown_seconds_per_node_step` of the
/// relax and growth benchmarks: "moving_and_rest" is the wall time outside the stages (the
/// minimiser's or integrator's update, residuals, bookkeeping; divisions in growth).
pub(super) fn breakdown(t: &StageTimes, wall: Real, node_steps: Real) -> Value {
    let per = |s: Real| s / node_steps.max(1.0);
    json!({
        "coupling": per(t.coupling),
        "internal_forces": per(t.internal),
        "contact_broad": per(t.contact_broad),
        "contact_lists": per(t.contact_lists),
        "contact_narrow": per(t.contact_narrow),
        "contact_apply": per(t.contact_apply),
        "polarity": per(t.polarity),
        "remeshing": per(t.remeshing),
        "moving_and_rest": per((wall - t.total()).max(0.0)),
    })
}

//! `tissuefit bench growth --cells N`: the paper's growth stress test (Fig. 1e). One spherical cell,
//! meshed in code at l_min, grows and divides with the settings of `pipelines/growth.toml` (embedded
//! at build time, so the benchmark and the shipped config cannot drift apart) until the tissue has N
//! cells. Prints one JSON object with the DESIGN.md §2 bench keys, the wall time, steps, nodes and
//! peak memory at each cell-count milestone (2, 4, 8, …, 1000, 2000, 4000, 8000, 10000), the cost
//! per node-step between milestones, and the exponent α of a least-squares fit T ∝ N^α.
//!
//! It never aborts: an unhealthy state (a non-finite force, a folded cell) or any other simulation
//! error ends the run with the JSON naming the step, the cell and the cause (exit code 1), as do
//! the step and wall-time limits.

use crate::geometry::Real;
use crate::mechanics::{ContactModel, Parameters, Simulation, SimulationError};
use crate::mesh::shapes::sphere_for_min_edge;
use crate::mesh::{Cell, CellId, CellKind, Tissue};
use anyhow::Context;
use serde_json::{Value, json};
use std::time::Instant;

/// The benchmark's parameters: `pipelines/growth.toml`.
pub const GROWTH_TOML: &str = include_str!("../../../pipelines/growth.toml");

/// Cell counts at which the benchmark records a milestone.
pub const MILESTONES: [usize; 14] = [2, 4, 8, 16, 32, 64, 128, 256, 500, 1000, 2000, 4000, 8000, 10000];

/// Radius of the initial cell (m): the reference benchmark's 6 µm-diameter sphere (V ≈ 1.13e-16 m³,
/// below the division volume 2e-16 m³ of the benchmark).
pub const INITIAL_RADIUS: Real = 3e-6;

/// What to run.
#[derive(Clone, Debug)]
pub struct GrowthBench {
    pub cells: usize,
    pub contact_model: Option<ContactModel>,
    pub l_min: Option<Real>,
    pub max_steps: u64,
    pub max_seconds: Option<Real>,
}

/// The benchmark parameters with the command-line overrides.
pub fn growth_parameters(contact_model: Option<ContactModel>, l_min: Option<Real>) -> anyhow::Result<Parameters> {
    let mut params = Parameters::from_toml_str(GROWTH_TOML, "pipelines/growth.toml")?;
    if let Some(model) = contact_model {
        params.numerics.contact_model = model;
    }
    if let Some(l) = l_min {
        params.numerics.min_edge_length = l;
        // Keep the reference's cutoff/l_min ratio (0.5/0.6).
        params.numerics.contact_cutoff = l * 5.0 / 6.0;
    }
    params.validate().context("benchmark parameters")?;
    Ok(params)
}

/// Peak resident memory of this process so far (bytes), from `VmHWM` in `/proc/self/status`
/// (Linux); `None` elsewhere.
pub fn peak_memory_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// CPU time (user + system, s) of this process so far, from `/proc/self/stat` (Linux; clock ticks of
/// 1/100 s); `None` elsewhere. On a shared machine it shows how much of the wall time was ours.
pub fn cpu_seconds() -> Option<Real> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name (which is in parentheses and may contain spaces).
    let rest = stat.rsplit_once(')')?.1;
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let ticks = fields.get(11)?.parse::<u64>().ok()? + fields.get(12)?.parse::<u64>().ok()?;
    Some(ticks as Real / 100.0)
}

/// Least-squares slope of ln T against ln N.
fn fit_exponent(points: &[(Real, Real)]) -> Option<Real> {
    if points.len() < 2 {
        return None;
    }
    let n = points.len() as Real;
    let (xs, ys): (Vec<Real>, Vec<Real>) = points.iter().map(|&(x, y)| (x.ln(), y.ln())).unzip();
    let (mx, my) = (xs.iter().sum::<Real>() / n, ys.iter().sum::<Real>() / n);
    let sxx: Real = xs.iter().map(|x| (x - mx).powi(2)).sum();
    let sxy: Real = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}

/// Runs the benchmark; returns the JSON and whether the target was reached.
pub fn run_growth(bench: &GrowthBench) -> anyhow::Result<(Value, bool)> {
    let params = growth_parameters(bench.contact_model, bench.l_min)?;
    let l_min = params.numerics.min_edge_length;
    let mesh = sphere_for_min_edge(INITIAL_RADIUS, l_min).context("meshing the initial sphere")?;
    let initial_nodes = mesh.node_count();
    let tissue = Tissue::from_cells(vec![Cell::new(CellId(1), CellKind::Epithelial, 0, mesh)])?;
    let mut sim = Simulation::new(tissue, &params)?;

    let started = Instant::now();
    let cpu_start = cpu_seconds();
    let cpu = || cpu_seconds().zip(cpu_start).map(|(now, start)| now - start);
    let mut milestones = Vec::new();
    let mut next = MILESTONES.iter().copied().filter(|&m| m <= bench.cells).peekable();
    let (mut node_steps, mut steps) = (0u64, 0u64);
    let (mut last_wall, mut last_node_steps) = (0.0, 0u64);
    let mut outcome: Result<(), String> = Ok(());
    let mut error = Value::Null;
    let result = sim.start();
    if let Err(e) = result {
        error = error_json(&e);
        outcome = Err(format!("unhealthy: {e}"));
    }
    while outcome.is_ok() && sim.tissue().len() < bench.cells {
        if steps >= bench.max_steps {
            outcome = Err(format!("step limit {} reached", bench.max_steps));
            break;
        }
        if bench.max_seconds.is_some_and(|limit| started.elapsed().as_secs_f64() > limit) {
            outcome = Err(format!("wall-time limit {} s reached", bench.max_seconds.unwrap_or_default()));
            break;
        }
        node_steps += sim.tissue().node_count() as u64;
        if let Err(e) = sim.time_step() {
            error = error_json(&e);
            outcome = Err(format!("stopped by the simulation: {e}"));
            break;
        }
        steps += 1;
        let cells = sim.tissue().len();
        while let Some(&m) = next.peek() {
            if cells < m {
                break;
            }
            next.next();
            let wall = started.elapsed().as_secs_f64();
            let nodes = sim.tissue().node_count();
            let since = (node_steps - last_node_steps).max(1) as Real;
            milestones.push(json!({
                "milestone": m,
                "cells": cells,
                "wall_seconds": wall,
                "steps": steps,
                "nodes": nodes,
                "nodes_per_cell": nodes as Real / cells as Real,
                "seconds_per_node_step": (wall - last_wall) / since,
                "cpu_seconds": cpu(),
                "peak_memory_bytes": peak_memory_bytes(),
            }));
            eprintln!(
                "growth: {cells} cells at step {steps}, {wall:.2} s, {nodes} nodes ({:.0} per cell), {:.3} µs per node-step since the last milestone",
                nodes as Real / cells as Real,
                1e6 * (wall - last_wall) / since
            );
            last_wall = wall;
            last_node_steps = node_steps;
        }
    }
    let wall = started.elapsed().as_secs_f64();
    // T ∝ N^α over the milestones from 16 cells on (earlier ones are dominated by the fixed cost of a
    // step with a handful of cells); all milestones when fewer than two reach 16.
    let points = |from: usize| -> Vec<(Real, Real)> {
        milestones
            .iter()
            .filter(|m| m["cells"].as_u64().unwrap_or(0) as usize >= from)
            .map(|m| (m["cells"].as_f64().unwrap_or(1.0), m["wall_seconds"].as_f64().unwrap_or(1.0)))
            .collect()
    };
    let (alpha_from, fit_points) = if points(16).len() >= 2 { (16, points(16)) } else { (2, points(2)) };
    let stats = sim.topology_stats();
    let reached = outcome.is_ok();
    let value = json!({
        "scenario": "growth",
        "threads": rayon::current_num_threads(),
        "cells": sim.tissue().len(),
        "nodes": sim.tissue().node_count(),
        "steps": steps,
        "wall_seconds": wall,
        "seconds_per_node_step": wall / node_steps.max(1) as Real,
        "cpu_seconds": cpu(),
        "peak_memory_bytes": peak_memory_bytes(),
        "target_cells": bench.cells,
        "reached": reached,
        "stop_reason": match &outcome { Ok(()) => "target reached".to_string(), Err(why) => why.clone() },
        "error": error,
        "contact_model": params.numerics.contact_model,
        "l_min": l_min,
        "initial_nodes": initial_nodes,
        "simulated_time": sim.time_and_step().0,
        "node_steps": node_steps,
        "candidate_rebuilds": sim.contacts().candidate_rebuilds,
        "candidate_updates": sim.contacts().candidate_updates,
        "breakdown_seconds_per_node_step": super::relax::breakdown(&sim.stage_times(), wall, node_steps as Real),
        "milestones": milestones,
        "alpha": fit_exponent(&fit_points),
        "alpha_from_cells": alpha_from,
        "alpha_points": fit_points.len(),
        "divisions": stats.divisions,
        "removals": stats.removals,
        "topology": stats,
    });
    Ok((value, reached))
}

/// The step, cell and cause of a simulation error, for the JSON.
fn error_json(e: &SimulationError) -> Value {
    match e {
        SimulationError::Unhealthy { step, cell, what, .. } => {
            json!({"step": step, "cell": cell.0, "what": what, "message": e.to_string()})
        }
        SimulationError::Topology { step, cell, what } => {
            json!({"step": step, "cell": cell.0, "what": what, "message": e.to_string()})
        }
        SimulationError::Remesh { step, .. } | SimulationError::Observer { step, .. } => {
            json!({"step": step, "message": e.to_string()})
        }
        _ => json!({"message": e.to_string()}),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exponent_of_a_power_law_is_recovered() {
        let points: Vec<(Real, Real)> =
            [16.0, 32.0, 64.0, 128.0].iter().map(|&n: &Real| (n, 0.013 * n.powf(1.33))).collect();
        assert!((fit_exponent(&points).unwrap() - 1.33).abs() < 1e-12);
        assert_eq!(fit_exponent(&points[..1]), None);
    }

    #[test]
    fn embedded_config_is_valid_and_the_sphere_is_within_bounds() {
        let params = growth_parameters(None, None).unwrap();
        assert_eq!(params.numerics.contact_model, ContactModel::Coupling);
        let mesh = sphere_for_min_edge(INITIAL_RADIUS, params.numerics.min_edge_length).unwrap();
        assert_eq!(mesh.validate(), Ok(()));
        let stats = mesh.edge_length_stats().unwrap();
        let l = params.numerics.min_edge_length;
        assert!(stats.min >= l && stats.max <= 3.0 * l, "{stats:?}");
    }
}

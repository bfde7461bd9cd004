//! `tissuefit bench SCENARIO`: throughput figures as one JSON object on stdout (DESIGN.md §2).
//!
//! Scenarios:
//! * `forces-cell`: internal-force evaluations of one ~1,000-node spherical cell;
//! * `forces-tissue FILE`: internal-force evaluations and full dynamic steps of a tissue file
//!   (e.g. simucell3d__embryo_1.vtk), no contacts;
//! * `relax-cube`: force evaluations to equilibrium of a cube cell relaxing to a sphere, FIRE vs
//!   overdamped integration.

use super::Outcome;
use crate::geometry::{Real, Vec3};
use crate::io::{ReadOptions, read_tissue};
use crate::mechanics::{
    Dynamics, Observer, Parameters, RelaxMethod, Sample, Simulation, TermSet, TissueForces, cell_parameters,
    integrate_step,
};
use crate::mesh::shapes::{cube_sphere, subdivided_cube};
use crate::mesh::{Cell, CellId, CellKind, FaceType, Tissue};
use anyhow::Context;
use serde_json::json;
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// forces-cell, forces-tissue or relax-cube.
    #[arg(value_parser = ["forces-cell", "forces-tissue", "relax-cube"])]
    pub scenario: String,
    /// Tissue file for forces-tissue.
    pub file: Option<PathBuf>,
    /// Repetitions (force evaluations or steps) per measurement.
    #[arg(long, default_value_t = 200)]
    pub repeat: usize,
}

/// A ~1,000-node sphere: a 13×13-subdivided cube projected onto a 5 µm sphere (1,016 nodes).
fn thousand_node_cell() -> Tissue {
    Tissue::from_cells(vec![Cell::new(CellId(1), CellKind::Epithelial, 0, cube_sphere(5e-6, 13, Vec3::zeros()))])
        .expect("one cell")
}

/// Median of repeated timings of `f`, in seconds.
fn median_seconds(samples: usize, mut f: impl FnMut()) -> Real {
    let mut times: Vec<Real> = (0..samples)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .collect();
    times.sort_by(Real::total_cmp);
    times[times.len() / 2]
}

fn forces_json(
    scenario: &str,
    tissue: &Tissue,
    params: &Parameters,
    repeat: usize,
) -> anyhow::Result<serde_json::Value> {
    let cell_params = cell_parameters(tissue, params)?;
    let nodes = tissue.node_count();
    let mut forces = TissueForces::default();
    forces.compute(tissue, &cell_params, TermSet::ALL);
    let batch = repeat.max(1);
    let force_eval = median_seconds(7, || {
        for _ in 0..batch {
            forces.compute(tissue, &cell_params, TermSet::ALL);
        }
    }) / batch as Real;
    let mut moving = tissue.clone();
    let mut momenta: Vec<Vec<Vec3>> =
        moving.cells().iter().map(|c| vec![Vec3::zeros(); c.mesh().node_count()]).collect();
    let mut numerics = params.numerics.clone();
    numerics.dynamics = Dynamics::Dynamic;
    let full_step = median_seconds(7, || {
        for _ in 0..batch {
            forces.compute(&moving, &cell_params, TermSet::ALL);
            integrate_step(&mut moving, &forces.cells, &cell_params, &mut momenta, &numerics);
        }
    }) / batch as Real;
    let bending_hinges_active =
        cell_params.iter().any(|p| FaceType::ALL.iter().any(|&t| p.faces.get(t).bending_modulus > 0.0));
    Ok(json!({
        "scenario": scenario,
        "threads": rayon::current_num_threads(),
        "cells": tissue.len(),
        "nodes": nodes,
        "steps": batch,
        "wall_seconds": full_step * batch as Real,
        "seconds_per_node_step": full_step / nodes as Real,
        "force_seconds_per_node_evaluation": force_eval / nodes as Real,
        "full_step_seconds_per_node": full_step / nodes as Real,
        "bending_active": bending_hinges_active,
        "terms": "pressure, area elasticity, tension, bending (no contacts)",
    }))
}

struct Quiet;
impl Observer for Quiet {
    fn sample(&mut self, _: &Sample<'_>) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        Ok(())
    }
}

fn relax_cube() -> anyhow::Result<serde_json::Value> {
    let mut params = Parameters::default();
    params.numerics.dynamics = Dynamics::Overdamped;
    params.numerics.damping = 3e-9;
    params.cell_types[0].growth_rate = 0.0;
    params.simulation.sample_every_steps = u64::MAX;
    params.simulation.max_steps = 1_000_000;
    let cube = || {
        Tissue::from_cells(vec![Cell::new(
            CellId(1),
            CellKind::Epithelial,
            0,
            subdivided_cube(8e-6, 10, Vec3::zeros()),
        )])
    };
    let mut results = Vec::new();
    for method in [RelaxMethod::Fire, RelaxMethod::Integrate] {
        params.simulation.method = method;
        let mut sim = Simulation::new(cube()?, &params)?;
        let t = Instant::now();
        let s = sim.run(&mut Quiet)?;
        let wall = t.elapsed().as_secs_f64();
        let m = sim.tissue().cells()[0].mesh();
        results.push((method, s, wall, m.area().powi(3) / m.signed_volume().powi(2), m.node_count()));
    }
    let (fire, od) = (&results[0], &results[1]);
    Ok(json!({
        "scenario": "relax-cube",
        "threads": rayon::current_num_threads(),
        "cells": 1,
        "nodes": fire.4,
        "steps": fire.1.steps,
        "wall_seconds": fire.2,
        "seconds_per_node_step": fire.2 / (fire.1.force_evaluations as Real * fire.4 as Real),
        "fire": {"force_evaluations": fire.1.force_evaluations, "converged": fire.1.converged, "wall_seconds": fire.2, "isoperimetric_ratio": fire.3},
        "overdamped": {"force_evaluations": od.1.force_evaluations, "converged": od.1.converged, "wall_seconds": od.2, "isoperimetric_ratio": od.3},
        "evaluation_ratio": od.1.force_evaluations as Real / fire.1.force_evaluations as Real,
    }))
}

pub fn run(args: &BenchArgs) -> anyhow::Result<Outcome> {
    let params = Parameters::default();
    let value = match args.scenario.as_str() {
        "forces-cell" => forces_json("forces-cell", &thousand_node_cell(), &params, args.repeat)?,
        "forces-tissue" => {
            let file = args.file.as_ref().context("forces-tissue needs a tissue FILE")?;
            let tissue = read_tissue(file, &ReadOptions::default())
                .with_context(|| format!("reading {}", file.display()))?
                .tissue;
            // One parameter set for all cells, whatever their cell_type_id (embryo_1 stores ids there).
            let retyped = Tissue::from_cells(
                tissue.cells().iter().map(|c| Cell::new(c.id(), CellKind::Epithelial, 0, c.mesh().clone())).collect(),
            )?;
            let mut v = forces_json("forces-tissue", &retyped, &params, args.repeat)?;
            v["file"] = json!(file.display().to_string());
            v
        }
        _ => relax_cube()?,
    };
    println!("{}", serde_json::to_string(&value)?);
    Ok(Outcome::Success)
}

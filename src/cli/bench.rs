//! `tissuefit bench SCENARIO`: throughput figures as one JSON object on stdout (DESIGN.md §2).
//!
//! Scenarios:
//! * `forces-cell`: internal-force evaluations of one ~1,000-node spherical cell;
//! * `forces-tissue FILE`: internal-force evaluations and full dynamic steps of a tissue file
//!   (e.g. simucell3d__embryo_1.vtk), no contacts;
//! * `relax-cube`: force evaluations to equilibrium of a cube cell relaxing to a sphere, FIRE vs
//!   overdamped integration;
//! * `contacts-tissue FILE`: a full dynamic step with spring contacts, broken down into internal
//!   forces, broad phase, narrow phase, force application and integration; then the same tissue
//!   replicated on a grid (1, 8, 27, 64 copies) to show how the contact stage scales;
//! * `growth --cells N`: the paper's growth stress test from one cell to N cells (`bench/growth.rs`);
//! * `relax FILE [--config CFG] [--steps N]`: N steps of the relaxation `simulate` would run, with
//!   the time per node-step of each stage (`bench/relax.rs`);
//! * `fit`: the 20-cell aggregate round trip, truth to fitted ratio, with the fit's CPU time and its
//!   accuracy (`bench/fit.rs`).

mod fit;
mod growth;
mod relax;

use super::Outcome;
use crate::geometry::{Real, Vec3};
use crate::io::{ReadOptions, read_tissue};
use crate::mechanics::{
    ContactModel, ContactWorkspace, CouplingWorkspace, Dynamics, NoObserver, Parameters, RelaxMethod, Simulation,
    TermSet, TissueForces, cell_parameters, integrate_step,
};
use crate::mesh::shapes::{cube_sphere, subdivided_cube};
use crate::mesh::{Cell, CellId, CellKind, FaceType, Tissue};
use anyhow::Context;
use serde_json::json;
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// forces-cell, forces-tissue FILE, relax-cube, contacts-tissue FILE, growth, relax FILE or fit.
    #[arg(value_parser = ["forces-cell", "forces-tissue", "relax-cube", "contacts-tissue", "growth", "relax", "fit"])]
    pub scenario: String,
    /// Tissue file for forces-tissue, contacts-tissue and relax.
    pub file: Option<PathBuf>,
    /// relax: the model (a parameter file, as `simulate --config`); default: the built-in defaults,
    /// the mesh-dependent numerics derived from FILE as `simulate` derives them.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// relax: steps to run (simulation.max_steps); the run stops earlier if it converges.
    #[arg(long, default_value_t = 1000)]
    pub steps: u64,
    /// Repetitions (force evaluations or steps) per measurement.
    #[arg(long, default_value_t = 200)]
    pub repeat: usize,
    /// Contact model: spring or coupling (default: spring for contacts-tissue and fit, the config's
    /// coupling for growth).
    #[arg(long, value_parser = ["spring", "coupling"])]
    pub contact_model: Option<String>,
    /// growth: stop when the tissue has this many cells (default 128); fit: cells of the aggregate
    /// (default 20).
    #[arg(long)]
    pub cells: Option<usize>,
    /// growth: minimum edge length l_min in metres (default: pipelines/growth.toml's 6e-7); the
    /// contact cutoff follows at 5/6·l_min.
    #[arg(long)]
    pub l_min: Option<f64>,
    /// growth: give up after this many steps.
    #[arg(long, default_value_t = 200_000)]
    pub max_steps: u64,
    /// growth: give up after this many seconds of wall time.
    #[arg(long)]
    pub max_seconds: Option<f64>,
    /// fit: the truth's key ratio, w/(2γ) for spring contacts (default 0.2), γ_lateral/γ_apical for
    /// coupling (default 0.5).
    #[arg(long)]
    pub ratio: Option<f64>,
    /// fit: voxels per mean cell diameter of the observed label volume.
    #[arg(long, default_value_t = 10.0)]
    pub voxels_per_diameter: f64,
    /// fit: target nodes per cell of the meshing (observed and initial aggregate).
    #[arg(long, default_value_t = 150)]
    pub nodes: usize,
    /// fit: Nelder–Mead evaluations (the profile's come on top).
    #[arg(long, default_value_t = 14)]
    pub evaluations: usize,
    /// fit: sub-voxel shifts each like-data measurement averages over (forward.measure_shifts).
    #[arg(long, default_value_t = 8)]
    pub shifts: usize,
}

fn contact_model(name: Option<&str>) -> Option<ContactModel> {
    name.map(|n| if n == "coupling" { ContactModel::Coupling } else { ContactModel::Spring })
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

fn relax_cube() -> anyhow::Result<serde_json::Value> {
    // l_min = 0.3 µm so that the cube's 0.8 µm edges lie within [l_min, 3·l_min] for remeshing.
    let mut params = Parameters::default();
    params.numerics.dynamics = Dynamics::Overdamped;
    params.numerics.damping = 3e-9;
    params.numerics.min_edge_length = 3e-7;
    params.numerics.contact_cutoff = 3e-7;
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
    let mut runs = serde_json::Map::new();
    let mut evaluations = Vec::new();
    let mut first = None;
    for (name, method, remesh) in [
        ("fire", RelaxMethod::Fire, 0),
        ("overdamped", RelaxMethod::Integrate, 0),
        ("fire_remesh50", RelaxMethod::Fire, 50),
        ("overdamped_remesh50", RelaxMethod::Integrate, 50),
    ] {
        params.simulation.method = method;
        params.simulation.remesh_every_steps = remesh;
        let mut sim = Simulation::new(cube()?, &params)?;
        let t = Instant::now();
        let s = sim.run(&mut NoObserver)?;
        let wall = t.elapsed().as_secs_f64();
        let m = sim.tissue().cells()[0].mesh();
        first.get_or_insert((s.steps, wall, m.node_count(), s.force_evaluations));
        evaluations.push(s.force_evaluations as Real);
        runs.insert(
            name.to_string(),
            json!({"force_evaluations": s.force_evaluations, "converged": s.converged, "wall_seconds": wall,
                   "nodes": m.node_count(), "isoperimetric_ratio": m.area().powi(3) / m.signed_volume().powi(2)}),
        );
    }
    let (steps, wall, nodes, evals) = first.expect("four runs");
    Ok(json!({
        "scenario": "relax-cube",
        "threads": rayon::current_num_threads(),
        "cells": 1,
        "nodes": nodes,
        "steps": steps,
        "wall_seconds": wall,
        "seconds_per_node_step": wall / (evals as Real * nodes as Real),
        "runs": runs,
        "evaluation_ratio_overdamped_over_fire": evaluations[1] / evaluations[0],
        "evaluation_ratio_with_remeshing": evaluations[3] / evaluations[2],
        "evaluation_ratio_overdamped_over_fire_with_remeshing": evaluations[1] / evaluations[2],
    }))
}

/// `copies`³ translated copies of `tissue` on a grid with 10 % gaps, every cell epithelial with
/// parameter set 0 and a fresh id.
fn replicate(tissue: &Tissue, copies: usize) -> anyhow::Result<Tissue> {
    let all: Vec<Vec3> = tissue.cells().iter().flat_map(|c| c.mesh().positions().iter().copied()).collect();
    let (lo, hi) = crate::geometry::bounding_box(&all).context("empty tissue")?;
    let step = 1.1 * (hi - lo);
    let mut out = Tissue::new();
    for i in 0..copies.pow(3) {
        let shift = Vec3::new((i % copies) as Real, ((i / copies) % copies) as Real, (i / (copies * copies)) as Real)
            .component_mul(&step);
        for c in tissue.cells() {
            let mut mesh = c.mesh().clone();
            mesh.positions_mut().iter_mut().for_each(|p| *p += shift);
            let id = out.allocate_id();
            out.push(Cell::new(id, CellKind::Epithelial, 0, mesh))?;
        }
    }
    Ok(out)
}

/// Median wall times (s) of the phases of a dynamic step with contacts.
fn contact_step_times(
    tissue: &Tissue,
    params: &Parameters,
    repeat: usize,
) -> anyhow::Result<(serde_json::Value, usize)> {
    let cell_params = cell_parameters(tissue, params)?;
    let mut forces = TissueForces::default();
    let mut contacts = ContactWorkspace::default();
    contacts.set_model(params.numerics.contact_model);
    contacts.set_quadrature(params.numerics.contact_quadrature);
    let coupled = params.numerics.contact_model == ContactModel::Coupling;
    let mut coupling = CouplingWorkspace::default();
    let mut moving = tissue.clone();
    let mut momenta: Vec<Vec<Vec3>> =
        moving.cells().iter().map(|c| vec![Vec3::zeros(); c.mesh().node_count()]).collect();
    let mut samples: Vec<[Real; 6]> = Vec::new();
    let mut pairs = 0;
    let mut coupled_pairs = 0;
    for _ in 0..repeat.max(3) {
        let t = Instant::now();
        if coupled {
            coupled_pairs = coupling.couple(
                &mut moving,
                &cell_params,
                params.numerics.contact_cutoff,
                params.numerics.coupling_junctions,
                params.numerics.coupling_persistent_junctions,
            );
        }
        let couple = t.elapsed().as_secs_f64();
        let t = Instant::now();
        forces.compute(&moving, &cell_params, TermSet::ALL);
        let internal = t.elapsed().as_secs_f64();
        contacts.add_contacts(&moving, &cell_params, params.numerics.contact_cutoff, &mut forces.cells);
        pairs = contacts.pair_count;
        let t = Instant::now();
        if coupled {
            coupling.average_forces(&moving, &mut forces.cells);
            coupling.average_momenta(&moving, &mut momenta);
        }
        integrate_step(&mut moving, &forces.cells, &cell_params, &mut momenta, &params.numerics);
        let integrate = t.elapsed().as_secs_f64();
        let ct = contacts.timings;
        samples.push([
            internal,
            ct.broad.as_secs_f64(),
            ct.narrow.as_secs_f64(),
            ct.apply.as_secs_f64(),
            integrate,
            couple,
        ]);
    }
    let nodes = tissue.node_count() as Real;
    let median = |k: usize| {
        let mut v: Vec<Real> = samples.iter().map(|s| s[k]).collect();
        v.sort_by(Real::total_cmp);
        v[v.len() / 2] / nodes
    };
    let parts = [median(0), median(1), median(2), median(3), median(4), median(5)];
    Ok((
        json!({
            "cells": tissue.len(),
            "nodes": tissue.node_count(),
            "pairs": pairs,
            "seconds_per_node_step": parts.iter().sum::<Real>(),
            "internal_forces": parts[0],
            "broad_phase": parts[1],
            "narrow_phase": parts[2],
            "apply_contacts": parts[3],
            "integration": parts[4],
            "node_coupling": parts[5],
            "coupled_pairs": coupled_pairs,
            "candidate_rebuilds": contacts.candidate_rebuilds,
            "contact_stage": parts[1] + parts[2] + parts[3] + parts[5],
        }),
        pairs,
    ))
}

fn contacts_json(file: &std::path::Path, repeat: usize, model: ContactModel) -> anyhow::Result<serde_json::Value> {
    let tissue =
        read_tissue(file, &ReadOptions::default()).with_context(|| format!("reading {}", file.display()))?.tissue;
    let mut params = Parameters::default();
    params.numerics.contact_model = model;
    let base = replicate(&tissue, 1)?;
    let t = Instant::now();
    let (one, _) = contact_step_times(&base, &params, repeat)?;
    let wall = t.elapsed().as_secs_f64();
    let mut scaling = Vec::new();
    for copies in [1, 2, 3, 4] {
        let big = replicate(&tissue, copies)?;
        let (v, _) = contact_step_times(&big, &params, 3)?;
        scaling.push(v);
    }
    Ok(json!({
        "scenario": "contacts-tissue",
        "file": file.display().to_string(),
        "threads": rayon::current_num_threads(),
        "cells": base.len(),
        "nodes": base.node_count(),
        "steps": repeat.max(3),
        "wall_seconds": wall,
        "seconds_per_node_step": one["seconds_per_node_step"],
        "contact_model": model,
        "breakdown_seconds_per_node_step": one,
        "scaling": scaling,
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
            let retyped = replicate(&tissue, 1)?;
            let mut v = forces_json("forces-tissue", &retyped, &params, args.repeat)?;
            v["file"] = json!(file.display().to_string());
            v
        }
        "contacts-tissue" => {
            let file = args.file.as_ref().context("contacts-tissue needs a tissue FILE")?;
            let model = contact_model(args.contact_model.as_deref()).unwrap_or(ContactModel::Spring);
            contacts_json(file, args.repeat.min(20), model)?
        }
        "growth" => {
            let bench = growth::GrowthBench {
                cells: args.cells.unwrap_or(128),
                contact_model: contact_model(args.contact_model.as_deref()),
                l_min: args.l_min,
                max_steps: args.max_steps,
                max_seconds: args.max_seconds,
            };
            let (value, reached) = growth::run_growth(&bench)?;
            println!("{}", serde_json::to_string(&value)?);
            return Ok(if reached { Outcome::Success } else { Outcome::CheckFailed });
        }
        "fit" => {
            let contact_model = contact_model(args.contact_model.as_deref()).unwrap_or(ContactModel::Spring);
            let bench = fit::FitBench {
                contact_model,
                ratio: args.ratio.unwrap_or(if contact_model == ContactModel::Spring { 0.2 } else { 0.5 }),
                cells: args.cells.unwrap_or(20),
                nodes: args.nodes,
                voxels_per_diameter: args.voxels_per_diameter,
                evaluations: args.evaluations,
                shifts: args.shifts,
            };
            let (value, accurate) = fit::run_fit_bench(&bench)?;
            println!("{}", serde_json::to_string(&value)?);
            return Ok(if accurate { Outcome::Success } else { Outcome::CheckFailed });
        }
        "relax" => {
            let file = args.file.as_ref().context("relax needs a tissue FILE")?;
            relax::run_relax(file, args.config.as_deref(), args.steps)?
        }
        _ => relax_cube()?,
    };
    println!("{}", serde_json::to_string(&value)?);
    Ok(Outcome::Success)
}

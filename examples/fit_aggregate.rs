//! The fit's acceptance round trip on an aggregate (issue 8; README "Fitting parameters"): a
//! 20-cell aggregate is relaxed with known tensions/adhesion, voxelised at a given number of voxels
//! per cell diameter, and fitted from that label volume alone (mesh → measure → fit). Prints one
//! JSON line with the truth, the recovered key ratio, its error, the evaluations and the wall time.
//!
//! ```text
//! cargo run --release --example fit_aggregate -- coupling 0.5 10      # γ_lateral/γ_apical = 0.5
//! cargo run --release --example fit_aggregate -- spring 0.2 10        # w/(2γ) = ω·c²/(4γ) = 0.2
//! ```
//!
//! Spring truths are searched within w/(2γ) ∈ [0.05, 0.3]: at w/(2γ) = 0.3 the spring aggregate
//! does not relax but crumples (mean sphericity 0.84 → 0.64 in 1500 FIRE steps, cells interpenetrating),
//! while 0.15 and 0.2 settle (0.93–0.95, flat from step 500 to 3000).
//!
//! Arguments: contact model (`coupling` or `spring`), the true key ratio, voxels per cell diameter,
//! and optionally the cells (default 20), the nodes per cell (default 150), the evaluation budget
//! (default 14) and an output folder (default: a temporary one). The model, the aggregate, the
//! truth's relaxation (6,000 steps, the last 1,000 on a fixed mesh) and the fit config are
//! `tests/integration/support/round_trip.rs`; `tests/slow/fit_round_trips.rs` runs one spring round trip of this example in CI.
//!
//! Options: `--shifts N` sets `forward.measure_shifts` (default 8: the like-data measurement averaged
//! over 8 sub-voxel shifts); `--probe F1,F2,…` evaluates the forward model at truth × each factor
//! instead of fitting and prints, per factor, one JSON line (residual history, remeshing counts,
//! metrics measured directly and like the data, the like-data metrics of the shape moved rigidly by
//! fractions of a voxel, objective): the noise study of README "Forward-model noise of spring
//! contacts"; `--from-initial` starts those probes from the truth's initial tissue instead of the
//! observed one.

use std::path::PathBuf;
use std::time::Instant;
use tissuefit::geometry::{Real, Vec3};
use tissuefit::inference::{FitConfig, FitOptions, run_fit};
use tissuefit::mechanics::{ContactModel, Observer, Sample};
use tissuefit::mesh::Tissue;

#[path = "../tests/integration/support/round_trip.rs"]
mod round_trip;
use round_trip::{
    AGGREGATE_GAMMA as GAMMA, aggregate_fit_config, aggregate_model, aggregate_truth, fitted_truth, initial_aggregate,
    observe_aggregate,
};

fn main() {
    // On a worker of the pool, as the CLI runs: its parallel loops then start by work stealing.
    tissuefit::on_pool(run);
}

fn run() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    // `--probe F1,F2,…`: instead of fitting, evaluate the forward model at truth × each factor and
    // print what each relaxation did (the noise study of README "Fitting parameters").
    let probe: Option<Vec<Real>> = args.iter().position(|a| a == "--probe").map(|i| {
        let list = args.get(i + 1).cloned().unwrap_or_default();
        args.drain(i..(i + 2).min(args.len()));
        list.split(',').map(|f| f.parse().expect("--probe takes comma-separated factors")).collect()
    });
    // `--from-initial`: probes relax from the truth's initial tissue (its path) instead of the observed one.
    let probe_from_initial = args.iter().position(|a| a == "--from-initial").map(|i| args.remove(i)).is_some();
    let shifts: usize = args.iter().position(|a| a == "--shifts").map_or(8, |i| {
        let n = args.get(i + 1).and_then(|v| v.parse().ok()).expect("--shifts takes a count");
        args.drain(i..i + 2);
        n
    });
    let usage = "usage: fit_aggregate coupling|spring RATIO VOXELS_PER_DIAMETER [CELLS [NODES [BUDGET [OUT]]]]";
    if args.len() < 3 {
        eprintln!("{usage}");
        std::process::exit(2);
    }
    let contact = match args[0].as_str() {
        "coupling" => ContactModel::Coupling,
        "spring" => ContactModel::Spring,
        other => {
            eprintln!("unknown contact model `{other}`; {usage}");
            std::process::exit(2);
        }
    };
    let num = |i: usize, default: Real| -> Real {
        args.get(i).map_or(default, |s| {
            s.parse().unwrap_or_else(|_| {
                eprintln!("argument {} `{s}` is not a number; {usage}", i + 1);
                std::process::exit(2)
            })
        })
    };
    let ratio = num(1, 0.5);
    let vpd = num(2, 10.0);
    let cells = num(3, 20.0) as usize;
    let nodes = num(4, 150.0) as usize;
    let budget = num(5, 14.0) as usize;
    let temp = tempfile::tempdir().expect("temporary folder");
    let dir: PathBuf = args.get(6).map_or_else(|| temp.path().to_path_buf(), PathBuf::from);
    std::fs::create_dir_all(&dir).expect("output folder");

    let started = Instant::now();
    let (initial, l_min) = initial_aggregate(cells, nodes);
    let (truth, ratio_name) = aggregate_truth(contact, l_min, ratio);
    let observed = observe_aggregate(&dir, &truth, &initial, vpd);
    eprintln!(
        "truth: {} steps, residual {:.3e}, {:.0} nodes per cell, diameter {:.3} µm, voxel {:.3} µm, {} overlapping voxels",
        observed.summary.steps,
        observed.summary.residual,
        observed.nodes_per_cell,
        observed.diameter * 1e6,
        observed.voxel * 1e6,
        observed.overlapping_voxels
    );
    let (diameter, overlapping) = (observed.diameter, observed.overlapping_voxels);
    let truth_seconds = started.elapsed().as_secs_f64();
    let base = aggregate_model(contact, l_min, GAMMA, 0.0);
    std::fs::write(dir.join("model.toml"), base.to_toml_string()).expect("model.toml");
    let config = aggregate_fit_config(contact, l_min, nodes, budget, shifts);
    std::fs::write(dir.join("fit.toml"), config).expect("fit.toml");
    let config = FitConfig::load(&dir.join("fit.toml")).expect("fit config");
    if let Some(factors) = probe {
        let truth_x = fitted_truth(contact, l_min, ratio).ln();
        probe_noise(&config, truth_x, &factors, probe_from_initial.then_some(&initial));
        return;
    }
    let result = run_fit(&config, &dir.join("out"), &FitOptions { plots: true, ..Default::default() }).expect("fit");
    let r = &result.ratios[ratio_name];
    let error = (r.value - ratio) / ratio;
    let line = serde_json::json!({
        "contact_model": args[0],
        "cells": cells,
        "nodes_per_cell": nodes,
        "voxels_per_diameter": vpd,
        "diameter_um": diameter * 1e6,
        "truth_overlapping_voxels": overlapping,
        "ratio": ratio_name,
        "truth": ratio,
        "recovered": r.value,
        "error_percent": 100.0 * error,
        "range": r.range,
        "determined": r.determined,
        "evaluations": result.evaluations,
        "profile_evaluations": result.profile_evaluations,
        "converged": result.converged,
        "fit_wall_seconds": result.wall_seconds,
        "truth_wall_seconds": truth_seconds,
        "threads": result.threads,
        "observed": result.observed,
        "best": result.best_metrics,
    });
    println!("{line}");
}

/// Records the residual every step and the directly measured metrics at every sample.
struct Recorder {
    delta: Real,
    residuals: Vec<Real>,
    samples: Vec<(u64, Real, Real, Real)>,
}

impl Observer for Recorder {
    fn sample(&mut self, s: &Sample<'_>) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        let (m, _) = tissuefit::inference::Metrics::measure(s.tissue, Some(self.delta))?;
        self.samples.push((
            s.step,
            s.residual,
            m.sphericity.unwrap_or(Real::NAN),
            m.contact_fraction.unwrap_or(Real::NAN),
        ));
        Ok(())
    }
    fn progress(&mut self, _step: u64, residual: Real) {
        self.residuals.push(residual);
    }
}

/// Runs the forward model's passes at exp(truth_x)·factor with a recording observer and prints, per
/// factor, the residual history, the topology counts, the direct and the like-data metrics.
fn probe_noise(config: &FitConfig, truth_x: Real, factors: &[Real], from: Option<&Tissue>) {
    use tissuefit::inference::{ForwardModel, ParameterSpace, load_observation};
    let observation = load_observation(config).expect("observation");
    let space = ParameterSpace::from_config(&config.parameters).expect("space");
    let base = config.base_parameters().expect("model");
    let model = ForwardModel::new(observation, base, space, config.objective.clone(), config.forward.clone())
        .expect("forward model");
    let delta = model.observation.contact_distance;
    eprintln!("observed {:?}, delta {:.4} um", model.observation.metrics, delta * 1e6);
    for &f in factors {
        let x = vec![truth_x + f.ln()];
        let mut params = model.space.apply(&model.base, &x);
        params.simulation.sample_every_steps = 250;
        let started = Instant::now();
        let mut rec = Recorder { delta, residuals: Vec::new(), samples: Vec::new() };
        let start = match from {
            Some(initial) => {
                let ids = |t: &Tissue| t.cells().iter().map(|c| c.id()).collect::<Vec<_>>();
                assert_eq!(ids(initial), ids(&model.observation.tissue), "cells in the same order");
                initial
            }
            None => &model.observation.tissue,
        };
        let (tissue, summary) = model.relax(&params, start, &mut rec).expect("relaxation");
        let like = model.measure(&tissue);
        let n = rec.residuals.len();
        let tail = &rec.residuals[n.saturating_sub(500)..];
        let (tmin, tmax) = tail.iter().fold((Real::INFINITY, 0.0 as Real), |(a, b), &r| (a.min(r), b.max(r)));
        let (direct, _) = tissuefit::inference::Metrics::measure(&tissue, Some(delta)).expect("measure");
        // The like-data measurement of the same shape rigidly shifted by fractions of a voxel.
        let voxel = model.observation.labels.as_ref().map_or(0.0, |l| l.voxel_size()[0]);
        let shifted: Vec<(Real, Real)> = [0.125, 0.25, 0.375, 0.5, 0.625, 0.75]
            .iter()
            .filter_map(|&f| {
                let mut t = tissue.clone();
                let offset = Vec3::new(f, 0.7 * f, 0.4 * f) * voxel;
                for c in t.cells_mut() {
                    for p in c.positions_mut() {
                        *p += offset;
                    }
                }
                model
                    .measure(&t)
                    .ok()
                    .map(|m| (m.sphericity.unwrap_or(Real::NAN), m.contact_fraction.unwrap_or(Real::NAN)))
            })
            .collect();
        let line = serde_json::json!({
            "factor": f,
            "x_bits": format!("{:016x}", x[0].to_bits()),
            "converged": summary.converged,
            "steps": summary.steps,
            "residual": summary.residual,
            "residual_last500_min_max": [tmin, tmax],
            "topology_last_relaxation": summary.topology,
            "direct": direct,
            "like_data": like.as_ref().ok(),
            "like_data_error": like.as_ref().err(),
            "objective": like.as_ref().map(|m| model.score(m)).ok(),
            "like_data_shifted_sph_phi": shifted,
            "samples_step_residual_sph_phi": rec.samples,
            "nodes_per_cell": tissue.node_count() as Real / tissue.len() as Real,
            "observed_nodes_per_cell": model.observation.tissue.node_count() as Real / tissue.len() as Real,
            "wall_seconds": started.elapsed().as_secs_f64(),
        });
        println!("{line}");
    }
}

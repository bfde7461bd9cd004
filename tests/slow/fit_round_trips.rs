//! The slow half of the inference round trip (DESIGN.md §6), in the slow test binary: the doublet
//! round trips for two coupling truths (with an exact resume) and spring adhesion, and the 20-cell
//! aggregate fits from label volumes, and the same seed giving the same trace on 1 and 2 threads. Minutes each on 2 cores: `cargo test --release --test slow
//! fit_round_trips::`; `.ci/run` runs them. The fast fit checks are tests/integration/fit.rs.

use std::path::Path;
use tissuefit::geometry::Real;
use tissuefit::imaging::{LabelPattern, LabelSpec, generate_labels};
use tissuefit::inference::{FitConfig, FitOptions, FitResult, read_trace, run_fit};
use tissuefit::mechanics::ContactModel;
use tissuefit::meshing::{LabelMeshingOptions, mesh_labels};

use crate::support::round_trip;
use round_trip::{AGGREGATE_GAMMA, aggregate_fit_config, aggregate_model, initial_aggregate, observe_aggregate};

use crate::support::fit_doublet::*;

#[test]
fn round_trip_recovers_the_coupling_tension_ratio_for_two_truths_and_resumes_exactly() {
    for (k, ratio) in [0.4, 0.7].into_iter().enumerate() {
        let case = Case {
            contact: ContactModel::Coupling,
            truth: (1e-3, ratio * 1e-3, 0.0),
            parameters: COUPLING,
            ratio: "lateral_over_apical",
        };
        let dir = tempfile::tempdir().unwrap();
        let (result, out) = round_trip(&case, dir.path());
        check(&case, &result);
        assert!(
            out.join("result.json").exists()
                && out.join("objective.png").exists()
                && out.join("landscape.png").exists()
        );
        if k == 0 {
            resumes_exactly(dir.path(), &out, &result);
        }
    }
}

/// A fit interrupted after k evaluations (its trace cut there) and resumed ends with the same trace
/// and result as the uninterrupted one.
fn resumes_exactly(dir: &Path, out: &Path, full: &FitResult) {
    let config = FitConfig::load(&dir.join("fit.toml")).unwrap();
    let space = tissuefit::inference::ParameterSpace::from_config(&config.parameters).unwrap();
    let trace = read_trace(&out.join("trace.csv"), &space).unwrap();
    let k = full.evaluations.saturating_sub(3).max(1);
    let text = std::fs::read_to_string(out.join("trace.csv")).unwrap();
    let cut: Vec<&str> = text.lines().take(k + 1).collect();
    let resumed_dir = dir.join("resumed");
    std::fs::create_dir_all(&resumed_dir).unwrap();
    std::fs::write(resumed_dir.join("trace.csv"), cut.join("\n") + "\n").unwrap();
    let resumed = fit(&dir.join("fit.toml"), &resumed_dir, true);
    assert_eq!(resumed.simulated_here, trace.len() - k, "only the evaluations after the cut are simulated");
    // The wall time goes on from the earlier session's last recorded row.
    let before = trace[k - 1].elapsed_seconds;
    assert!(before > 0.0, "the trace records the fit's elapsed time: {before}");
    assert!(
        resumed.wall_seconds >= before + resumed.session_wall_seconds
            && resumed.wall_seconds < before + resumed.session_wall_seconds + 1.0,
        "wall_seconds {} counts only this session ({} s; earlier {before} s)",
        resumed.wall_seconds,
        resumed.session_wall_seconds
    );
    let again = read_trace(&resumed_dir.join("trace.csv"), &space).unwrap();
    assert_eq!(again.len(), trace.len());
    for (a, b) in trace.iter().zip(&again) {
        assert_eq!(a.x, b.x);
        assert_eq!(a.objective.to_bits(), b.objective.to_bits());
    }
    assert_eq!(resumed.evaluations, full.evaluations);
    assert_eq!(resumed.objective.to_bits(), full.objective.to_bits());
    for (name, p) in &full.parameters {
        assert_eq!(p.si.to_bits(), resumed.parameters[name].si.to_bits(), "{name}");
    }
}

/// A spring doublet's sphericity moves so little with the adhesion that the acceptable range of the
/// truth 0.3 spans w/(2γ) 0.12–0.38 at 12 voxels per diameter, so its fit is set by the forward
/// model's noise: changes that should not matter moved the recovered value of the truth 0.3 between
/// −12.8 % and +16.5 % (remeshing at the last step or not, each part of the volume treatment, normal
/// relaxation; the code before them gave −0.4 %; see README "Fitting parameters"). What
/// must hold is that the fit says so: it recovers the ratio within 10 % and reports it determined with
/// a range holding the truth, or it reports it NOT determined, still with an acceptable range that
/// holds the truth. Truth and fit use the face quadrature with c = l_min / 2.4, and each truth is
/// checked against Young–Dupré before the fit runs ([`truth_follows_young_dupre`]), so the ratio
/// recovered is w/(2γ) in the Young–Dupré sense. The acceptance test of spring
/// contacts is the aggregate (`aggregate_round_trip_recovers_spring_adhesion_over_tension_within_10_percent`),
/// whose ~60 contacts determine it.
///
/// CI runs the weak adhesion 0.3 (reported NOT determined when measured); the strong one, 0.45
/// (determined, +1.3 %), is [`study_spring_doublet_round_trip_at_strong_adhesion`], left out of CI
/// for time (each case costs a 16,000-step truth and a fit, minutes on 2 cores).
#[test]
fn round_trip_of_a_spring_doublet_recovers_the_adhesion_or_reports_it_undetermined() {
    spring_doublet_round_trip(0.3);
}

/// The spring doublet round trip at w/(2γ) = 0.45, the figure of docs/src/validation/fitting.md (a
/// study, skipped by CI: `cargo test --release --test integration -- --ignored --nocapture fit::study_spring`).
#[test]
#[ignore = "study for the docs, minutes: run with --ignored study_spring (CI skips study_*)"]
fn study_spring_doublet_round_trip_at_strong_adhesion() {
    spring_doublet_round_trip(0.45);
}

/// [`round_trip_of_a_spring_doublet_recovers_the_adhesion_or_reports_it_undetermined`] at the truth
/// w/(2γ) = `w_over_2g`.
fn spring_doublet_round_trip(w_over_2g: Real) {
    let (_, l_min) = initial_doublet();
    // w/(2γ) = ω·c²/(4γ).
    let c = spring_cutoff(l_min);
    let omega = w_over_2g * 4.0 * 1e-3 / (c * c);
    let case = Case {
        contact: ContactModel::Spring,
        truth: (1e-3, 1e-3, omega),
        parameters: SPRING,
        ratio: "adhesion_energy_over_tension",
    };
    let dir = tempfile::tempdir().unwrap();
    let (result, _) = round_trip(&case, dir.path());
    let r = &result.ratios[case.ratio];
    match r.determined {
        Some(true) => {
            check(&case, &result);
            let [lo, hi] = r.range;
            assert!(lo <= w_over_2g && w_over_2g <= hi, "determined range [{lo}, {hi}] misses the truth {w_over_2g}");
        }
        _ => {
            let error = recovery_error(&case, &result);
            eprintln!("w/(2γ) = {w_over_2g}: reported NOT determined ({:+.1} %)", 100.0 * error);
            let [lo, hi] = r.range;
            assert!(lo <= w_over_2g && w_over_2g <= hi, "acceptable range [{lo}, {hi}] misses the truth {w_over_2g}");
            assert!(
                result.identifiability.iter().any(|line| line.contains("NOT determined")),
                "an undetermined ratio must be reported in plain words: {:?}",
                result.identifiability
            );
        }
    }
}

/// The docs' resolution figures (docs/src/validation/fitting.md): recovery error at 10 and 20 voxels
/// per cell diameter, both contact models. A study that prints, skipped by CI (minutes): run with
/// `cargo test --release --test integration -- --ignored --nocapture fit::study_resolution`.
#[test]
#[ignore = "study for the docs, minutes: run with --ignored study_resolution (CI skips study_*)"]
fn study_resolution_10_vs_20_voxels_per_diameter() {
    let (_, l_min) = initial_doublet();
    let cases = [
        Case {
            contact: ContactModel::Coupling,
            truth: (1e-3, 0.5e-3, 0.0),
            parameters: COUPLING,
            ratio: "lateral_over_apical",
        },
        Case {
            contact: ContactModel::Spring,
            truth: (1e-3, 1e-3, 0.35 * 4.0 * 1e-3 / spring_cutoff(l_min).powi(2)),
            parameters: SPRING,
            ratio: "adhesion_energy_over_tension",
        },
    ];
    for case in &cases {
        for vpd in [10.0, 20.0] {
            let dir = tempfile::tempdir().unwrap();
            let (result, _) = round_trip_at(case, dir.path(), vpd);
            let error = recovery_error(case, &result);
            eprintln!("RESOLUTION {:?} {vpd} voxels per diameter: error {:.1} %", case.contact, 100.0 * error);
        }
    }
}

/// The aggregate round trip's forward model in CI (the full fits, two truths, 10 and 20 voxels per
/// diameter, are `examples/fit_aggregate.rs`, minutes each): a 20-cell coupled aggregate relaxed with
/// γ_l/γ_a = 0.7, voxelised at 10 voxels per diameter and seen only as labels. Measured like the data
/// with the observed δ, the objective (sphericity + contact-area fraction) is lowest at the truth
/// among truth ÷ 1.3, truth, truth × 1.3, and φ falls as γ_l rises (less spreading): the aggregate's
/// morphology brackets the ratio on both sides.
#[test]
fn aggregate_objective_brackets_the_true_tension_ratio_from_the_label_volume() {
    use tissuefit::inference::{ForwardModel, ParameterSpace, load_observation};
    let spec = LabelSpec {
        pattern: LabelPattern::Aggregate,
        shape: [40, 40, 40],
        voxel_size: [0.4e-6; 3],
        cells: 20,
        seed: 2,
        lumen: false,
    };
    let labels = generate_labels(&spec).unwrap();
    let meshed = mesh_labels(&labels.volume, &LabelMeshingOptions { target_nodes: 150, ..Default::default() }).unwrap();
    assert_eq!(meshed.tissue.len(), 20);
    let l_min = meshed.l_min.unwrap();
    let dir = tempfile::tempdir().unwrap();
    let truth = model(ContactModel::Coupling, l_min, 1e-3, 0.7e-3, 0.0);
    observed_labels_after(dir.path(), &truth, &meshed.tissue, 10.0, 3000);
    let config = write_config(
        dir.path(),
        &model(ContactModel::Coupling, l_min, 1e-3, 1e-3, 0.0),
        COUPLING,
        "method = \"nelder_mead\"\nmax_evaluations = 3",
        0,
    );
    let mut config = FitConfig::load(&config).unwrap();
    config.observed.as_mut().unwrap().meshing.target_nodes = 150;
    config.objective.contact_fraction = 1.0;
    config.forward.max_steps = Some(600);
    config.forward.volume_passes = 1;
    let space = ParameterSpace::from_config(&config.parameters).unwrap();
    let observation = load_observation(&config).unwrap();
    assert_eq!(observation.cell_labels.len(), 20, "every cell of the observed labels meshed");
    let m = ForwardModel::new(
        observation,
        config.base_parameters().unwrap(),
        space,
        config.objective.clone(),
        config.forward.clone(),
    )
    .unwrap();
    let points: Vec<Vec<Real>> = [0.7e-3 / 1.3, 0.7e-3, 0.7e-3 * 1.3].iter().map(|g: &Real| vec![g.ln()]).collect();
    let evals: Vec<_> = {
        use rayon::prelude::*;
        points.par_iter().map(|x| m.evaluate(x)).collect()
    };
    for e in &evals {
        eprintln!(
            "γ_l = {:.3e}: {} objective {:.3} {:?} ({} steps, {:.1} s) {}",
            e.x[0].exp(),
            e.status.name(),
            e.objective,
            e.metrics,
            e.steps,
            e.wall_seconds,
            e.reason
        );
        assert!(e.status.usable(), "{}", e.reason);
    }
    eprintln!("observed {:?}", m.observation.metrics);
    let (low, mid, high) = (&evals[0], &evals[1], &evals[2]);
    assert!(mid.objective < low.objective && mid.objective < high.objective);
    let phi = |e: &tissuefit::inference::Evaluation| e.metrics.contact_fraction.unwrap();
    assert!(phi(low) > phi(mid) && phi(mid) > phi(high), "φ: {} {} {}", phi(low), phi(mid), phi(high));
}

/// The acceptance round trip on an aggregate, in CI (the four spring and the coupling cases of the
/// README are `examples/fit_aggregate.rs`): 20 spring cells relaxed with w/(2γ) = ωc²/(4γ) = 0.2
/// (moving along their normals, settling on a fixed mesh), voxelised at 10 voxels per diameter;
/// the fit sees only the labels (meshed, measured like the data over 8 sub-voxel shifts, 14
/// Nelder–Mead evaluations) and must recover w/(2γ) within 10 %, report it as determined, and give
/// a range that holds the truth. About two and a half minutes on 2 cores.
#[test]
fn aggregate_round_trip_recovers_spring_adhesion_over_tension_within_10_percent() {
    let (cells, nodes, truth_ratio) = (20, 150, 0.2);
    let dir = tempfile::tempdir().unwrap();
    let (initial, l_min) = initial_aggregate(cells, nodes);
    let omega = truth_ratio * 4.0 * AGGREGATE_GAMMA / (l_min * l_min);
    let truth = aggregate_model(ContactModel::Spring, l_min, AGGREGATE_GAMMA, omega);
    let observed = observe_aggregate(dir.path(), &truth, &initial, 10.0);
    assert!(observed.summary.steps > 0);
    let base = aggregate_model(ContactModel::Spring, l_min, AGGREGATE_GAMMA, 0.0);
    std::fs::write(dir.path().join("model.toml"), base.to_toml_string()).unwrap();
    let config = dir.path().join("fit.toml");
    std::fs::write(&config, aggregate_fit_config(ContactModel::Spring, l_min, nodes, 14, 8)).unwrap();
    let result = fit(&config, &dir.path().join("out"), false);
    let r = &result.ratios["adhesion_energy_over_tension"];
    let error = (r.value - truth_ratio) / truth_ratio;
    eprintln!(
        "aggregate spring round trip: w/(2γ) {truth_ratio} → {:.4} ({:+.1} %), range {:?}, determined {:?}, {} + {} evaluations",
        r.value,
        100.0 * error,
        r.range,
        r.determined,
        result.evaluations,
        result.profile_evaluations
    );
    assert!(error.abs() < 0.10, "recovered {} for the truth {truth_ratio}", r.value);
    assert_eq!(r.determined, Some(true), "the fit must find w/(2γ) determined by the aggregate's morphology");
    let [lo, hi] = r.range;
    assert!(lo <= truth_ratio && truth_ratio <= hi, "range [{lo}, {hi}] excludes the truth {truth_ratio}");
}

#[test]
fn same_seed_gives_the_same_trace_whatever_the_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let (initial, l_min) = initial_doublet();
    let truth = model(ContactModel::Coupling, l_min, 1e-3, 0.5e-3, 0.0);
    observed_labels(dir.path(), &truth, &initial, 12.0);
    let base = model(ContactModel::Coupling, l_min, 1e-3, 1e-3, 0.0);
    let config = write_config(
        dir.path(),
        &base,
        COUPLING,
        "method = \"particle_swarm\"\nmax_evaluations = 6\nswarm_size = 3\nseed = 7\ntolerance = 0",
        0,
    );
    let traces: Vec<String> = [1, 2]
        .into_iter()
        .map(|threads| {
            let out = dir.path().join(format!("out{threads}"));
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| fit(&config, &out, false));
            // Everything but the wall times.
            let text = std::fs::read_to_string(out.join("trace.csv")).unwrap();
            let mut rdr = csv::Reader::from_reader(text.as_bytes());
            let header = rdr.headers().unwrap().clone();
            let wall = |i: usize| matches!(&header[i], "wall_seconds" | "elapsed_seconds");
            rdr.records()
                .map(|r| {
                    let r = r.unwrap();
                    r.iter().enumerate().filter(|(i, _)| !wall(*i)).map(|(_, v)| v).collect::<Vec<_>>().join(",")
                })
                .collect::<Vec<_>>()
                .join("\n")
        })
        .collect();
    assert_eq!(traces[0].lines().count(), 6);
    assert_eq!(traces[0], traces[1]);
    // A different seed draws a different swarm.
    let mut config2 = FitConfig::load(&config).unwrap();
    config2.optimizer.seed = 8;
    config2.optimizer.max_evaluations = 3;
    let out = dir.path().join("seed8");
    run_fit(&config2, &out, &FitOptions::default()).unwrap();
    let other = std::fs::read_to_string(out.join("trace.csv")).unwrap();
    let first = |t: &str| t.lines().nth(1).map(|l| l.split(',').nth(1).unwrap_or("").to_string());
    assert_ne!(first(&other), traces[0].lines().next().map(|l| l.split(',').nth(1).unwrap_or("").to_string()));
}

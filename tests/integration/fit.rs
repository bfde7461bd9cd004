//! The inference round trip (the product's acceptance test, DESIGN.md §6): a doublet relaxed with
//! known parameters is voxelised at ≥ 10 voxels per cell diameter; the fit sees only that label
//! TIFF (meshed, measured, fitted) and must recover what the data determine within 10 %, for two
//! truths and both contact models. Plus: the same seed gives the same trace whatever the thread
//! count, and a fit resumed from a truncated trace ends exactly where the uninterrupted one did.
//!
//! Kept small for CI (two cells of ~200 nodes, 1000 FIRE steps per evaluation, 1-D fits of the
//! parameter that the shape determines, with the other one fixed as a measurement would fix it).

use std::path::{Path, PathBuf};
use tissuefit::geometry::{Real, Vec3};
use tissuefit::imaging::{
    LabelPattern, LabelSpec, LabelWriteOptions, VoxelGrid, generate_labels, voxelize, write_label_tiff,
};
use tissuefit::inference::{FitConfig, FitOptions, FitResult, read_trace, run_fit};
use tissuefit::mechanics::{ContactModel, ContactQuadrature, NoObserver, Parameters, Simulation};
use tissuefit::mesh::FaceType;
use tissuefit::mesh::Tissue;
use tissuefit::meshing::{LabelMeshingOptions, mesh_labels};

use crate::support::round_trip;
use crate::support::young_dupre;
use round_trip::{
    AGGREGATE_GAMMA, aggregate_fit_config, aggregate_model, initial_aggregate, observe_aggregate, round_trip_model,
};
use young_dupre::{far_field_half_angles, young_dupre};

/// Cell radius of the generated doublet (m) and the nodes per cell of its meshes.
const VOXEL: Real = 0.4e-6;
const TARGET_NODES: usize = 200;
const STEPS: u64 = 1000;
const TRUTH_STEPS: u64 = 4000;
/// Spring truths: the contact line spreads slowly with c = l_min / 2.4 (4,000 steps left the
/// truth at w/(2γ) = 0.3 3.3° short of Young–Dupré, still spreading).
const SPRING_TRUTH_STEPS: u64 = 16_000;

/// The round trip's model (see [`round_trip_model`]) with this file's spring step and step count.
fn model(contact: ContactModel, l_min: Real, gamma: Real, gamma_lateral: Real, adhesion: Real) -> Parameters {
    let mut p = round_trip_model(contact, l_min, gamma, gamma_lateral, adhesion, 5e-9, STEPS);
    if contact == ContactModel::Spring {
        p.numerics.contact_quadrature = ContactQuadrature::Faces;
        p.numerics.contact_cutoff = spring_cutoff(l_min);
        for ft in FaceType::ALL {
            p.cell_types[0].faces.get_mut(ft).repulsion = 1e12;
        }
    }
    p
}

/// The spring round trips' contact range c = l_min / 2.4 (≈ 0.19 µm, c/R ≈ 0.1 on this doublet).
fn spring_cutoff(l_min: Real) -> Real {
    l_min / 2.4
}

/// A meshed doublet (two half-overlapping spheres, 12 voxels across each) and its l_min.
fn initial_doublet() -> (Tissue, Real) {
    let spec = LabelSpec {
        pattern: LabelPattern::Doublet,
        shape: [14, 14, 24],
        voxel_size: [VOXEL; 3],
        cells: 2,
        seed: 1,
        lumen: false,
    };
    let labels = generate_labels(&spec).unwrap();
    let opts = LabelMeshingOptions { target_nodes: TARGET_NODES, ..Default::default() };
    let meshed = mesh_labels(&labels.volume, &opts).unwrap();
    assert_eq!(meshed.tissue.len(), 2);
    (meshed.tissue, meshed.l_min.unwrap())
}

/// Relaxes the doublet with the truth and voxelises it at `voxels_per_diameter`; writes the TIFF.
fn observed_labels(dir: &Path, truth: &Parameters, initial: &Tissue, voxels_per_diameter: Real) -> PathBuf {
    observed_labels_after(dir, truth, initial, voxels_per_diameter, TRUTH_STEPS).0
}

/// [`observed_labels`] with the truth relaxed for `steps`.
fn observed_labels_after(
    dir: &Path,
    truth: &Parameters,
    initial: &Tissue,
    voxels_per_diameter: Real,
    steps: u64,
) -> (PathBuf, Tissue) {
    // The truth is relaxed longer than an evaluation: it starts from the generated spheres, far
    // from equilibrium, while evaluations start from the observed (equilibrium) shape.
    let mut truth = truth.clone();
    truth.simulation.max_steps = steps;
    let mut sim = Simulation::new(initial.clone(), &truth).unwrap();
    let summary = sim.run(&mut NoObserver).unwrap();
    eprintln!("truth relaxation: {summary:?}");
    let tissue = sim.into_tissue();
    let mean_volume = tissue.cells().iter().map(|c| c.mesh().signed_volume()).sum::<Real>() / tissue.len() as Real;
    let diameter = 2.0 * (3.0 * mean_volume / (4.0 * std::f64::consts::PI)).cbrt();
    let voxel = diameter / voxels_per_diameter;
    let (mut lo, mut hi) = (Vec3::repeat(Real::INFINITY), Vec3::repeat(Real::NEG_INFINITY));
    for c in tissue.cells() {
        for p in c.mesh().positions() {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
    }
    let grid = VoxelGrid::covering(lo, hi, [voxel; 3], 2).unwrap();
    let labels = voxelize(&tissue, &grid).unwrap();
    let path = dir.join("observed.tif");
    write_label_tiff(&path, &labels, &LabelWriteOptions::default()).unwrap();
    (path, tissue)
}

/// Writes the model and the fit config; returns the config's path.
fn write_config(dir: &Path, base: &Parameters, parameters: &str, optimizer: &str, profile_points: usize) -> PathBuf {
    std::fs::write(dir.join("model.toml"), base.to_toml_string()).unwrap();
    // Spring contacts keep the model's c below l_min (c/R ≈ 0.1, where the contact angle follows
    // Young–Dupré); the fit would otherwise set c to the meshing's l_min.
    let match_mesh =
        if base.numerics.contact_cutoff < base.numerics.min_edge_length { "match_mesh_length = false" } else { "" };
    let text = format!(
        r#"
model = "model.toml"

[observed]
labels = "observed.tif"

[observed.meshing]
target_nodes = {TARGET_NODES}

{parameters}

[optimizer]
{optimizer}

[forward]
# The coupling model's residual hovers above the tolerance once the shape has settled (see
# tests/integration/contact_models.rs); the run length is the criterion.
accept_residual = 1e9
{match_mesh}

[objective]
# A doublet has one contact: its φ and rim angle, re-measured like the data, jump between
# neighbouring parameter values (±0.03, ±10°) where sphericity moves smoothly; the 20-cell aggregate
# of examples/fit_aggregate.rs averages ~60 contacts and fits φ too.
contact_fraction = 0.0
coordination = 0.0
contact_angle = 0.0

[profile]
points = {profile_points}
span = 1.3
"#
    );
    let path = dir.join("fit.toml");
    std::fs::write(&path, text).unwrap();
    path
}

fn fit(config: &Path, out: &Path, resume: bool) -> FitResult {
    let config = FitConfig::load(config).unwrap();
    run_fit(&config, out, &FitOptions { resume, progress: false, plots: true }).unwrap()
}

/// w/(2γ) = ω·c²/(4γ) of the truth (c = [`spring_cutoff`], as set by `model`).
fn w_over_2g_truth(omega: Real, gamma: Real) -> Real {
    let (_, l_min) = initial_doublet();
    let c = spring_cutoff(l_min);
    omega * c * c / (4.0 * gamma)
}

/// Before a spring round trip fits anything, its truth must be physical: the relaxed doublet's
/// far-field half-angles (sphere fits to the free caps, as `tests/integration/spring_young_dupre.rs` reads them)
/// within 3° of Young–Dupré's for w/(2γ), the regime grid's bound. At c = l_min (c/R ≈ 0.25) this
/// doublet ended +4.2…+6.0° off (w/(2γ) = 0.2 and 0.45; Young–Dupré is the zero-range limit of the
/// well), hence c = l_min / 2.4.
fn truth_follows_young_dupre(relaxed: &Tissue, w_over_2g: Real, cutoff: Real) {
    let radius = relaxed.cells().iter().map(|c| (3.0 * c.mesh().signed_volume() / (4.0 * std::f64::consts::PI)).cbrt());
    let radius = radius.sum::<Real>() / relaxed.len() as Real;
    let [ha, hb] = far_field_half_angles(relaxed, 0.3 * radius);
    let yd = young_dupre(w_over_2g);
    eprintln!(
        "spring truth w/(2γ) = {w_over_2g:.3}: far-field half-angles {ha:.2}°/{hb:.2}° against Young–Dupré {yd:.2}° \
         (R = {:.2} µm, c = {:.3} µm)",
        radius * 1e6,
        cutoff * 1e6
    );
    for h in [ha, hb] {
        assert!((h - yd).abs() <= 3.0, "the truth is not physical: half-angle {h:.2}° against Young–Dupré {yd:.2}°");
    }
}

struct Case {
    contact: ContactModel,
    /// Truth: free-surface tension, lateral tension, adhesion.
    truth: (Real, Real, Real),
    parameters: &'static str,
    /// The ratio the data determine and its true value.
    ratio: &'static str,
}

fn round_trip(case: &Case, dir: &Path) -> (FitResult, PathBuf) {
    round_trip_at(case, dir, 12.0)
}

fn round_trip_at(case: &Case, dir: &Path, voxels_per_diameter: Real) -> (FitResult, PathBuf) {
    let (initial, l_min) = initial_doublet();
    let (g, gl, w) = case.truth;
    let truth = model(case.contact, l_min, g, gl, w);
    let steps = if case.contact == ContactModel::Spring { SPRING_TRUTH_STEPS } else { TRUTH_STEPS };
    let (_, relaxed) = observed_labels_after(dir, &truth, &initial, voxels_per_diameter, steps);
    if case.contact == ContactModel::Spring && gl == g {
        truth_follows_young_dupre(&relaxed, w_over_2g_truth(w, g), spring_cutoff(l_min));
    }
    // The base model the fit starts from: wrong values for the fitted parameter (the config sets them).
    let base = model(case.contact, l_min, 1e-3, 1e-3, 0.0);
    let config = write_config(
        dir,
        &base,
        case.parameters,
        "method = \"nelder_mead\"\nmax_evaluations = 24\ntolerance = 0.01",
        2,
    );
    let out = dir.join("out");
    let result = fit(&config, &out, false);
    (result, out)
}

/// The true value of the case's key ratio.
fn true_ratio(case: &Case) -> Real {
    let (g, gl, w) = case.truth;
    match case.ratio {
        "lateral_over_apical" => gl / g,
        "adhesion_energy_over_tension" => w_over_2g_truth(w, g),
        _ => w / g,
    }
}

/// Relative error of the recovered key ratio (printed with the fit's figures).
fn recovery_error(case: &Case, result: &FitResult) -> Real {
    let truth = true_ratio(case);
    let r = &result.ratios[case.ratio];
    let error = (r.value - truth).abs() / truth;
    eprintln!(
        "{:?} truth {} = {truth:.4e}: recovered {:.4e} ({:+.1} %), range [{:.3e}, {:.3e}], determined {:?}; \
         objective {:.3e}, {} evaluations + {} profile, {:.1} s; observed {:?} best {:?}",
        case.contact,
        case.ratio,
        r.value,
        100.0 * (r.value - truth) / truth,
        r.range[0],
        r.range[1],
        r.determined,
        result.objective,
        result.evaluations,
        result.profile_evaluations,
        result.wall_seconds,
        result.observed,
        result.best_metrics
    );
    error
}

fn check(case: &Case, result: &FitResult) -> Real {
    let error = recovery_error(case, result);
    let r = &result.ratios[case.ratio];
    let truth = true_ratio(case);
    assert!(
        error < 0.10,
        "{:?}: {} recovered {} vs truth {truth} ({:.1} % off)",
        case.contact,
        case.ratio,
        r.value,
        100.0 * error
    );
    assert_eq!(r.determined, Some(true), "{:?}: the contact shape should determine {}", case.contact, case.ratio);
    error
}

const COUPLING: &str = r#"
[parameters.surface_tension]
value = 1e-3
[parameters.surface_tension_lateral]
bounds = [2e-4, 1e-3]
initial = 8e-4
"#;

const SPRING: &str = r#"
[parameters.surface_tension]
value = 1e-3
[parameters.adhesion]
bounds = [1e10, 7e10]
initial = 2.5e10
"#;

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

#[test]
fn bad_configs_are_errors_naming_the_key() {
    let cases = [
        (
            "[observed]\ntissue = \"a.vtp\"\n[parameters.surface_tension]\nbounds = [1e-3, 1e-4]\n",
            "parameters.surface_tension.bounds",
        ),
        ("[observed]\ntissue = \"a.vtp\"\n[parameters.tension]\nbounds = [1e-4, 1e-3]\n", "parameters.tension"),
        ("[observed]\ntissue = \"a.vtp\"\nfoo = 1\n[parameters.adhesion]\nbounds = [1e8, 1e9]\n", "foo"),
        ("[observed]\n[parameters.adhesion]\nbounds = [1e8, 1e9]\n", "observed"),
        ("[observed]\ntissue = \"a.vtp\"\n[parameters.adhesion]\nvalue = 1e9\n", "every parameter is fixed"),
        (
            "[observed]\ntissue = \"a.vtp\"\n[parameters.adhesion]\nbounds = [1e8, 1e9]\n[optimizer]\nmethod = \"simplex\"\n",
            "simplex",
        ),
        (
            "[observed]\ntissue = \"a.vtp\"\n[parameters.adhesion]\nbounds = [1e8, 1e9]\n[objective]\nshape = 1.0\n",
            "objective.shape",
        ),
    ];
    for (text, key) in cases {
        let e = FitConfig::from_toml_str(text, "fit.toml").unwrap_err().to_string();
        assert!(e.contains(key) && e.contains("fit.toml"), "error `{e}` should name `{key}`");
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

#[test]
fn trace_round_trips_exactly_including_missing_metrics_and_failures() {
    use tissuefit::inference::{Evaluation, Metrics, ParameterConfig, ParameterSpace, Status, write_trace};
    let mut params = std::collections::BTreeMap::new();
    params.insert("adhesion".to_string(), ParameterConfig { bounds: Some([1e8, 1e10]), value: None, initial: None });
    params.insert("surface_tension".to_string(), ParameterConfig { bounds: None, value: Some(1e-3), initial: None });
    let space = ParameterSpace::from_config(&params).unwrap();
    let evals = vec![
        Evaluation {
            x: vec![(3e9 as Real).ln() + 1e-15],
            metrics: Metrics { sphericity: Some(0.1 + 0.2), contact_fraction: None, ..Default::default() },
            objective: 1.0 / 3.0,
            status: Status::Accepted,
            reason: String::new(),
            steps: 1000,
            residual: 0.0123,
            wall_seconds: 0.5,
            elapsed_seconds: 12.25,
        },
        Evaluation {
            x: vec![(1e10 as Real).ln()],
            metrics: Metrics::default(),
            objective: 1e6,
            status: Status::Failed,
            reason: "simulation: step 3, cell 1: non-finite force, \"quoted\"".into(),
            steps: 0,
            residual: Real::NAN,
            wall_seconds: 0.01,
            elapsed_seconds: 13.0,
        },
    ];
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("trace.csv");
    write_trace(&path, &space, &evals).unwrap();
    let back = read_trace(&path, &space).unwrap();
    assert_eq!(back.len(), 2);
    assert_eq!(back[0], evals[0]);
    assert_eq!(back[1].x, evals[1].x);
    assert_eq!(back[1].reason, evals[1].reason);
    assert!(back[1].residual.is_nan());
    // A trace of another parameter space is refused, naming the file.
    let mut other = params.clone();
    other.insert(
        "surface_tension_lateral".into(),
        ParameterConfig { bounds: Some([1e-4, 1e-3]), value: None, initial: None },
    );
    let e = read_trace(&path, &ParameterSpace::from_config(&other).unwrap()).unwrap_err().to_string();
    assert!(e.contains("trace.csv") && e.contains("columns"), "{e}");
}

#[test]
fn cli_fit_writes_the_design_keys_and_refuses_to_overwrite_without_resume() {
    let dir = tempfile::tempdir().unwrap();
    let (initial, l_min) = initial_doublet();
    let truth = model(ContactModel::Coupling, l_min, 1e-3, 0.6e-3, 0.0);
    observed_labels(dir.path(), &truth, &initial, 12.0);
    let config = write_config(
        dir.path(),
        &model(ContactModel::Coupling, l_min, 1e-3, 1e-3, 0.0),
        COUPLING,
        "method = \"nelder_mead\"\nmax_evaluations = 3\ntolerance = 0",
        1,
    );
    let out = dir.path().join("out");
    let run = |extra: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_tissuefit"))
            .args(["--threads", "2", "fit", "--config"])
            .arg(&config)
            .arg("--out")
            .arg(&out)
            .args(extra)
            .output()
            .unwrap()
    };
    let first = run(&[]);
    // The budget of 3 ends the search before the simplex converges: exit code 1.
    assert_eq!(first.status.code(), Some(1), "{}", String::from_utf8_lossy(&first.stderr));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("result.json")).unwrap()).unwrap();
    for key in ["parameters", "objective", "evaluations", "converged", "wall_seconds"] {
        assert!(json.get(key).is_some(), "result.json lacks {key}");
    }
    let p = &json["parameters"]["surface_tension_lateral"];
    assert!(p["si"].as_f64().unwrap() > 0.0 && p["dimensionless"].as_f64().unwrap() > 0.0);
    assert_eq!(p["range"].as_array().unwrap().len(), 2);
    assert_eq!(json["evaluations"].as_u64(), Some(3));
    assert_eq!(json["converged"].as_bool(), Some(false));
    for f in ["trace.csv", "objective.png", "landscape.png", "fit.toml", "model.toml"] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    let png = std::fs::read(out.join("objective.png")).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    let again = run(&[]);
    assert_eq!(again.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&again.stderr);
    assert!(stderr.contains("--resume"), "{stderr}");
    // Resuming with a larger budget reuses the three evaluations.
    let resumed = run(&["--resume", "--max-evaluations", "4"]);
    assert!(resumed.status.code() == Some(0) || resumed.status.code() == Some(1));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("result.json")).unwrap()).unwrap();
    assert_eq!(json["evaluations"].as_u64(), Some(4));
    // Only the fourth point (and at most the new profile) is simulated; the first three come from the trace.
    let simulated = json["simulated_here"].as_u64().unwrap();
    assert!(simulated >= 1 && simulated <= 1 + json["profile_evaluations"].as_u64().unwrap(), "{json}");
}

#[test]
fn a_failing_evaluation_is_penalised_with_its_reason_not_fatal() {
    use tissuefit::inference::{
        ForwardConfig, ForwardModel, ObjectiveConfig, Observation, ParameterConfig, ParameterSpace, Status,
    };
    let (initial, l_min) = initial_doublet();
    let observation = Observation::new(initial, None, None).unwrap();
    let mut params = std::collections::BTreeMap::new();
    // Adhesion so stiff that the time step is unstable: the parameters fail validation.
    params.insert("adhesion".to_string(), ParameterConfig { bounds: Some([1e9, 1e17]), value: None, initial: None });
    let space = ParameterSpace::from_config(&params).unwrap();
    let base = model(ContactModel::Spring, l_min, 1e-3, 1e-3, 1e9);
    let objective = ObjectiveConfig { failure_penalty: 123.0, ..Default::default() };
    let m = ForwardModel::new(observation, base, space, objective, ForwardConfig::default()).unwrap();
    let e = m.evaluate(&[(1e17 as Real).ln()]);
    assert_eq!(e.status, Status::Failed);
    assert_eq!(e.objective, 123.0);
    assert!(e.reason.contains("invalid parameters"), "{}", e.reason);
    // A point outside the bounds is clamped before it is evaluated.
    let e = m.evaluate(&[(1e18 as Real).ln()]);
    assert_eq!(e.x, vec![(1e17 as Real).ln()]);
}

/// The optional shape term (mean 1 − IoU of each moving cell against its observed voxels): small at
/// the truth, large at a wrong tension, and it enters the objective; it is a real comparison that a
/// wrong shape fails.
#[test]
fn shape_term_is_small_at_the_truth_and_grows_away_from_it() {
    use tissuefit::inference::{ForwardModel, ParameterSpace, load_observation};
    let dir = tempfile::tempdir().unwrap();
    let (initial, l_min) = initial_doublet();
    let truth = model(ContactModel::Coupling, l_min, 1e-3, 0.5e-3, 0.0);
    observed_labels(dir.path(), &truth, &initial, 12.0);
    let config = write_config(
        dir.path(),
        &model(ContactModel::Coupling, l_min, 1e-3, 1e-3, 0.0),
        COUPLING,
        "method = \"nelder_mead\"\nmax_evaluations = 3",
        0,
    );
    let mut config = FitConfig::load(&config).unwrap();
    config.objective.sphericity = 0.0;
    config.objective.shape = 1.0;
    let space = ParameterSpace::from_config(&config.parameters).unwrap();
    let observation = load_observation(&config).unwrap();
    let m = ForwardModel::new(
        observation,
        config.base_parameters().unwrap(),
        space,
        config.objective.clone(),
        config.forward.clone(),
    )
    .unwrap();
    let at = |gamma_lateral: Real| m.evaluate(&[gamma_lateral.ln()]);
    let (right, wrong) = (at(0.5e-3), at(1e-3));
    eprintln!(
        "shape term: truth {:?} ({}), γ_l = γ_a {:?} ({})",
        right.metrics.shape, right.objective, wrong.metrics.shape, wrong.objective
    );
    let (s_right, s_wrong) = (right.metrics.shape.unwrap(), wrong.metrics.shape.unwrap());
    // At the truth the relaxed cells cover their observed voxels up to the meshing and voxelisation
    // error: a cell 12 voxels across has 42 % of its voxels in its outer layer, so a boundary off by
    // half a voxel everywhere gives 1 − IoU ≈ 0.2 (measured 0.13). A wrong ratio moves the contact
    // rim and the whole cell (measured 0.41 at γ_l = γ_a).
    assert!(s_right < 0.2, "1 − IoU at the truth is {s_right}");
    assert!(s_wrong > 2.0 * s_right, "1 − IoU: {s_wrong} at γ_l = γ_a vs {s_right} at the truth");
    assert!(wrong.objective > right.objective);
    // The objective is the shape term alone here: w·(χ/s)².
    let expected = (s_right / config.objective.shape_scale).powi(2);
    assert!((right.objective - expected).abs() <= 1e-12 * expected.max(1.0), "{} vs {expected}", right.objective);
}

/// Warm start, measured: relaxing from the equilibrium of a neighbouring evaluation instead of the
/// observed tissue. The fit starts every evaluation cold (forward.rs, "No warm start"); this test
/// pins down why: a warm start does not reach the same equilibrium metrics as a cold one at the same
/// parameters (the relaxation is not run to a unique end state: the coupling model's residual
/// hovers, and the mesh carries the history of its remeshing), by more than the fit resolves.
#[test]
fn warm_start_reaches_other_metrics_than_a_cold_start_so_evaluations_start_cold() {
    use tissuefit::inference::{ForwardModel, ParameterSpace, load_observation};
    let dir = tempfile::tempdir().unwrap();
    let (initial, l_min) = initial_doublet();
    let truth = model(ContactModel::Coupling, l_min, 1e-3, 0.5e-3, 0.0);
    observed_labels(dir.path(), &truth, &initial, 12.0);
    let config = write_config(
        dir.path(),
        &model(ContactModel::Coupling, l_min, 1e-3, 1e-3, 0.0),
        COUPLING,
        "method = \"nelder_mead\"\nmax_evaluations = 3",
        0,
    );
    let config = FitConfig::load(&config).unwrap();
    let space = ParameterSpace::from_config(&config.parameters).unwrap();
    let observation = load_observation(&config).unwrap();
    let m = ForwardModel::new(
        observation,
        config.base_parameters().unwrap(),
        space,
        config.objective.clone(),
        config.forward.clone(),
    )
    .unwrap();
    let x = |g: Real| vec![g.ln()];
    // The neighbour: 10 % off the point evaluated next.
    let (neighbour, relaxed) = m.evaluate_from(&x(0.55e-3), &m.observation.tissue);
    let relaxed = relaxed.expect("the neighbour relaxed");
    assert!(neighbour.status.usable(), "{neighbour:?}");
    let cold = m.evaluate(&x(0.5e-3));
    let (warm, _) = m.evaluate_from(&x(0.5e-3), &relaxed);
    let again = m.evaluate(&x(0.5e-3));
    eprintln!(
        "cold: objective {:.4} {:?} {} steps {:.2} s; warm: objective {:.4} {:?} {} steps {:.2} s",
        cold.objective,
        cold.metrics,
        cold.steps,
        cold.wall_seconds,
        warm.objective,
        warm.metrics,
        warm.steps,
        warm.wall_seconds
    );
    // A cold start is a function of the parameters alone: bit for bit.
    assert_eq!(again.objective.to_bits(), cold.objective.to_bits());
    // Nothing saved: the coupling relaxation never meets the force tolerance (its residual hovers),
    // so every pass runs its max_steps from either start (measured 3000 = 3000 steps).
    assert_eq!(warm.steps, cold.steps);
    // And the end state depends on the start. Since the first relaxation starts at the Laplace
    // target volume (no 36 % shrinking and regrowing), the sphericity hardly does (measured −0.00029,
    // 0.06 scales; before: −0.0026, half a scale), but the contact does (rim angle 62.9° cold vs
    // 71.2° warm, 8.4 scales; φ 0.180 vs 0.193): a warm-started fit of contact metrics would depend
    // on the order of its evaluations.
    let o = &config.objective;
    let scales = [o.sphericity_scale, o.contact_fraction_scale, o.coordination_scale, o.contact_angle_scale];
    let apart = cold
        .metrics
        .values()
        .iter()
        .zip(warm.metrics.values())
        .zip(scales)
        .filter_map(|((c, w), s)| Some(((w? - (*c)?) / s).abs()))
        .fold(0.0, Real::max);
    eprintln!(
        "warm − cold: up to {apart:.2} scales (sphericity {:+.5})",
        warm.metrics.sphericity.unwrap() - cold.metrics.sphericity.unwrap()
    );
    assert!(
        apart > 1.0,
        "warm and cold starts agree to {apart:.2} scales in every metric: a warm start could be enabled"
    );
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

/// The like-data measurement (voxelise on the observed grid, mesh again, measure) of one shape
/// depends on where that shape lies on the voxel grid: moved rigidly by a fraction of a voxel, an
/// aggregate's re-meshed contact-area fraction and sphericity change although the shape did not.
/// On the relaxed spring aggregate of the README this scatter (±0.007 in φ) was as large as the
/// difference between relaxations at parameters one bit apart. `forward.measure_shifts` averages
/// the measurement over sub-voxel shifts; the averaged metrics of the rigidly moved shape must
/// scatter much less than the single measurements do.
#[test]
fn measuring_like_the_data_averaged_over_sub_voxel_shifts_hardly_depends_on_where_the_shape_lies() {
    use tissuefit::inference::{ForwardConfig, ForwardModel, ObjectiveConfig, Observation, ParameterSpace};
    let spec = LabelSpec {
        pattern: LabelPattern::Aggregate,
        shape: [26, 26, 26],
        voxel_size: [VOXEL; 3],
        cells: 8,
        seed: 2,
        lumen: false,
    };
    let labels = generate_labels(&spec).unwrap().volume;
    let options = LabelMeshingOptions { target_nodes: 120, ..Default::default() };
    let meshed = mesh_labels(&labels, &options).unwrap();
    assert_eq!(meshed.tissue.len(), 8);
    let options = LabelMeshingOptions { l_min: meshed.l_min, ..options };
    let observation = Observation::new(meshed.tissue.clone(), Some(labels), Some(options)).unwrap();
    let config = FitConfig::from_toml_str(
        "[observed]\nlabels = \"unused.tif\"\n[parameters.surface_tension]\nbounds = [1e-4, 1e-2]\n",
        "test",
    )
    .unwrap();
    let space = ParameterSpace::from_config(&config.parameters).unwrap();
    let model_with = |shifts: usize| {
        let forward = ForwardConfig { measure_shifts: shifts, ..Default::default() };
        ForwardModel::new(
            observation.clone(),
            Parameters::default(),
            space.clone(),
            ObjectiveConfig::default(),
            forward,
        )
        .unwrap()
    };
    let (single, averaged) = (model_with(1), model_with(8));
    // The shape moved rigidly to 5 places on the grid (not the Halton shifts themselves).
    let spread = |m: &ForwardModel| {
        let (mut phi, mut sph) = (Vec::new(), Vec::new());
        for j in 0..5 {
            let offset = Vec3::new(0.13, 0.29, 0.41) * (j as Real * VOXEL);
            let mut t = meshed.tissue.clone();
            for c in t.cells_mut() {
                for p in c.positions_mut() {
                    *p += offset;
                }
            }
            let metrics = m.measure(&t).unwrap();
            phi.push(metrics.contact_fraction.unwrap());
            sph.push(metrics.sphericity.unwrap());
        }
        let range = |v: &[Real]| {
            v.iter().cloned().fold(Real::NEG_INFINITY, Real::max) - v.iter().cloned().fold(Real::INFINITY, Real::min)
        };
        eprintln!("φ {phi:?}, sphericity {sph:?}");
        (range(&phi), range(&sph))
    };
    let (phi_1, sph_1) = spread(&single);
    let (phi_8, sph_8) = spread(&averaged);
    eprintln!("spread over rigid moves: single φ {phi_1:.4} Ψ {sph_1:.5}; 8 shifts φ {phi_8:.4} Ψ {sph_8:.5}");
    // Measured: single φ 0.022, Ψ 0.0058 (more than the default scales 0.01 and 0.005: the placement
    // alone moved the objective by several units); 8 shifts φ 0.0069, Ψ 0.00085.
    assert!(phi_1 > 0.01, "the single measurement's scatter this test is about: {phi_1}");
    assert!(phi_8 < 0.5 * phi_1 && sph_8 < 0.5 * sph_1, "averaging over shifts must narrow the scatter");
    assert!(phi_8 < 0.01 && sph_8 < 0.0025, "averaged scatter within one φ scale and half a Ψ scale");
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

//! The doublet of the fit round trips (tests/integration/fit.rs, tests/slow/fit_round_trips.rs): its
//! model, the observed label volume, the fit config and the recovery checks.

use std::path::{Path, PathBuf};
use tissuefit::geometry::{Real, Vec3};
use tissuefit::imaging::{
    LabelPattern, LabelSpec, LabelWriteOptions, VoxelGrid, generate_labels, voxelize, write_label_tiff,
};
use tissuefit::inference::{FitConfig, FitOptions, FitResult, run_fit};
use tissuefit::mechanics::{ContactModel, ContactQuadrature, NoObserver, Parameters, Simulation};
use tissuefit::mesh::FaceType;
use tissuefit::mesh::Tissue;
use tissuefit::meshing::{LabelMeshingOptions, mesh_labels};

use crate::support::round_trip;
use crate::support::young_dupre;
use round_trip::round_trip_model;
use young_dupre::{far_field_half_angles, young_dupre};

/// Cell radius of the generated doublet (m) and the nodes per cell of its meshes.
pub const VOXEL: Real = 0.4e-6;
pub const TARGET_NODES: usize = 200;
pub const STEPS: u64 = 1000;
pub const TRUTH_STEPS: u64 = 4000;
/// Spring truths: the contact line spreads slowly with c = l_min / 2.4 (4,000 steps left the
/// truth at w/(2γ) = 0.3 3.3° short of Young–Dupré, still spreading).
pub const SPRING_TRUTH_STEPS: u64 = 16_000;

/// The round trip's model (see [`round_trip_model`]) with this file's spring step and step count.
pub fn model(contact: ContactModel, l_min: Real, gamma: Real, gamma_lateral: Real, adhesion: Real) -> Parameters {
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
pub fn spring_cutoff(l_min: Real) -> Real {
    l_min / 2.4
}

/// A meshed doublet (two half-overlapping spheres, 12 voxels across each) and its l_min.
pub fn initial_doublet() -> (Tissue, Real) {
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
pub fn observed_labels(dir: &Path, truth: &Parameters, initial: &Tissue, voxels_per_diameter: Real) -> PathBuf {
    observed_labels_after(dir, truth, initial, voxels_per_diameter, TRUTH_STEPS).0
}

/// [`observed_labels`] with the truth relaxed for `steps`.
pub fn observed_labels_after(
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

/// The coupled doublet at γ_l/γ_a = 0.5 voxelised at 12 voxels per diameter into `dir` (returned:
/// the label volume's path) and the fit config of γ_l starting at γ_l = γ_a, with
/// `max_evaluations` and no profile, loaded.
pub fn coupled_doublet_fit(dir: &Path, max_evaluations: usize) -> (PathBuf, FitConfig) {
    let (initial, l_min) = initial_doublet();
    let truth = model(ContactModel::Coupling, l_min, 1e-3, 0.5e-3, 0.0);
    let labels = observed_labels(dir, &truth, &initial, 12.0);
    let config = write_config(
        dir,
        &model(ContactModel::Coupling, l_min, 1e-3, 1e-3, 0.0),
        COUPLING,
        &format!("method = \"nelder_mead\"\nmax_evaluations = {max_evaluations}"),
        0,
    );
    (labels, FitConfig::load(&config).unwrap())
}

/// The forward model of `config` (its observation loaded and meshed).
pub fn forward_model(config: &FitConfig) -> tissuefit::inference::ForwardModel {
    use tissuefit::inference::{ForwardModel, ParameterSpace, load_observation};
    let space = ParameterSpace::from_config(&config.parameters).unwrap();
    let observation = load_observation(config).unwrap();
    ForwardModel::new(
        observation,
        config.base_parameters().unwrap(),
        space,
        config.objective.clone(),
        config.forward.clone(),
    )
    .unwrap()
}

/// Writes the model and the fit config; returns the config's path.
pub fn write_config(
    dir: &Path,
    base: &Parameters,
    parameters: &str,
    optimizer: &str,
    profile_points: usize,
) -> PathBuf {
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

pub fn fit(config: &Path, out: &Path, resume: bool) -> FitResult {
    let config = FitConfig::load(config).unwrap();
    run_fit(&config, out, &FitOptions { resume, progress: false, plots: true, ..Default::default() }).unwrap()
}

/// w/(2γ) = ω·c²/(4γ) of the truth (c = [`spring_cutoff`], as set by `model`).
pub fn w_over_2g_truth(omega: Real, gamma: Real) -> Real {
    let (_, l_min) = initial_doublet();
    let c = spring_cutoff(l_min);
    omega * c * c / (4.0 * gamma)
}

/// Before a spring round trip fits anything, its truth must be physical: the relaxed doublet's
/// far-field half-angles (sphere fits to the free caps, as `tests/integration/spring_young_dupre.rs` reads them)
/// within 3° of Young–Dupré's for w/(2γ), the regime grid's bound. At c = l_min (c/R ≈ 0.25) this
/// doublet ended +4.2…+6.0° off (w/(2γ) = 0.2 and 0.45; Young–Dupré is the zero-range limit of the
/// well), hence c = l_min / 2.4.
pub fn truth_follows_young_dupre(relaxed: &Tissue, w_over_2g: Real, cutoff: Real) {
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

pub struct Case {
    pub contact: ContactModel,
    /// Truth: free-surface tension, lateral tension, adhesion.
    pub truth: (Real, Real, Real),
    pub parameters: &'static str,
    /// The ratio the data determine and its true value.
    pub ratio: &'static str,
}

pub fn round_trip(case: &Case, dir: &Path) -> (FitResult, PathBuf) {
    round_trip_at(case, dir, 12.0)
}

pub fn round_trip_at(case: &Case, dir: &Path, voxels_per_diameter: Real) -> (FitResult, PathBuf) {
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
pub fn true_ratio(case: &Case) -> Real {
    let (g, gl, w) = case.truth;
    match case.ratio {
        "lateral_over_apical" => gl / g,
        "adhesion_energy_over_tension" => w_over_2g_truth(w, g),
        _ => w / g,
    }
}

/// Relative error of the recovered key ratio (printed with the fit's figures).
pub fn recovery_error(case: &Case, result: &FitResult) -> Real {
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

pub fn check(case: &Case, result: &FitResult) -> Real {
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

pub const COUPLING: &str = r#"
[parameters.surface_tension]
value = 1e-3
[parameters.surface_tension_lateral]
bounds = [2e-4, 1e-3]
initial = 8e-4
"#;

pub const SPRING: &str = r#"
[parameters.surface_tension]
value = 1e-3
[parameters.adhesion]
bounds = [1e10, 7e10]
initial = 2.5e10
"#;

//! The synthetic aggregate round trip: an aggregate of polyhedral cells is relaxed with known
//! tensions/adhesion (the truth), voxelised at a given number of voxels per cell diameter, and fitted
//! from that label volume alone. `tissuefit bench fit` times it (issue 24's "20-cell global fit"),
//! `examples/fit_aggregate.rs` studies it, and the fit's round-trip tests run it
//! (`tests/slow/fit_round_trips.rs`).

use crate::geometry::{Real, Vec3};
use crate::imaging::{
    LabelPattern, LabelSpec, LabelWriteOptions, VoxelGrid, generate_labels, voxelize_with_stats, write_label_tiff,
};
use crate::mechanics::{
    ContactModel, Dynamics, NoObserver, Parameters, Polarity, RelaxMethod, Simulation, SimulationMode,
    SimulationSummary,
};
use crate::mesh::{FaceType, Tissue};
use crate::meshing::{LabelMeshingOptions, mesh_labels};
use std::path::Path;

/// Apical (free-surface) tension of the aggregate truths (N/m).
pub const AGGREGATE_GAMMA: Real = 1e-3;
/// Relaxation steps of an aggregate truth from the generated polyhedra, the last
/// [`AGGREGATE_SETTLE_STEPS`] without remeshing (`simulation.settle_steps`): the polyhedra round up
/// over the first thousands of steps, which remeshing must follow, then the shape settles on a
/// fixed mesh. Remeshed to the end, a spring truth kept creeping (φ +0.05 from step 1,000 to
/// 10,000), and what the fit recovered was where its relaxation had stopped.
pub const AGGREGATE_TRUTH_STEPS: u64 = 6000;
pub const AGGREGATE_SETTLE_STEPS: u64 = 1000;
/// Steps of every relaxation pass of a spring evaluation (from the observed, near-equilibrium
/// shape), the last [`AGGREGATE_SETTLE_STEPS`] on a fixed mesh; coupling contacts settle within 600.
pub const AGGREGATE_SPRING_STEPS: u64 = 1500;
pub const AGGREGATE_COUPLING_STEPS: u64 = 600;

/// No bending, no area elasticity, no pressure cap, no growth (so the equilibrium shape is set by
/// tensions, adhesion and K alone), polarity from contacts, FIRE for `max_steps`. Spring contacts get
/// a stiff repulsion and `spring_time_step` (the stability check asks for a shorter step than the
/// default 1e-7 s).
pub fn round_trip_model(
    contact: ContactModel,
    l_min: Real,
    gamma: Real,
    gamma_lateral: Real,
    adhesion: Real,
    spring_time_step: Real,
    max_steps: u64,
) -> Parameters {
    let mut p = Parameters::default();
    p.numerics.contact_model = contact;
    p.numerics.polarity = Polarity::Contacts;
    p.numerics.dynamics = Dynamics::Overdamped;
    p.numerics.damping = 3e-9;
    p.numerics.min_edge_length = l_min;
    p.numerics.contact_cutoff = l_min;
    let t = &mut p.cell_types[0];
    for ft in FaceType::ALL {
        let f = t.faces.get_mut(ft);
        f.surface_tension = gamma;
        f.bending_modulus = 0.0;
        f.adhesion = adhesion;
        if contact == ContactModel::Spring {
            f.repulsion = 1e11;
        }
    }
    if contact == ContactModel::Spring {
        p.numerics.time_step = spring_time_step;
    }
    t.faces.lateral.surface_tension = gamma_lateral;
    t.area_elasticity = 0.0;
    t.max_pressure = Real::INFINITY;
    t.growth_rate = 0.0;
    p.simulation.mode = SimulationMode::Equilibrium;
    p.simulation.method = RelaxMethod::Fire;
    p.simulation.remesh_every_steps = 50;
    p.simulation.max_steps = max_steps;
    p.simulation.sample_every_steps = i64::MAX as u64;
    p
}

/// The aggregate round trip's model: [`round_trip_model`] with apical tension
/// [`AGGREGATE_GAMMA`], the spring step 1.5e-8 s and the step counts above; spring relaxations move
/// nodes along their normals (`simulation.normal_relaxation`) and settle on a fixed mesh.
pub fn aggregate_model(contact: ContactModel, l_min: Real, gamma_lateral: Real, adhesion: Real) -> Parameters {
    let steps = if contact == ContactModel::Spring { AGGREGATE_SPRING_STEPS } else { AGGREGATE_COUPLING_STEPS };
    let mut p = round_trip_model(contact, l_min, AGGREGATE_GAMMA, gamma_lateral, adhesion, 1.5e-8, steps);
    if contact == ContactModel::Spring {
        p.simulation.settle_steps = AGGREGATE_SETTLE_STEPS;
        p.simulation.normal_relaxation = true;
    }
    p
}

/// The generated aggregate (`cells` polyhedra in a 40³ grid of 0.4 µm voxels, seed 2), meshed at
/// `nodes` per cell, and its l_min; an error when a cell could not be meshed.
pub fn initial_aggregate(cells: usize, nodes: usize) -> Result<(Tissue, Real), String> {
    let spec = LabelSpec {
        pattern: LabelPattern::Aggregate,
        shape: [40, 40, 40],
        voxel_size: [0.4e-6; 3],
        cells,
        seed: 2,
        lumen: false,
    };
    let labels = generate_labels(&spec).map_err(|e| format!("generating the aggregate's labels: {e}"))?;
    let meshed = mesh_labels(&labels.volume, &LabelMeshingOptions { target_nodes: nodes, ..Default::default() })
        .map_err(|e| format!("meshing the aggregate: {e}"))?;
    if meshed.tissue.len() != cells {
        return Err(format!("{} of the {cells} generated cells meshed", meshed.tissue.len()));
    }
    let l_min = meshed.l_min.ok_or("the meshed aggregate has no l_min")?;
    Ok((meshed.tissue, l_min))
}

/// What [`observe_aggregate`] made.
pub struct Observed {
    /// Mean cell diameter of the relaxed truth (m).
    pub diameter: Real,
    pub voxel: Real,
    /// Voxels claimed by two cells of the relaxed truth.
    pub overlapping_voxels: u64,
    pub summary: SimulationSummary,
    /// Mean nodes per cell of the relaxed truth.
    pub nodes_per_cell: Real,
}

/// Relaxes the truth ([`AGGREGATE_TRUTH_STEPS`], settling as above, for either contact model) from
/// `initial` and voxelises it
/// at `vpd` voxels per mean cell diameter into DIR/observed.tif.
pub fn observe_aggregate(dir: &Path, truth: &Parameters, initial: &Tissue, vpd: Real) -> Result<Observed, String> {
    let mut truth = truth.clone();
    truth.simulation.max_steps = AGGREGATE_TRUTH_STEPS;
    truth.simulation.settle_steps = AGGREGATE_SETTLE_STEPS;
    let mut sim = Simulation::new(initial.clone(), &truth).map_err(|e| format!("the truth's simulation: {e}"))?;
    let summary = sim.run(&mut NoObserver).map_err(|e| format!("the truth's relaxation: {e}"))?;
    let tissue = sim.into_tissue();
    let mean_volume = tissue.cells().iter().map(|c| c.mesh().signed_volume()).sum::<Real>() / tissue.len() as Real;
    let diameter = 2.0 * (3.0 * mean_volume / (4.0 * std::f64::consts::PI)).cbrt();
    let (mut lo, mut hi) = (Vec3::repeat(Real::INFINITY), Vec3::repeat(Real::NEG_INFINITY));
    for c in tissue.cells() {
        for p in c.mesh().positions() {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
    }
    let voxel = diameter / vpd;
    let grid = VoxelGrid::covering(lo, hi, [voxel; 3], 2).map_err(|e| format!("the observed grid: {e}"))?;
    let (labels, stats) = voxelize_with_stats(&tissue, &grid).map_err(|e| format!("voxelising the truth: {e}"))?;
    let path = dir.join("observed.tif");
    write_label_tiff(&path, &labels, &LabelWriteOptions::default())
        .map_err(|e| format!("writing {}: {e}", path.display()))?;
    let nodes_per_cell = tissue.node_count() as Real / tissue.len() as Real;
    Ok(Observed { diameter, voxel, overlapping_voxels: stats.overlapping_voxels, summary, nodes_per_cell })
}

/// The fit config of an aggregate round trip (model.toml beside it): sphericity and contact-area
/// fraction, Nelder–Mead with `budget` evaluations, `shifts` sub-voxel shifts, one volume pass, a
/// profile of 2 points per side; spring meshing keeps the truth's l_min (the cutoff c = l_min is a
/// length of the model, not only of the mesh).
pub fn aggregate_fit_config(contact: ContactModel, l_min: Real, nodes: usize, budget: usize, shifts: usize) -> String {
    let (parameters, meshing_l_min) = match contact {
        ContactModel::Coupling => (
            "[parameters.surface_tension]\nvalue = 1e-3\n[parameters.surface_tension_lateral]\nbounds = [2e-4, 1e-3]\ninitial = 8e-4\n"
                .to_string(),
            String::new(),
        ),
        ContactModel::Spring => {
            // w/(2γ) = ω·c²/(4γ), c = l_min, searched within [0.05, 0.3].
            let omega = |ratio: Real| spring_adhesion(ratio, l_min);
            (
                format!(
                    "[parameters.surface_tension]\nvalue = 1e-3\n[parameters.adhesion]\nbounds = [{:e}, {:e}]\ninitial = {:e}\n",
                    omega(0.05),
                    omega(0.3),
                    omega(0.25),
                ),
                format!("l_min = {l_min:e}"),
            )
        }
    };
    format!(
        r#"model = "model.toml"
[observed]
labels = "observed.tif"
[observed.meshing]
target_nodes = {nodes}
{meshing_l_min}
{parameters}
[objective]
sphericity = 1.0
contact_fraction = 1.0
coordination = 0.0
# The rim angle of re-meshed voxels hardly moves with the ratio at 10 voxels per diameter
# (40.7° → 46.1° for γ_l/γ_a 0.8 → 0.44) against ±1–2° between neighbouring points: left out.
contact_angle = 0.0
[optimizer]
method = "nelder_mead"
max_evaluations = {budget}
tolerance = 0.01
[forward]
accept_residual = 1e9
volume_passes = 1
measure_shifts = {shifts}
[profile]
points = 2
span = 1.3
"#
    )
}

/// The truth of a round trip with key ratio `ratio` and the name of that ratio in the fit's result:
/// γ_lateral/γ_apical for coupling contacts; w/(2γ) = ω·c²/(4γ) with c = l_min for spring contacts.
pub fn aggregate_truth(contact: ContactModel, l_min: Real, ratio: Real) -> (Parameters, &'static str) {
    let value = fitted_truth(contact, l_min, ratio);
    match contact {
        ContactModel::Coupling => (aggregate_model(contact, l_min, value, 0.0), "lateral_over_apical"),
        ContactModel::Spring => (aggregate_model(contact, l_min, AGGREGATE_GAMMA, value), super::ADHESION_RATIO),
    }
}

/// The true value of the parameter a round trip fits ([`aggregate_fit_config`]) for key ratio
/// `ratio`: γ_lateral (N/m) for coupling contacts, the adhesion ω for spring contacts.
pub fn fitted_truth(contact: ContactModel, l_min: Real, ratio: Real) -> Real {
    match contact {
        ContactModel::Coupling => ratio * AGGREGATE_GAMMA,
        ContactModel::Spring => spring_adhesion(ratio, l_min),
    }
}

/// The adhesion ω whose w/(2γ) = ω·c²/(4γ) (c = l_min, γ = [`AGGREGATE_GAMMA`]) is `ratio`.
pub fn spring_adhesion(ratio: Real, l_min: Real) -> Real {
    ratio * 4.0 * AGGREGATE_GAMMA / (l_min * l_min)
}

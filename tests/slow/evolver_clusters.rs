//! Outside truth (issue 19): foam-like clusters relaxed by Surface Evolver 2.70 (fixed volumes, tension
//! 1 on cell–medium faces and T_cc on cell–cell faces; `validation/evolver/make_cluster.py`), committed
//! as multi-material meshes in `validation/evolver/fixtures`. Our simulator, started from Evolver's
//! equilibrium at the true tensions (γ_a = 1 mN/m, γ_l = T_cc/2), must stay there: the same measuring
//! code on both sides, far-field contact angles within 1°, scale-free contact areas and sphericities
//! close. And the cause found for the outside-truth fit errors is pinned: with one coupling partner
//! per node (`numerics.coupling_junctions = false`) the tetrahedral cluster's contacts shrink and its
//! rim angles fall far from Evolver's.

use std::path::{Path, PathBuf};
use tissuefit::geometry::{Real, Vec3};
use tissuefit::io::{LengthScale, ReadOptions, read_tissue};
use tissuefit::mechanics::{CellOverrideConfig, NoObserver, Parameters, PerFaceType, Simulation};
use tissuefit::mesh::Tissue;
use tissuefit::morphology::{MeasureSettings, Morphology, measure_tissue};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("validation/evolver/fixtures").join(name)
}

fn truth(name: &str) -> serde_json::Value {
    let text = std::fs::read_to_string(fixture(name).join("truth.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

fn truth_ratio(name: &str) -> Real {
    truth(name)["lateral_over_apical"].as_f64().unwrap()
}

fn evolver_tissue(name: &str) -> Tissue {
    let options = ReadOptions { length_scale: LengthScale(Vec3::repeat(1e-6)), orient: false };
    read_tissue(&fixture(name).join("cluster.vtk"), &options).unwrap().tissue
}

/// One contact rule for both sides: the distance δ = 0.05 µm, well below either mesh's edges, so the
/// contact areas compare the shapes and not the meshes (Evolver's faces carry interface labels, ours do
/// not, so the labels are not used).
fn measure(tissue: &Tissue) -> Morphology {
    let settings =
        MeasureSettings { contact_distance: Some(5e-8), interface_labels: false, ..MeasureSettings::default() };
    measure_tissue(tissue, &settings).unwrap()
}

/// Relaxes the Evolver equilibrium at its own tensions with the validation model.
fn relax(name: &str, junctions: bool, steps: u64) -> (Morphology, Morphology, Real) {
    relax_with(name, steps, |p| p.numerics.coupling_junctions = junctions)
}

/// The same with the parameters changed by `change` after the validation model's are set.
fn relax_with(name: &str, steps: u64, change: impl FnOnce(&mut Parameters)) -> (Morphology, Morphology, Real) {
    let tissue = evolver_tissue(name);
    let evolver = measure(&tissue);
    let params = validation_params(name, steps, change);
    let mut sim = Simulation::new(tissue, &params).unwrap();
    let summary = sim.run(&mut NoObserver).unwrap();
    (evolver, measure(sim.tissue()), summary.residual)
}

/// The validation model at the cluster's true tensions, l_min = c = 0.3 µm, `steps` steps.
fn validation_params(name: &str, steps: u64, change: impl FnOnce(&mut Parameters)) -> Parameters {
    let model = Path::new(env!("CARGO_MANIFEST_DIR")).join("validation/evolver/model.toml");
    let mut params = Parameters::load(&model).unwrap();
    params.numerics.min_edge_length = 3e-7;
    params.numerics.contact_cutoff = 3e-7;
    params.simulation.max_steps = steps;
    if let Some(ratio) = truth(name)["lateral_over_apical"].as_f64() {
        params.cell_types[0].faces.lateral.surface_tension = ratio * 1e-3;
    }
    change(&mut params);
    params
}

/// One line of the docs' table (docs/scripts/evolver.sh collects them).
fn report(case: &str, d: &[Real; 4], residual: Real) {
    println!("| {case} | {:.2}° | {:.2}° | {:.2} % | {:.1e} | {residual:.1e} |", d[0], d[1], 100.0 * d[2], d[3]);
}

/// Largest |Δ far-field angle| (°), largest |Δ rim angle| (°), largest relative Δ of the scale-free
/// contact area A/V^(2/3), largest |Δ sphericity|.
fn differences(evolver: &Morphology, ours: &Morphology) -> [Real; 4] {
    assert_eq!(evolver.contacts.len(), ours.contacts.len(), "the contacts changed");
    let mut worst = [0.0; 4];
    for (e, o) in evolver.contacts.iter().zip(&ours.contacts) {
        assert_eq!((e.cell_a, e.cell_b), (o.cell_a, o.cell_b));
        // Contacts enclosed by others (in the ball) have no free caps, so no far-field angle, and
        // may have no rim; those columns skip them.
        if let (Some(fe), Some(fo)) = (e.far_field_angle_deg, o.far_field_angle_deg) {
            worst[0] = Real::max(worst[0], (fo - fe).abs());
        }
        if let (Some(re), Some(ro)) = (e.contact_angle_deg, o.contact_angle_deg) {
            worst[1] = Real::max(worst[1], (ro - re).abs());
        }
        worst[2] = Real::max(worst[2], (scaled_area(ours, o) / scaled_area(evolver, e) - 1.0).abs());
    }
    for (e, o) in evolver.cells.iter().zip(&ours.cells) {
        worst[3] = Real::max(worst[3], (o.sphericity - e.sphericity).abs());
    }
    worst
}

#[test]
fn coupled_doublet_stays_at_the_evolver_equilibrium_and_young_dupre() {
    let (evolver, ours, residual) = relax("doublet", true, 3000);
    let d = differences(&evolver, &ours);
    report("doublet, 0.60", &d, residual);
    let young = 2.0 * truth_ratio("doublet").acos().to_degrees();
    let ff = ours.contacts[0].far_field_angle_deg.unwrap();
    assert!((ff - young).abs() < 0.5, "far-field angle {ff:.2}° against Young–Dupré {young:.2}°");
    assert!(d[0] < 0.5 && d[2] < 0.01 && d[3] < 1e-3, "{d:?}");
}

#[test]
fn tetrahedral_cluster_stays_at_the_evolver_equilibrium_only_with_junction_groups() {
    let (evolver, ours, residual) = relax("tetra", true, 3000);
    let d = differences(&evolver, &ours);
    report("tetrahedral, 0.60", &d, residual);
    assert!(d[0] < 1.0, "far-field angles off by {:.2}°", d[0]);
    assert!(d[1] < 2.0, "rim angles off by {:.2}°", d[1]);
    assert!(d[2] < 0.02, "contact areas off by {:.1} %", 100.0 * d[2]);
    assert!(d[3] < 2e-3, "sphericity off by {:.4}", d[3]);
    // The defect that made the outside-truth fits miss by 25 %: pairs only.
    let (evolver, pairs, residual) = relax("tetra", false, 3000);
    let p = differences(&evolver, &pairs);
    report("tetrahedral, 0.60, one partner per node (`coupling_junctions = false`)", &p, residual);
    assert!(p[1] > 15.0 && p[2] > 0.05, "one partner per node no longer opens the junctions: {p:?}");
}

/// Relaxes an Evolver equilibrium whose cells have different pressures (3000 steps, l_min = c =
/// 0.2 µm). Evolver holds
/// the volumes fixed, its pressures are their Lagrange multipliers; our cells are compressible
/// (p = −K ln(V/V0)), so each cell's rest volume is set to where the pressure Evolver found holds
/// its volume, V0 = V·exp(p/K) (with V0 = V every cell would shrink by its own p/K, ≈ 18 %, and
/// unequally: another equilibrium than Evolver's).
fn relax_at_evolver_pressures(name: &str, change: impl FnOnce(&mut Parameters)) -> (Morphology, Morphology, Real) {
    let mut tissue = evolver_tissue(name);
    let evolver = measure(&tissue);
    let mut params = validation_params(name, 3000, change);
    // A finer mesh than the other clusters' 0.3 µm: its smallest contact (5.9 µm², T/2γ = 0.85, near
    // detachment) is a few edges across, and at 0.3 µm it shrank by 17 % in 3,000 steps (0.2 µm: 2.9 %).
    params.numerics.min_edge_length = 2e-7;
    params.numerics.contact_cutoff = 2e-7;
    let truth = truth(name);
    // Evolver's pressure is in units of its tension (1 = γ_a = 1 mN/m) per its length unit.
    let per_length = 1e-3 / (truth["evolver_length_to_um"].as_f64().unwrap() * 1e-6);
    let k = params.cell_types[0].bulk_modulus;
    for cell in tissue.cells_mut() {
        let p = truth["pressures"][cell.id().0.to_string()].as_f64().unwrap() * per_length;
        let v = cell.mesh().signed_volume();
        cell.set_target_volume(v * (p / k).exp());
    }
    let mut sim = Simulation::new(tissue, &params).unwrap();
    let summary = sim.run(&mut NoObserver).unwrap();
    (evolver, measure(sim.tissue()), summary.residual)
}

/// Issue 25, per-cell parameters against an outside truth: Evolver's heterogeneous cluster (hetero4:
/// cell–medium tension 1, six cell–cell tensions 0.9–1.7) is additive, T_ij = a_i + a_j, so one
/// lateral tension per cell (`[[cell_overrides]]`, γ_l,i = a_i mN/m) is its model. Started from
/// Evolver's equilibrium with them, ours stays there within the tetrahedral cluster's bounds; with
/// one lateral tension for all cells (their mean, the best a per-type model can do) it moves away.
#[test]
fn heterogeneous_cluster_stays_at_the_evolver_equilibrium_only_with_per_cell_tensions() {
    let interfaces = truth("hetero4")["interfaces"].as_object().unwrap().clone();
    // a_i by least squares over the six pairs (4 unknowns): the residual says whether it is additive.
    let mut m = nalgebra::DMatrix::<Real>::zeros(interfaces.len(), 4);
    let mut t = nalgebra::DVector::<Real>::zeros(interfaces.len());
    for (row, (pair, v)) in interfaces.iter().enumerate() {
        let (a, b) = pair.split_once('-').unwrap();
        m[(row, a.parse::<usize>().unwrap() - 1)] = 1.0;
        m[(row, b.parse::<usize>().unwrap() - 1)] = 1.0;
        t[row] = v["tension"].as_f64().unwrap();
    }
    let a = m.clone().svd(true, true).solve(&t, 1e-12).unwrap();
    assert!((&m * &a - &t).amax() < 1e-9, "hetero4 is not additive: {a}");
    let own: Vec<CellOverrideConfig> = (0..4)
        .map(|i| CellOverrideConfig {
            id: i as u32 + 1,
            surface_tension: PerFaceType { lateral: Some(a[i] * 1e-3), ..PerFaceType::default() },
            adhesion: PerFaceType::default(),
        })
        .collect();
    let (evolver, ours, residual) = relax_at_evolver_pressures("hetero4", |p| p.cell_overrides = own);
    let d = differences(&evolver, &ours);
    report(&format!("hetero4, per-cell γ_l = ({:.2}, {:.2}, {:.2}, {:.2}) mN/m", a[0], a[1], a[2], a[3]), &d, residual);
    let mean = a.mean();
    let (evolver, uniform, residual) =
        relax_at_evolver_pressures("hetero4", |p| p.cell_types[0].faces.lateral.surface_tension = mean * 1e-3);
    let u = differences(&evolver, &uniform);
    report(&format!("hetero4, one γ_l = {mean:.2} mN/m for all cells"), &u, residual);
    eprintln!("per-cell {d:?}, uniform {u:?}");
    // Measured: per-cell 0.60° (far field), 2.9 % (areas), 7e-4 (sphericity); one γ_l for all 33.6°,
    // 258 %. The bounds are the tetrahedral cluster's for angles and sphericity; the areas get 4 %
    // (2 % there) because they drift slowly in longer runs (5.7 % after 9,000 steps: not understood,
    // see docs/src/validation/evolver.md). Rim angles are not asserted: with per-cell tensions ours
    // read up to 25° below Evolver's while the far-field angles agree (also in the docs).
    assert!(d[0] < 1.0, "far-field angles off by {:.2}°", d[0]);
    assert!(d[2] < 0.04, "contact areas off by {:.1} %", 100.0 * d[2]);
    assert!(d[3] < 2e-3, "sphericity off by {:.4}", d[3]);
    assert!(u[0] > 20.0 && u[2] > 1.0, "one lateral tension for all cells matched the heterogeneous cluster: {u:?}");
}

#[test]
fn planar_triplet_stays_at_the_evolver_equilibrium() {
    let (evolver, ours, residual) = relax("triplet", true, 3000);
    let d = differences(&evolver, &ours);
    report("planar triplet, 0.85", &d, residual);
    assert!(d[0] < 1.0, "far-field angles off by {:.2}°", d[0]);
    assert!(d[2] < 0.01, "contact areas off by {:.1} %", 100.0 * d[2]);
    assert!(d[3] < 1e-3, "sphericity off by {:.4}", d[3]);
    // Before junction groups reached 2c the three cells' meshes churned at the junction (824 splits
    // and 1,156 collapses in these 3,000 steps), its nodes stopped coinciding, the junction opened and
    // the contacts ended 9 % small (docs: validation, Surface Evolver clusters). l_max = 3.5·l_min
    // (`max_edge_ratio`) calms the churn: the same contacts, 4 splits.
    let (evolver, slack, residual) = relax_with("triplet", 3000, |p| p.numerics.max_edge_ratio = 3.5);
    let p = differences(&evolver, &slack);
    report("planar triplet, 0.85, l_max = 3.5·l_min (`max_edge_ratio = 3.5`)", &p, residual);
    assert!(p[0] < 1.0 && p[2] < 0.01, "{p:?}");
}

/// The 12-cell ball (151 junction vertices shared by three cells, 18 quadruple points), relaxed
/// from Evolver's mesh at its own tensions like the others. Measured 2026-11-27 (after the contact
/// sign at folded features came from the winding number): the total contact area stays within
/// 0.9 % and 35 of its 38 contacts within 5 % (30 within 2 %), the worst at −6.3 %, sphericity within
/// 2e-3. Before that fix two contacts of cell 4 grew by 10.5 and 10.8 %: a node a few nanometres
/// from a folded junction sliver had been read as inside its neighbour and pushed out. The bounds
/// keep the measured values with a margin; the docs' table row shows the worst contact.
#[test]
fn twelve_cell_ball_stays_near_the_evolver_equilibrium() {
    let (evolver, ours, residual) = relax("ball12", true, 3000);
    let d = differences(&evolver, &ours);
    report("12-cell ball, 0.85 (worst of 38 contacts; see the text)", &d, residual);
    let changes = contact_area_changes(&evolver, &ours);
    let total = changes.iter().map(|c| c.1).sum::<Real>() / changes.iter().map(|c| c.0).sum::<Real>() - 1.0;
    let off = changes.iter().filter(|c| (c.1 / c.0 - 1.0).abs() > 0.05).count();
    eprintln!(
        "ball12: total contact area {:+.2} %, {off} of {} contacts off by more than 5 %",
        100.0 * total,
        changes.len()
    );
    let worst = changes.iter().map(|c| (c.1 / c.0 - 1.0).abs()).fold(0.0, Real::max);
    assert!(total.abs() < 0.01, "total contact area off by {:.2} %", 100.0 * total);
    assert!(worst < 0.08, "a contact off by {:.1} %: {changes:?}", 100.0 * worst);
    assert!(off <= 3, "{off} contacts off by more than 5 %: {changes:?}");
    assert!(d[3] < 2e-3, "sphericity off by {:.4}", d[3]);
}

/// (Evolver, ours) scale-free contact areas A/V^(2/3) of every contact.
/// The price of `numerics.coupling_persistent_junctions` (which keeps a generated 200-cell spheroid
/// from passing through itself; docs: simulation, coupling): on the ball, whose junctions must
/// re-form as it relaxes, the worst contact and rim angle move farther than with the default. The
/// row goes into the docs' table; the bounds are the ones the option measured, so that it gets no
/// worse unnoticed.
#[test]
fn twelve_cell_ball_with_persistent_junction_groups_stays_within_its_measured_bounds() {
    let (evolver, ours, residual) = relax_with("ball12", 3000, |p| p.numerics.coupling_persistent_junctions = true);
    let d = differences(&evolver, &ours);
    report("12-cell ball, 0.85, coupling_persistent_junctions (worst of 38 contacts)", &d, residual);
    let changes = contact_area_changes(&evolver, &ours);
    let total = changes.iter().map(|c| c.1).sum::<Real>() / changes.iter().map(|c| c.0).sum::<Real>() - 1.0;
    let worst = changes.iter().map(|c| (c.1 / c.0 - 1.0).abs()).fold(0.0, Real::max);
    assert!(total.abs() < 0.01, "total contact area off by {:.2} %", 100.0 * total);
    assert!(worst < 0.12, "a contact off by {:.1} %", 100.0 * worst);
    assert!(d[1] < 12.0 && d[3] < 2e-3, "rim angle off by {:.1}°, sphericity by {:.4}", d[1], d[3]);
}

fn contact_area_changes(evolver: &Morphology, ours: &Morphology) -> Vec<(Real, Real)> {
    evolver.contacts.iter().zip(&ours.contacts).map(|(e, o)| (scaled_area(evolver, e), scaled_area(ours, o))).collect()
}

/// The scale-free area A/V^(2/3) of a contact (V: the mean volume of its two cells).
fn scaled_area(m: &Morphology, c: &tissuefit::morphology::ContactMorphology) -> Real {
    let volume = |id: u32| m.cells.iter().find(|x| x.cell == id).unwrap().volume;
    c.area / (0.5 * (volume(c.cell_a) + volume(c.cell_b))).powf(2.0 / 3.0)
}

/// Evolver's meshes are conforming: a vertex on an interface, a junction line or a quadruple point
/// is one node of each cell sharing it, at the same place. At the start every such set must be one
/// tied group (a quadruple point's four nodes included: diagonal cells there meet at a corner, whose
/// node normals need not face each other).
#[test]
fn every_shared_evolver_vertex_of_the_twelve_cell_ball_is_one_tied_group() {
    let tissue = evolver_tissue("ball12");
    let mut shared: std::collections::BTreeMap<[i64; 3], Vec<(u32, u32)>> = Default::default();
    for (c, cell) in tissue.cells().iter().enumerate() {
        for (n, p) in cell.mesh().positions().iter().enumerate() {
            let key = [p.x, p.y, p.z].map(|x| (x * 1e12).round() as i64);
            shared.entry(key).or_default().push((c as u32, n as u32));
        }
    }
    let params = validation_params("ball12", 0, |_| {});
    let mut sim = Simulation::new(tissue.clone(), &params).unwrap();
    sim.run(&mut NoObserver).unwrap();
    let mut group_of = std::collections::HashMap::new();
    for (g, group) in sim.coupled_groups().enumerate() {
        for &m in group {
            group_of.insert(m, (g, group.len()));
        }
    }
    let mut by_size = [[0usize; 2]; 5];
    for members in shared.values().filter(|m| m.len() > 1) {
        let k = members.len().min(4);
        // One group holds them all (with, at most, a node of a third cell nearby: the junction reach).
        let whole = members.iter().all(|m| {
            group_of
                .get(m)
                .is_some_and(|&(g, len)| len >= members.len() && Some(g) == group_of.get(&members[0]).map(|x| x.0))
        });
        by_size[k][usize::from(whole)] += 1;
    }
    println!(
        "shared vertices by cells sharing them, [not one group, one group]: 2 {:?}, 3 {:?}, 4 {:?}",
        by_size[2], by_size[3], by_size[4]
    );
    assert!(by_size[4][1] > 10, "too few quadruple points: {by_size:?}");
    assert_eq!(by_size[4][0], 0, "quadruple points left apart: {by_size:?}");
    assert_eq!(by_size[3][0], 0, "junction-line vertices left apart: {by_size:?}");
}

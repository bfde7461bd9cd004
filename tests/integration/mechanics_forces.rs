//! Internal forces are the exact negative gradients of their energies (central finite differences),
//! and exert no net force or torque.

use tissuefit::geometry::{Real, Vec3};
use tissuefit::mechanics::{CellForces, CellTerm, CellTypeParams, Parameters, TermSet};
use tissuefit::mesh::shapes::icosphere;
use tissuefit::mesh::{Cell, CellId, CellKind, FaceType};

/// Deterministic pseudo-random numbers in [-1, 1] (no test dependency on a RNG crate).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> Real {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 11) as Real / (1u64 << 53) as Real) * 2.0 - 1.0
    }
}

/// A 5 µm icosphere with every node moved by up to 15 % of the edge length, face types cycling
/// through apical/lateral/basal, and a target volume 10 % below the volume (so pressure acts).
fn perturbed_cell(subdivisions: u32, seed: u64) -> Cell {
    let mut mesh = icosphere(5e-6, subdivisions, Vec3::new(1e-5, -3e-6, 2e-6));
    let l = mesh.edge_length_stats().unwrap().mean;
    let mut rng = Lcg(seed);
    for p in mesh.positions_mut() {
        *p += 0.15 * l * Vec3::new(rng.next(), rng.next(), rng.next());
    }
    let faces = mesh.face_count();
    let types = (0..faces).map(|f| FaceType::ALL[(f * 7 / 3) % 3]).collect();
    let v = mesh.signed_volume();
    Cell::new(CellId(3), CellKind::Epithelial, 0, mesh).with_face_types(types).unwrap().with_target_volume(0.9 * v)
}

/// Parameters with different values on each face type, all terms active.
fn params() -> CellTypeParams {
    let mut p = Parameters::default().cell_types[0].clone();
    p.faces.apical.surface_tension = 1e-3;
    p.faces.lateral.surface_tension = 4e-4;
    p.faces.basal.surface_tension = 2.5e-3;
    p.faces.apical.bending_modulus = 2e-18;
    p.faces.lateral.bending_modulus = 5e-19;
    p.faces.basal.bending_modulus = 1e-18;
    p.area_elasticity = 1e-15;
    p.target_isoperimetric_ratio = 150.0;
    p.max_pressure = Real::INFINITY;
    p
}

fn energy(cell: &Cell, p: &CellTypeParams, terms: TermSet) -> Real {
    let mut w = CellForces::default();
    w.compute(cell, p, terms);
    w.energy.total()
}

/// Compares forces with −∇U by central differences at a sample of nodes; returns the worst
/// error relative to the largest force component.
fn gradient_error(cell: &Cell, p: &CellTypeParams, terms: TermSet) -> Real {
    let mut w = CellForces::default();
    w.compute(cell, p, terms);
    let fmax = w.forces.iter().flat_map(|f| f.iter().map(|c| c.abs())).fold(0.0, Real::max);
    assert!(fmax > 0.0, "{terms:?}: no force at all");
    let l = cell.mesh().edge_length_stats().unwrap().mean;
    // h = 1e-4·l: truncation error ~ (h/l)² ≈ 1e-8, round-off ε·|U|/h well below 1e-8 of the forces.
    let h = 1e-4 * l;
    let mut worst: Real = 0.0;
    let n = cell.mesh().node_count();
    for node in (0..n).step_by((n / 40).max(1)) {
        for axis in 0..3 {
            let mut plus = cell.clone();
            plus.positions_mut()[node][axis] += h;
            let mut minus = cell.clone();
            minus.positions_mut()[node][axis] -= h;
            let fd = -(energy(&plus, p, terms) - energy(&minus, p, terms)) / (2.0 * h);
            worst = worst.max((fd - w.forces[node][axis]).abs() / fmax);
        }
    }
    worst
}

#[test]
fn every_term_and_the_total_is_minus_the_gradient_of_its_energy() {
    let p = params();
    for (subdivisions, seed) in [(2, 1), (3, 2)] {
        let cell = perturbed_cell(subdivisions, seed);
        for name in CellTerm::ALL {
            let e = gradient_error(&cell, &p, TermSet::only(name));
            assert!(e <= 1e-6, "{name} at {subdivisions} subdivisions: relative error {e:e}");
        }
        let e = gradient_error(&cell, &p, TermSet::ALL);
        assert!(e <= 1e-6, "total at {subdivisions} subdivisions: relative error {e:e}");
    }
}

#[test]
fn capped_pressure_is_still_a_gradient() {
    // V0 far above V: −K ln(V/V0) ≈ 260 Pa exceeds the cap of 100 Pa, so the capped branch is used.
    let mut p = params();
    p.max_pressure = 100.0;
    let cell = perturbed_cell(2, 5);
    let v = cell.mesh().signed_volume();
    let cell = cell.with_target_volume(1.11 * v);
    let mut w = CellForces::default();
    w.compute(&cell, &p, TermSet::ALL);
    assert_eq!(w.pressure, 100.0);
    let e = gradient_error(&cell, &p, TermSet::only(CellTerm::Pressure));
    assert!(e <= 1e-6, "capped pressure: relative error {e:e}");
}

#[test]
fn internal_forces_have_no_net_force_or_torque() {
    let p = params();
    let cell = perturbed_cell(3, 9);
    for name in CellTerm::ALL {
        let mut w = CellForces::default();
        w.compute(&cell, &p, TermSet::only(name));
        let positions = cell.mesh().positions();
        let scale: Real = w.forces.iter().map(|f| f.norm()).sum();
        let net: Vec3 = w.forces.iter().sum();
        // Torque about the cell's own centre, so the lever arms are the cell's size.
        let c = cell.mesh().volume_centroid().unwrap();
        let torque: Vec3 = positions.iter().zip(&w.forces).map(|(r, f)| (r - c).cross(f)).sum();
        let lever = 5e-6;
        assert!(net.norm() <= 1e-12 * scale, "{name}: net force {net:?} vs Σ|f| {scale:e}");
        assert!(torque.norm() <= 1e-12 * scale * lever, "{name}: net torque {torque:?}");
    }
}

#[test]
fn forces_do_not_depend_on_where_the_cell_is() {
    // Translation invariance: moving the cell 1 mm away changes forces only at round-off.
    let p = params();
    let cell = perturbed_cell(2, 11);
    let mut moved = cell.clone();
    moved.positions_mut().iter_mut().for_each(|r| *r += Vec3::new(1e-3, 0.0, 0.0));
    let (mut a, mut b) = (CellForces::default(), CellForces::default());
    a.compute(&cell, &p, TermSet::ALL);
    b.compute(&moved, &p, TermSet::ALL);
    let fmax = a.forces.iter().map(|f| f.norm()).fold(0.0, Real::max);
    let diff = a.forces.iter().zip(&b.forces).map(|(x, y)| (x - y).norm()).fold(0.0, Real::max);
    assert!(diff <= 1e-6 * fmax, "translation changed forces by {diff:e} of {fmax:e}");
}

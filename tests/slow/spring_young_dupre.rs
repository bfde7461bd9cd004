//! Spring contacts against Young–Dupré (issue 20): a doublet of equal cells (tension γ on every face,
//! spring adhesion w = ωc²/2 per contact) relaxed with full forces and remeshing, from touching spheres
//! and from an over-adhered start, must end at the external half-angle of cos(θ/2) = 1 − w/(2γ),
//! read in the far field (sphere fits to the free caps, `tests/integration/support/young_dupre.rs`).
//!
//! With the face quadrature (`numerics.contact_quadrature = "faces"`) the contact line moves to
//! Young–Dupré from both sides. The vertex quadrature (the default) misses it by 3–6° on these same
//! doublets (receding and advancing) and churns the remesher: the docs' regime table
//! (docs/src/generated/spring-regime.md, `docs/scripts/spring_regime.py`) has both.
//!
//! Tolerance ±3° (the issue's, at ≈ 600 nodes per cell): at l_min = c the face quadrature ends
//! +1.6…+1.9° above Young–Dupré after 40,000 steps (the rim, rounded over one element and a well of
//! width c = R/10, is not a sharp wedge), at l_min = 2.5·c within 0.4°. The overlap bound 0.5 % of
//! a cell's volume is the issue's.

use tissuefit::geometry::Real;
use tissuefit::mechanics::{ContactQuadrature, NoObserver, Simulation};

use crate::support::young_dupre;
use young_dupre::{Doublet, far_field_half_angles, params, start, young_dupre};

/// Relaxes `a` and checks the far-field half-angle of both cells and the overlap.
fn check(a: Doublet) {
    let p = params(&a);
    let mut sim = Simulation::new(start(&a), &p).unwrap();
    let summary = sim.run(&mut NoObserver).unwrap();
    let [ha, hb] = far_field_half_angles(sim.tissue(), 0.3 * a.radius);
    let yd = young_dupre(a.ratio);
    let what = format!(
        "R = {} µm, l_min = {} µm, c = {} µm, w/(2γ) = {}, {} start: half-angles {ha:.2}°/{hb:.2}° against \
         Young–Dupré {yd:.2}°, overlap {:.3} %, {} splits + {} collapses",
        a.radius * 1e6,
        a.lmin * 1e6,
        a.cutoff * 1e6,
        a.ratio,
        if a.over { "over-adhered" } else { "touching" },
        100.0 * summary.max_overlap_fraction,
        summary.topology.splits,
        summary.topology.collapses
    );
    eprintln!("{what}");
    for h in [ha, hb] {
        assert!((h - yd).abs() <= 3.0, "{what}");
    }
    assert!(summary.max_overlap_fraction <= 0.005, "{what}");
}

fn faces(radius_um: Real, lmin_um: Real, cutoff_um: Real, ratio: Real, over: bool) -> Doublet {
    Doublet {
        radius: radius_um * 1e-6,
        lmin: lmin_um * 1e-6,
        cutoff: cutoff_um * 1e-6,
        ratio,
        over,
        steps: 40_000,
        quadrature: ContactQuadrature::Faces,
        ..Doublet::default()
    }
}

/// Advancing: from touching spheres the contact spreads to Young–Dupré (l_min = c; the vertex
/// quadrature stopped at −6.3°).
#[test]
fn face_quadrature_doublet_spreads_to_young_dupre_from_touching_spheres() {
    check(faces(2.0, 0.2, 0.2, 0.3, false));
}

/// Receding: from a contact 15° too wide the line retracts to Young–Dupré (the vertex quadrature:
/// −3.4°).
#[test]
fn face_quadrature_doublet_recedes_to_young_dupre_from_an_over_adhered_start() {
    check(faces(2.0, 0.2, 0.2, 0.1, true));
}

/// Strong adhesion, w/(2γ) = 0.5 (the vertex quadrature: −5.1°, 15,000 remeshing operations).
#[test]
fn face_quadrature_doublet_with_strong_adhesion_reaches_young_dupre() {
    check(faces(2.0, 0.2, 0.2, 0.5, false));
}

/// A coarse mesh against a narrow well, l_min = 2.5·c, at R = 5 µm.
#[test]
fn face_quadrature_doublet_on_a_mesh_coarser_than_the_well_reaches_young_dupre() {
    check(faces(5.0, 0.5, 0.2, 0.3, false));
}

/// A large cell, R = 10 µm on 1 µm elements, l_min = 2·c, spreading from touching spheres. Here the
/// repulsion's stiffness ξ·a_p ≈ 0.9 N/m is ~900 times the tension's γ = 1e-3 N/m; with unit masses
/// FIRE's step was held down by it and the contact stopped 13.6° short of Young–Dupré after 40,000
/// steps (the regime table of the design note "Spring contacts and Young–Dupré", made before the
/// change). FIRE now makes nodes in contact heavier along their contact direction
/// (`Simulation::contact_masses`): +1.1° in the same steps.
#[test]
fn face_quadrature_doublet_of_large_cells_spreads_to_young_dupre() {
    check(faces(10.0, 1.0, 0.5, 0.1, false));
}

/// The normal relaxation (`simulation.normal_relaxation`, with FIRE's measured masses as the
/// "aggregate" preset relaxes) pins the contact line: from touching spheres at w/(2γ) = 0.5 it
/// reports converged about 17° short of Young–Dupré (docs/src/generated/contact-full-forces.md), a
/// state that is not an equilibrium of the energy. With the contact nodes' full forces
/// (`simulation.full_forces_at_contacts`) the line spreads to Young–Dupré (+0.7° in the table).
/// Both runs here, so that a fix of the pinning or a loss of the spreading both show.
#[test]
fn normal_relaxation_spreads_to_young_dupre_only_with_the_contact_nodes_full_forces() {
    let base = Doublet { steps: 20_000, normal: true, measured_masses: true, ..faces(5.0, 0.5, 0.2, 0.5, false) };
    let pinned = base.clone();
    let p = params(&pinned);
    let mut sim = Simulation::new(start(&pinned), &p).unwrap();
    sim.run(&mut NoObserver).unwrap();
    let [ha, hb] = far_field_half_angles(sim.tissue(), 0.3 * pinned.radius);
    let yd = young_dupre(pinned.ratio);
    eprintln!("normal relaxation alone: half-angles {ha:.2}°/{hb:.2}° against Young–Dupré {yd:.2}°");
    assert!(ha < yd - 10.0 && hb < yd - 10.0, "the pinning this test is about: {ha:.2}°/{hb:.2}° vs {yd:.2}°");
    check(Doublet { contact_full_forces: true, ..base });
}

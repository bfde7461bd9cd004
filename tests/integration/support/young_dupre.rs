//! Spring-contact doublets against Young–Dupré (issue 20), shared by `examples/spring_regime.rs`
//! (the regime table of the docs) and `tests/slow/spring_young_dupre.rs`: two equal cells with surface
//! tension γ on every face and the spring adhesion ω, relaxed to equilibrium, and their far-field
//! contact half-angle (a sphere fitted to each free cap, the interface plane through the midpoint
//! of the two centres).
#![allow(dead_code)]

use tissuefit::geometry::{Real, Vec3};
use tissuefit::mechanics::{ContactModel, ContactQuadrature, Parameters, Polarity, RelaxMethod, SimulationMode};
use tissuefit::mesh::shapes::icosphere;
use tissuefit::mesh::{Cell, CellId, CellKind, FaceType, Tissue};
use tissuefit::morphology::far_field::fit_sphere;

/// Surface tension of every face (N/m).
pub const GAMMA: Real = 1e-3;

/// One doublet run: geometry (m), adhesion, start and relaxation.
#[derive(Clone, Debug)]
pub struct Doublet {
    pub radius: Real,
    pub lmin: Real,
    pub cutoff: Real,
    /// w/(2γ) = ωc²/(4γ).
    pub ratio: Real,
    /// Start from truncated spheres whose flat contact lies 15° beyond Young–Dupré's half-angle
    /// (false: spheres 0.25·c apart).
    pub over: bool,
    pub normal: bool,
    pub steps: u64,
    pub settle: u64,
    /// Repulsion ξ (Pa/m).
    pub xi: Real,
    pub integrate: bool,
    pub remesh: u64,
    pub quadrature: ContactQuadrature,
    /// FIRE with unit masses everywhere (`Simulation::set_fire_contact_masses(false)`).
    pub unit_masses: bool,
    /// FIRE's masses from the nodes' measured stiffnesses (`simulation.fire_measured_masses`).
    pub measured_masses: bool,
    /// With `normal`: contact nodes keep their whole force (`simulation.full_forces_at_contacts`).
    pub contact_full_forces: bool,
}

impl Default for Doublet {
    fn default() -> Self {
        Self {
            radius: 2e-6,
            lmin: 2e-7,
            cutoff: 2e-7,
            ratio: 0.3,
            over: false,
            normal: false,
            steps: 8000,
            settle: 0,
            xi: 1e12,
            integrate: false,
            remesh: 50,
            quadrature: ContactQuadrature::Vertices,
            unit_masses: false,
            measured_masses: false,
            contact_full_forces: false,
        }
    }
}

/// Young–Dupré half-angle (degrees) for w/(2γ) = `ratio`.
pub fn young_dupre(ratio: Real) -> Real {
    (1.0 - ratio).clamp(-1.0, 1.0).acos().to_degrees()
}

/// An icosphere of radius `r` fine enough for edges near `lmin`, centred at x = `x`; with `flat`,
/// its nodes beyond the plane x = `plane` (on the side away from the centre) are moved onto it.
pub fn cell(id: u32, r: Real, lmin: Real, x: Real, flat: Option<Real>) -> Cell {
    let subdivisions = ((1.1 * r / lmin).log2().round() as u32).clamp(2, 5);
    let mut mesh = icosphere(r, subdivisions, Vec3::new(x, 0.0, 0.0));
    if let Some(plane) = flat {
        let side = (plane - x).signum();
        for p in mesh.positions_mut() {
            if (p.x - plane) * side > 0.0 {
                p.x = plane;
            }
        }
    }
    let types = vec![FaceType::Basal; mesh.face_count()];
    Cell::new(CellId(id), CellKind::Epithelial, 0, mesh).with_face_types(types).expect("one type per face")
}

pub fn params(a: &Doublet) -> Parameters {
    let mut p = Parameters::default();
    p.numerics.contact_model = ContactModel::Spring;
    p.numerics.contact_quadrature = a.quadrature;
    p.numerics.polarity = Polarity::None;
    p.numerics.min_edge_length = a.lmin;
    p.numerics.contact_cutoff = a.cutoff;
    // Only integration uses it (and validation checks it against the contact stiffness).
    p.numerics.time_step = 2e-8;
    let omega = 4.0 * a.ratio * GAMMA / (a.cutoff * a.cutoff);
    let t = &mut p.cell_types[0];
    for ft in FaceType::ALL {
        let f = t.faces.get_mut(ft);
        f.surface_tension = GAMMA;
        f.adhesion = omega;
        f.repulsion = a.xi;
        f.bending_modulus = 0.0;
    }
    t.area_elasticity = 0.0;
    t.max_pressure = Real::INFINITY;
    t.growth_rate = 0.0;
    t.laplace_target_volume = true;
    let s = &mut p.simulation;
    s.mode = SimulationMode::Equilibrium;
    s.method = if a.integrate { RelaxMethod::Integrate } else { RelaxMethod::Fire };
    s.remesh_every_steps = a.remesh;
    s.max_steps = a.steps;
    s.settle_steps = a.settle;
    s.normal_relaxation = a.normal;
    s.fire_measured_masses = a.measured_masses;
    s.full_forces_at_contacts = a.contact_full_forces;
    s.sample_every_steps = a.steps + 1;
    p
}

/// Far-field half-angles of both cells: each free cap (nodes farther than `margin` from the other
/// cell's centre side of the midplane) fitted by a sphere; cos ψ = h/ρ with h the distance from the
/// cap's centre to the midplane (positive on its own side).
pub fn far_field_half_angles(t: &Tissue, margin: Real) -> [Real; 2] {
    let centroid = |c: &Cell| c.mesh().positions().iter().sum::<Vec3>() / c.mesh().node_count() as Real;
    let [a, b] = [&t.cells()[0], &t.cells()[1]];
    let (ca, cb) = (centroid(a), centroid(b));
    let axis = (cb - ca).normalize();
    let mid = 0.5 * (ca + cb);
    let mut out = [0.0; 2];
    for (k, (cell, towards)) in [(a, -axis), (b, axis)].into_iter().enumerate() {
        let cap: Vec<Vec3> =
            cell.mesh().positions().iter().copied().filter(|p| (p - mid).dot(&towards) > margin).collect();
        let (sphere, _) = fit_sphere(&cap).expect("a free cap fixes a sphere");
        let h = (sphere.centre - mid).dot(&towards);
        out[k] = (h / sphere.radius).clamp(-1.0, 1.0).acos().to_degrees();
    }
    out
}

/// The starting tissue of `a`.
pub fn start(a: &Doublet) -> Tissue {
    let (r, c) = (a.radius, a.cutoff);
    let cells = if a.over {
        let psi = (young_dupre(a.ratio) + 15.0).min(80.0).to_radians();
        let x = r * psi.cos() + 0.25 * c;
        vec![cell(1, r, a.lmin, -x, Some(-0.25 * c)), cell(2, r, a.lmin, x, Some(0.25 * c))]
    } else {
        let x = r + 0.25 * c;
        vec![cell(1, r, a.lmin, -x, None), cell(2, r, a.lmin, x, None)]
    };
    Tissue::from_cells(cells).expect("two valid cells")
}

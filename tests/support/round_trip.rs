//! The model of the fit round trips, shared by `tests/fit.rs` and `examples/fit_aggregate.rs`.

use tissuefit::geometry::Real;
use tissuefit::mechanics::{ContactModel, Dynamics, Parameters, Polarity, RelaxMethod, SimulationMode};
use tissuefit::mesh::FaceType;

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

//! Equations of motion (paper Methods, "Time integration").
//!
//! * Dynamic: m·r̈ + ζ·ṙ = f with node mass m = ρV/N (cell volume V, N nodes), integrated by
//!   semi-implicit Euler on momenta: p ← p + Δt·(f − ζ·p/m), r ← r + Δt·p/m.
//! * Overdamped: ζ·ṙ = f, forward Euler: r ← r + Δt·f/ζ.
//!
//! Cells of immobile kinds (ECM, static) never move. Each cell is updated independently, in
//! parallel, so the result does not depend on the thread count.

use super::{CellForces, CellTypeParams, Dynamics, Numerics};
use crate::geometry::{Real, Vec3};
use crate::mesh::Tissue;
use rayon::prelude::*;

/// Advances positions (and momenta, for the dynamic model) by one time step with the forces of
/// the current positions. `momenta[c]` must have one entry per node of cell c.
pub fn integrate_step(
    tissue: &mut Tissue,
    forces: &[CellForces],
    cell_params: &[CellTypeParams],
    momenta: &mut [Vec<Vec3>],
    numerics: &Numerics,
) {
    let (dt, zeta) = (numerics.time_step, numerics.damping);
    tissue
        .cells_mut()
        .par_iter_mut()
        .zip(forces.par_iter())
        .zip(cell_params.par_iter())
        .zip(momenta.par_iter_mut())
        .for_each(|(((cell, work), p), momentum)| {
            if cell.kind().is_immobile() {
                return;
            }
            let f = &work.forces;
            match numerics.dynamics {
                Dynamics::Overdamped => {
                    let s = dt / zeta;
                    for (r, f) in cell.positions_mut().iter_mut().zip(f) {
                        *r += s * f;
                    }
                }
                Dynamics::Dynamic => {
                    let nodes = f.len() as Real;
                    let mass = p.mass_density * work.geometry.volume / nodes;
                    let (damp, inv_m) = (zeta / mass, 1.0 / mass);
                    for ((r, f), m) in cell.positions_mut().iter_mut().zip(f).zip(momentum.iter_mut()) {
                        *m += dt * (f - damp * *m);
                        *r += (dt * inv_m) * *m;
                    }
                }
            }
        });
}

//! Cytoplasmic pressure (paper Methods, "Pressure").
//!
//! p = −K ln(V/V0), optionally capped from above at p_max. The energy whose derivative this is,
//! U = K·V·(ln(V/V0) − 1) (so that −dU/dV = p), is continued below the cap volume
//! V_c = V0·exp(−p_max/K) by the tangent line U(V_c) − p_max·(V − V_c), which keeps U continuously
//! differentiable and the capped force its exact negative gradient.
//!
//! Force: F_i = −∂U/∂r_i = p·∂V/∂r_i = (p/3)·Σ_f A_f n̂_f over the faces f around node i (exact on a
//! closed surface), i.e. every face pushes each of its three nodes by (p/3)·A_f n̂_f
//! ([`face_force`], applied in the shared pass over the faces of `forces.rs`).

use super::CellTypeParams;
use super::forces::Prepared;
use crate::geometry::{Real, Vec3};
use crate::mesh::Cell;

/// Pressure (Pa) and energy (J) of a cell of volume `v` with target volume `v0`, bulk modulus `k`
/// (Pa) and pressure cap `p_max` (Pa, `inf` for none). `k = 0` gives no pressure.
pub fn pressure_energy(v: Real, v0: Real, k: Real, p_max: Real) -> (Real, Real) {
    if k == 0.0 {
        return (0.0, 0.0);
    }
    let p = -k * (v / v0).ln() + 0.0; // + 0.0 turns −0 into 0
    if p <= p_max {
        (p, k * v * ((v / v0).ln() - 1.0))
    } else {
        let v_cap = v0 * (-p_max / k).exp();
        let u_cap = k * v_cap * (-p_max / k - 1.0);
        (p_max, u_cap - p_max * (v - v_cap))
    }
}

/// Pressure (Pa) and energy (J) of `cell` at volume `volume` (m³), with its type's K and p_max.
pub(super) fn cell_pressure(cell: &Cell, p: &CellTypeParams, volume: Real) -> (Real, Real) {
    pressure_energy(volume, cell.target_volume(), p.bulk_modulus, p.max_pressure)
}

/// The term's per-cell preparation, from the cell's [`cell_pressure`]: its energy, and its
/// −∂U/∂V = p for the shared face pass.
pub(super) fn prepare(pressure: Real, energy: Real) -> Prepared {
    Prepared { energy, pressure, ..Prepared::NONE }
}

/// Force (N) of a pressure on each of the three nodes of one face: (p/3)·A_f n̂_f, from p/3 (Pa)
/// and the face's area vector A_f n̂_f (m²).
#[inline(always)]
pub(super) fn face_force(p_third: Real, area_vector: &Vec3) -> Vec3 {
    p_third * area_vector
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::triangle_area_vector;

    /// On a closed surface (a tetrahedron) the faces' pushes add up to p·∂V/∂r_i at every node:
    /// central differences of the volume (step 1e-6 of the size, well inside 1e-7 relative).
    #[test]
    fn face_forces_add_up_to_the_pressure_times_the_volume_gradient() {
        let r = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.1e-6, 0.0, 0.1e-6),
            Vec3::new(0.2e-6, 0.9e-6, 0.0),
            Vec3::new(0.3e-6, 0.2e-6, 1.3e-6),
        ];
        let faces = [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]];
        let volume = |r: &[Vec3; 4]| faces.iter().map(|f| r[f[0]].dot(&r[f[1]].cross(&r[f[2]]))).sum::<Real>() / 6.0;
        assert!(volume(&r) > 0.0, "outward winding");
        let p = 300.0;
        let mut forces = [Vec3::zeros(); 4];
        for f in faces {
            let push = face_force(p / 3.0, &triangle_area_vector(&r[f[0]], &r[f[1]], &r[f[2]]));
            f.iter().for_each(|&n| forces[n] += push);
        }
        let (h, scale) = (1e-12, p * 1e-12);
        for node in 0..4 {
            for axis in 0..3 {
                let (mut plus, mut minus) = (r, r);
                plus[node][axis] += h;
                minus[node][axis] -= h;
                let fd = p * (volume(&plus) - volume(&minus)) / (2.0 * h);
                assert!((fd - forces[node][axis]).abs() <= 1e-7 * scale, "node {node} axis {axis}");
            }
        }
    }
}

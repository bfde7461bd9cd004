//! Membrane area elasticity (paper Methods, "Membrane area elasticity").
//!
//! U = (k_a/2)(A/A0 − 1)² with A = Σ_f A_f the cell's area and the target area A0 = (Q0·V0²)^(1/3)
//! set by the *target* volume V0 and the target isoperimetric ratio Q0. A0 does not depend on node
//! positions, so the force
//!
//! F_i = −(dU/dA)·∇_i A = −(dU/dA)·Σ_f ∇_i A_f,    dU/dA = (k_a/A0)(A/A0 − 1),
//!
//! is the exact gradient (the reference program recomputes A0 from the current volume, which makes
//! its force inconsistent with its energy). dU/dA acts as an extra tension, the same on every face:
//! [`prepare`] hands it to the shared face pass, which applies it with the tension's per-face
//! kernel (`tension::face_forces`, ∇_i A_f = ½ n̂_f × (r_k − r_j)).

use super::CellTypeParams;
use super::cell_geometry::CellGeometry;
use super::forces::Prepared;
use crate::geometry::Real;
use crate::mesh::Cell;

/// Target area A0 = (Q0·V0²)^(1/3) (m²).
pub fn target_area(isoperimetric_ratio: Real, target_volume: Real) -> Real {
    (isoperimetric_ratio * target_volume * target_volume).cbrt()
}

/// Energy (J) and its derivative dU/dA (N/m, an effective extra tension) at area `a`.
pub fn area_elasticity_energy(a: Real, a0: Real, k_a: Real) -> (Real, Real) {
    if k_a == 0.0 {
        return (0.0, 0.0);
    }
    let strain = a / a0 - 1.0;
    (0.5 * k_a * strain * strain, k_a * strain / a0)
}

/// The term's per-cell preparation: its energy, and dU/dA as a tension on every face type.
pub(super) fn prepare(cell: &Cell, p: &CellTypeParams, geometry: &CellGeometry) -> Prepared {
    let a0 = target_area(p.target_isoperimetric_ratio, cell.target_volume());
    let (energy, du_da) = area_elasticity_energy(geometry.area, a0, p.area_elasticity);
    Prepared { energy, tension: [du_da; 3], ..Prepared::NONE }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// dU/dA, the tension the face pass applies, is the derivative of the energy (central
    /// differences in A, step 1e-6 of A0: truncation ~1e-12 relative, inside 1e-6).
    #[test]
    fn the_extra_tension_is_the_derivative_of_the_energy() {
        let (a0, k_a, h) = (3e-10, 1e-15, 3e-16);
        for a in [0.7 * a0, a0, 1.3 * a0] {
            let (_, du_da) = area_elasticity_energy(a, a0, k_a);
            let fd = (area_elasticity_energy(a + h, a0, k_a).0 - area_elasticity_energy(a - h, a0, k_a).0) / (2.0 * h);
            assert!((fd - du_da).abs() <= 1e-6 * k_a / a0, "A/A0 = {}: {fd:e} vs {du_da:e}", a / a0);
        }
    }
}

//! Membrane area elasticity (paper Methods, "Membrane area elasticity").
//!
//! U = (k_a/2)(A/A0 − 1)² with the target area A0 = (Q0·V0²)^(1/3) set by the *target* volume V0
//! and the target isoperimetric ratio Q0. A0 does not depend on node positions, so the force
//! −(k_a/A0)(A/A0 − 1)·∇A is the exact gradient (the reference program recomputes A0 from the
//! current volume, which makes its force inconsistent with its energy).

use crate::geometry::Real;

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

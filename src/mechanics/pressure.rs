//! Cytoplasmic pressure (paper Methods, "Pressure").
//!
//! p = −K ln(V/V0), optionally capped from above at p_max. The energy whose derivative this is,
//! U = K·V·(ln(V/V0) − 1) (so that −dU/dV = p), is continued below the cap volume
//! V_c = V0·exp(−p_max/K) by the tangent line U(V_c) − p_max·(V − V_c), which keeps U continuously
//! differentiable and the capped force its exact negative gradient. The nodal force is
//! p·∂V/∂r_i = (p/3)·Σ_f A_f n̂_f over the faces around node i (exact on a closed surface).

use crate::geometry::Real;

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

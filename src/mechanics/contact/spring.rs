//! The contact stress law of the paper's spring model (Methods, "Intercellular contacts", Eq. 2),
//! and the energy it derives from.
//!
//! With d the signed distance of a node from another cell's surface (positive outside it):
//! σ(d) = ξ·d on [−c, 0) (repulsion, ξ in Pa/m), ω·d on [0, c/2) and ω·(c − d) on [c/2, c]
//! (bilinear adhesion, ω in Pa/m), 0 beyond. σ > 0 pulls the node towards the surface. The energy
//! density per unit area is Φ(d) = −∫_d^c σ(s) ds (J/m²), so that dΦ/dd = σ: Φ = 0 beyond c,
//! −ω(c − d)²/2 on [c/2, c], −ωc²/4 + ω(c²/4 − d²)/2 … continuous down to −c, constant below
//! (the paper's σ vanishes there).

use crate::geometry::Real;

/// Stress σ(d) (Pa) of Eq. 2: [`adhesion_stress`] + [`repulsion_stress`].
pub fn contact_stress(d: Real, cutoff: Real, adhesion: Real, repulsion: Real) -> Real {
    adhesion_stress(d, cutoff, adhesion) + repulsion_stress(d, cutoff, repulsion)
}

/// Energy per unit area Φ(d) (J/m²) whose derivative is [`contact_stress`]:
/// 0 for d ≥ c; −ω(c − d)²/2 on [c/2, c]; −ωc²/4 + ωd²/2 on [0, c/2); −ωc²/4 + ξd²/2 on [−c, 0);
/// constant −ωc²/4 + ξc²/2 below −c. The sum of [`adhesion_energy_density`] and
/// [`repulsion_energy_density`].
pub fn contact_energy_density(d: Real, cutoff: Real, adhesion: Real, repulsion: Real) -> Real {
    adhesion_energy_density(d, cutoff, adhesion) + repulsion_energy_density(d, cutoff, repulsion)
}

/// The adhesive part of Eq. 2's stress (Pa): ω·d on [0, c/2), ω·(c − d) on [c/2, c], 0 elsewhere.
pub fn adhesion_stress(d: Real, cutoff: Real, adhesion: Real) -> Real {
    if !(0.0..=cutoff).contains(&d) {
        0.0
    } else if d < 0.5 * cutoff {
        adhesion * d
    } else {
        adhesion * (cutoff - d)
    }
}

/// The repulsive part of Eq. 2's stress (Pa): ξ·d on [−c, 0), 0 elsewhere.
pub fn repulsion_stress(d: Real, cutoff: Real, repulsion: Real) -> Real {
    if (-cutoff..0.0).contains(&d) { repulsion * d } else { 0.0 }
}

/// The adhesion well A(d) ≤ 0 (J/m²), dA/dd = [`adhesion_stress`]: 0 for d ≥ c, −ω(c − d)²/2 on
/// [c/2, c], −ωc²/4 + ωd²/2 on [0, c/2), and its bottom −ωc²/4 for d < 0. Its depth ωc²/4 is the
/// adhesion energy per unit area of one side of a contact.
pub fn adhesion_energy_density(d: Real, cutoff: Real, adhesion: Real) -> Real {
    let c = cutoff;
    if d >= c {
        0.0
    } else if d >= 0.5 * c {
        -0.5 * adhesion * (c - d) * (c - d)
    } else {
        -0.25 * adhesion * c * c + 0.5 * adhesion * d.max(0.0) * d.max(0.0)
    }
}

/// The repulsion penalty R(d) ≥ 0 (J/m²), dR/dd = [`repulsion_stress`]: ξd²/2 on [−c, 0), ξc²/2 below,
/// 0 for d ≥ 0.
pub fn repulsion_energy_density(d: Real, cutoff: Real, repulsion: Real) -> Real {
    if d >= 0.0 { 0.0 } else { 0.5 * repulsion * d.max(-cutoff).powi(2) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn energy_density_is_continuous_and_its_derivative_is_the_stress() {
        let (c, w, x) = (2e-7, 1e9, 3e9);
        let h = 1e-13;
        let mut d = -1.5 * c;
        while d < 1.5 * c {
            let fd = (contact_energy_density(d + h, c, w, x) - contact_energy_density(d - h, c, w, x)) / (2.0 * h);
            let s = contact_stress(d, c, w, x);
            // Away from the jump at −c, the derivative matches the stress.
            if (d + c).abs() > 2.0 * h {
                assert!((fd - s).abs() <= 1e-6 * w * c, "d = {d:e}: dΦ/dd = {fd:e}, σ = {s:e}");
            }
            d += c / 97.0;
        }
        for knot in [0.0, 0.5 * c, c] {
            let (lo, hi) =
                (contact_energy_density(knot - 1e-18, c, w, x), contact_energy_density(knot + 1e-18, c, w, x));
            assert!((lo - hi).abs() <= 1e-9 * w * c * c, "Φ jumps at {knot:e}");
        }
        assert_eq!(contact_energy_density(0.0, c, w, x), -0.25 * w * c * c);
        assert!(contact_stress(0.75 * c, c, w, x) > 0.0 && contact_stress(-0.5 * c, c, w, x) < 0.0);
    }
}

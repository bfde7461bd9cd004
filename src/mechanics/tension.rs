//! Surface tension (paper Methods, "Surface tension"): U = Σ_f γ_f·A_f with γ_f the tension (N/m)
//! of the face's type (apical, lateral, basal).
//!
//! Force: F_i = −Σ_f γ_f ∇_i A_f over the faces f around node i, with ∇_i A_f = ½ n̂_f × (r_k − r_j)
//! for a face (i, j, k) wound counter-clockwise seen from outside (cyclically for j and k).
//! [`prepare`] hands γ per face type to the shared face pass of `forces.rs`, which calls
//! [`face_forces`] once per face with the tension summed over every area term (area elasticity's
//! dU/dA acts as an extra tension on every face).

use super::CellTypeParams;
use super::cell_geometry::CellGeometry;
use super::forces::Prepared;
use crate::geometry::{Real, Vec3, triangle_area_gradients};
use crate::mesh::FaceType;

/// Tension energy (J) of faces with the given areas and types; `gamma` is indexed by face-type code.
pub fn tension_energy(areas: &[Real], face_types: &[FaceType], gamma: [Real; 3]) -> Real {
    areas.iter().zip(face_types).map(|(a, t)| gamma[t.code() as usize] * a).sum()
}

/// The term's per-cell preparation: its energy, and γ of each face type for the shared face pass.
pub(super) fn prepare(p: &CellTypeParams, geometry: &CellGeometry, face_types: &[FaceType]) -> Prepared {
    let gamma = FaceType::ALL.map(|t| p.faces.get(t).surface_tension);
    Prepared { energy: tension_energy(&geometry.areas, face_types, gamma), tension: gamma, ..Prepared::NONE }
}

/// Forces (N) of a tension `c` (N/m) on the nodes of one face (i, j, k) at `ri`, `rj`, `rk` with
/// unit normal `normal`: −c ∇_i A_f, −c ∇_j A_f, −c ∇_k A_f.
#[inline(always)]
pub(super) fn face_forces(c: Real, ri: &Vec3, rj: &Vec3, rk: &Vec3, normal: &Vec3) -> [Vec3; 3] {
    // c·∇A: the area gradients of the normal scaled by c.
    triangle_area_gradients(ri, rj, rk, &(c * normal)).map(|g| -g)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::triangle_area_vector;

    /// One face's forces are −c ∇A_f: central differences of c·A_f in every coordinate of every
    /// corner (step 1e-6 of the edge: truncation ~1e-12 relative, well inside 1e-7).
    #[test]
    fn face_forces_are_minus_the_tension_times_the_area_gradient() {
        let r = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.2e-6, 0.1e-6, 0.0), Vec3::new(0.3e-6, 0.9e-6, 0.4e-6)];
        let c = 2.5e-3;
        let area = |r: &[Vec3; 3]| triangle_area_vector(&r[0], &r[1], &r[2]).norm();
        let normal = triangle_area_vector(&r[0], &r[1], &r[2]).normalize();
        let forces = face_forces(c, &r[0], &r[1], &r[2], &normal);
        let (h, scale) = (1e-12, c * 1e-6);
        for node in 0..3 {
            for axis in 0..3 {
                let (mut plus, mut minus) = (r, r);
                plus[node][axis] += h;
                minus[node][axis] -= h;
                let fd = -c * (area(&plus) - area(&minus)) / (2.0 * h);
                assert!((fd - forces[node][axis]).abs() <= 1e-7 * scale, "node {node} axis {axis}");
            }
        }
    }
}

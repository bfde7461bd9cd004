//! Surface tension (paper Methods, "Surface tension"): U = Σ_f γ_f·A_f with γ_f the tension of the
//! face's type (apical, lateral, basal), force −Σ_f γ_f ∇_i A_f with ∇_i A_f = ½ n̂_f × (r_k − r_j)
//! for a face (i, j, k) wound counter-clockwise seen from outside.

use crate::geometry::Real;
use crate::mesh::FaceType;

/// Tension energy (J) of faces with the given areas and types; `gamma` is indexed by face-type code.
pub fn tension_energy(areas: &[Real], face_types: &[FaceType], gamma: [Real; 3]) -> Real {
    areas.iter().zip(face_types).map(|(a, t)| gamma[t.code() as usize] * a).sum()
}

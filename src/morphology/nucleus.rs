//! Which cell holds each nucleus: the cell whose closed surface contains the nucleus centroid.
//!
//! Containment uses the generalised winding number w(p) = Σ_faces Ω_f(p) / 4π (Van Oosterom & Strackee
//! 1983 solid angle of a triangle; Jacobson et al. 2013): 1 inside a closed outward surface, 0 outside,
//! and still well defined (fractional) near holes of a defective mesh; p is inside when w > 1/2. No ray
//! is cast, so hitting an edge or a vertex exactly cannot flip the answer.

use crate::geometry::{Real, Vec3};
use crate::mesh::CellMesh;

/// Generalised winding number of `mesh` around `p`: ≈ 1 inside, ≈ 0 outside an outward surface.
pub fn winding_number(mesh: &CellMesh, p: &Vec3) -> Real {
    let x = mesh.positions();
    let mut total = 0.0;
    for t in mesh.triangles() {
        let [a, b, c] = t.map(|i| x[i as usize] - p);
        let (la, lb, lc) = (a.norm(), b.norm(), c.norm());
        let numerator = a.dot(&b.cross(&c));
        let denominator = la * lb * lc + a.dot(&b) * lc + b.dot(&c) * la + c.dot(&a) * lb;
        total += 2.0 * numerator.atan2(denominator);
    }
    total / (4.0 * std::f64::consts::PI)
}

/// Whether `p` lies inside the closed surface `mesh` (winding number above 1/2), after a bounding-box test.
pub fn contains(mesh: &CellMesh, p: &Vec3) -> bool {
    match crate::geometry::bounding_box(mesh.positions()) {
        Some((lo, hi)) if (0..3).all(|k| lo[k] <= p[k] && p[k] <= hi[k]) => winding_number(mesh, p) > 0.5,
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::{cuboid, icosphere};

    #[test]
    fn winding_number_is_one_inside_and_zero_outside() {
        let sphere = icosphere(1.0, 2, Vec3::new(3.0, 0.0, 0.0));
        assert!((winding_number(&sphere, &Vec3::new(3.2, 0.1, -0.3)) - 1.0).abs() < 1e-9);
        assert!(winding_number(&sphere, &Vec3::new(5.0, 0.0, 0.0)).abs() < 1e-9);
        // On the line through a vertex and an edge of a box: no ray, no parity trouble.
        let bx = cuboid(Vec3::new(2.0, 2.0, 2.0), Vec3::zeros());
        assert!(contains(&bx, &Vec3::new(0.0, 0.0, 0.0)));
        assert!(contains(&bx, &Vec3::new(0.999, 0.999, 0.0)));
        assert!(!contains(&bx, &Vec3::new(1.001, 0.0, 0.0)));
    }
}

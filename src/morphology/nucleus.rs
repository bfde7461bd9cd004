//! Which cell holds each nucleus: the cell whose closed surface contains the nucleus centroid.
//!
//! Containment uses the generalised winding number ([`CellMesh::winding_number`]; Jacobson et al.
//! 2013): 1 inside a closed outward surface, 0 outside, and still well defined (fractional) near holes
//! of a defective mesh; p is inside when w > 1/2. No ray is cast, so hitting an edge or a vertex
//! exactly cannot flip the answer.

use crate::geometry::Vec3;
use crate::mesh::CellMesh;

/// Whether `p` lies inside the closed surface `mesh` (winding number above 1/2), after a bounding-box test.
pub fn contains(mesh: &CellMesh, p: &Vec3) -> bool {
    match crate::geometry::bounding_box(mesh.positions()) {
        Some((lo, hi)) if (0..3).all(|k| lo[k] <= p[k] && p[k] <= hi[k]) => mesh.winding_number(p) > 0.5,
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
        assert!((sphere.winding_number(&Vec3::new(3.2, 0.1, -0.3)) - 1.0).abs() < 1e-9);
        assert!(sphere.winding_number(&Vec3::new(5.0, 0.0, 0.0)).abs() < 1e-9);
        // On the line through a vertex and an edge of a box: no ray, no parity trouble.
        let bx = cuboid(Vec3::new(2.0, 2.0, 2.0), Vec3::zeros());
        assert!(contains(&bx, &Vec3::new(0.0, 0.0, 0.0)));
        assert!(contains(&bx, &Vec3::new(0.999, 0.999, 0.0)));
        assert!(!contains(&bx, &Vec3::new(1.001, 0.0, 0.0)));
    }
}

//! Edge flip (paper Fig. S2c, "edge swap"): the diagonal `a`–`b` of the quad `a, d, b, c` is replaced
//! by `c`–`d`.
//!
//! ```text
//!        c                 c
//!       / \               /|\
//!      /   \             / | \
//!     a-----b    →      a  |  b
//!      \   /             \ | /
//!       \ /               \|/
//!        d                 d
//! ```
//! `[a, b, c]`, `[b, a, d]` become `[c, a, d]`, `[d, b, c]`. Nodes do not move; the enclosed volume
//! changes by the signed volume of the tetrahedron `a, b, c, d` (zero when the quad is planar).
//!
//! Quality: the paper's score is `S = 36·A/(√3·P²)` (A area, P perimeter), which equals
//! `12·√3·A/P²`: 1 for an equilateral triangle, → 0 for a sliver. (The reference program's
//! `(36/√3)·A/P²` is the same number.) We use it unchanged, see [`triangle_quality`].
//!
//! A flip is made only when it is legal and useful:
//! * `c` and `d` are not already joined (else a duplicate edge), and `a`, `b` keep valence ≥ 3;
//! * the new faces are not degenerate and keep the orientation: each new normal has a positive dot
//!   product with the sum of the old unit normals (a non-convex quad would fold one over);
//! * the smaller quality of the two faces strictly increases, so flips cannot cycle;
//! * (pass policy) the new edge is not longer than `max_edge`, so a flip never undoes a split.
//!
//! Face types: both new faces take the type of the larger-area old face. Each new face straddles both
//! old ones, so no choice is exact; the larger face is the better guess of the region the quad
//! belongs to, and on a boundary between regions the choice moves the boundary by at most one quad.

use super::edit::{EditMesh, is_degenerate, normal};
use super::{RemeshError, RemeshRefusal, apply_single};
use crate::geometry::{Real, Vec3, triangle_area};
use crate::mesh::{CellMesh, FaceType, NodeId};

/// Triangle quality `S = 36·A/(√3·P²) = 12·√3·A/P²`: 1 for an equilateral triangle, 0 for a
/// degenerate one (paper, "Local mesh adaptation"). 0 when the perimeter vanishes.
pub fn triangle_quality(a: &Vec3, b: &Vec3, c: &Vec3) -> Real {
    let perimeter = (b - a).norm() + (c - b).norm() + (a - c).norm();
    if perimeter > 0.0 { 12.0 * 3f64.sqrt() * triangle_area(a, b, c) / (perimeter * perimeter) } else { 0.0 }
}

fn quality(corners: [Vec3; 3]) -> Real {
    triangle_quality(&corners[0], &corners[1], &corners[2])
}

impl EditMesh {
    /// Quality of a face, see [`triangle_quality`].
    pub(super) fn face_quality(&self, f: u32) -> Real {
        quality(self.corners(f))
    }

    /// Flips edge `a`–`b`. Refused when illegal or not an improvement (see the module doc), or when the
    /// new edge would be longer than `max_edge`.
    pub(super) fn flip(&mut self, a: u32, b: u32, max_edge: Real) -> Result<(), RemeshRefusal> {
        let w = self.wing(a, b)?;
        let (c, d) = (w.c, w.d);
        let around_c = self.neighbours(c);
        if around_c.binary_search(&d).is_ok() {
            return Err(RemeshRefusal::AlreadyConnected { c, d });
        }
        for n in [a, b] {
            let valence = self.neighbours(n).len() - 1;
            if valence < 3 {
                return Err(RemeshRefusal::Valence { node: n, valence });
            }
        }
        let length = self.length(c, d);
        if length > max_edge {
            return Err(RemeshRefusal::TooLong { a: c, b: d, length });
        }
        let p = |n: u32| self.positions[n as usize];
        let (old_left, old_right) = (self.corners(w.left), self.corners(w.right));
        let (new_left, new_right) = ([p(c), p(a), p(d)], [p(d), p(b), p(c)]);
        if is_degenerate(new_left) || is_degenerate(new_right) {
            return Err(RemeshRefusal::Degenerate { a, b });
        }
        let up = normal(old_left).normalize() + normal(old_right).normalize();
        if normal(new_left).dot(&up) <= 0.0 || normal(new_right).dot(&up) <= 0.0 {
            return Err(RemeshRefusal::Inversion { face: w.left });
        }
        let before = quality(old_left).min(quality(old_right));
        let after = quality(new_left).min(quality(new_right));
        if after.partial_cmp(&before) != Some(std::cmp::Ordering::Greater) {
            return Err(RemeshRefusal::NoImprovement { a, b });
        }

        let larger = if normal(old_left).norm() >= normal(old_right).norm() { w.left } else { w.right };
        let face_type = self.face_types[larger as usize];
        self.triangles[w.left as usize] = [c, a, d];
        self.triangles[w.right as usize] = [d, b, c];
        self.face_types[w.left as usize] = face_type;
        self.face_types[w.right as usize] = face_type;
        self.detach(b, w.left);
        self.attach(d, w.left);
        self.detach(a, w.right);
        self.attach(c, w.right);
        Ok(())
    }
}

/// Flips edge `a`–`b` of `mesh` (replaces it by the edge joining the two opposite nodes), keeping
/// `face_types` (one per face) in step when given. Node indices do not change.
///
/// Refused (mesh unchanged) when the opposite nodes are already joined, an end node would drop to
/// valence 2, a new face would be degenerate or folded, or the smaller quality of the two faces
/// would not increase.
pub fn flip_edge(
    mesh: &mut CellMesh,
    a: NodeId,
    b: NodeId,
    face_types: Option<&mut Vec<FaceType>>,
) -> Result<(), RemeshError> {
    apply_single(mesh, None, face_types, |edit| edit.flip(a.0, b.0, Real::INFINITY)).map(|_| ())
}

#[cfg(test)]
mod tests {
    use super::super::testing::{Lcg, euler_characteristic, perturbed_cube, perturbed_sphere};
    use super::*;
    use crate::mesh::Adjacency;
    use crate::mesh::shapes::icosphere;

    fn min_quality(mesh: &CellMesh) -> Real {
        (0..mesh.face_count())
            .map(|f| quality(mesh.corners(crate::mesh::FaceId(f as u32))))
            .fold(Real::INFINITY, Real::min)
    }

    /// Quality is 1 for an equilateral triangle, scale-invariant, and small for a sliver.
    #[test]
    fn quality_is_one_for_an_equilateral_triangle() {
        let s = 3f64.sqrt() / 2.0;
        let (a, b, c) = (Vec3::zeros(), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.5, s, 0.0));
        assert!((triangle_quality(&a, &b, &c) - 1.0).abs() < 1e-14);
        assert!((triangle_quality(&(a * 1e-6), &(b * 1e-6), &(c * 1e-6)) - 1.0).abs() < 1e-12);
        assert!(triangle_quality(&a, &b, &Vec3::new(0.5, 0.05, 0.0)) < 0.15);
        assert_eq!(triangle_quality(&a, &a, &a), 0.0);
    }

    /// Squash a node of an icosphere onto the midpoint of the opposite edge so that the face becomes a
    /// flat cap: flipping that edge raises the smaller quality of the two faces, keeps the mesh valid,
    /// and changes the volume by exactly the tetrahedron a, b, c, d.
    #[test]
    fn flip_of_a_cap_raises_the_minimum_quality() {
        let mut mesh = icosphere(1.0, 2, Vec3::zeros());
        let adj = Adjacency::new(&mesh);
        let [a, b] = adj.edges()[7];
        let faces = adj.edge_faces(7).to_vec();
        let t = mesh.triangles()[faces[0] as usize];
        let c = *t.iter().find(|&&n| n != a && n != b).unwrap();
        let mid = 0.5 * (mesh.position(NodeId(a)) + mesh.position(NodeId(b)));
        let pc = mesh.position(NodeId(c));
        mesh.positions_mut()[c as usize] = mid + 0.08 * (pc - mid);
        assert_eq!(mesh.validate(), Ok(()));
        let pair = |m: &CellMesh, x: u32, y: u32| {
            let f: Vec<[u32; 3]> = m.triangles().iter().copied().filter(|t| t.contains(&x) && t.contains(&y)).collect();
            f.iter().map(|t| quality(t.map(|i| m.position(NodeId(i))))).fold(Real::INFINITY, Real::min)
        };
        let before = pair(&mesh, a, b);
        assert!(before < 0.3, "the cap has quality {before}");
        let v0 = mesh.signed_volume();
        let d = {
            let t = mesh.triangles()[faces[1] as usize];
            *t.iter().find(|&&n| n != a && n != b).unwrap()
        };
        let [pa, pb, pc, pd] = [a, b, c, d].map(|n| mesh.position(NodeId(n)));
        let tet = (pb - pa).dot(&(pc - pa).cross(&(pd - pa))).abs() / 6.0;
        let generation = mesh.topology_generation();
        let mut types: Vec<FaceType> = vec![FaceType::Apical; mesh.face_count()];
        types[faces[0] as usize] = FaceType::Lateral;
        let area_of = |m: &CellMesh, f: usize| m.face_areas()[f];
        let larger_is_left = area_of(&mesh, faces[0] as usize) >= area_of(&mesh, faces[1] as usize);
        flip_edge(&mut mesh, NodeId(a), NodeId(b), Some(&mut types)).unwrap();
        assert_eq!(mesh.validate(), Ok(()));
        assert_eq!(euler_characteristic(&mesh), 2);
        assert_ne!(mesh.topology_generation(), generation);
        let after = pair(&mesh, c, d);
        assert!(after > before, "quality {before} → {after}");
        assert!(pair(&mesh, a, b).is_infinite(), "edge a-b still exists");
        let dv = (mesh.signed_volume() - v0).abs();
        assert!((dv - tet).abs() <= 1e-12 * v0, "volume change {dv:e} vs tetrahedron {tet:e}");
        let expected = if larger_is_left { FaceType::Lateral } else { FaceType::Apical };
        assert_eq!(types[faces[0] as usize], expected);
        assert_eq!(types[faces[1] as usize], expected);
    }

    /// Flips refused by the rules leave the mesh as it was; accepted flips on perturbed meshes keep it
    /// valid and never lower the global minimum quality.
    #[test]
    fn flips_keep_meshes_valid_and_never_lower_the_minimum_quality() {
        let mut rng = Lcg::new(31);
        let mut accepted = 0;
        for mesh0 in [perturbed_sphere(&mut rng, 2, 0.35), perturbed_cube(&mut rng, 4, 0.3)] {
            let mut mesh = mesh0;
            for [a, b] in Adjacency::new(&mesh).edges().to_vec() {
                let q0 = min_quality(&mesh);
                let before = mesh.clone();
                match flip_edge(&mut mesh, NodeId(a), NodeId(b), None) {
                    Ok(()) => {
                        accepted += 1;
                        assert_eq!(mesh.validate(), Ok(()));
                        assert_eq!(euler_characteristic(&mesh), 2);
                        assert!(min_quality(&mesh) >= q0);
                        assert_eq!(mesh.positions(), before.positions());
                    }
                    Err(RemeshError::Refused(_)) => assert_eq!(mesh, before),
                    Err(e) => panic!("unexpected error {e}"),
                }
            }
        }
        assert!(accepted >= 10, "only {accepted} flips were accepted");
    }

    /// On a regular icosahedron every face is equilateral, so no flip can raise the quality: refused.
    #[test]
    fn flip_without_improvement_is_refused() {
        let mut mesh = icosphere(1.0, 0, Vec3::zeros());
        let err = flip_edge(&mut mesh, NodeId(0), NodeId(11), None).unwrap_err();
        assert!(
            matches!(err, RemeshError::Refused(RemeshRefusal::NoImprovement { .. } | RemeshRefusal::Inversion { .. })),
            "{err:?}"
        );
    }
}

//! Edge split (paper Fig. S2a): a new node at the midpoint of edge `a`–`b`; its two faces become four.
//!
//! ```text
//!        c                 c
//!       / \               /|\
//!      /   \             / | \
//!     a-----b    →      a--m--b
//!      \   /             \ | /
//!       \ /               \|/
//!        d                 d
//! ```
//! `[a, b, c]` becomes `[a, m, c]` + `[m, b, c]` and `[b, a, d]` becomes `[b, m, d]` + `[m, a, d]`; each
//! child lies in its parent's plane and inherits its face type, so the surface, its area and its
//! volume are unchanged (up to rounding). Momentum: `m` receives a third of each end node's momentum
//! and the ends keep two thirds, `p_m = (p_a + p_b)/3`, so the total is conserved.

use super::edit::{EditMesh, is_degenerate};
use super::{RemeshError, RemeshRefusal, apply_single};
use crate::geometry::Vec3;
use crate::mesh::{CellMesh, FaceType, NodeId};

impl EditMesh {
    /// Splits edge `a`–`b` at its midpoint; returns the new node.
    pub(super) fn split(&mut self, a: u32, b: u32) -> Result<u32, RemeshRefusal> {
        let w = self.wing(a, b)?;
        let m =
            u32::try_from(self.positions.len()).ok().filter(|&m| m < u32::MAX).ok_or(RemeshRefusal::TooManyNodes)?;
        let p = |n: u32| self.positions[n as usize];
        let pm = 0.5 * (p(a) + p(b));
        let children = [[p(a), pm, p(w.c)], [pm, p(b), p(w.c)], [p(b), pm, p(w.d)], [pm, p(a), p(w.d)]];
        if children.into_iter().any(is_degenerate) {
            return Err(RemeshRefusal::Degenerate { a, b });
        }

        self.positions.push(pm);
        let (ma, mb) = (self.momenta[a as usize], self.momenta[b as usize]);
        self.momenta.push((ma + mb) / 3.0);
        self.momenta[a as usize] = ma * (2.0 / 3.0);
        self.momenta[b as usize] = mb * (2.0 / 3.0);
        self.node_alive.push(true);

        let left_child = self.triangles.len() as u32;
        let right_child = left_child + 1;
        self.triangles[w.left as usize] = [a, m, w.c];
        self.triangles[w.right as usize] = [b, m, w.d];
        self.triangles.push([m, b, w.c]);
        self.triangles.push([m, a, w.d]);
        let (left_type, right_type) = (self.face_types[w.left as usize], self.face_types[w.right as usize]);
        self.face_types.extend([left_type, right_type]);
        self.face_alive.extend([true, true]);

        self.detach(b, w.left);
        self.attach(b, left_child);
        self.detach(a, w.right);
        self.attach(a, right_child);
        self.attach(w.c, left_child);
        self.attach(w.d, right_child);
        self.node_faces.push(vec![w.left, left_child, w.right, right_child]);
        Ok(m)
    }
}

/// Splits edge `a`–`b` of `mesh` at its midpoint, keeping `momenta` (one per node) and `face_types`
/// (one per face) in step when given. Returns the new node, which is the last one.
///
/// Refused (mesh unchanged) when `a`–`b` is not a manifold edge or a child face would be degenerate.
pub fn split_edge(
    mesh: &mut CellMesh,
    a: NodeId,
    b: NodeId,
    momenta: Option<&mut Vec<Vec3>>,
    face_types: Option<&mut Vec<FaceType>>,
) -> Result<NodeId, RemeshError> {
    let (m, new_index) = apply_single(mesh, momenta, face_types, |edit| edit.split(a.0, b.0))?;
    Ok(NodeId(new_index[m as usize]))
}

#[cfg(test)]
mod tests {
    use super::super::testing::{Lcg, euler_characteristic, perturbed_cube, perturbed_sphere, random_momenta, sum};
    use super::*;
    use crate::mesh::Adjacency;

    /// Splitting every edge of perturbed meshes, one at a time: the mesh stays valid, gains one node
    /// and two faces, keeps its volume and area (children are coplanar with their parents), and the
    /// momentum sum and the face types are conserved.
    #[test]
    fn split_keeps_the_surface_valid_and_conserves_momentum_volume_and_area() {
        let mut rng = Lcg::new(11);
        for mesh0 in [perturbed_sphere(&mut rng, 2, 0.2), perturbed_cube(&mut rng, 3, 0.15)] {
            let edges = Adjacency::new(&mesh0).edges().to_vec();
            let mut mesh = mesh0.clone();
            let mut momenta = random_momenta(&mut rng, mesh.node_count());
            let mut types: Vec<FaceType> = (0..mesh.face_count()).map(|f| FaceType::ALL[f % 3]).collect();
            for [a, b] in edges.into_iter().step_by(3) {
                let (v0, area0, p0) = (mesh.signed_volume(), mesh.area(), sum(&momenta));
                let counts0 = type_counts(&types);
                let generation = mesh.topology_generation();
                let (nodes, faces) = (mesh.node_count(), mesh.face_count());
                let m = split_edge(&mut mesh, NodeId(a), NodeId(b), Some(&mut momenta), Some(&mut types)).unwrap();
                assert_eq!(mesh.validate(), Ok(()));
                assert_eq!(euler_characteristic(&mesh), 2);
                assert_eq!((mesh.node_count(), mesh.face_count()), (nodes + 1, faces + 2));
                assert_eq!(m.index(), nodes);
                assert_ne!(mesh.topology_generation(), generation);
                assert!((mesh.signed_volume() - v0).abs() <= 1e-12 * v0, "volume changed");
                assert!((mesh.area() - area0).abs() <= 1e-12 * area0, "area changed");
                assert!((sum(&momenta) - p0).norm() <= 1e-12 * p0.norm().max(1.0), "momentum not conserved");
                assert_eq!((momenta.len(), types.len()), (mesh.node_count(), mesh.face_count()));
                // The two parents' types each gained one face.
                let counts = type_counts(&types);
                assert_eq!(counts.iter().sum::<usize>(), counts0.iter().sum::<usize>() + 2);
                assert!(counts.iter().zip(&counts0).all(|(n, n0)| n >= n0));
                let p = mesh.positions();
                assert!((p[m.index()] - 0.5 * (p[a as usize] + p[b as usize])).norm() < 1e-15);
            }
        }
    }

    /// The new node gets a third of each end's momentum, the ends keep two thirds.
    #[test]
    fn split_shares_momentum_in_thirds() {
        let mut mesh = crate::mesh::shapes::icosphere(1.0, 1, Vec3::zeros());
        let [a, b] = Adjacency::new(&mesh).edges()[0];
        let mut momenta = vec![Vec3::zeros(); mesh.node_count()];
        momenta[a as usize] = Vec3::new(3.0, 0.0, 0.0);
        momenta[b as usize] = Vec3::new(0.0, 6.0, 0.0);
        let m = split_edge(&mut mesh, NodeId(a), NodeId(b), Some(&mut momenta), None).unwrap();
        assert_eq!(momenta[a as usize], Vec3::new(2.0, 0.0, 0.0));
        assert_eq!(momenta[b as usize], Vec3::new(0.0, 4.0, 0.0));
        assert_eq!(momenta[m.index()], Vec3::new(1.0, 2.0, 0.0));
    }

    /// A pair of nodes that is not an edge is refused and the mesh is left untouched.
    #[test]
    fn split_of_a_non_edge_is_refused() {
        let mut mesh = crate::mesh::shapes::icosphere(1.0, 1, Vec3::zeros());
        let adj = Adjacency::new(&mesh);
        let b = (1..mesh.node_count() as u32).find(|b| !adj.node_neighbours(0).contains(b)).unwrap();
        let before = mesh.clone();
        let generation = mesh.topology_generation();
        let err = split_edge(&mut mesh, NodeId(0), NodeId(b), None, None).unwrap_err();
        assert_eq!(err, RemeshError::Refused(RemeshRefusal::NotAnEdge { a: 0, b }));
        assert_eq!(mesh, before);
        assert_eq!(mesh.topology_generation(), generation);
    }

    fn type_counts(types: &[FaceType]) -> [usize; 3] {
        let mut counts = [0; 3];
        types.iter().for_each(|t| counts[t.code() as usize] += 1);
        counts
    }
}

//! Contact angle at the free rim of a contact between two cells (doublets, triplets, aggregates).
//!
//! Definition: a *rim edge* of cell `a` toward cell `b` is an edge of `a`'s surface between a face in
//! contact with `b` and a free face (in contact with nothing; see [`super::face_contacts`]). At a rim edge
//! with free-face outward unit normal `n_a`, take the rim edge of `b` toward `a` whose midpoint is nearest
//! (within 3 edge lengths + δ) and its free-face normal `n_b`. The contact angle is the *external* angle
//! between the two free surfaces, i.e. the opening of the wedge of medium between the cells:
//!
//! θ = π − arccos(n_a · n_b).
//!
//! θ = 0 for two cells that merely touch (n_a = −n_b) and θ = π when the two free surfaces continue each
//! other (n_a = n_b). For a doublet of two spherical caps of radius R joined by a flat disc of radius r,
//! the sphere normal at the rim makes the angle β = arcsin(r/R) with the disc normal on each side, so
//! **θ = 2·arcsin(r/R)** (the value the tests check). The reported angle is the mean over the rim edges
//! of both cells.
//!
//! Resolution: a flat free face spanning the distance h_⊥ away from the rim has the normal of the curved
//! surface half-way across it, so on a free surface of radius R each side's normal tilts by h_⊥/(2R) and
//! θ is overestimated by about h_⊥/R radians (the angle one free face spans; 3° for R = 20 h_⊥). The
//! error is first order and shrinks under refinement (tested); it is the same for simulated and
//! segmented meshes of equal resolution, so comparisons at equal resolution are fair.

use super::face_contacts::{FREE, FaceContacts};
use crate::geometry::{Real, Vec3};
use crate::mesh::{Adjacency, CellMesh};

/// One rim edge of a cell's contact with a partner.
#[derive(Clone, Debug, PartialEq)]
pub struct RimEdge {
    /// Tissue index of the partner body.
    pub partner: u32,
    /// Midpoint of the edge (m).
    pub midpoint: Vec3,
    /// Outward unit normal of the free face at the edge.
    pub free_normal: Vec3,
    /// Edge length (m).
    pub length: Real,
}

/// The rim edges of one cell, sorted by partner (stable: in edge order within a partner).
pub fn rim_edges(mesh: &CellMesh, contacts: &FaceContacts) -> Vec<RimEdge> {
    let adjacency = Adjacency::new(mesh);
    let p = mesh.positions();
    let normals = mesh.face_normals();
    let mut rims = Vec::new();
    for (e, &[u, v]) in adjacency.edges().iter().enumerate() {
        let &[f, g] = adjacency.edge_faces(e) else { continue };
        let (pf, pg) = (contacts.partner[f as usize], contacts.partner[g as usize]);
        let (contact_partner, free_face) = match (pf == FREE, pg == FREE) {
            (false, true) => (pf, g),
            (true, false) => (pg, f),
            _ => continue,
        };
        let normal = normals[free_face as usize];
        if normal == Vec3::zeros() {
            continue;
        }
        let (a, b) = (p[u as usize], p[v as usize]);
        rims.push(RimEdge {
            partner: contact_partner,
            midpoint: (a + b) / 2.0,
            free_normal: normal,
            length: (b - a).norm(),
        });
    }
    rims.sort_by_key(|r| r.partner);
    rims
}

/// The rim edges of `rims` (sorted by partner) toward `partner`.
pub fn rim_toward(rims: &[RimEdge], partner: u32) -> &[RimEdge] {
    let start = rims.partition_point(|r| r.partner < partner);
    let end = rims.partition_point(|r| r.partner <= partner);
    &rims[start..end]
}

/// Mean contact angle (radians) over the matched rim edges of both sides, and the number of matches;
/// `None` when no rim edge found a partner edge.
pub fn contact_angle(rim_a: &[RimEdge], rim_b: &[RimEdge], delta: Real) -> Option<(Real, usize)> {
    let mut sum = 0.0;
    let mut count = 0usize;
    for (from, to) in [(rim_a, rim_b), (rim_b, rim_a)] {
        for e in from {
            let limit = 3.0 * e.length + delta;
            let nearest = to
                .iter()
                .map(|o| ((o.midpoint - e.midpoint).norm(), o))
                .filter(|(d, _)| *d <= limit)
                .min_by(|x, y| x.0.total_cmp(&y.0));
            if let Some((_, o)) = nearest {
                let cos = e.free_normal.dot(&o.free_normal).clamp(-1.0, 1.0);
                sum += std::f64::consts::PI - cos.acos();
                count += 1;
            }
        }
    }
    (count > 0).then(|| (sum / count as Real, count))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn edge(partner: u32, midpoint: Vec3, free_normal: Vec3) -> RimEdge {
        RimEdge { partner, midpoint, free_normal, length: 0.1 }
    }

    /// Sphere normals at the rim of two caps on a disc of radius R·sin β: θ = 2β.
    #[test]
    fn contact_angle_of_cap_normals_is_twice_the_cap_angle() {
        let beta: Real = 0.4;
        let a = [edge(1, Vec3::new(1.0, 0.0, 0.0), Vec3::new(beta.sin(), 0.0, beta.cos()))];
        let b = [edge(0, Vec3::new(1.0, 0.0, 0.01), Vec3::new(beta.sin(), 0.0, -beta.cos()))];
        let (theta, n) = contact_angle(&a, &b, 0.01).unwrap();
        assert_eq!(n, 2);
        assert!((theta - 2.0 * beta).abs() < 1e-12, "θ = {theta}");
        // Rim edges too far apart to be the same rim are not matched.
        let far = [edge(0, Vec3::new(5.0, 0.0, 0.0), Vec3::new(0.0, 0.0, -1.0))];
        assert_eq!(contact_angle(&a, &far, 0.01), None);
        assert_eq!(contact_angle(&a, &[], 0.01), None);
    }

    #[test]
    fn rim_toward_selects_one_partner() {
        let rims: Vec<RimEdge> =
            [0u32, 2, 2, 5].iter().map(|&p| edge(p, Vec3::zeros(), Vec3::new(0.0, 0.0, 1.0))).collect();
        assert_eq!(rim_toward(&rims, 2).len(), 2);
        assert!(rim_toward(&rims, 3).is_empty());
        assert_eq!(rim_toward(&rims, 5)[0].partner, 5);
    }
}

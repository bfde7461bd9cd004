//! Which faces of a cell touch which other body: the contact partition of every surface.
//!
//! Definition: face `f` of body `a` is *in contact* with body `b ≠ a` when the centroid of `f` lies
//! within the contact distance δ of `b`'s surface (exact point–triangle distance,
//! [`crate::geometry::closest_point_on_triangle`]). When several bodies are within δ, the face belongs to
//! the nearest (ties: the lower tissue index), so every face is either free or assigned to exactly one
//! partner, and a cell's contact areas add up to at most its area. The centroid test splits the faces that
//! straddle a contact rim about where the rim crosses them, so the contact area's discretisation error
//! stays of the order of (rim length × edge length) with both signs, not one-sided.
//!
//! Broad phase: one [`SpatialGrid`] over all participating faces, each box padded by δ; a centroid reads
//! the single cube it falls in. Parallel over bodies with rayon; every result depends only on the input
//! (ties are broken by index, not by visiting order), so 1 and N threads give identical partitions.

use crate::geometry::{Real, SpatialGrid, Vec3, closest_point_on_triangle};
use crate::mesh::Tissue;
use rayon::prelude::*;

/// Marks a face in contact with no body.
pub const FREE: u32 = u32::MAX;

/// The contact partition of one body's faces.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FaceContacts {
    /// For each face, the tissue index of the body it touches, or [`FREE`].
    pub partner: Vec<u32>,
    /// For each face, the distance (m) from its centroid to the partner's surface; `Real::INFINITY` when free.
    pub distance: Vec<Real>,
}

/// Computes the contact partition of every body of `tissue` (in tissue order). Bodies with
/// `participates[i] == false` (nuclei) neither touch nor are touched: all their faces are free.
///
/// `delta` is the contact distance δ (m), finite and positive (checked by the caller).
pub fn detect_face_contacts(tissue: &Tissue, participates: &[bool], delta: Real) -> Vec<FaceContacts> {
    let cells = tissue.cells();
    let mut boxes: Vec<(Vec3, Vec3)> = Vec::with_capacity(tissue.face_count());
    let mut owner: Vec<u32> = Vec::with_capacity(tissue.face_count());
    let mut owner_face: Vec<u32> = Vec::with_capacity(tissue.face_count());
    let pad = Vec3::repeat(delta);
    for (i, cell) in cells.iter().enumerate() {
        if !participates[i] {
            continue;
        }
        let mesh = cell.mesh();
        for (f, t) in mesh.triangles().iter().enumerate() {
            let [a, b, c] = t.map(|k| mesh.positions()[k as usize]);
            boxes.push((a.inf(&b).inf(&c) - pad, a.sup(&b).sup(&c) + pad));
            owner.push(i as u32);
            owner_face.push(f as u32);
        }
    }
    if boxes.is_empty() {
        return cells.iter().map(|c| free_partition(c.mesh().face_count())).collect();
    }
    // Cube edge: the mean padded box extent, so a typical box spans at most 2 cubes per axis (the
    // grid keeps the few much larger boxes in its oversized list).
    let mean_extent = boxes.iter().map(|(lo, hi)| (hi - lo).max()).sum::<Real>() / boxes.len() as Real;
    let cell_size = if mean_extent.is_finite() && mean_extent > 0.0 { mean_extent } else { 2.0 * delta };
    let mut grid = SpatialGrid::new(cell_size);
    grid.rebuild(&boxes);

    (0..cells.len())
        .into_par_iter()
        .map(|i| {
            let mesh = cells[i].mesh();
            if !participates[i] {
                return free_partition(mesh.face_count());
            }
            let p = mesh.positions();
            let mut partner = Vec::with_capacity(mesh.face_count());
            let mut distance = Vec::with_capacity(mesh.face_count());
            for t in mesh.triangles() {
                let centroid = (p[t[0] as usize] + p[t[1] as usize] + p[t[2] as usize]) / 3.0;
                let (mut best, mut best_d) = (FREE, Real::INFINITY);
                grid.for_each_at(&centroid, |item| {
                    let item = item as usize;
                    let b = owner[item];
                    if b as usize == i {
                        return;
                    }
                    let (lo, hi) = &boxes[item];
                    if !(0..3).all(|k| lo[k] <= centroid[k] && centroid[k] <= hi[k]) {
                        return;
                    }
                    let other = cells[b as usize].mesh();
                    let [x, y, z] = other.triangles()[owner_face[item] as usize].map(|k| other.positions()[k as usize]);
                    let d = closest_point_on_triangle(&centroid, &x, &y, &z).distance;
                    if d <= delta && (d < best_d || (d == best_d && b < best)) {
                        best = b;
                        best_d = d;
                    }
                });
                partner.push(best);
                distance.push(best_d);
            }
            FaceContacts { partner, distance }
        })
        .collect()
}

fn free_partition(faces: usize) -> FaceContacts {
    FaceContacts { partner: vec![FREE; faces], distance: vec![Real::INFINITY; faces] }
}

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
//! Broad phase: a [`SpatialGrid`] per body over its faces' boxes padded by δ, and one over the bodies'
//! padded boxes; a face centroid reads, for each other body whose padded box holds it, the single cube
//! of that body's grid it falls in, so a cell's own faces are never candidates. Parallel over bodies with
//! rayon; every result depends only on the input (ties are broken by index, not by visiting order), so 1
//! and N threads give identical partitions.

use super::ContactRule;
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
    let pad = Vec3::repeat(delta);
    // One grid per body over its faces' padded boxes: a centroid then reads only the grids of the bodies
    // whose padded box holds it, never its own faces (which were most of the candidates of a single grid).
    let grids: Vec<Option<BodyGrid>> = cells
        .par_iter()
        .zip(participates)
        .map(|(cell, &take)| if take { BodyGrid::new(cell.mesh(), pad) } else { None })
        .collect();
    // Body-level broad phase: for each body, the other bodies whose padded boxes overlap its own.
    let body_boxes: Vec<(Vec3, Vec3)> = grids
        .iter()
        .map(|g| g.as_ref().map_or((Vec3::repeat(Real::NAN), Vec3::repeat(Real::NAN)), |g| (g.lo, g.hi)))
        .collect();
    let extents: Vec<Real> =
        body_boxes.iter().map(|(lo, hi)| (hi - lo).max()).filter(|e| e.is_finite() && *e > 0.0).collect();
    if extents.is_empty() {
        return cells.iter().map(|c| free_partition(c.mesh().face_count())).collect();
    }
    let mut body_grid = SpatialGrid::new(extents.iter().sum::<Real>() / extents.len() as Real);
    body_grid.rebuild(&body_boxes);

    (0..cells.len())
        .into_par_iter()
        .map(|i| {
            let mesh = cells[i].mesh();
            let Some(own) = &grids[i] else { return free_partition(mesh.face_count()) };
            let mut others = Vec::new();
            body_grid.collect_candidates(&own.lo, &own.hi, &mut others);
            others.retain(|&j| j as usize != i);
            let p = mesh.positions();
            let mut partner = Vec::with_capacity(mesh.face_count());
            let mut distance = Vec::with_capacity(mesh.face_count());
            for t in mesh.triangles() {
                let centroid = (p[t[0] as usize] + p[t[1] as usize] + p[t[2] as usize]) / 3.0;
                let (mut best, mut best_d) = (FREE, Real::INFINITY);
                for &b in &others {
                    let Some(g) = &grids[b as usize] else { continue };
                    if !inside(&centroid, &(g.lo, g.hi)) {
                        continue;
                    }
                    let other = cells[b as usize].mesh();
                    g.grid.for_each_at(&centroid, |f| {
                        if !inside(&centroid, &g.boxes[f as usize]) {
                            return;
                        }
                        let [x, y, z] = other.triangles()[f as usize].map(|k| other.positions()[k as usize]);
                        let d = closest_point_on_triangle(&centroid, &x, &y, &z).distance;
                        if d <= delta && (d < best_d || (d == best_d && b < best)) {
                            best = b;
                            best_d = d;
                        }
                    });
                }
                partner.push(best);
                distance.push(best_d);
            }
            FaceContacts { partner, distance }
        })
        .collect()
}

fn inside(p: &Vec3, (lo, hi): &(Vec3, Vec3)) -> bool {
    (0..3).all(|k| lo[k] <= p[k] && p[k] <= hi[k])
}

/// The faces of one body in a grid of their boxes padded by δ, and the union of those boxes.
struct BodyGrid {
    boxes: Vec<(Vec3, Vec3)>,
    grid: SpatialGrid,
    lo: Vec3,
    hi: Vec3,
}

impl BodyGrid {
    /// `None` for a body without faces.
    fn new(mesh: &crate::mesh::CellMesh, pad: Vec3) -> Option<Self> {
        let p = mesh.positions();
        let boxes: Vec<(Vec3, Vec3)> = mesh
            .triangles()
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|k| p[k as usize]);
                (a.inf(&b).inf(&c) - pad, a.sup(&b).sup(&c) + pad)
            })
            .collect();
        let (lo, hi) = boxes.iter().fold((Vec3::repeat(Real::INFINITY), Vec3::repeat(Real::NEG_INFINITY)), |acc, b| {
            (acc.0.inf(&b.0), acc.1.sup(&b.1))
        });
        if boxes.is_empty() || !(lo.iter().chain(hi.iter()).all(|v| v.is_finite())) {
            return None;
        }
        // Cube edge: the mean padded box extent, so a typical box spans at most 2 cubes per axis (the
        // grid keeps the few much larger boxes in its oversized list).
        let mean_extent = boxes.iter().map(|(lo, hi)| (hi - lo).max()).sum::<Real>() / boxes.len() as Real;
        let mut grid = SpatialGrid::new(mean_extent);
        grid.rebuild(&boxes);
        Some(Self { boxes, grid, lo, hi })
    }
}

fn free_partition(faces: usize) -> FaceContacts {
    FaceContacts { partner: vec![FREE; faces], distance: vec![Real::INFINITY; faces] }
}

/// The contact partition of every body and how it was found: from the interface labels when
/// `use_labels` and every participating body carries them ([`labelled_face_contacts`]), otherwise by
/// the contact distance `delta` ([`detect_face_contacts`]).
pub fn contact_partition(
    tissue: &Tissue,
    participates: &[bool],
    delta: Real,
    use_labels: bool,
) -> (Vec<FaceContacts>, ContactRule) {
    match use_labels.then(|| labelled_face_contacts(tissue, participates)).flatten() {
        Some(partition) => (partition, ContactRule::InterfaceLabels),
        None => (detect_face_contacts(tissue, participates, delta), ContactRule::Distance),
    }
}

/// The contact partition read from the interface labels of a multi-material input
/// ([`crate::mesh::Cell::interface_labels`]): face `f` of body `a` touches the body whose id its label
/// names, exactly as the file says, without a distance rule. A label naming the medium (0), a body
/// missing from the tissue, a body that does not participate or `a` itself leaves the face free.
/// Contact faces get distance 0.
///
/// `None` unless every participating body carries labels (a partition half from labels and half from
/// distances would mix two definitions).
pub fn labelled_face_contacts(tissue: &Tissue, participates: &[bool]) -> Option<Vec<FaceContacts>> {
    let cells = tissue.cells();
    if !participates.iter().any(|&p| p)
        || cells.iter().zip(participates).any(|(c, &p)| p && c.interface_labels().is_none())
    {
        return None;
    }
    let index_of: std::collections::HashMap<u32, u32> =
        cells.iter().enumerate().filter(|&(i, _)| participates[i]).map(|(i, c)| (c.id().0, i as u32)).collect();
    Some(
        cells
            .iter()
            .enumerate()
            .map(|(i, cell)| match cell.interface_labels() {
                Some(labels) if participates[i] => {
                    let partner: Vec<u32> = labels
                        .iter()
                        .map(|l| index_of.get(l).copied().filter(|&j| j as usize != i).unwrap_or(FREE))
                        .collect();
                    let distance = partner.iter().map(|&p| if p == FREE { Real::INFINITY } else { 0.0 }).collect();
                    FaceContacts { partner, distance }
                }
                _ => free_partition(cell.mesh().face_count()),
            })
            .collect(),
    )
}

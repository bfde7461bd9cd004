//! Turning the ball-pivoting triangles into a closed surface: drop pinched fans and stray pieces,
//! then fill each remaining hole by minimum-angle ear clipping.
//!
//! 1. A vertex whose faces form several fans (a "join" of the pivoting front) keeps its largest fan;
//!    the faces of the others are removed (repeated until every vertex has one fan).
//! 2. Only the largest edge-connected piece is kept.
//! 3. Each boundary loop, walked against the winding of the faces along it, is triangulated by
//!    repeatedly cutting the ear with the smallest interior angle whose closing diagonal is not
//!    already an edge. The angle at a corner is measured about that point's own outward normal
//!    (reflex corners count 2π − φ), not a normal of the whole loop: the typical hole left by the
//!    pivoting is a long seam where the front met itself, curved around the cell, and zipping it
//!    from its sharp ends needs the local sense of "convex". The new faces keep the surface's
//!    winding. Long diagonals are later split by remeshing.

use super::MeshingError;
use crate::geometry::{Real, Vec3};
use std::collections::{HashMap, HashSet};

/// What the repair did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct RepairStats {
    /// Faces removed as pinched fans or stray pieces.
    pub removed_faces: usize,
    /// Boundary loops filled.
    pub holes: usize,
    /// Faces added by hole filling.
    pub hole_faces: usize,
    /// Boundary edges of the largest hole.
    pub largest_hole: usize,
}

/// Most rounds of pinched-fan removal.
const MAX_FAN_ROUNDS: usize = 32;

/// Repairs `faces` (consistently wound, each directed edge used at most once) over `points`.
pub(crate) fn close_surface(
    points: &[Vec3],
    normals: &[Vec3],
    mut faces: Vec<[u32; 3]>,
) -> Result<(Vec<[u32; 3]>, RepairStats), MeshingError> {
    let mut stats = RepairStats::default();
    let before = faces.len();
    for _ in 0..MAX_FAN_ROUNDS {
        let keep = single_fans(points.len(), &faces);
        if keep.iter().all(|&k| k) {
            break;
        }
        faces = faces.into_iter().zip(keep).filter_map(|(f, k)| k.then_some(f)).collect();
    }
    faces = largest_piece(faces);
    stats.removed_faces = before - faces.len();
    if faces.is_empty() {
        return Err(MeshingError::Repair { reason: "no faces left after removing pinched fans".into() });
    }
    let half: HashMap<(u32, u32), u32> =
        faces.iter().enumerate().flat_map(|(f, t)| edges(t).map(move |e| (e, f as u32))).collect();
    if half.len() != 3 * faces.len() {
        return Err(MeshingError::Repair { reason: "a directed edge is used by two faces".into() });
    }
    // Hole edges run against the faces: face edge a→b without b→a gives hole edge b→a.
    let mut next: HashMap<u32, u32> = HashMap::new();
    let mut starts = Vec::new();
    for t in &faces {
        for (a, b) in edges(t) {
            if !half.contains_key(&(b, a)) {
                if next.insert(b, a).is_some() {
                    return Err(MeshingError::Repair { reason: format!("node {b} starts two boundary edges") });
                }
                starts.push(b);
            }
        }
    }
    let mut all_edges: HashSet<(u32, u32)> = half.keys().map(|&(a, b)| (a.min(b), a.max(b))).collect();
    let mut visited: HashSet<u32> = HashSet::new();
    for start in starts {
        if visited.contains(&start) {
            continue;
        }
        let mut hole = vec![start];
        visited.insert(start);
        let mut v = next[&start];
        while v != start {
            if !visited.insert(v) || hole.len() > next.len() {
                return Err(MeshingError::Repair { reason: format!("boundary loop through node {v} does not close") });
            }
            hole.push(v);
            v = *next.get(&v).ok_or_else(|| MeshingError::Repair { reason: format!("boundary ends at node {v}") })?;
        }
        stats.holes += 1;
        stats.largest_hole = stats.largest_hole.max(hole.len());
        let added = fill_hole(points, normals, hole, &mut all_edges, &mut faces)?;
        stats.hole_faces += added;
    }
    Ok((faces, stats))
}

fn edges(t: &[u32; 3]) -> impl Iterator<Item = (u32, u32)> + '_ {
    (0..3).map(move |s| (t[s], t[(s + 1) % 3]))
}

/// For each face, whether it is kept: at every vertex whose faces form more than one fan, only the
/// largest fan (ties: the one with the lowest face index) keeps its faces.
fn single_fans(nodes: usize, faces: &[[u32; 3]]) -> Vec<bool> {
    let half: HashMap<(u32, u32), u32> =
        faces.iter().enumerate().flat_map(|(f, t)| edges(t).map(move |e| (e, f as u32))).collect();
    let mut node_faces: Vec<Vec<u32>> = vec![Vec::new(); nodes];
    for (f, t) in faces.iter().enumerate() {
        t.iter().for_each(|&v| node_faces[v as usize].push(f as u32));
    }
    let mut keep = vec![true; faces.len()];
    for (v, fs) in node_faces.iter().enumerate() {
        if fs.len() < 2 {
            continue;
        }
        let mut parent: Vec<usize> = (0..fs.len()).collect();
        for (q, &f) in fs.iter().enumerate() {
            let t = faces[f as usize];
            let s = t.iter().position(|&x| x == v as u32).expect("face of the node");
            let (next, prev) = (t[(s + 1) % 3], t[(s + 2) % 3]);
            // Neighbours across the two edges at v: next→v and v→prev traversed by other faces.
            for key in [(next, v as u32), (v as u32, prev)] {
                if let Some(&g) = half.get(&key)
                    && let Some(r) = fs.iter().position(|&x| x == g)
                {
                    let (a, b) = (root(&mut parent, q), root(&mut parent, r));
                    parent[a.max(b)] = a.min(b);
                }
            }
        }
        let mut size = vec![0usize; fs.len()];
        for q in 0..fs.len() {
            size[root(&mut parent, q)] += 1;
        }
        let best = (0..fs.len()).max_by(|&a, &b| size[a].cmp(&size[b]).then(b.cmp(&a))).expect("faces");
        if size[best] == fs.len() {
            continue;
        }
        for (q, &f) in fs.iter().enumerate() {
            if root(&mut parent, q) != best {
                keep[f as usize] = false;
            }
        }
    }
    keep
}

fn root(parent: &mut [usize], mut i: usize) -> usize {
    while parent[i] != i {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    i
}

/// The largest piece of faces joined through shared edges (ties: the one with the lowest face).
fn largest_piece(faces: Vec<[u32; 3]>) -> Vec<[u32; 3]> {
    let mut by_edge: HashMap<(u32, u32), usize> = HashMap::new();
    let mut parent: Vec<usize> = (0..faces.len()).collect();
    for (f, t) in faces.iter().enumerate() {
        for (a, b) in edges(t) {
            match by_edge.entry((a.min(b), a.max(b))) {
                std::collections::hash_map::Entry::Occupied(o) => {
                    let (x, y) = (root(&mut parent, f), root(&mut parent, *o.get()));
                    parent[x.max(y)] = x.min(y);
                }
                std::collections::hash_map::Entry::Vacant(v) => {
                    v.insert(f);
                }
            }
        }
    }
    let mut size = vec![0usize; faces.len()];
    for f in 0..faces.len() {
        size[root(&mut parent, f)] += 1;
    }
    let Some(best) = (0..faces.len()).max_by(|&a, &b| size[a].cmp(&size[b]).then(b.cmp(&a))) else {
        return faces;
    };
    let roots: Vec<usize> = (0..faces.len()).map(|f| root(&mut parent, f)).collect();
    faces.into_iter().zip(roots).filter_map(|(t, r)| (r == best).then_some(t)).collect()
}

/// Triangulates one boundary loop (walked so that faces `(prev, v, next)` keep the winding);
/// returns the number of faces added.
fn fill_hole(
    points: &[Vec3],
    normals: &[Vec3],
    mut hole: Vec<u32>,
    all_edges: &mut HashSet<(u32, u32)>,
    faces: &mut Vec<[u32; 3]>,
) -> Result<usize, MeshingError> {
    let p = |i: u32| points[i as usize];
    let mut added = 0;
    while hole.len() > 3 {
        let n = hole.len();
        // Ears whose triangle faces the way of its corners' normals come first (a folded ear
        // would wrap the filling across the hole); among them the smallest interior angle.
        let mut best: Option<(bool, Real, usize)> = None;
        for q in 0..n {
            let (a, v, b) = (hole[(q + n - 1) % n], hole[q], hole[(q + 1) % n]);
            if all_edges.contains(&(a.min(b), a.max(b))) {
                continue;
            }
            let (da, db) = (p(a) - p(v), p(b) - p(v));
            let phi = da.angle(&db);
            let face_normal = (p(v) - p(a)).cross(&(p(b) - p(v)));
            let convex = face_normal.dot(&normals[v as usize]) >= 0.0;
            let interior = if convex { phi } else { std::f64::consts::TAU - phi };
            let folded = [a, v, b].iter().any(|&k| face_normal.dot(&normals[k as usize]) <= 0.0);
            if best.is_none_or(|(f, x, _)| (folded, interior) < (f, x)) {
                best = Some((folded, interior, q));
            }
        }
        let best = best.map(|(_, x, q)| (x, q));
        let Some((_, q)) = best else {
            return Err(MeshingError::Repair {
                reason: format!("a hole of {n} edges has no ear whose diagonal is not already an edge"),
            });
        };
        let (a, v, b) = (hole[(q + n - 1) % n], hole[q], hole[(q + 1) % n]);
        faces.push([a, v, b]);
        all_edges.insert((a.min(b), a.max(b)));
        hole.remove(q);
        added += 1;
    }
    faces.push([hole[0], hole[1], hole[2]]);
    Ok(added + 1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::CellMesh;
    use crate::mesh::shapes::icosphere;

    #[test]
    fn holes_punched_in_a_sphere_are_filled() {
        let sphere = icosphere(1.0, 3, Vec3::zeros());
        let pts = sphere.positions().to_vec();
        // Remove the faces around node 0 and around a far node: two holes.
        let far =
            (0..pts.len()).max_by(|&a, &b| (pts[a] - pts[0]).norm().total_cmp(&(pts[b] - pts[0]).norm())).unwrap();
        let faces: Vec<[u32; 3]> =
            sphere.triangles().iter().copied().filter(|t| !t.contains(&0) && !t.contains(&(far as u32))).collect();
        let normals: Vec<Vec3> = pts.iter().map(|p| p.normalize()).collect();
        let (closed, stats) = close_surface(&pts, &normals, faces).unwrap();
        assert_eq!(stats.holes, 2);
        assert_eq!(stats.largest_hole, 5);
        let mut mesh = CellMesh::from_triangles(pts, closed).unwrap();
        mesh.remove_unused_nodes();
        assert_eq!(mesh.validate(), Ok(()));
    }

    #[test]
    fn a_pinched_fan_is_removed_and_the_hole_closed() {
        let sphere = icosphere(1.0, 2, Vec3::zeros());
        let mut pts = sphere.positions().to_vec();
        let mut faces = sphere.triangles().to_vec();
        // A stray triangle hanging off node 0 by a vertex only.
        let base = pts.len() as u32;
        pts.push(pts[0] * 1.3 + Vec3::new(0.1, 0.0, 0.0));
        pts.push(pts[0] * 1.3 + Vec3::new(0.0, 0.1, 0.0));
        faces.push([0, base, base + 1]);
        let normals: Vec<Vec3> = pts.iter().map(|p| p.normalize()).collect();
        let (closed, stats) = close_surface(&pts, &normals, faces).unwrap();
        assert_eq!(stats.removed_faces, 1);
        assert_eq!(stats.holes, 0);
        let mut mesh = CellMesh::from_triangles(pts, closed).unwrap();
        mesh.remove_unused_nodes();
        assert_eq!(mesh.validate(), Ok(()));
    }
}

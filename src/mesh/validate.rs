//! Mesh invariant checks: what makes a triangle surface a valid cell.
//!
//! A valid cell surface is: finite coordinates; no degenerate or duplicate faces; every edge shared by
//! exactly two faces (closed, 2-manifold); neighbouring faces traverse their shared edge in opposite
//! directions (consistently oriented); each node's faces form one fan (no pinched vertices); every node
//! used; one connected component with Euler characteristic V − E + F = 2 (a sphere, genus 0); positive
//! signed volume (normals point outward).

use super::{Adjacency, CellMesh};
use crate::geometry::{Real, triangle_area};
use serde::Serialize;

/// The first checks stop collecting after this many defects (pathological inputs).
const MAX_DEFECTS: usize = 1000;

/// One way in which a mesh fails to be a valid cell surface.
#[derive(Clone, Debug, PartialEq, thiserror::Error, Serialize)]
#[serde(tag = "defect", rename_all = "snake_case")]
pub enum MeshDefect {
    #[error("the mesh has {faces} faces; a closed surface needs at least 4")]
    TooFewFaces { faces: usize },
    #[error("node {node} has a non-finite coordinate")]
    NonFiniteCoordinate { node: u32 },
    #[error("face {face} is degenerate (repeated node or zero area)")]
    DegenerateFace { face: u32 },
    #[error("faces {a} and {b} use the same three nodes")]
    DuplicateFace { a: u32, b: u32 },
    #[error("edge {a}-{b} borders only face {face}: the surface has a hole")]
    BoundaryEdge { a: u32, b: u32, face: u32 },
    #[error("edge {a}-{b} is shared by {faces} faces (non-manifold edge)")]
    NonManifoldEdge { a: u32, b: u32, faces: usize },
    #[error("faces {face_a} and {face_b} are oriented inconsistently across edge {a}-{b} (a flipped face)")]
    InconsistentOrientation { face_a: u32, face_b: u32, a: u32, b: u32 },
    #[error("node {node} is a non-manifold vertex: its faces form {fans} separate fans")]
    NonManifoldVertex { node: u32, fans: usize },
    #[error("node {node} is used by no face")]
    UnusedNode { node: u32 },
    #[error("the surface has {components} connected components, expected 1")]
    Disconnected { components: usize },
    #[error("Euler characteristic V - E + F = {chi}, expected 2 (a surface of genus 0)")]
    EulerCharacteristic { chi: i64 },
    #[error("signed volume {volume:e} is not positive: the faces point inward")]
    NonPositiveVolume { volume: Real },
}

impl CellMesh {
    /// Checks every invariant of a valid cell surface; returns the first defect found.
    pub fn validate(&self) -> Result<(), MeshDefect> {
        match self.check().into_iter().next() {
            Some(d) => Err(d),
            None => Ok(()),
        }
    }

    /// All defects (up to a cap), in the order: size, coordinates, faces, edges, orientation,
    /// vertices, topology, volume. Later checks are skipped when earlier ones make them meaningless.
    pub fn check(&self) -> Vec<MeshDefect> {
        let mut defects = Vec::new();
        let tris = self.triangles();
        if tris.len() < 4 {
            defects.push(MeshDefect::TooFewFaces { faces: tris.len() });
            return defects;
        }
        for (n, p) in self.positions().iter().enumerate() {
            if !p.iter().all(|c| c.is_finite()) && defects.len() < MAX_DEFECTS {
                defects.push(MeshDefect::NonFiniteCoordinate { node: n as u32 });
            }
        }
        let finite = defects.is_empty();
        for (f, t) in tris.iter().enumerate() {
            if defects.len() >= MAX_DEFECTS {
                break;
            }
            let repeated = t[0] == t[1] || t[1] == t[2] || t[0] == t[2];
            let flat = finite && !repeated && {
                let [a, b, c] = t.map(|i| self.positions()[i as usize]);
                let longest = (b - a).norm_squared().max((c - b).norm_squared()).max((a - c).norm_squared());
                triangle_area(&a, &b, &c) <= 1e-12 * longest
            };
            if repeated || flat {
                defects.push(MeshDefect::DegenerateFace { face: f as u32 });
            }
        }
        let mut sorted: Vec<([u32; 3], u32)> = tris
            .iter()
            .enumerate()
            .map(|(f, t)| {
                let mut k = *t;
                k.sort_unstable();
                (k, f as u32)
            })
            .collect();
        sorted.sort_unstable();
        for w in sorted.windows(2) {
            if w[0].0 == w[1].0 && defects.len() < MAX_DEFECTS {
                defects.push(MeshDefect::DuplicateFace { a: w[0].1, b: w[1].1 });
            }
        }

        let adj = Adjacency::new(self);
        let mut manifold_edges = true;
        for (e, &[a, b]) in adj.edges().iter().enumerate() {
            let faces = adj.edge_faces(e);
            match faces.len() {
                2 => {
                    let (fa, fb) = (faces[0], faces[1]);
                    if directed(tris[fa as usize], a, b) == directed(tris[fb as usize], a, b)
                        && defects.len() < MAX_DEFECTS
                    {
                        defects.push(MeshDefect::InconsistentOrientation { face_a: fa, face_b: fb, a, b });
                    }
                }
                1 => {
                    manifold_edges = false;
                    if defects.len() < MAX_DEFECTS {
                        defects.push(MeshDefect::BoundaryEdge { a, b, face: faces[0] });
                    }
                }
                n => {
                    manifold_edges = false;
                    if defects.len() < MAX_DEFECTS {
                        defects.push(MeshDefect::NonManifoldEdge { a, b, faces: n });
                    }
                }
            }
        }

        let mut used_nodes = 0usize;
        for n in 0..self.node_count() {
            let faces = adj.node_faces(n);
            if faces.is_empty() {
                if defects.len() < MAX_DEFECTS {
                    defects.push(MeshDefect::UnusedNode { node: n as u32 });
                }
                continue;
            }
            used_nodes += 1;
            if manifold_edges {
                let fans = count_fans(&adj, faces, n as u32, tris);
                if fans > 1 && defects.len() < MAX_DEFECTS {
                    defects.push(MeshDefect::NonManifoldVertex { node: n as u32, fans });
                }
            }
        }

        let components = face_components(&adj, tris.len());
        if components != 1 {
            defects.push(MeshDefect::Disconnected { components });
        }
        let chi = used_nodes as i64 - adj.edges().len() as i64 + tris.len() as i64;
        if chi != 2 && components == 1 {
            defects.push(MeshDefect::EulerCharacteristic { chi });
        }
        if defects.is_empty() {
            let volume = self.signed_volume();
            if volume.is_nan() || volume <= 0.0 {
                defects.push(MeshDefect::NonPositiveVolume { volume });
            }
        }
        defects
    }
}

/// Whether triangle `t` traverses the edge from `a` to `b` (true) or from `b` to `a` (false).
fn directed(t: [u32; 3], a: u32, b: u32) -> bool {
    (0..3).any(|s| t[s] == a && t[(s + 1) % 3] == b)
}

/// Number of fans formed by the faces around node `n`: faces are joined when they share an edge
/// incident to `n`. Called only when every edge borders exactly two faces.
fn count_fans(adj: &Adjacency, faces: &[u32], n: u32, tris: &[[u32; 3]]) -> usize {
    if is_single_fan(adj, faces, n, tris) {
        return 1;
    }
    count_fans_by_union(adj, faces, n, tris)
}

/// Fast path of [`count_fans`] for the common case: walks from the first face around `n`, always
/// leaving a face through its other side incident to `n`. When every edge borders two faces, each
/// face that holds `n` once has exactly two such sides, so the faces form cycles and the walk goes
/// round one of them; it is a single fan iff that cycle holds all the faces. Returns false (the
/// caller then counts with union–find) for anything unusual, such as a face holding `n` twice.
fn is_single_fan(adj: &Adjacency, faces: &[u32], n: u32, tris: &[[u32; 3]]) -> bool {
    // The side of face `f` leaving node `n` (side k joins corners k and k + 1) and the side coming
    // into it, as edge indices; None if `n` is not exactly once in `f`.
    let sides = |f: u32| -> Option<[u32; 2]> {
        let t = tris[f as usize];
        let mut corners = (0..3).filter(|&k| t[k] == n);
        let k = corners.next()?;
        if corners.next().is_some() {
            return None;
        }
        if t[(k + 1) % 3] == t[(k + 2) % 3] {
            return None;
        }
        let e = adj.face_edges(f as usize);
        Some([e[k], e[(k + 2) % 3]])
    };
    let start = faces[0];
    let Some([first, _]) = sides(start) else { return false };
    let (mut face, mut edge) = (start, first);
    for step in 1..=faces.len() {
        let next = match *adj.edge_faces(edge as usize) {
            [a, b] if a == face && b != face => b,
            [a, b] if b == face && a != face => a,
            _ => return false,
        };
        let Some([x, y]) = sides(next) else { return false };
        edge = if x == edge { y } else { x };
        face = next;
        if face == start {
            // Each step went to a face sharing an edge incident to `n` (so a face around `n`),
            // never back through the edge it came in by: a cycle of `step` distinct faces.
            return step == faces.len();
        }
    }
    false
}

/// [`count_fans`] by union–find over the faces around `n`.
fn count_fans_by_union(adj: &Adjacency, faces: &[u32], n: u32, tris: &[[u32; 3]]) -> usize {
    let mut parent: Vec<usize> = (0..faces.len()).collect();
    for (i, &f) in faces.iter().enumerate() {
        let t = tris[f as usize];
        for s in 0..3 {
            if t[s] != n && t[(s + 1) % 3] != n {
                continue;
            }
            let e = adj.face_edges(f as usize)[s] as usize;
            for &g in adj.edge_faces(e) {
                if g != f
                    && let Ok(j) = faces.binary_search(&g)
                {
                    union(&mut parent, i, j);
                }
            }
        }
    }
    (0..faces.len()).filter(|&i| find(&mut parent, i) == i).count()
}

/// Number of connected components of the face graph (faces joined through shared edges).
pub(crate) fn face_components(adj: &Adjacency, faces: usize) -> usize {
    face_components_of(adj, faces).1
}

/// Connected component of every face (0-based, in order of first face) and the component count.
pub(crate) fn face_components_of(adj: &Adjacency, faces: usize) -> (Vec<usize>, usize) {
    let mut parent: Vec<usize> = (0..faces).collect();
    for e in 0..adj.edges().len() {
        let fs = adj.edge_faces(e);
        for w in fs.windows(2) {
            union(&mut parent, w[0] as usize, w[1] as usize);
        }
    }
    let mut label = vec![usize::MAX; faces];
    let mut count = 0;
    for f in 0..faces {
        let r = find(&mut parent, f);
        if label[r] == usize::MAX {
            label[r] = count;
            count += 1;
        }
        label[f] = label[r];
    }
    (label, count)
}

fn find(parent: &mut [usize], mut i: usize) -> usize {
    while parent[i] != i {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    i
}

fn union(parent: &mut [usize], a: usize, b: usize) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    if ra != rb {
        parent[ra.max(rb)] = ra.min(rb);
    }
}

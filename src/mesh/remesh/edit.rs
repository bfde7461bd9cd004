//! `EditMesh`: the working form of a cell surface while it is remeshed.
//!
//! Triangles keep their slots while edits run (a removed face is marked dead, a removed node is marked
//! dead), so node and face indices stay stable through a whole pass and the operations never hold a
//! reference across a push (the reference program's edge split does, and crashes). Each node knows
//! its incident faces, which is all the local operations need. `compact` renumbers at the end.

use super::RemeshRefusal;
use crate::geometry::{Real, Vec3, triangle_area, triangle_normal};
use crate::mesh::{CellMesh, FaceType};

/// A face whose area is at most this fraction of its longest side squared counts as degenerate.
/// Stricter than `validate()` (1e-12), so an accepted edit never produces a face close to that limit.
const DEGENERATE_AREA_RATIO: Real = 1e-9;

/// An interior edge `a → b` with its two faces: `left = [a, b, c]` and `right = [b, a, d]`
/// (counter-clockwise from outside, up to rotation).
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub(super) struct Wing {
    pub a: u32,
    pub b: u32,
    pub c: u32,
    pub d: u32,
    pub left: u32,
    pub right: u32,
}

/// A mesh under local edits, with its per-node momenta and per-face types.
#[derive(Clone, Debug)]
pub(super) struct EditMesh {
    pub positions: Vec<Vec3>,
    pub momenta: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    pub face_types: Vec<FaceType>,
    pub face_alive: Vec<bool>,
    pub node_alive: Vec<bool>,
    /// Live faces incident to each node, unordered.
    pub node_faces: Vec<Vec<u32>>,
}

/// The arrays of an edited mesh after dead nodes and faces are dropped.
pub(super) struct Compacted {
    pub positions: Vec<Vec3>,
    pub momenta: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    pub face_types: Vec<FaceType>,
    /// New index of each old node (`u32::MAX` for a removed node).
    pub new_index: Vec<u32>,
}

impl EditMesh {
    /// Copies `mesh`; `momenta` has one entry per node and `face_types` one per face (the caller checks).
    pub fn new(mesh: &CellMesh, momenta: Vec<Vec3>, face_types: Vec<FaceType>) -> Self {
        debug_assert_eq!(momenta.len(), mesh.node_count());
        debug_assert_eq!(face_types.len(), mesh.face_count());
        let mut node_faces = vec![Vec::new(); mesh.node_count()];
        for (f, t) in mesh.triangles().iter().enumerate() {
            for &n in t {
                // A face with a repeated corner is listed once per distinct corner.
                if !node_faces[n as usize].contains(&(f as u32)) {
                    node_faces[n as usize].push(f as u32);
                }
            }
        }
        Self {
            positions: mesh.positions().to_vec(),
            momenta,
            triangles: mesh.triangles().to_vec(),
            face_types,
            face_alive: vec![true; mesh.face_count()],
            node_alive: vec![true; mesh.node_count()],
            node_faces,
        }
    }

    /// Whether `n` is a live node of this mesh.
    pub fn has_node(&self, n: u32) -> bool {
        self.node_alive.get(n as usize).copied().unwrap_or(false)
    }

    /// The two faces of edge `a`–`b`, oriented so that `left` runs `a → b`. Refused when the edge does
    /// not exist or is not a manifold edge with consistently oriented faces.
    pub fn wing(&self, a: u32, b: u32) -> Result<Wing, RemeshRefusal> {
        if a == b || !self.has_node(a) || !self.has_node(b) {
            return Err(RemeshRefusal::NotAnEdge { a, b });
        }
        let mut left = None;
        let mut right = None;
        let mut count = 0;
        for &f in &self.node_faces[a as usize] {
            let t = self.triangles[f as usize];
            let Some(s) = (0..3).find(|&s| t[s] == a) else { continue };
            if !t.contains(&b) {
                continue;
            }
            count += 1;
            if t[(s + 1) % 3] == b {
                left = Some((f, t[(s + 2) % 3]));
            } else if t[(s + 2) % 3] == b {
                right = Some((f, t[(s + 1) % 3]));
            }
        }
        match (count, left, right) {
            (0, _, _) => Err(RemeshRefusal::NotAnEdge { a, b }),
            (2, Some((left, c)), Some((right, d))) if c != d && c != a && c != b && d != a && d != b => {
                Ok(Wing { a, b, c, d, left, right })
            }
            _ => Err(RemeshRefusal::NonManifoldEdge { a, b }),
        }
    }

    /// Nodes joined to `n` by an edge, sorted.
    pub fn neighbours(&self, n: u32) -> Vec<u32> {
        let mut out: Vec<u32> =
            self.node_faces[n as usize].iter().flat_map(|&f| self.triangles[f as usize]).filter(|&m| m != n).collect();
        out.sort_unstable();
        out.dedup();
        out
    }

    /// Distance between two nodes.
    pub fn length(&self, a: u32, b: u32) -> Real {
        (self.positions[a as usize] - self.positions[b as usize]).norm()
    }

    /// Corner positions of a face.
    pub fn corners(&self, f: u32) -> [Vec3; 3] {
        self.triangles[f as usize].map(|i| self.positions[i as usize])
    }

    /// Removes `f` from the face list of node `n`.
    pub fn detach(&mut self, n: u32, f: u32) {
        let faces = &mut self.node_faces[n as usize];
        if let Some(k) = faces.iter().position(|&g| g == f) {
            faces.swap_remove(k);
        }
    }

    /// Adds `f` to the face list of node `n`.
    pub fn attach(&mut self, n: u32, f: u32) {
        self.node_faces[n as usize].push(f);
    }

    /// Live undirected edges `[a, b]` (`a < b`) with their lengths, keeping those for which
    /// `keep(length)` holds; sorted by nodes and deduplicated. Only the kept edges are sorted, so
    /// asking for the few out-of-range edges of a mesh is cheap.
    pub fn edges_with_length(&self, keep: impl Fn(Real) -> bool) -> Vec<(Real, [u32; 2])> {
        let mut out: Vec<(Real, [u32; 2])> = Vec::new();
        for f in self.live_faces() {
            let t = self.triangles[f as usize];
            for s in 0..3 {
                let (a, b) = (t[s], t[(s + 1) % 3]);
                let l = self.length(a, b);
                if keep(l) {
                    out.push((l, [a.min(b), a.max(b)]));
                }
            }
        }
        out.sort_unstable_by_key(|x| x.1);
        out.dedup_by(|x, y| x.1 == y.1);
        out
    }

    /// Indices of the live faces, in increasing order.
    pub fn live_faces(&self) -> impl Iterator<Item = u32> + '_ {
        self.face_alive.iter().enumerate().filter(|(_, alive)| **alive).map(|(f, _)| f as u32)
    }

    /// Drops dead nodes and faces, renumbering the rest in their original order.
    pub fn compact(self) -> Compacted {
        let mut new_index = vec![u32::MAX; self.positions.len()];
        let mut positions = Vec::with_capacity(self.positions.len());
        let mut momenta = Vec::with_capacity(self.positions.len());
        for (n, alive) in self.node_alive.iter().enumerate() {
            if *alive {
                new_index[n] = positions.len() as u32;
                positions.push(self.positions[n]);
                momenta.push(self.momenta[n]);
            }
        }
        let mut triangles = Vec::with_capacity(self.triangles.len());
        let mut face_types = Vec::with_capacity(self.triangles.len());
        for (f, alive) in self.face_alive.iter().enumerate() {
            if *alive {
                triangles.push(self.triangles[f].map(|i| new_index[i as usize]));
                face_types.push(self.face_types[f]);
            }
        }
        Compacted { positions, momenta, triangles, face_types, new_index }
    }
}

/// Whether a triangle is (nearly) degenerate: area at most `DEGENERATE_AREA_RATIO` times its longest
/// side squared, or not finite.
pub(super) fn is_degenerate(corners: [Vec3; 3]) -> bool {
    let [a, b, c] = corners;
    let longest = (b - a).norm_squared().max((c - b).norm_squared()).max((a - c).norm_squared());
    let area = triangle_area(&a, &b, &c);
    !area.is_finite() || area <= DEGENERATE_AREA_RATIO * longest
}

/// Unnormalised outward normal of a triangle.
pub(super) fn normal(corners: [Vec3; 3]) -> Vec3 {
    triangle_normal(&corners[0], &corners[1], &corners[2])
}

//! Geometry of one cell recomputed at every force evaluation: face area vectors, areas and unit
//! normals, total area and signed volume. Kept in a reusable buffer so the hot loop never allocates.

use crate::geometry::{Real, Vec3};
use crate::mesh::CellMesh;

/// Per-evaluation geometry of one cell.
#[derive(Clone, Debug, Default)]
pub struct CellGeometry {
    /// A_f·n̂_f of every face (m²).
    pub area_vectors: Vec<Vec3>,
    /// A_f of every face (m²).
    pub areas: Vec<Real>,
    /// n̂_f of every face (zero for a degenerate face).
    pub normals: Vec<Vec3>,
    /// Total area A (m²).
    pub area: Real,
    /// Signed volume V (m³), positive for an outward-oriented surface.
    pub volume: Real,
}

impl CellGeometry {
    /// Recomputes everything for the mesh's current positions.
    pub fn update(&mut self, mesh: &CellMesh) {
        let p = mesh.positions();
        let tris = mesh.triangles();
        let n = tris.len();
        self.area_vectors.resize(n, Vec3::zeros());
        self.areas.resize(n, 0.0);
        self.normals.resize(n, Vec3::zeros());
        let o = p.first().copied().unwrap_or_else(Vec3::zeros);
        let (mut area, mut six_volume) = (0.0, 0.0);
        for (f, t) in tris.iter().enumerate() {
            let (a, b, c) = (p[t[0] as usize] - o, p[t[1] as usize] - o, p[t[2] as usize] - o);
            let cross = (b - a).cross(&(c - a));
            let norm = cross.norm();
            self.area_vectors[f] = 0.5 * cross;
            self.areas[f] = 0.5 * norm;
            self.normals[f] = if norm > 0.0 { cross / norm } else { Vec3::zeros() };
            area += 0.5 * norm;
            six_volume += a.dot(&b.cross(&c));
        }
        self.area = area;
        self.volume = six_volume / 6.0;
    }
}

//! A per-cell geometric summary: size, measures and validity, as `tissuefit inspect` reports it.

use super::{Cell, MeshDefect, sphericity};
use crate::geometry::Real;
use serde::Serialize;

/// Measures and validity of one cell. Keys are a stable interface (`inspect --json`, DESIGN.md §2).
#[derive(Clone, Debug, Serialize)]
pub struct CellSummary {
    pub id: u32,
    pub kind: &'static str,
    /// Parameter-set index (`cell_type_id` in SimuCell3D files).
    pub cell_type: u32,
    pub nodes: usize,
    pub faces: usize,
    /// Signed volume (m³); negative for an inside-out surface.
    pub volume: Real,
    /// Surface area (m²).
    pub area: Real,
    /// π^(1/3)(6V)^(2/3)/A.
    pub sphericity: Real,
    /// Whether the mesh is a valid closed cell surface.
    pub valid: bool,
    /// The first defect, when invalid.
    pub defect: Option<String>,
    /// Number of defects found (capped at 1000).
    pub defect_count: usize,
    /// Edge lengths (m): shortest, mean, longest.
    pub edge_min: Real,
    pub edge_mean: Real,
    pub edge_max: Real,
}

impl CellSummary {
    /// Measures `cell` and checks its mesh.
    pub fn of(cell: &Cell) -> Self {
        let mesh = cell.mesh();
        let defects: Vec<MeshDefect> = mesh.check();
        let (volume, area) = (mesh.signed_volume(), mesh.area());
        let edges = mesh.edge_length_stats();
        Self {
            id: cell.id().0,
            kind: cell.kind().name(),
            cell_type: cell.cell_type(),
            nodes: mesh.node_count(),
            faces: mesh.face_count(),
            volume,
            area,
            sphericity: sphericity(volume.max(0.0), area),
            valid: defects.is_empty(),
            defect: defects.first().map(|d| d.to_string()),
            defect_count: defects.len(),
            edge_min: edges.map_or(Real::NAN, |e| e.min),
            edge_mean: edges.map_or(Real::NAN, |e| e.mean),
            edge_max: edges.map_or(Real::NAN, |e| e.max),
        }
    }
}

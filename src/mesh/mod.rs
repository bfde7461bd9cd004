//! Cell surfaces: `CellMesh` (closed, outward-oriented triangle surface with `u32` indices), its
//! adjacency, invariant checks, measures, analytic shapes, division by a plane, and the `Tissue` that
//! groups cells.

mod adjacency;
mod cap;
mod cell_mesh;
mod divide;
mod ids;
mod measures;
mod orient;
pub mod remesh;
pub mod shapes;
mod summary;
mod tissue;
mod triangulate;
mod validate;

pub use adjacency::Adjacency;
pub use cell_mesh::CellMesh;
pub use divide::{
    CAP_SPACING, Daughter, DaughterSide, DivisionError, DivisionPlane, NodeOrigin, SNAP_FRACTION, divide_mesh,
    division_plane, division_plane_normal,
};
pub use ids::{CellId, FaceId, NodeId};
pub use measures::{EdgeLengthStats, PrincipalAxes, sphericity};
pub use summary::CellSummary;
pub use tissue::{Cell, CellKind, CellOverrides, FaceType, Tissue, TissueError};
pub use validate::MeshDefect;

/// Errors building a mesh from raw arrays.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MeshError {
    #[error("face {face} refers to node {index}, but the mesh has {nodes} nodes")]
    NodeIndexOutOfRange { face: usize, index: usize, nodes: usize },
    #[error("polygon {polygon} has {corners} corners; a face needs at least 3")]
    PolygonTooSmall { polygon: usize, corners: usize },
    #[error("{nodes} nodes exceed the u32 index range")]
    TooManyNodes { nodes: usize },
}

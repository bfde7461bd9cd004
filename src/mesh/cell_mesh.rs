//! `CellMesh`: one cell's closed, outward-oriented triangle surface.

use super::MeshError;
use super::ids::{FaceId, NodeId};
use super::triangulate::triangulate_polygon;
use crate::geometry::{Real, Vec3};

/// A cell surface: node positions (metres) and triangles as `u32` node indices.
///
/// A valid cell mesh (see [`CellMesh::validate`]) is closed, 2-manifold, connected, genus 0, and
/// wound so that `(b − a) × (c − a)` points out of the cell (positive signed volume). Construction only
/// checks that indices are in range: meshes read from real files may be defective, and the defects
/// are reported by `validate()`/`check()` rather than refused.
#[derive(Clone, Debug)]
pub struct CellMesh {
    positions: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
    /// Changes whenever the triangles change, so caches of derived topology (adjacency, hinges)
    /// know when to rebuild. Not part of equality.
    topology_generation: u64,
}

/// Meshes are equal when their positions and triangles are; the cache generation does not count.
impl PartialEq for CellMesh {
    fn eq(&self, other: &Self) -> bool {
        self.positions == other.positions && self.triangles == other.triangles
    }
}

/// Source of topology generations, unique across all meshes of the process, so a cache never
/// mistakes one mesh's topology for another's.
static NEXT_GENERATION: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);

fn next_generation() -> u64 {
    NEXT_GENERATION.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
}

impl CellMesh {
    /// Builds a mesh from triangles. Errors if an index is out of range or there are more than
    /// `u32::MAX` nodes.
    pub fn from_triangles(positions: Vec<Vec3>, triangles: Vec<[u32; 3]>) -> Result<Self, MeshError> {
        let nodes = u32::try_from(positions.len()).map_err(|_| MeshError::TooManyNodes { nodes: positions.len() })?;
        for (f, t) in triangles.iter().enumerate() {
            if let Some(&index) = t.iter().find(|&&i| i >= nodes) {
                return Err(MeshError::NodeIndexOutOfRange { face: f, index: index as usize, nodes: nodes as usize });
            }
        }
        Ok(Self { positions, triangles, topology_generation: next_generation() })
    }

    /// Builds a mesh from polygons (any number of corners ≥ 3), triangulating each in its plane while
    /// keeping its winding. Returns the mesh and, for each triangle, the index of its source polygon.
    pub fn from_polygons<P: AsRef<[u32]>>(positions: Vec<Vec3>, polygons: &[P]) -> Result<(Self, Vec<u32>), MeshError> {
        let nodes = positions.len();
        let mut triangles = Vec::with_capacity(polygons.len());
        let mut source = Vec::with_capacity(polygons.len());
        for (k, poly) in polygons.iter().enumerate() {
            let poly = poly.as_ref();
            if poly.len() < 3 {
                return Err(MeshError::PolygonTooSmall { polygon: k, corners: poly.len() });
            }
            if let Some(&index) = poly.iter().find(|&&i| i as usize >= nodes) {
                return Err(MeshError::NodeIndexOutOfRange { face: k, index: index as usize, nodes });
            }
            let before = triangles.len();
            triangulate_polygon(&positions, poly, &mut triangles);
            source.extend(std::iter::repeat_n(k as u32, triangles.len() - before));
        }
        Ok((Self::from_triangles(positions, triangles)?, source))
    }

    /// Identifies the current triangle list: it changes with every topology edit (and differs
    /// between meshes), so caches keyed by it are never stale.
    #[inline]
    pub fn topology_generation(&self) -> u64 {
        self.topology_generation
    }

    /// Node positions.
    #[inline]
    pub fn positions(&self) -> &[Vec3] {
        &self.positions
    }

    /// Mutable node positions (topology unchanged).
    #[inline]
    pub fn positions_mut(&mut self) -> &mut [Vec3] {
        &mut self.positions
    }

    /// Triangles as node indices, counter-clockwise seen from outside.
    #[inline]
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// Number of nodes.
    #[inline]
    pub fn node_count(&self) -> usize {
        self.positions.len()
    }

    /// Number of triangles.
    #[inline]
    pub fn face_count(&self) -> usize {
        self.triangles.len()
    }

    /// Position of one node.
    #[inline]
    pub fn position(&self, n: NodeId) -> Vec3 {
        self.positions[n.index()]
    }

    /// The three corner positions of a face.
    #[inline]
    pub fn corners(&self, f: FaceId) -> [Vec3; 3] {
        self.triangles[f.index()].map(|i| self.positions[i as usize])
    }

    /// Length of the shortest edge (m); infinity for a mesh without faces. Reads every triangle's
    /// three edges (each interior edge twice) without building the adjacency: cheap enough to call
    /// every step.
    pub fn shortest_edge(&self) -> Real {
        let x = &self.positions;
        let mut shortest = Real::INFINITY;
        for t in &self.triangles {
            let [a, b, c] = t.map(|i| x[i as usize]);
            shortest = shortest.min((a - b).norm_squared()).min((b - c).norm_squared()).min((c - a).norm_squared());
        }
        shortest.sqrt()
    }

    /// Reverses the winding of one face.
    pub fn flip_face(&mut self, f: FaceId) {
        self.triangles[f.index()].swap(1, 2);
        self.topology_generation = next_generation();
    }

    /// Reverses the winding of every face (turns the surface inside out).
    pub fn flip_all(&mut self) {
        self.triangles.iter_mut().for_each(|t| t.swap(1, 2));
        self.topology_generation = next_generation();
    }

    /// Multiplies coordinates component-wise by `factor` (unit conversion, anisotropic voxels).
    /// A factor with an odd number of negative components would turn the surface inside out, so the
    /// winding is reversed in that case.
    pub fn scale(&mut self, factor: Vec3) {
        self.positions.iter_mut().for_each(|p| *p = p.component_mul(&factor));
        if factor.x * factor.y * factor.z < 0.0 {
            self.flip_all();
        }
    }

    /// Removes nodes used by no triangle, renumbering the rest in their original order.
    pub fn remove_unused_nodes(&mut self) {
        let mut new_index = vec![u32::MAX; self.positions.len()];
        for t in &self.triangles {
            for &i in t {
                new_index[i as usize] = 0;
            }
        }
        let mut next = 0u32;
        let mut kept = Vec::with_capacity(self.positions.len());
        for (old, slot) in new_index.iter_mut().enumerate() {
            if *slot == 0 {
                *slot = next;
                next += 1;
                kept.push(self.positions[old]);
            }
        }
        for t in &mut self.triangles {
            *t = t.map(|i| new_index[i as usize]);
        }
        self.positions = kept;
        self.topology_generation = next_generation();
    }
}

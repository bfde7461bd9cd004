//! `Tissue`: the cells of a simulation or a segmented image, each a closed surface with an identity,
//! a kind, a parameter-set (cell type) index, and a face type per triangle.

use super::{CellId, CellMesh};
use crate::geometry::Real;
use serde::{Deserialize, Serialize};
use std::fmt;

/// What a closed surface represents. The numeric codes are SimuCell3D's `global_cell_id`s, used in
/// its files and in ours.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum CellKind {
    /// A free, deformable cell.
    Epithelial,
    /// Extracellular matrix: an enclosing body that never moves; contacts are sensed from inside.
    Ecm,
    /// A lumen: a fluid cavity with pressure and tension, no adhesion.
    Lumen,
    /// A nucleus: a body enclosed by its cell.
    Nucleus,
    /// A cell that never moves (e.g. the boundary cells of an imaged patch).
    Static,
}

impl CellKind {
    /// All kinds, in code order.
    pub const ALL: [CellKind; 5] =
        [CellKind::Epithelial, CellKind::Ecm, CellKind::Lumen, CellKind::Nucleus, CellKind::Static];

    /// SimuCell3D `global_cell_id`: 0 epithelial, 1 ECM, 2 lumen, 3 nucleus, 4 static.
    pub fn code(self) -> u32 {
        self as u32
    }

    /// Inverse of [`CellKind::code`].
    pub fn from_code(code: u32) -> Option<Self> {
        Self::ALL.get(code as usize).copied()
    }

    /// Lower-case name as used in configs and reports.
    pub fn name(self) -> &'static str {
        match self {
            CellKind::Epithelial => "epithelial",
            CellKind::Ecm => "ecm",
            CellKind::Lumen => "lumen",
            CellKind::Nucleus => "nucleus",
            CellKind::Static => "static",
        }
    }

    /// Whether cells of this kind never move.
    pub fn is_immobile(self) -> bool {
        matches!(self, CellKind::Ecm | CellKind::Static)
    }

    /// Whether this kind is a cell of the tissue proper (epithelial or static): what couples, gets
    /// polarised, hosts nuclei and forms the contact graph, as opposed to the ECM, lumen and nuclei.
    pub fn is_cell(self) -> bool {
        matches!(self, CellKind::Epithelial | CellKind::Static)
    }
}

impl fmt::Display for CellKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Membrane region of a triangle; each has its own tension, bending stiffness, adhesion and repulsion.
/// Codes follow SimuCell3D's face types: 0 apical, 1 lateral, 2 basal.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FaceType {
    /// Facing a lumen (or, without polarisation, every face: SimuCell3D's type 0).
    #[default]
    Apical,
    /// Facing another cell.
    Lateral,
    /// Facing the exterior or the ECM.
    Basal,
}

impl FaceType {
    /// All face types, in code order.
    pub const ALL: [FaceType; 3] = [FaceType::Apical, FaceType::Lateral, FaceType::Basal];

    /// Numeric code: 0 apical, 1 lateral, 2 basal.
    pub fn code(self) -> u32 {
        self as u32
    }

    /// Inverse of [`FaceType::code`].
    pub fn from_code(code: u32) -> Option<Self> {
        Self::ALL.get(code as usize).copied()
    }

    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            FaceType::Apical => "apical",
            FaceType::Lateral => "lateral",
            FaceType::Basal => "basal",
        }
    }
}

/// Structural errors of a tissue (not mesh defects: those are reported per cell by `validate`).
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum TissueError {
    #[error("cell {cell}: {face_types} face types given for {faces} faces")]
    FaceTypeCount { cell: CellId, face_types: usize, faces: usize },
    #[error("cell id {0} appears twice")]
    DuplicateCellId(CellId),
    #[error("cell {cell}: {labels} interface labels given for {faces} faces")]
    InterfaceLabelCount { cell: CellId, labels: usize, faces: usize },
}

/// Per-cell values that replace its cell type's, per face type (code order: apical, lateral,
/// basal); `None` keeps the type's value. What a per-cell map of tensions and adhesions sets: the
/// simulation runs each cell with its type's parameters overridden by these, tissue files carry
/// them (`surface_tension_apical` … `adhesion_basal` cell arrays), and daughters inherit them.
#[derive(Copy, Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct CellOverrides {
    /// Surface tension γ per face type. Unit: N/m.
    pub surface_tension: [Option<Real>; 3],
    /// Spring adhesion strength ω per face type. Unit: Pa/m.
    pub adhesion: [Option<Real>; 3],
}

impl CellOverrides {
    /// The quantities a cell may override, with their units: the names of their file arrays are
    /// `NAME_FACETYPE` (e.g. `surface_tension_lateral`).
    pub const QUANTITIES: [(&'static str, &'static str); 2] = [("surface_tension", "N/m"), ("adhesion", "Pa/m")];

    /// Whether nothing is overridden.
    pub fn is_empty(&self) -> bool {
        self.surface_tension.iter().chain(&self.adhesion).all(Option::is_none)
    }

    /// The values of quantity `q` (an index into [`Self::QUANTITIES`]), per face type.
    pub fn values(&self, q: usize) -> &[Option<Real>; 3] {
        if q == 0 { &self.surface_tension } else { &self.adhesion }
    }

    /// Mutable values of quantity `q` (an index into [`Self::QUANTITIES`]), per face type.
    pub fn values_mut(&mut self, q: usize) -> &mut [Option<Real>; 3] {
        if q == 0 { &mut self.surface_tension } else { &mut self.adhesion }
    }

    /// The names of the cell arrays a tissue file carries them in, per quantity (as
    /// [`Self::QUANTITIES`]) and face type (code order).
    pub const ARRAY_NAMES: [[&'static str; 3]; 2] = [
        ["surface_tension_apical", "surface_tension_lateral", "surface_tension_basal"],
        ["adhesion_apical", "adhesion_lateral", "adhesion_basal"],
    ];

    /// Every (array name, quantity index, face type) a tissue file may carry, e.g.
    /// (`surface_tension_lateral`, 0, Lateral).
    pub fn array_names() -> impl Iterator<Item = (&'static str, usize, FaceType)> {
        (0..2).flat_map(|q| FaceType::ALL.into_iter().map(move |t| (Self::ARRAY_NAMES[q][t.code() as usize], q, t)))
    }

    /// The first value that is not a finite number ≥ 0, as (array name, value).
    pub fn invalid(&self) -> Option<(&'static str, Real)> {
        Self::array_names().find_map(|(name, q, t)| {
            self.values(q)[t.code() as usize].filter(|v| !(v.is_finite() && *v >= 0.0)).map(|v| (name, v))
        })
    }
}

/// One cell: its surface and what it is.
#[derive(Clone, Debug, PartialEq)]
pub struct Cell {
    id: CellId,
    kind: CellKind,
    cell_type: u32,
    mesh: CellMesh,
    face_types: Vec<FaceType>,
    target_volume: Real,
    /// The cell this one was born from by division (lineage); `None` for founders.
    parent: Option<CellId>,
    /// Per face, the id of the body on its other side as the input file said (0 = the medium), for
    /// meshes whose faces carry both materials (multi-material meshes). `None` when the file said
    /// nothing or the surface has moved or been remeshed since (see [`Cell::interface_labels`]).
    interface_labels: Option<Vec<u32>>,
    /// Its own tensions and adhesions, on top of its cell type's.
    overrides: CellOverrides,
}

impl Cell {
    /// A cell with every face of the default type (apical) and target volume = current volume.
    /// `cell_type` indexes the parameter sets (`[[cell_types]]` in the config).
    pub fn new(id: CellId, kind: CellKind, cell_type: u32, mesh: CellMesh) -> Self {
        let face_types = vec![FaceType::default(); mesh.face_count()];
        let target_volume = mesh.signed_volume();
        Self {
            id,
            kind,
            cell_type,
            mesh,
            face_types,
            target_volume,
            parent: None,
            interface_labels: None,
            overrides: CellOverrides::default(),
        }
    }

    /// Records, per face, the id of the body on the face's other side (0 = the medium), as a
    /// multi-material mesh labels its faces; errors if the count differs from the face count.
    pub fn with_interface_labels(mut self, labels: Vec<u32>) -> Result<Self, TissueError> {
        self.set_interface_labels(labels)?;
        Ok(self)
    }

    /// [`Cell::with_interface_labels`] in place.
    pub fn set_interface_labels(&mut self, labels: Vec<u32>) -> Result<(), TissueError> {
        if labels.len() != self.mesh.face_count() {
            return Err(TissueError::InterfaceLabelCount {
                cell: self.id,
                labels: labels.len(),
                faces: self.mesh.face_count(),
            });
        }
        self.interface_labels = Some(labels);
        Ok(())
    }

    /// Per face, the id of the body on its other side (0 = the medium) as the input file labelled it,
    /// or `None`. The labels describe the surface as read: moving nodes ([`Cell::positions_mut`]) or
    /// remeshing drops them, since contacts then change; re-orienting faces and scaling the whole
    /// tissue (unit conversion) keep them.
    pub fn interface_labels(&self) -> Option<&[u32]> {
        self.interface_labels.as_deref()
    }

    /// Records the mother cell this one was born from by division.
    pub fn with_parent(mut self, parent: CellId) -> Self {
        self.parent = Some(parent);
        self
    }

    /// Gives the cell its own tensions and adhesions on top of its cell type's.
    pub fn with_overrides(mut self, overrides: CellOverrides) -> Self {
        self.overrides = overrides;
        self
    }

    /// The cell's own tensions and adhesions, on top of its cell type's.
    pub fn overrides(&self) -> &CellOverrides {
        &self.overrides
    }

    /// Mutable per-cell tensions and adhesions.
    pub fn overrides_mut(&mut self) -> &mut CellOverrides {
        &mut self.overrides
    }

    /// The mother cell this one was born from by division; `None` for founders.
    pub fn parent(&self) -> Option<CellId> {
        self.parent
    }

    /// Replaces the face types; one per triangle.
    pub fn with_face_types(mut self, face_types: Vec<FaceType>) -> Result<Self, TissueError> {
        if face_types.len() != self.mesh.face_count() {
            return Err(TissueError::FaceTypeCount {
                cell: self.id,
                face_types: face_types.len(),
                faces: self.mesh.face_count(),
            });
        }
        self.face_types = face_types;
        Ok(self)
    }

    /// Changes the target (rest) volume V0 (m³), e.g. by growth.
    pub fn set_target_volume(&mut self, target_volume: Real) {
        self.target_volume = target_volume;
    }

    /// Sets the target (rest) volume V0 (m³).
    pub fn with_target_volume(mut self, target_volume: Real) -> Self {
        self.target_volume = target_volume;
        self
    }

    pub fn id(&self) -> CellId {
        self.id
    }
    pub fn kind(&self) -> CellKind {
        self.kind
    }
    /// Changes what the surface represents (a config's `cell_types[i].kind` overriding a file's).
    pub fn set_kind(&mut self, kind: CellKind) {
        self.kind = kind;
    }
    /// Index of this cell's parameter set.
    pub fn cell_type(&self) -> u32 {
        self.cell_type
    }
    pub fn mesh(&self) -> &CellMesh {
        &self.mesh
    }
    /// Mutable mesh positions; topology changes go through operations that keep face types in step.
    pub fn positions_mut(&mut self) -> &mut [crate::geometry::Vec3] {
        self.interface_labels = None;
        self.mesh.positions_mut()
    }
    /// Scales coordinates component-wise (unit conversion), and the target volume with them.
    pub fn scale(&mut self, factor: crate::geometry::Vec3) {
        self.mesh.scale(factor);
        self.target_volume *= (factor.x * factor.y * factor.z).abs();
    }
    /// Orients the faces consistently and outward (see [`CellMesh::orient_outward`]); face types
    /// stay with their faces. Returns how many faces were flipped.
    pub fn orient_outward(&mut self) -> usize {
        self.mesh.orient_outward()
    }
    /// Runs a local remeshing pass on the surface (see [`super::remesh`]); face types follow their
    /// faces (children inherit, flipped pairs take the larger face's type), and `momenta`, one per
    /// node, are shared on splits and summed on collapses. Errors name the cell.
    pub fn remesh(
        &mut self,
        momenta: Option<&mut Vec<crate::geometry::Vec3>>,
        settings: &super::remesh::RemeshSettings,
    ) -> Result<super::remesh::RemeshReport, super::remesh::RemeshError> {
        self.interface_labels = None;
        super::remesh::remesh_cell(&mut self.mesh, momenta, Some(&mut self.face_types), settings)
            .map_err(|source| super::remesh::RemeshError::Cell { cell: self.id, source: Box::new(source) })
    }
    pub fn face_types(&self) -> &[FaceType] {
        &self.face_types
    }
    /// The mesh and mutable face types, one per triangle (polarisation re-types faces in place).
    pub fn mesh_and_face_types_mut(&mut self) -> (&CellMesh, &mut [FaceType]) {
        (&self.mesh, &mut self.face_types)
    }
    /// Target (rest) volume V0 (m³).
    pub fn target_volume(&self) -> Real {
        self.target_volume
    }
}

/// A set of cells with unique, never-reused ids.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Tissue {
    cells: Vec<Cell>,
    next_id: u32,
}

impl Tissue {
    /// An empty tissue.
    pub fn new() -> Self {
        Self::default()
    }

    /// Builds a tissue, checking that ids are unique.
    pub fn from_cells(cells: Vec<Cell>) -> Result<Self, TissueError> {
        let mut tissue = Self::new();
        for c in cells {
            tissue.push(c)?;
        }
        Ok(tissue)
    }

    /// The same tissue with every cell id (and parent) one higher, for files that number their cells
    /// from 0 (SimuCell3D's convention) where 0 must mean the medium (the interface maps). Faces'
    /// interface labels, which cannot tell such a cell 0 from the medium, are dropped.
    pub fn with_ids_shifted_by_one(&self) -> Result<Self, TissueError> {
        let shift = |id: CellId| CellId(id.0.saturating_add(1));
        let cells = self
            .cells
            .iter()
            .map(|c| Cell { id: shift(c.id), parent: c.parent.map(shift), interface_labels: None, ..c.clone() })
            .collect();
        Self::from_cells(cells)
    }

    /// Adds a cell; errors if its id is taken.
    pub fn push(&mut self, cell: Cell) -> Result<(), TissueError> {
        if self.cells.iter().any(|c| c.id == cell.id) {
            return Err(TissueError::DuplicateCellId(cell.id));
        }
        self.next_id = self.next_id.max(cell.id.0.saturating_add(1));
        self.cells.push(cell);
        Ok(())
    }

    /// Removes and returns the cell at `index` (tissue order; later cells move up by one). Its id is
    /// never handed out again.
    ///
    /// # Panics
    /// If `index` is out of range.
    pub fn remove(&mut self, index: usize) -> Cell {
        self.cells.remove(index)
    }

    /// Puts `cell` in place of the cell at `index` and returns the old one; errors if the new id is
    /// held by another cell.
    ///
    /// # Panics
    /// If `index` is out of range.
    pub fn replace(&mut self, index: usize, cell: Cell) -> Result<Cell, TissueError> {
        if self.cells.iter().enumerate().any(|(i, c)| i != index && c.id == cell.id) {
            return Err(TissueError::DuplicateCellId(cell.id));
        }
        self.next_id = self.next_id.max(cell.id.0.saturating_add(1));
        Ok(std::mem::replace(&mut self.cells[index], cell))
    }

    /// The mean edge length (m), each triangle's three edges counted (every edge of a closed surface
    /// twice, so this is the mean over edges), nuclei left out; `None` without faces. The length
    /// scale of a mesh: measurement's default contact distance and the simulation's mesh-dependent
    /// defaults derive from it.
    pub fn mean_edge_length(&self) -> Option<Real> {
        let (sum, count) = self
            .cells
            .iter()
            .filter(|c| c.kind() != CellKind::Nucleus)
            .flat_map(|c| {
                let p = c.mesh().positions();
                c.mesh().triangles().iter().map(move |t| {
                    let [a, b, d] = t.map(|i| p[i as usize]);
                    (a - b).norm() + (b - d).norm() + (d - a).norm()
                })
            })
            .fold((0.0, 0usize), |(s, n), l| (s + l, n + 3));
        (count > 0).then(|| sum / count as Real)
    }

    /// The id [`Self::allocate_id`] hands out next.
    pub fn next_id(&self) -> CellId {
        CellId(self.next_id)
    }

    /// Raises the next fresh id to at least `next` (restoring a saved tissue whose largest ids died).
    pub fn reserve_ids_below(&mut self, next: CellId) {
        self.next_id = self.next_id.max(next.0);
    }

    /// A fresh id, larger than every id this tissue has ever held.
    pub fn allocate_id(&mut self) -> CellId {
        let id = CellId(self.next_id);
        self.next_id += 1;
        id
    }

    pub fn cells(&self) -> &[Cell] {
        &self.cells
    }
    pub fn cells_mut(&mut self) -> &mut [Cell] {
        &mut self.cells
    }
    /// Scales every cell's coordinates component-wise (unit conversion).
    pub fn scale(&mut self, factor: crate::geometry::Vec3) {
        self.cells.iter_mut().for_each(|c| c.scale(factor));
    }
    /// The cell with this id.
    pub fn cell(&self, id: CellId) -> Option<&Cell> {
        self.cells.iter().find(|c| c.id == id)
    }
    pub fn len(&self) -> usize {
        self.cells.len()
    }
    pub fn is_empty(&self) -> bool {
        self.cells.is_empty()
    }
    /// Total number of nodes over all cells.
    pub fn node_count(&self) -> usize {
        self.cells.iter().map(|c| c.mesh.node_count()).sum()
    }
    /// Total number of triangles over all cells.
    pub fn face_count(&self) -> usize {
        self.cells.iter().map(|c| c.mesh.face_count()).sum()
    }
}

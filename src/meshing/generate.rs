//! Synthetic tissues (paper Fig. 1f and Fig. 3a): a single cell, a vesicle, a sheet, a tube or a
//! spheroid, meshed at a requested l_min and ready to simulate.
//!
//! **Construction (voxel route).** The intended cells are written into a label volume of voxel edge
//! l_min / [`VOXELS_PER_L_MIN`] (a voxel is labelled when its centre lies in the cell), and the volume
//! goes through the same mesher as segmented images ([`mesh_cells_and_nuclei`]): every cell, the lumen
//! become closed, outward, genus-0 surfaces with edges in [l_min, 3·l_min]. Neighbouring
//! cells come from the same voxel partition, so their surfaces follow the same interface: they start in
//! contact, crossing each other by less than a voxel (checked, [`Penetration`]). The geometric route
//! (clipping convex Voronoi cells) was not taken: the apical and basal faces of a shell's cells are
//! curved, so they are not convex, and remeshing sharp polyhedra flips edges across their creases.
//!
//! **Sizes.** `cell_size` l is the cube root of the mean cell volume (the paper's length scale
//! l = ⟨V(t=0)⟩^(1/3)); columnar cells (vesicle, sheet, tube) have height = `aspect` × width, width w
//! being the side of the square of the same area as the cell's mid-surface patch.
//! - `sphere`: one ball of volume l³. `cube`: one cube of edge l. Both are analytic surfaces
//!   ([`sphere_for_min_edge`], [`subdivided_cube`]), not voxelised.
//! - `vesicle`: N columnar cells between the spheres R_in < r < R_out, the spherical Voronoi cells of N
//!   seeds on the unit sphere (a Fibonacci lattice, turned by a seeded random rotation, jittered and
//!   relaxed by a few steps of short-range repulsion); a lumen (kind lumen) fills r < R_in; an ECM (kind
//!   ECM) encases the tissue. Mid-sphere area per cell = w², R_out − R_in = aspect·w. With `ecm_room`
//!   F > 1 the ECM sphere leaves room for the cells to grow to F times their volume.
//! - `sheet`: a flat columnar patch: the N points of a hexagonal lattice nearest to the centre, jittered,
//!   their planar Voronoi cells extruded over −h/2 < z < h/2 and cut at 0.75 lattice spacings from the
//!   seeds (the patch border). With `static_border`, the outer ring (lattice points with fewer than 6
//!   lattice neighbours in the patch) is of kind static (the paper's Application 2 patch).
//! - `tube`: N columnar cells between the cylinders R_in < ρ < R_out, |z| < L/2 with L = 4·R_mid (two
//!   mid diameters), the Voronoi cells of a Fibonacci lattice on the mid cylinder (periodic around
//!   it: distances are chords between points projected onto the mid cylinder); optionally a lumen
//!   filling ρ < R_in, |z| < L/2. The tube's ends are open (cells face the medium there).
//! - `spheroid`: a ball of volume N·l³ cut into the Voronoi cells of N seeded random points kept apart
//!   by at least 0.8 mean spacings (as `generate labels --kind aggregate`), then relaxed by short-range
//!   repulsion and kept half a spacing inside the surface.
//!
//! **The ECM.** Our contact model treats an ECM body as an *enclosing* closed surface: for nodes of
//! other cells the sign of the distance to it is flipped, so cells inside it adhere to it from inside
//! and are repelled when pushed out (see [`crate::mechanics`] contacts), and the layer count takes
//! ECM-touching cells as the exterior side. The reference program also reads the ECM as one closed
//! polyhedron (its test `cell_in_ecm_geometry.vtk`: an epithelial cell inside an ECM sphere) and never
//! moves it. A shell (two surfaces) would not be a genus-0 cell, so the ECM here is one sphere of
//! radius R_out + l_min/4 around the vesicle ([`ECM_GAP_PER_L_MIN`]): the cells' basal faces start
//! within the contact cutoff of its inner side, without crossing it. Because it never moves, a
//! growing vesicle needs room inside it (`ecm_room`): otherwise the cells can only grow by crushing
//! the lumen.
//!
//! **Nuclei**: a sphere ([`sphere_for_min_edge`]) around each epithelial cell's volume centroid, of
//! radius `nucleus_radius` × the cell's equivalent-sphere radius, capped so that it stays
//! [`NUCLEUS_CLEARANCE_PER_L_MIN`]·l_min clear of the cell's meshed surface (an error when that leaves
//! less than l_min); every nucleus node must lie inside its host's surface (checked; an error
//! otherwise). Nucleus cell id = host id + the largest id. Spheres rather than voxelised balls: a
//! nucleus is a few l_min across, too small for the voxel mesher's clearance and sampling.
//!
//! **Kinds and types.** Each body's `cell_type` is its kind's code (0 epithelial, 1 ECM, 2 lumen, 3
//! nucleus, 4 static), the index of that kind's entry in the default parameter list. Cell ids: cells
//! 1..=N, the lumen N+1, nuclei host id + the largest of those, the ECM the next free id.
//!
//! Deterministic: the seeds come from ChaCha8 seeded with `seed`, the volume is filled voxel by voxel,
//! and the mesher is thread-count independent, so the same spec gives the same tissue on 1 or N threads.

use super::{
    LabelMeshingError, LabelMeshingOptions, LabelReport, LabelStatus, MIN_VOXELS, VOXELS_PER_L_MIN,
    mesh_cells_and_nuclei,
};
use crate::geometry::{Real, SpatialGrid, Vec3, closest_point_on_triangle};
use crate::imaging::{ImagingError, LabelVolume, VoxelGrid};
use crate::mesh::remesh::{RemeshError, RemeshSettings, remesh_cell};
use crate::mesh::shapes::{sphere_for_min_edge, subdivided_cube};
use crate::mesh::{Cell, CellId, CellKind, MeshDefect, Tissue, TissueError};
use ndarray::{Axis, Zip};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::f64::consts::PI;
use std::fmt;
use std::str::FromStr;

/// Least distance between a nucleus and its host's surface, in units of l_min.
pub const NUCLEUS_CLEARANCE_PER_L_MIN: Real = 0.5;

/// Gap between the vesicle's outer radius and its ECM sphere, in units of l_min.
pub const ECM_GAP_PER_L_MIN: Real = 0.25;

/// Most cells a generated tissue may have.
pub const MAX_GENERATED_CELLS: usize = 100_000;

/// Most voxels of the intermediate label volume (memory guard: 4 bytes each).
pub const MAX_GENERATED_VOXELS: usize = 400_000_000;

/// Which tissue to generate.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TissueKind {
    Sphere,
    Cube,
    Vesicle,
    Sheet,
    Tube,
    Spheroid,
}

impl TissueKind {
    pub const ALL: [TissueKind; 6] = [
        TissueKind::Sphere,
        TissueKind::Cube,
        TissueKind::Vesicle,
        TissueKind::Sheet,
        TissueKind::Tube,
        TissueKind::Spheroid,
    ];

    pub fn name(self) -> &'static str {
        match self {
            TissueKind::Sphere => "sphere",
            TissueKind::Cube => "cube",
            TissueKind::Vesicle => "vesicle",
            TissueKind::Sheet => "sheet",
            TissueKind::Tube => "tube",
            TissueKind::Spheroid => "spheroid",
        }
    }

    /// The cell count when none is given: 1 for sphere and cube, 100 for a vesicle, 37 for a sheet, 60
    /// for a tube, 30 for a spheroid.
    pub fn default_cells(self) -> usize {
        match self {
            TissueKind::Sphere | TissueKind::Cube => 1,
            TissueKind::Vesicle => 100,
            TissueKind::Sheet => 37,
            TissueKind::Tube => 60,
            TissueKind::Spheroid => 30,
        }
    }

    /// Whether the kind is a single cell (no `cells` count).
    pub fn is_single_cell(self) -> bool {
        matches!(self, TissueKind::Sphere | TissueKind::Cube)
    }
}

impl fmt::Display for TissueKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for TissueKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| format!("unknown tissue kind `{s}`; one of {}", Self::ALL.map(|k| k.name()).join(", ")))
    }
}

/// What to generate. Lengths in metres.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct TissueSpec {
    pub kind: TissueKind,
    /// Number of cells (1 for sphere and cube).
    pub cells: usize,
    /// l: cube root of the mean cell volume (m).
    pub cell_size: Real,
    /// Minimum edge length l_min (m) of every surface.
    pub l_min: Real,
    /// Height / width of columnar cells (vesicle, sheet, tube); ignored by the other kinds.
    pub aspect: Real,
    /// Seed of the cell centres and of the surface sampling.
    pub seed: u64,
    /// With `Some(f)`: a nucleus in every epithelial cell, radius f × the cell's equivalent-sphere radius.
    pub nucleus_radius: Option<Real>,
    /// With nuclei: each nucleus is an ellipsoid elongated by this factor (≥ 1) along its cell's longest
    /// principal axis; 1 = a sphere.
    pub nucleus_aspect: Real,
    /// Sheet only: the outer ring of cells is static.
    pub static_border: bool,
    /// Tube only: a lumen inside the tube.
    pub lumen: bool,
    /// Vesicle only: room inside the ECM, as a multiple F ≥ 1 of the cells' shell volume: the ECM sphere
    /// has radius (R_in³ + F·(R_out³ − R_in³))^(1/3) + l_min/4. 1 (default): the ECM touches the cells;
    /// 2: the cells can double their volume by growing outward (the paper's Application 1; the ECM
    /// never moves).
    pub ecm_room: Real,
}

/// Errors generating a tissue.
#[derive(Debug, thiserror::Error)]
pub enum GenerateError {
    #[error("invalid tissue specification: {0}")]
    InvalidSpec(String),
    #[error(transparent)]
    Imaging(#[from] ImagingError),
    #[error(transparent)]
    Meshing(#[from] LabelMeshingError),
    #[error(transparent)]
    Remesh(#[from] RemeshError),
    #[error(transparent)]
    Tissue(#[from] TissueError),
    #[error("{what} {label} could not be meshed: {reason}; try a smaller --min-edge-length")]
    Dropped { what: &'static str, label: u32, reason: String },
    #[error("cell {cell} ({kind}) is not a valid closed surface: {defect}")]
    InvalidCell { cell: CellId, kind: CellKind, defect: MeshDefect },
    #[error(
        "cell {cell} has room for a nucleus of radius {radius:e} m only, less than l_min = {l_min:e} m; use a smaller \
         --min-edge-length"
    )]
    NucleusTooSmall { cell: CellId, radius: Real, l_min: Real },
    #[error(
        "nucleus {nucleus}: {outside} of its nodes lie outside its host cell {host}; try a smaller --nucleus-radius"
    )]
    NucleusOutside { nucleus: CellId, host: CellId, outside: usize },
    #[error(
        "cell {cell}: a nucleus elongated {aspect}× comes within {clearance:e} m of the cell's surface (less than \
         half of l_min = {l_min:e} m); use a smaller --nucleus-aspect or --nucleus-radius"
    )]
    NucleusTooLong { cell: CellId, aspect: Real, clearance: Real, l_min: Real },
}

/// Largest depth of a node inside another body (see [`max_penetration`]).
#[derive(Copy, Clone, Debug, PartialEq, serde::Serialize)]
pub struct Penetration {
    /// Depth (m) of the deepest node: −(signed distance) to the other body's surface, > 0 inside it.
    pub depth: Real,
    /// Cell id of the node's body.
    pub cell: u32,
    /// Cell id of the body it lies in.
    pub other: u32,
}

/// Geometry of the generated tissue (m); radii are `None` where the kind has none.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct TissueGeometry {
    /// Width w of a columnar cell (m).
    pub cell_width: Option<Real>,
    /// Height of a columnar cell (m).
    pub cell_height: Option<Real>,
    pub inner_radius: Option<Real>,
    pub outer_radius: Option<Real>,
    /// Vesicle: radius of the ECM sphere.
    pub ecm_radius: Option<Real>,
    /// Tube: length; sheet: lattice spacing.
    pub length: Option<Real>,
    /// Voxel edge of the intermediate label volume (m); `None` for analytic single cells.
    pub voxel_size: Option<Real>,
    /// Shape of the label volume (z, y, x).
    pub volume_shape: Option<[usize; 3]>,
}

/// A generated tissue and how it was made.
#[derive(Clone, Debug)]
pub struct GeneratedTissue {
    pub tissue: Tissue,
    pub spec: TissueSpec,
    pub geometry: TissueGeometry,
    /// The mesher's report per label (cells and lumen), empty for analytic single cells.
    pub labels: Vec<LabelReport>,
    /// Deepest node inside another body (within 3·l_min of its surface), `None` when no node is inside one.
    pub penetration: Option<Penetration>,
    /// For each nucleus id, its host cell id.
    pub hosts: Vec<(CellId, CellId)>,
}

/// Per-kind figures of a [`GenerationSummary`].
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct KindCount {
    pub bodies: usize,
    pub nodes: usize,
    pub faces: usize,
    /// m³.
    pub volume: Real,
    /// m³ (smallest, mean, largest body volume).
    pub min_volume: Real,
    pub mean_volume: Real,
    pub max_volume: Real,
}

/// One body of a [`GenerationSummary`].
#[derive(Clone, Debug, serde::Serialize)]
pub struct BodyRow {
    pub id: u32,
    pub kind: CellKind,
    pub nodes: usize,
    pub faces: usize,
    /// m³.
    pub volume: Real,
    pub sphericity: Real,
    /// The host cell of a nucleus.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub host: Option<u32>,
}

/// What a generated tissue holds: the report of `tissuefit generate mesh` (without its file names and
/// timing) and of a pipeline's generated input (`mesh/report.json`).
#[derive(Clone, Debug, serde::Serialize)]
pub struct GenerationSummary {
    pub spec: TissueSpec,
    pub geometry: TissueGeometry,
    pub cells: usize,
    pub nodes: usize,
    pub faces: usize,
    /// Kind name → counts and volumes.
    pub kinds: std::collections::BTreeMap<&'static str, KindCount>,
    /// Mean volume of the epithelial and static cells (m³) and l = its cube root (m), the paper's length
    /// scale.
    pub mean_cell_volume: Real,
    pub length_scale: Real,
    /// Deepest node inside another body (m), 0 when none; with the two cell ids.
    pub max_penetration: Real,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub penetration: Option<Penetration>,
    /// One row per body.
    pub bodies: Vec<BodyRow>,
}

impl GeneratedTissue {
    /// Counts, volumes and the length scale of the generated tissue.
    pub fn summary(&self) -> GenerationSummary {
        let tissue = &self.tissue;
        let mut kinds: std::collections::BTreeMap<&'static str, KindCount> = std::collections::BTreeMap::new();
        let mut bodies = Vec::with_capacity(tissue.len());
        for c in tissue.cells() {
            let (volume, area) = (c.mesh().signed_volume(), c.mesh().area());
            let k = kinds.entry(c.kind().name()).or_default();
            if k.bodies == 0 {
                (k.min_volume, k.max_volume) = (volume, volume);
            }
            k.bodies += 1;
            k.nodes += c.mesh().node_count();
            k.faces += c.mesh().face_count();
            k.volume += volume;
            k.min_volume = k.min_volume.min(volume);
            k.max_volume = k.max_volume.max(volume);
            bodies.push(BodyRow {
                id: c.id().0,
                kind: c.kind(),
                nodes: c.mesh().node_count(),
                faces: c.mesh().face_count(),
                volume,
                sphericity: crate::mesh::sphericity(volume, area),
                host: self.hosts.iter().find(|(n, _)| *n == c.id()).map(|(_, h)| h.0),
            });
        }
        for k in kinds.values_mut() {
            k.mean_volume = k.volume / k.bodies as Real;
        }
        let cell_volumes: Vec<Real> =
            tissue.cells().iter().filter(|c| c.kind().is_cell()).map(|c| c.mesh().signed_volume()).collect();
        let mean_cell_volume = cell_volumes.iter().sum::<Real>() / cell_volumes.len().max(1) as Real;
        GenerationSummary {
            spec: self.spec.clone(),
            geometry: self.geometry.clone(),
            cells: tissue.len(),
            nodes: tissue.node_count(),
            faces: tissue.face_count(),
            kinds,
            mean_cell_volume,
            length_scale: mean_cell_volume.cbrt(),
            max_penetration: self.penetration.map_or(0.0, |p| p.depth),
            penetration: self.penetration,
            bodies,
        }
    }
}

impl TissueSpec {
    /// Checks the specification before anything is generated (what `generate_tissue` checks first).
    pub fn validate(&self) -> Result<(), GenerateError> {
        let bad = |m: String| Err(GenerateError::InvalidSpec(m));
        if !(self.l_min.is_finite() && self.l_min > 0.0) {
            return bad(format!("the minimum edge length {} m must be positive", self.l_min));
        }
        if !(self.cell_size.is_finite() && self.cell_size > 0.0) {
            return bad(format!("the cell size {} m must be positive", self.cell_size));
        }
        if self.cell_size < 4.0 * self.l_min {
            return bad(format!(
                "the cell size {:.4} µm is less than 4 × the minimum edge length {:.4} µm: a cell would have too \
                 few nodes; use a smaller --min-edge-length or a larger --cell-size",
                self.cell_size * 1e6,
                self.l_min * 1e6
            ));
        }
        if self.cell_size > 2000.0 * self.l_min {
            return bad(format!(
                "the cell size is {:.0} × the minimum edge length (at most 2000): cells would have millions of nodes",
                self.cell_size / self.l_min
            ));
        }
        if !(self.aspect.is_finite() && (0.2..=10.0).contains(&self.aspect)) {
            return bad(format!("the aspect ratio {} must lie in [0.2, 10]", self.aspect));
        }
        if self.kind.is_single_cell() && self.cells != 1 {
            return bad(format!("a {} is a single cell; --cells {} does not apply", self.kind, self.cells));
        }
        if !self.kind.is_single_cell() && !(2..=MAX_GENERATED_CELLS).contains(&self.cells) {
            return bad(format!("a {} needs 2 to {MAX_GENERATED_CELLS} cells, not {}", self.kind, self.cells));
        }
        if let Some(f) = self.nucleus_radius
            && !(f > 0.0 && f < 1.0)
        {
            return bad(format!("the nucleus radius fraction {f} must lie in (0, 1)"));
        }
        if !(self.nucleus_aspect.is_finite() && (1.0..=10.0).contains(&self.nucleus_aspect)) {
            return bad(format!("the nucleus aspect {} must lie in [1, 10]", self.nucleus_aspect));
        }
        if self.static_border && self.kind != TissueKind::Sheet {
            return bad("a static border applies to a sheet only".into());
        }
        if !(self.ecm_room.is_finite() && (1.0..=100.0).contains(&self.ecm_room)) {
            return bad(format!("the ECM room factor {} must lie in [1, 100]", self.ecm_room));
        }
        if self.ecm_room != 1.0 && self.kind != TissueKind::Vesicle {
            return bad("the ECM room applies to a vesicle only".into());
        }
        if self.lumen && self.kind != TissueKind::Tube {
            return bad(format!(
                "a lumen option applies to a tube only (a vesicle always has one, a {} has none)",
                self.kind
            ));
        }
        Ok(())
    }
}

/// Generates the tissue described by `spec`; see the module documentation.
pub fn generate_tissue(spec: &TissueSpec) -> Result<GeneratedTissue, GenerateError> {
    spec.validate()?;
    if spec.kind.is_single_cell() {
        return single_cell(spec);
    }
    let layout = Layout::new(spec)?;
    let voxel = spec.l_min / VOXELS_PER_L_MIN;
    let (lo, hi) = layout.bounds();
    let grid = VoxelGrid::covering(lo, hi, [voxel; 3], 3)?;
    let voxels: usize = grid.shape.iter().product();
    if voxels > MAX_GENERATED_VOXELS {
        return Err(GenerateError::InvalidSpec(format!(
            "the label volume would have {voxels} voxels (at most {MAX_GENERATED_VOXELS}); use a larger \
             --min-edge-length or fewer cells"
        )));
    }
    let mut volume = LabelVolume::zeros(&grid)?;
    volume.labels_mut().axis_iter_mut(Axis(0)).into_par_iter().enumerate().for_each(|(k, mut slice)| {
        Zip::indexed(&mut slice)
            .for_each(|(j, i), v| *v = layout.label_at(&grid.voxel_centre([k as isize, j as isize, i as isize])));
    });
    let n = spec.cells as u32;
    let options = LabelMeshingOptions {
        l_min: Some(spec.l_min),
        min_voxels: MIN_VOXELS as u64,
        lumen_labels: layout.lumen.then_some(n + 1).into_iter().collect(),
        seed: spec.seed,
        ..Default::default()
    };
    let meshing = mesh_cells_and_nuclei(&volume, None, &options, &|_| true)?;
    let expected_labels = n as usize + usize::from(layout.lumen);
    if let Some(r) = meshing.report.iter().find(|r| r.status == LabelStatus::Dropped) {
        let what = if r.label > n { "the lumen" } else { "cell" };
        return Err(GenerateError::Dropped { what, label: r.label, reason: r.reason.clone().unwrap_or_default() });
    }
    if meshing.report.len() != expected_labels {
        return Err(GenerateError::InvalidSpec(format!(
            "{} of {expected_labels} bodies got voxels; use a smaller --min-edge-length",
            meshing.report.len()
        )));
    }
    let mut cells = Vec::with_capacity(2 * meshing.tissue.len() + 1);
    for c in meshing.tissue.cells() {
        let kind = match c.kind() {
            CellKind::Epithelial if layout.static_labels.contains(&c.id().0) => CellKind::Static,
            k => k,
        };
        cells.push(Cell::new(c.id(), kind, kind.code(), c.mesh().clone()));
    }
    let hosts = match spec.nucleus_radius {
        Some(f) => add_nuclei(&mut cells, f, spec.nucleus_aspect, spec.l_min)?,
        None => Vec::new(),
    };
    let mut geometry = layout.geometry.clone();
    geometry.voxel_size = Some(voxel);
    geometry.volume_shape = Some(grid.shape);
    if let Some(radius) = layout.ecm_radius {
        let mut mesh = sphere_for_min_edge(radius, spec.l_min)?;
        mesh.positions_mut().iter_mut().for_each(|p| *p += layout.centre);
        let id = cells.iter().map(|c| c.id().0).max().unwrap_or(0) + 1;
        cells.push(Cell::new(CellId(id), CellKind::Ecm, CellKind::Ecm.code(), mesh));
        geometry.ecm_radius = Some(radius);
    }
    finish(spec, Tissue::from_cells(cells)?, geometry, meshing.report, hosts)
}

/// Puts a nucleus in every epithelial cell of `cells` (appended after them): a sphere
/// ([`sphere_for_min_edge`]) around the cell's volume centroid of radius `fraction` × the cell's
/// equivalent-sphere radius, but at most the distance from the centroid to the cell's surface less
/// [`NUCLEUS_CLEARANCE_PER_L_MIN`]·l_min. With `aspect` > 1 the sphere is stretched by that factor along
/// the cell's longest principal axis (then remeshed to l_min) and must still stay that clear of the
/// cell's surface. Nucleus id = its host's id + the largest id. Returns (nucleus, host) pairs.
fn add_nuclei(
    cells: &mut Vec<Cell>,
    fraction: Real,
    aspect: Real,
    l_min: Real,
) -> Result<Vec<(CellId, CellId)>, GenerateError> {
    let offset = cells.iter().map(|c| c.id().0).max().unwrap_or(0);
    let made: Vec<Result<Option<Cell>, GenerateError>> = cells
        .par_iter()
        .map(|host| {
            if host.kind() != CellKind::Epithelial {
                return Ok(None);
            }
            let mesh = host.mesh();
            let volume = mesh.signed_volume();
            let centre = mesh.volume_centroid().unwrap_or_else(Vec3::zeros);
            let p = mesh.positions();
            let room = mesh
                .triangles()
                .iter()
                .map(|t| {
                    closest_point_on_triangle(&centre, &p[t[0] as usize], &p[t[1] as usize], &p[t[2] as usize]).distance
                })
                .fold(Real::INFINITY, Real::min);
            let r_eq = (3.0 * volume / (4.0 * PI)).cbrt();
            let r = (fraction * r_eq).min(room - NUCLEUS_CLEARANCE_PER_L_MIN * l_min);
            if r.is_nan() || r < l_min {
                return Err(GenerateError::NucleusTooSmall { cell: host.id(), radius: r.max(0.0), l_min });
            }
            let mut nucleus = sphere_for_min_edge(r, l_min)?;
            if aspect != 1.0 {
                let axis = mesh.principal_axes().map_or(Vec3::z(), |a| a.axes[0]);
                nucleus.positions_mut().iter_mut().for_each(|q| *q += (aspect - 1.0) * q.dot(&axis) * axis);
                remesh_cell(&mut nucleus, None, None, &RemeshSettings::new(l_min))?;
                let clearance = nucleus
                    .positions()
                    .iter()
                    .map(|q| {
                        let q = q + centre;
                        mesh.triangles()
                            .iter()
                            .map(|t| {
                                closest_point_on_triangle(&q, &p[t[0] as usize], &p[t[1] as usize], &p[t[2] as usize])
                                    .distance
                            })
                            .fold(Real::INFINITY, Real::min)
                    })
                    .fold(Real::INFINITY, Real::min);
                // (The in-plane radius may sit exactly at the clearance: a little rounding is allowed.)
                if clearance < (1.0 - 1e-6) * NUCLEUS_CLEARANCE_PER_L_MIN * l_min {
                    return Err(GenerateError::NucleusTooLong { cell: host.id(), aspect, clearance, l_min });
                }
            }
            nucleus.positions_mut().iter_mut().for_each(|q| *q += centre);
            let id = CellId(offset + host.id().0);
            Ok(Some(Cell::new(id, CellKind::Nucleus, CellKind::Nucleus.code(), nucleus)))
        })
        .collect();
    let mut hosts = Vec::new();
    let mut nuclei = Vec::new();
    for (host, made) in cells.iter().zip(made) {
        if let Some(nucleus) = made? {
            hosts.push((nucleus.id(), host.id()));
            nuclei.push(nucleus);
        }
    }
    cells.extend(nuclei);
    Ok(hosts)
}

/// Validates every body, checks nuclei against their hosts and measures penetration.
fn finish(
    spec: &TissueSpec,
    tissue: Tissue,
    geometry: TissueGeometry,
    labels: Vec<LabelReport>,
    hosts: Vec<(CellId, CellId)>,
) -> Result<GeneratedTissue, GenerateError> {
    for c in tissue.cells() {
        c.mesh().validate().map_err(|defect| GenerateError::InvalidCell { cell: c.id(), kind: c.kind(), defect })?;
    }
    for &(nucleus, host) in &hosts {
        let (Some(nc), Some(hc)) = (tissue.cell(nucleus), tissue.cell(host)) else { continue };
        let outside = nc.mesh().positions().iter().filter(|p| hc.mesh().winding_number(p) <= 0.5).count();
        if outside > 0 {
            return Err(GenerateError::NucleusOutside { nucleus, host, outside });
        }
    }
    let penetration = max_penetration(&tissue, &hosts, 3.0 * spec.l_min);
    Ok(GeneratedTissue { tissue, spec: spec.clone(), geometry, labels, penetration, hosts })
}

fn single_cell(spec: &TissueSpec) -> Result<GeneratedTissue, GenerateError> {
    let l = spec.cell_size;
    let mut geometry = TissueGeometry::default();
    let mesh = match spec.kind {
        TissueKind::Sphere => {
            let r = (3.0 / (4.0 * PI)).cbrt() * l;
            geometry.outer_radius = Some(r);
            sphere_for_min_edge(r, spec.l_min)?
        }
        _ => {
            // Squares of side ≤ 2·l_min: diagonals ≤ 2.83·l_min < l_max, sides ≥ l_min (l ≥ 4·l_min).
            let n = (l / (2.0 * spec.l_min)).ceil().max(1.0) as u32;
            let mut mesh = subdivided_cube(l, n, Vec3::zeros());
            remesh_cell(&mut mesh, None, None, &RemeshSettings::new(spec.l_min))?;
            geometry.length = Some(l);
            mesh
        }
    };
    let mut cells = vec![Cell::new(CellId(1), CellKind::Epithelial, CellKind::Epithelial.code(), mesh)];
    let hosts = match spec.nucleus_radius {
        Some(f) => add_nuclei(&mut cells, f, spec.nucleus_aspect, spec.l_min)?,
        None => Vec::new(),
    };
    finish(spec, Tissue::from_cells(cells)?, geometry, Vec::new(), hosts)
}

/// How seeds are compared with a point.
#[derive(Clone, Debug)]
enum Partition {
    /// Nearest seed direction (seeds are unit vectors; p is projected onto the unit sphere).
    Sphere,
    /// Nearest seed on the mid cylinder of radius `r` (p is projected onto it; z kept).
    Cylinder { r: Real },
    /// Nearest seed in the plane z = 0 (p projected), within `reach` of it.
    Plane { reach: Real },
    /// Nearest seed in space.
    Space,
}

/// The intended cells, lumen and ECM of a multi-cell tissue.
struct Layout {
    centre: Vec3,
    seeds: NearestSeed,
    partition: Partition,
    /// Region test: 0 outside, 1 epithelium, 2 lumen.
    region: Region,
    lumen: bool,
    n: u32,
    static_labels: Vec<u32>,
    ecm_radius: Option<Real>,
    geometry: TissueGeometry,
    half_extent: Vec3,
}

#[derive(Clone, Copy, Debug)]
enum Region {
    Shell { r_in: Real, r_out: Real },
    Tube { r_in: Real, r_out: Real, half_length: Real, lumen: bool },
    Slab { half_height: Real },
    Ball { r: Real },
}

impl Layout {
    fn new(spec: &TissueSpec) -> Result<Self, GenerateError> {
        let n = spec.cells;
        let l = spec.cell_size;
        let mut rng = ChaCha8Rng::seed_from_u64(spec.seed);
        let mut geometry = TissueGeometry::default();
        let centre = Vec3::zeros();
        let too_few = |min_ratio: Real| {
            GenerateError::InvalidSpec(format!(
                "{n} cells of aspect ratio {} leave no room for a lumen (inner radius below {min_ratio} × the mid \
                 radius); use more cells or a smaller --aspect",
                spec.aspect
            ))
        };
        match spec.kind {
            TissueKind::Vesicle => {
                // Unit width first: mid-sphere area per cell 1, height = aspect.
                let r_mid = (n as Real / (4.0 * PI)).sqrt();
                let (r_in, r_out) = (r_mid - 0.5 * spec.aspect, r_mid + 0.5 * spec.aspect);
                if r_in < 0.25 * r_mid {
                    return Err(too_few(0.25));
                }
                let per_cell = 4.0 / 3.0 * PI * (r_out.powi(3) - r_in.powi(3)) / n as Real;
                let s = l / per_cell.cbrt();
                let (r_in, r_out) = (s * r_in, s * r_out);
                let room = (r_in.powi(3) + spec.ecm_room * (r_out.powi(3) - r_in.powi(3))).cbrt();
                let ecm = room + ECM_GAP_PER_L_MIN * spec.l_min;
                geometry.cell_width = Some(s);
                geometry.cell_height = Some(s * spec.aspect);
                geometry.inner_radius = Some(r_in);
                geometry.outer_radius = Some(r_out);
                let seeds = sphere_seeds(n, &mut rng);
                Ok(Self {
                    centre,
                    seeds: NearestSeed::new(seeds),
                    partition: Partition::Sphere,
                    region: Region::Shell { r_in, r_out },
                    lumen: true,
                    n: n as u32,
                    static_labels: Vec::new(),
                    ecm_radius: Some(ecm),
                    geometry,
                    half_extent: Vec3::repeat(r_out),
                })
            }
            TissueKind::Tube => {
                // Mid-cylinder area 2π·r_mid·L = n with L = 4·r_mid (unit width).
                let r_mid = (n as Real / (8.0 * PI)).sqrt();
                let (r_in, r_out) = (r_mid - 0.5 * spec.aspect, r_mid + 0.5 * spec.aspect);
                if r_in < 0.25 * r_mid {
                    return Err(too_few(0.25));
                }
                let length = 4.0 * r_mid;
                let per_cell = PI * (r_out * r_out - r_in * r_in) * length / n as Real;
                let s = l / per_cell.cbrt();
                let (r_mid, r_in, r_out, length) = (s * r_mid, s * r_in, s * r_out, s * length);
                geometry.cell_width = Some(s);
                geometry.cell_height = Some(s * spec.aspect);
                geometry.inner_radius = Some(r_in);
                geometry.outer_radius = Some(r_out);
                geometry.length = Some(length);
                // Fibonacci lattice on the mid cylinder, turned and jittered.
                let golden = 0.5 * (5f64.sqrt() - 1.0);
                let turn = rng.random::<Real>() * 2.0 * PI;
                let jitter = 0.1 * s;
                let seeds = (0..n)
                    .map(|i| {
                        let z = length * ((i as Real + 0.5) / n as Real - 0.5) + jitter * (rng.random::<Real>() - 0.5);
                        let theta = 2.0 * PI * (i as Real * golden).fract()
                            + turn
                            + jitter / r_mid * (rng.random::<Real>() - 0.5);
                        Vec3::new(r_mid * theta.cos(), r_mid * theta.sin(), z)
                    })
                    .collect();
                Ok(Self {
                    centre,
                    seeds: NearestSeed::new(seeds),
                    partition: Partition::Cylinder { r: r_mid },
                    region: Region::Tube { r_in, r_out, half_length: 0.5 * length, lumen: spec.lumen },
                    lumen: spec.lumen,
                    n: n as u32,
                    static_labels: Vec::new(),
                    ecm_radius: None,
                    geometry,
                    half_extent: Vec3::new(r_out, r_out, 0.5 * length),
                })
            }
            TissueKind::Sheet => {
                // Hexagon of area w² (lattice spacing a), prism height aspect·w, volume l³.
                let w = l / spec.aspect.cbrt();
                let a = w * (2.0 / 3f64.sqrt()).sqrt();
                let h = spec.aspect * w;
                geometry.cell_width = Some(w);
                geometry.cell_height = Some(h);
                geometry.length = Some(a);
                let points = hexagonal_patch(n);
                let set: std::collections::HashSet<(i64, i64)> = points.iter().copied().collect();
                let neighbours = [(1, 0), (-1, 0), (0, 1), (0, -1), (1, -1), (-1, 1)];
                let static_labels = if spec.static_border {
                    (0..n)
                        .filter(|&k| {
                            let (i, j) = points[k];
                            neighbours.iter().any(|(di, dj)| !set.contains(&(i + di, j + dj)))
                        })
                        .map(|k| k as u32 + 1)
                        .collect()
                } else {
                    Vec::new()
                };
                if spec.static_border && static_labels.len() == n {
                    return Err(GenerateError::InvalidSpec(format!(
                        "with {n} cells every cell of the sheet is on its border; use at least 7 cells with --static-border"
                    )));
                }
                let jitter = 0.1 * a;
                let seeds: Vec<Vec3> = points
                    .iter()
                    .map(|&(i, j)| {
                        let (x, y) = (a * (i as Real + 0.5 * j as Real), a * (0.5 * 3f64.sqrt() * j as Real));
                        Vec3::new(
                            x + jitter * (rng.random::<Real>() - 0.5),
                            y + jitter * (rng.random::<Real>() - 0.5),
                            0.0,
                        )
                    })
                    .collect();
                let reach = 0.75 * a;
                let radius = seeds.iter().map(|s| s.norm()).fold(0.0, Real::max) + reach;
                Ok(Self {
                    centre,
                    seeds: NearestSeed::new(seeds),
                    partition: Partition::Plane { reach },
                    region: Region::Slab { half_height: 0.5 * h },
                    lumen: false,
                    n: n as u32,
                    static_labels,
                    ecm_radius: None,
                    geometry,
                    half_extent: Vec3::new(radius, radius, 0.5 * h),
                })
            }
            TissueKind::Spheroid => {
                let r = (3.0 * n as Real / (4.0 * PI)).cbrt() * l;
                geometry.outer_radius = Some(r);
                let seeds = ball_seeds(n, r, &mut rng);
                Ok(Self {
                    centre,
                    seeds: NearestSeed::new(seeds),
                    partition: Partition::Space,
                    region: Region::Ball { r },
                    lumen: false,
                    n: n as u32,
                    static_labels: Vec::new(),
                    ecm_radius: None,
                    geometry,
                    half_extent: Vec3::repeat(r),
                })
            }
            TissueKind::Sphere | TissueKind::Cube => unreachable!("single cells are not laid out"),
        }
    }

    fn bounds(&self) -> (Vec3, Vec3) {
        (self.centre - self.half_extent, self.centre + self.half_extent)
    }

    /// The label of the point `p`: 0 background, 1..=n cells, n+1 the lumen.
    fn label_at(&self, p: &Vec3) -> u32 {
        let q = p - self.centre;
        let lumen = self.n + 1;
        match self.region {
            Region::Shell { r_in, r_out } => {
                let r = q.norm();
                if r > r_out {
                    return 0;
                }
                if r < r_in {
                    return lumen;
                }
            }
            Region::Tube { r_in, r_out, half_length, lumen: has_lumen } => {
                let rho = q.xy().norm();
                if q.z.abs() > half_length || rho > r_out {
                    return 0;
                }
                if rho < r_in {
                    return if has_lumen { lumen } else { 0 };
                }
            }
            Region::Slab { half_height } => {
                if q.z.abs() > half_height {
                    return 0;
                }
            }
            Region::Ball { r } => {
                if q.norm() > r {
                    return 0;
                }
            }
        }
        let (probe, reach) = match self.partition {
            Partition::Sphere => match q.try_normalize(0.0) {
                Some(u) => (u, None),
                None => return 0,
            },
            Partition::Cylinder { r } => match q.xy().try_normalize(0.0) {
                Some(u) => (Vec3::new(r * u.x, r * u.y, q.z), None),
                None => return 0,
            },
            Partition::Plane { reach } => (Vec3::new(q.x, q.y, 0.0), Some(reach)),
            Partition::Space => (q, None),
        };
        let (index, d2) = self.seeds.nearest(&probe);
        match reach {
            Some(r) if d2 > r * r => 0,
            _ => index as u32 + 1,
        }
    }
}

/// `n` points on the unit sphere: a Fibonacci lattice, turned by a random rotation, jittered by 0.15
/// of the mean spacing and relaxed by 10 steps of short-range repulsion.
fn sphere_seeds(n: usize, rng: &mut ChaCha8Rng) -> Vec<Vec3> {
    let golden = PI * (3.0 - 5f64.sqrt());
    let axis = Vec3::new(rng.random::<Real>() - 0.5, rng.random::<Real>() - 0.5, rng.random::<Real>() - 0.5);
    let rotation = nalgebra::Rotation3::new(axis.try_normalize(0.0).unwrap_or(Vec3::z()) * rng.random::<Real>() * PI);
    let spacing = (4.0 * PI / n as Real).sqrt();
    let points: Vec<Vec3> = (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as Real + 0.5) / n as Real;
            let rho = (1.0 - z * z).sqrt();
            let phi = golden * i as Real;
            let jitter = Vec3::new(rng.random::<Real>() - 0.5, rng.random::<Real>() - 0.5, rng.random::<Real>() - 0.5);
            (rotation * Vec3::new(rho * phi.cos(), rho * phi.sin(), z) + 0.15 * spacing * jitter).normalize()
        })
        .collect();
    relax(points, spacing, |p| p.normalize())
}

/// 10 steps of short-range repulsion between `points` (mean spacing `spacing`), each point then
/// mapped by `project` (back onto the sphere, into the ball): evens out a random or jittered lattice,
/// so that no Voronoi cell is much thinner than the others.
fn relax(mut points: Vec<Vec3>, spacing: Real, project: impl Fn(Vec3) -> Vec3 + Sync) -> Vec<Vec3> {
    let reach = 2.0 * spacing;
    for _ in 0..10 {
        let index = NearestSeed::new(points.clone());
        let moved: Vec<Vec3> = points
            .par_iter()
            .enumerate()
            .map(|(i, p)| {
                let mut push = Vec3::zeros();
                index.for_each_within(p, reach, |j, d| {
                    if j != i && d > 0.0 {
                        let s = d / spacing;
                        push += (p - index.points[j]) / d * (0.05 * spacing / (s * s)).min(0.2 * spacing);
                    }
                });
                project(p + push)
            })
            .collect();
        points = moved;
    }
    points
}

/// `n` points uniform in a ball of radius `r` (origin), at least a distance apart that starts at
/// 0.8 × the mean spacing and shrinks when placement stalls (rejection sampling).
fn ball_seeds(n: usize, r: Real, rng: &mut ChaCha8Rng) -> Vec<Vec3> {
    let spacing = (4.0 / 3.0 * PI * r.powi(3) / n as Real).cbrt();
    let mut min_dist = 0.8 * spacing;
    let mut seeds: Vec<Vec3> = Vec::with_capacity(n);
    let mut failures = 0;
    while seeds.len() < n {
        let q = Vec3::new(
            rng.random::<Real>() * 2.0 - 1.0,
            rng.random::<Real>() * 2.0 - 1.0,
            rng.random::<Real>() * 2.0 - 1.0,
        );
        if q.norm() > 1.0 {
            continue;
        }
        let p = q * r;
        if seeds.iter().all(|s| (s - p).norm_squared() >= min_dist * min_dist) {
            seeds.push(p);
            failures = 0;
        } else {
            failures += 1;
            if failures > 1000 {
                min_dist *= 0.95;
                failures = 0;
            }
        }
    }
    // Keep the seeds half a spacing inside the surface, so that outer cells are not flat slivers.
    let inner = (r - 0.5 * spacing).max(0.5 * r);
    relax(seeds, spacing, |p| if p.norm() > inner { p * (inner / p.norm()) } else { p })
}

/// The `n` points of the unit hexagonal lattice (i, j) ↦ (i + j/2, j·√3/2) nearest to the origin,
/// ties broken by angle then by (i, j): a roughly round patch.
fn hexagonal_patch(n: usize) -> Vec<(i64, i64)> {
    let mut radius = 1i64;
    loop {
        let mut points: Vec<(i64, i64)> = Vec::new();
        for i in -radius..=radius {
            for j in -radius..=radius {
                points.push((i, j));
            }
        }
        let norm = |&(i, j): &(i64, i64)| i * i + i * j + j * j;
        if points.iter().filter(|p| norm(p) <= radius * radius * 3 / 4).count() >= n {
            points.sort_by(|a, b| {
                let angle = |&(i, j): &(i64, i64)| (0.5 * 3f64.sqrt() * j as Real).atan2(i as Real + 0.5 * j as Real);
                norm(a).cmp(&norm(b)).then(angle(a).total_cmp(&angle(b))).then(a.cmp(b))
            });
            points.truncate(n);
            return points;
        }
        radius *= 2;
    }
}

/// Nearest-seed queries through a uniform bucket grid (cell edge ≈ the mean seed spacing).
struct NearestSeed {
    points: Vec<Vec3>,
    lo: Vec3,
    cell: Real,
    dims: [usize; 3],
    offsets: Vec<u32>,
    items: Vec<u32>,
}

impl NearestSeed {
    fn new(points: Vec<Vec3>) -> Self {
        let (lo, hi) = crate::geometry::bounding_box(&points).unwrap_or((Vec3::zeros(), Vec3::zeros()));
        let extent = (hi - lo).map(|e| e.max(1e-30));
        // About 2 points per bucket, over the box's non-degenerate axes.
        let spanned: Vec<Real> = extent.iter().copied().filter(|e| *e > 1e-9 * extent.max()).collect();
        let measure: Real = spanned.iter().product();
        let cell = (2.0 * measure / points.len().max(1) as Real).powf(1.0 / spanned.len().max(1) as Real);
        let cell = if cell.is_finite() && cell > 0.0 { cell.max(extent.max() / 1000.0) } else { extent.max() };
        let dims = [0, 1, 2].map(|a| (extent[a] / cell).floor() as usize + 1);
        let bucket_of = |p: &Vec3| -> usize {
            let c = [0, 1, 2].map(|a| (((p[a] - lo[a]) / cell).floor().max(0.0) as usize).min(dims[a] - 1));
            (c[2] * dims[1] + c[1]) * dims[0] + c[0]
        };
        let mut counts = vec![0u32; dims.iter().product::<usize>() + 1];
        for p in &points {
            counts[bucket_of(p) + 1] += 1;
        }
        for k in 1..counts.len() {
            counts[k] += counts[k - 1];
        }
        let mut fill = counts.clone();
        let mut items = vec![0u32; points.len()];
        for (i, p) in points.iter().enumerate() {
            let b = bucket_of(p);
            items[fill[b] as usize] = i as u32;
            fill[b] += 1;
        }
        Self { points, lo, cell, dims, offsets: counts, items }
    }

    fn coords(&self, p: &Vec3) -> [i64; 3] {
        [0, 1, 2].map(|a| ((p[a] - self.lo[a]) / self.cell).floor() as i64)
    }

    fn bucket(&self, c: [i64; 3]) -> &[u32] {
        let b = (c[2] as usize * self.dims[1] + c[1] as usize) * self.dims[0] + c[0] as usize;
        &self.items[self.offsets[b] as usize..self.offsets[b + 1] as usize]
    }

    /// Calls `f(index, distance)` for every point within `radius` of `p`.
    fn for_each_within(&self, p: &Vec3, radius: Real, mut f: impl FnMut(usize, Real)) {
        let lo = self.coords(&(p - Vec3::repeat(radius)));
        let hi = self.coords(&(p + Vec3::repeat(radius)));
        for z in lo[2].max(0)..=hi[2].min(self.dims[2] as i64 - 1) {
            for y in lo[1].max(0)..=hi[1].min(self.dims[1] as i64 - 1) {
                for x in lo[0].max(0)..=hi[0].min(self.dims[0] as i64 - 1) {
                    for &i in self.bucket([x, y, z]) {
                        let d = (self.points[i as usize] - p).norm();
                        if d <= radius {
                            f(i as usize, d);
                        }
                    }
                }
            }
        }
    }

    /// Index of the nearest point (lowest index on ties) and its squared distance.
    fn nearest(&self, p: &Vec3) -> (usize, Real) {
        let c = self.coords(p);
        let clamp = |v: i64, a: usize| v.clamp(0, self.dims[a] as i64 - 1);
        let centre = [clamp(c[0], 0), clamp(c[1], 1), clamp(c[2], 2)];
        // Distance from p to the box of buckets within ring k of `centre` bounds what ring k+1 can hold.
        let mut best = (usize::MAX, Real::INFINITY);
        let max_ring = self.dims.iter().copied().max().unwrap_or(1) as i64;
        for ring in 0..=max_ring {
            for z in centre[2] - ring..=centre[2] + ring {
                for y in centre[1] - ring..=centre[1] + ring {
                    for x in centre[0] - ring..=centre[0] + ring {
                        let on_ring = (x - centre[0]).abs() == ring
                            || (y - centre[1]).abs() == ring
                            || (z - centre[2]).abs() == ring;
                        if !on_ring
                            || x < 0
                            || y < 0
                            || z < 0
                            || x >= self.dims[0] as i64
                            || y >= self.dims[1] as i64
                            || z >= self.dims[2] as i64
                        {
                            continue;
                        }
                        for &i in self.bucket([x, y, z]) {
                            let d2 = (self.points[i as usize] - p).norm_squared();
                            if d2 < best.1 || (d2 == best.1 && (i as usize) < best.0) {
                                best = (i as usize, d2);
                            }
                        }
                    }
                }
            }
            // Everything outside rings 0..=ring is farther from p than this bound.
            let inner_lo = [0, 1, 2].map(|a| self.lo[a] + (centre[a] - ring) as Real * self.cell);
            let inner_hi = [0, 1, 2].map(|a| self.lo[a] + (centre[a] + ring + 1) as Real * self.cell);
            let margin = (0..3)
                .map(|a| {
                    let below = if centre[a] - ring <= 0 { Real::INFINITY } else { p[a] - inner_lo[a] };
                    let above =
                        if centre[a] + ring >= self.dims[a] as i64 - 1 { Real::INFINITY } else { inner_hi[a] - p[a] };
                    below.min(above)
                })
                .fold(Real::INFINITY, Real::min);
            if best.0 != usize::MAX && (margin.is_infinite() || margin * margin > best.1) {
                break;
            }
        }
        best
    }
}

/// The deepest node of any body inside another body, among nodes within `search` (m) of the other
/// body's surface: for each node, the signed distance to every other body whose surface is within
/// `search`, negative inside it. The sign comes from the normals of the faces sharing the closest
/// point (their sum: the pseudo-normal of an edge, a plain average at a vertex). For an ECM (an
/// enclosing body) and for a nucleus against its host (`hosts`: nucleus → host), the inside and
/// outside are swapped, as in the contact model. `None` when no node is inside another body.
pub fn max_penetration(tissue: &Tissue, hosts: &[(CellId, CellId)], search: Real) -> Option<Penetration> {
    let cells = tissue.cells();
    let pad = Vec3::repeat(search);
    let grids: Vec<(SpatialGrid, Vec<Vec3>, Vec3, Vec3)> = cells
        .par_iter()
        .map(|c| {
            let mesh = c.mesh();
            let p = mesh.positions();
            let boxes: Vec<(Vec3, Vec3)> = mesh
                .triangles()
                .iter()
                .map(|t| {
                    let (a, b, d) = (p[t[0] as usize], p[t[1] as usize], p[t[2] as usize]);
                    (a.inf(&b).inf(&d) - pad, a.sup(&b).sup(&d) + pad)
                })
                .collect();
            let (lo, hi) = crate::geometry::bounding_box(p).unwrap_or((Vec3::zeros(), Vec3::zeros()));
            let mut grid = SpatialGrid::new(3.0 * search);
            grid.rebuild(&boxes);
            (grid, mesh.face_normals(), lo - pad, hi + pad)
        })
        .collect();
    let host_of = |id: CellId| hosts.iter().find(|(n, _)| *n == id).map(|(_, h)| *h);
    let per_cell: Vec<Option<Penetration>> = (0..cells.len())
        .into_par_iter()
        .map(|a| {
            let cell_a = &cells[a];
            let mut worst: Option<Penetration> = None;
            for (b, cell_b) in cells.iter().enumerate() {
                if a == b {
                    continue;
                }
                let (grid, normals, lo, hi) = &grids[b];
                let flipped = (cell_b.kind() == CellKind::Ecm && cell_a.kind() != CellKind::Ecm)
                    || host_of(cell_a.id()) == Some(cell_b.id());
                let mesh_b = cell_b.mesh();
                let pb = mesh_b.positions();
                for p in cell_a.mesh().positions() {
                    if (0..3).any(|k| p[k] < lo[k] || p[k] > hi[k]) {
                        continue;
                    }
                    let mut best = Real::INFINITY;
                    let mut normal = Vec3::zeros();
                    let mut closest = Vec3::zeros();
                    grid.for_each_at(p, |f| {
                        let t = mesh_b.triangles()[f as usize];
                        let q =
                            closest_point_on_triangle(p, &pb[t[0] as usize], &pb[t[1] as usize], &pb[t[2] as usize]);
                        let tol = 1e-9 * search;
                        if q.distance < best - tol {
                            best = q.distance;
                            normal = normals[f as usize];
                            closest = q.point;
                        } else if q.distance <= best + tol {
                            normal += normals[f as usize];
                        }
                    });
                    if best > search {
                        continue;
                    }
                    let mut inside = (p - closest).dot(&normal) < 0.0;
                    if flipped {
                        inside = !inside;
                    }
                    if inside && best > 0.0 && worst.is_none_or(|w| best > w.depth) {
                        worst = Some(Penetration { depth: best, cell: cell_a.id().0, other: cell_b.id().0 });
                    }
                }
            }
            worst
        })
        .collect();
    per_cell.into_iter().flatten().fold(None, |acc: Option<Penetration>, p| match acc {
        Some(a) if a.depth >= p.depth => Some(a),
        _ => Some(p),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_seed_agrees_with_brute_force() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let seeds = ball_seeds(200, 1.0, &mut rng);
        let index = NearestSeed::new(seeds.clone());
        for _ in 0..2000 {
            let p = Vec3::new(
                rng.random::<Real>() * 3.0 - 1.5,
                rng.random::<Real>() * 3.0 - 1.5,
                rng.random::<Real>() * 3.0 - 1.5,
            );
            let brute = seeds
                .iter()
                .enumerate()
                .map(|(i, s)| (i, (s - p).norm_squared()))
                .fold((usize::MAX, Real::INFINITY), |b, c| if c.1 < b.1 { c } else { b });
            assert_eq!(index.nearest(&p), brute);
        }
        // Points on a plane (a degenerate axis) too.
        let flat: Vec<Vec3> = hexagonal_patch(50).iter().map(|&(i, j)| Vec3::new(i as Real, j as Real, 0.0)).collect();
        let index = NearestSeed::new(flat.clone());
        let p = Vec3::new(0.3, -2.2, 0.0);
        let brute = flat.iter().map(|s| (s - p).norm_squared()).fold(Real::INFINITY, Real::min);
        assert_eq!(index.nearest(&p).1, brute);
    }

    #[test]
    fn hexagonal_patch_of_seven_is_a_centre_and_its_ring() {
        let p = hexagonal_patch(7);
        assert_eq!(p[0], (0, 0));
        let mut ring: Vec<(i64, i64)> = p[1..].to_vec();
        ring.sort();
        assert_eq!(ring, vec![(-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0)]);
    }

    #[test]
    fn sphere_seeds_are_spread_out() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let n = 100;
        let s = sphere_seeds(n, &mut rng);
        let spacing = (4.0 * PI / n as Real).sqrt();
        for (i, p) in s.iter().enumerate() {
            assert!((p.norm() - 1.0).abs() < 1e-12);
            let nearest = s
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != i)
                .map(|(_, q)| (p - q).norm())
                .fold(Real::INFINITY, Real::min);
            // A relaxed lattice: nearest neighbour ≈ 1.1 spacings, never half of one.
            assert!(nearest > 0.6 * spacing, "{nearest} vs spacing {spacing}");
        }
    }
}

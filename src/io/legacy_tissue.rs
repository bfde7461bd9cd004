//! Legacy VTK grid → `Tissue`, for the three layouts found in practice:
//!
//! * **SimuCell3D** (`cell_data` files): one polyhedron (VTK type 42) per cell, faces any k-gon,
//!   `cell_type_id` per cell (an index into the parameter file's cell types; SimuCell3D's default
//!   list maps 0..4 to epithelial, ECM, lumen, nucleus, static), optionally `cell_id`.
//! * **Multi-material triangle meshes** from image tools (delaunay-watershed, deltaMic, foambryo):
//!   triangles or polygons carrying `label1`/`label2`, the materials on the two sides, 0 = outside.
//!   A cell is every face where its label appears, oriented outward.
//! * **Face-labelled surfaces** (SimuCell3D `face_data` files): polygons with `face_cell_id` (and
//!   optionally `face_type_id`); each face belongs to one cell.

use super::IoError;
use super::legacy_parse::{DataArray, LegacyGrid, polyhedron_faces};
use crate::geometry::Vec3;
use crate::mesh::{Cell, CellId, CellKind, CellMesh, CellOverrides, FaceType, Tissue};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::path::Path;

/// Which layout a file had.
#[derive(Copy, Clone, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TissueFormat {
    /// SimuCell3D legacy VTK: one polyhedron per cell.
    Simucell3d,
    /// Triangle soup with `label1`/`label2` per face.
    MultiMaterial,
    /// Faces with one owning cell each (`face_cell_id`).
    FaceLabelled,
    /// ParaView XML PolyData written by tissuefit (faces carry `cell_id`).
    Vtp,
}

const POLYHEDRON: u8 = 42;
const SURFACE_TYPES: [u8; 3] = [5, 7, 9]; // triangle, polygon, quad

pub(crate) fn tissue_from_grid(
    path: &Path,
    g: &LegacyGrid,
    warnings: &mut Vec<String>,
) -> Result<(Tissue, TissueFormat), IoError> {
    let n = g.cell_count();
    if n == 0 {
        return Err(IoError::parse(path, Some(g.cells_line), "the file has no cells"));
    }
    let known = |t: &u8| *t == POLYHEDRON || SURFACE_TYPES.contains(t);
    if let Some((c, &t)) = g.cell_types.iter().enumerate().find(|&(_, t)| !known(t)) {
        return Err(IoError::Unsupported {
            path: path.into(),
            message: format!(
                "cell {c} has VTK type {t}; tissuefit reads polyhedra (type 42, SimuCell3D) or triangles/polygons (types 5, 7, 9) labelled with label1/label2 or face_cell_id"
            ),
        });
    }
    let polyhedra_count = g.cell_types.iter().filter(|&&t| t == POLYHEDRON).count();
    if polyhedra_count == n {
        return polyhedra(path, g, warnings).map(|t| (t, TissueFormat::Simucell3d));
    }
    if polyhedra_count > 0 {
        return Err(IoError::Unsupported {
            path: path.into(),
            message: format!(
                "{polyhedra_count} polyhedra mixed with {} surface faces; a file holds either one polyhedron per cell or labelled faces",
                n - polyhedra_count
            ),
        });
    }
    if let (Some(l1), Some(l2)) = (g.array("label1"), g.array("label2")) {
        return multi_material(path, g, l1, l2, warnings).map(|t| (t, TissueFormat::MultiMaterial));
    }
    if let Some(owner) = ["face_cell_id", "cell_id", "label"].iter().find_map(|k| g.array(k)) {
        return face_labelled(path, g, owner, warnings).map(|t| (t, TissueFormat::FaceLabelled));
    }
    Err(IoError::Unsupported {
        path: path.into(),
        message: "a surface mesh without label1/label2 (multi-material) or face_cell_id cell data: cannot tell which cell each face belongs to".into(),
    })
}

/// Reads an integer-valued array entry, with a message naming the array, entry and line.
fn integer(path: &Path, a: &DataArray, i: usize) -> Result<u32, IoError> {
    let v = a.values[i * a.components];
    if v.fract() != 0.0 || !(0.0..=u32::MAX as f64).contains(&v) {
        return Err(IoError::parse(
            path,
            Some(a.line),
            format!("{} of cell {i} is {v}, expected a non-negative integer", a.name),
        ));
    }
    Ok(v as u32)
}

/// Builds a cell mesh from faces given as global point ids: nodes are renumbered in increasing
/// global order, so a cell written contiguously reads back with the same node order.
fn cell_mesh<F: AsRef<[u32]>>(
    path: &Path,
    g: &LegacyGrid,
    id: CellId,
    faces: &[F],
) -> Result<(CellMesh, Vec<u32>), IoError> {
    let mut used: Vec<u32> = faces.iter().flat_map(|f| f.as_ref().iter().copied()).collect();
    used.sort_unstable();
    used.dedup();
    let local_of = |global: u32| used.binary_search(&global).expect("every face point is in `used`") as u32;
    let local: Vec<Vec<u32>> = faces.iter().map(|f| f.as_ref().iter().map(|&i| local_of(i)).collect()).collect();
    let positions: Vec<Vec3> = used.iter().map(|&i| g.points[i as usize]).collect();
    CellMesh::from_polygons(positions, &local).map_err(|source| IoError::Mesh { path: path.into(), cell: id, source })
}

fn polyhedra(path: &Path, g: &LegacyGrid, warnings: &mut Vec<String>) -> Result<Tissue, IoError> {
    let n = g.cell_count();
    let type_ids = g.array("cell_type_id");
    if type_ids.is_none() {
        warnings.push("no cell_type_id array: every cell gets cell type 0 (epithelial)".into());
    }
    let ids: Vec<CellId> = match g.array("cell_id") {
        Some(a) => {
            let ids = (0..n).map(|i| integer(path, a, i).map(CellId)).collect::<Result<Vec<_>, _>>()?;
            let mut sorted = ids.clone();
            sorted.sort_unstable();
            if sorted.windows(2).any(|w| w[0] == w[1]) {
                warnings.push("cell_id values repeat: cells are numbered by their order in the file instead".into());
                (0..n as u32).map(CellId).collect()
            } else {
                ids
            }
        }
        None => (0..n as u32).map(CellId).collect(),
    };
    let is_static = g.array("cell_is_static");
    let kinds = g.array("cell_kind");
    let targets = g.array("cell_target_volume");
    let override_arrays: Vec<_> = CellOverrides::array_names()
        .filter_map(|(name, q, t)| g.array(&format!("cell_{name}")).map(|a| (name, q, t, a)))
        .collect();
    // SimuCell3D reads cell_type_id as an index into its parameter file's cell types; its default
    // list is 0..4 = epithelial, ECM, lumen, nucleus, static. Some files store per-cell ids there
    // instead (0..15 in embryo_1): then no value can be trusted as a kind, and all cells are epithelial.
    let type_values: Vec<u32> = match type_ids {
        Some(a) => (0..n).map(|i| integer(path, a, i)).collect::<Result<_, _>>()?,
        None => vec![0; n],
    };
    let types_are_kinds = type_values.iter().all(|&t| CellKind::from_code(t).is_some());
    if !types_are_kinds {
        let max = type_values.iter().max().copied().unwrap_or(0);
        warnings.push(format!(
            "cell_type_id holds values up to {max}, beyond SimuCell3D's default types (0 epithelial, 1 ECM, 2 lumen, 3 nucleus, 4 static): the file probably stores per-cell ids there, so every cell is read as epithelial (cell_type keeps the value). Simulating it needs a config whose [[cell_types]] cover these indices"
        ));
    }
    // Meshes are built in parallel (cells are independent), then assembled in file order.
    let meshes: Vec<CellMesh> = (0..n)
        .into_par_iter()
        .map(|c| {
            let faces = polyhedron_faces(g.cell(c))
                .map_err(|m| IoError::parse(path, Some(g.cells_line), format!("cell {c} (polyhedron): {m}")))?;
            cell_mesh(path, g, ids[c], &faces).map(|(mesh, _)| mesh)
        })
        .collect::<Result<_, _>>()?;
    let mut tissue = Tissue::new();
    for (c, mesh) in meshes.into_iter().enumerate() {
        let id = ids[c];
        let cell_type = type_values[c];
        let mut kind = match kinds {
            Some(a) => {
                let code = integer(path, a, c)?;
                CellKind::from_code(code).ok_or_else(|| {
                    IoError::parse(path, Some(a.line), format!("cell_kind of cell {c} is {code}; valid kinds are 0..4"))
                })?
            }
            None if types_are_kinds => CellKind::from_code(cell_type).unwrap_or(CellKind::Epithelial),
            None => CellKind::Epithelial,
        };
        if let Some(a) = is_static
            && integer(path, a, c)? == 1
            && kind == CellKind::Epithelial
        {
            kind = CellKind::Static;
        }
        let mut cell = Cell::new(id, kind, cell_type, mesh);
        if let Some(a) = targets {
            cell = cell.with_target_volume(a.values[c * a.components]);
        }
        for &(name, q, t, a) in &override_arrays {
            // −1 (as written) or NaN: the cell keeps its type's value.
            let v = a.values[c * a.components];
            if v == -1.0 || v.is_nan() {
                continue;
            }
            if !(v.is_finite() && v >= 0.0) {
                return Err(IoError::parse(
                    path,
                    Some(a.line),
                    format!(
                        "cell_{name} of cell {c} is {v}: a cell's own value must be a finite number ≥ 0 (−1: none)"
                    ),
                ));
            }
            cell.overrides_mut().values_mut(q)[t.code() as usize] = Some(v);
        }
        tissue.push(cell).map_err(|source| IoError::Tissue { path: path.into(), source })?;
    }
    Ok(tissue)
}

/// Face records of a surface grid, each a polygon of global point ids.
fn surface_faces<'g>(path: &Path, g: &'g LegacyGrid) -> Result<Vec<&'g [u32]>, IoError> {
    (0..g.cell_count())
        .map(|c| {
            let f = g.cell(c);
            if f.len() < 3 {
                Err(IoError::parse(
                    path,
                    Some(g.cells_line),
                    format!("face {c} has {} points; a face needs at least 3", f.len()),
                ))
            } else {
                Ok(f)
            }
        })
        .collect()
}

fn multi_material(
    path: &Path,
    g: &LegacyGrid,
    l1: &DataArray,
    l2: &DataArray,
    warnings: &mut Vec<String>,
) -> Result<Tissue, IoError> {
    let faces = surface_faces(path, g)?;
    // label → (faces where it is label1, faces where it is label2).
    let mut cells: BTreeMap<u32, (Vec<usize>, Vec<usize>)> = BTreeMap::new();
    let mut same = 0usize;
    let mut sides = Vec::with_capacity(faces.len());
    for f in 0..faces.len() {
        let (a, b) = (integer(path, l1, f)?, integer(path, l2, f)?);
        sides.push((a, b));
        if a == b {
            same += 1;
            continue;
        }
        if a != 0 {
            cells.entry(a).or_default().0.push(f);
        }
        if b != 0 {
            cells.entry(b).or_default().1.push(f);
        }
    }
    if same > 0 {
        warnings.push(format!("{same} faces have the same material on both sides and were skipped"));
    }
    if cells.is_empty() {
        return Err(IoError::parse(path, Some(l1.line), "no face carries a non-zero label: the file holds no cells"));
    }
    // Orientation convention: the tools differ on whether a face's normal points into label1 or
    // label2. Build each cell with faces kept where it is label1 and flipped where it is label2, and
    // flip the whole convention if most cells come out inside-out. Some tools also wind a few
    // triangles arbitrarily (deltaMic), so each cell is then made consistent and outward.
    let mut built: Vec<(u32, CellMesh, Vec<u32>)> = cells
        .par_iter()
        .map(|(&label, (as1, as2))| {
            let polys: Vec<Vec<u32>> = as1
                .iter()
                .map(|&f| faces[f].to_vec())
                .chain(as2.iter().map(|&f| faces[f].iter().rev().copied().collect()))
                .collect();
            // Each triangle's interface label: the material on the other side of its source face.
            let other = |k: usize| match as1.get(k) {
                Some(&f) => sides[f].1,
                None => sides[as2[k - as1.len()]].0,
            };
            cell_mesh(path, g, CellId(label), &polys)
                .map(|(mesh, source)| (label, mesh, source.iter().map(|&k| other(k as usize)).collect()))
        })
        .collect::<Result<_, _>>()?;
    let inverted = built.iter().filter(|(_, m, _)| m.signed_volume() < 0.0).count();
    if 2 * inverted > built.len() {
        built.iter_mut().for_each(|(_, m, _)| m.flip_all());
    }
    for (label, mesh, _) in &mut built {
        let flipped = mesh.orient_outward();
        if flipped > 0 {
            warnings.push(format!("cell {label}: {flipped} faces wound against their neighbours were re-oriented"));
        }
    }
    let cells = built
        .into_iter()
        .map(|(label, mesh, others)| {
            Cell::new(CellId(label), CellKind::Epithelial, 0, mesh).with_interface_labels(others)
        })
        .collect::<Result<_, _>>()
        .map_err(|source| IoError::Tissue { path: path.into(), source })?;
    Tissue::from_cells(cells).map_err(|source| IoError::Tissue { path: path.into(), source })
}

fn face_labelled(
    path: &Path,
    g: &LegacyGrid,
    owner: &DataArray,
    warnings: &mut Vec<String>,
) -> Result<Tissue, IoError> {
    let faces = surface_faces(path, g)?;
    let types = g.array("face_type_id");
    let mut cells: BTreeMap<u32, Vec<usize>> = BTreeMap::new();
    for f in 0..faces.len() {
        cells.entry(integer(path, owner, f)?).or_default().push(f);
    }
    let mut tissue = Tissue::new();
    let mut bad_types = 0usize;
    for (&label, fs) in &cells {
        let polys: Vec<&[u32]> = fs.iter().map(|&f| faces[f]).collect();
        let (mesh, source) = cell_mesh(path, g, CellId(label), &polys)?;
        let mut cell = Cell::new(CellId(label), CellKind::Epithelial, 0, mesh);
        if let Some(t) = types {
            let face_types = source
                .iter()
                .map(|&p| {
                    let code = integer(path, t, fs[p as usize])?;
                    Ok(FaceType::from_code(code).unwrap_or_else(|| {
                        bad_types += 1;
                        FaceType::default()
                    }))
                })
                .collect::<Result<Vec<_>, IoError>>()?;
            cell = cell.with_face_types(face_types).map_err(|source| IoError::Tissue { path: path.into(), source })?;
        }
        tissue.push(cell).map_err(|source| IoError::Tissue { path: path.into(), source })?;
    }
    if bad_types > 0 {
        warnings.push(format!("{bad_types} faces have a face_type_id outside 0..2 and were set to apical"));
    }
    Ok(tissue)
}

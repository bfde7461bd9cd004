//! PLY meshes (ASCII or binary, read with `ply-rs-bw`) as the same grid a legacy VTK surface file
//! gives, so that [`super::legacy_tissue::tissue_from_grid`] builds the tissue exactly as for a `.vtk`:
//!
//! * faces with `label1`/`label2` (multi-material, 3-D closed cells),
//! * faces with one owner (`label`, `cell_id` or `face_cell_id`),
//! * a cell element listing each cell's faces (`volume` or `cell` with a `face_index` list and an
//!   optional `label`; the cellcomplex/TissueLab "topomesh" layout), read as faces with one owner.
//!
//! Each face's scalar properties become its cell-data arrays (colours and the like are carried and
//! ignored). A face that no cell element lists is left out, with a warning.

use super::IoError;
use super::legacy_parse::{DataArray, LegacyGrid};
use crate::geometry::{Real, Vec3};
use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{DefaultElement, Property};
use std::collections::BTreeMap;
use std::path::Path;

/// Element names that list each cell's faces.
const CELL_ELEMENTS: [&str; 2] = ["volume", "cell"];
/// List properties that hold a face's vertices.
const VERTEX_LISTS: [&str; 2] = ["vertex_indices", "vertex_index"];

fn scalar(p: &Property) -> Option<Real> {
    match *p {
        Property::Char(v) => Some(v.into()),
        Property::UChar(v) => Some(v.into()),
        Property::Short(v) => Some(v.into()),
        Property::UShort(v) => Some(v.into()),
        Property::Int(v) => Some(v.into()),
        Property::UInt(v) => Some(v.into()),
        Property::Float(v) => Some(v.into()),
        Property::Double(v) => Some(v),
        _ => None,
    }
}

fn indices(p: &Property) -> Option<Vec<i64>> {
    Some(match p {
        Property::ListChar(v) => v.iter().map(|&x| x.into()).collect(),
        Property::ListUChar(v) => v.iter().map(|&x| x.into()).collect(),
        Property::ListShort(v) => v.iter().map(|&x| x.into()).collect(),
        Property::ListUShort(v) => v.iter().map(|&x| x.into()).collect(),
        Property::ListInt(v) => v.iter().map(|&x| x.into()).collect(),
        Property::ListUInt(v) => v.iter().map(|&x| x.into()).collect(),
        _ => return None,
    })
}

fn get<'a>(element: &'a DefaultElement, name: &str) -> Option<&'a Property> {
    element.iter().find(|(k, _)| k.eq_ignore_ascii_case(name)).map(|(_, v)| v)
}

/// The grid of a PLY file's bytes: points, faces (VTK polygons) and per-face arrays.
pub(crate) fn parse_ply(path: &Path, bytes: &[u8]) -> Result<(LegacyGrid, Vec<String>), IoError> {
    let parse = |m: String| IoError::parse(path, None, m);
    let ply = Parser::<DefaultElement>::new()
        .read_ply(&mut &bytes[..])
        .map_err(|e| IoError::parse(path, e.line(), format!("not a readable PLY file: {e}")))?;
    let element = |name: &str| ply.payload.iter().find(|(k, _)| k.eq_ignore_ascii_case(name)).map(|(_, v)| v);
    let vertices = element("vertex").ok_or_else(|| parse("the file has no `vertex` element".into()))?;
    let mut points = Vec::with_capacity(vertices.len());
    for (i, v) in vertices.iter().enumerate() {
        let mut p = Vec3::zeros();
        for (k, axis) in ["x", "y", "z"].iter().enumerate() {
            p[k] = get(v, axis)
                .and_then(scalar)
                .ok_or_else(|| parse(format!("vertex {i} has no numeric `{axis}` property")))?;
        }
        if !p.iter().all(|c| c.is_finite()) {
            return Err(parse(format!("vertex {i} has a non-finite coordinate")));
        }
        points.push(p);
    }
    let faces = element("face").ok_or_else(|| {
        parse("the file has no `face` element: tissuefit reads surface meshes (a point cloud has no cells)".into())
    })?;
    let mut polygons: Vec<Vec<u32>> = Vec::with_capacity(faces.len());
    for (f, face) in faces.iter().enumerate() {
        let list = VERTEX_LISTS
            .iter()
            .find_map(|n| get(face, n))
            .and_then(indices)
            .ok_or_else(|| parse(format!("face {f} has no `vertex_indices` list")))?;
        if list.len() < 3 {
            return Err(parse(format!("face {f} has {} vertices; a face needs at least 3", list.len())));
        }
        let ids = list
            .iter()
            .map(|&i| u32::try_from(i).ok().filter(|&i| (i as usize) < points.len()))
            .collect::<Option<Vec<u32>>>()
            .ok_or_else(|| parse(format!("face {f} names a vertex outside 0..{}", points.len())))?;
        polygons.push(ids);
    }
    // Per-face scalar arrays, in the order of the face element's first record.
    let names: Vec<String> = faces
        .first()
        .map(|f| f.iter().filter(|(_, v)| scalar(v).is_some()).map(|(k, _)| k.clone()).collect())
        .unwrap_or_default();
    let mut arrays: Vec<DataArray> = names
        .iter()
        .map(|name| DataArray { name: name.clone(), components: 1, values: Vec::with_capacity(faces.len()), line: 0 })
        .collect();
    for (f, face) in faces.iter().enumerate() {
        for a in &mut arrays {
            let v =
                get(face, &a.name).and_then(scalar).ok_or_else(|| parse(format!("face {f} has no `{}`", a.name)))?;
            a.values.push(v);
        }
    }
    let mut warnings = Vec::new();
    let mut keep: Vec<usize> = (0..polygons.len()).collect();
    if let Some((name, cells)) = CELL_ELEMENTS.iter().find_map(|n| element(n).map(|e| (*n, e))) {
        // Each listed face gets its cell's label (the element's `label`, else its index + 1).
        let mut owner: BTreeMap<usize, u32> = BTreeMap::new();
        let mut empty = 0usize;
        for (c, cell) in cells.iter().enumerate() {
            let label = match get(cell, "label").and_then(scalar) {
                Some(l) if l.fract() == 0.0 && (1.0..=u32::MAX as Real).contains(&l) => l as u32,
                Some(l) => return Err(parse(format!("{name} {c} has label {l}; labels are positive integers"))),
                None => c as u32 + 1,
            };
            let listed = ["face_index", "faces", "face_indices"]
                .iter()
                .find_map(|n| get(cell, n))
                .and_then(indices)
                .ok_or_else(|| parse(format!("{name} {c} has no `face_index` list")))?;
            if listed.is_empty() {
                empty += 1;
            }
            for f in listed {
                let f = usize::try_from(f).ok().filter(|&f| f < polygons.len()).ok_or_else(|| {
                    parse(format!("{name} {c} (label {label}) names face {f}, outside 0..{}", polygons.len()))
                })?;
                if let Some(other) = owner.insert(f, label)
                    && other != label
                {
                    return Err(parse(format!(
                        "face {f} is listed by the cells labelled {other} and {label}; in a `{name}` element every \
                         face belongs to one cell (shared walls need label1/label2 on the faces)"
                    )));
                }
            }
        }
        if empty > 0 {
            warnings.push(format!("{empty} `{name}` records list no faces and were left out"));
        }
        let unowned = polygons.len() - owner.len();
        if unowned > 0 {
            warnings.push(format!("{unowned} faces belong to no `{name}` record and were left out"));
        }
        keep = owner.keys().copied().collect();
        arrays.retain(|a| !a.name.eq_ignore_ascii_case("label"));
        arrays.push(DataArray { name: "label".into(), components: 1, values: vec![0.0; polygons.len()], line: 0 });
        let last = arrays.len() - 1;
        for (&f, &label) in &owner {
            arrays[last].values[f] = label.into();
        }
    }
    let mut grid = LegacyGrid { points, points_line: 0, cells_line: 0, ..Default::default() };
    grid.offsets.push(0);
    for &f in &keep {
        grid.connectivity.extend_from_slice(&polygons[f]);
        grid.offsets.push(grid.connectivity.len());
        grid.cell_types.push(if polygons[f].len() == 3 { 5 } else { 7 });
    }
    for a in &mut arrays {
        a.values = keep.iter().map(|&f| a.values[f]).collect();
    }
    grid.cell_data = arrays;
    Ok((grid, warnings))
}

//! Writer of the SimuCell3D legacy VTK format, so our tissues open in the reference program and in
//! ParaView: ASCII 4.2, `UNSTRUCTURED_GRID`, one polyhedron (type 42) per cell with its triangles as
//! faces, and per-cell field data.
//!
//! Fields: SimuCell3D's `cell_id`, `cell_type_id` (the cell's parameter-set index, as the reference
//! reads it), `cell_area`, `cell_volume`, `cell_is_static`, plus `cell_kind` and `cell_target_volume`
//! (ignored by the reference, read back by tissuefit), when some cell has its own tensions or
//! adhesions `cell_surface_tension_apical|lateral|basal` (N/m) and `cell_adhesion_apical|lateral|basal`
//! (Pa/m), −1 where the cell keeps its type's value ([`crate::mesh::CellOverrides`]), and any extra
//! per-cell field, prefixed `cell_`.
//! Coordinates are written with the shortest representation that parses back to the same `f64`,
//! so a write → read round trip is exact (the reference keeps only 5 significant digits).

use super::{CellField, IoError, write_atomically};
use crate::mesh::{CellKind, CellOverrides, Tissue};
use std::io::Write;
use std::path::Path;

/// Writes `tissue` as a SimuCell3D legacy VTK file (atomically).
pub fn write_simucell3d(path: &Path, tissue: &Tissue, extra: &[CellField<'_>]) -> Result<(), IoError> {
    let n = tissue.len();
    if let Some(f) = extra.iter().find(|f| f.values.len() != n) {
        return Err(IoError::Write {
            path: path.into(),
            source: std::io::Error::other(format!("field {} has {} values for {n} cells", f.name, f.values.len())),
        });
    }
    let meshes: Vec<_> = tissue.cells().iter().map(|c| c.mesh()).collect();
    write_atomically(path, |w| {
        writeln!(w, "# vtk DataFile Version 4.2")?;
        writeln!(w, "tissuefit {} tissue: SimuCell3D cell_data layout, lengths in metres", env!("CARGO_PKG_VERSION"))?;
        writeln!(w, "ASCII\nDATASET UNSTRUCTURED_GRID")?;
        writeln!(w, "POINTS {} double", tissue.node_count())?;
        for m in &meshes {
            for p in m.positions() {
                writeln!(w, "{:e} {:e} {:e}", p.x, p.y, p.z)?;
            }
        }
        let size: usize = meshes.iter().map(|m| 2 + 4 * m.face_count()).sum();
        writeln!(w, "\nCELLS {n} {size}")?;
        let mut base = 0usize;
        for m in &meshes {
            write!(w, "{} {}", 1 + 4 * m.face_count(), m.face_count())?;
            for t in m.triangles() {
                write!(w, " 3 {} {} {}", base + t[0] as usize, base + t[1] as usize, base + t[2] as usize)?;
            }
            writeln!(w)?;
            base += m.node_count();
        }
        writeln!(w, "\nCELL_TYPES {n}")?;
        for _ in 0..n {
            writeln!(w, "42")?;
        }
        let cells = tissue.cells();
        let overrides = cells.iter().any(|c| !c.overrides().is_empty());
        let arrays = 7 + extra.len() + if overrides { 6 } else { 0 };
        writeln!(w, "\nCELL_DATA {n}\nFIELD FieldData {arrays}")?;
        let int_field = |w: &mut dyn Write, name: &str, v: &dyn Fn(usize) -> u32| -> std::io::Result<()> {
            writeln!(w, "{name} 1 {n} int")?;
            for i in 0..n {
                writeln!(w, "{}", v(i))?;
            }
            Ok(())
        };
        let real_field = |w: &mut dyn Write, name: &str, v: &dyn Fn(usize) -> f64| -> std::io::Result<()> {
            writeln!(w, "{name} 1 {n} double")?;
            for i in 0..n {
                writeln!(w, "{:e}", v(i))?;
            }
            Ok(())
        };
        int_field(w, "cell_id", &|i| cells[i].id().0)?;
        int_field(w, "cell_type_id", &|i| cells[i].cell_type())?;
        real_field(w, "cell_area", &|i| meshes[i].area())?;
        real_field(w, "cell_volume", &|i| meshes[i].signed_volume())?;
        int_field(w, "cell_is_static", &|i| u32::from(cells[i].kind() == CellKind::Static))?;
        int_field(w, "cell_kind", &|i| cells[i].kind().code())?;
        real_field(w, "cell_target_volume", &|i| cells[i].target_volume())?;
        if overrides {
            // -1 where the cell keeps its type's value: a NaN would stop VTK's ASCII reader.
            for (name, q, t) in CellOverrides::array_names() {
                let value = |i: usize| cells[i].overrides().values(q)[t.code() as usize].unwrap_or(-1.0);
                real_field(w, &format!("cell_{name}"), &value)?;
            }
        }
        for f in extra {
            let name = if f.name.starts_with("cell_") { f.name.to_string() } else { format!("cell_{}", f.name) };
            real_field(w, &name, &|i| f.values[i])?;
        }
        Ok(())
    })
    .map_err(IoError::from)
}

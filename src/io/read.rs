//! Reading and writing tissue files, dispatched on the file's extension (and content, for reading).

use super::legacy_parse::parse_legacy;
use super::legacy_tissue::tissue_from_grid;
use super::legacy_write::write_simucell3d;
use super::ply::parse_ply;
use super::{CellField, IoError, LengthScale, OutputUnit, TissueFormat, write_vtp_in};
use crate::geometry::{Vec3, bounding_box};
use crate::mesh::Tissue;
use std::path::Path;

/// How to interpret a file.
#[derive(Clone, Debug, Default)]
pub struct ReadOptions {
    /// Metres per file length unit. SimuCell3D files are in metres; image-tool meshes in voxels or µm.
    /// A `.vtp` that records its unit (`length_unit`, as `--output-unit um` writes) is read in it
    /// whatever this says; a different scale given for such a file is an error.
    pub length_scale: LengthScale,
    /// Re-orient every cell's faces consistently and outward (always done for multi-material meshes,
    /// whose winding is unreliable; optional for the others, whose winding is kept as written).
    pub orient: bool,
}

/// A tissue read from a file, with what was noticed on the way.
#[derive(Debug)]
pub struct ReadReport {
    pub tissue: Tissue,
    pub format: TissueFormat,
    /// Things the user should know (unknown cell types, skipped faces, suspicious units).
    pub warnings: Vec<String>,
}

/// Reads a tissue from a legacy VTK (`.vtk`), ParaView PolyData (`.vtp`) or PLY (`.ply`) file.
///
/// Cells with mesh defects (holes, non-manifold edges) are read as they are; `CellMesh::check`
/// reports the defects. Structural problems (truncated file, wrong counts, indices out of range,
/// non-finite coordinates, unknown cell types) are errors naming the file and line.
pub fn read_tissue(path: &Path, options: &ReadOptions) -> Result<ReadReport, IoError> {
    let bytes = super::read_capped(path, super::MAX_TISSUE_FILE)
        .map_err(|source| IoError::Open { path: path.into(), source })?;
    read_tissue_bytes(path, &bytes, options)
}

/// [`read_tissue`] on the file's bytes; `path` names it in errors and its extension picks the format
/// as for a file.
pub fn read_tissue_bytes(path: &Path, bytes: &[u8], options: &ReadOptions) -> Result<ReadReport, IoError> {
    let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
    let head = &bytes[..bytes.len().min(64)];
    let mut warnings = Vec::new();
    let mut recorded_unit = None;
    let (mut tissue, format) =
        if ext.as_deref() == Some("vtp") || head.starts_with(b"<?xml") || head.starts_with(b"<VTKFile") {
            let (tissue, unit) = super::vtp::parse_vtp(path, bytes)?;
            recorded_unit = unit;
            (tissue, TissueFormat::Vtp)
        } else if head.starts_with(b"# vtk") || ext.as_deref() == Some("vtk") {
            let grid = parse_legacy(path, bytes)?;
            tissue_from_grid(path, &grid, &mut warnings)?
        } else if head.starts_with(b"ply") || ext.as_deref() == Some("ply") {
            let (grid, ply_warnings) = parse_ply(path, bytes)?;
            warnings.extend(ply_warnings);
            tissue_from_grid(path, &grid, &mut warnings)?
        } else {
            return Err(IoError::Unsupported {
                path: path.into(),
                message:
                    "unknown file type; tissuefit reads legacy VTK (.vtk), ParaView PolyData (.vtp) and PLY (.ply) \
                          meshes"
                        .into(),
            });
        };
    for cell in tissue.cells() {
        if let Some(node) = cell.mesh().positions().iter().position(|p| !p.iter().all(|v| v.is_finite())) {
            return Err(IoError::parse(
                path,
                None,
                format!("cell {}: node {node} has a non-finite coordinate", cell.id()),
            ));
        }
    }
    if options.orient {
        for cell in tissue.cells_mut() {
            let flipped = cell.orient_outward();
            if flipped > 0 {
                warnings.push(format!("cell {}: {flipped} faces re-oriented", cell.id()));
            }
        }
    }
    match &recorded_unit {
        // Already converted to metres from the file's own unit; the same unit given again is no error.
        Some((unit, metres))
            if !options.length_scale.is_identity() && options.length_scale.0 != Vec3::repeat(*metres) =>
        {
            return Err(IoError::Unsupported {
                path: path.into(),
                message: format!(
                    "the file records its length unit ({unit}) and is read in it, but a length unit of {} was \
                     given too; leave --length-unit (input.length_unit) out for this file",
                    options.length_scale
                ),
            });
        }
        Some(_) => {}
        None if !options.length_scale.is_identity() => tissue.scale(options.length_scale.0),
        None => {}
    }
    for cell in tissue.cells() {
        let (target, volume) = (cell.target_volume(), cell.mesh().signed_volume());
        let ratio = target / volume;
        if volume > 0.0 && ratio.is_finite() && !(1e-3..=1e3).contains(&ratio.abs()) {
            warnings.push(format!(
                "cell {}: its stored target volume {target:.3e} m³ is {ratio:.1e} × its mesh volume {volume:.3e} m³, so a \
                 simulation will drive it there; were the target volumes written in other units than the coordinates \
                 (see --length-unit)?",
                cell.id()
            ));
        }
    }
    let all: Vec<_> = tissue.cells().iter().flat_map(|c| c.mesh().positions().iter().copied()).collect();
    if let Some((lo, hi)) = bounding_box(&all) {
        let extent = (hi - lo).max();
        if extent > 1e-2 {
            warnings.push(format!(
                "the tissue spans {extent:.3e} m; tissuefit works in metres. If the file is in µm or voxels, pass --length-unit (e.g. um, or the voxel size 0.15,0.15,0.235um)"
            ));
        }
    }
    Ok(ReadReport { tissue, format, warnings })
}

/// Writes a tissue; the extension picks the format: `.vtp` (ParaView) or `.vtk` (SimuCell3D legacy).
/// `extra` holds per-cell fields (one value per cell, e.g. pressure).
pub fn write_tissue(path: &Path, tissue: &Tissue, extra: &[CellField<'_>]) -> Result<(), IoError> {
    write_tissue_in(path, tissue, extra, OutputUnit::Metre)
}

/// [`write_tissue`] with lengths in `unit` (see [`super::write_vtp_in`]; `extra` fields as given). A
/// SimuCell3D legacy `.vtk` is in metres by definition (SimuCell3D reads it so): another unit is refused.
pub fn write_tissue_in(path: &Path, tissue: &Tissue, extra: &[CellField<'_>], unit: OutputUnit) -> Result<(), IoError> {
    match path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()).as_deref() {
        Some("vtp") => write_vtp_in(path, tissue, extra, None, unit),
        Some("vtk") if !unit.is_si() => Err(IoError::Unsupported {
            path: path.into(),
            message: format!(
                "a SimuCell3D legacy .vtk is in metres; write .vtp for lengths in {unit}, or leave the output unit at m"
            ),
        }),
        Some("vtk") => write_simucell3d(path, tissue, extra),
        _ => Err(IoError::Unsupported {
            path: path.into(),
            message: "unknown output type; use .vtp (ParaView PolyData) or .vtk (SimuCell3D legacy)".into(),
        }),
    }
}

//! Per-cell morphology: one row of `cells.csv`.

use crate::geometry::Real;
use crate::mesh::CellKind;
use serde::Serialize;

/// Morphology of one body of a tissue (cell, ECM, lumen or nucleus), SI units.
///
/// Flat on purpose: it is one CSV row. The first eight fields are the stable interface of
/// `cells.csv` (DESIGN.md §2); more may be appended. Filled from meshes by
/// [`super::measure_tissue`] and from voxels by [`super::measure_labels()`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CellMorphology {
    /// Cell id (the input label).
    pub cell: u32,
    pub kind: CellKind,
    /// Whether the body never moves (kind `static`): boundary cells of an imaged patch.
    #[serde(rename = "static")]
    pub is_static: bool,
    /// Enclosed volume (m³), signed: negative for an inside-out surface.
    pub volume: Real,
    /// Surface area (m²).
    pub area: Real,
    /// Ψ = π^(1/3)(6V)^(2/3)/A (1 for a sphere).
    pub sphericity: Real,
    /// Coordination number z: number of distinct cells (epithelial or static) in contact.
    pub neighbours: usize,
    /// φ = (own surface area in contact with other cells) / area.
    pub contact_fraction: Real,
    /// Own surface area in contact with other cells (m²), the numerator of φ.
    pub contact_area: Real,
    /// Own surface area in contact with lumen bodies (m²).
    pub lumen_contact_area: Real,
    /// Own surface area in contact with ECM bodies (m²).
    pub ecm_contact_area: Real,
    /// Own surface area in contact with nothing (m²).
    pub free_area: Real,
    /// Area of the faces typed apical, lateral and basal (m²), from the input face types; empty for a
    /// label volume (no face types).
    pub apical_area: Option<Real>,
    pub lateral_area: Option<Real>,
    pub basal_area: Option<Real>,
    /// Semi-axes of the ellipsoid with the same second moments as the solid (m), decreasing.
    pub semi_axis_1: Real,
    pub semi_axis_2: Real,
    pub semi_axis_3: Real,
    /// Longest over shortest semi-axis (≥ 1).
    pub elongation: Real,
    /// Volume centroid (m).
    pub centroid_x: Real,
    pub centroid_y: Real,
    pub centroid_z: Real,
    /// Whether the cell touches a lumen body.
    pub lumen_facing: bool,
    /// Whether the cell faces the exterior (touches the ECM, or, without ECM, has enough free surface).
    pub exterior_facing: bool,
    /// Cells on the shortest lumen→exterior path through this cell (see [`super::layers`]).
    pub layer: Option<u32>,
    /// Whether the cell enters the tissue statistics (cells only; static ones on request).
    pub in_statistics: bool,
    /// Id of the nucleus inside this cell (the largest, when several).
    pub nucleus: Option<u32>,
    /// Number of nuclei whose centroid lies inside this cell.
    pub nuclei: usize,
    /// Volume (m³) and sphericity of that nucleus.
    pub nucleus_volume: Option<Real>,
    pub nucleus_sphericity: Option<Real>,
    /// Distance between the nucleus centroid and the cell centroid (m).
    pub nucleus_offset: Option<Real>,
    /// Intersection over union with the same label in a compared tissue or label volume, on a common
    /// voxel grid (see [`super::compare_shapes`]); empty without a comparison.
    pub iou: Option<Real>,
    /// Deformation χ = 1 − IoU.
    pub chi: Option<Real>,
}

impl CellMorphology {
    /// Whether a body of this kind is a cell (a node of the contact graph): epithelial or static.
    pub fn is_cell_kind(kind: CellKind) -> bool {
        kind.is_cell()
    }

    /// A row of zeros: its serialisation names the columns of `cells.csv` when there is no row.
    pub fn example() -> Self {
        Self {
            cell: 0,
            kind: CellKind::Epithelial,
            is_static: false,
            volume: 0.0,
            area: 0.0,
            sphericity: 0.0,
            neighbours: 0,
            contact_fraction: 0.0,
            contact_area: 0.0,
            lumen_contact_area: 0.0,
            ecm_contact_area: 0.0,
            free_area: 0.0,
            apical_area: None,
            lateral_area: None,
            basal_area: None,
            semi_axis_1: 0.0,
            semi_axis_2: 0.0,
            semi_axis_3: 0.0,
            elongation: 0.0,
            centroid_x: 0.0,
            centroid_y: 0.0,
            centroid_z: 0.0,
            lumen_facing: false,
            exterior_facing: false,
            layer: None,
            in_statistics: false,
            nucleus: None,
            nuclei: 0,
            nucleus_volume: None,
            nucleus_sphericity: None,
            nucleus_offset: None,
            iou: None,
            chi: None,
        }
    }
}

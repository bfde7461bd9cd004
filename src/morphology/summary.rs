//! Tissue-level morphology: `summary.json`.

use super::{CellMorphology, ContactMorphology, Distribution};
use crate::geometry::Real;
use crate::mesh::CellKind;
use serde::Serialize;
use std::collections::{BTreeMap, HashMap};

/// Number of bodies of each kind in the measured tissue.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct BodyCounts {
    pub total: usize,
    pub epithelial: usize,
    #[serde(rename = "static")]
    pub static_cells: usize,
    pub ecm: usize,
    pub lumen: usize,
    pub nucleus: usize,
}

/// How exterior-facing cells were decided for the layer count (see [`super::layers`]).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ExteriorRule {
    /// The tissue has an ECM body: exterior-facing cells touch it.
    TouchesEcm,
    /// No ECM body: exterior-facing cells have at least the given free-area fraction.
    FreeSurfaceFraction,
}

/// How the contacts were found (see [`super`]).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ContactRule {
    /// A face touches a body when its centroid lies within the contact distance δ of its surface.
    Distance,
    /// The input's interface labels: each face names the body on its other side (multi-material
    /// meshes), so contact areas and rims are the file's own, exact.
    InterfaceLabels,
    /// Voxel-face adjacency of a label volume.
    VoxelFaces,
}

/// Tissue summary. The keys `cells`, `mean_sphericity`, `mean_contact_fraction`, `mean_coordination` and
/// `layers` are the stable interface (DESIGN.md §2); the others may grow. Means and `statistics` cover
/// the cells with `in_statistics` (epithelial; static too with `include_static`); ECM, lumen and nuclei
/// are never cells. A mean of no cells is `null`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MorphologySummary {
    /// Number of cells in the statistics.
    pub cells: usize,
    pub mean_sphericity: Option<Real>,
    pub mean_contact_fraction: Option<Real>,
    /// Mean coordination number ⟨z⟩.
    pub mean_coordination: Option<Real>,
    /// Layer count N = max over cells of N(c); `null` without a lumen or without exterior-facing cells.
    pub layers: Option<u32>,
    /// Mean over lumen-facing cells of the shortest lumen→exterior path length (cells).
    pub mean_layers: Option<Real>,
    /// Mean contact angle (degrees) over cell–cell contacts with a free rim that involve a counted cell.
    pub mean_contact_angle_deg: Option<Real>,
    /// Mean far-field contact angle (degrees) over the same contacts, where it could be read (see
    /// [`super::far_field`]).
    pub mean_far_field_angle_deg: Option<Real>,
    /// Contact distance δ used (m); `null` when the contacts were not found by distance (`contact_rule`).
    pub contact_distance: Option<Real>,
    /// How the contacts were found.
    pub contact_rule: ContactRule,
    /// Mean deformation χ = 1 − IoU over the counted cells that were compared (see
    /// [`super::compare_shapes`]); `null` without a comparison.
    pub mean_chi: Option<Real>,
    pub include_static: bool,
    pub bodies: BodyCounts,
    /// Edges of the contact graph: touching pairs of cells (epithelial or static).
    pub cell_contacts: usize,
    /// All touching pairs, ECM and lumen included (rows of `contacts.csv`).
    pub contacts: usize,
    pub lumen_facing_cells: usize,
    pub exterior_facing_cells: usize,
    pub exterior_rule: ExteriorRule,
    /// Cells that hold at least one nucleus.
    pub cells_with_nucleus: usize,
    /// Per-metric statistics over the counted cells (`contact_angle_deg`: over the contacts above).
    pub statistics: BTreeMap<&'static str, Distribution>,
}

impl MorphologySummary {
    /// Summarises per-cell and per-contact morphology, from meshes or from a label volume alike.
    pub fn from_rows(
        cells: &[CellMorphology],
        contacts: &[ContactMorphology],
        contact_rule: ContactRule,
        contact_distance: Option<Real>,
        include_static: bool,
        exterior_rule: ExteriorRule,
    ) -> Self {
        let counted: Vec<&CellMorphology> = cells.iter().filter(|c| c.in_statistics).collect();
        let stat = |f: &dyn Fn(&CellMorphology) -> Option<Real>| Distribution::of(counted.iter().filter_map(|c| f(c)));
        let mut statistics = BTreeMap::new();
        statistics.insert("volume", stat(&|c| Some(c.volume)));
        statistics.insert("area", stat(&|c| Some(c.area)));
        statistics.insert("sphericity", stat(&|c| Some(c.sphericity)));
        statistics.insert("elongation", stat(&|c| Some(c.elongation)));
        statistics.insert("neighbours", stat(&|c| Some(c.neighbours as Real)));
        statistics.insert("contact_fraction", stat(&|c| Some(c.contact_fraction)));
        statistics.insert("contact_area", stat(&|c| Some(c.contact_area)));
        statistics.insert("layer", stat(&|c| c.layer.map(Real::from)));
        statistics.insert("nucleus_sphericity", stat(&|c| c.nucleus_sphericity));
        statistics.insert("nucleus_offset", stat(&|c| c.nucleus_offset));
        statistics.insert("chi", stat(&|c| c.chi));

        let counted_ids: HashMap<u32, bool> = cells.iter().map(|c| (c.cell, c.in_statistics)).collect();
        let is_cell = |k: CellKind| CellMorphology::is_cell_kind(k);
        let cell_contacts: Vec<&ContactMorphology> =
            contacts.iter().filter(|c| is_cell(c.kind_a) && is_cell(c.kind_b)).collect();
        let counted_contacts = || {
            cell_contacts
                .iter()
                .filter(|c| counted_ids.get(&c.cell_a) == Some(&true) || counted_ids.get(&c.cell_b) == Some(&true))
        };
        let angles = Distribution::of(counted_contacts().filter_map(|c| c.contact_angle_deg));
        let far_field = Distribution::of(counted_contacts().filter_map(|c| c.far_field_angle_deg));

        let mut bodies = BodyCounts { total: cells.len(), ..Default::default() };
        for c in cells {
            match c.kind {
                CellKind::Epithelial => bodies.epithelial += 1,
                CellKind::Static => bodies.static_cells += 1,
                CellKind::Ecm => bodies.ecm += 1,
                CellKind::Lumen => bodies.lumen += 1,
                CellKind::Nucleus => bodies.nucleus += 1,
            }
        }
        let graph_cells = || cells.iter().filter(|c| is_cell(c.kind));
        let lumen_facing: Vec<&CellMorphology> = graph_cells().filter(|c| c.lumen_facing).collect();
        let mean_layers = Distribution::of(lumen_facing.iter().filter_map(|c| c.layer.map(Real::from))).mean;
        Self {
            cells: counted.len(),
            mean_sphericity: statistics["sphericity"].mean,
            mean_contact_fraction: statistics["contact_fraction"].mean,
            mean_coordination: statistics["neighbours"].mean,
            layers: graph_cells().filter_map(|c| c.layer).max(),
            mean_layers,
            mean_contact_angle_deg: angles.mean,
            mean_far_field_angle_deg: far_field.mean,
            contact_distance,
            contact_rule,
            mean_chi: statistics["chi"].mean,
            include_static,
            bodies,
            cell_contacts: cell_contacts.len(),
            contacts: contacts.len(),
            lumen_facing_cells: lumen_facing.len(),
            exterior_facing_cells: graph_cells().filter(|c| c.exterior_facing).count(),
            exterior_rule,
            cells_with_nucleus: graph_cells().filter(|c| c.nucleus.is_some()).count(),
            statistics: {
                statistics.insert("contact_angle_deg", angles);
                statistics.insert("far_field_angle_deg", far_field);
                statistics
            },
        }
    }
}

//! The model's own mechanics of a simulated tissue, as the truth that per-cell maps are compared
//! with: every cell's parameters (its cell type's with its own tensions and adhesions laid over them,
//! [`crate::mesh::CellOverrides`]) and pressure (`model_cells.csv`), and every touching pair's
//! interface tension T_ab (`model_interfaces.csv`). The simulate stage writes both beside the final
//! tissue's measurement, in SI units with mN/m and µm² next to them.
//!
//! T_ab is what the model's energy makes of the interface, per unit area: coupled contacts tie the
//! two cells' faces into one sheet pulled by both, T_ab = γ_a + γ_b; spring contacts lower that by
//! the adhesion energy of the two sides, T_ab = γ_a + γ_b − (ω_a + ω_b)·c²/4 (the well depth
//! ωc²/4 per side, [`crate::mechanics::FaceParams::adhesion_well_depth`]). Each side's γ and ω are
//! those of the face type that faces the partner: lateral towards a cell (apical when the cell has
//! no lateral faces at all, as without polarity), apical towards a lumen, basal towards the ECM; a
//! lumen or ECM body contributes its apical values.

use crate::geometry::Real;
use crate::mechanics::{ContactModel, Parameters};
use crate::mesh::{Cell, CellKind, FaceType, Tissue};
use crate::morphology::Morphology;
use serde::Serialize;

/// One cell of `model_cells.csv`.
#[derive(Clone, Debug, Default, Serialize)]
pub struct ModelCellRow {
    pub cell: u32,
    pub kind: String,
    pub cell_type: u32,
    /// Whether the cell has its own tensions or adhesions (else its type's).
    pub own_values: bool,
    /// p = min(−K ln(V/V0), p_max) at the final state (Pa).
    pub pressure_pa: Real,
    pub surface_tension_apical_n_per_m: Real,
    pub surface_tension_lateral_n_per_m: Real,
    pub surface_tension_basal_n_per_m: Real,
    pub surface_tension_apical_mn_per_m: Real,
    pub surface_tension_lateral_mn_per_m: Real,
    pub surface_tension_basal_mn_per_m: Real,
    pub adhesion_apical_pa_per_m: Real,
    pub adhesion_lateral_pa_per_m: Real,
    pub adhesion_basal_pa_per_m: Real,
}

/// One touching pair of `model_interfaces.csv`.
#[derive(Clone, Debug, Default, Serialize)]
pub struct ModelInterfaceRow {
    pub cell_a: u32,
    pub cell_b: u32,
    /// The contact area as measured (`contacts.csv`), m² and µm².
    pub area_m2: Real,
    pub area_um2: Real,
    /// T_ab (N/m and mN/m).
    pub tension_n_per_m: Real,
    pub tension_mn_per_m: Real,
    /// "coupling" or "spring".
    pub contact_model: &'static str,
}

/// The face type of `cell` that faces a body of kind `partner`.
fn facing(cell: &Cell, partner: CellKind) -> FaceType {
    if !cell.kind().is_cell() {
        return FaceType::Apical;
    }
    match partner {
        CellKind::Lumen => FaceType::Apical,
        CellKind::Ecm => FaceType::Basal,
        _ if cell.face_types().contains(&FaceType::Lateral) => FaceType::Lateral,
        _ => FaceType::Apical,
    }
}

/// The two tables for `tissue` at its final state, with each cell's pressure from `pressure` (tissue
/// order) and the touching pairs of `morphology`.
pub fn model_tables(
    tissue: &Tissue,
    params: &Parameters,
    pressure: &[Real],
    morphology: &Morphology,
) -> (Vec<ModelCellRow>, Vec<ModelInterfaceRow>) {
    let mut cells = Vec::with_capacity(tissue.len());
    for (c, cell) in tissue.cells().iter().enumerate() {
        let Some(p) = params.parameters_of(cell) else { continue };
        let [ga, gl, gb] = FaceType::ALL.map(|t| p.faces.get(t).surface_tension);
        let [wa, wl, wb] = FaceType::ALL.map(|t| p.faces.get(t).adhesion);
        cells.push(ModelCellRow {
            cell: cell.id().0,
            kind: cell.kind().name().to_owned(),
            cell_type: cell.cell_type(),
            own_values: !cell.overrides().is_empty(),
            pressure_pa: pressure.get(c).copied().unwrap_or(Real::NAN),
            surface_tension_apical_n_per_m: ga,
            surface_tension_lateral_n_per_m: gl,
            surface_tension_basal_n_per_m: gb,
            surface_tension_apical_mn_per_m: ga * 1e3,
            surface_tension_lateral_mn_per_m: gl * 1e3,
            surface_tension_basal_mn_per_m: gb * 1e3,
            adhesion_apical_pa_per_m: wa,
            adhesion_lateral_pa_per_m: wl,
            adhesion_basal_pa_per_m: wb,
        });
    }
    let cutoff = params.numerics.contact_cutoff;
    let model = params.numerics.contact_model;
    let mut interfaces = Vec::new();
    for contact in &morphology.contacts {
        let ids = [contact.cell_a, contact.cell_b].map(crate::mesh::CellId);
        let [Some(a), Some(b)] = ids.map(|id| tissue.cell(id)) else { continue };
        if a.kind() == CellKind::Nucleus || b.kind() == CellKind::Nucleus {
            continue;
        }
        let [Some(pa), Some(pb)] = [a, b].map(|c| params.parameters_of(c)) else { continue };
        let (fa, fb) = (pa.faces.get(facing(a, b.kind())), pb.faces.get(facing(b, a.kind())));
        // Coupling ties two cells; a cell and a lumen or the ECM always meet by springs.
        let coupled = model == ContactModel::Coupling && a.kind().is_cell() && b.kind().is_cell();
        let adhesion = if coupled { 0.0 } else { fa.adhesion_well_depth(cutoff) + fb.adhesion_well_depth(cutoff) };
        let tension = fa.surface_tension + fb.surface_tension - adhesion;
        interfaces.push(ModelInterfaceRow {
            cell_a: contact.cell_a,
            cell_b: contact.cell_b,
            area_m2: contact.area,
            area_um2: contact.area * 1e12,
            tension_n_per_m: tension,
            tension_mn_per_m: tension * 1e3,
            contact_model: if coupled { "coupling" } else { "spring" },
        });
    }
    (cells, interfaces)
}

//! Internal forces of every cell: pressure, area elasticity, surface tension and bending, each the
//! exact negative gradient of its energy; parallel over cells, deterministic.
//!
//! Per cell, one pass over the faces assembles the three area-based terms (they share ∇A_f and the
//! area vector): node i of face f gets (p/3)·A_f n̂_f − (γ_f + dU_area/dA)·∇_i A_f. Bending runs over
//! the cached hinges, skipping those with zero stiffness (exactly zero energy and force). Energies are
//! reported per term, per cell and for the tissue. Contact forces (inter-cell terms) are added on
//! top of these per-cell buffers by the contact stage.

use super::area_elasticity::{area_elasticity_energy, target_area};
use super::bending::{Hinge, add_bending_forces, build_hinges};
use super::cell_geometry::CellGeometry;
use super::pressure::pressure_energy;
use super::tension::tension_energy;
use super::{CellTypeParams, Parameters};
use crate::geometry::{Real, Vec3, triangle_area_gradients};
use crate::mesh::{Cell, CellId, CellKind, FaceType, Tissue};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Energy of each term (J).
#[derive(Copy, Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct EnergyTerms {
    pub pressure: Real,
    pub area_elasticity: Real,
    pub tension: Real,
    pub bending: Real,
    /// Contact (adhesion and repulsion) energy of this cell's nodes near other cells.
    pub contact: Real,
}

impl EnergyTerms {
    /// Names of the terms, in field order.
    pub const NAMES: [&'static str; 5] = [
        CellTerm::Pressure.name(),
        CellTerm::AreaElasticity.name(),
        CellTerm::Tension.name(),
        CellTerm::Bending.name(),
        "contact",
    ];

    /// Sum of all terms.
    pub fn total(&self) -> Real {
        self.pressure + self.area_elasticity + self.tension + self.bending + self.contact
    }

    /// The terms as an array, in [`EnergyTerms::NAMES`] order.
    pub fn values(&self) -> [Real; 5] {
        [self.pressure, self.area_elasticity, self.tension, self.bending, self.contact]
    }
}

impl std::ops::AddAssign for EnergyTerms {
    fn add_assign(&mut self, o: Self) {
        self.pressure += o.pressure;
        self.area_elasticity += o.area_elasticity;
        self.tension += o.tension;
        self.bending += o.bending;
        self.contact += o.contact;
    }
}

/// Which terms to include (all by default; single terms for gradient checks and diagnostics).
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct TermSet {
    pub pressure: bool,
    pub area_elasticity: bool,
    pub tension: bool,
    pub bending: bool,
}

impl TermSet {
    pub const ALL: TermSet = TermSet { pressure: true, area_elasticity: true, tension: true, bending: true };
    pub const NONE: TermSet = TermSet { pressure: false, area_elasticity: false, tension: false, bending: false };

    /// Only `term`.
    pub fn only(term: CellTerm) -> TermSet {
        let mut t = TermSet::NONE;
        match term {
            CellTerm::Pressure => t.pressure = true,
            CellTerm::AreaElasticity => t.area_elasticity = true,
            CellTerm::Tension => t.tension = true,
            CellTerm::Bending => t.bending = true,
        }
        t
    }
}

/// An energy term computed per cell (all but contact, which needs the other cells): the choices of
/// [`TermSet::only`], so a misspelt term cannot select nothing.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CellTerm {
    Pressure,
    AreaElasticity,
    Tension,
    Bending,
}

impl CellTerm {
    /// Every per-cell term, in [`EnergyTerms::NAMES`] order.
    pub const ALL: [CellTerm; 4] = [CellTerm::Pressure, CellTerm::AreaElasticity, CellTerm::Tension, CellTerm::Bending];

    /// The term's name, as in [`EnergyTerms::NAMES`] and the `energy_*` columns.
    pub const fn name(self) -> &'static str {
        match self {
            CellTerm::Pressure => "pressure",
            CellTerm::AreaElasticity => "area_elasticity",
            CellTerm::Tension => "tension",
            CellTerm::Bending => "bending",
        }
    }
}

impl std::fmt::Display for CellTerm {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl Default for TermSet {
    fn default() -> Self {
        TermSet::ALL
    }
}

/// Reusable per-cell buffers and results of the last evaluation.
#[derive(Clone, Debug, Default)]
pub struct CellForces {
    /// Nodal forces (N), one per node.
    pub forces: Vec<Vec3>,
    pub geometry: CellGeometry,
    pub energy: EnergyTerms,
    /// Pressure p (Pa) at the current volume.
    pub pressure: Real,
    hinges: Vec<Hinge>,
    hinge_generation: u64,
}

impl CellForces {
    /// Computes the internal forces and energies of `cell` with parameters `p`.
    pub fn compute(&mut self, cell: &Cell, p: &CellTypeParams, terms: TermSet) {
        let mesh = cell.mesh();
        let kb = FaceType::ALL.map(|t| p.faces.get(t).bending_modulus);
        // Hinges are built only when bending acts (k_b = 0 everywhere, as in the growth benchmark,
        // contributes exactly nothing); the cache is rebuilt lazily once it does.
        let bending_on = terms.bending && kb.iter().any(|&k| k != 0.0);
        if bending_on && self.hinge_generation != mesh.topology_generation() {
            self.hinges = build_hinges(mesh);
            self.hinge_generation = mesh.topology_generation();
        }
        self.geometry.update(mesh);
        let g = &self.geometry;
        let face_types = cell.face_types();
        let (pressure, u_pressure) = pressure_energy(g.volume, cell.target_volume(), p.bulk_modulus, p.max_pressure);
        let a0 = target_area(p.target_isoperimetric_ratio, cell.target_volume());
        let (u_area, du_da) = area_elasticity_energy(g.area, a0, p.area_elasticity);
        let gamma = FaceType::ALL.map(|t| p.faces.get(t).surface_tension);

        self.pressure = pressure;
        self.energy = EnergyTerms {
            pressure: if terms.pressure { u_pressure } else { 0.0 },
            area_elasticity: if terms.area_elasticity { u_area } else { 0.0 },
            tension: if terms.tension { tension_energy(&g.areas, face_types, gamma) } else { 0.0 },
            bending: 0.0,
            contact: 0.0,
        };

        let positions = mesh.positions();
        self.forces.clear();
        self.forces.resize(positions.len(), Vec3::zeros());
        // Area-based terms in one pass: f_i += (p/3)·A_f n̂_f − c_f ∇_i A_f, c_f = γ_f + dU_area/dA.
        let p_third = if terms.pressure { pressure / 3.0 } else { 0.0 };
        let tension_on = if terms.tension { 1.0 } else { 0.0 };
        let extra = if terms.area_elasticity { du_da } else { 0.0 };
        let coefficient = gamma.map(|gm| tension_on * gm + extra);
        if p_third != 0.0 || coefficient.iter().any(|&c| c != 0.0) {
            for (f, t) in mesh.triangles().iter().enumerate() {
                let [i, j, k] = t.map(|n| n as usize);
                let c = coefficient[face_types[f].code() as usize];
                let push = p_third * g.area_vectors[f];
                // c·∇A: the area gradients of the normal scaled by c.
                let grad = triangle_area_gradients(&positions[i], &positions[j], &positions[k], &(c * g.normals[f]));
                self.forces[i] += push - grad[0];
                self.forces[j] += push - grad[1];
                self.forces[k] += push - grad[2];
            }
        }
        if bending_on {
            self.energy.bending = add_bending_forces(
                positions,
                mesh.triangles(),
                &g.normals,
                &g.areas,
                face_types,
                kb,
                &self.hinges,
                &mut self.forces,
            );
        }
    }

    /// Whether every force component is finite.
    pub fn all_finite(&self) -> bool {
        self.forces.iter().all(|f| f.iter().all(|c| c.is_finite()))
    }
}

/// Forces and energies of a whole tissue, one [`CellForces`] per cell in tissue order.
#[derive(Clone, Debug, Default)]
pub struct TissueForces {
    pub cells: Vec<CellForces>,
}

/// A cell refers to a parameter set that does not exist.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error(
    "cell {cell} has cell_type {cell_type}, but the parameters define {defined} cell types (0..{}); add [[cell_types]] entries or relabel the cells",
    defined.saturating_sub(1)
)]
pub struct UnknownCellType {
    pub cell: CellId,
    pub cell_type: u32,
    pub defined: usize,
}

/// The parameter set of every cell, in tissue order; errors on a cell whose type is undefined.
pub fn cell_parameters<'p>(
    tissue: &Tissue,
    params: &'p Parameters,
) -> Result<Vec<&'p CellTypeParams>, UnknownCellType> {
    tissue
        .cells()
        .iter()
        .map(|c| {
            params.cell_type(c.cell_type()).ok_or(UnknownCellType {
                cell: c.id(),
                cell_type: c.cell_type(),
                defined: params.cell_types.len(),
            })
        })
        .collect()
}

/// Gives every cell the kind its cell type declares in the parameters (`[[cell_types]] kind`), which
/// wins over the kind a tissue file stored or its reader inferred (SimuCell3D files without
/// `cell_kind` have their kind guessed from `cell_type_id`). One exception: a cell the file marks
/// static (`cell_is_static`, e.g. the boundary of an imaged patch) stays static when its type is
/// epithelial, as SimuCell3D does. Returns one line per cell type whose cells changed kind, for the
/// caller to show. Cells whose type is undefined are left alone ([`cell_parameters`] reports them).
pub fn apply_configured_kinds(tissue: &mut Tissue, params: &Parameters) -> Vec<String> {
    let mut changed: Vec<(u32, CellKind, CellKind, usize)> = Vec::new();
    for cell in tissue.cells_mut() {
        let Some(p) = params.cell_type(cell.cell_type()) else { continue };
        let (from, to) = (cell.kind(), p.kind);
        if from == to || (from == CellKind::Static && to == CellKind::Epithelial) {
            continue;
        }
        cell.set_kind(to);
        match changed.iter_mut().find(|(t, f, k, _)| (*t, *f, *k) == (cell.cell_type(), from, to)) {
            Some(entry) => entry.3 += 1,
            None => changed.push((cell.cell_type(), from, to, 1)),
        }
    }
    changed
        .into_iter()
        .map(|(t, from, to, n)| {
            let name = params.cell_type(t).map_or("", |p| p.name.as_str());
            format!(
                "cell type {t} ({name}): {n} cell(s) read as {} run as {} as the configuration says",
                from.name(),
                to.name()
            )
        })
        .collect()
}

impl TissueForces {
    /// Computes every cell's internal forces in parallel (each cell independently, so the result
    /// does not depend on the thread count). `cell_params[i]` is the parameter set of cell i.
    pub fn compute(&mut self, tissue: &Tissue, cell_params: &[&CellTypeParams], terms: TermSet) {
        self.cells.resize_with(tissue.len(), CellForces::default);
        self.cells
            .par_iter_mut()
            .zip(tissue.cells().par_iter())
            .zip(cell_params.par_iter())
            .for_each(|((work, cell), p)| work.compute(cell, p, terms));
    }

    /// Sum of all cells' energies, added in cell order (deterministic).
    pub fn energy(&self) -> EnergyTerms {
        let mut e = EnergyTerms::default();
        for c in &self.cells {
            e += c.energy;
        }
        e
    }
}

//! Internal forces of every cell: pressure, area elasticity, surface tension and bending, each the
//! exact negative gradient of its energy; parallel over cells, deterministic.
//!
//! Each term lives in its own file with its energy, its force and their formulas (`pressure.rs`,
//! `area_elasticity.rs`, `tension.rs`, `bending.rs`); this file only orchestrates. [`CellTerm`]
//! lists the terms, and [`CellForces::compute`] runs, per cell:
//!
//! 1. every acting term's per-cell preparation (one match on [`CellTerm`]), which returns its energy
//!    and what it adds to the shared face pass ([`Prepared`]);
//! 2. the shared pass over the faces. The terms that act through the face areas and the volume only
//!    (pressure, area elasticity, tension) share it, for speed: their coefficients are summed per
//!    cell (p = −Σ ∂U/∂V, c_f = Σ ∂U/∂A_f by face type) and node i of face f gets
//!    (p/3)·A_f n̂_f − c_f ∇_i A_f, one area gradient per face whatever the number of terms;
//! 3. the passes of the terms with a geometry of their own (bending, over the hinges), which add
//!    their forces on top (a second match on [`CellTerm`]).
//!
//! Energies are reported per term, per cell and for the tissue. Contact forces (inter-cell terms)
//! are added on top of these per-cell buffers by the contact stage. ARCHITECTURE.md, "Adding an
//! energy term", says what a new term touches.

use super::bending::BendingCache;
use super::cell_geometry::CellGeometry;
use super::{CellTypeParams, Parameters, area_elasticity, pressure, tension};
use crate::geometry::{Real, Vec3};
use crate::mesh::{Cell, CellId, CellKind, Tissue};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Energy of each term (J). The fields are the file formats' (checkpoints encode them in this
/// order, `stats.csv` has a column per field): the per-cell terms in [`CellTerm::ALL`] order, then
/// contact.
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
    /// How many terms: every [`CellTerm`], and contact.
    pub const COUNT: usize = CellTerm::ALL.len() + 1;

    /// Names of the terms, in field order: [`CellTerm::ALL`]'s, then `contact`.
    pub const NAMES: [&'static str; Self::COUNT] = {
        let mut names = ["contact"; Self::COUNT];
        let mut i = 0;
        while i < CellTerm::ALL.len() {
            names[i] = CellTerm::ALL[i].name();
            i += 1;
        }
        names
    };

    /// The energy of a per-cell term.
    pub fn term(&self, term: CellTerm) -> Real {
        match term {
            CellTerm::Pressure => self.pressure,
            CellTerm::AreaElasticity => self.area_elasticity,
            CellTerm::Tension => self.tension,
            CellTerm::Bending => self.bending,
        }
    }

    /// The energy of a per-cell term, to set.
    pub fn term_mut(&mut self, term: CellTerm) -> &mut Real {
        match term {
            CellTerm::Pressure => &mut self.pressure,
            CellTerm::AreaElasticity => &mut self.area_elasticity,
            CellTerm::Tension => &mut self.tension,
            CellTerm::Bending => &mut self.bending,
        }
    }

    /// Sum of all terms, added in [`EnergyTerms::NAMES`] order.
    pub fn total(&self) -> Real {
        let [first, rest @ ..] = self.values();
        rest.iter().fold(first, |sum, e| sum + e)
    }

    /// The terms as an array, in [`EnergyTerms::NAMES`] order.
    pub fn values(&self) -> [Real; Self::COUNT] {
        let mut values = [self.contact; Self::COUNT];
        for (value, term) in values.iter_mut().zip(CellTerm::ALL) {
            *value = self.term(term);
        }
        values
    }
}

impl std::ops::AddAssign for EnergyTerms {
    fn add_assign(&mut self, o: Self) {
        for term in CellTerm::ALL {
            *self.term_mut(term) += o.term(term);
        }
        self.contact += o.contact;
    }
}

/// An energy term computed per cell (all but contact, which needs the other cells): the choices of
/// [`TermSet::only`], so a misspelt term cannot select nothing. The one list of the terms: a new
/// term is a variant here (and in [`CellTerm::ALL`]), and the matches on it say what else it needs.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CellTerm {
    Pressure,
    AreaElasticity,
    Tension,
    Bending,
}

impl CellTerm {
    /// Every per-cell term, in declaration order (a term's position is its discriminant, which
    /// [`TermSet`] uses as its bit), and in [`EnergyTerms::NAMES`] order.
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

    /// The term's bit in a [`TermSet`].
    const fn bit(self) -> u32 {
        1 << self as u32
    }
}

impl std::fmt::Display for CellTerm {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Which terms to include (all by default; single terms for gradient checks and diagnostics): a
/// set of [`CellTerm`]s.
#[derive(Copy, Clone, PartialEq, Eq)]
pub struct TermSet(u32);

impl TermSet {
    pub const ALL: TermSet = {
        let mut bits = 0;
        let mut i = 0;
        while i < CellTerm::ALL.len() {
            bits |= CellTerm::ALL[i].bit();
            i += 1;
        }
        TermSet(bits)
    };
    pub const NONE: TermSet = TermSet(0);

    /// Only `term`.
    pub const fn only(term: CellTerm) -> TermSet {
        TermSet(term.bit())
    }

    /// This set and `term`.
    pub const fn with(self, term: CellTerm) -> TermSet {
        TermSet(self.0 | term.bit())
    }

    /// Whether `term` is in the set.
    pub const fn contains(self, term: CellTerm) -> bool {
        self.0 & term.bit() != 0
    }

    /// The terms in the set, in [`CellTerm::ALL`] order.
    pub fn iter(self) -> impl Iterator<Item = CellTerm> {
        CellTerm::ALL.into_iter().filter(move |&t| self.contains(t))
    }
}

impl Default for TermSet {
    fn default() -> Self {
        TermSet::ALL
    }
}

impl std::fmt::Debug for TermSet {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_set().entries(self.iter().map(CellTerm::name)).finish()
    }
}

/// What one term contributes to a cell, from its per-cell preparation (before any force is
/// added): its energy, and its coefficients in the shared pass over the faces. A term with a pass
/// of its own leaves the coefficients zero ([`Prepared::NONE`]).
#[derive(Copy, Clone, Debug, PartialEq)]
pub(super) struct Prepared {
    /// The term's energy U (J).
    pub energy: Real,
    /// −∂U/∂V (Pa): each face pushes its nodes by (p/3)·A_f n̂_f ([`pressure::face_force`]).
    pub pressure: Real,
    /// ∂U/∂A_f (N/m) by face-type code: each face pulls its nodes by −c ∇_i A_f
    /// ([`tension::face_forces`]).
    pub tension: [Real; 3],
}

impl Prepared {
    /// Zero energy, nothing in the face pass.
    pub const NONE: Prepared = Prepared { energy: 0.0, pressure: 0.0, tension: [0.0; 3] };
}

/// Reusable per-cell buffers and results of the last evaluation.
#[derive(Clone, Debug, Default)]
pub struct CellForces {
    /// Nodal forces (N), one per node.
    pub forces: Vec<Vec3>,
    pub geometry: CellGeometry,
    pub energy: EnergyTerms,
    /// Pressure p (Pa) at the current volume (whichever terms act).
    pub pressure: Real,
    bending: BendingCache,
}

impl CellForces {
    /// Computes the internal forces and energies of `cell` with parameters `p`.
    pub fn compute(&mut self, cell: &Cell, p: &CellTypeParams, terms: TermSet) {
        let mesh = cell.mesh();
        self.geometry.update(mesh);
        let g = &self.geometry;
        let face_types = cell.face_types();
        let (pressure, u_pressure) = pressure::cell_pressure(cell, p, g.volume);
        self.pressure = pressure;

        // 1. Each acting term's energy and its coefficients in the face pass, summed over the terms.
        self.energy = EnergyTerms::default();
        let mut pass = Prepared::NONE;
        for term in terms.iter() {
            let prepared = match term {
                CellTerm::Pressure => pressure::prepare(pressure, u_pressure),
                CellTerm::AreaElasticity => area_elasticity::prepare(cell, p, g),
                CellTerm::Tension => tension::prepare(p, g, face_types),
                CellTerm::Bending => Prepared::NONE, // its own pass, below
            };
            *self.energy.term_mut(term) = prepared.energy;
            pass.pressure += prepared.pressure;
            for (c, t) in pass.tension.iter_mut().zip(prepared.tension) {
                *c += t;
            }
        }

        // 2. The face pass: f_i += (p/3)·A_f n̂_f − c_f ∇_i A_f.
        let positions = mesh.positions();
        self.forces.clear();
        self.forces.resize(positions.len(), Vec3::zeros());
        let p_third = pass.pressure / 3.0;
        if p_third != 0.0 || pass.tension.iter().any(|&c| c != 0.0) {
            for (f, t) in mesh.triangles().iter().enumerate() {
                let [i, j, k] = t.map(|n| n as usize);
                let push = pressure::face_force(p_third, &g.area_vectors[f]);
                let c = pass.tension[face_types[f].code() as usize];
                let pull = tension::face_forces(c, &positions[i], &positions[j], &positions[k], &g.normals[f]);
                self.forces[i] += push + pull[0];
                self.forces[j] += push + pull[1];
                self.forces[k] += push + pull[2];
            }
        }

        // 3. The terms with a pass of their own.
        for term in terms.iter() {
            match term {
                CellTerm::Pressure | CellTerm::AreaElasticity | CellTerm::Tension => {} // in the face pass
                CellTerm::Bending => {
                    *self.energy.term_mut(term) = self.bending.add_forces(cell, p, &self.geometry, &mut self.forces);
                }
            }
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

/// The parameter set of every cell, in tissue order: its cell type's, with the cell's own tensions
/// and adhesions ([`crate::mesh::CellOverrides`]) in place of the type's; errors on a cell whose
/// type is undefined.
pub fn cell_parameters(tissue: &Tissue, params: &Parameters) -> Result<Vec<CellTypeParams>, UnknownCellType> {
    tissue
        .cells()
        .iter()
        .map(|c| {
            params.parameters_of(c).ok_or(UnknownCellType {
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
    pub fn compute(&mut self, tissue: &Tissue, cell_params: &[CellTypeParams], terms: TermSet) {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_terms_place_in_the_list_is_its_bit_its_name_and_its_energy_field() {
        for (i, term) in CellTerm::ALL.into_iter().enumerate() {
            assert_eq!(term as usize, i, "{term}: CellTerm::ALL must list the variants in declaration order");
            assert_eq!(EnergyTerms::NAMES[i], term.name());
            let mut e = EnergyTerms::default();
            *e.term_mut(term) = 2.5;
            assert_eq!(e.term(term), 2.5);
            assert_eq!(e.values().iter().position(|&v| v == 2.5), Some(i), "{term}");
            assert_eq!(e.total(), 2.5);
            assert_eq!(TermSet::only(term).iter().collect::<Vec<_>>(), [term]);
            assert!(TermSet::ALL.contains(term) && !TermSet::NONE.contains(term));
        }
        assert_eq!(EnergyTerms::NAMES.last(), Some(&"contact"));
        assert_eq!(TermSet::ALL.iter().collect::<Vec<_>>(), CellTerm::ALL);
        let two = TermSet::only(CellTerm::Tension).with(CellTerm::Pressure);
        assert_eq!(two.iter().collect::<Vec<_>>(), [CellTerm::Pressure, CellTerm::Tension]);
        assert_eq!(format!("{two:?}"), r#"{"pressure", "tension"}"#);
    }

    /// The fields (which the files encode, in field order) are the terms of `NAMES`, in its order.
    #[test]
    fn energy_fields_are_the_names_in_order() {
        let e = EnergyTerms { pressure: 1.0, area_elasticity: 2.0, tension: 3.0, bending: 4.0, contact: 5.0 };
        let json = serde_json::to_string(&e).unwrap();
        let at: Vec<usize> = EnergyTerms::NAMES.iter().map(|n| json.find(&format!("\"{n}\":")).unwrap()).collect();
        assert!(at.is_sorted(), "{json}");
        let mut sum = e;
        sum += e;
        assert_eq!(sum.values(), e.values().map(|v| 2.0 * v));
        assert_eq!(e.total(), 15.0);
    }
}

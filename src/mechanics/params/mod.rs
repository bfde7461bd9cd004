//! Simulation parameters: the numerics of a run and one parameter set per cell type, in SI units.
//!
//! The model (DESIGN.md §3; Runser et al., SimuCell3D, Table 2 "Model parameters"): a cell's energy is
//! U = K·V·(ln(V/V0) − 1) + (k_a/2)(A/A0 − 1)² + Σ_f γ_f·A_f + bending, with A0 = (Q0·V0²)^(1/3) and
//! the pressure p = −K ln(V/V0) capped at p_max ([`CellTypeParams::pressure`]). Faces of different
//! cells closer than the cutoff c adhere (ω) or repel (ξ). Nodes move either dynamically (mass
//! m = ρV/N, damping ζ, semi-implicit Euler) or overdamped (r += Δt·f/ζ).
//!
//! # Config files
//! A TOML file holds `[numerics]` and a list of `[[cell_types]]`; a cell's `cell_type` (SimuCell3D's
//! `cell_type_id`) indexes that list. Files may be partial. Missing `[numerics]` fields take their
//! defaults (the paper gives separate dynamic and overdamped defaults for ζ: the one of the file's
//! `dynamics` is used). A given `cell_types` list replaces the default one, and each entry's missing
//! fields take the defaults *of that entry's kind* ([`CellTypeParams::default_for`]). This is done by
//! overlaying the user's TOML tables on the serialised defaults, key by key, and only then
//! deserialising: one code path, so an unknown key is rejected wherever it sits, and its full path
//! (`cell_types[0].faces.apical`) is named.
//!
//! # Documentation
//! The doc comment of each field is its documentation in the commented config reference
//! (`tissuefit config defaults`): the first paragraph, in the words of the TOML file, ends with
//! `Unit: <unit>.` where the value has one (`Unit: dimensionless.` for a pure number); later
//! paragraphs (defaults as the code sets them, links) are for the code only. `writing.rs` reads the
//! docs from the `schemars` schema of [`Parameters`], in declaration order, so the order of the
//! fields here is the order of the written file.
//!
//! # Validation
//! [`Parameters::validate`] collects every problem at once, each naming its TOML path, the unit and
//! a fix. It includes a time-step stability estimate ([`Parameters::time_step_limits`]), because an
//! unstable Δt otherwise shows up much later as exploding meshes.

use super::settings::{RelaxMethod, SimulationMode, SimulationSettings};
use crate::geometry::Real;
use crate::mesh::{CellKind, FaceType};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;
use std::path::Path;
use toml::Table;

mod mesh_defaults;
mod reading;
#[cfg(test)]
mod tests;
mod validate;
mod writing;

pub use mesh_defaults::{
    DerivedValue, ExplicitNumerics, MEAN_EDGE_PER_MIN_EDGE, MIN_CUTOFF_FRACTION, MIN_EDGE_MISMATCH, MeshFit, MeshScale,
};
use reading::resolve;
pub use validate::TimeStepLimit;
use writing::write_toml;

/// Isoperimetric ratio A³/V² of a sphere, 36π ≈ 113.1: the smallest of any closed surface.
pub const SPHERE_ISOPERIMETRIC_RATIO: Real = 36.0 * PI;

/// Everything a simulation needs besides the geometry.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Parameters {
    /// Numerical parameters shared by all cells (paper Table 2, numerical parameters).
    ///
    /// Defaults: [`Numerics::default`].
    pub numerics: Numerics,
    /// One parameter set per cell type; a cell's cell_type (SimuCell3D's cell_type_id) indexes this
    /// list.
    ///
    /// Default: one entry per [`CellKind`], in code order (epithelial, ecm, lumen, nucleus,
    /// static), each with [`CellTypeParams::default_for`] its kind.
    pub cell_types: Vec<CellTypeParams>,
    /// What `tissuefit simulate` runs, with which method, when it stops and how often it saves.
    ///
    /// Defaults: [`SimulationSettings::default`].
    pub simulation: SimulationSettings,
    /// Per-cell tensions and adhesions in place of their cell type's, one `[[cell_overrides]]` entry
    /// per cell: `id` (the cell's id, its label in a label volume) and `surface_tension` and/or
    /// `adhesion` tables with `apical`, `lateral`, `basal` values (face types left out keep the
    /// value of the cell type or of the tissue file). They win over the per-cell values a tissue
    /// file carries; daughters inherit them.
    ///
    /// Default: none.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub cell_overrides: Vec<CellOverrideConfig>,
}

/// One cell's own tensions and adhesions (`[[cell_overrides]]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CellOverrideConfig {
    /// The cell's id (its label in a label volume, `cell_id` in a tissue file).
    pub id: u32,
    /// Surface tension γ per face type in place of the cell type's. Unit: N/m.
    #[serde(default, skip_serializing_if = "PerFaceType::is_empty")]
    pub surface_tension: PerFaceType,
    /// Spring adhesion strength ω per face type in place of the cell type's. Unit: Pa/m.
    #[serde(default, skip_serializing_if = "PerFaceType::is_empty")]
    pub adhesion: PerFaceType,
}

/// An optional value per face type.
#[derive(Copy, Clone, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PerFaceType {
    /// Apical faces.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub apical: Option<Real>,
    /// Lateral faces.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lateral: Option<Real>,
    /// Basal faces.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub basal: Option<Real>,
}

impl PerFaceType {
    /// Whether no face type has a value.
    pub fn is_empty(&self) -> bool {
        self.to_array().iter().all(Option::is_none)
    }

    /// The three values in face-type code order.
    pub fn to_array(self) -> [Option<Real>; 3] {
        [self.apical, self.lateral, self.basal]
    }
}

impl CellOverrideConfig {
    /// Lays this entry's values over `overrides` (values it leaves out keep theirs).
    pub fn apply_to(&self, overrides: &mut crate::mesh::CellOverrides) {
        for (q, given) in [self.surface_tension, self.adhesion].into_iter().enumerate() {
            for (slot, value) in overrides.values_mut(q).iter_mut().zip(given.to_array()) {
                if value.is_some() {
                    *slot = value;
                }
            }
        }
    }
}

/// A `[[cell_overrides]]` entry names a cell the tissue does not have.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error(
    "cell_overrides[{index}]: the tissue has no cell with id {id} (its ids: {ids}); use the cell's label in the label volume (cell_id in a tissue file)"
)]
pub struct UnknownOverrideCell {
    pub index: usize,
    pub id: u32,
    pub ids: String,
}

impl Parameters {
    /// A cell's own tensions and adhesions: the tissue file's, with this config's
    /// `[[cell_overrides]]` entry for its id laid over them.
    pub fn overrides_of(&self, cell: &crate::mesh::Cell) -> crate::mesh::CellOverrides {
        let mut overrides = *cell.overrides();
        for entry in self.cell_overrides.iter().filter(|e| e.id == cell.id().0) {
            entry.apply_to(&mut overrides);
        }
        overrides
    }

    /// The parameter set cell `cell` runs with: its cell type's with its own tensions and adhesions
    /// ([`crate::mesh::CellOverrides`]) in place of the type's; `None` when its type is undefined.
    pub fn parameters_of(&self, cell: &crate::mesh::Cell) -> Option<CellTypeParams> {
        self.cell_type(cell.cell_type()).map(|p| p.with_overrides(cell.overrides()))
    }

    /// Gives every cell named in `[[cell_overrides]]` its values ([`Self::overrides_of`]); errors on an
    /// entry whose id is not a cell of `tissue`. Returns how many cells it changed.
    pub fn apply_cell_overrides(&self, tissue: &mut crate::mesh::Tissue) -> Result<usize, UnknownOverrideCell> {
        for (index, entry) in self.cell_overrides.iter().enumerate() {
            if tissue.cell(crate::mesh::CellId(entry.id)).is_none() {
                let mut ids: Vec<u32> = tissue.cells().iter().map(|c| c.id().0).collect();
                ids.sort_unstable();
                let ids = match ids.as_slice() {
                    [] => "none".to_owned(),
                    [one] => one.to_string(),
                    [first, .., last] if ids.len() > 8 => format!("{first}..{last}, {} cells", ids.len()),
                    all => all.iter().map(u32::to_string).collect::<Vec<_>>().join(", "),
                };
                return Err(UnknownOverrideCell { index, id: entry.id, ids });
            }
        }
        let mut changed = 0;
        for cell in tissue.cells_mut() {
            let overrides = self.overrides_of(cell);
            if overrides != *cell.overrides() {
                *cell.overrides_mut() = overrides;
                changed += 1;
            }
        }
        Ok(changed)
    }
}

/// How nodes move.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Default, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Dynamics {
    /// Newtonian with viscous damping: p ← p + Δt·(f − (ζ/m)·p), r ← r + Δt·p/m (semi-implicit Euler).
    #[default]
    Dynamic,
    /// First order: r ← r + Δt·f/ζ.
    Overdamped,
}

impl Dynamics {
    /// All variants.
    pub const ALL: [Dynamics; 2] = [Dynamics::Dynamic, Dynamics::Overdamped];
}

/// How contacts between cells are modelled (DESIGN.md §3).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Default, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ContactModel {
    /// Paper Eq. 2: node–face springs with adhesion ω and repulsion ξ within the cutoff c.
    #[default]
    Spring,
    /// The paper's second model: node pairs of two epithelial (or static) cells closer than c, both
    /// flatter than H_max, are tied together (positions, forces and momenta averaged); repulsion ξ
    /// keeps the other nodes out, and ECM, lumen and nuclei interact by springs.
    Coupling,
}

impl ContactModel {
    /// All variants.
    pub const ALL: [ContactModel; 2] = [ContactModel::Spring, ContactModel::Coupling];
}

/// How the spring contact energy Σ a·Φ(d) is integrated over a cell's surface.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Default, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ContactQuadrature {
    /// At the nodes: Σ_p a_p·Φ(d_p), a_p a third of the node's faces' areas (the paper's sampling).
    #[default]
    Vertices,
    /// Over each face, exactly, with d linear between the face's corners (`contact::face_quadrature`):
    /// the energy no longer depends on where nodes sit along an unchanged surface.
    Faces,
}

impl ContactQuadrature {
    /// All variants.
    pub const ALL: [ContactQuadrature; 2] = [ContactQuadrature::Vertices, ContactQuadrature::Faces];
}

/// How face types (apical/lateral/basal) are assigned during a simulation.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Default, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Polarity {
    /// Face types stay as read from the input file.
    #[default]
    None,
    /// Paper polarisation mode 1, from contacts, every force evaluation: faces of epithelial and
    /// static cells whose three nodes touch another cell become lateral, those touching the lumen
    /// apical, and those touching the ECM or nothing (the medium) basal.
    Contacts,
    /// Paper polarisation mode 2 (Fig. 2): the domain is voxelised, the voxels off the surfaces are
    /// clustered into cytoplasm, lumen, exterior and ECM regions, and a ray cast from each face of an
    /// epithelial or static cell along its normal types it by the first region it meets (another
    /// cell → lateral, lumen → apical, exterior or ECM → basal). At the start, every
    /// `polarity_interval` steps and after every division.
    RayCasting,
}

impl Polarity {
    /// All variants.
    pub const ALL: [Polarity; 3] = [Polarity::None, Polarity::Contacts, Polarity::RayCasting];
}

/// How the division plane of a cell is oriented (paper Methods, "Cell division"). The plane always
/// passes through the cell's volume centroid.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Default, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum DivisionPlaneRule {
    /// Hertwig's rule: perpendicular to the cell's longest principal axis.
    #[default]
    LongestAxis,
    /// A uniformly random orientation, drawn from a stream seeded by (numerics.seed, cell id).
    Random,
}

impl DivisionPlaneRule {
    /// All variants.
    pub const ALL: [DivisionPlaneRule; 2] = [DivisionPlaneRule::LongestAxis, DivisionPlaneRule::Random];
}

/// Numerical parameters (paper Table 2, "Numerical parameters").
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Numerics {
    /// Minimum edge length l_min: remeshing collapses shorter edges and splits edges longer than
    /// l_max = max_edge_ratio·l_min. Unit: m.
    ///
    /// Default 2e-7 m. l_max: [`Numerics::max_edge_length`].
    pub min_edge_length: Real,
    /// l_max/l_min of the simulation's remeshing, at least 2; 3 as in the paper. Larger values
    /// leave more slack between a collapse and the next split (fewer remeshing operations).
    ///
    /// Default 3. On a planar Surface Evolver triplet relaxed at its own tensions 3.5 made 4 splits
    /// in 3,000 steps where 3 made 824 (both keep its contacts within 1 % now that junction groups
    /// reach 2c; see `contact::coupling`).
    #[serde(default = "default_max_edge_ratio")]
    pub max_edge_ratio: Real,
    /// Contact cutoff distance c: faces of different cells farther apart do not interact. At most
    /// 3·l_min. Unit: m.
    ///
    /// Default 2e-7 m.
    pub contact_cutoff: Real,
    /// Viscous damping coefficient ζ per node. The paper's overdamped default is 3e-9 kg/s, which a
    /// file with dynamics = "overdamped" and no damping gets. Unit: kg/s.
    ///
    /// Default 2.5e-10 kg/s (the paper's dynamic default); overdamped:
    /// [`Numerics::PAPER_OVERDAMPED_DAMPING`].
    pub damping: Real,
    /// Time step Δt. Validation estimates its stability limit per cell type. Unit: s.
    ///
    /// Default 1e-7 s.
    pub time_step: Real,
    /// Equation of motion: "dynamic" (node mass ρV/N, damping ζ, semi-implicit Euler) or
    /// "overdamped" (r += Δt·f/ζ).
    ///
    /// Default [`Dynamics::Dynamic`].
    pub dynamics: Dynamics,
    /// Contact model: "spring" (paper Eq. 2: nodes within the cutoff c of another cell's surface
    /// adhere with ω and are repelled with ξ) or "coupling" (node pairs of two epithelial or static
    /// cells closer than c, both with mean curvature below max_coupling_curvature, are tied
    /// together; the other nodes are repelled with ξ; ECM, lumen and nuclei use springs).
    ///
    /// Default [`ContactModel::Spring`].
    pub contact_model: ContactModel,
    /// Spring contacts only: how the energy density Φ(d) is integrated over a cell's surface.
    /// "vertices" (the paper's sampling: each node's area times Φ at the node) or "faces" (each
    /// face's exact mean of Φ with d linear between its corners; nodes are searched out to c plus
    /// the longest edge). With vertices the energy changes when nodes slide along an unchanged
    /// surface, which pushes the contact line of adhering cells off Young–Dupré (see the docs book:
    /// Design notes, Spring contacts and Young–Dupré); validation warns about it from w/(2γ) = ωc²/(4γ)
    /// = 0.05 on an epithelial face.
    ///
    /// Default [`ContactQuadrature::Vertices`].
    #[serde(default)]
    pub contact_quadrature: ContactQuadrature,
    /// Coupling contacts only: where three or four cells meet (junction lines, quadruple points),
    /// tie one node of each into one group that moves as one node, so the interface tensions
    /// balance at a shared point as in a foam. false: at most one partner per node, as in the
    /// paper, which leaves the third cell's junction node free and opens a channel along every
    /// junction (a tetrahedral Surface Evolver cluster lost 31° of rim angle and 19 % of its
    /// contact area). The dynamic vesicle model keeps false (see the docs book).
    ///
    /// Default true (see `contact::coupling`).
    pub coupling_junctions: bool,
    /// Coupling contacts with junction groups only: a group of three or four nodes formed at one
    /// force evaluation may form again at the next whatever its nodes' normals (until the curvature
    /// threshold releases them or a member's cell is remeshed). The snap turns a junction node's
    /// normal, so groups matched afresh break and re-form, and their nodes jump by up to 1.5·c: on
    /// a generated 200-cell spheroid (85 nodes per cell) cells then passed through each other
    /// within 1,000 steps, which this prevents. It costs accuracy on conforming meshes: a 12-cell
    /// Surface Evolver ball relaxed at its own tensions moved its worst contact by 10.2 % instead
    /// of 6.3 % (see the docs book: Simulation, coupling).
    ///
    /// Default false.
    #[serde(default)]
    pub coupling_persistent_junctions: bool,
    /// Face types during the simulation: "none" (as in the input file), "contacts" (paper mode 1,
    /// every step: faces touching another cell lateral, the lumen apical, the ECM or the medium
    /// basal) or "ray_casting" (paper mode 2: the domain is voxelised, the voxels off the surfaces
    /// are clustered into cytoplasm, lumen, exterior and ECM, and a ray cast from each face along
    /// its normal types it by the first region it meets: another cell lateral, lumen apical,
    /// exterior or ECM basal; at the start, every polarity_interval steps and after every
    /// division).
    ///
    /// Default [`Polarity::None`].
    pub polarity: Polarity,
    /// Voxel edge of the ray-casting polarisation; 0 = 1.5·min_edge_length. It must exceed the gaps
    /// between cells in contact (else they read as lumen pockets) and be small against the cells; a
    /// grid above 2^24 voxels is coarsened with a warning. Unit: m.
    ///
    /// Default 0 (see `polarity::ray_casting`).
    pub polarity_voxel_size: Real,
    /// Steps between two ray-casting polarisations (also at the start and after every division); at
    /// least 1.
    ///
    /// Default 100.
    pub polarity_interval: u64,
    /// Ray casting: an enclosed cavity that is no body is a lumen (its faces apical) when it holds
    /// at least this fraction of the mean cell volume; smaller cavities (gaps where cells meet) are
    /// passed through by the rays.
    ///
    /// Default 0.25.
    pub polarity_min_lumen_fraction: Real,
    /// Seed of every random draw (growth rates, division volumes and planes).
    ///
    /// Default 1.
    pub seed: u64,
}

impl Numerics {
    /// The paper's overdamped default damping ζ [kg/s] (Table 2).
    pub const PAPER_OVERDAMPED_DAMPING: Real = 3e-9;

    /// Paper Table 2 defaults for the given equation of motion (they differ only in ζ).
    pub fn default_for(dynamics: Dynamics) -> Self {
        Self {
            min_edge_length: 2e-7,
            max_edge_ratio: default_max_edge_ratio(),
            contact_cutoff: 2e-7,
            damping: match dynamics {
                Dynamics::Dynamic => 2.5e-10,
                Dynamics::Overdamped => Self::PAPER_OVERDAMPED_DAMPING,
            },
            time_step: 1e-7,
            dynamics,
            contact_model: ContactModel::Spring,
            contact_quadrature: ContactQuadrature::Vertices,
            coupling_junctions: true,
            coupling_persistent_junctions: false,
            polarity: Polarity::None,
            polarity_voxel_size: 0.0,
            polarity_interval: 100,
            polarity_min_lumen_fraction: 0.25,
            seed: 1,
        }
    }

    /// Maximum edge length l_max = `max_edge_ratio`·l_min [m]: longer edges are split.
    pub fn max_edge_length(&self) -> Real {
        self.max_edge_ratio * self.min_edge_length
    }
}

fn default_max_edge_ratio() -> Real {
    3.0
}

impl Default for Numerics {
    fn default() -> Self {
        Self::default_for(Dynamics::Dynamic)
    }
}

/// The parameters of one cell type (paper Table 2, "Cell volume parameters" and "Cell surface
/// parameters"). Defaults depend on the kind: [`CellTypeParams::default_for`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CellTypeParams {
    /// Name of the cell type, unique within the list.
    ///
    /// Used in reports. Default: the kind's name.
    pub name: String,
    /// What the cells are: "epithelial", "ecm", "lumen", "nucleus" or "static". Omitted fields of
    /// the entry take the defaults of this kind.
    ///
    /// Default [`CellKind::Epithelial`].
    pub kind: CellKind,
    /// Mass density ρ; node mass m = ρV/N in the dynamic model. Unit: kg/m³.
    ///
    /// Default 1000 kg/m³.
    pub mass_density: Real,
    /// Bulk modulus K: pressure p = −K ln(V/V0). Unit: Pa.
    ///
    /// Default 2500 Pa (ECM: 0).
    pub bulk_modulus: Real,
    /// Largest internal pressure p_max; inf for no cap. Unit: Pa.
    ///
    /// Default 2500 Pa.
    pub max_pressure: Real,
    /// Volume V_min below which a cell is removed (apoptosis); 0 for never. Unit: m³.
    ///
    /// Default 3.7e-16 m³ (other kinds than epithelial: 0, never removed).
    pub min_volume: Real,
    /// Mean volume V_max at which a cell divides; inf for never. Unit: m³.
    ///
    /// Default 1.4e-15 m³ (other kinds than epithelial: inf).
    pub division_volume: Real,
    /// Standard deviation of the division volume drawn per cell. Unit: m³.
    ///
    /// Default 0 m³.
    pub division_volume_std: Real,
    /// Orientation of the division plane, which passes through the volume centroid: "longest_axis"
    /// (Hertwig's rule, perpendicular to the longest principal axis) or "random" (uniform, seeded
    /// by numerics.seed and the cell id). Daughters get fresh cell ids, V0 = the mother's V0 / 2,
    /// new draws of growth rate and division volume; the cut is closed by a lateral cap.
    ///
    /// Default [`DivisionPlaneRule::LongestAxis`].
    pub division_plane: DivisionPlaneRule,
    /// Mean volumetric growth rate g = dV0/dt; negative shrinks. Unit: m³/s.
    ///
    /// Default 1e-11 m³/s (other kinds than epithelial: 0).
    pub growth_rate: Real,
    /// Standard deviation of the growth rate drawn per cell. Unit: m³/s.
    ///
    /// Default 0 m³/s.
    pub growth_rate_std: Real,
    /// Target isoperimetric ratio Q0 = A³/V², giving the target area A0 = (Q0·V0²)^(1/3); at least
    /// 36π ≈ 113.1 (a sphere). Unit: dimensionless.
    ///
    /// Default 250; a sphere's is [`SPHERE_ISOPERIMETRIC_RATIO`].
    pub target_isoperimetric_ratio: Real,
    /// Area elasticity modulus k_a of the energy (k_a/2)(A/A0 − 1)². Unit: J.
    ///
    /// Default 1e-15 J.
    pub area_elasticity: Real,
    /// Largest mean curvature H_max at which a node may be coupled to another cell (paper Table 2;
    /// used by the node-coupling contact model, numerics.contact_model = "coupling"). Unit: 1/m.
    ///
    /// Default 5e6 1/m.
    pub max_coupling_curvature: Real,
    /// When true, a simulation starts each cell of this type with V0 = V·exp(2γ̄/(K·R)) (R =
    /// (3V/4π)^(1/3), γ̄ = its area-weighted mean surface tension): a free sphere of its initial
    /// volume is then in pressure balance, so the body keeps its size instead of shrinking under
    /// its tension (for nuclei: at γ̃_n = 0.24 a free nucleus would shrink to ≈ 31 % of its volume,
    /// whatever K). Needs K > 0 and max_pressure above 2γ̄/R.
    ///
    /// The target volume is [`CellTypeParams::laplace_volume`]; γ̄ leaves area elasticity out. At
    /// γ̃ = γ/(K·V^(1/3)) the free sphere's equilibrium volume is V/V0 = x with ln(1/x) =
    /// 3.22·γ̃·x^(−1/3), whatever K is. Default false.
    pub laplace_target_volume: bool,
    /// Membrane parameters per face type (apical, lateral, basal); each face of a cell has one
    /// type.
    ///
    /// Default: Table 2 on every face type (other kinds: the reference's tension and repulsion, no
    /// adhesion).
    pub faces: FaceTypeParams,
}

impl CellTypeParams {
    /// Defaults of a kind, named after it.
    ///
    /// Epithelial: paper Table 2. The other kinds take K, γ and ξ from the reference program's shipped
    /// scenarios (notes on SimuCell3D, (d) "Non-epithelial types"); they neither grow nor divide,
    /// have no adhesion (the reference sets none), and are never removed for being small
    /// (min_volume 0; the reference's 1e-18 m³ means the same, while Table 2's V_min would delete
    /// every typical nucleus). Every other value is Table 2's.
    pub fn default_for(kind: CellKind) -> Self {
        let table2 = Self {
            name: kind.name().to_owned(),
            kind,
            mass_density: 1000.0,
            bulk_modulus: 2500.0,
            max_pressure: 2500.0,
            min_volume: 3.7e-16,
            division_volume: 1.4e-15,
            division_volume_std: 0.0,
            division_plane: DivisionPlaneRule::LongestAxis,
            growth_rate: 1e-11,
            growth_rate_std: 0.0,
            target_isoperimetric_ratio: 250.0,
            area_elasticity: 1e-15,
            max_coupling_curvature: 5e6,
            laplace_target_volume: false,
            faces: FaceTypeParams::uniform(FaceParams::default()),
        };
        // (K [Pa], γ [N/m], ξ [Pa/m]) from the reference scenarios.
        let (bulk_modulus, surface_tension, repulsion) = match kind {
            CellKind::Epithelial => return table2,
            CellKind::Ecm => (0.0, 5e-4, 2e9),
            CellKind::Lumen => (2500.0, 4e-4, 5e9),
            CellKind::Nucleus => (2500.0, 0.0, 1e9),
            CellKind::Static => (2500.0, 2e-11, 1e9),
        };
        let face = FaceParams { surface_tension, adhesion: 0.0, repulsion, ..FaceParams::default() };
        Self {
            bulk_modulus,
            min_volume: 0.0,
            division_volume: Real::INFINITY,
            growth_rate: 0.0,
            faces: FaceTypeParams::uniform(face),
            ..table2
        }
    }

    /// This parameter set with a cell's own tensions and adhesions in place of its values.
    pub fn with_overrides(&self, overrides: &crate::mesh::CellOverrides) -> Self {
        let mut p = self.clone();
        for t in FaceType::ALL {
            let face = p.faces.get_mut(t);
            let i = t.code() as usize;
            if let Some(g) = overrides.surface_tension[i] {
                face.surface_tension = g;
            }
            if let Some(w) = overrides.adhesion[i] {
                face.adhesion = w;
            }
        }
        p
    }

    /// Pressure p = min(−K ln(V/V0), p_max) [Pa] of a cell of volume `volume` and target volume
    /// `target_volume` (both m³, > 0): the paper's pressure with its cap.
    pub fn pressure(&self, volume: Real, target_volume: Real) -> Real {
        (-self.bulk_modulus * (volume / target_volume).ln()).min(self.max_pressure)
    }

    /// The area-weighted mean surface tension γ̄ (N/m) of a cell of this type over its faces (0 for a
    /// cell without area).
    pub fn mean_tension(&self, cell: &crate::mesh::Cell) -> Real {
        let areas = cell.mesh().face_areas();
        let area: Real = areas.iter().sum();
        let weighted: Real =
            areas.iter().zip(cell.face_types()).map(|(a, t)| a * self.faces.get(*t).surface_tension).sum();
        if area > 0.0 { weighted / area } else { 0.0 }
    }

    /// The Laplace target volume of [`CellTypeParams::laplace_target_volume`] for a body of volume
    /// `volume` (m³) whose faces have the area-weighted mean tension `mean_tension` (N/m). `Err` holds
    /// the balancing pressure p = 2γ̄/R when no target volume can balance it (K = 0, p above
    /// max_pressure, or no finite positive radius).
    pub fn laplace_volume(&self, volume: Real, mean_tension: Real) -> Result<Real, Real> {
        let radius = (3.0 * volume / (4.0 * PI)).cbrt();
        let pressure = 2.0 * mean_tension / radius;
        if self.bulk_modulus <= 0.0
            || pressure.is_nan()
            || pressure > self.max_pressure
            || !radius.is_finite()
            || radius <= 0.0
        {
            return Err(pressure);
        }
        Ok(volume * (pressure / self.bulk_modulus).exp())
    }
}

impl Default for CellTypeParams {
    /// Epithelial defaults (paper Table 2).
    fn default() -> Self {
        Self::default_for(CellKind::Epithelial)
    }
}

/// Membrane parameters of the three face types of a cell type.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FaceTypeParams {
    /// Apical faces: facing a lumen (every face of an unpolarised cell).
    ///
    /// Default: Table 2.
    pub apical: FaceParams,
    /// Lateral faces: facing another cell.
    ///
    /// Default: Table 2.
    pub lateral: FaceParams,
    /// Basal faces: facing the exterior or the ECM.
    ///
    /// Default: Table 2.
    pub basal: FaceParams,
}

impl FaceTypeParams {
    /// The same parameters on every face type.
    pub fn uniform(face: FaceParams) -> Self {
        Self { apical: face.clone(), lateral: face.clone(), basal: face }
    }

    /// Parameters of one face type.
    pub fn get(&self, face_type: FaceType) -> &FaceParams {
        match face_type {
            FaceType::Apical => &self.apical,
            FaceType::Lateral => &self.lateral,
            FaceType::Basal => &self.basal,
        }
    }

    /// Mutable parameters of one face type.
    pub fn get_mut(&mut self, face_type: FaceType) -> &mut FaceParams {
        match face_type {
            FaceType::Apical => &mut self.apical,
            FaceType::Lateral => &mut self.lateral,
            FaceType::Basal => &mut self.basal,
        }
    }

    /// The three face types with their parameters, in code order.
    pub fn iter(&self) -> impl Iterator<Item = (FaceType, &FaceParams)> {
        FaceType::ALL.into_iter().map(|face_type| (face_type, self.get(face_type)))
    }
}

/// Membrane parameters of one face type (paper Table 2, "Cell surface parameters").
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FaceParams {
    /// Surface tension γ: energy γ·A per face. Unit: N/m.
    ///
    /// Default 1e-3 N/m.
    pub surface_tension: Real,
    /// Bending modulus k_b of the discrete hinge energy. Unit: J.
    ///
    /// Default 2e-18 J.
    pub bending_modulus: Real,
    /// Adhesion strength ω: contact stress per unit separation. Unit: Pa/m.
    ///
    /// Default 1e9 Pa/m.
    pub adhesion: Real,
    /// Repulsion strength ξ: contact stress per unit penetration. With the spring contact model and
    /// no `repulsion` anywhere in the config, `simulate` and the pipeline derive it per moving cell
    /// type from the input tissue: ξ·c = 25 × the largest Laplace pressure 2γ̄/R of its cells
    /// (contacts sink c/25), and at least 20 × its strongest adhesion ω. Unit: Pa/m.
    ///
    /// Default 1e9 Pa/m. The derived value: [`crate::mechanics::derived_repulsion`] (25 and 20 are
    /// [`crate::mechanics::REPULSION_PER_PRESSURE`] and
    /// [`crate::mechanics::REPULSION_PER_ADHESION`]).
    pub repulsion: Real,
}

impl FaceParams {
    /// Largest ratio W/γ of the spring model's adhesion well depth to the surface tension that
    /// validation accepts without a warning. At W/γ = 1 a contact face has no net tension (complete
    /// wetting): its area grows without bound and the surface crumples (measured: the 24-cell vesicle
    /// folded at step 213 at ω̃ = 2, c = 1.6 µm, W = γ). Runs also broke down at 0.7 (a doublet whose rim
    /// nodes were pulled deeper than the cutoff) and ran at 0.5 (the vesicle at ω̃ = 1, a 6-cell
    /// aggregate, doublets).
    pub const MAX_ADHESION_TENSION_RATIO: Real = 0.7;

    /// Depth W = ωc²/4 [J/m²] of the spring model's adhesion well at cutoff c: the adhesion energy per
    /// unit area of one side of a contact, which acts as a negative surface tension on contact faces.
    pub fn adhesion_well_depth(&self, cutoff: Real) -> Real {
        0.25 * self.adhesion * cutoff * cutoff
    }

    /// Whether [`Self::adhesion_well_depth`] reaches [`Self::MAX_ADHESION_TENSION_RATIO`] × the
    /// surface tension (with some adhesion).
    pub fn adhesion_outweighs_tension(&self, cutoff: Real) -> bool {
        self.adhesion > 0.0
            && self.adhesion_well_depth(cutoff) >= Self::MAX_ADHESION_TENSION_RATIO * self.surface_tension
    }

    /// The adhesion ω [Pa/m] below which [`Self::adhesion_outweighs_tension`] is false.
    pub fn max_adhesion(&self, cutoff: Real) -> Real {
        4.0 * Self::MAX_ADHESION_TENSION_RATIO * self.surface_tension / (cutoff * cutoff)
    }
}

impl Default for FaceParams {
    /// Paper Table 2.
    fn default() -> Self {
        Self { surface_tension: 1e-3, bending_modulus: 2e-18, adhesion: 1e9, repulsion: 1e9 }
    }
}

impl Default for Parameters {
    /// Table 2 numerics and one cell type per kind, in code order, so that SimuCell3D's
    /// `cell_type_id` = `global_cell_id` files map onto the list as they are.
    fn default() -> Self {
        Self {
            numerics: Numerics::default(),
            cell_types: CellKind::ALL.into_iter().map(CellTypeParams::default_for).collect(),
            simulation: SimulationSettings::default(),
            cell_overrides: Vec::new(),
        }
    }
}

/// Parameters that could not be read or are not valid. Every message names the origin (the file).
#[derive(Debug, thiserror::Error)]
pub enum ParamError {
    /// The file could not be read.
    #[error("{origin}: cannot read: {source}")]
    Read { origin: String, source: std::io::Error },
    /// The text is not TOML.
    #[error("{origin}: {message}")]
    Syntax { origin: String, message: String },
    /// The TOML does not fit the schema: unknown keys, wrong value types.
    #[error("{}", prefixed_lines(.origin, .problems))]
    Schema { origin: String, problems: Vec<String> },
    /// Values out of range, inconsistent, or an unstable time step.
    #[error("{}", prefixed_lines(.origin, .problems))]
    Invalid { origin: String, problems: Vec<String> },
}

/// Deep merge of `over` into `base` (tables merged key by key, other values replaced).
fn merge_tables(base: &mut Table, over: &Table) {
    for (key, value) in over {
        match (base.get_mut(key), value) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) => merge_tables(b, o),
            _ => {
                base.insert(key.clone(), value.clone());
            }
        }
    }
}

/// A parameter file's TOML table.
fn read_table(path: &Path) -> Result<Table, ParamError> {
    let origin = path.display().to_string();
    let text = crate::files::read_text_capped(path, crate::files::MAX_CONFIG_FILE)
        .map_err(|source| ParamError::Read { origin: origin.clone(), source })?;
    toml::from_str::<Table>(&text).map_err(|e| ParamError::Syntax { origin, message: e.to_string() })
}

fn prefixed_lines(origin: &str, problems: &[String]) -> String {
    problems.iter().map(|problem| format!("{origin}: {problem}")).collect::<Vec<_>>().join("\n")
}

impl Parameters {
    /// A model file (or the defaults when `None`) with `overrides` merged over it key by key (tables
    /// merged, other values replaced), then read like [`Parameters::from_toml_str`]. Errors name the
    /// file and say that the overrides took part. This is how the fit and the pipeline take a model.
    pub fn load_with_overrides(model: Option<&Path>, overrides: Option<&Table>) -> Result<Self, ParamError> {
        Self::load_with_overrides_explicit(model, overrides).map(|(params, _)| params)
    }

    /// [`Parameters::load_with_overrides`], also saying which mesh-dependent numerics the model and
    /// its overrides set themselves ([`Parameters::fit_to_mesh`] derives the others).
    pub fn load_with_overrides_explicit(
        model: Option<&Path>,
        overrides: Option<&Table>,
    ) -> Result<(Self, ExplicitNumerics), ParamError> {
        let mut table = match model {
            Some(path) => read_table(path)?,
            None => Table::new(),
        };
        if let Some(over) = overrides {
            merge_tables(&mut table, over);
        }
        let origin = match model {
            Some(p) => format!("model {} + model_overrides", p.display()),
            None => "model_overrides".to_string(),
        };
        let text = toml::to_string(&table)
            .map_err(|e| ParamError::Syntax { origin: origin.clone(), message: e.to_string() })?;
        Ok((Self::from_toml_str(&text, &origin)?, ExplicitNumerics::of_table(&table)))
    }

    /// Reads and validates a TOML parameter file (partial files allowed: see the module doc).
    /// The result passed [`Parameters::validate`]; call it again for the warnings.
    pub fn load(path: &Path) -> Result<Self, ParamError> {
        Self::load_explicit(path).map(|(params, _)| params)
    }

    /// [`Parameters::load`], also saying which mesh-dependent numerics the file sets itself.
    pub fn load_explicit(path: &Path) -> Result<(Self, ExplicitNumerics), ParamError> {
        let origin = path.display().to_string();
        let text = crate::files::read_text_capped(path, crate::files::MAX_CONFIG_FILE)
            .map_err(|source| ParamError::Read { origin: origin.clone(), source })?;
        let params = Self::from_toml_str(&text, &origin)?;
        // It parsed as TOML just now.
        let table: Table = toml::from_str(&text).map_err(|e| ParamError::Syntax { origin, message: e.to_string() })?;
        Ok((params, ExplicitNumerics::of_table(&table)))
    }

    /// Parses and validates TOML text; `origin` (usually the file path) prefixes every error.
    pub fn from_toml_str(text: &str, origin: &str) -> Result<Self, ParamError> {
        let table: Table = toml::from_str(text)
            .map_err(|error| ParamError::Syntax { origin: origin.to_owned(), message: error.to_string() })?;
        let params = resolve(table).map_err(|problems| ParamError::Schema { origin: origin.to_owned(), problems })?;
        let (errors, _warnings) = params.check();
        if errors.is_empty() {
            Ok(params)
        } else {
            Err(ParamError::Invalid { origin: origin.to_owned(), problems: errors })
        }
    }

    /// Checks every value; returns the warnings, or an error listing every problem found.
    pub fn validate(&self) -> Result<Vec<String>, ParamError> {
        let (errors, warnings) = self.check();
        if errors.is_empty() {
            Ok(warnings)
        } else {
            Err(ParamError::Invalid { origin: "parameters".to_owned(), problems: errors })
        }
    }

    /// The parameters of cell type `index` (a cell's `cell_type`).
    pub fn cell_type(&self, index: u32) -> Option<&CellTypeParams> {
        self.cell_types.get(index as usize)
    }

    /// Steps a run makes at most: `simulation.max_steps` for a relaxation, duration / Δt for a time run.
    pub fn planned_steps(&self) -> u64 {
        let s = &self.simulation;
        match s.mode {
            SimulationMode::Equilibrium => s.max_steps,
            SimulationMode::Time => (s.duration / self.numerics.time_step).round() as u64,
        }
    }

    /// The time-step stability estimate of every cell type, in list order (see [`TimeStepLimit`]).
    pub fn time_step_limits(&self) -> Vec<TimeStepLimit> {
        self.cell_types
            .iter()
            .enumerate()
            .map(|(index, cell_type)| TimeStepLimit::estimate(index, cell_type, &self.numerics))
            .collect()
    }

    /// The full parameters as TOML, without comments (for writing the resolved config of a run).
    pub fn to_toml_string(&self) -> String {
        write_toml(self, false)
    }

    /// The default parameters as a complete TOML file in which every section and field carries a
    /// comment with its meaning, unit and default.
    pub fn default_toml_commented() -> String {
        write_toml(&Self::default(), true)
    }
}

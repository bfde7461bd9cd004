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
//! # Validation
//! [`Parameters::validate`] collects every problem at once, each naming its TOML path, the unit and
//! a fix. It includes a time-step stability estimate ([`Parameters::time_step_limits`]), because an
//! unstable Δt otherwise shows up much later as exploding meshes.

use super::settings::{RelaxMethod, SimulationMode, SimulationSettings};
use crate::geometry::Real;
use crate::mesh::{CellKind, FaceType};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::f64::consts::PI;
use std::fmt::Write as _;
use std::path::Path;
use toml::{Table, Value};

/// Isoperimetric ratio A³/V² of a sphere, 36π ≈ 113.1: the smallest of any closed surface.
pub const SPHERE_ISOPERIMETRIC_RATIO: Real = 36.0 * PI;

/// Everything a simulation needs besides the geometry.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Parameters {
    /// Numerical parameters shared by all cells. Defaults: [`Numerics::default`].
    pub numerics: Numerics,
    /// One parameter set per cell type; a cell's `cell_type` (SimuCell3D's `cell_type_id`) indexes
    /// this list. Default: one entry per [`CellKind`], in code order (epithelial, ecm, lumen,
    /// nucleus, static), each with [`CellTypeParams::default_for`] its kind.
    pub cell_types: Vec<CellTypeParams>,
    /// What `tissuefit simulate` runs and when it stops. Defaults: [`SimulationSettings::default`].
    pub simulation: SimulationSettings,
}

/// How nodes move.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
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
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ContactModel {
    /// Paper Eq. 2: node–face springs with adhesion ω and repulsion ξ within the cutoff c.
    #[default]
    Spring,
    /// Node–node coupling: nodes of different cells closer than c, both with mean curvature below
    /// H_max, are tied together (positions, forces and momenta averaged).
    Coupling,
}

impl ContactModel {
    /// All variants.
    pub const ALL: [ContactModel; 2] = [ContactModel::Spring, ContactModel::Coupling];
}

/// Numerical parameters (paper Table 2, "Numerical parameters").
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Numerics {
    /// Minimum edge length l_min [m]: remeshing collapses shorter edges and splits edges longer than
    /// l_max = 3·l_min ([`Numerics::max_edge_length`]). Default 2e-7 m.
    pub min_edge_length: Real,
    /// Contact cutoff distance c [m]: faces of different cells farther apart do not interact; must
    /// not exceed l_max. Default 2e-7 m.
    pub contact_cutoff: Real,
    /// Viscous damping coefficient ζ [kg/s], per node. Default 2.5e-10 kg/s (the paper's dynamic
    /// default); the paper's overdamped default is 3e-9 kg/s, which a config file with
    /// `dynamics = "overdamped"` and no `damping` gets.
    pub damping: Real,
    /// Time step Δt [s]. Default 1e-7 s.
    pub time_step: Real,
    /// Equation of motion. Default [`Dynamics::Dynamic`].
    pub dynamics: Dynamics,
    /// Contact model. Default [`ContactModel::Spring`].
    pub contact_model: ContactModel,
    /// Seed of every random draw (growth rates, division volumes and planes). Default 1.
    pub seed: u64,
}

impl Numerics {
    /// The paper's overdamped default damping ζ [kg/s] (Table 2).
    pub const PAPER_OVERDAMPED_DAMPING: Real = 3e-9;

    /// Paper Table 2 defaults for the given equation of motion (they differ only in ζ).
    pub fn default_for(dynamics: Dynamics) -> Self {
        Self {
            min_edge_length: 2e-7,
            contact_cutoff: 2e-7,
            damping: match dynamics {
                Dynamics::Dynamic => 2.5e-10,
                Dynamics::Overdamped => Self::PAPER_OVERDAMPED_DAMPING,
            },
            time_step: 1e-7,
            dynamics,
            contact_model: ContactModel::Spring,
            seed: 1,
        }
    }

    /// Maximum edge length l_max = 3·l_min [m]: longer edges are split.
    pub fn max_edge_length(&self) -> Real {
        3.0 * self.min_edge_length
    }
}

impl Default for Numerics {
    fn default() -> Self {
        Self::default_for(Dynamics::Dynamic)
    }
}

/// The parameters of one cell type (paper Table 2, "Cell volume parameters" and "Cell surface
/// parameters"). Defaults depend on the kind: [`CellTypeParams::default_for`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CellTypeParams {
    /// Name, unique within the list; used in reports. Default: the kind's name.
    pub name: String,
    /// What the cells of this type are. Default [`CellKind::Epithelial`].
    pub kind: CellKind,
    /// Mass density ρ [kg/m³]; node mass m = ρV/N in the dynamic model. Default 1000 kg/m³.
    pub mass_density: Real,
    /// Bulk modulus K [Pa]: pressure p = −K ln(V/V0). Default 2500 Pa (ECM: 0).
    pub bulk_modulus: Real,
    /// Largest internal pressure p_max [Pa]; `inf` for no cap. Default 2500 Pa.
    pub max_pressure: Real,
    /// Volume V_min [m³] below which a cell is removed (apoptosis). Default 3.7e-16 m³ (other kinds
    /// than epithelial: 0, never removed).
    pub min_volume: Real,
    /// Mean volume V_max [m³] at which a cell divides; `inf` for never. Default 1.4e-15 m³ (other
    /// kinds than epithelial: inf).
    pub division_volume: Real,
    /// Standard deviation [m³] of the division volume drawn per cell. Default 0 m³.
    pub division_volume_std: Real,
    /// Mean volumetric growth rate g = dV0/dt [m³/s]; negative shrinks. Default 1e-11 m³/s (other
    /// kinds than epithelial: 0).
    pub growth_rate: Real,
    /// Standard deviation [m³/s] of the growth rate drawn per cell. Default 0 m³/s.
    pub growth_rate_std: Real,
    /// Target isoperimetric ratio Q0 = A³/V² [dimensionless], giving the target area
    /// A0 = (Q0·V0²)^(1/3); at least 36π (a sphere's). Default 250.
    pub target_isoperimetric_ratio: Real,
    /// Area elasticity modulus k_a [J] of the energy (k_a/2)(A/A0 − 1)². Default 1e-15 J.
    pub area_elasticity: Real,
    /// Largest mean curvature H_max [1/m] at which a node may be coupled to another cell (coupling
    /// contact model). Default 5e6 1/m.
    pub max_coupling_curvature: Real,
    /// Membrane parameters per face type. Default: Table 2 on every face type (other kinds: the
    /// reference's tension and repulsion, no adhesion).
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
            growth_rate: 1e-11,
            growth_rate_std: 0.0,
            target_isoperimetric_ratio: 250.0,
            area_elasticity: 1e-15,
            max_coupling_curvature: 5e6,
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

    /// Pressure p = min(−K ln(V/V0), p_max) [Pa] of a cell of volume `volume` and target volume
    /// `target_volume` (both m³, > 0): the paper's pressure with its cap.
    pub fn pressure(&self, volume: Real, target_volume: Real) -> Real {
        (-self.bulk_modulus * (volume / target_volume).ln()).min(self.max_pressure)
    }
}

impl Default for CellTypeParams {
    /// Epithelial defaults (paper Table 2).
    fn default() -> Self {
        Self::default_for(CellKind::Epithelial)
    }
}

/// Membrane parameters of the three face types of a cell type.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FaceTypeParams {
    /// Apical faces (facing a lumen; every face of an unpolarised cell). Default: Table 2.
    pub apical: FaceParams,
    /// Lateral faces (facing another cell). Default: Table 2.
    pub lateral: FaceParams,
    /// Basal faces (facing the exterior or the ECM). Default: Table 2.
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
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FaceParams {
    /// Surface tension γ [N/m]: energy γ·A per face. Default 1e-3 N/m.
    pub surface_tension: Real,
    /// Bending modulus k_b [J] of the discrete hinge energy. Default 2e-18 J.
    pub bending_modulus: Real,
    /// Adhesion strength ω [Pa/m]: contact stress per unit separation. Default 1e9 Pa/m.
    pub adhesion: Real,
    /// Repulsion strength ξ [Pa/m]: contact stress per unit penetration. Default 1e9 Pa/m.
    pub repulsion: Real,
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

fn prefixed_lines(origin: &str, problems: &[String]) -> String {
    problems.iter().map(|problem| format!("{origin}: {problem}")).collect::<Vec<_>>().join("\n")
}

impl Parameters {
    /// Reads and validates a TOML parameter file (partial files allowed: see the module doc).
    /// The result passed [`Parameters::validate`]; call it again for the warnings.
    pub fn load(path: &Path) -> Result<Self, ParamError> {
        let origin = path.display().to_string();
        let text =
            std::fs::read_to_string(path).map_err(|source| ParamError::Read { origin: origin.clone(), source })?;
        Self::from_toml_str(&text, &origin)
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

    /// Returns (errors, warnings).
    fn check(&self) -> (Vec<String>, Vec<String>) {
        let mut report = Report::default();
        let numerics = &self.numerics;
        let numerics_defaults = Numerics::default_for(numerics.dynamics);
        let l_min_ok = report.number(
            "numerics.min_edge_length",
            numerics.min_edge_length,
            numerics_defaults.min_edge_length,
            Bound::Positive,
        );
        let cutoff_ok = report.number(
            "numerics.contact_cutoff",
            numerics.contact_cutoff,
            numerics_defaults.contact_cutoff,
            Bound::Positive,
        );
        report.number("numerics.damping", numerics.damping, numerics_defaults.damping, Bound::Positive);
        report.number("numerics.time_step", numerics.time_step, numerics_defaults.time_step, Bound::Positive);
        if l_min_ok && cutoff_ok && numerics.contact_cutoff > numerics.max_edge_length() {
            report.errors.push(format!(
                "numerics.contact_cutoff = {} m exceeds l_max = 3·numerics.min_edge_length = {} m; the reference model \
                 requires c ≤ l_max so that a contact stays within one edge of the surface; lower contact_cutoff or \
                 raise min_edge_length",
                fmt_real(numerics.contact_cutoff),
                fmt_real(numerics.max_edge_length())
            ));
        }

        let numerics_valid = report.errors.is_empty();
        let sim = &self.simulation;
        let sim_defaults = SimulationSettings::default();
        report.number("simulation.duration", sim.duration, sim_defaults.duration, Bound::Positive);
        report.number("simulation.sampling_period", sim.sampling_period, sim_defaults.sampling_period, Bound::Positive);
        report.number("simulation.force_tolerance", sim.force_tolerance, sim_defaults.force_tolerance, Bound::Positive);
        report.number(
            "simulation.energy_tolerance",
            sim.energy_tolerance,
            sim_defaults.energy_tolerance,
            Bound::Positive,
        );
        report.number(
            "simulation.volume_tolerance",
            sim.volume_tolerance,
            sim_defaults.volume_tolerance,
            Bound::Positive,
        );
        if sim.max_steps == 0 {
            report.errors.push("simulation.max_steps = 0: give a step budget of at least 1".to_owned());
        }
        if sim.sample_every_steps == 0 {
            report.errors.push("simulation.sample_every_steps = 0: must be at least 1".to_owned());
        }

        if self.cell_types.is_empty() {
            report.errors.push("cell_types is empty; give at least one [[cell_types]] entry".to_owned());
        }
        let mut first_with_name: HashMap<&str, usize> = HashMap::new();
        let mut type_valid = Vec::with_capacity(self.cell_types.len());
        for (index, cell_type) in self.cell_types.iter().enumerate() {
            let errors_before = report.errors.len();
            if cell_type.name.trim().is_empty() {
                report.errors.push(format!("cell_types[{index}].name is empty; give every cell type a name"));
            } else if let Some(first) = first_with_name.get(cell_type.name.as_str()) {
                report.errors.push(format!(
                    "cell_types[{index}].name = {:?} is already the name of cell_types[{first}]; names must be unique",
                    cell_type.name
                ));
            } else {
                first_with_name.insert(&cell_type.name, index);
            }
            report.cell_type(index, cell_type);
            type_valid.push(report.errors.len() == errors_before);
        }

        // The stability estimate is meaningless with invalid inputs, and would only add noise.
        if numerics_valid {
            for limit in self.time_step_limits() {
                if type_valid[limit.cell_type] {
                    report.time_step(&limit, numerics);
                }
            }
        }
        (report.errors, report.warnings)
    }
}

/// Time-step stability estimate for one cell type: how close Δt is to making the integrator diverge.
///
/// The estimate models a typical node of the type. Its edges are l = 2·l_min long (between l_min and
/// l_max = 3·l_min, where remeshing keeps them), so it carries the area a_n = (√3/2)·l² of two
/// equilateral triangles (a node has ~6 triangles, each shared by 3 nodes). The cell has volume
/// V = min_volume (the smallest, lightest cell of the type; (4/3)π(10·l_min)³ if min_volume is 0),
/// hence about N = (36π)^(1/3)·V^(2/3)/a_n nodes (a sphere's area over a_n; at least 4) of mass
/// m = ρV/N. The stiffness k [N/m] of one node is estimated by the largest of
/// * surface tension 4·γ_max (the in-plane tension pulls a displaced node back with ~4γ per unit
///   displacement), γ_max the largest tension over the type's face types;
/// * contact max(ω, ξ)·a_n (a contact stress per unit distance acting on the node's area);
/// * bending 10·k_b/l² (the hinge energy's curvature at one node);
/// * bulk K·a_n²/V (a node displacement changes V by a_n per unit length, dp/dV = K/V);
/// * area elasticity k_a·l²/A0² with A0 = (Q0·V²)^(1/3) (likewise through the area).
///
/// Dynamic model (p ← p + Δt(f − (ζ/m)p), r ← r + Δt·p/m): the damping update multiplies p by
/// 1 − ζΔt/m, which overshoots past zero above 1 and diverges above 2; semi-implicit Euler on an
/// oscillator of frequency √(k/m) is stable for Δt·√(k/m) < 2. Overdamped model (r ← r + Δt·f/ζ):
/// explicit Euler on a relaxation of rate k/ζ is stable for Δt·k/ζ < 2. Validation calls a ratio
/// above its limit an error and above half its limit a warning. It is an order-of-magnitude
/// estimate: meshes finer than 2·l_min somewhere, or stiffer contacts, can need a smaller Δt.
#[derive(Clone, Debug, PartialEq)]
pub struct TimeStepLimit {
    /// Index of the cell type.
    pub cell_type: usize,
    /// Name of the cell type.
    pub name: String,
    /// Whether the kind never moves (ECM, static): then no limit applies.
    pub immobile: bool,
    /// Estimated node count N of a cell.
    pub node_count: Real,
    /// Estimated node mass m = ρV/N [kg].
    pub node_mass: Real,
    /// Estimated largest node stiffness k [N/m].
    pub stiffness: Real,
    /// Which term gives that stiffness ("surface tension", "contact", "bending", "bulk modulus",
    /// "area elasticity").
    pub stiffest_term: &'static str,
    /// ζΔt/m: dynamic model, stable below 2.
    pub damping_ratio: Real,
    /// Δt·√(k/m): dynamic model, stable below 2.
    pub oscillation_ratio: Real,
    /// Δt·k/ζ: overdamped model, stable below 2.
    pub overdamped_ratio: Real,
    /// Largest stable Δt [s] for the configured dynamics: min(2m/ζ, 2√(m/k)) dynamic, 2ζ/k
    /// overdamped.
    pub max_time_step: Real,
}

impl TimeStepLimit {
    /// Stability limit of every ratio.
    pub const LIMIT: Real = 2.0;

    fn estimate(index: usize, cell_type: &CellTypeParams, numerics: &Numerics) -> Self {
        let l_min = numerics.min_edge_length;
        let edge = 2.0 * l_min;
        let node_area = 3.0_f64.sqrt() / 2.0 * edge * edge;
        let volume =
            if cell_type.min_volume > 0.0 { cell_type.min_volume } else { 4.0 / 3.0 * PI * (10.0 * l_min).powi(3) };
        let node_count = (SPHERE_ISOPERIMETRIC_RATIO.cbrt() * volume.powf(2.0 / 3.0) / node_area).max(4.0);
        let node_mass = cell_type.mass_density * volume / node_count;

        let faces = || cell_type.faces.iter().map(|(_, face)| face);
        let max_over_faces = |value: fn(&FaceParams) -> Real| faces().map(value).fold(0.0, Real::max);
        let target_area = (cell_type.target_isoperimetric_ratio * volume * volume).cbrt();
        let terms = [
            ("surface tension", 4.0 * max_over_faces(|f| f.surface_tension)),
            ("contact", max_over_faces(|f| f.adhesion.max(f.repulsion)) * node_area),
            ("bending", 10.0 * max_over_faces(|f| f.bending_modulus) / (edge * edge)),
            ("bulk modulus", cell_type.bulk_modulus * node_area * node_area / volume),
            ("area elasticity", cell_type.area_elasticity * edge * edge / (target_area * target_area)),
        ];
        let (stiffest_term, stiffness) =
            terms.into_iter().fold(terms[0], |best, term| if term.1 > best.1 { term } else { best });

        let (dt, zeta) = (numerics.time_step, numerics.damping);
        let max_time_step = match numerics.dynamics {
            Dynamics::Dynamic => (Self::LIMIT * node_mass / zeta).min(Self::LIMIT * (node_mass / stiffness).sqrt()),
            Dynamics::Overdamped => Self::LIMIT * zeta / stiffness,
        };
        Self {
            cell_type: index,
            name: cell_type.name.clone(),
            immobile: cell_type.kind.is_immobile(),
            node_count,
            node_mass,
            stiffness,
            stiffest_term,
            damping_ratio: zeta * dt / node_mass,
            oscillation_ratio: dt * (stiffness / node_mass).sqrt(),
            overdamped_ratio: dt * stiffness / zeta,
            max_time_step,
        }
    }
}

/// Accumulates the problems found by validation.
#[derive(Default)]
struct Report {
    errors: Vec<String>,
    warnings: Vec<String>,
}

/// The allowed range of a value. `+inf` is allowed only where `…OrInf`.
#[derive(Copy, Clone, PartialEq)]
enum Bound {
    Positive,
    NonNegative,
    Finite,
    NonNegativeOrInf,
    AtLeastSphere,
}

impl Report {
    /// Checks one value against `bound`; records an error naming `path` and returns false if it fails.
    fn number(&mut self, path: &str, value: Real, default: Real, bound: Bound) -> bool {
        let unit = unit_of(path);
        let unit_suffix = if unit.is_empty() { String::new() } else { format!(" {unit}") };
        let allow_inf = bound == Bound::NonNegativeOrInf;
        let problem = if value.is_nan() {
            Some("is NaN; give a number".to_owned())
        } else if value.is_infinite() && !(allow_inf && value > 0.0) {
            Some(if allow_inf { "must be finite or +inf" } else { "must be finite" }.to_owned())
        } else {
            match bound {
                Bound::Positive if value <= 0.0 => Some(format!("must be > 0{unit_suffix}")),
                Bound::NonNegative | Bound::NonNegativeOrInf if value < 0.0 => {
                    Some(format!("must be ≥ 0{unit_suffix}"))
                }
                Bound::AtLeastSphere if value < SPHERE_ISOPERIMETRIC_RATIO => Some(format!(
                    "is below 36π ≈ {:.1}, the isoperimetric ratio A³/V² of a sphere; no closed surface has a \
                     smaller one, so the target area could never be reached; use at least {:.1}",
                    SPHERE_ISOPERIMETRIC_RATIO, SPHERE_ISOPERIMETRIC_RATIO
                )),
                _ => None,
            }
        };
        match problem {
            Some(problem) => {
                self.errors.push(format!(
                    "{path} = {}{unit_suffix}: {problem} (default: {}{unit_suffix})",
                    fmt_real(value),
                    fmt_real(default)
                ));
                false
            }
            None => true,
        }
    }

    /// Checks every value of cell type `index`.
    fn cell_type(&mut self, index: usize, t: &CellTypeParams) {
        let d = CellTypeParams::default_for(t.kind);
        let p = |field: &str| format!("cell_types[{index}].{field}");
        self.number(&p("mass_density"), t.mass_density, d.mass_density, Bound::Positive);
        self.number(&p("bulk_modulus"), t.bulk_modulus, d.bulk_modulus, Bound::NonNegative);
        self.number(&p("max_pressure"), t.max_pressure, d.max_pressure, Bound::NonNegativeOrInf);
        let min_ok = self.number(&p("min_volume"), t.min_volume, d.min_volume, Bound::NonNegative);
        let division_ok =
            self.number(&p("division_volume"), t.division_volume, d.division_volume, Bound::NonNegativeOrInf);
        self.number(&p("division_volume_std"), t.division_volume_std, d.division_volume_std, Bound::NonNegative);
        self.number(&p("growth_rate"), t.growth_rate, d.growth_rate, Bound::Finite);
        self.number(&p("growth_rate_std"), t.growth_rate_std, d.growth_rate_std, Bound::NonNegative);
        self.number(
            &p("target_isoperimetric_ratio"),
            t.target_isoperimetric_ratio,
            d.target_isoperimetric_ratio,
            Bound::AtLeastSphere,
        );
        self.number(&p("area_elasticity"), t.area_elasticity, d.area_elasticity, Bound::NonNegative);
        self.number(&p("max_coupling_curvature"), t.max_coupling_curvature, d.max_coupling_curvature, Bound::Positive);
        for (face_type, face) in t.faces.iter() {
            let default = d.faces.get(face_type);
            let p = |field: &str| format!("cell_types[{index}].faces.{}.{field}", face_type.name());
            self.number(&p("surface_tension"), face.surface_tension, default.surface_tension, Bound::NonNegative);
            self.number(&p("bending_modulus"), face.bending_modulus, default.bending_modulus, Bound::NonNegative);
            self.number(&p("adhesion"), face.adhesion, default.adhesion, Bound::NonNegative);
            self.number(&p("repulsion"), face.repulsion, default.repulsion, Bound::NonNegative);
        }
        if min_ok && division_ok && t.min_volume >= t.division_volume {
            self.errors.push(format!(
                "{} = {} m³ is not below {} = {} m³: a cell would be removed before it could divide; lower \
                 min_volume or raise division_volume (inf: never divide)",
                p("min_volume"),
                fmt_real(t.min_volume),
                p("division_volume"),
                fmt_real(t.division_volume)
            ));
        }
    }

    /// Compares the time step with the stability limits of one cell type.
    fn time_step(&mut self, limit: &TimeStepLimit, numerics: &Numerics) {
        if limit.immobile {
            return; // its nodes never move, so no update can diverge
        }
        let who = format!("cell_types[{}] ({})", limit.cell_type, limit.name);
        let dt = fmt_real(numerics.time_step);
        let zeta = fmt_real(numerics.damping);
        let mass = fmt_real_short(limit.node_mass);
        let stiffness = fmt_real_short(limit.stiffness);
        let max_dt = fmt_real_short(limit.max_time_step);
        let mut judge = |ratio: Real, what: String, fix: &str| {
            let severity = if ratio > TimeStepLimit::LIMIT {
                "the update diverges"
            } else if ratio > TimeStepLimit::LIMIT / 2.0 {
                "above half the stability limit 2, so the run is close to diverging"
            } else {
                return;
            };
            let message = format!(
                "numerics.time_step = {dt} s: {what} = {} for {who} ({severity}; estimated node mass {mass} kg, \
                 node stiffness {stiffness} N/m from {}); the largest stable time step is about {max_dt} s; {fix}",
                fmt_real_short(ratio),
                limit.stiffest_term
            );
            if ratio > TimeStepLimit::LIMIT {
                self.errors.push(message);
            } else {
                self.warnings.push(message);
            }
        };
        match numerics.dynamics {
            Dynamics::Dynamic => {
                judge(
                    limit.damping_ratio,
                    format!("with numerics.damping = {zeta} kg/s the damping ratio ζΔt/m"),
                    "use a smaller time_step or a smaller damping (or dynamics = \"overdamped\")",
                );
                judge(
                    limit.oscillation_ratio,
                    "the oscillation ratio Δt·√(k/m)".to_owned(),
                    "use a smaller time_step (or a larger min_edge_length)",
                );
            }
            Dynamics::Overdamped => judge(
                limit.overdamped_ratio,
                format!("with numerics.damping = {zeta} kg/s the relaxation ratio Δt·k/ζ"),
                &format!(
                    "use a smaller time_step or a larger damping (the paper's overdamped default is {} kg/s)",
                    fmt_real(Numerics::PAPER_OVERDAMPED_DAMPING)
                ),
            ),
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Reading: overlay the user's tables on the defaults of each kind, then deserialise.

/// Serialises a parameter struct to a TOML value. The structs hold only numbers, strings and
/// tables, so this cannot fail.
fn to_value<T: Serialize>(value: &T) -> Value {
    Value::try_from(value).expect("parameter structs serialise to TOML")
}

/// Merges a user's file into the defaults and deserialises; Err holds every schema problem found.
fn resolve(mut user: Table) -> Result<Parameters, Vec<String>> {
    let mut problems = Vec::new();

    let user_numerics = user.remove("numerics");
    let dynamics = user_numerics
        .as_ref()
        .and_then(|numerics| numerics.get("dynamics"))
        .and_then(|value| parse_choice(value, &Dynamics::ALL, "numerics.dynamics", &mut problems))
        .unwrap_or_default();
    let mut numerics = to_value(&Numerics::default_for(dynamics));
    if let Some(user_numerics) = user_numerics {
        if let Some(value) = user_numerics.get("contact_model") {
            parse_choice(value, &ContactModel::ALL, "numerics.contact_model", &mut problems);
        }
        overlay(&mut numerics, user_numerics, "numerics", &mut problems);
    }

    let cell_types = match user.remove("cell_types") {
        None => to_value(&Parameters::default().cell_types),
        Some(Value::Array(entries)) => Value::Array(
            entries
                .into_iter()
                .enumerate()
                .map(|(index, entry)| resolve_cell_type(index, entry, &mut problems))
                .collect(),
        ),
        Some(other) => {
            problems.push(format!(
                "cell_types = {}: expected an array of tables (write each entry as a [[cell_types]] section)",
                show(&other)
            ));
            Value::Array(Vec::new())
        }
    };

    let mut simulation = to_value(&SimulationSettings::default());
    if let Some(user_simulation) = user.remove("simulation") {
        if let Some(value) = user_simulation.get("mode") {
            parse_choice(value, &SimulationMode::ALL, "simulation.mode", &mut problems);
        }
        if let Some(value) = user_simulation.get("method") {
            parse_choice(value, &RelaxMethod::ALL, "simulation.method", &mut problems);
        }
        overlay(&mut simulation, user_simulation, "simulation", &mut problems);
    }

    for key in user.keys() {
        problems.push(unknown_field(key, "at the top level", ["cell_types", "numerics", "simulation"].iter().copied()));
    }
    if !problems.is_empty() {
        return Err(problems);
    }
    let mut merged = Table::new();
    merged.insert("numerics".to_owned(), numerics);
    merged.insert("cell_types".to_owned(), cell_types);
    merged.insert("simulation".to_owned(), simulation);
    // Every schema problem was caught above; this is the backstop (deny_unknown_fields included).
    Value::Table(merged).try_into().map_err(|error: toml::de::Error| vec![error.to_string().replace('\n', " ")])
}

/// One `[[cell_types]]` entry overlaid on the defaults of its kind.
fn resolve_cell_type(index: usize, entry: Value, problems: &mut Vec<String>) -> Value {
    let path = format!("cell_types[{index}]");
    if !entry.is_table() {
        problems.push(format!("{path} = {}: expected a table", show(&entry)));
        return entry;
    }
    let kind = entry
        .get("kind")
        .and_then(|value| parse_choice(value, &CellKind::ALL, &format!("{path}.kind"), problems))
        .unwrap_or(CellKind::Epithelial);
    let mut merged = to_value(&CellTypeParams::default_for(kind));
    overlay(&mut merged, entry, &path, problems);
    merged
}

/// Reads an enum given as a string; records a problem naming the choices if it is not one. A
/// non-string is left to [`overlay`]'s type check.
fn parse_choice<T: Serialize + DeserializeOwned + Copy>(
    value: &Value,
    all: &[T],
    path: &str,
    problems: &mut Vec<String>,
) -> Option<T> {
    let text = value.as_str()?;
    if let Some(&choice) = all.iter().find(|choice| to_value(*choice).as_str() == Some(text)) {
        return Some(choice);
    }
    let names: Vec<String> = all.iter().map(|choice| show(&to_value(choice))).collect();
    problems.push(format!("{path} = {}: unknown value, expected one of {}", show(value), names.join(", ")));
    None
}

/// Overlays `user` on `base` recursively: tables key by key, other values replaced. Records unknown
/// keys and values of the wrong type (integers are accepted for floats).
fn overlay(base: &mut Value, user: Value, path: &str, problems: &mut Vec<String>) {
    match (base, user) {
        (Value::Table(base), Value::Table(user)) => {
            for (key, value) in user {
                match base.get_mut(&key) {
                    Some(slot) => overlay(slot, value, &format!("{path}.{key}"), problems),
                    None => problems.push(unknown_field(&key, &format!("in {path}"), base.keys().map(String::as_str))),
                }
            }
        }
        (base, Value::Integer(integer)) if base.is_float() => *base = Value::Float(integer as Real),
        (base, user) if std::mem::discriminant(&*base) == std::mem::discriminant(&user) => *base = user,
        (base, user) => problems.push(format!("{path} = {}: expected {}", show(&user), type_name(base))),
    }
}

/// `location` is "in <path>" or "at the top level".
fn unknown_field<'a>(key: &str, location: &str, expected: impl Iterator<Item = &'a str>) -> String {
    let expected: Vec<&str> = expected.collect();
    let suggestion = expected
        .iter()
        .map(|candidate| (edit_distance(key, candidate), *candidate))
        .filter(|&(distance, _)| distance <= 3)
        .min()
        .map(|(_, candidate)| format!(" (did you mean `{candidate}`?)"))
        .unwrap_or_default();
    let expected = expected.iter().map(|name| format!("`{name}`")).collect::<Vec<_>>().join(", ");
    format!("unknown field `{key}` {location}, expected one of {expected}{suggestion}")
}

/// Levenshtein distance, for "did you mean" hints.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diagonal = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let substitution = diagonal + usize::from(ca != cb);
            diagonal = row[j + 1];
            row[j + 1] = substitution.min(row[j] + 1).min(row[j + 1] + 1);
        }
    }
    row[b.len()]
}

fn type_name(value: &Value) -> &'static str {
    match value {
        Value::String(_) => "a string",
        Value::Integer(_) => "an integer",
        Value::Float(_) => "a number",
        Value::Boolean(_) => "a boolean",
        Value::Datetime(_) => "a date-time",
        Value::Array(_) => "an array",
        Value::Table(_) => "a table",
    }
}

/// A value for a message: scalars as TOML, containers by type.
fn show(value: &Value) -> String {
    match value {
        Value::Float(x) => fmt_real(*x),
        Value::Array(_) | Value::Table(_) => type_name(value).to_owned(),
        scalar => scalar.to_string(),
    }
}

// ---------------------------------------------------------------------------------------------
// Writing.

/// A float as a TOML literal that reads back exactly: exponent form for small and large magnitudes
/// (`2e-7`, `1e9`), decimal otherwise (`2500.0`, `0.001`), `inf`/`nan` as TOML spells them.
fn fmt_real(x: Real) -> String {
    if x.is_nan() {
        "nan".to_owned()
    } else if x.is_infinite() {
        if x > 0.0 { "inf" } else { "-inf" }.to_owned()
    } else if x != 0.0 && !(1e-3..1e5).contains(&x.abs()) {
        format!("{x:e}")
    } else {
        format!("{x:?}")
    }
}

/// A float to 3 significant digits, for estimates in messages.
fn fmt_real_short(x: Real) -> String {
    if x.is_finite() && x != 0.0 && !(1e-3..1e5).contains(&x.abs()) {
        format!("{x:.2e}")
    } else if x.is_finite() {
        format!("{x:.3}")
    } else {
        fmt_real(x)
    }
}

/// Documentation of one section or field of the config, keyed by its path without list indices;
/// `*` stands for any face type.
struct FieldDoc {
    path: &'static str,
    unit: &'static str,
    text: &'static str,
}

/// The config reference, in the order fields are written. Values are not repeated here: the
/// commented defaults take them from the serialised [`Parameters::default`].
static FIELD_DOCS: &[FieldDoc] = &[
    FieldDoc {
        path: "numerics",
        unit: "",
        text: "Numerical parameters shared by all cells (paper Table 2, numerical parameters).",
    },
    FieldDoc {
        path: "numerics.min_edge_length",
        unit: "m",
        text: "Minimum edge length l_min: remeshing collapses shorter edges and splits edges longer than l_max = 3·l_min.",
    },
    FieldDoc {
        path: "numerics.contact_cutoff",
        unit: "m",
        text: "Contact cutoff distance c: faces of different cells farther apart do not interact. At most l_max = 3·l_min.",
    },
    FieldDoc {
        path: "numerics.damping",
        unit: "kg/s",
        text: "Viscous damping coefficient ζ per node. The paper's overdamped default is 3e-9 kg/s, which a file with \
               dynamics = \"overdamped\" and no damping gets.",
    },
    FieldDoc {
        path: "numerics.time_step",
        unit: "s",
        text: "Time step Δt. Validation estimates its stability limit per cell type.",
    },
    FieldDoc {
        path: "numerics.dynamics",
        unit: "",
        text: "Equation of motion: \"dynamic\" (node mass ρV/N, damping ζ, semi-implicit Euler) or \"overdamped\" (r += Δt·f/ζ).",
    },
    FieldDoc {
        path: "numerics.contact_model",
        unit: "",
        text: "Contact model: \"spring\" (paper Eq. 2, node–face springs with adhesion ω and repulsion ξ) or \"coupling\" \
               (nodes of different cells closer than c are tied together).",
    },
    FieldDoc {
        path: "numerics.seed",
        unit: "",
        text: "Seed of every random draw (growth rates, division volumes and planes).",
    },
    FieldDoc {
        path: "cell_types",
        unit: "",
        text: "One parameter set per cell type; a cell's cell_type (SimuCell3D's cell_type_id) indexes this list.",
    },
    FieldDoc { path: "cell_types.name", unit: "", text: "Name of the cell type, unique within the list." },
    FieldDoc {
        path: "cell_types.kind",
        unit: "",
        text: "What the cells are: \"epithelial\", \"ecm\", \"lumen\", \"nucleus\" or \"static\". Omitted fields of the entry \
               take the defaults of this kind.",
    },
    FieldDoc {
        path: "cell_types.mass_density",
        unit: "kg/m³",
        text: "Mass density ρ; node mass m = ρV/N in the dynamic model.",
    },
    FieldDoc { path: "cell_types.bulk_modulus", unit: "Pa", text: "Bulk modulus K: pressure p = −K ln(V/V0)." },
    FieldDoc { path: "cell_types.max_pressure", unit: "Pa", text: "Largest internal pressure p_max; inf for no cap." },
    FieldDoc {
        path: "cell_types.min_volume",
        unit: "m³",
        text: "Volume V_min below which a cell is removed (apoptosis); 0 for never.",
    },
    FieldDoc {
        path: "cell_types.division_volume",
        unit: "m³",
        text: "Mean volume V_max at which a cell divides; inf for never.",
    },
    FieldDoc {
        path: "cell_types.division_volume_std",
        unit: "m³",
        text: "Standard deviation of the division volume drawn per cell.",
    },
    FieldDoc {
        path: "cell_types.growth_rate",
        unit: "m³/s",
        text: "Mean volumetric growth rate g = dV0/dt; negative shrinks.",
    },
    FieldDoc {
        path: "cell_types.growth_rate_std",
        unit: "m³/s",
        text: "Standard deviation of the growth rate drawn per cell.",
    },
    FieldDoc {
        path: "cell_types.target_isoperimetric_ratio",
        unit: "1",
        text: "Target isoperimetric ratio Q0 = A³/V², giving the target area A0 = (Q0·V0²)^(1/3); at least 36π ≈ 113.1 (a sphere).",
    },
    FieldDoc {
        path: "cell_types.area_elasticity",
        unit: "J",
        text: "Area elasticity modulus k_a of the energy (k_a/2)(A/A0 − 1)².",
    },
    FieldDoc {
        path: "cell_types.max_coupling_curvature",
        unit: "1/m",
        text: "Largest mean curvature H_max at which a node may be coupled to another cell (coupling contact model).",
    },
    FieldDoc {
        path: "cell_types.faces",
        unit: "",
        text: "Membrane parameters per face type (apical, lateral, basal); each face of a cell has one type.",
    },
    FieldDoc {
        path: "cell_types.faces.apical",
        unit: "",
        text: "Apical faces: facing a lumen (every face of an unpolarised cell).",
    },
    FieldDoc { path: "cell_types.faces.lateral", unit: "", text: "Lateral faces: facing another cell." },
    FieldDoc { path: "cell_types.faces.basal", unit: "", text: "Basal faces: facing the exterior or the ECM." },
    FieldDoc {
        path: "cell_types.faces.*.surface_tension",
        unit: "N/m",
        text: "Surface tension γ: energy γ·A per face.",
    },
    FieldDoc {
        path: "cell_types.faces.*.bending_modulus",
        unit: "J",
        text: "Bending modulus k_b of the discrete hinge energy.",
    },
    FieldDoc {
        path: "cell_types.faces.*.adhesion",
        unit: "Pa/m",
        text: "Adhesion strength ω: contact stress per unit separation.",
    },
    FieldDoc {
        path: "cell_types.faces.*.repulsion",
        unit: "Pa/m",
        text: "Repulsion strength ξ: contact stress per unit penetration.",
    },
    FieldDoc {
        path: "simulation",
        unit: "",
        text: "What `tissuefit simulate` runs, with which method, when it stops and how often it saves.",
    },
    FieldDoc {
        path: "simulation.mode",
        unit: "",
        text: "\"equilibrium\" (relax until the stopping criteria hold, or max_steps: not converged) or \"time\" (integrate for duration, with growth).",
    },
    FieldDoc {
        path: "simulation.method",
        unit: "",
        text: "Equilibrium method: \"fire\" (FIRE 2.0 minimiser, adaptive step: far fewer force evaluations) or \"integrate\" (the equations of motion of numerics.dynamics).",
    },
    FieldDoc { path: "simulation.duration", unit: "s", text: "Simulated time span of a \"time\" run." },
    FieldDoc {
        path: "simulation.max_steps",
        unit: "",
        text: "Step budget of an \"equilibrium\" run; reaching it is reported as not converged.",
    },
    FieldDoc {
        path: "simulation.sampling_period",
        unit: "s",
        text: "Simulated time between saved frames (and stats rows) of a \"time\" run.",
    },
    FieldDoc {
        path: "simulation.sample_every_steps",
        unit: "",
        text: "Steps between saved frames (and stats rows) of an \"equilibrium\" run.",
    },
    FieldDoc {
        path: "simulation.force_tolerance",
        unit: "",
        text: "Equilibrium when the largest nodal force is below this fraction of the typical tension force γ·l_min (γ: mean surface tension of the moving cells' faces) ...",
    },
    FieldDoc {
        path: "simulation.energy_tolerance",
        unit: "",
        text: "... and the total energy changes by less than this fraction per step ...",
    },
    FieldDoc {
        path: "simulation.volume_tolerance",
        unit: "",
        text: "... and no cell volume changes by more than this fraction per step.",
    },
];

const HEADER: &str = "\
tissuefit simulation parameters. SI units; every value below is the default.

A config file may be partial:
- a missing [numerics] field takes its default (damping: 3e-9 kg/s if dynamics = \"overdamped\");
- a given list of [[cell_types]] replaces the default list; a cell's cell_type (SimuCell3D's
  cell_type_id) indexes it, in file order;
- a missing field of a [[cell_types]] entry, including single fields of its
  [cell_types.faces.apical|lateral|basal] tables, takes the default of the entry's kind
  (epithelial if kind is omitted). The five entries below are the defaults of the five kinds.
Unknown keys are errors. inf is allowed for max_pressure and division_volume.";

/// The doc entry of a path like `cell_types.faces.apical.adhesion` (indices already stripped).
fn field_doc(path: &str) -> Option<&'static FieldDoc> {
    let starred = star_face_type(path);
    FIELD_DOCS.iter().find(|doc| doc.path == path).or_else(|| FIELD_DOCS.iter().find(|doc| doc.path == starred))
}

/// `cell_types.faces.<type>.<field>` → `cell_types.faces.*.<field>`; other paths unchanged.
fn star_face_type(path: &str) -> String {
    match path.strip_prefix("cell_types.faces.").and_then(|rest| rest.split_once('.')) {
        Some((_, field)) => format!("cell_types.faces.*.{field}"),
        None => path.to_owned(),
    }
}

/// The unit of a path with list indices (`cell_types[0].bulk_modulus`), for messages.
fn unit_of(path: &str) -> &'static str {
    let mut plain = String::with_capacity(path.len());
    let mut in_index = false;
    for c in path.chars() {
        match c {
            '[' => in_index = true,
            ']' => in_index = false,
            c if !in_index => plain.push(c),
            _ => {}
        }
    }
    field_doc(&plain).map_or("", |doc| match doc.unit {
        "1" => "",
        unit => unit,
    })
}

fn join_path(parent: &str, key: &str) -> String {
    if parent.is_empty() { key.to_owned() } else { format!("{parent}.{key}") }
}

/// Keys of a table in documentation order; undocumented keys (none, if FIELD_DOCS is complete) last.
fn ordered_keys<'a>(table: &'a Table, doc_path: &str) -> Vec<&'a str> {
    let mut keys: Vec<&str> = Vec::with_capacity(table.len());
    for doc in FIELD_DOCS {
        if let Some((key, _)) = table.get_key_value(doc.path.rsplit('.').next().unwrap_or(doc.path))
            && field_doc(&join_path(doc_path, key)).is_some_and(|found| found.path == doc.path)
            && !keys.contains(&key.as_str())
        {
            keys.push(key);
        }
    }
    keys.extend(table.keys().map(String::as_str).filter(|key| !keys.contains(key)).collect::<Vec<_>>());
    keys
}

fn is_section(value: &Value) -> bool {
    match value {
        Value::Table(_) => true,
        Value::Array(items) => !items.is_empty() && items.iter().all(Value::is_table),
        _ => false,
    }
}

fn format_value(value: &Value) -> String {
    match value {
        Value::Float(x) => fmt_real(*x),
        Value::Array(items) => format!("[{}]", items.iter().map(format_value).collect::<Vec<_>>().join(", ")),
        other => other.to_string(),
    }
}

/// Writes `# ` comment lines, wrapped at about 100 columns.
fn write_comment(out: &mut String, text: &str) {
    for paragraph in text.lines() {
        let mut line = String::from("#");
        for word in paragraph.split_whitespace() {
            if line.len() > 1 && line.chars().count() + 1 + word.chars().count() > 100 {
                out.push_str(&line);
                out.push('\n');
                line = String::from("#");
            }
            line.push(' ');
            line.push_str(word);
        }
        out.push_str(&line);
        out.push('\n');
    }
}

fn write_toml(params: &Parameters, comments: bool) -> String {
    let Value::Table(root) = to_value(params) else { unreachable!("a struct serialises to a table") };
    let mut out = String::new();
    if comments {
        write_comment(&mut out, HEADER);
    }
    write_table(&mut out, &root, "", "", None, comments);
    out.trim_start().to_owned()
}

/// Writes a table's plain fields, then its sub-tables and arrays of tables.
/// `doc_path` is the path without indices, `header` the TOML section name, `kind` the kind of the
/// enclosing cell type (for "default for kind" comments).
fn write_table(out: &mut String, table: &Table, doc_path: &str, header: &str, kind: Option<&str>, comments: bool) {
    let keys = ordered_keys(table, doc_path);
    for &key in &keys {
        let value = &table[key];
        if is_section(value) {
            continue;
        }
        let path = join_path(doc_path, key);
        let formatted = format_value(value);
        if comments {
            let doc = field_doc(&path);
            let unit = doc.map_or("", |doc| doc.unit);
            let unit = match unit {
                "" => String::new(),
                "1" => " [dimensionless]".to_owned(),
                unit => format!(" [{unit}]"),
            };
            let default = match kind {
                Some(kind) => format!("Default for kind {kind}: {formatted}."),
                None => format!("Default: {formatted}."),
            };
            write_comment(out, &format!("{}{unit} {default}", doc.map_or("(undocumented)", |doc| doc.text)));
        }
        let _ = writeln!(out, "{key} = {formatted}");
    }
    for &key in &keys {
        let path = join_path(doc_path, key);
        let section = join_path(header, key);
        let section_doc = field_doc(&path).map_or("(undocumented)", |doc| doc.text);
        match &table[key] {
            Value::Table(sub) => {
                out.push('\n');
                if comments {
                    write_comment(out, section_doc);
                }
                let _ = writeln!(out, "[{section}]");
                write_table(out, sub, &path, &section, kind, comments);
            }
            Value::Array(items) if is_section(&table[key]) => {
                for (index, item) in items.iter().enumerate() {
                    let Value::Table(item) = item else { continue };
                    let item_kind = item.get("kind").and_then(Value::as_str);
                    out.push('\n');
                    if comments {
                        if index == 0 {
                            write_comment(out, section_doc);
                        }
                        let kind_note = item_kind.map(|kind| format!(", kind {kind}")).unwrap_or_default();
                        write_comment(
                            out,
                            &format!("{key}[{index}]{kind_note}: used by cells with cell_type = {index}."),
                        );
                    }
                    let _ = writeln!(out, "[[{section}]]");
                    write_table(out, item, &path, &section, item_kind, comments);
                }
            }
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn load(text: &str) -> Result<Parameters, ParamError> {
        Parameters::from_toml_str(text, "params.toml")
    }

    /// The error message of a config that must be rejected.
    fn rejection(text: &str) -> String {
        match load(text) {
            Ok(params) => panic!("accepted: {params:?}"),
            Err(error) => error.to_string(),
        }
    }

    #[test]
    fn defaults_validate_without_errors_or_warnings() {
        let params = Parameters::default();
        let warnings = params.validate().expect("defaults are valid");
        assert!(warnings.is_empty(), "{warnings:?}");
        // The paper's defaults sit well inside the dynamic stability limits: ζΔt/m ≈ 0.1.
        let epithelial = &params.time_step_limits()[0];
        assert!((0.05..0.2).contains(&epithelial.damping_ratio), "{epithelial:?}");
        assert!(epithelial.oscillation_ratio < 1.0, "{epithelial:?}");
    }

    #[test]
    fn default_list_follows_cell_kind_codes() {
        let params = Parameters::default();
        for kind in CellKind::ALL {
            let cell_type = params.cell_type(kind.code()).expect("one entry per kind");
            assert_eq!(cell_type.kind, kind);
            assert_eq!(cell_type.name, kind.name());
        }
        assert!(params.cell_type(5).is_none());
        assert_eq!(params.cell_types[1].bulk_modulus, 0.0);
        assert_eq!(params.cell_types[2].faces.lateral.repulsion, 5e9);
        assert_eq!(params.cell_types[3].faces.basal.surface_tension, 0.0);
        assert_eq!(params.cell_types[4].faces.apical.adhesion, 0.0);
    }

    #[test]
    fn commented_defaults_read_back_exactly() {
        let text = Parameters::default_toml_commented();
        assert_eq!(load(&text).expect("commented defaults load"), Parameters::default());
        assert!(text.contains("division_volume = inf"), "{text}");
        let plain = Parameters::default().to_toml_string();
        assert_eq!(load(&plain).expect("plain defaults load"), Parameters::default());
    }

    #[test]
    fn resolved_config_round_trips() {
        let mut params = Parameters::default();
        params.numerics.seed = 42;
        params.numerics.contact_model = ContactModel::Coupling;
        params.cell_types[0].faces.lateral.surface_tension = 1.234_567_891_234e-4;
        params.cell_types[0].max_pressure = Real::INFINITY;
        assert_eq!(load(&params.to_toml_string()).expect("loads"), params);
    }

    fn count_leaves(value: &Value) -> usize {
        match value {
            Value::Table(table) => table.values().map(count_leaves).sum(),
            Value::Array(items) if is_section(value) => items.iter().map(count_leaves).sum(),
            _ => 1,
        }
    }

    #[test]
    fn every_default_field_is_documented() {
        let text = Parameters::default_toml_commented();
        let lines: Vec<&str> = text.lines().collect();
        // The comment block directly above line `i`, without the `# ` markers.
        let comment_above = |i: usize| {
            let start = lines[..i].iter().rposition(|line| !line.starts_with('#')).map_or(0, |j| j + 1);
            lines[start..i].iter().map(|line| line.trim_start_matches('#').trim()).collect::<Vec<_>>().join(" ")
        };
        let mut assignments = 0;
        for (i, line) in lines.iter().enumerate() {
            if line.starts_with('#') || line.trim().is_empty() {
                continue;
            }
            let comment = comment_above(i);
            assert!(!comment.is_empty() && !comment.contains("(undocumented)"), "{line:?} has no comment");
            if line.starts_with('[') {
                continue;
            }
            assignments += 1;
            let (key, value) = line.split_once(" = ").expect("a `key = value` line");
            assert!(comment.contains(&format!(": {value}.")), "{key}: comment {comment:?} states no default");
            assert!(comment.len() > key.len() + 20, "{key}: comment {comment:?} explains nothing");
        }
        assert_eq!(assignments, count_leaves(&to_value(&Parameters::default())));
        // Fields are written in the documented (struct) order, not alphabetically.
        let position = |needle: &str| text.find(needle).unwrap_or_else(|| panic!("{needle} missing"));
        assert!(position("min_edge_length =") < position("contact_cutoff ="));
        assert!(position("surface_tension =") < position("adhesion ="));
        // Every documented path is used, so the table holds no stale entries.
        for doc in FIELD_DOCS {
            let key = doc.path.rsplit('.').next().unwrap_or(doc.path);
            assert!(text.contains(&format!("{key} =")) || text.contains(&format!("{key}]")), "stale doc {}", doc.path);
        }
    }

    #[test]
    fn partial_cell_type_takes_the_defaults_of_its_kind() {
        let params = load(
            "[numerics]\n\
             time_step = 5e-8\n\
             [[cell_types]]\n\
             kind = \"nucleus\"\n\
             bulk_modulus = 3000\n\
             [cell_types.faces.lateral]\n\
             surface_tension = 2e-4\n",
        )
        .expect("valid partial config");
        let nucleus = CellTypeParams::default_for(CellKind::Nucleus);
        assert_eq!(params.numerics, Numerics { time_step: 5e-8, ..Numerics::default() });
        assert_eq!(params.cell_types.len(), 1);
        let t = &params.cell_types[0];
        assert_eq!(t.name, "nucleus");
        assert_eq!(t.bulk_modulus, 3000.0);
        assert_eq!(t.growth_rate, nucleus.growth_rate);
        assert_eq!(t.division_volume, Real::INFINITY);
        assert_eq!(t.faces.apical, nucleus.faces.apical);
        assert_eq!(t.faces.lateral.surface_tension, 2e-4);
        assert_eq!(t.faces.lateral.repulsion, nucleus.faces.lateral.repulsion);
        assert_eq!(t.faces.lateral.adhesion, 0.0);
        // Without a kind, an entry is epithelial.
        let params = load("[[cell_types]]\nname = \"a\"\n").expect("valid");
        assert_eq!(params.cell_types[0], CellTypeParams { name: "a".into(), ..CellTypeParams::default() });
    }

    #[test]
    fn overdamped_file_gets_the_overdamped_damping() {
        let params = load("[numerics]\ndynamics = \"overdamped\"\n").expect("valid");
        assert_eq!(params.numerics.damping, Numerics::PAPER_OVERDAMPED_DAMPING);
        assert!(params.validate().expect("valid").is_empty());
    }

    #[test]
    fn unknown_keys_are_rejected_with_their_path() {
        let message = rejection("[[cell_types]]\n[cell_types.faces.apical]\nsurface_tenson = 1e-3\n");
        assert!(message.starts_with("params.toml: "), "{message}");
        assert!(message.contains("unknown field `surface_tenson` in cell_types[0].faces.apical"), "{message}");
        assert!(message.contains("did you mean `surface_tension`?"), "{message}");
        let message = rejection("[numerics]\ntimestep = 1e-7\n[solver]\n");
        assert!(message.contains("`timestep` in numerics"), "{message}");
        assert!(message.contains("`solver` at the top level"), "{message}");
    }

    #[test]
    fn wrong_types_and_choices_are_rejected() {
        let message = rejection("[numerics]\ndamping = \"high\"\n");
        assert!(message.contains("numerics.damping = \"high\": expected a number"), "{message}");
        let message = rejection("[[cell_types]]\nkind = \"nucleous\"\n");
        assert!(message.contains("cell_types[0].kind = \"nucleous\": unknown value"), "{message}");
        let message = rejection("[numerics]\ndynamics = \"fast\"\n");
        assert!(message.contains("numerics.dynamics"), "{message}");
        let message = rejection("cell_types = 3\n");
        assert!(message.contains("array of tables"), "{message}");
        assert!(matches!(load("[numerics\n"), Err(ParamError::Syntax { .. })));
    }

    #[test]
    fn invalid_values_are_rejected_naming_the_field() {
        let cases = [
            (
                "[[cell_types]]\n[cell_types.faces.apical]\nsurface_tension = -1e-3\n",
                "cell_types[0].faces.apical.surface_tension = -0.001 N/m: must be ≥ 0",
            ),
            ("[[cell_types]]\nbulk_modulus = nan\n", "cell_types[0].bulk_modulus = nan Pa: is NaN"),
            ("[numerics]\ncontact_cutoff = 7e-7\n", "numerics.contact_cutoff = 7e-7 m exceeds l_max"),
            (
                "[[cell_types]]\ntarget_isoperimetric_ratio = 100\n",
                "cell_types[0].target_isoperimetric_ratio = 100.0: is below 36π",
            ),
            ("[numerics]\ntime_step = 1e-4\n", "numerics.time_step = 1e-4 s: with numerics.damping"),
            ("[[cell_types]]\nmin_volume = 2e-15\n", "cell_types[0].min_volume = 2e-15 m³ is not below"),
            ("[[cell_types]]\ngrowth_rate = inf\n", "cell_types[0].growth_rate = inf m³/s: must be finite"),
            (
                "[[cell_types]]\n[[cell_types]]\n",
                "cell_types[1].name = \"epithelial\" is already the name of cell_types[0]",
            ),
            ("cell_types = []\n", "cell_types is empty"),
        ];
        for (text, expected) in cases {
            let message = rejection(text);
            assert!(message.contains(expected), "expected {expected:?} in {message:?}");
            assert!(message.starts_with("params.toml: "), "{message}");
        }
    }

    #[test]
    fn every_problem_is_reported_on_its_own_line() {
        let message = rejection("[numerics]\ndamping = -1\n[[cell_types]]\nmass_density = 0\n");
        let lines: Vec<&str> = message.lines().collect();
        assert_eq!(lines.len(), 2, "{message}");
        assert!(lines[0].starts_with("params.toml: numerics.damping = -1.0 kg/s: must be > 0"), "{message}");
        assert!(lines[1].starts_with("params.toml: cell_types[0].mass_density = 0.0 kg/m³"), "{message}");
    }

    #[test]
    fn unstable_time_step_is_reported_beside_other_errors() {
        let message = rejection(
            "[numerics]\ntime_step = 1e-4\n[[cell_types]]\ngrowth_rate = nan\n[[cell_types]]\nname = \"b\"\n",
        );
        assert!(message.contains("cell_types[0].growth_rate = nan"), "{message}");
        assert!(message.contains("numerics.time_step = 1e-4 s") && message.contains("cell_types[1] (b)"), "{message}");
        assert!(!message.contains("cell_types[0] (epithelial)"), "{message}");
    }

    #[test]
    fn time_step_limits_flag_unstable_steps() {
        let mut params = Parameters::default();
        params.numerics.time_step = 1e-4;
        let message = params.validate().expect_err("unstable").to_string();
        assert!(message.contains("largest stable time step"), "{message}");
        let limits = params.time_step_limits();
        assert!(limits[0].damping_ratio > TimeStepLimit::LIMIT, "{:?}", limits[0]);
        let max_time_step = limits
            .iter()
            .filter(|limit| !limit.immobile)
            .map(|limit| limit.max_time_step)
            .fold(Real::INFINITY, Real::min);
        assert!(max_time_step < 1e-6 && max_time_step > 1e-8, "{limits:?}");

        // Just below the limit: valid, with a warning.
        params.numerics.time_step = 0.9 * max_time_step;
        let warnings = params.validate().expect("stable");
        assert!(warnings.iter().any(|w| w.contains("half the stability limit")), "{warnings:?}");

        // Overdamped with a damping 300× below the paper's overdamped default is unstable.
        params.numerics = Numerics { dynamics: Dynamics::Overdamped, damping: 1e-11, ..Numerics::default() };
        let message = params.validate().expect_err("unstable").to_string();
        assert!(message.contains("Δt·k/ζ"), "{message}");
        assert!(message.contains("larger damping"), "{message}");
    }

    #[test]
    fn immobile_kinds_have_no_time_step_limit() {
        let mut params = Parameters::default();
        params.cell_types[1].faces.basal.repulsion = 1e15; // ECM: absurdly stiff, but it never moves
        assert!(params.validate().is_ok());
        params.cell_types[2].faces.basal.repulsion = 1e15; // lumen: moves
        let message = params.validate().expect_err("unstable").to_string();
        assert!(message.contains("cell_types[2] (lumen)") && message.contains("contact"), "{message}");
    }

    #[test]
    fn pressure_is_capped() {
        let mut cell_type = CellTypeParams::default();
        // Compressed to half its target volume: K ln 2 ≈ 1733 Pa, below the 2500 Pa cap.
        assert!((cell_type.pressure(0.5, 1.0) - 2500.0 * 2.0_f64.ln()).abs() < 1e-9);
        // Compressed to a tenth: K ln 10 ≈ 5756 Pa, capped.
        assert_eq!(cell_type.pressure(0.1, 1.0), 2500.0);
        assert!(cell_type.pressure(2.0, 1.0) < 0.0);
        cell_type.max_pressure = Real::INFINITY;
        assert!((cell_type.pressure(0.1, 1.0) - 2500.0 * 10.0_f64.ln()).abs() < 1e-9);
    }

    #[test]
    fn face_types_index_their_parameters() {
        let mut faces = FaceTypeParams::uniform(FaceParams::default());
        faces.get_mut(FaceType::Basal).adhesion = 7.0;
        assert_eq!(faces.basal.adhesion, 7.0);
        assert_eq!(faces.get(FaceType::Basal).adhesion, 7.0);
        assert_eq!(faces.iter().map(|(t, _)| t).collect::<Vec<_>>(), FaceType::ALL.to_vec());
    }

    #[test]
    fn floats_print_as_exact_toml() {
        for x in [2e-7, 1e9, 2500.0, 0.001, 250.0, 0.0, 1.4e-15, 3e-9, 12345.678, -0.001, 1e5, 0.1 + 0.2] {
            let text = format!("x = {}", fmt_real(x));
            let table: Table = toml::from_str(&text).expect("valid TOML float");
            assert_eq!(table["x"].as_float(), Some(x), "{text}");
        }
        assert_eq!(fmt_real(Real::INFINITY), "inf");
    }
}

//! Validation of parameters: every value against its bound, and the time-step stability estimate.

use super::writing::{fmt_real, fmt_real_short, unit_of};
use super::*;
use std::collections::HashMap;

/// w/(2γ) from which spring adhesion with the vertex quadrature is warned about: the lower end of
/// the adhesions users fit (issue 20's regime: 0.05–0.6); the defaults' ω = 1e9 Pa/m at c = 0.2 µm
/// (w/(2γ) = 0.01 at γ = 1 mN/m) stays below it.
const VERTEX_QUADRATURE_WARN_RATIO: Real = 0.05;

impl Parameters {
    /// Returns (errors, warnings).
    pub(super) fn check(&self) -> (Vec<String>, Vec<String>) {
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
        report.number(
            "numerics.polarity_voxel_size",
            numerics.polarity_voxel_size,
            numerics_defaults.polarity_voxel_size,
            Bound::NonNegative,
        );
        report.number(
            "numerics.polarity_min_lumen_fraction",
            numerics.polarity_min_lumen_fraction,
            numerics_defaults.polarity_min_lumen_fraction,
            Bound::NonNegative,
        );
        if numerics.polarity_interval == 0 {
            report.errors.push(
                "numerics.polarity_interval = 0: must be at least 1 (steps between two ray-casting polarisations)"
                    .to_owned(),
            );
        }
        let paper_l_max = 3.0 * numerics.min_edge_length;
        if l_min_ok && cutoff_ok && numerics.contact_cutoff > paper_l_max {
            report.errors.push(format!(
                "numerics.contact_cutoff = {} m exceeds 3·numerics.min_edge_length = {} m (the paper's l_max); the \
                 reference model requires c ≤ l_max so that a contact stays within one edge of the surface; lower \
                 contact_cutoff or raise min_edge_length",
                fmt_real(numerics.contact_cutoff),
                fmt_real(paper_l_max)
            ));
        }
        let ratio = numerics.max_edge_ratio;
        if !(ratio.is_finite() && ratio >= 2.0) {
            report.errors.push(format!(
                "numerics.max_edge_ratio = {}: must be a number of at least 2 (l_max/l_min; a split halves an edge, \
                 which must not make it shorter than l_min) (default: {})",
                fmt_real(ratio),
                fmt_real(numerics_defaults.max_edge_ratio)
            ));
        } else if ratio > 10.0 {
            report.warnings.push(format!(
                "numerics.max_edge_ratio = {}: edges up to {}·l_min leave curved surfaces coarse (default: {})",
                fmt_real(ratio),
                fmt_real(ratio),
                fmt_real(numerics_defaults.max_edge_ratio)
            ));
        }

        // Plausible for cells, or a unit slip (a bare number is metres): warned, not refused.
        for (key, l) in [
            ("numerics.min_edge_length", numerics.min_edge_length),
            ("numerics.contact_cutoff", numerics.contact_cutoff),
        ] {
            if l > 0.0
                && let Some(w) = crate::files::implausible_length(key, l)
            {
                report.warnings.push(w);
            }
        }
        // Cells' tensions (a nucleus' envelope may be far softer by design).
        for (index, cell_type) in self.cell_types.iter().enumerate().filter(|(_, t)| t.kind == CellKind::Epithelial) {
            for (face_type, face) in cell_type.faces.iter() {
                let key = format!("cell_types[{index}].faces.{}.surface_tension", face_type.name());
                if let Some(w) = crate::files::implausible_tension(&key, face.surface_tension) {
                    report.warnings.push(w);
                }
            }
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
        if !(sim.remesh_below_edge_fraction.is_finite() && (0.0..1.0).contains(&sim.remesh_below_edge_fraction)) {
            report.errors.push(format!(
                "simulation.remesh_below_edge_fraction = {}: must be a number in [0, 1) (a fraction of \
                 numerics.min_edge_length; 0: never; default {})",
                sim.remesh_below_edge_fraction, sim_defaults.remesh_below_edge_fraction
            ));
        }
        if sim.fire_measured_masses {
            if sim.mode != SimulationMode::Equilibrium || sim.method != RelaxMethod::Fire {
                report.warnings.push(
                    "simulation.fire_measured_masses = true acts only on equilibrium runs with simulation.method = \
                     \"fire\"; this run ignores it"
                        .to_owned(),
                );
            } else if !sim.normal_relaxation {
                report.warnings.push(
                    "simulation.fire_measured_masses = true without simulation.normal_relaxation = true: with the \
                     full forces the faster descent drifts nodes along the contacts and wrinkles the surfaces \
                     (SimuCell3D's doublet: residual 3.2 after 20,000 steps, 15 times the bending energy of its \
                     converged state); set simulation.normal_relaxation = true (docs book: Design notes, \
                     \"Spring contacts and Young–Dupré\")"
                        .to_owned(),
                );
            }
        }
        let adheres = self.numerics.contact_model == ContactModel::Spring
            && self
                .cell_types
                .iter()
                .any(|t| t.kind == CellKind::Epithelial && t.faces.iter().any(|(_, f)| f.adhesion > 0.0));
        if sim.normal_relaxation && !sim.full_forces_at_contacts && adheres && sim.mode == SimulationMode::Equilibrium {
            report.warnings.push(
                "simulation.normal_relaxation = true with adhering spring contacts: moved along their normals only, \
                 nodes at a contact rim lose the adhesion's pull along the surface and the contact line stays near \
                 where it started; such runs report \"converged\" 14–18° short of Young–Dupré at w/(2γ) = 0.5 from \
                 touching spheres; set simulation.full_forces_at_contacts = true so that contact lines slide (docs \
                 book: Design notes, \"Spring contacts and Young–Dupré\")"
                    .to_owned(),
            );
        }
        if sim.full_forces_at_contacts {
            if !sim.normal_relaxation {
                report.warnings.push(
                    "simulation.full_forces_at_contacts = true without simulation.normal_relaxation = true: every node \
                     already keeps its whole force; this run ignores it"
                        .to_owned(),
                );
            } else if self.numerics.contact_model != ContactModel::Spring {
                report.warnings.push(
                    "simulation.full_forces_at_contacts = true acts on spring contacts (numerics.contact_model = \
                     \"spring\"); coupled contacts move along their normals; this run ignores it"
                        .to_owned(),
                );
            }
        }
        if !(sim.checkpoint_every_seconds.is_finite() && sim.checkpoint_every_seconds >= 0.0) {
            report.errors.push(format!(
                "simulation.checkpoint_every_seconds = {}: must be a finite number ≥ 0 (0: not by time)",
                sim.checkpoint_every_seconds
            ));
        }
        // A config must be writable back as TOML, whose integers are 64-bit signed.
        for (key, value) in [
            ("simulation.checkpoint_every_steps", sim.checkpoint_every_steps),
            ("numerics.seed", self.numerics.seed),
            ("numerics.polarity_interval", self.numerics.polarity_interval),
            ("simulation.max_steps", sim.max_steps),
            ("simulation.sample_every_steps", sim.sample_every_steps),
            ("simulation.remesh_every_steps", sim.remesh_every_steps),
            ("simulation.settle_steps", sim.settle_steps),
        ] {
            if value > i64::MAX as u64 {
                report.errors.push(format!("{key} = {value} is larger than the largest TOML integer {}", i64::MAX));
            }
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

        self.check_cell_overrides(&mut report);

        // The stability estimate is meaningless with invalid inputs, and would only add noise.
        if numerics_valid {
            for limit in self.time_step_limits() {
                if type_valid[limit.cell_type] {
                    report.time_step(&limit, numerics);
                }
            }
            let c = numerics.contact_cutoff;
            for (index, cell_type) in self.cell_types.iter().enumerate() {
                if cell_type.kind.is_immobile() || !type_valid[index] {
                    continue;
                }
                for (face_type, face) in cell_type.faces.iter().filter(|(_, f)| f.adhesion_outweighs_tension(c)) {
                    report.warnings.push(format!(
                        "cell_types[{index}].faces.{name}.adhesion = {} Pa/m: its adhesion energy per unit area \
                         ωc²/4 = {} J/m² (c = numerics.contact_cutoff = {} m) is not below {} × the face's \
                         surface_tension = {} N/m; adhesion acts as a negative tension on contact faces, which \
                         crumple once it reaches γ (runs broke down from 0.7γ); keep adhesion below {} Pa/m or \
                         lower contact_cutoff",
                        fmt_real(face.adhesion),
                        fmt_real_short(face.adhesion_well_depth(c)),
                        fmt_real(c),
                        FaceParams::MAX_ADHESION_TENSION_RATIO,
                        fmt_real(face.surface_tension),
                        fmt_real_short(face.max_adhesion(c)),
                        name = face_type.name(),
                    ));
                }
            }
            if let Some(w) = self.vertex_quadrature_bias(&type_valid) {
                report.warnings.push(w);
            }
        }
        (report.errors, report.warnings)
    }

    /// A warning when spring contacts adhere noticeably (w/(2γ) = ωc²/(4γ) ≥
    /// [`VERTEX_QUADRATURE_WARN_RATIO`] on a face of an epithelial cell type) with the vertex quadrature,
    /// whose contact angles settle off Young–Dupré (docs book: Design notes, "Spring contacts and
    /// Young–Dupré"): a run or fit that reads contact angles or w/(2γ) should use the face quadrature.
    fn vertex_quadrature_bias(&self, type_valid: &[bool]) -> Option<String> {
        let n = &self.numerics;
        if n.contact_model != ContactModel::Spring || n.contact_quadrature != ContactQuadrature::Vertices {
            return None;
        }
        let c = n.contact_cutoff;
        let (index, face_type, ratio) = self
            .cell_types
            .iter()
            .enumerate()
            .filter(|(i, t)| t.kind == CellKind::Epithelial && type_valid[*i])
            .flat_map(|(i, t)| {
                t.faces
                    .iter()
                    .filter(|(_, f)| f.surface_tension > 0.0)
                    .map(move |(ft, f)| (i, ft, f.adhesion_well_depth(c) / f.surface_tension))
            })
            .reduce(|a, b| if b.2 > a.2 { b } else { a })?;
        (ratio >= VERTEX_QUADRATURE_WARN_RATIO).then(|| {
            format!(
                "numerics.contact_quadrature = \"vertices\" with spring adhesion (cell_types[{index}].faces.{}: \
                 w/(2γ) = ωc²/(4γ) = {}): with the vertex quadrature adhering cells' contact angles settle off \
                 Young–Dupré (measured on doublets at w/(2γ) = 0.3: 0.5–6.3° too small from R = 2 to 10 µm, 15.7° \
                 at R = 10 µm from an over-adhered start), so angles and a fitted w/(2γ) are biased; set \
                 numerics.contact_quadrature = \"faces\" (about 2.5× the contact cost per step) where they matter \
                 (docs book: Design notes, \"Spring contacts and Young–Dupré\")",
                face_type.name(),
                fmt_real_short(ratio),
            )
        })
    }
}

impl Parameters {
    /// `[[cell_overrides]]`: unique ids, finite values ≥ 0, plausible tensions; a warning when a
    /// value is far above every moving cell type's (the time-step estimate is the types').
    fn check_cell_overrides(&self, report: &mut Report) {
        let mut seen: HashMap<u32, usize> = HashMap::new();
        let moving = || self.cell_types.iter().filter(|t| !t.kind.is_immobile());
        let largest = [
            moving().flat_map(|t| t.faces.iter().map(|(_, f)| f.surface_tension)).fold(0.0, Real::max),
            moving().flat_map(|t| t.faces.iter().map(|(_, f)| f.adhesion)).fold(0.0, Real::max),
        ];
        for (index, entry) in self.cell_overrides.iter().enumerate() {
            if let Some(first) = seen.insert(entry.id, index) {
                report.errors.push(format!(
                    "cell_overrides[{index}].id = {}: cell_overrides[{first}] already names this cell; give each \
                     cell one entry",
                    entry.id
                ));
            }
            for (q, values) in [entry.surface_tension, entry.adhesion].into_iter().enumerate() {
                let (quantity, unit) = crate::mesh::CellOverrides::QUANTITIES[q];
                for (face_type, value) in FaceType::ALL.into_iter().zip(values.to_array()) {
                    let Some(value) = value else { continue };
                    let key = format!("cell_overrides[{index}].{quantity}.{}", face_type.name());
                    if !(value.is_finite() && value >= 0.0) {
                        report
                            .errors
                            .push(format!("{key} = {}: must be a finite number ≥ 0 ({unit})", fmt_real(value)));
                        continue;
                    }
                    if q == 0
                        && let Some(w) = crate::files::implausible_tension(&key, value)
                    {
                        report.warnings.push(w);
                    }
                    if largest[q] > 0.0 && value > 4.0 * largest[q] {
                        report.warnings.push(format!(
                            "{key} = {} {unit} is over 4 × the largest {quantity} of the moving cell types ({} \
                             {unit}); the time-step estimate uses the types' values, so lower numerics.time_step \
                             if the run turns unstable",
                            fmt_real(value),
                            fmt_real(largest[q])
                        ));
                    }
                }
            }
        }
    }
}

/// Time-step stability estimate for one cell type: how close Δt is to making the integrator diverge.
///
/// The estimate models a typical node of the type. Its edges are l = 2·l_min long (between l_min and
/// l_max ≈ 3·l_min, where remeshing keeps them), so it carries the area a_n = (√3/2)·l² of two
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

    pub(super) fn estimate(index: usize, cell_type: &CellTypeParams, numerics: &Numerics) -> Self {
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
        if t.laplace_target_volume && (t.bulk_modulus.is_nan() || t.bulk_modulus <= 0.0) {
            self.errors.push(format!(
                "{} = true needs a bulk modulus K > 0 (cell_types[{index}].bulk_modulus = {}): the target volume that \
                 balances the tension comes from the pressure −K ln(V/V0); set bulk_modulus or drop laplace_target_volume",
                p("laplace_target_volume"),
                fmt_real(t.bulk_modulus)
            ));
        }
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

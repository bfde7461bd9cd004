//! Mesh-dependent numerics derived from the input tissue (issue 22, item 4).
//!
//! Table 2's l_min = c = 0.2 µm suits SimuCell3D's own meshes, not a tissue meshed from a label
//! volume at its voxel size: on a mesh of 1–2 µm edges a 0.2 µm cutoff leaves the gaps between
//! neighbouring surfaces unseen (no adhesion, no repulsion: the cells round up and part), and the
//! residual max|f|/(γ·l_min) is scaled by the wrong length. So a simulation of a given tissue takes
//! l_min from the tissue's mesh when its config does not set `numerics.min_edge_length`:
//! l_min = ⟨edge⟩ / [`MEAN_EDGE_PER_MIN_EDGE`], the l_min `tissuefit mesh` would have used for that
//! mesh. The contact cutoff follows l_min (c = l_min, as in Table 2 and the fit's
//! `forward.match_mesh_length`) when the config does not set it, and when l_min was derived and the
//! config sets no time step, the step is lowered to a quarter of the largest stable one (stability
//! ratio 0.5) when the estimate ([`super::TimeStepLimit`]) at the new l_min puts the default above
//! half the limit. What a config sets is kept, but contradictions with the mesh are warned about
//! with the numbers and the change to make.
//!
//! With the spring contact model and no `repulsion` set anywhere in the config, the repulsion ξ of
//! each moving cell type is derived from its cells ([`Parameters::fit_to_tissue`], issue 20 item 3):
//! ξ·c = [`crate::mechanics::REPULSION_PER_PRESSURE`] × the largest Laplace pressure 2γ̄/R of its
//! cells (capped at max_pressure), so that contacts sink c/25 and cells never pass through each
//! other, and at least [`crate::mechanics::REPULSION_PER_ADHESION`] × its strongest adhesion ω; the default 1e9 Pa/m holds only 200 Pa at c = 0.2 µm, below the 480 Pa of an 8 µm cell at
//! 1 mN/m. The time step is then derived again (the stiffer contacts lower the stable step) unless
//! the config sets it.

use super::writing::fmt_real_short;
use super::*;
use crate::mesh::Tissue;
use toml::Value;

/// Mean edge length over l_min of tissues meshed by `tissuefit mesh` (Poisson-disk sampling at
/// spacing l_min, then ball pivoting): 1.35 to 1.42 on `data/demo/doublet.tif` from 90 to 1000
/// nodes per cell (the shortest edge is l_min, the median 1.37·l_min). On SimuCell3D's own meshes
/// ⟨edge⟩/1.4 lands at their 5th edge-length percentile, the edges remeshing would collapse first.
pub const MEAN_EDGE_PER_MIN_EDGE: Real = 1.4;

/// A set l_min this many times the mesh's (or less than its inverse) contradicts the mesh.
pub const MIN_EDGE_MISMATCH: Real = 2.0;

/// A set cutoff below this fraction of the mesh's l_min leaves the gaps between meshed neighbours
/// unseen.
pub const MIN_CUTOFF_FRACTION: Real = 0.5;

/// Which of the mesh-dependent numerics a config sets itself (the others take their defaults, or
/// values derived from the mesh).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ExplicitNumerics {
    pub min_edge_length: bool,
    pub contact_cutoff: bool,
    pub time_step: bool,
    /// The config sets `repulsion` on some face type of some cell type (then no ξ is derived).
    pub repulsion: bool,
}

impl ExplicitNumerics {
    /// Everything set: nothing is derived (a resumed run keeps its resolved parameters).
    pub const ALL: Self = Self { min_edge_length: true, contact_cutoff: true, time_step: true, repulsion: true };

    /// The keys a user's TOML table (a parameter file, with any overrides merged in) sets.
    pub fn of_table(table: &Table) -> Self {
        let numerics = table.get("numerics").and_then(Value::as_table);
        let set = |key: &str| numerics.is_some_and(|n| n.contains_key(key));
        let repulsion = table.get("cell_types").and_then(Value::as_array).is_some_and(|types| {
            types.iter().any(|t| {
                t.get("faces").and_then(Value::as_table).is_some_and(|faces| {
                    faces.values().any(|f| f.as_table().is_some_and(|f| f.contains_key("repulsion")))
                })
            })
        });
        Self {
            min_edge_length: set("min_edge_length"),
            contact_cutoff: set("contact_cutoff"),
            time_step: set("time_step"),
            repulsion,
        }
    }
}

/// The length scale of an input mesh.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct MeshScale {
    /// Mean edge length (m) of the non-nucleus cells ([`Tissue::mean_edge_length`]).
    pub mean_edge: Real,
    /// l_min (m) of the mesh: mean_edge / [`MEAN_EDGE_PER_MIN_EDGE`].
    pub min_edge_length: Real,
}

impl MeshScale {
    /// The scale of `tissue`; `None` without faces or with a degenerate mean edge.
    pub fn of(tissue: &Tissue) -> Option<Self> {
        let mean_edge = tissue.mean_edge_length().filter(|h| h.is_finite() && *h > 0.0)?;
        Some(Self { mean_edge, min_edge_length: mean_edge / MEAN_EDGE_PER_MIN_EDGE })
    }
}

/// One value derived from the input mesh instead of taking its default.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DerivedValue {
    /// TOML path, e.g. `numerics.min_edge_length`.
    pub key: String,
    /// SI (m or s).
    pub value: Real,
    /// The default it replaces.
    pub default: Real,
    /// Where it came from, in words.
    pub from: String,
}

/// What [`Parameters::fit_to_mesh`] did: written into the simulate stage's summary.json
/// (`mesh_defaults`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MeshFit {
    /// Mean edge length (m) of the input mesh; `None` when it has no faces (nothing derived).
    pub mesh_mean_edge: Option<Real>,
    /// l_min (m) of the input mesh, mean edge / [`MEAN_EDGE_PER_MIN_EDGE`].
    pub mesh_min_edge_length: Option<Real>,
    /// The values derived from the mesh (absent keys: set by the config, or their default kept).
    pub derived: Vec<DerivedValue>,
    /// Where the config's values contradict the mesh (each also logged as a warning).
    pub warnings: Vec<String>,
}

impl MeshFit {
    /// One line per derived value, e.g. "numerics.min_edge_length = 0.95 µm (default 0.2 µm): from the
    /// input mesh's mean edge length 1.33 µm / 1.4; set it in the config to choose another".
    pub fn lines(&self) -> Vec<String> {
        self.derived
            .iter()
            .map(|d| {
                let show = |v: Real| {
                    if d.key == "numerics.time_step" {
                        format!("{} s", fmt_real_short(v))
                    } else if d.key.ends_with(".repulsion") {
                        format!("{v:.3e} Pa/m")
                    } else {
                        um(v)
                    }
                };
                format!(
                    "{} = {} (default {}): {}; set it in the config to choose another",
                    d.key,
                    show(d.value),
                    show(d.default),
                    d.from
                )
            })
            .collect()
    }

    /// The value derived for `key`, if any.
    pub fn derived_value(&self, key: &str) -> Option<Real> {
        self.derived.iter().find(|d| d.key == key).map(|d| d.value)
    }
}

/// A length in µm for messages, 3 significant digits.
fn um(metres: Real) -> String {
    format!("{} µm", fmt_real_short(metres * 1e6))
}

/// What a derived spring cutoff does to the adhesion energy w = ωc²/2 (it grows with c²): the
/// largest w/(2γ) = ωc²/(4γ) over the moving cell types' adhesive face types at `cutoff` and at the
/// default cutoff, as a clause for the note; empty without adhesion.
fn adhesion_at_cutoff(cell_types: &[CellTypeParams], cutoff: Real, default: Real) -> String {
    let ratio = |c: Real, f: &FaceParams| f.adhesion * c * c / (4.0 * f.surface_tension);
    let strongest = cell_types
        .iter()
        .filter(|t| !t.kind.is_immobile())
        .flat_map(|t| t.faces.iter().map(move |(face, f)| (t, face, f)))
        .filter(|(_, _, f)| f.adhesion > 0.0 && f.surface_tension > 0.0)
        // The first of the strongest (min_by keeps the first of equals).
        .min_by(|a, b| ratio(cutoff, b.2).total_cmp(&ratio(cutoff, a.2)));
    match strongest {
        Some((t, face, f)) => format!(
            "; the spring adhesion energy ωc²/2 grows with c²: w/(2γ) = ωc²/(4γ) = {} on {}'s {} faces (ω = {:e} \
             Pa/m), {} at the default cutoff {} (adhesion ω = 4γ·(w/2γ)/c² gives the w you mean)",
            fmt_real_short(ratio(cutoff, f)),
            t.name,
            face.name(),
            f.adhesion,
            fmt_real_short(ratio(default, f)),
            um(default)
        ),
        None => String::new(),
    }
}

impl Parameters {
    /// Fills the mesh-dependent numerics the config leaves unset (`explicit`) from the input mesh's
    /// `scale`, and collects warnings where the set ones contradict it (see the module doc). Call
    /// [`Parameters::validate`] afterwards.
    pub fn fit_to_mesh(&mut self, explicit: &ExplicitNumerics, scale: &MeshScale) -> MeshFit {
        let defaults = Numerics::default_for(self.numerics.dynamics);
        let l = scale.min_edge_length;
        let mesh_words =
            format!("the input mesh's mean edge length {} / {MEAN_EDGE_PER_MIN_EDGE}", um(scale.mean_edge));
        let mut derived = Vec::new();
        let mut warnings = Vec::new();
        let n = &mut self.numerics;
        if explicit.min_edge_length {
            let ratio = n.min_edge_length / l;
            if !(1.0 / MIN_EDGE_MISMATCH..=MIN_EDGE_MISMATCH).contains(&ratio) {
                let effect = if ratio > 1.0 {
                    "remeshing would collapse most of its edges and the residual max|f|/(γ·l_min) reads small"
                } else {
                    "remeshing would split most of its edges (many more nodes, a slower run) and the residual \
                     max|f|/(γ·l_min) reads large"
                };
                warnings.push(format!(
                    "numerics.min_edge_length = {} is {:.2}× the input mesh's l_min ≈ {} ({mesh_words}): {effect}; \
                     set min_edge_length = {:.3e} (or delete the key to derive it from the mesh)",
                    um(n.min_edge_length),
                    ratio,
                    um(l),
                    l
                ));
            }
        } else {
            n.min_edge_length = l;
            derived.push(DerivedValue {
                key: "numerics.min_edge_length".to_string(),
                value: l,
                default: defaults.min_edge_length,
                from: format!("from {mesh_words}"),
            });
        }
        if explicit.contact_cutoff {
            if n.contact_cutoff < MIN_CUTOFF_FRACTION * l {
                warnings.push(format!(
                    "numerics.contact_cutoff = {} is below {MIN_CUTOFF_FRACTION} × the input mesh's l_min ≈ {} \
                     ({mesh_words}): neighbouring cells meshed at this resolution lie farther apart than the cutoff \
                     in places, so they neither adhere nor repel there, round up and drift apart; set \
                     contact_cutoff = {:.3e} (or delete the key to use min_edge_length)",
                    um(n.contact_cutoff),
                    um(l),
                    l
                ));
            }
        } else {
            n.contact_cutoff = n.min_edge_length;
            let mut from = if explicit.min_edge_length {
                "equal to numerics.min_edge_length (the config's), as Table 2 ties them".to_string()
            } else {
                "equal to the derived numerics.min_edge_length, as Table 2 and the fit's forward.match_mesh_length tie them"
                    .to_string()
            };
            if n.contact_model == ContactModel::Spring {
                from.push_str(&adhesion_at_cutoff(&self.cell_types, n.contact_cutoff, defaults.contact_cutoff));
            }
            derived.push(DerivedValue {
                key: "numerics.contact_cutoff".to_string(),
                value: n.contact_cutoff,
                default: defaults.contact_cutoff,
                from,
            });
        }
        // Only a derived l_min moves the stability estimate away from what validating the config saw.
        if !explicit.time_step && !explicit.min_edge_length {
            derived.extend(self.derive_time_step());
        }
        MeshFit { mesh_mean_edge: Some(scale.mean_edge), mesh_min_edge_length: Some(l), derived, warnings }
    }

    /// [`Parameters::fit_to_mesh`] with the scale of `tissue`, then, with the spring contact model and
    /// no `repulsion` in the config, the repulsion of each moving cell type derived from its cells
    /// (module doc), and the time step derived again for the stiffer contacts unless the config sets
    /// it. What the simulate command and the pipeline's simulate stage call.
    pub fn fit_to_tissue(&mut self, explicit: &ExplicitNumerics, tissue: &Tissue) -> MeshFit {
        let mut fit = match MeshScale::of(tissue) {
            Some(scale) => self.fit_to_mesh(explicit, &scale),
            None => MeshFit::default(),
        };
        if explicit.repulsion || self.numerics.contact_model != ContactModel::Spring || tissue.len() < 2 {
            return fit;
        }
        let repulsions = self.derive_repulsion(tissue, false);
        if repulsions.is_empty() {
            return fit;
        }
        fit.derived.extend(repulsions);
        if !explicit.time_step
            && let Some(step) = self.derive_time_step()
        {
            fit.derived.retain(|d| d.key != step.key);
            fit.derived.push(step);
        }
        fit
    }

    /// With spring contacts: the repulsion of each cell type with moving cells raised to
    /// [`crate::mechanics::derived_repulsion`] where it is below it (never lowered), counting the
    /// cells' own adhesions and tensions (`cell_overrides`), and then the time step derived again
    /// for the stiffer contacts. For a model whose per-cell values are set after its config was
    /// read: a per-cell fit's adhesion map ([`crate::inference::run_per_cell`]), where a cell's ω
    /// may be many times its type's.
    pub fn raise_repulsion_for_overrides(&mut self, tissue: &Tissue) -> Vec<DerivedValue> {
        if self.numerics.contact_model != ContactModel::Spring || tissue.len() < 2 {
            return Vec::new();
        }
        let mut derived = self.derive_repulsion(tissue, true);
        if !derived.is_empty()
            && let Some(step) = self.derive_time_step()
        {
            derived.push(step);
        }
        derived
    }

    /// Sets the repulsion of every face type of each cell type with moving (epithelial) cells in
    /// `tissue` to [`crate::mechanics::derived_repulsion`] of its largest-pressure cell and its
    /// strongest adhesion (its own or one of its cells' `cell_overrides`); with `raise_only`, only
    /// where that is above the current repulsion.
    fn derive_repulsion(&mut self, tissue: &Tissue, raise_only: bool) -> Vec<DerivedValue> {
        let c = self.numerics.contact_cutoff;
        if !(c.is_finite() && c > 0.0) {
            return Vec::new();
        }
        let worst = self.largest_laplace_pressures(tissue);
        let mut own_adhesion: Vec<Real> = vec![0.0; self.cell_types.len()];
        for cell in tissue.cells().iter().filter(|c| c.kind() == CellKind::Epithelial) {
            let Some(p) = self.cell_types.get(cell.cell_type() as usize) else { continue };
            let own = p.with_overrides(&self.overrides_of(cell));
            let omega = FaceType::ALL.iter().map(|&ft| own.faces.get(ft).adhesion).fold(0.0, Real::max);
            own_adhesion[cell.cell_type() as usize] = own_adhesion[cell.cell_type() as usize].max(omega);
        }
        let mut derived = Vec::new();
        for (t, entry) in worst.into_iter().enumerate() {
            let Some((pressure, radius)) = entry else { continue };
            let faces = &mut self.cell_types[t].faces;
            let omega = FaceType::ALL.iter().map(|&ft| faces.get(ft).adhesion).fold(own_adhesion[t], Real::max);
            let xi = crate::mechanics::derived_repulsion(0.5 * pressure * radius, radius, c, omega);
            let default = faces.get(FaceType::Lateral).repulsion;
            if raise_only && FaceType::ALL.iter().all(|&ft| faces.get(ft).repulsion >= xi) {
                continue;
            }
            for ft in FaceType::ALL {
                faces.get_mut(ft).repulsion = xi;
            }
            let (k_p, k_w) = (crate::mechanics::REPULSION_PER_PRESSURE, crate::mechanics::REPULSION_PER_ADHESION);
            let from = if xi > k_p * pressure / c {
                format!(
                    "{k_w} × its strongest adhesion ω = {omega:.3e} Pa/m (above ξ·c = {k_p} × its cells' Laplace pressure)"
                )
            } else {
                format!(
                    "ξ·c = {k_p} × the Laplace pressure 2γ̄/R = {pressure:.0} Pa of its largest-pressure cell (R ≈ {}, \
                     cutoff c = {}), so that contacts sink c/{k_p}",
                    um(radius),
                    um(c)
                )
            };
            derived.push(DerivedValue { key: format!("cell_types[{t}].faces.*.repulsion"), value: xi, default, from });
        }
        derived
    }

    /// Per cell type: the largest Laplace pressure 2γ̄/R (Pa, capped at max_pressure) among its
    /// moving (epithelial) cells in `tissue`, R from the cell's volume, and that cell's R (m); `None`
    /// for a type without such cells.
    pub fn largest_laplace_pressures(&self, tissue: &Tissue) -> Vec<Option<(Real, Real)>> {
        let mut worst: Vec<Option<(Real, Real)>> = vec![None; self.cell_types.len()];
        for cell in tissue.cells() {
            if cell.kind() != CellKind::Epithelial {
                continue;
            }
            let Some(p) = self.cell_types.get(cell.cell_type() as usize) else { continue };
            let radius = (3.0 * cell.mesh().signed_volume() / (4.0 * std::f64::consts::PI)).cbrt();
            let tension = p.with_overrides(&self.overrides_of(cell)).mean_tension(cell);
            let pressure = (2.0 * tension / radius).min(p.max_pressure);
            if !(pressure.is_finite() && pressure > 0.0) {
                continue;
            }
            let slot = &mut worst[cell.cell_type() as usize];
            if slot.is_none_or(|(q, _)| pressure > q) {
                *slot = Some((pressure, radius));
            }
        }
        worst
    }

    /// The time step lowered to a quarter of the largest stable one when the current one's stability
    /// ratio is above half the limit ([`TimeStepLimit`]); `None` when it is kept.
    fn derive_time_step(&mut self) -> Option<DerivedValue> {
        let defaults = Numerics::default_for(self.numerics.dynamics);
        // The largest stable step over the moving cell types, and how close the current one is.
        let limits: Vec<TimeStepLimit> = self.time_step_limits().into_iter().filter(|t| !t.immobile).collect();
        let worst = limits
            .iter()
            .map(|t| match self.numerics.dynamics {
                Dynamics::Dynamic => t.damping_ratio.max(t.oscillation_ratio),
                Dynamics::Overdamped => t.overdamped_ratio,
            })
            .fold(0.0, Real::max);
        let max_step = limits.iter().map(|t| t.max_time_step).fold(Real::INFINITY, Real::min);
        if !(worst > TimeStepLimit::LIMIT / 2.0 && max_step.is_finite() && max_step > 0.0) {
            return None;
        }
        let dt = max_step / 4.0;
        self.numerics.time_step = dt;
        Some(DerivedValue {
            key: "numerics.time_step".to_string(),
            value: dt,
            default: defaults.time_step,
            from: format!(
                "a quarter of the largest stable step {} s estimated at min_edge_length = {} (the stability ratio \
                 {:.2} was above half the limit {})",
                fmt_real_short(max_step),
                um(self.numerics.min_edge_length),
                worst,
                TimeStepLimit::LIMIT
            ),
        })
    }
}

//! The parameter space: which model parameters are fitted (searched in log space within bounds),
//! which are fixed, and how a point of the space is written into the model's [`Parameters`].

use super::InferenceError;
use super::config::ParameterConfig;
use crate::geometry::Real;
use crate::mechanics::Parameters;
use crate::mesh::{CellKind, FaceType};
use std::collections::BTreeMap;

/// A model parameter a fit can set (in every epithelial cell type).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FitParameter {
    /// γ of every face type (a per-face-type parameter given too overrides its type).
    SurfaceTension,
    SurfaceTensionApical,
    SurfaceTensionLateral,
    SurfaceTensionBasal,
    /// ω of every face type.
    Adhesion,
}

impl FitParameter {
    pub const ALL: [FitParameter; 5] = [
        FitParameter::SurfaceTension,
        FitParameter::SurfaceTensionApical,
        FitParameter::SurfaceTensionLateral,
        FitParameter::SurfaceTensionBasal,
        FitParameter::Adhesion,
    ];

    /// The name in fit configs, trace columns and `result.json`.
    pub const fn name(self) -> &'static str {
        match self {
            FitParameter::SurfaceTension => "surface_tension",
            FitParameter::SurfaceTensionApical => "surface_tension_apical",
            FitParameter::SurfaceTensionLateral => "surface_tension_lateral",
            FitParameter::SurfaceTensionBasal => "surface_tension_basal",
            FitParameter::Adhesion => "adhesion",
        }
    }

    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|p| p.name() == name)
    }

    /// The one face type a per-face-type tension sets.
    pub const fn face_type(self) -> Option<FaceType> {
        match self {
            FitParameter::SurfaceTensionApical => Some(FaceType::Apical),
            FitParameter::SurfaceTensionLateral => Some(FaceType::Lateral),
            FitParameter::SurfaceTensionBasal => Some(FaceType::Basal),
            FitParameter::SurfaceTension | FitParameter::Adhesion => None,
        }
    }

    /// A surface tension (N/m), as opposed to the adhesion strength (Pa/m).
    pub const fn is_tension(self) -> bool {
        !matches!(self, FitParameter::Adhesion)
    }

    /// The value made dimensionless with the bulk modulus K and the length scale l: γ/(K·l), ω·l/K.
    pub fn dimensionless(self, v: Real, l: Real, k: Real) -> Real {
        if self.is_tension() { v / (k * l) } else { v * l / k }
    }
}

/// Names of the parameters a fit can set, in [`FitParameter::ALL`] order.
pub const PARAMETER_NAMES: [&str; 5] = [
    FitParameter::SurfaceTension.name(),
    FitParameter::SurfaceTensionApical.name(),
    FitParameter::SurfaceTensionLateral.name(),
    FitParameter::SurfaceTensionBasal.name(),
    FitParameter::Adhesion.name(),
];

/// The dimensionless spelling of the spring adhesion in `[parameters]`: w/(2γ) = ω·c²/(4γ), the
/// group that sets a spring contact's Young–Dupré angle (cos(θ/2) = 1 − w/(2γ)), whatever the
/// contact cutoff c that the meshing of the data sets. Resolved into `adhesion` (Pa/m) by
/// [`resolve_adhesion_ratio`] once c is known.
pub const ADHESION_RATIO: &str = "adhesion_energy_over_tension";

/// The fixed `surface_tension` of `parameters`: the γ of w/(2γ).
fn fixed_tension(parameters: &BTreeMap<String, ParameterConfig>) -> Option<Real> {
    parameters.get(FitParameter::SurfaceTension.name()).and_then(|p| p.value)
}

/// Why [`ADHESION_RATIO`] in `parameters` cannot mean one ω (the reason, without the key): `adhesion`
/// given too, or no fixed `surface_tension`; `None` when it is absent or consistent. The config check
/// and [`resolve_adhesion_ratio`] both ask it.
pub(super) fn adhesion_ratio_conflict(parameters: &BTreeMap<String, ParameterConfig>) -> Option<String> {
    if !parameters.contains_key(ADHESION_RATIO) {
        None
    } else if parameters.contains_key(FitParameter::Adhesion.name()) {
        Some("give it or `adhesion` (ω in Pa/m), not both: they set the same parameter".into())
    } else if fixed_tension(parameters).is_none() {
        Some("needs the tension γ of w/(2γ) fixed: give [parameters.surface_tension] a `value` (e.g. 1e-3)".into())
    } else {
        None
    }
}

/// `parameters` with [`ADHESION_RATIO`] (its bounds, start or value given as w/(2γ)) written as
/// `adhesion` in Pa/m, ω = 4γ·(w/(2γ))/c², with γ the fixed `surface_tension` and c the model's
/// contact cutoff `cutoff` (m; after `forward.match_mesh_length`); the other entries unchanged.
/// An error names what is missing (a fixed `surface_tension`, spring contacts) or contradicts it
/// (`adhesion` given too).
pub fn resolve_adhesion_ratio(
    parameters: &BTreeMap<String, ParameterConfig>,
    cutoff: Real,
    spring: bool,
) -> Result<BTreeMap<String, ParameterConfig>, InferenceError> {
    let Some(ratio) = parameters.get(ADHESION_RATIO) else {
        return Ok(parameters.clone());
    };
    let err = |m: String| InferenceError::Config(format!("parameters.{ADHESION_RATIO}: {m}"));
    if let Some(m) = adhesion_ratio_conflict(parameters) {
        return Err(err(m));
    }
    if !spring {
        return Err(err("w/(2γ) = ω·c²/(4γ) is the spring contacts' adhesion; the model's contacts are coupled (set \
             numerics.contact_model = \"spring\", or fit surface_tension_lateral)"
            .into()));
    }
    let gamma = fixed_tension(parameters).expect("adhesion_ratio_conflict checked it");
    if !(cutoff.is_finite() && cutoff > 0.0) {
        return Err(err(format!(
            "needs a positive contact cutoff c; the model has numerics.contact_cutoff = {cutoff}"
        )));
    }
    let omega = |r: Real| 4.0 * gamma * r / (cutoff * cutoff);
    let resolved = ParameterConfig {
        bounds: ratio.bounds.map(|[lo, hi]| [omega(lo), omega(hi)]),
        value: ratio.value.map(omega),
        initial: ratio.initial.map(omega),
    };
    tracing::info!(
        "parameters.{ADHESION_RATIO}: w/(2γ) {} → adhesion ω {} Pa/m (γ = {gamma:e} N/m, contact cutoff c = {:.4} µm)",
        match (ratio.bounds, ratio.value) {
            (Some([lo, hi]), _) => format!("in [{lo}, {hi}]"),
            (None, Some(v)) => format!("= {v}"),
            (None, None) => "unset".into(),
        },
        match (resolved.bounds, resolved.value) {
            (Some([lo, hi]), _) => format!("in [{lo:.4e}, {hi:.4e}]"),
            (None, Some(v)) => format!("= {v:.4e}"),
            (None, None) => "unset".into(),
        },
        cutoff * 1e6
    );
    let mut out = parameters.clone();
    out.remove(ADHESION_RATIO);
    out.insert(FitParameter::Adhesion.name().to_string(), resolved);
    Ok(out)
}

/// One fitted parameter: which, and its log-space bounds.
#[derive(Clone, Debug, PartialEq)]
pub struct FittedParameter {
    pub parameter: FitParameter,
    /// SI bounds `[lo, hi]`.
    pub bounds: [Real; 2],
    /// Start of the search (SI).
    pub initial: Real,
}

impl FittedParameter {
    pub fn name(&self) -> &'static str {
        self.parameter.name()
    }

    /// `[ln lo, ln hi]`.
    pub fn log_bounds(&self) -> [Real; 2] {
        [self.bounds[0].ln(), self.bounds[1].ln()]
    }
}

/// Fitted parameters (in name order; a point is the vector of their natural logs) and fixed ones.
#[derive(Clone, Debug, PartialEq)]
pub struct ParameterSpace {
    pub fitted: Vec<FittedParameter>,
    pub fixed: Vec<(FitParameter, Real)>,
}

impl ParameterSpace {
    /// From the config's `[parameters]` (already checked by [`super::FitConfig`]).
    pub fn from_config(parameters: &BTreeMap<String, ParameterConfig>) -> Result<Self, InferenceError> {
        let mut fitted = Vec::new();
        let mut fixed = Vec::new();
        for (name, p) in parameters {
            let parameter = FitParameter::from_name(name).ok_or_else(|| {
                InferenceError::Config(if name == ADHESION_RATIO {
                    format!("parameters.{name}: must be resolved into `adhesion` first (resolve_adhesion_ratio)")
                } else {
                    format!(
                        "parameters.{name}: unknown parameter; one of {}, {ADHESION_RATIO}",
                        PARAMETER_NAMES.join(", ")
                    )
                })
            })?;
            match (p.bounds, p.value) {
                (Some(bounds), None) => {
                    let initial = p.initial.unwrap_or_else(|| (bounds[0] * bounds[1]).sqrt());
                    fitted.push(FittedParameter { parameter, bounds, initial });
                }
                (None, Some(v)) => fixed.push((parameter, v)),
                _ => return Err(InferenceError::Config(format!("parameters.{name}: give `bounds` or `value`"))),
            }
        }
        Ok(Self { fitted, fixed })
    }

    /// Number of fitted parameters.
    pub fn dim(&self) -> usize {
        self.fitted.len()
    }

    /// The log-space start.
    pub fn initial_point(&self) -> Vec<Real> {
        self.fitted.iter().map(|p| p.initial.ln()).collect()
    }

    /// Lower and upper log bounds.
    pub fn log_bounds(&self) -> (Vec<Real>, Vec<Real>) {
        (
            self.fitted.iter().map(|p| p.log_bounds()[0]).collect(),
            self.fitted.iter().map(|p| p.log_bounds()[1]).collect(),
        )
    }

    /// Clamps a log point into the bounds; also returns the squared log-distance it was moved.
    pub fn clamp(&self, x: &[Real]) -> (Vec<Real>, Real) {
        let mut moved = 0.0;
        let clamped = x
            .iter()
            .zip(&self.fitted)
            .map(|(&v, p)| {
                let [lo, hi] = p.log_bounds();
                let c = v.clamp(lo, hi);
                moved += (v - c) * (v - c);
                c
            })
            .collect();
        (clamped, moved)
    }

    /// SI values of a log point.
    pub fn si(&self, x: &[Real]) -> Vec<Real> {
        x.iter().map(|v| v.exp()).collect()
    }

    /// Every parameter's SI value at a log point: fixed ones and fitted ones, by name.
    pub fn values(&self, x: &[Real]) -> BTreeMap<String, Real> {
        self.parameter_values(x).into_iter().map(|(p, v)| (p.name().to_string(), v)).collect()
    }

    /// Every parameter with its SI value at a log point: the fixed ones, then the fitted ones.
    pub fn parameter_values(&self, x: &[Real]) -> Vec<(FitParameter, Real)> {
        let fitted = self.fitted.iter().zip(x).map(|(p, v)| (p.parameter, v.exp()));
        self.fixed.iter().copied().chain(fitted).collect()
    }

    /// Whether the space names `p`, fitted or fixed.
    pub fn names(&self, p: FitParameter) -> bool {
        self.fitted.iter().any(|f| f.parameter == p) || self.fixed.iter().any(|(f, _)| *f == p)
    }

    /// The model with the parameters of log point `x` written into every epithelial cell type.
    /// `surface_tension` sets every face type first; a per-face-type name then overrides its type.
    pub fn apply(&self, base: &Parameters, x: &[Real]) -> Parameters {
        let mut values = self.parameter_values(x);
        // `surface_tension` first: a per-face-type tension overrides it on its type.
        values.sort_by_key(|(p, _)| *p != FitParameter::SurfaceTension);
        let mut params = base.clone();
        for cell_type in params.cell_types.iter_mut().filter(|t| t.kind == CellKind::Epithelial) {
            for &(p, v) in &values {
                for ft in p.face_type().map_or(FaceType::ALL.to_vec(), |ft| vec![ft]) {
                    let face = cell_type.faces.get_mut(ft);
                    if p.is_tension() {
                        face.surface_tension = v;
                    } else {
                        face.adhesion = v;
                    }
                }
            }
        }
        params
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn space(toml: &str) -> ParameterSpace {
        let parameters: BTreeMap<String, ParameterConfig> = toml::from_str(toml).unwrap();
        ParameterSpace::from_config(&parameters).unwrap()
    }

    #[test]
    fn every_parameter_name_reads_back_and_an_unknown_one_is_refused() {
        for p in FitParameter::ALL {
            assert_eq!(FitParameter::from_name(p.name()), Some(p));
        }
        assert_eq!(PARAMETER_NAMES, FitParameter::ALL.map(FitParameter::name));
        let parameters: BTreeMap<String, ParameterConfig> =
            toml::from_str("[surface_tension_lateal]\nvalue = 1e-3\n").unwrap();
        let e = ParameterSpace::from_config(&parameters).unwrap_err().to_string();
        assert!(e.contains("surface_tension_lateal") && e.contains("surface_tension_lateral"), "{e}");
    }

    #[test]
    fn the_adhesion_ratio_becomes_adhesion_at_the_models_cutoff() {
        let parameters: BTreeMap<String, ParameterConfig> = toml::from_str(
            "[surface_tension]\nvalue = 2e-3\n[adhesion_energy_over_tension]\nbounds = [0.1, 0.4]\ninitial = 0.2\n",
        )
        .unwrap();
        let c = 0.5e-6;
        let resolved = resolve_adhesion_ratio(&parameters, c, true).unwrap();
        let s = ParameterSpace::from_config(&resolved).unwrap();
        assert_eq!(s.fitted.len(), 1);
        let p = &s.fitted[0];
        assert_eq!(p.parameter, FitParameter::Adhesion);
        // w/(2γ) = ω·c²/(4γ) back from the SI bounds and start.
        let ratio = |omega: Real| omega * c * c / (4.0 * 2e-3);
        assert!((ratio(p.bounds[0]) - 0.1).abs() < 1e-12 && (ratio(p.bounds[1]) - 0.4).abs() < 1e-12);
        assert!((ratio(p.initial) - 0.2).abs() < 1e-12);
        // Unresolved, it is refused with the reason; coupled contacts, a fitted tension or `adhesion`
        // given too are errors naming the key.
        let e = ParameterSpace::from_config(&parameters).unwrap_err().to_string();
        assert!(e.contains("resolve"), "{e}");
        let e = resolve_adhesion_ratio(&parameters, c, false).unwrap_err().to_string();
        assert!(e.contains("adhesion_energy_over_tension") && e.contains("spring"), "{e}");
        let fitted_gamma: BTreeMap<String, ParameterConfig> = toml::from_str(
            "[surface_tension]\nbounds = [1e-4, 1e-3]\n[adhesion_energy_over_tension]\nbounds = [0.1, 0.4]\n",
        )
        .unwrap();
        let e = resolve_adhesion_ratio(&fitted_gamma, c, true).unwrap_err().to_string();
        assert!(e.contains("surface_tension") && e.contains("value"), "{e}");
        let both: BTreeMap<String, ParameterConfig> = toml::from_str(
            "[surface_tension]\nvalue = 1e-3\n[adhesion]\nvalue = 1e9\n[adhesion_energy_over_tension]\nvalue = 0.2\n",
        )
        .unwrap();
        assert!(resolve_adhesion_ratio(&both, c, true).unwrap_err().to_string().contains("not both"));
    }

    #[test]
    fn a_face_type_tension_overrides_the_all_faces_one_and_adhesion_sets_every_face() {
        // `adhesion` < `surface_tension` < `surface_tension_lateral` in name order: the all-faces
        // tension must still be written before the per-type one overrides it.
        let s = space(
            "[adhesion]\nvalue = 2e9\n[surface_tension]\nvalue = 1e-3\n\
             [surface_tension_lateral]\nbounds = [1e-4, 1e-3]\ninitial = 4e-4\n",
        );
        assert_eq!(s.fitted.len(), 1);
        assert!(s.names(FitParameter::SurfaceTension) && !s.names(FitParameter::SurfaceTensionApical));
        let params = s.apply(&Parameters::default(), &s.initial_point());
        let faces = &params.cell_types[0].faces;
        assert!((faces.get(FaceType::Lateral).surface_tension - 4e-4).abs() < 1e-15);
        for ft in [FaceType::Apical, FaceType::Basal] {
            assert_eq!(faces.get(ft).surface_tension, 1e-3);
        }
        for ft in FaceType::ALL {
            assert_eq!(faces.get(ft).adhesion, 2e9);
        }
        assert_eq!(FitParameter::Adhesion.dimensionless(2e9, 1e-5, 2500.0), 2e9 * 1e-5 / 2500.0);
        assert_eq!(FitParameter::SurfaceTension.dimensionless(1e-3, 1e-5, 2500.0), 1e-3 / (2500.0 * 1e-5));
    }
}

//! The parameter space: which model parameters are fitted (searched in log space within bounds),
//! which are fixed, and how a point of the space is written into the model's [`Parameters`].

use super::InferenceError;
use super::config::ParameterConfig;
use crate::geometry::Real;
use crate::mechanics::Parameters;
use crate::mesh::{CellKind, FaceType};
use std::collections::BTreeMap;

/// Names of the parameters a fit can set (applied to every epithelial cell type).
pub const PARAMETER_NAMES: [&str; 5] =
    ["surface_tension", "surface_tension_apical", "surface_tension_lateral", "surface_tension_basal", "adhesion"];

/// One fitted parameter: its name and log-space bounds.
#[derive(Clone, Debug, PartialEq)]
pub struct FittedParameter {
    pub name: String,
    /// SI bounds `[lo, hi]`.
    pub bounds: [Real; 2],
    /// Start of the search (SI).
    pub initial: Real,
}

impl FittedParameter {
    /// `[ln lo, ln hi]`.
    pub fn log_bounds(&self) -> [Real; 2] {
        [self.bounds[0].ln(), self.bounds[1].ln()]
    }
}

/// Fitted parameters (in name order; a point is the vector of their natural logs) and fixed ones.
#[derive(Clone, Debug, PartialEq)]
pub struct ParameterSpace {
    pub fitted: Vec<FittedParameter>,
    pub fixed: Vec<(String, Real)>,
}

impl ParameterSpace {
    /// From the config's `[parameters]` (already checked by [`super::FitConfig`]).
    pub fn from_config(parameters: &BTreeMap<String, ParameterConfig>) -> Result<Self, InferenceError> {
        let mut fitted = Vec::new();
        let mut fixed = Vec::new();
        for (name, p) in parameters {
            match (p.bounds, p.value) {
                (Some(bounds), None) => {
                    let initial = p.initial.unwrap_or_else(|| (bounds[0] * bounds[1]).sqrt());
                    fitted.push(FittedParameter { name: name.clone(), bounds, initial });
                }
                (None, Some(v)) => fixed.push((name.clone(), v)),
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
        let mut all: BTreeMap<String, Real> = self.fixed.iter().cloned().collect();
        for (p, v) in self.fitted.iter().zip(x) {
            all.insert(p.name.clone(), v.exp());
        }
        all
    }

    /// The model with the parameters of log point `x` written into every epithelial cell type.
    /// `surface_tension` sets every face type first; a per-face-type name then overrides its type.
    pub fn apply(&self, base: &Parameters, x: &[Real]) -> Parameters {
        let values = self.values(x);
        let mut params = base.clone();
        for cell_type in params.cell_types.iter_mut().filter(|t| t.kind == CellKind::Epithelial) {
            if let Some(&g) = values.get("surface_tension") {
                for ft in FaceType::ALL {
                    cell_type.faces.get_mut(ft).surface_tension = g;
                }
            }
            for (name, ft) in [
                ("surface_tension_apical", FaceType::Apical),
                ("surface_tension_lateral", FaceType::Lateral),
                ("surface_tension_basal", FaceType::Basal),
            ] {
                if let Some(&g) = values.get(name) {
                    cell_type.faces.get_mut(ft).surface_tension = g;
                }
            }
            if let Some(&w) = values.get("adhesion") {
                for ft in FaceType::ALL {
                    cell_type.faces.get_mut(ft).adhesion = w;
                }
            }
        }
        params
    }
}

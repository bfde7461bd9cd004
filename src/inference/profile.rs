//! Uncertainty and identifiability after the optimum: the objective along a few directions through
//! the best point, evaluated in one parallel batch (not charged to the budget).
//!
//! - one slice per fitted parameter (the others held at the optimum);
//! - the *scale* direction (every fitted parameter multiplied by the same factor), along which an
//!   equilibrium shape changes only through volume compression against K: when the objective stays
//!   acceptable along it, the absolute values are not determined, only ratios;
//! - one direction per key ratio (γ_lateral/γ_apical, ω/γ) that changes the ratio at a fixed scale.
//!
//! Points lie at factors span^(±k/points), k = 1…points, from the optimum.
//!
//! Noise floor: the forward model need not be a smooth function of the parameters (an adhesive
//! spring aggregate never converges, and a one-bit change of the adhesion ends its relaxation at
//! another shape: objectives 1.2 and 3.6). So the batch also evaluates `noise_replicates` points at
//! the optimum moved by k·1e-9 in every log coordinate; the objectives there (with the best) give a
//! reference J_ref (their mean) and a noise σ (their standard deviation; infinite when a replicate
//! failed). A point is acceptable when its objective is at most
//! threshold = J_ref + `acceptable_increase` + `noise_sigmas`·σ: a side closes only where the
//! objective rises above the noise, so a range narrower than the noise is never reported, and a
//! quantity whose profile stays within the noise is reported not determined. (Without the noise
//! term the best of many noisy evaluations, a low outlier, set the threshold, and the spring fits
//! reported ranges narrower than the scatter of repeated evaluations as determined.)
//!
//! The acceptable range on each side ends where the objective crosses that threshold, interpolated
//! between the last acceptable and the first unacceptable point linearly in √(J − J_ref) (exact for a quadratic bowl; interpolating J itself
//! put the crossing of a steep side at a tenth of its distance); a side with no crossing inside the
//! probed span, or whose next point failed or did not converge (a penalty, not a misfit), is *open*
//! and the range extends to the search bound. A quantity is reported determined when its range is closed on
//! both sides (and, for an absolute parameter with several fitted, the scale direction is closed too).
//! These are slices, not re-optimised profiles: they can call a quantity determined that a full
//! profile would find correlated with another; the ratio and scale directions cover the correlations
//! the physics predicts.

use super::InferenceError;
use super::config::ProfileConfig;
use super::optimise::Evaluator;
use crate::geometry::Real;
use serde::Serialize;

/// The objective along one direction through the optimum.
#[derive(Clone, Debug, Serialize)]
pub struct Slice {
    /// What is varied: a parameter name, `scale`, or a ratio name.
    pub name: String,
    /// Log-space offsets from the optimum (of the varied quantity) and their objectives, ascending.
    pub offsets: Vec<Real>,
    pub objectives: Vec<Real>,
    /// Acceptable range of the offset `[lo, hi]`, model error included (widened in quadrature by `profile.model_error`);
    /// `None` on a side that never crossed.
    pub lower: Option<Real>,
    pub upper: Option<Real>,
    /// The same from the objective and its noise alone (without the model error).
    pub noise_lower: Option<Real>,
    pub noise_upper: Option<Real>,
}

/// A closed side's log offset (`sign` −1 below the optimum, +1 above) widened by the model's
/// relative error `model_error` in quadrature: sign·√(o² + ln(1 + m)²). An open side stays open.
fn with_model_error(offset: Option<Real>, sign: Real, model_error: Real) -> Option<Real> {
    let e = model_error.ln_1p();
    offset.map(|o| sign * o.hypot(e))
}

impl Slice {
    /// Closed on both sides.
    pub fn determined(&self) -> bool {
        self.lower.is_some() && self.upper.is_some()
    }
}

/// The forward model's noise at the optimum (see the module doc).
#[derive(Clone, Debug, Default, Serialize)]
pub struct NoiseFloor {
    /// Objectives of the best point and of its replicates (1 + k·1e-9), in that order.
    pub objectives: Vec<Real>,
    /// Their mean (the reference the threshold is measured from).
    pub reference: Real,
    /// Their standard deviation (n − 1); infinite when a replicate failed, 0 without replicates.
    pub std: Real,
    /// The acceptance threshold of the profile: reference + acceptable_increase + noise_sigmas·std.
    pub threshold: Real,
    /// Why σ is infinite (a replicate's failure), empty otherwise.
    pub reason: String,
    /// The objective that the observed mask's own boundary noise is expected to add at the truth
    /// (one realisation of `forward.roughen_voxels`' noise against their average; see
    /// [`super::ForwardModel::calibrate_roughness`]); the threshold adds `noise_sigmas`² times it. 0
    /// without roughening.
    pub mask: Real,
}

impl NoiseFloor {
    /// The noise floor from the best objective and its replicates' (objective, usable, reason).
    pub fn estimate(best: Real, replicates: &[(Real, bool, String)], config: &ProfileConfig) -> Self {
        let mut objectives = vec![best];
        objectives.extend(replicates.iter().map(|r| r.0));
        let failed = replicates.iter().find(|r| !r.1);
        let n = objectives.len() as Real;
        let reference = if failed.is_some() { best } else { objectives.iter().sum::<Real>() / n };
        let std = match failed {
            Some(_) => Real::INFINITY,
            None if objectives.len() < 2 => 0.0,
            None => (objectives.iter().map(|j| (j - reference).powi(2)).sum::<Real>() / (n - 1.0)).sqrt(),
        };
        let threshold = reference + config.acceptable_increase + config.noise_sigmas * std;
        let reason = failed.map(|r| r.2.clone()).unwrap_or_default();
        Self { objectives, reference, std, threshold, reason, mask: 0.0 }
    }

    /// Adds the mask's own noise `mask` (objective units, see [`NoiseFloor::mask`]) to the
    /// threshold: a range that a different draw of the segmentation's noise would move is not
    /// narrower than that move.
    pub fn with_mask_noise(mut self, mask: Real, config: &ProfileConfig) -> Self {
        if mask > 0.0 {
            self.mask = mask;
            self.threshold += config.noise_sigmas.powi(2) * mask;
        }
        self
    }
}

/// Relative step (in every log coordinate) between the optimum and its noise replicates (taken
/// downwards in a coordinate whose upper bound is that close).
pub const NOISE_STEP: Real = 1e-9;

/// A named direction in log space: offset δ of the quantity moves the point by δ·direction.
struct Direction {
    name: String,
    direction: Vec<Real>,
}

/// How far a unit step along the ratio num/den moves each fitted parameter's log: +½ and −½ when
/// both are fitted, the one fitted alone by ±1; `None` when neither is fitted.
pub fn ratio_direction(fitted: &[impl AsRef<str>], num: &str, den: &str) -> Option<Vec<Real>> {
    let position = |name: &str| fitted.iter().position(|f| f.as_ref() == name);
    let mut d = vec![0.0; fitted.len()];
    match (position(num), position(den)) {
        (Some(i), Some(j)) => {
            d[i] = 0.5;
            d[j] = -0.5;
        }
        (Some(i), None) => d[i] = 1.0,
        (None, Some(j)) => d[j] = -1.0,
        (None, None) => return None,
    }
    Some(d)
}

/// Names and (numerator, denominator) parameter choices of the key ratios.
pub fn ratio_parts(names: &[String]) -> Vec<(&'static str, &'static str, &'static str)> {
    let has = |n: &str| names.iter().any(|m| m == n);
    let mut out = Vec::new();
    let apical = if has("surface_tension_apical") {
        Some("surface_tension_apical")
    } else if has("surface_tension") {
        Some("surface_tension")
    } else {
        None
    };
    if has("surface_tension_lateral")
        && let Some(a) = apical
    {
        out.push(("lateral_over_apical", "surface_tension_lateral", a));
    }
    let tension = if has("surface_tension") { Some("surface_tension") } else { apical };
    if has("adhesion")
        && let Some(t) = tension
    {
        out.push(("adhesion_over_tension", "adhesion", t));
    }
    out
}

/// Probes every direction through `best` and returns the slices (parameters, scale, ratios) and
/// the noise floor at the optimum; [`InferenceError::Stopped`] when the caller stopped the fit.
pub fn profile(
    evaluator: &Evaluator<'_>,
    best: &[Real],
    best_objective: Real,
    config: &ProfileConfig,
) -> Result<(Vec<Slice>, NoiseFloor), InferenceError> {
    let space = &evaluator.model().space;
    let n = space.dim();
    if config.points == 0 {
        let mask = evaluator.model().mask_noise;
        return Ok((Vec::new(), NoiseFloor::estimate(best_objective, &[], config).with_mask_noise(mask, config)));
    }
    let fitted: Vec<String> = space.fitted.iter().map(|p| p.name().to_string()).collect();
    let mut dirs: Vec<Direction> = (0..n)
        .map(|i| {
            let mut d = vec![0.0; n];
            d[i] = 1.0;
            Direction { name: fitted[i].clone(), direction: d }
        })
        .collect();
    if n > 1 {
        dirs.push(Direction { name: "scale".into(), direction: vec![1.0; n] });
    }
    let mut all: Vec<String> = fitted.clone();
    all.extend(space.fixed.iter().map(|(k, _)| k.name().to_string()));
    for (name, num, den) in ratio_parts(&all) {
        let Some(d) = ratio_direction(&fitted, num, den) else { continue };
        // With a single fitted parameter the ratio's direction is that parameter's slice.
        if dirs.iter().any(|e| e.direction == d) {
            let twin = dirs.iter().find(|e| e.direction == d).map(|e| e.name.clone()).unwrap_or_default();
            dirs.push(Direction { name: format!("{name}={twin}"), direction: d });
            continue;
        }
        dirs.push(Direction { name: name.into(), direction: d });
    }
    let step = config.span.ln() / config.points as Real;
    let offsets: Vec<Real> = (1..=config.points)
        .rev()
        .map(|k| -(k as Real) * step)
        .chain((1..=config.points).map(|k| k as Real * step))
        .collect();
    let mut points = Vec::new();
    for d in &dirs {
        for &o in &offsets {
            points.push(best.iter().zip(&d.direction).map(|(b, v)| b + o * v).collect::<Vec<_>>());
        }
    }
    let probes = points.len();
    // Inward from an upper bound, so that clamping does not turn a replicate into the best point.
    let (_, upper) = space.log_bounds();
    let reach = config.noise_replicates as Real * NOISE_STEP;
    let sign: Vec<Real> = best.iter().zip(&upper).map(|(b, u)| if b + reach > *u { -1.0 } else { 1.0 }).collect();
    for k in 1..=config.noise_replicates {
        points.push(best.iter().zip(&sign).map(|(b, s)| b + s * k as Real * NOISE_STEP).collect());
    }
    // Profile points are not charged to the budget: only a stop refuses them.
    let evals = evaluator.evaluate_batch(&points, false).map_err(|_| InferenceError::Stopped)?;
    let replicates: Vec<(Real, bool, String)> =
        evals[probes..].iter().map(|e| (e.objective, e.status.usable(), e.reason.clone())).collect();
    let noise =
        NoiseFloor::estimate(best_objective, &replicates, config).with_mask_noise(evaluator.model().mask_noise, config);
    let (threshold, reference) = (noise.threshold, noise.reference);
    let per = offsets.len();
    let slices = dirs
        .iter()
        .enumerate()
        .map(|(k, d)| {
            let slice = &evals[k * per..(k + 1) * per];
            // Full curve including the optimum at offset 0.
            let mut xs = offsets.clone();
            let mut ys: Vec<Real> = slice.iter().map(|e| e.objective).collect();
            let mut usable: Vec<bool> = slice.iter().map(|e| e.status.usable()).collect();
            let mid = config.points;
            xs.insert(mid, 0.0);
            ys.insert(mid, best_objective);
            usable.insert(mid, true);
            let upper = crossing(&xs, &ys, &usable, mid, threshold, reference, Box::new(mid + 1..xs.len()));
            let lower = crossing(&xs, &ys, &usable, mid, threshold, reference, Box::new((0..mid).rev()));
            let name = d.name.split('=').next().unwrap_or(&d.name).to_string();
            // The scale direction is not a quantity the model's shape error applies to.
            let m = if name == "scale" { 0.0 } else { config.model_error };
            let (noise_lower, noise_upper) = (lower, upper);
            let lower = with_model_error(lower, -1.0, m);
            let upper = with_model_error(upper, 1.0, m);
            Slice { name, offsets: xs, objectives: ys, lower, upper, noise_lower, noise_upper }
        })
        .collect();
    Ok((slices, noise))
}

/// Where the objective first crosses `threshold` walking from the optimum (index `mid`) through
/// `order`: interpolated linearly in √(J − J_ref) (J_ref: `best`, the reference level), which grows linearly with the distance from the
/// optimum of a quadratic bowl (exact for a χ²-like objective; interpolating J itself puts the
/// crossing far too close to the optimum when the next point is steep). `None` (open) when no
/// point crosses, or when the walk meets a failed or unconverged run first: its objective is a
/// penalty, not a measured misfit, and says nothing about the objective there.
fn crossing(
    xs: &[Real],
    ys: &[Real],
    usable: &[bool],
    mid: usize,
    threshold: Real,
    best: Real,
    order: Box<dyn Iterator<Item = usize>>,
) -> Option<Real> {
    let root = |y: Real| (y - best).max(0.0).sqrt();
    let mut prev = mid;
    for i in order {
        if !usable[i] {
            return None;
        }
        if ys[i] > threshold {
            let (r0, r1, rt) = (root(ys[prev]), root(ys[i]), root(threshold));
            let t = if r1 > r0 { ((rt - r0) / (r1 - r0)).clamp(0.0, 1.0) } else { 0.0 };
            return Some(xs[prev] + t * (xs[i] - xs[prev]));
        }
        prev = i;
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The model error widens a closed side in quadrature, keeps its side, leaves an open side open,
    /// and with 0 changes nothing: a range of ±2 % from the objective and a 5 % model error give
    /// ±√(2² + 4.88²) ≈ 5.27 % in log space.
    #[test]
    fn the_model_error_widens_closed_sides_in_quadrature() {
        let (o, e) = (0.02_f64, 0.05_f64.ln_1p());
        let lo = with_model_error(Some(-o), -1.0, 0.05).unwrap();
        let hi = with_model_error(Some(o), 1.0, 0.05).unwrap();
        assert!((lo + o.hypot(e)).abs() < 1e-15 && (hi - o.hypot(e)).abs() < 1e-15, "{lo} {hi}");
        assert!(hi > e && hi < o + e);
        assert_eq!(with_model_error(None, 1.0, 0.05), None);
        assert_eq!(with_model_error(Some(-o), -1.0, 0.0), Some(-o));
        // A side closed at the optimum itself still gets the model error.
        assert!((with_model_error(Some(0.0), -1.0, 0.05).unwrap() + e).abs() < 1e-15);
    }

    /// The noisy spring aggregate of the README: the best point scored 1.2 and a one-bit twin 3.56.
    /// A slice that rises to 2.5–2.6 at ±0.1 crossed best + 1 = 2.2 there and was called
    /// determined; with the replicates' noise (σ ≈ 1.2) the threshold is 2.25 + 1 + 2σ ≈ 5.6 and
    /// nothing within the probed span rises above it, so both sides stay open.
    #[test]
    fn a_range_narrower_than_the_forward_models_noise_is_not_determined() {
        let config = ProfileConfig::default();
        let xs = [-0.2, -0.1, 0.0, 0.1, 0.2];
        let ys = [4.0, 2.5, 1.2, 2.6, 4.5];
        let usable = [true; 5];
        let closed = |threshold: Real, reference: Real| {
            let up = crossing(&xs, &ys, &usable, 2, threshold, reference, Box::new(3..5));
            let lo = crossing(&xs, &ys, &usable, 2, threshold, reference, Box::new((0..2).rev()));
            (lo, up)
        };
        // Without replicates: best + 1, closed on both sides inside ±0.1.
        let plain = NoiseFloor::estimate(1.2, &[], &config);
        assert_eq!((plain.reference, plain.std, plain.threshold), (1.2, 0.0, 2.2));
        let (lo, up) = closed(plain.threshold, plain.reference);
        assert!(lo.is_some_and(|l| l > -0.1) && up.is_some_and(|u| u < 0.1), "{lo:?} {up:?}");
        // With two replicates at the optimum (1.2, 3.56, 2.0): mean 2.2533, σ 1.2002.
        let noisy = NoiseFloor::estimate(1.2, &[(3.56, true, String::new()), (2.0, true, String::new())], &config);
        assert!((noisy.reference - 2.253_333).abs() < 1e-5, "{noisy:?}");
        assert!((noisy.std - 1.200_222).abs() < 1e-5, "{noisy:?}");
        assert!((noisy.threshold - (noisy.reference + 1.0 + 2.0 * noisy.std)).abs() < 1e-12);
        assert_eq!(closed(noisy.threshold, noisy.reference), (None, None));
        // A smooth model (replicates equal to the best) keeps the plain threshold.
        let smooth = NoiseFloor::estimate(1.2, &[(1.2, true, String::new()), (1.2, true, String::new())], &config);
        assert_eq!((smooth.std, smooth.threshold), (0.0, 2.2));
        // The mask's own noise (objective units) adds noise_sigmas² times itself; none adds nothing.
        let masked = NoiseFloor::estimate(1.2, &[], &config).with_mask_noise(0.5, &config);
        assert_eq!((masked.mask, masked.threshold), (0.5, 2.2 + 4.0 * 0.5));
        assert_eq!(NoiseFloor::estimate(1.2, &[], &config).with_mask_noise(0.0, &config).threshold, 2.2);
        // A failed replicate: the noise is unknown, the threshold infinite, nothing closes.
        let failed = NoiseFloor::estimate(1.2, &[(1e6, false, "simulation (pass 1): diverged".into())], &config);
        assert!(failed.std.is_infinite() && failed.threshold.is_infinite() && failed.reason.contains("diverged"));
        assert_eq!(closed(failed.threshold, failed.reference), (None, None));
    }

    /// A quadratic bowl J = 1 + 100·x² probed at x = ±0.2 (J = 5): best + 1 is crossed at x = ±0.1
    /// exactly (linear interpolation in J would say ±0.05).
    #[test]
    fn crossing_of_a_quadratic_bowl_is_exact_and_a_failed_point_leaves_the_side_open() {
        let xs = [-0.2, 0.0, 0.2];
        let ys = [5.0, 1.0, 5.0];
        let up = crossing(&xs, &ys, &[true; 3], 1, 2.0, 1.0, Box::new(2..3)).unwrap();
        let lo = crossing(&xs, &ys, &[true; 3], 1, 2.0, 1.0, Box::new((0..1).rev())).unwrap();
        assert!((up - 0.1).abs() < 1e-12 && (lo + 0.1).abs() < 1e-12, "{lo} {up}");
        // A penalised run below the optimum: that side is open, not closed at the optimum.
        let ys = [1e6, 1.0, 5.0];
        assert_eq!(crossing(&xs, &ys, &[false, true, true], 1, 2.0, 1.0, Box::new((0..1).rev())), None);
        // No crossing within the probed span: open.
        let ys = [1.5, 1.0, 1.5];
        assert_eq!(crossing(&xs, &ys, &[true; 3], 1, 2.0, 1.0, Box::new(2..3)), None);
    }
}

//! Summary statistics of a per-cell metric over a tissue.

use crate::geometry::Real;
use serde::Serialize;

/// Count, mean, sample standard deviation and quantiles of a set of values (non-finite values are left
/// out). Quantiles interpolate linearly between order statistics (Hyndman & Fan type 7, the default of
/// numpy and R). Every statistic is `None` (JSON `null`) for an empty set; `std` is `None` below 2 values.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Distribution {
    pub count: usize,
    pub mean: Option<Real>,
    /// Sample standard deviation (n − 1 in the denominator).
    pub std: Option<Real>,
    pub min: Option<Real>,
    pub q25: Option<Real>,
    pub median: Option<Real>,
    pub q75: Option<Real>,
    pub max: Option<Real>,
}

impl Distribution {
    /// Statistics of `values`, summed in the given order (deterministic).
    pub fn of(values: impl IntoIterator<Item = Real>) -> Self {
        let mut v: Vec<Real> = values.into_iter().filter(|x| x.is_finite()).collect();
        let n = v.len();
        if n == 0 {
            return Self::default();
        }
        let mean = v.iter().sum::<Real>() / n as Real;
        let std = (n > 1).then(|| (v.iter().map(|x| (x - mean).powi(2)).sum::<Real>() / (n - 1) as Real).sqrt());
        v.sort_by(|a, b| a.total_cmp(b));
        let q = |p: Real| {
            let h = p * (n - 1) as Real;
            let (lo, frac) = (h.floor() as usize, h - h.floor());
            let hi = (lo + 1).min(n - 1);
            v[lo] + frac * (v[hi] - v[lo])
        };
        Self {
            count: n,
            mean: Some(mean),
            std,
            min: Some(v[0]),
            q25: Some(q(0.25)),
            median: Some(q(0.5)),
            q75: Some(q(0.75)),
            max: Some(v[n - 1]),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn statistics_of_a_small_set() {
        let d = Distribution::of([4.0, 1.0, 3.0, 2.0, Real::NAN]);
        assert_eq!(d.count, 4);
        assert_eq!(d.mean, Some(2.5));
        assert!((d.std.unwrap() - (5.0f64 / 3.0).sqrt()).abs() < 1e-12);
        assert_eq!((d.min, d.q25, d.median, d.q75, d.max), (Some(1.0), Some(1.75), Some(2.5), Some(3.25), Some(4.0)));
        let one = Distribution::of([7.0]);
        assert_eq!((one.mean, one.std, one.median), (Some(7.0), None, Some(7.0)));
        assert_eq!(Distribution::of([]).mean, None);
    }
}

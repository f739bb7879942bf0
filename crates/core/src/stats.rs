//! Error summaries shared by every tool that reports accuracy (the fold rule of the evaluation
//! protocol is `wipdr_eval::fold_rules`).

use serde::{Deserialize, Serialize};

/// Summary of a set of errors (metres): count, mean, RMS and percentiles.
///
/// Non-finite errors (NaN, infinite) cannot be averaged: they are left out of the figures
/// and counted in [`ErrorStats::non_finite`], so a caller can report them; an empty set
/// (or one of non-finite errors only) has `count == 0` ([`ErrorStats::is_empty`]) and all
/// figures 0, which callers must not print as a result.
///
/// ```
/// use wipdr_core::stats::ErrorStats;
/// let s = ErrorStats::from_errors(&[1.0, 2.0, 3.0, 4.0, f64::NAN]);
/// assert_eq!((s.count, s.non_finite), (4, 1));
/// assert!((s.mean - 2.5).abs() < 1e-12);
/// assert!((s.p50 - 2.5).abs() < 1e-12);
/// assert_eq!(s.max, 4.0);
/// assert!(ErrorStats::from_errors(&[]).is_empty());
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct ErrorStats {
    /// Number of finite errors summarised.
    pub count: usize,
    /// Number of non-finite errors (NaN, infinite) left out of every figure.
    #[serde(default)]
    pub non_finite: usize,
    /// Mean.
    pub mean: f64,
    /// Root mean square.
    pub rms: f64,
    /// Median (linear interpolation between order statistics).
    pub p50: f64,
    /// 75th percentile.
    pub p75: f64,
    /// 90th percentile.
    pub p90: f64,
    /// 95th percentile.
    pub p95: f64,
    /// Maximum.
    pub max: f64,
}

impl ErrorStats {
    /// Summarises `errors`; non-finite values are left out of the figures and counted in
    /// [`ErrorStats::non_finite`]. All figures are 0 when no error is finite.
    pub fn from_errors(errors: &[f64]) -> Self {
        let mut v: Vec<f64> = errors.iter().copied().filter(|e| e.is_finite()).collect();
        let non_finite = errors.len() - v.len();
        if v.is_empty() {
            return Self {
                non_finite,
                ..Self::default()
            };
        }
        v.sort_by(f64::total_cmp);
        let n = v.len() as f64;
        let mean = v.iter().sum::<f64>() / n;
        let rms = (v.iter().map(|e| e * e).sum::<f64>() / n).sqrt();
        Self {
            count: v.len(),
            non_finite,
            mean,
            rms,
            p50: percentile_sorted(&v, 50.0),
            p75: percentile_sorted(&v, 75.0),
            p90: percentile_sorted(&v, 90.0),
            p95: percentile_sorted(&v, 95.0),
            max: v[v.len() - 1],
        }
    }

    /// No finite error was summarised: the figures are placeholders (0), not a result.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }
}

/// Percentile `q` (0-100) of sorted data, linear interpolation (numpy's default); 0 if empty.
/// `q` is clamped to `[0, 100]`; a NaN `q` counts as 0 (the minimum).
pub fn percentile_sorted(sorted: &[f64], q: f64) -> f64 {
    match sorted.len() {
        0 => 0.0,
        1 => sorted[0],
        n => {
            let q = if q.is_nan() { 0.0 } else { q.clamp(0.0, 100.0) };
            let pos = (q / 100.0) * (n - 1) as f64;
            // In [0, n - 1] by the clamp, so the cast is exact and in range.
            let lo = (pos.floor() as usize).min(n - 1);
            let hi = (lo + 1).min(n - 1);
            let f = pos - lo as f64;
            sorted[lo] * (1.0 - f) + sorted[hi] * f
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_and_nan() {
        assert_eq!(ErrorStats::from_errors(&[]), ErrorStats::default());
        assert!(ErrorStats::from_errors(&[]).is_empty());
        let s = ErrorStats::from_errors(&[f64::NAN, 3.0]);
        assert_eq!(s.count, 1);
        assert_eq!(s.p95, 3.0);
    }

    #[test]
    fn non_finite_errors_are_counted_not_dropped_silently() {
        let s = ErrorStats::from_errors(&[f64::NAN, 3.0, f64::INFINITY, f64::NEG_INFINITY]);
        assert_eq!((s.count, s.non_finite), (1, 3));
        assert_eq!(s.mean, 3.0);
        let s = ErrorStats::from_errors(&[f64::NAN]);
        assert!(s.is_empty());
        assert_eq!(s.non_finite, 1);
        assert_eq!(s.mean, 0.0);
    }

    #[test]
    fn percentile_of_a_nan_or_out_of_range_q_stays_in_the_data() {
        let v = [1.0, 2.0, 3.0];
        assert_eq!(percentile_sorted(&v, f64::NAN), 1.0);
        assert_eq!(percentile_sorted(&v, 1e300), 3.0);
        assert_eq!(percentile_sorted(&v, -5.0), 1.0);
    }

    #[test]
    fn percentiles_match_numpy() {
        let v: Vec<f64> = (1..=10).map(f64::from).collect();
        assert!((percentile_sorted(&v, 95.0) - 9.55).abs() < 1e-12);
        assert!((percentile_sorted(&v, 75.0) - 7.75).abs() < 1e-12);
    }
}

//! Error summaries shared by every tool that reports accuracy (the fold rule of the evaluation
//! protocol is `wipdr_eval::folds`).

use serde::{Deserialize, Serialize};

/// Summary of a set of errors (metres): count, mean, RMS and percentiles.
///
/// ```
/// use wipdr_core::stats::ErrorStats;
/// let s = ErrorStats::from_errors(&[1.0, 2.0, 3.0, 4.0]);
/// assert_eq!(s.count, 4);
/// assert!((s.mean - 2.5).abs() < 1e-12);
/// assert!((s.p50 - 2.5).abs() < 1e-12);
/// assert_eq!(s.max, 4.0);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct ErrorStats {
    /// Number of finite errors summarised.
    pub count: usize,
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
    /// Summarises `errors`; non-finite values are ignored (and not counted). All fields are 0
    /// for an empty set.
    pub fn from_errors(errors: &[f64]) -> Self {
        let mut v: Vec<f64> = errors.iter().copied().filter(|e| e.is_finite()).collect();
        if v.is_empty() {
            return Self::default();
        }
        v.sort_by(f64::total_cmp);
        let n = v.len() as f64;
        let mean = v.iter().sum::<f64>() / n;
        let rms = (v.iter().map(|e| e * e).sum::<f64>() / n).sqrt();
        Self {
            count: v.len(),
            mean,
            rms,
            p50: percentile_sorted(&v, 50.0),
            p75: percentile_sorted(&v, 75.0),
            p90: percentile_sorted(&v, 90.0),
            p95: percentile_sorted(&v, 95.0),
            max: v[v.len() - 1],
        }
    }
}

/// Percentile `q` (0-100) of sorted data, linear interpolation (numpy's default); 0 if empty.
pub fn percentile_sorted(sorted: &[f64], q: f64) -> f64 {
    match sorted.len() {
        0 => 0.0,
        1 => sorted[0],
        n => {
            let pos = (q.clamp(0.0, 100.0) / 100.0) * (n - 1) as f64;
            let lo = pos.floor() as usize;
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
        let s = ErrorStats::from_errors(&[f64::NAN, 3.0]);
        assert_eq!(s.count, 1);
        assert_eq!(s.p95, 3.0);
    }

    #[test]
    fn percentiles_match_numpy() {
        let v: Vec<f64> = (1..=10).map(f64::from).collect();
        assert!((percentile_sorted(&v, 95.0) - 9.55).abs() < 1e-12);
        assert!((percentile_sorted(&v, 75.0) - 7.75).abs() < 1e-12);
    }
}

//! The quantile rule of the organisers' scorer: MATLAB's `quantile`.
//!
//! The `i`-th of `n` sorted values (1-based) sits at cumulative probability `(i - 0.5) / n`;
//! a quantile in between two of them is interpolated linearly, and one below the first or
//! above the last is that value (clamped). It is not numpy's default (`(i - 1) / (n - 1)`,
//! [`wipdr_core::stats::percentile_sorted`]): on the 69 points of a 2023 scoring trial the two
//! rules give a P95 0.6 m apart.

/// The `p` quantile (`0..=1`) of `sorted` (ascending, finite) by MATLAB's rule; `None` when
/// `sorted` is empty. A `p` outside `[0, 1]` is clamped; a NaN `p` counts as 0.
///
/// ```
/// use wipdr_eval::evaal_score::quantile_sorted;
/// let v = [1.0, 2.0, 3.0, 4.0];
/// assert_eq!(quantile_sorted(&v, 0.75), Some(3.5)); // numpy's default gives 3.25
/// assert_eq!(quantile_sorted(&v, 0.5), Some(2.5));
/// assert_eq!(quantile_sorted(&v, 0.95), Some(4.0)); // above (n - 0.5) / n: the maximum
/// assert_eq!(quantile_sorted(&[], 0.5), None);
/// ```
pub fn quantile_sorted(sorted: &[f64], p: f64) -> Option<f64> {
    let (first, last) = (*sorted.first()?, *sorted.last()?);
    let n = sorted.len();
    let p = if p.is_nan() { 0.0 } else { p.clamp(0.0, 1.0) };
    // 0-based position of `p` among the values: value i sits at (i + 0.5) / n.
    let pos = p * n as f64 - 0.5;
    if pos <= 0.0 {
        return Some(first);
    }
    // `pos` is in (0, n - 0.5]: below `n`, so the truncation is exact and in range.
    let lo = pos.floor() as usize;
    if lo + 1 >= n {
        return Some(last);
    }
    let f = pos - lo as f64;
    Some(sorted[lo] + (sorted[lo + 1] - sorted[lo]) * f)
}

/// The `p` quantile of the finite values of `values` (any order) by MATLAB's rule
/// ([`quantile_sorted`]); `None` without a finite value.
pub fn quantile(values: &[f64], p: f64) -> Option<f64> {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    quantile_sorted(&v, p)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_sit_at_i_minus_a_half_over_n() {
        let v = [10.0, 20.0, 30.0, 40.0, 50.0];
        // Positions 0.1, 0.3, 0.5, 0.7, 0.9.
        for (p, want) in [
            (0.1, 10.0),
            (0.3, 20.0),
            (0.5, 30.0),
            (0.7, 40.0),
            (0.9, 50.0),
        ] {
            assert!(
                (quantile_sorted(&v, p).unwrap() - want).abs() < 1e-12,
                "{p}"
            );
        }
        assert!((quantile_sorted(&v, 0.75).unwrap() - 42.5).abs() < 1e-12);
        assert!((quantile_sorted(&v, 0.2).unwrap() - 15.0).abs() < 1e-12);
    }

    #[test]
    fn the_ends_are_clamped() {
        let v = [1.0, 2.0, 3.0, 4.0];
        assert_eq!(quantile_sorted(&v, 0.1), Some(1.0));
        assert_eq!(quantile_sorted(&v, 0.125), Some(1.0));
        assert_eq!(quantile_sorted(&v, 0.875), Some(4.0));
        assert_eq!(quantile_sorted(&v, 0.99), Some(4.0));
        assert_eq!(quantile_sorted(&v, -3.0), Some(1.0));
        assert_eq!(quantile_sorted(&v, 7.0), Some(4.0));
        assert_eq!(quantile_sorted(&v, f64::NAN), Some(1.0));
        assert_eq!(quantile_sorted(&[7.0], 0.75), Some(7.0));
    }

    #[test]
    fn the_median_is_the_usual_median() {
        assert_eq!(quantile(&[3.0, 1.0, 2.0], 0.5), Some(2.0));
        assert_eq!(quantile(&[4.0, 1.0, 3.0, 2.0], 0.5), Some(2.5));
        assert_eq!(quantile(&[f64::NAN, 4.0, f64::INFINITY], 0.5), Some(4.0));
        assert_eq!(quantile(&[f64::NAN], 0.5), None);
    }

    proptest::proptest! {
        #[test]
        fn within_the_range_and_monotone(
            v in proptest::collection::vec(-1e6f64..1e6, 1..50),
            p in 0.0f64..1.0,
            q in 0.0f64..1.0,
        ) {
            let mut v = v;
            v.sort_by(f64::total_cmp);
            let a = quantile_sorted(&v, p.min(q)).unwrap();
            let b = quantile_sorted(&v, p.max(q)).unwrap();
            proptest::prop_assert!(v[0] <= a && a <= b && b <= v[v.len() - 1]);
        }
    }
}

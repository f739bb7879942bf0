//! Resampling as free functions returning the indexes of the particles to keep (FilterPy's
//! shape). Weights are assumed normalised; the last cumulative weight is clamped to 1 so that
//! rounding never indexes past the end.
//!
//! ```
//! use rand::SeedableRng;
//! let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(7);
//! let idx = wipdr_fusion::resample::systematic(&[0.0, 1.0, 0.0], &mut rng);
//! assert_eq!(idx, vec![1, 1, 1]);
//! ```

use rand::{Rng, RngExt};

fn cumulative(weights: &[f64]) -> Vec<f64> {
    let mut acc = 0.0;
    let mut c: Vec<f64> = weights
        .iter()
        .map(|w| {
            acc += if w.is_finite() && *w > 0.0 { *w } else { 0.0 };
            acc
        })
        .collect();
    if let Some(last) = c.last_mut() {
        *last = 1.0;
    }
    c
}

fn pick(cum: &[f64], positions: impl Iterator<Item = f64>) -> Vec<usize> {
    let n = cum.len();
    let mut out = Vec::with_capacity(n);
    let mut j = 0;
    for u in positions {
        while j + 1 < n && cum[j] <= u {
            j += 1;
        }
        out.push(j);
    }
    out
}

/// Systematic resampling: one uniform offset, `n` evenly spaced positions.
pub fn systematic<R: Rng + ?Sized>(weights: &[f64], rng: &mut R) -> Vec<usize> {
    let n = weights.len();
    if n == 0 {
        return vec![];
    }
    let u0: f64 = rng.random_range(0.0..1.0);
    pick(
        &cumulative(weights),
        (0..n).map(|i| (i as f64 + u0) / n as f64),
    )
}

/// Stratified resampling: one uniform draw inside each of `n` strata.
pub fn stratified<R: Rng + ?Sized>(weights: &[f64], rng: &mut R) -> Vec<usize> {
    let n = weights.len();
    if n == 0 {
        return vec![];
    }
    let cum = cumulative(weights);
    let positions: Vec<f64> = (0..n)
        .map(|i| (i as f64 + rng.random_range(0.0..1.0)) / n as f64)
        .collect();
    pick(&cum, positions.into_iter())
}

/// Multinomial resampling: `n` independent draws (sorted, then picked).
pub fn multinomial<R: Rng + ?Sized>(weights: &[f64], rng: &mut R) -> Vec<usize> {
    let n = weights.len();
    let mut u: Vec<f64> = (0..n).map(|_| rng.random_range(0.0..1.0)).collect();
    u.sort_by(f64::total_cmp);
    pick(&cumulative(weights), u.into_iter())
}

/// Residual resampling: `floor(n w_i)` copies of each particle, the rest multinomially.
pub fn residual<R: Rng + ?Sized>(weights: &[f64], rng: &mut R) -> Vec<usize> {
    let n = weights.len();
    let mut out = Vec::with_capacity(n);
    let mut residuals = Vec::with_capacity(n);
    for (i, w) in weights.iter().enumerate() {
        let w = if w.is_finite() && *w > 0.0 { *w } else { 0.0 };
        // Checked: an unnormalised weight (n w > n) still gives at most n copies.
        let copies = wipdr_core::grid::checked_usize((n as f64 * w).floor(), n).unwrap_or(n);
        out.extend(std::iter::repeat_n(i, copies.min(n - out.len().min(n))));
        residuals.push(n as f64 * w - copies as f64);
    }
    out.truncate(n);
    let rest = n - out.len();
    if rest > 0 {
        let sum: f64 = residuals.iter().sum();
        let r: Vec<f64> = if sum > 0.0 {
            residuals.iter().map(|r| r / sum).collect()
        } else {
            vec![1.0 / n as f64; n]
        };
        let mut extra = multinomial(&r, rng);
        extra.truncate(rest);
        out.extend(extra);
    }
    out
}

/// Effective sample size `1 / sum w^2` of normalised weights.
pub fn effective_sample_size(weights: &[f64]) -> f64 {
    let s: f64 = weights.iter().map(|w| w * w).sum();
    if s > 0.0 { 1.0 / s } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use rand::SeedableRng;
    use rand::rngs::ChaCha8Rng;

    proptest! {
        #[test]
        fn every_scheme_keeps_the_count_and_valid_indexes(
            raw in prop::collection::vec(0.0f64..1.0, 1..300), seed in any::<u64>()
        ) {
            let sum: f64 = raw.iter().sum();
            let w: Vec<f64> = if sum > 0.0 { raw.iter().map(|x| x / sum).collect() }
                else { vec![1.0 / raw.len() as f64; raw.len()] };
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            for idx in [systematic(&w, &mut rng), stratified(&w, &mut rng),
                        multinomial(&w, &mut rng), residual(&w, &mut rng)] {
                prop_assert_eq!(idx.len(), w.len());
                for i in idx {
                    prop_assert!(i < w.len());
                    prop_assert!(w[i] > 0.0);
                }
            }
        }
    }

    #[test]
    fn sum_slightly_below_one_never_indexes_past_the_end() {
        let w = vec![0.1 - 1e-12; 10];
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..100 {
            assert!(systematic(&w, &mut rng).iter().all(|&i| i < 10));
        }
        assert!((effective_sample_size(&[0.5, 0.5]) - 2.0).abs() < 1e-12);
    }
}

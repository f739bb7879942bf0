//! K-means baseline (Lloyd's algorithm) for the clustering comparison of paper 001 §2.2
//! ("compared with the K-means method, APC has a faster convergence rate ...").
//!
//! Deterministic: the initial centres are chosen by farthest-point seeding (the first row, then
//! repeatedly the row farthest from every centre so far, ties to the lower index), so no random
//! seed is involved and the result is reproducible. Squared Euclidean distance over the filled
//! RSS vectors; an emptied cluster keeps its previous centre. Stops when no label changes or
//! after `max_iter` iterations (reported, never an endless loop).
//!
//! ```
//! use wipdr_fingerprint::kmeans::{kmeans, KMeansConfig};
//! let data = [0.0f32, 0.0, 0.1, 0.0, 10.0, 10.0, 10.1, 10.0];
//! let out = kmeans(&data, 2, &KMeansConfig { k: 2, ..KMeansConfig::default() }).unwrap();
//! assert_eq!(out.labels[0], out.labels[1]);
//! assert_ne!(out.labels[0], out.labels[2]);
//! assert!(out.converged);
//! ```

use crate::FingerprintError;
use crate::mixdis::squared_euclidean;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// K-means settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct KMeansConfig {
    /// Number of clusters (capped at the number of rows).
    pub k: usize,
    /// Maximum Lloyd iterations.
    pub max_iter: usize,
}

impl Default for KMeansConfig {
    fn default() -> Self {
        Self {
            k: 8,
            max_iter: 100,
        }
    }
}

/// A K-means clustering.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct KMeansResult {
    /// Cluster of each row.
    pub labels: Vec<usize>,
    /// Centres, row-major `k x dim`.
    pub centres: Vec<f32>,
    /// Number of clusters.
    pub k: usize,
    /// Iterations run.
    pub iterations: usize,
    /// Whether the labels stopped changing before `max_iter`.
    pub converged: bool,
}

/// Runs K-means on `data` (`n` rows of `dim` values, row-major).
pub fn kmeans(
    data: &[f32],
    dim: usize,
    config: &KMeansConfig,
) -> Result<KMeansResult, FingerprintError> {
    if dim == 0 || data.is_empty() || !data.len().is_multiple_of(dim) {
        return Err(FingerprintError::InvalidInput(format!(
            "k-means: {} values are not rows of {dim}",
            data.len()
        )));
    }
    if config.k == 0 || config.max_iter == 0 {
        return Err(FingerprintError::InvalidConfig(
            wipdr_core::ConfigError::new("kmeans", "k and max_iter must be at least 1"),
        ));
    }
    if data.iter().any(|v| !v.is_finite()) {
        return Err(FingerprintError::InvalidInput(
            "k-means: non-finite value".into(),
        ));
    }
    let n = data.len() / dim;
    let k = config.k.min(n);
    let row = |i: usize| &data[i * dim..(i + 1) * dim];
    // Farthest-point seeding.
    let mut centres: Vec<f32> = row(0).to_vec();
    let mut nearest: Vec<f32> = (0..n).map(|i| squared_euclidean(row(i), row(0))).collect();
    for _ in 1..k {
        let (far, _) = nearest
            .iter()
            .enumerate()
            .fold(
                (0, f32::NEG_INFINITY),
                |b, (i, &d)| if d > b.1 { (i, d) } else { b },
            );
        centres.extend_from_slice(row(far));
        let c = &centres[centres.len() - dim..];
        for (i, d) in nearest.iter_mut().enumerate() {
            *d = d.min(squared_euclidean(row(i), c));
        }
    }
    let mut labels = vec![usize::MAX; n];
    let mut iterations = 0;
    let mut converged = false;
    for _ in 0..config.max_iter {
        iterations += 1;
        let new: Vec<usize> = (0..n)
            .into_par_iter()
            .map(|i| {
                let mut best = (0, f32::INFINITY);
                for c in 0..k {
                    let d = squared_euclidean(row(i), &centres[c * dim..(c + 1) * dim]);
                    if d < best.1 {
                        best = (c, d);
                    }
                }
                best.0
            })
            .collect();
        let changed = new != labels;
        labels = new;
        if !changed {
            converged = true;
            break;
        }
        let mut sums = vec![0f64; k * dim];
        let mut counts = vec![0usize; k];
        for (i, &l) in labels.iter().enumerate() {
            counts[l] += 1;
            for (s, &v) in sums[l * dim..(l + 1) * dim].iter_mut().zip(row(i)) {
                *s += f64::from(v);
            }
        }
        for c in 0..k {
            if counts[c] > 0 {
                for (dst, s) in centres[c * dim..(c + 1) * dim]
                    .iter_mut()
                    .zip(&sums[c * dim..(c + 1) * dim])
                {
                    *dst = (s / counts[c] as f64) as f32;
                }
            }
        }
    }
    Ok(KMeansResult {
        labels,
        centres,
        k,
        iterations,
        converged,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn separates_blobs_and_is_deterministic() {
        let mut data = Vec::new();
        for i in 0..30 {
            let c = (i % 3) as f32 * 20.0;
            data.extend_from_slice(&[c + (i % 5) as f32 * 0.1, -c]);
        }
        let cfg = KMeansConfig { k: 3, max_iter: 50 };
        let a = kmeans(&data, 2, &cfg).unwrap();
        let b = kmeans(&data, 2, &cfg).unwrap();
        assert_eq!(a, b);
        assert!(a.converged);
        for i in 0..30 {
            assert_eq!(a.labels[i], a.labels[i % 3]);
        }
        assert_eq!(
            a.labels
                .iter()
                .collect::<std::collections::BTreeSet<_>>()
                .len(),
            3
        );
    }

    #[test]
    fn bad_input_is_an_error() {
        assert!(kmeans(&[1.0, 2.0, 3.0], 2, &KMeansConfig::default()).is_err());
        assert!(kmeans(&[1.0, f32::NAN], 2, &KMeansConfig::default()).is_err());
        assert!(kmeans(&[1.0, 2.0], 2, &KMeansConfig { k: 0, max_iter: 5 }).is_err());
    }
}

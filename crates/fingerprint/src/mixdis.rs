//! Clustering features of paper 001 §2.1 (eq. 1-3) and the similarity matrices fed to
//! [`affinity_propagation`](crate::affinity::affinity_propagation).
//!
//! - **SigDis** (eq. 1): `sum_k |v_ik - v_jk| / m_ij` over every AP column (not-heard entries
//!   at the fill value, so an AP heard at only one of the two points counts with its full
//!   difference to the fill value), `m_ij` = number of APs heard at both points. `m_ij = 0`
//!   means "infinitely far" ([`f64::INFINITY`]).
//! - **GeoDis** (eq. 2): Euclidean distance of the positions.
//! - **MixDis** (eq. 3): `Nor(SigDis) * Nor(GeoDis)` with `Nor` the min-max normalisation over
//!   all pairs `i != j` (pairs with infinite SigDis excluded from SigDis's min and max).
//! - Similarity = **-MixDis** (`docs/algorithms.md` erratum: the paper feeds MixDis in as
//!   `s(i, j)`, but a similarity must grow with likeness). Pairs with `m_ij = 0` get
//!   `-`[`MixDisConfig::disjoint_mixdis`] (default 10, ten times the largest possible finite
//!   MixDis), finite so that affinity propagation can run, and never chosen over a real pair.
//! - **Signal similarity** for comparison: `-sum_k (v_ik - v_jk)^2` (negative squared
//!   Euclidean distance of the filled RSS vectors, scikit-learn's `affinity="euclidean"`).
//!
//! Every function here takes a contiguous row-major block of fingerprints (`n` rows of
//! `n_aps` values, not-heard entries equal to `not_heard`) and returns N² values: memory
//! O(N²).
//!
//! ```
//! use wipdr_fingerprint::mixdis::{sig_dis, signal_similarity, Fingerprints};
//! use wipdr_core::Point2;
//! let rss = [-40.0, -60.0, -110.0, /**/ -42.0, -61.0, -110.0, /**/ -110.0, -110.0, -50.0];
//! let pos = [Point2::new(0.0, 0.0), Point2::new(1.0, 0.0), Point2::new(9.0, 0.0)];
//! let fp = Fingerprints::new(&rss, 3, &pos, -110.0).unwrap();
//! let d = sig_dis(&fp);
//! assert_eq!(d[1], 3.0 / 2.0); // |-40+42| + |-60+61| over 2 shared APs
//! assert!(d[2].is_infinite()); // no AP heard at both points 0 and 2
//! let s = signal_similarity(&fp);
//! assert_eq!(s.get(0, 1), -5.0);
//! ```

use crate::affinity::SimilarityMatrix;
use crate::{FingerprintError, RadioMap};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use wipdr_core::Point2;

/// A borrowed block of fingerprints with positions.
#[derive(Debug, Clone, Copy)]
pub struct Fingerprints<'a> {
    rss: &'a [f32],
    n_aps: usize,
    positions: &'a [Point2],
    not_heard: f32,
}

impl<'a> Fingerprints<'a> {
    /// `rss` holds `positions.len()` rows of `n_aps` values; entries equal to `not_heard`
    /// are "not heard".
    pub fn new(
        rss: &'a [f32],
        n_aps: usize,
        positions: &'a [Point2],
        not_heard: f32,
    ) -> Result<Self, FingerprintError> {
        if rss.len() != positions.len() * n_aps {
            return Err(FingerprintError::DimensionMismatch {
                expected: positions.len() * n_aps,
                found: rss.len(),
            });
        }
        if let Some(bad) = rss.iter().position(|v| !v.is_finite()) {
            return Err(FingerprintError::InvalidInput(format!(
                "non-finite RSS at row {}, column {}",
                bad / n_aps.max(1),
                bad % n_aps.max(1)
            )));
        }
        Ok(Self {
            rss,
            n_aps,
            positions,
            not_heard,
        })
    }

    /// Number of fingerprints.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Whether there is none.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Row `i`.
    pub fn row(&self, i: usize) -> &'a [f32] {
        &self.rss[i * self.n_aps..(i + 1) * self.n_aps]
    }
}

/// An owned copy of some reference points of a [`RadioMap`], in the layout of
/// [`Fingerprints`].
#[derive(Debug, Clone)]
pub struct OwnedFingerprints {
    /// Row-major filled RSS.
    pub rss: Vec<f32>,
    /// Columns per row.
    pub n_aps: usize,
    /// Positions.
    pub positions: Vec<Point2>,
    /// The fill value.
    pub not_heard: f32,
}

impl OwnedFingerprints {
    /// Copies the points `indices` of `map`.
    pub fn from_map(map: &RadioMap, indices: &[usize]) -> Self {
        let mut rss = Vec::with_capacity(indices.len() * map.n_aps());
        for &i in indices {
            rss.extend_from_slice(map.filled_row(i));
        }
        Self {
            rss,
            n_aps: map.n_aps(),
            positions: indices.iter().map(|&i| map.point(i).position).collect(),
            not_heard: map.not_heard_dbm(),
        }
    }

    /// The borrowed view.
    pub fn view(&self) -> Fingerprints<'_> {
        Fingerprints {
            rss: &self.rss,
            n_aps: self.n_aps,
            positions: &self.positions,
            not_heard: self.not_heard,
        }
    }
}

/// Which similarity the clustering uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum SimilarityKind {
    /// `-MixDis` (paper 001 eq. 3 with the sign erratum).
    #[default]
    MixDis,
    /// Negative squared Euclidean distance of the RSS vectors.
    Signal,
}

/// MixDis settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MixDisConfig {
    /// MixDis given to pairs with no AP heard at both points (`m_ij = 0`, SigDis infinite);
    /// finite MixDis values lie in `[0, 1]`.
    pub disjoint_mixdis: f64,
}

impl Default for MixDisConfig {
    fn default() -> Self {
        Self {
            disjoint_mixdis: 10.0,
        }
    }
}

const LANES: usize = 8;

/// `sum_k |a_k - b_k|` and the number of columns heard in both.
#[inline]
fn abs_diff_and_shared(a: &[f32], b: &[f32], not_heard: f32) -> (f64, usize) {
    let mut acc = [0f32; LANES];
    let mut shared = [0u32; LANES];
    let ca = a.chunks_exact(LANES);
    let cb = b.chunks_exact(LANES);
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (xa, xb) in ca.zip(cb) {
        for l in 0..LANES {
            acc[l] += (xa[l] - xb[l]).abs();
            shared[l] += u32::from(xa[l] != not_heard && xb[l] != not_heard);
        }
    }
    let mut total: f64 = acc.iter().map(|&v| f64::from(v)).sum();
    let mut m: usize = shared.iter().map(|&v| v as usize).sum();
    for (&x, &y) in ra.iter().zip(rb) {
        total += f64::from((x - y).abs());
        m += usize::from(x != not_heard && y != not_heard);
    }
    (total, m)
}

/// `sum_k (a_k - b_k)^2` (exact for integer dBm values up to 2^24 per lane).
#[inline]
pub fn squared_euclidean(a: &[f32], b: &[f32]) -> f32 {
    let mut acc = [0f32; LANES];
    let ca = a.chunks_exact(LANES);
    let cb = b.chunks_exact(LANES);
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (xa, xb) in ca.zip(cb) {
        for l in 0..LANES {
            let d = xa[l] - xb[l];
            acc[l] += d * d;
        }
    }
    let mut total: f32 = acc.iter().sum();
    for (&x, &y) in ra.iter().zip(rb) {
        let d = x - y;
        total += d * d;
    }
    total
}

/// SigDis (paper 001 eq. 1) for all pairs, row-major N²; diagonal 0; `m_ij = 0` -> infinity.
pub fn sig_dis(fp: &Fingerprints<'_>) -> Vec<f64> {
    let n = fp.len();
    let mut out = vec![0.0; n * n];
    if n == 0 {
        return out;
    }
    out.par_chunks_mut(n).enumerate().for_each(|(i, row)| {
        let a = fp.row(i);
        for (j, v) in row.iter_mut().enumerate() {
            if j == i {
                continue;
            }
            let (sum, m) = abs_diff_and_shared(a, fp.row(j), fp.not_heard);
            *v = if m == 0 {
                f64::INFINITY
            } else {
                sum / m as f64
            };
        }
    });
    out
}

/// GeoDis (paper 001 eq. 2) for all pairs, row-major N².
pub fn geo_dis(positions: &[Point2]) -> Vec<f64> {
    let n = positions.len();
    let mut out = vec![0.0; n * n];
    if n == 0 {
        return out;
    }
    out.par_chunks_mut(n).enumerate().for_each(|(i, row)| {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (positions[i] - positions[j]).norm();
        }
    });
    out
}

/// Min-max range over the off-diagonal finite entries; `None` if there is none.
fn off_diagonal_range(values: &[f64], n: usize) -> Option<(f64, f64)> {
    let (lo, hi) = values
        .par_chunks(n.max(1))
        .enumerate()
        .map(|(i, row)| {
            let mut lo = f64::INFINITY;
            let mut hi = f64::NEG_INFINITY;
            for (j, &v) in row.iter().enumerate() {
                if j != i && v.is_finite() {
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
            }
            (lo, hi)
        })
        .reduce(
            || (f64::INFINITY, f64::NEG_INFINITY),
            |a, b| (a.0.min(b.0), a.1.max(b.1)),
        );
    (lo <= hi).then_some((lo, hi))
}

/// `Nor` of eq. 3: `(v - min) / (max - min)` over off-diagonal finite entries, in place;
/// a constant set maps to 0; infinite entries stay infinite.
pub fn min_max_normalise(values: &mut [f64], n: usize) {
    let Some((lo, hi)) = off_diagonal_range(values, n) else {
        return;
    };
    let span = hi - lo;
    values.par_iter_mut().for_each(|v| {
        if v.is_finite() {
            *v = if span > 0.0 {
                ((*v - lo) / span).max(0.0)
            } else {
                0.0
            };
        }
    });
}

/// MixDis (paper 001 eq. 3) for all pairs, row-major N²: `Nor(SigDis) * Nor(GeoDis)`,
/// diagonal 0, pairs without a shared AP at [`MixDisConfig::disjoint_mixdis`].
pub fn mix_dis(fp: &Fingerprints<'_>, config: &MixDisConfig) -> Vec<f64> {
    let n = fp.len();
    let mut sig = sig_dis(fp);
    let mut geo = geo_dis(fp.positions);
    min_max_normalise(&mut sig, n);
    min_max_normalise(&mut geo, n);
    sig.par_chunks_mut(n.max(1))
        .zip(geo.par_chunks(n.max(1)))
        .enumerate()
        .for_each(|(i, (srow, grow))| {
            for (j, (s, &g)) in srow.iter_mut().zip(grow).enumerate() {
                *s = if j == i {
                    0.0
                } else if s.is_finite() {
                    *s * g
                } else {
                    config.disjoint_mixdis
                };
            }
        });
    sig
}

/// Similarity `-MixDis` (paper 001 eq. 3 with the sign erratum), as `f32`.
pub fn mixdis_similarity(fp: &Fingerprints<'_>, config: &MixDisConfig) -> SimilarityMatrix<f32> {
    let n = fp.len();
    let data: Vec<f32> = mix_dis(fp, config).par_iter().map(|&v| -v as f32).collect();
    SimilarityMatrix::new(n, data).unwrap_or_else(|_| unreachable!("n*n values by construction"))
}

/// Similarity `-||v_i - v_j||^2` of the filled RSS vectors, as `f32` (symmetric; each pair
/// computed once).
pub fn signal_similarity(fp: &Fingerprints<'_>) -> SimilarityMatrix<f32> {
    let n = fp.len();
    let mut data = vec![0f32; n * n];
    if n == 0 {
        return SimilarityMatrix::new(0, data).unwrap_or_else(|_| unreachable!());
    }
    // Upper triangle by rows in parallel, then mirror.
    data.par_chunks_mut(n).enumerate().for_each(|(i, row)| {
        let a = fp.row(i);
        for (j, v) in row.iter_mut().enumerate().skip(i + 1) {
            *v = -squared_euclidean(a, fp.row(j));
        }
    });
    for i in 0..n {
        for j in 0..i {
            data[i * n + j] = data[j * n + i];
        }
    }
    SimilarityMatrix::new(n, data).unwrap_or_else(|_| unreachable!("n*n values by construction"))
}

/// The similarity of `kind` for a block of fingerprints.
pub fn similarity(
    fp: &Fingerprints<'_>,
    kind: SimilarityKind,
    config: &MixDisConfig,
) -> SimilarityMatrix<f32> {
    match kind {
        SimilarityKind::MixDis => mixdis_similarity(fp, config),
        SimilarityKind::Signal => signal_similarity(fp),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn block(rows: &[[f32; 3]]) -> (Vec<f32>, Vec<Point2>) {
        let rss = rows.iter().flatten().copied().collect();
        let pos = (0..rows.len())
            .map(|i| Point2::new(i as f64, 0.0))
            .collect();
        (rss, pos)
    }

    #[test]
    fn sigdis_counts_only_shared_aps_and_marks_disjoint_pairs_infinite() {
        let (rss, pos) = block(&[
            [-40.0, -110.0, -70.0],
            [-50.0, -60.0, -110.0],
            [-110.0, -80.0, -110.0],
        ]);
        let fp = Fingerprints::new(&rss, 3, &pos, -110.0).unwrap();
        let d = sig_dis(&fp);
        // (0,1): |10| + |50| + |40| over m = 1 shared AP (column 0)
        assert_eq!(d[1], 100.0);
        // (0,2): no AP heard at both
        assert!(d[2].is_infinite());
        // (1,2): |60| + |20| + 0 over 1 shared AP (column 1)
        assert_eq!(d[5], 80.0);
        assert_eq!(d[0], 0.0);
    }

    #[test]
    fn mixdis_is_product_of_normalised_features_in_unit_range() {
        let (rss, pos) = block(&[
            [-40.0, -50.0, -70.0],
            [-45.0, -55.0, -75.0],
            [-80.0, -50.0, -40.0],
        ]);
        let fp = Fingerprints::new(&rss, 3, &pos, -110.0).unwrap();
        let m = mix_dis(&fp, &MixDisConfig::default());
        // SigDis: (0,1) = 15/3 = 5, (0,2) = 70/3, (1,2) = 35+5+35 = 75/3 = 25 -> Nor 0, .8772, 1
        // GeoDis: 1, 2, 1 -> Nor 0, 1, 0
        assert_eq!(m[1], 0.0);
        assert!((m[2] - (70.0 / 3.0 - 5.0) / 20.0).abs() < 1e-12);
        assert_eq!(m[5], 0.0);
        for v in &m {
            assert!((0.0..=1.0).contains(v));
        }
    }

    proptest! {
        #[test]
        fn similarities_are_symmetric_finite_and_nonpositive(
            vals in proptest::collection::vec(prop_oneof![Just(-110.0f32), -100.0f32..-30.0], 5 * 6),
        ) {
            let pos: Vec<Point2> = (0..5).map(|i| Point2::new(i as f64, (i * i) as f64)).collect();
            let fp = Fingerprints::new(&vals, 6, &pos, -110.0).unwrap();
            for s in [mixdis_similarity(&fp, &MixDisConfig::default()), signal_similarity(&fp)] {
                for i in 0..5 {
                    prop_assert_eq!(s.get(i, i), 0.0);
                    for j in 0..5 {
                        prop_assert!(s.get(i, j).is_finite() && s.get(i, j) <= 0.0);
                        prop_assert_eq!(s.get(i, j), s.get(j, i));
                    }
                }
            }
        }
    }
}

//! Affinity propagation (Frey & Dueck 2007; paper 001 §2.2, eq. 4-6) on any similarity matrix.
//!
//! # The algorithm
//!
//! Each point `i` sends every candidate exemplar `k` a *responsibility* `r(i, k)` (eq. 4) and
//! receives an *availability* `a(i, k)` (eq. 5, self-availability eq. 6). Both are damped:
//! `new = damping * old + (1 - damping) * update`. After each iteration a point is an exemplar
//! when `a(k, k) + r(k, k) > 0`; the run stops when the exemplar set has been unchanged for
//! `convergence_iter` consecutive iterations (and is not empty), or after `max_iter`
//! iterations, in which case the outcome says [`ConvergenceStatus::NotConverged`]. It never
//! loops forever.
//!
//! The update order, the convergence rule, the final exemplar refinement and the degenerate
//! case (all similarities and preferences equal) follow scikit-learn's
//! `_affinity_propagation` (version 1.9) exactly, so that the same matrix gives the same
//! exemplars. scikit-learn adds tiny noise `(eps * s + 100 * tiny) * N(0, 1)` to the matrix
//! with a seeded NumPy `RandomState` to break ties; [`TieBreakNoise::SklearnCompatible`]
//! reproduces that stream bit for bit (MT19937 + NumPy's legacy polar Gaussian), and
//! [`TieBreakNoise::None`] leaves the matrix untouched (ties then go to the lowest index).
//!
//! # Performance and memory
//!
//! Memory is O(N²): the similarity, responsibility and availability matrices, each N² values
//! of `T` (`f32` or `f64`), contiguous and row-major, plus one column-sum vector per block of
//! [`ROW_BLOCK`] rows. For N = 3,951 that is 187 MB in `f32` and 375 MB in `f64`.
//!
//! One iteration is a single parallel pass over row blocks (rayon): for row `i` it updates
//! the availabilities from the previous column sums, then finds the two largest `a + s`,
//! updates the responsibilities, and accumulates `max(r, 0)` into the block's column sums.
//! Every inner loop is a plain slice loop the compiler vectorises. Column sums are reduced
//! in a fixed block order, so results do not depend on the number of threads.
//!
//! ```
//! use wipdr_fingerprint::affinity::{affinity_propagation, AffinityConfig, SimilarityMatrix};
//! // Two well separated groups on a line: similarity = -squared distance.
//! let xs = [0.0, 0.1, 0.2, 10.0, 10.1, 10.2];
//! let s = SimilarityMatrix::<f64>::from_fn(xs.len(), |i, j| -(xs[i] - xs[j]) * (xs[i] - xs[j]));
//! let out = affinity_propagation(&s, &AffinityConfig::default()).unwrap();
//! assert_eq!(out.n_clusters(), 2);
//! assert_eq!(out.labels, vec![0, 0, 0, 1, 1, 1]);
//! assert!(out.converged());
//! ```

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::fmt::Debug;
use std::ops::{Add, Mul, Sub};

mod dense;
mod noise;
mod pruned;
#[cfg(test)]
mod tests;

use dense::*;
pub use noise::NumpyRandomState;
use noise::*;
use pruned::*;

/// Rows per parallel work item; also fixes the summation order of the column sums.
pub const ROW_BLOCK: usize = 32;

/// Floating-point element type of a [`SimilarityMatrix`] (`f32` or `f64`).
pub trait ApFloat:
    Copy
    + Send
    + Sync
    + Debug
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + 'static
{
    /// Zero.
    const ZERO: Self;
    /// Negative infinity.
    const NEG_INFINITY: Self;
    /// Conversion from `f64` (rounding for `f32`).
    fn from_f64(v: f64) -> Self;
    /// Conversion to `f64`.
    fn to_f64(self) -> f64;
    /// Whether the value is finite.
    fn is_finite_value(self) -> bool;
    /// Whether scikit-learn's tie-breaking noise (relative size `f64::EPSILON`, absolute
    /// `100 * f64::MIN_POSITIVE`) can change a value of this type. For `f32` it cannot: the
    /// noise is below half an `f32` ulp of every finite value (and underflows at zero), so
    /// adding it in `f64` and rounding back returns the value unchanged (up to the sign of a
    /// zero, which no comparison or sum can see); it is then skipped.
    const SKLEARN_NOISE_VISIBLE: bool;
}

impl ApFloat for f64 {
    const ZERO: Self = 0.0;
    const NEG_INFINITY: Self = f64::NEG_INFINITY;
    fn from_f64(v: f64) -> Self {
        v
    }
    fn to_f64(self) -> f64 {
        self
    }
    fn is_finite_value(self) -> bool {
        self.is_finite()
    }
    const SKLEARN_NOISE_VISIBLE: bool = true;
}

impl ApFloat for f32 {
    const ZERO: Self = 0.0;
    const NEG_INFINITY: Self = f32::NEG_INFINITY;
    fn from_f64(v: f64) -> Self {
        v as f32
    }
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
    fn is_finite_value(self) -> bool {
        self.is_finite()
    }
    const SKLEARN_NOISE_VISIBLE: bool = false;
}

/// A dense square similarity matrix, row-major and contiguous: `s(i, j)` is how well `j`
/// would serve as the exemplar of `i` (larger = more alike).
#[derive(Debug, Clone, PartialEq)]
pub struct SimilarityMatrix<T> {
    n: usize,
    data: Vec<T>,
}

impl<T: ApFloat> SimilarityMatrix<T> {
    /// Wraps row-major data of an `n x n` matrix.
    pub fn new(n: usize, data: Vec<T>) -> Result<Self, AffinityError> {
        if data.len() != n * n {
            return Err(AffinityError::NotSquare { n, len: data.len() });
        }
        Ok(Self { n, data })
    }

    /// Builds the matrix from `f(i, j)`, rows in parallel.
    pub fn from_fn(n: usize, f: impl Fn(usize, usize) -> T + Sync) -> Self {
        let mut data = vec![T::ZERO; n * n];
        if n > 0 {
            data.par_chunks_mut(n).enumerate().for_each(|(i, row)| {
                for (j, v) in row.iter_mut().enumerate() {
                    *v = f(i, j);
                }
            });
        }
        Self { n, data }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Whether the matrix has no points.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// `s(i, j)`.
    pub fn get(&self, i: usize, j: usize) -> T {
        self.data[i * self.n + j]
    }

    /// Row `i`.
    pub fn row(&self, i: usize) -> &[T] {
        &self.data[i * self.n..(i + 1) * self.n]
    }

    /// The row-major data.
    pub fn as_slice(&self) -> &[T] {
        &self.data
    }

    /// Consumes the matrix, returning its row-major data.
    pub fn into_vec(self) -> Vec<T> {
        self.data
    }
}

/// How the self-similarity `s(k, k)` (the preference: larger means more clusters) is set.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Preference {
    /// Median of row `k` without the diagonal entry (paper 001 §2.2: "the median in line k
    /// of S is selected as the initial value of s(k, k)").
    RowMedian,
    /// Median of all N² entries, diagonal included (Frey & Dueck; scikit-learn's default).
    GlobalMedian,
    /// One value for every point.
    Value(f64),
    /// One value per point.
    PerPoint(Vec<f64>),
}

/// Tie-breaking noise added to the similarities before the iterations.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TieBreakNoise {
    /// No noise: exact ties go to the lowest index.
    None,
    /// scikit-learn's `s += (eps * s + 100 * tiny) * z`, `z` from NumPy's
    /// `RandomState(seed).standard_normal((n, n))`, reproduced bit for bit in `f64` (in `f32`
    /// the values are computed in `f64` and rounded, where they are mostly below resolution).
    SklearnCompatible {
        /// The `random_state` integer (scikit-learn examples use 0).
        seed: u32,
    },
}

/// Affinity-propagation settings (defaults: paper 001 / `docs/algorithms.md`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AffinityConfig {
    /// Damping factor in `[0.5, 1)` (default 0.9).
    pub damping: f64,
    /// Maximum number of iterations (default 200).
    pub max_iter: usize,
    /// Iterations the exemplar set must stay unchanged to declare convergence (default 15).
    pub convergence_iter: usize,
    /// Preference `s(k, k)` (default: row median, paper 001).
    pub preference: Preference,
    /// Tie-breaking noise (default: scikit-learn compatible, seed 0).
    pub noise: TieBreakNoise,
    /// Message-passing kernel (default: [`Kernel::Pruned`]).
    pub kernel: Kernel,
}

/// How the messages are stored and updated. Both run the same recursion (same iterations,
/// same convergence rule); they differ in memory traffic and in floating-point rounding.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Kernel {
    /// Dense `R` and `A` matrices updated exactly as scikit-learn does, operation for
    /// operation (3 N² values; one fused pass over them per iteration).
    Dense,
    /// Exact pruned form (only S is N²): the responsibilities are kept as
    /// `r(i,k) = alpha_t s(i,k) - mu_i + c_i(k)` with `c_i` non-zero only at past arg-max
    /// columns, the availabilities as `a(i,k) = beta_k + e_i(k)` with `e_i` non-zero only where
    /// `r(i,k)` was ever positive, and each row's similarities are visited in descending order
    /// only as far as a bound proves the rest irrelevant (`a(i,k) <= 0` off the diagonal, so a
    /// column with `s(i,k)` below the running second-best cannot enter the top two; `r(i,k) > 0`
    /// needs `alpha s(i,k) + c_i(k) > mu_i`). Mathematically identical to [`Kernel::Dense`];
    /// rounding differs in the last bits, which matters only at a knife-edge tie that
    /// scikit-learn's ~1e-16 noise decides (then use `Dense` to follow scikit-learn).
    #[default]
    Pruned,
}

impl Default for AffinityConfig {
    fn default() -> Self {
        Self {
            damping: 0.9,
            max_iter: 200,
            convergence_iter: 15,
            preference: Preference::RowMedian,
            noise: TieBreakNoise::SklearnCompatible { seed: 0 },
            kernel: Kernel::Pruned,
        }
    }
}

/// Errors of [`affinity_propagation`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AffinityError {
    /// The data length is not `n * n`.
    #[error("similarity matrix of {n} points needs {} values, got {len}", n * n)]
    NotSquare {
        /// Declared point count.
        n: usize,
        /// Data length.
        len: usize,
    },
    /// No points.
    #[error("similarity matrix is empty")]
    Empty,
    /// A similarity or preference is NaN or infinite.
    #[error("non-finite similarity at ({row}, {col})")]
    NonFinite {
        /// Row.
        row: usize,
        /// Column.
        col: usize,
    },
    /// Damping outside `[0.5, 1)`.
    #[error("damping {0} outside [0.5, 1)")]
    InvalidDamping(f64),
    /// `max_iter` or `convergence_iter` is zero.
    #[error("max_iter and convergence_iter must be at least 1")]
    InvalidIterations,
    /// A per-point preference vector of the wrong length.
    #[error("{got} preferences for {n} points")]
    PreferenceLength {
        /// Point count.
        n: usize,
        /// Preferences given.
        got: usize,
    },
    /// The run ended without any exemplar (it did not converge): no clustering exists.
    #[error(
        "affinity propagation did not converge after {iterations} iterations and found no exemplar"
    )]
    NoExemplars {
        /// Iterations run.
        iterations: usize,
    },
}

/// Whether the run converged.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ConvergenceStatus {
    /// Exemplars unchanged for `convergence_iter` iterations.
    Converged,
    /// `max_iter` reached: the exemplars are those of the last iteration, refined as usual;
    /// they may be degenerate (scikit-learn warns and returns them too).
    NotConverged,
    /// All similarities and preferences equal: no iteration was run (scikit-learn's rule:
    /// every point its own exemplar if the preference is larger, else one cluster).
    Degenerate,
}

/// A clustering found by affinity propagation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Clustering {
    /// Exemplar point indices, ascending.
    pub exemplars: Vec<usize>,
    /// For each point, the index into `exemplars` of its cluster.
    pub labels: Vec<usize>,
    /// Iterations run (scikit-learn's `n_iter_`).
    pub iterations: usize,
    /// Convergence outcome.
    pub status: ConvergenceStatus,
    /// The preferences used, one per point.
    pub preferences: Vec<f64>,
}

impl Clustering {
    /// Whether the run converged.
    pub fn converged(&self) -> bool {
        self.status != ConvergenceStatus::NotConverged
    }

    /// Number of clusters.
    pub fn n_clusters(&self) -> usize {
        self.exemplars.len()
    }

    /// Size of each cluster, in exemplar order.
    pub fn sizes(&self) -> Vec<usize> {
        let mut sizes = vec![0; self.exemplars.len()];
        for &l in &self.labels {
            sizes[l] += 1;
        }
        sizes
    }

    /// Member point indices of each cluster, in exemplar order.
    pub fn members(&self) -> Vec<Vec<usize>> {
        let mut m = vec![Vec::new(); self.exemplars.len()];
        for (i, &l) in self.labels.iter().enumerate() {
            m[l].push(i);
        }
        m
    }
}

/// Runs affinity propagation on a copy of `s` (see the module docs). Memory: 3 N² values.
pub fn affinity_propagation<T: ApFloat>(
    s: &SimilarityMatrix<T>,
    config: &AffinityConfig,
) -> Result<Clustering, AffinityError> {
    affinity_propagation_owned(s.clone(), config)
}

/// Runs affinity propagation, consuming `s` to save one N² copy.
pub fn affinity_propagation_owned<T: ApFloat>(
    s: SimilarityMatrix<T>,
    config: &AffinityConfig,
) -> Result<Clustering, AffinityError> {
    let n = s.n;
    if n == 0 {
        return Err(AffinityError::Empty);
    }
    if !(0.5..1.0).contains(&config.damping) {
        return Err(AffinityError::InvalidDamping(config.damping));
    }
    if config.max_iter == 0 || config.convergence_iter == 0 {
        return Err(AffinityError::InvalidIterations);
    }
    if let Some(pos) = s.data.iter().position(|v| !v.is_finite_value()) {
        return Err(AffinityError::NonFinite {
            row: pos / n,
            col: pos % n,
        });
    }
    let preferences = compute_preferences(&s, &config.preference)?;
    if let Some(k) = preferences.iter().position(|p| !p.is_finite()) {
        return Err(AffinityError::NonFinite { row: k, col: k });
    }
    let mut s = s;

    // scikit-learn: degenerate input, no iterations.
    if n == 1 || equal_similarities_and_preferences(&s, &preferences) {
        let first_pref = preferences[0];
        let (exemplars, labels) = if first_pref > s.data[n - 1].to_f64() {
            ((0..n).collect(), (0..n).collect())
        } else {
            (vec![0], vec![0; n])
        };
        return Ok(Clustering {
            exemplars,
            labels,
            iterations: 0,
            status: ConvergenceStatus::Degenerate,
            preferences,
        });
    }

    for (k, &p) in preferences.iter().enumerate() {
        s.data[k * n + k] = T::from_f64(p);
    }
    if let TieBreakNoise::SklearnCompatible { seed } = config.noise
        && T::SKLEARN_NOISE_VISIBLE
    {
        add_sklearn_noise(&mut s.data, seed);
    }

    let (exemplar_flags, iterations, converged) = match config.kernel {
        Kernel::Dense => iterate(&s, config),
        Kernel::Pruned => iterate_pruned(&s, config),
    };
    let exemplars: Vec<usize> = (0..n).filter(|&i| exemplar_flags[i]).collect();
    if exemplars.is_empty() {
        return Err(AffinityError::NoExemplars { iterations });
    }
    let (exemplars, labels) = refine(&s, exemplars);
    Ok(Clustering {
        exemplars,
        labels,
        iterations,
        status: if converged {
            ConvergenceStatus::Converged
        } else {
            ConvergenceStatus::NotConverged
        },
        preferences,
    })
}

fn compute_preferences<T: ApFloat>(
    s: &SimilarityMatrix<T>,
    preference: &Preference,
) -> Result<Vec<f64>, AffinityError> {
    let n = s.n;
    Ok(match preference {
        Preference::Value(v) => vec![*v; n],
        Preference::PerPoint(v) => {
            if v.len() != n {
                return Err(AffinityError::PreferenceLength { n, got: v.len() });
            }
            v.clone()
        }
        Preference::GlobalMedian => {
            let mut all = s.data.clone();
            vec![median_of(&mut all); n]
        }
        Preference::RowMedian => (0..n)
            .into_par_iter()
            .map(|k| {
                let mut row: Vec<f64> = s
                    .row(k)
                    .iter()
                    .enumerate()
                    .filter(|&(j, _)| j != k || n == 1)
                    .map(|(_, v)| v.to_f64())
                    .collect();
                median_in_place(&mut row)
            })
            .collect(),
    })
}

/// [`median_in_place`] for any [`ApFloat`] (finite values), computed in `f64`.
fn median_of<T: ApFloat>(values: &mut [T]) -> f64 {
    let len = values.len();
    let mid = len / 2;
    let order = |a: &T, b: &T| a.partial_cmp(b).unwrap_or(std::cmp::Ordering::Equal);
    let (_, &mut upper, _) = values.select_nth_unstable_by(mid, order);
    if len % 2 == 1 {
        upper.to_f64()
    } else {
        let lower = values[..mid]
            .iter()
            .fold(T::NEG_INFINITY, |m, &v| if v > m { v } else { m });
        (lower.to_f64() + upper.to_f64()) / 2.0
    }
}

/// Median as NumPy computes it (mean of the two middle values for an even count).
/// `values` must be non-empty and finite.
pub fn median_in_place(values: &mut [f64]) -> f64 {
    let len = values.len();
    let mid = len / 2;
    let (_, &mut upper, _) = values.select_nth_unstable_by(mid, f64::total_cmp);
    if len % 2 == 1 {
        upper
    } else {
        let lower = values[..mid]
            .iter()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max);
        (lower + upper) / 2.0
    }
}

fn equal_similarities_and_preferences<T: ApFloat>(s: &SimilarityMatrix<T>, prefs: &[f64]) -> bool {
    if prefs.iter().any(|&p| p != prefs[0]) {
        return false;
    }
    let n = s.n;
    let first = if n > 1 { s.data[1] } else { return true };
    s.data
        .par_chunks(n)
        .enumerate()
        .all(|(i, row)| row.iter().enumerate().all(|(j, &v)| j == i || v == first))
}

/// scikit-learn's final step: assign every point to its most similar exemplar, move each
/// exemplar to the member with the largest summed similarity to its cluster, reassign, and
/// renumber the clusters by ascending exemplar index.
fn refine<T: ApFloat>(s: &SimilarityMatrix<T>, exemplars: Vec<usize>) -> (Vec<usize>, Vec<usize>) {
    let n = s.n;
    let assign = |ex: &[usize]| -> Vec<usize> {
        let mut c: Vec<usize> = (0..n)
            .into_par_iter()
            .map(|i| {
                let row = s.row(i);
                let mut best = 0;
                for (k, &e) in ex.iter().enumerate() {
                    if row[e] > row[ex[best]] {
                        best = k;
                    }
                }
                best
            })
            .collect();
        for (k, &e) in ex.iter().enumerate() {
            c[e] = k;
        }
        c
    };
    let c = assign(&exemplars);
    let k_count = exemplars.len();
    let mut members = vec![Vec::new(); k_count];
    for (i, &l) in c.iter().enumerate() {
        members[l].push(i);
    }
    let refined: Vec<usize> = members
        .par_iter()
        .map(|ii| {
            // argmax_j sum_{i in ii} s(i, j), j in ii; sums in row order as NumPy does.
            let mut sums = vec![T::ZERO; ii.len()];
            for &row_i in ii {
                let row = s.row(row_i);
                for (acc, &j) in sums.iter_mut().zip(ii) {
                    *acc = *acc + row[j];
                }
            }
            let mut best = 0;
            for (j, &v) in sums.iter().enumerate() {
                if v > sums[best] {
                    best = j;
                }
            }
            ii[best]
        })
        .collect();
    let c = assign(&refined);
    let labels_point: Vec<usize> = c.iter().map(|&k| refined[k]).collect();
    let mut centres = labels_point.clone();
    centres.sort_unstable();
    centres.dedup();
    let labels = labels_point
        .iter()
        .map(|p| centres.binary_search(p).unwrap_or(0))
        .collect();
    (centres, labels)
}

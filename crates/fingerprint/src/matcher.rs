//! The one matcher trait, and the shared last step of every k-NN style matcher: weights,
//! weighted estimate (paper 001 eq. 7) and floor/building majority.

use crate::{FingerprintError, Query, QueryFilter, RadioMap};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use wipdr_core::{Candidate, MotionState, Point2, WifiObservation, WifiScan};

/// A fingerprint matcher: one online query in, one [`WifiObservation`] out.
///
/// Contract (every implementation, including the cluster / AP-index / MED matchers):
/// - `candidates` are ordered by increasing signal distance (ties by map index), at most
///   `k` of them, with weights that sum to 1; `candidates[i].index` indexes [`Matcher::map`];
/// - `estimate` is the weighted mean of the candidate positions, so it lies in their convex
///   hull;
/// - `visited` counts the reference points whose distance was computed;
/// - `floor` / `building` are the majority over the candidates where the map has them;
/// - the result does not depend on the order of APs in the scan (queries are column-sorted);
/// - bad input is an error, never a panic and never a NaN in the output.
pub trait Matcher: Send + Sync {
    /// Short name as used by the tools (`nn`, `knn`, `wknn`, …).
    fn name(&self) -> String;

    /// The radio map candidates index into.
    fn map(&self) -> &RadioMap;

    /// Locates one query.
    fn locate(&self, query: &Query) -> Result<WifiObservation, FingerprintError>;

    /// Locates many queries; the default runs [`Matcher::locate`] in parallel with rayon.
    fn locate_batch(&self, queries: &[Query]) -> Vec<Result<WifiObservation, FingerprintError>> {
        queries.par_iter().map(|q| self.locate(q)).collect()
    }

    /// Locates one query knowing the walker's motion state (paper 002 §3.2.1: the AP index
    /// uses a stricter RSSI threshold while moving). The default ignores `motion` and calls
    /// [`Matcher::locate`]; motion-aware matchers override it.
    fn locate_with_motion(
        &self,
        query: &Query,
        motion: &MotionState,
    ) -> Result<WifiObservation, FingerprintError> {
        let _ = motion;
        self.locate(query)
    }

    /// Filters a scan against the map and locates it with [`Matcher::locate_with_motion`].
    fn locate_scan_with_motion(
        &self,
        scan: &WifiScan,
        filter: &QueryFilter,
        motion: &MotionState,
    ) -> Result<WifiObservation, FingerprintError> {
        let q = Query::from_scan(scan, self.map(), filter)?;
        self.locate_with_motion(&q, motion)
    }

    /// Filters a scan against the map and locates it.
    fn locate_scan(
        &self,
        scan: &WifiScan,
        filter: &QueryFilter,
    ) -> Result<WifiObservation, FingerprintError> {
        let q = Query::from_scan(scan, self.map(), filter)?;
        self.locate(&q)
    }
}

/// How the K candidates are weighted in the estimate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Weighting {
    /// Plain mean (KNN).
    Uniform,
    /// `w_i = 1 / d_i^power` (WKNN; paper 001 eq. 7 with power 1, `1/d^2` with power 2),
    /// normalised. Candidates at distance 0 take all the weight, shared equally (the limit of
    /// the weights as `d -> 0`, and scikit-learn's convention).
    InverseDistance {
        /// The exponent `w` of `1/d^w`.
        power: f64,
    },
}

impl Default for Weighting {
    fn default() -> Self {
        Self::InverseDistance { power: 1.0 }
    }
}

/// Distances at or below this are treated as zero by [`Weighting::InverseDistance`].
pub const ZERO_DISTANCE: f64 = 1e-9;

/// Builds the observation from the `(map index, distance)` pairs of the chosen neighbours,
/// already sorted by distance. `visited` is the number of points whose distance was computed.
pub fn observation_from_neighbours(
    map: &RadioMap,
    query: &Query,
    neighbours: &[(usize, f64)],
    weighting: Weighting,
    visited: usize,
) -> Result<WifiObservation, FingerprintError> {
    if neighbours.is_empty() {
        return Err(FingerprintError::EmptyMap);
    }
    let weights = weights_of(neighbours, weighting);
    let mut estimate = Point2::origin();
    let mut candidates = Vec::with_capacity(neighbours.len());
    for (&(index, distance), &w) in neighbours.iter().zip(&weights) {
        let point = map.point(index);
        let p = point.position;
        estimate.x += w * p.x;
        estimate.y += w * p.y;
        candidates.push(Candidate {
            position: p,
            distance,
            weight: w,
            index,
            floor: point.floor,
        });
    }
    let floor = majority(neighbours.iter().map(|&(i, _)| map.point(i).floor));
    let building = majority(neighbours.iter().map(|&(i, _)| map.point(i).building));
    Ok(WifiObservation {
        t: query.t,
        estimate,
        candidates,
        visited,
        floor,
        building,
        likelihood: None,
    })
}

/// Normalised weights (sum 1) for distances sorted ascending.
pub fn weights_of(neighbours: &[(usize, f64)], weighting: Weighting) -> Vec<f64> {
    let n = neighbours.len();
    let uniform = vec![1.0 / n as f64; n];
    match weighting {
        Weighting::Uniform => uniform,
        Weighting::InverseDistance { power } => {
            let zeros = neighbours
                .iter()
                .filter(|(_, d)| d.is_nan() || *d <= ZERO_DISTANCE)
                .count();
            if zeros > 0 {
                return neighbours
                    .iter()
                    .map(|(_, d)| {
                        if *d > ZERO_DISTANCE {
                            0.0
                        } else {
                            1.0 / zeros as f64
                        }
                    })
                    .collect();
            }
            let raw: Vec<f64> = neighbours.iter().map(|(_, d)| d.powf(-power)).collect();
            let sum: f64 = raw.iter().sum();
            if !(sum.is_finite() && sum > 0.0) {
                // Underflow or overflow of d^-power: fall back to the plain mean.
                return uniform;
            }
            raw.iter().map(|w| w / sum).collect()
        }
    }
}

/// The most frequent value (ties: the one that appears first, i.e. the nearest candidate);
/// `None` values are ignored; `None` when there is no value.
pub fn majority<I: IntoIterator<Item = Option<i32>>>(values: I) -> Option<i32> {
    let mut counts: Vec<(i32, usize)> = Vec::new();
    for v in values.into_iter().flatten() {
        match counts.iter_mut().find(|(x, _)| *x == v) {
            Some((_, c)) => *c += 1,
            None => counts.push((v, 1)),
        }
    }
    let best = counts.iter().map(|(_, c)| *c).max()?;
    counts.iter().find(|(_, c)| *c == best).map(|(v, _)| *v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_handle_zero_distance() {
        let w = weights_of(
            &[(0, 0.0), (1, 0.0), (2, 3.0)],
            Weighting::InverseDistance { power: 1.0 },
        );
        assert_eq!(w, vec![0.5, 0.5, 0.0]);
        let w = weights_of(
            &[(0, 1.0), (1, 3.0)],
            Weighting::InverseDistance { power: 1.0 },
        );
        assert!((w[0] - 0.75).abs() < 1e-12 && (w[1] - 0.25).abs() < 1e-12);
        let w = weights_of(
            &[(0, 1.0), (1, 3.0)],
            Weighting::InverseDistance { power: 2.0 },
        );
        assert!((w[0] - 0.9).abs() < 1e-12);
        let w = weights_of(
            &[(0, 1e-300), (1, 1e-300)],
            Weighting::InverseDistance { power: 2.0 },
        );
        assert!(w.iter().all(|x| x.is_finite()) && (w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn majority_ties_go_to_nearest() {
        assert_eq!(majority([Some(2), Some(1), Some(1), Some(2)]), Some(2));
        assert_eq!(majority([Some(2), Some(1), Some(1)]), Some(1));
        assert_eq!(majority([None, None]), None);
    }
}

//! Wi-Fi observations: what a matcher hands to fusion (architecture "the seams").

use crate::{Point2, TimestampMs};
use serde::{Deserialize, Serialize};

/// One reference point a matcher chose for an estimate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Candidate {
    /// Reference-point position, metres.
    pub position: Point2,
    /// Signal-space distance to the query (matcher's metric).
    pub distance: f64,
    /// Normalised weight in the estimate (weights of a result sum to 1).
    pub weight: f64,
    /// Index of the reference point in its radio map.
    pub index: usize,
    /// The reference point's floor, where the map has floors.
    #[serde(default)]
    pub floor: Option<i32>,
}

/// A Wi-Fi position fix with the evidence behind it, so that TCPF can re-filter candidates and
/// robust filters can judge quality.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WifiObservation {
    /// Scan time (Unix ms).
    pub t: TimestampMs,
    /// The estimate, metres.
    pub estimate: Point2,
    /// The K candidates, ordered by increasing distance.
    pub candidates: Vec<Candidate>,
    /// How many reference points the search visited.
    pub visited: usize,
    /// Floor, as the majority of the candidates, where the map has floors.
    pub floor: Option<i32>,
    /// Building, as the majority of the candidates, where the map has buildings.
    pub building: Option<i32>,
    /// The scan's likelihood over the floor, for the filters that weigh positions by it
    /// (`pmf` with `wifi_likelihood`); `None` when the front end was not asked for it or the
    /// site model has none for this floor. Not serialised (derived from the scan and the site
    /// model).
    #[serde(skip)]
    pub likelihood: Option<std::sync::Arc<crate::WifiLikelihood>>,
}

impl WifiObservation {
    /// The fix restricted to the candidates on `floor` (weights renormalised, estimate their
    /// weighted mean, `floor` set); `None` when no candidate is on that floor. A fix whose
    /// candidates have no floor is returned unchanged but for `floor`.
    ///
    /// ```
    /// use wipdr_core::{Candidate, Point2, WifiObservation};
    /// let c = |x: f64, floor| Candidate { position: Point2::new(x, 0.0), distance: 1.0, weight: 0.5, index: 0, floor };
    /// let fix = WifiObservation { t: 0, estimate: Point2::new(5.0, 0.0), candidates: vec![c(0.0, Some(0)), c(10.0, Some(-2))],
    ///                             visited: 2, floor: Some(0), building: None, likelihood: None };
    /// let on = fix.on_floor(-2).unwrap();
    /// assert_eq!((on.estimate.x, on.candidates.len(), on.floor), (10.0, 1, Some(-2)));
    /// assert!(fix.on_floor(1).is_none());
    /// ```
    pub fn on_floor(&self, floor: i32) -> Option<WifiObservation> {
        if self.candidates.iter().all(|c| c.floor.is_none()) {
            return Some(WifiObservation {
                floor: Some(floor),
                ..self.clone()
            });
        }
        let mut candidates: Vec<Candidate> = self
            .candidates
            .iter()
            .filter(|c| c.floor == Some(floor))
            .copied()
            .collect();
        if candidates.is_empty() {
            return None;
        }
        let sum: f64 = candidates.iter().map(|c| c.weight).sum();
        let n = candidates.len() as f64;
        for c in &mut candidates {
            c.weight = if sum.is_finite() && sum > 0.0 {
                c.weight / sum
            } else {
                1.0 / n
            };
        }
        let mut estimate = Point2::origin();
        for c in &candidates {
            estimate.x += c.weight * c.position.x;
            estimate.y += c.weight * c.position.y;
        }
        Some(WifiObservation {
            t: self.t,
            estimate,
            candidates,
            visited: self.visited,
            floor: Some(floor),
            building: self.building,
            likelihood: self.likelihood.clone(),
        })
    }

    /// Signal distance of the best candidate (a quality signal: large means a poor match).
    pub fn best_distance(&self) -> Option<f64> {
        self.candidates.first().map(|c| c.distance)
    }

    /// Weighted spatial spread of the candidates around the estimate (RMS, metres); 0 with
    /// fewer than two candidates.
    pub fn spread(&self) -> f64 {
        if self.candidates.len() < 2 {
            return 0.0;
        }
        let wsum: f64 = self.candidates.iter().map(|c| c.weight).sum();
        if wsum.is_nan() || wsum <= 0.0 {
            return 0.0;
        }
        let v: f64 = self
            .candidates
            .iter()
            .map(|c| c.weight * (c.position - self.estimate).norm_squared())
            .sum();
        (v / wsum).sqrt()
    }
}

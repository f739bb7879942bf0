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
}

impl WifiObservation {
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

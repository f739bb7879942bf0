//! What a [`crate::Positioner`] answers.

use nalgebra::Matrix2;
use serde::{Deserialize, Serialize};
use wipdr_core::{Point2, TimestampMs};

/// The current estimate of a stream.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PositionEstimate {
    /// Time of the latest input that moved the estimate (ms, the stream's clock).
    pub t: TimestampMs,
    /// Position in the map's metre frame.
    pub position: Point2,
    /// Floor, when known (the matcher's candidates' majority floor of the latest fix).
    pub floor: Option<i32>,
    /// Horizontal covariance, m², where the scheme has one.
    pub covariance: Option<Matrix2<f64>>,
}

impl PositionEstimate {
    /// Horizontal standard deviation, metres: `sqrt(trace(P) / 2)` (the RMS of the two axes'
    /// standard deviations); `None` without a covariance or when it is not finite and >= 0.
    pub fn sd_m(&self) -> Option<f64> {
        let p = self.covariance?;
        let half_trace = 0.5 * (p[(0, 0)] + p[(1, 1)]);
        (half_trace.is_finite() && half_trace >= 0.0).then(|| half_trace.sqrt())
    }
}

//! Step events: what PDR hands to fusion (architecture "the seams").

use crate::TimestampMs;
use serde::{Deserialize, Serialize};

/// Turn state of a step from accumulated gyroscope over consecutive steps
/// (paper 001 eq. 17-18).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub enum TurnState {
    /// No consistent rotation.
    #[default]
    Straight,
    /// Consistent rotation above the threshold.
    Turning,
    /// Consistent sign but below the threshold (a slow drift or curve).
    PseudoTurning,
}

/// Walking speed class (paper 000 §4.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub enum SpeedClass {
    /// Slower than usual.
    Slow,
    /// Usual pace.
    #[default]
    Normal,
    /// Faster than usual.
    Fast,
}

/// Motion state attached to a step; the adaptive filters key on it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub struct MotionState {
    /// Straight / turning / pseudo-turning.
    pub turn: TurnState,
    /// Slow / normal / fast.
    pub speed: SpeedClass,
    /// Whether the walker was standing still just before this event (paper 002 §3.2.1).
    pub stationary: bool,
}

/// One motion event: a detected step, or a learned odometry output (the displacement over
/// its interval with its covariance, see [`StepEvent::covariance`]). Either way the event
/// moves the walker by `length` along `heading`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StepEvent {
    /// Time of the step (Unix ms), when it was detected (causal).
    pub t: TimestampMs,
    /// Step length, metres.
    pub length: f64,
    /// Heading in the map frame (radians, clockwise from `+y`).
    pub heading: f64,
    /// Heading change since the previous step, wrapped to `(-pi, pi]`.
    pub heading_change: f64,
    /// Step period (seconds since the previous step).
    pub period_s: f64,
    /// Motion state.
    pub motion: MotionState,
    /// The covariance `(xx, xy, yy)` of the displacement (m², map frame East / North) when
    /// the motion source gives one (learned odometry: `wipdr_pdr::odometry`); the schemes
    /// then move by the displacement with this noise instead of their own step noise.
    /// `None` for a detected step.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub covariance: Option<[f64; 3]>,
}

/// Largest displacement variance a motion event may carry, m² (a 1 km standard deviation):
/// beyond it the covariance is not usable ([`StepEvent::displacement_covariance`]) and would
/// overflow the filters' arithmetic. The learned odometry's variances stay below about
/// 400 m² a second (`wipdr_pdr::odometry::LOG_VAR_RANGE`).
pub const MAX_DISPLACEMENT_VARIANCE_M2: f64 = 1e6;

impl StepEvent {
    /// The displacement covariance as a matrix, when the event carries a usable one: every
    /// entry finite, positive semi-definite (`xx, yy >= 0`, `xy^2 <= xx yy`), variances at
    /// most [`MAX_DISPLACEMENT_VARIANCE_M2`]. `None` otherwise: the schemes then use their own
    /// step noise.
    pub fn displacement_covariance(&self) -> Option<nalgebra::Matrix2<f64>> {
        let [xx, xy, yy] = self.covariance?;
        let ok = [xx, xy, yy].iter().all(|v| v.is_finite())
            && (0.0..=MAX_DISPLACEMENT_VARIANCE_M2).contains(&xx)
            && (0.0..=MAX_DISPLACEMENT_VARIANCE_M2).contains(&yy)
            && xy * xy <= xx * yy;
        ok.then(|| nalgebra::Matrix2::new(xx, xy, xy, yy))
    }
}

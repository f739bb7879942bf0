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

/// One detected step.
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
}

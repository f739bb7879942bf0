//! Motion state per step: straight / turning / pseudo-turning (paper 001 eq. 17-18), slow /
//! normal / fast (paper 000 §4.1), stationary (paper 002 §3.2.1).

use serde::{Deserialize, Serialize};
use std::collections::VecDeque;
use wipdr_core::{SpeedClass, TimestampMs, TurnState};

/// Settings of the motion-state classifiers.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MotionConfig {
    /// Turn threshold `T` on the accumulated gyro of one step, `|SGyr_k|` (eq. 17), as an
    /// angle in radians (the integral of the heading rate over the step). The paper's
    /// "10 rad/s" is a sum of raw samples; at its ~50 Hz that sum is an angle of
    /// 10 / 50 = 0.2 rad, the default. Calibrated on the synthetic walks (see
    /// `docs/results/pdr.md`).
    pub turn_threshold_rad: f64,
    /// `|SGyr_k|` below this is noise: the step counts as straight whatever the sign
    /// agreement (eq. 18 alone would call half of all straight steps pseudo-turns), rad.
    pub pseudo_turn_min_rad: f64,
    /// A step period above this is slow, s.
    pub slow_period_s: f64,
    /// A step period below this is fast, s.
    pub fast_period_s: f64,
    /// Window of the stationary detector, s.
    pub stationary_window_s: f64,
    /// Stationary when the standard deviation of the acceleration magnitude over the window
    /// is below this, m/s².
    pub stationary_std: f64,
    /// ... and its mean is within this of gravity, m/s².
    pub stationary_mean_tolerance: f64,
    /// Gravity, m/s².
    pub gravity: f64,
    /// A step coming this long after the previous one (or the first) follows a stop, s.
    pub stop_gap_s: f64,
}

impl Default for MotionConfig {
    fn default() -> Self {
        Self {
            turn_threshold_rad: 0.2,
            pseudo_turn_min_rad: 0.03,
            slow_period_s: 0.65,
            fast_period_s: 0.45,
            stationary_window_s: 1.0,
            stationary_std: 0.3,
            stationary_mean_tolerance: 0.5,
            gravity: 9.81,
            stop_gap_s: 1.5,
        }
    }
}

/// Eq. 17-18: turning if `SGyr_k SGyr_{k-1} > 0` and `|SGyr_k| > T`; pseudo-turning if the
/// signs agree but `|SGyr_k| <= T` (and above the noise floor); straight otherwise.
///
/// ```
/// use wipdr_core::TurnState;
/// use wipdr_pdr::motion::{classify_turn, MotionConfig};
/// let c = MotionConfig::default();
/// assert_eq!(classify_turn(0.4, 0.3, &c), TurnState::Turning);
/// assert_eq!(classify_turn(0.1, 0.05, &c), TurnState::PseudoTurning);
/// assert_eq!(classify_turn(0.4, -0.3, &c), TurnState::Straight);
/// ```
pub fn classify_turn(sgyr_k: f64, sgyr_prev: f64, cfg: &MotionConfig) -> TurnState {
    if !(sgyr_k.is_finite() && sgyr_prev.is_finite()) || sgyr_k * sgyr_prev <= 0.0 {
        return TurnState::Straight;
    }
    if sgyr_k.abs() > cfg.turn_threshold_rad {
        TurnState::Turning
    } else if sgyr_k.abs() > cfg.pseudo_turn_min_rad {
        TurnState::PseudoTurning
    } else {
        TurnState::Straight
    }
}

/// Speed class from the step period.
pub fn classify_speed(period_s: f64, cfg: &MotionConfig) -> SpeedClass {
    if period_s > cfg.slow_period_s {
        SpeedClass::Slow
    } else if period_s < cfg.fast_period_s {
        SpeedClass::Fast
    } else {
        SpeedClass::Normal
    }
}

/// Streaming stationary detector: mean and standard deviation of the acceleration magnitude
/// over a sliding time window (paper 002 §3.2.1).
#[derive(Debug, Clone)]
pub struct StationaryDetector {
    cfg: MotionConfig,
    window: VecDeque<(TimestampMs, f64)>,
    sum: f64,
    sum_sq: f64,
    stationary: bool,
    since_last_step: bool,
}

impl StationaryDetector {
    /// A detector that starts as "stationary" (the walker has not moved yet).
    pub fn new(cfg: MotionConfig) -> Self {
        Self {
            cfg,
            window: VecDeque::with_capacity(128),
            sum: 0.0,
            sum_sq: 0.0,
            stationary: true,
            since_last_step: true,
        }
    }

    /// Feeds an acceleration magnitude (m/s²) at `t` (ms); returns the current state.
    pub fn push(&mut self, t: TimestampMs, magnitude: f64) -> bool {
        if !magnitude.is_finite() {
            return self.stationary;
        }
        self.window.push_back((t, magnitude));
        self.sum += magnitude;
        self.sum_sq += magnitude * magnitude;
        let w = (self.cfg.stationary_window_s * 1000.0) as i64;
        while let Some(&(t0, v0)) = self.window.front() {
            if t - t0 > w {
                self.window.pop_front();
                self.sum -= v0;
                self.sum_sq -= v0 * v0;
            } else {
                break;
            }
        }
        let full = self
            .window
            .front()
            .is_some_and(|&(t0, _)| t - t0 >= w * 3 / 4);
        if full {
            let n = self.window.len() as f64;
            let mean = self.sum / n;
            let std = (self.sum_sq / n - mean * mean).max(0.0).sqrt();
            self.stationary = std < self.cfg.stationary_std
                && (mean - self.cfg.gravity).abs() < self.cfg.stationary_mean_tolerance;
        }
        if self.stationary {
            self.since_last_step = true;
        }
        self.stationary
    }

    /// Whether the walker is standing still now.
    pub fn is_stationary(&self) -> bool {
        self.stationary
    }

    /// Whether the walker stood still at some time since the previous step; resets the flag.
    pub fn take_stop_since_last_step(&mut self) -> bool {
        std::mem::replace(&mut self.since_last_step, self.stationary)
    }

    /// Clears the window (after a gap in the stream).
    pub fn reset(&mut self) {
        self.window.clear();
        self.sum = 0.0;
        self.sum_sq = 0.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn speed_classes() {
        let c = MotionConfig::default();
        assert_eq!(classify_speed(0.8, &c), SpeedClass::Slow);
        assert_eq!(classify_speed(0.55, &c), SpeedClass::Normal);
        assert_eq!(classify_speed(0.4, &c), SpeedClass::Fast);
    }

    #[test]
    fn turn_rules_and_nan() {
        let c = MotionConfig::default();
        assert_eq!(classify_turn(-0.5, -0.25, &c), TurnState::Turning);
        assert_eq!(classify_turn(0.01, 0.01, &c), TurnState::Straight);
        assert_eq!(classify_turn(f64::NAN, 0.5, &c), TurnState::Straight);
    }

    #[test]
    fn stationary_then_walking() {
        let c = MotionConfig::default();
        let mut d = StationaryDetector::new(c);
        for i in 0..100 {
            d.push(i * 20, 9.81 + 0.02 * ((i % 3) as f64 - 1.0));
        }
        assert!(d.is_stationary());
        for i in 100..200 {
            let t = i as f64 * 0.02;
            d.push(
                i * 20,
                9.81 + 2.0 * (2.0 * std::f64::consts::PI * 2.0 * t).sin(),
            );
        }
        assert!(!d.is_stationary());
        assert!(d.take_stop_since_last_step());
        assert!(!d.take_stop_since_last_step());
    }
}

//! Handling gate: steps the accelerometer "detects" while the phone is being turned over in
//! the hand (compass calibration figure-eights, picking it up, putting it away) are not
//! steps. Such handling rotates the phone fast in every axis (mean |omega| of 2-7 rad/s over
//! seconds in the IPIN 2023 logfiles, whose first minute is handling), while a phone carried
//! in front of a walker turns at well under 1 rad/s, and a swung phone about one axis. The
//! gate rejects a step while the smoothed rotation rate exceeds
//! [`HandlingConfig::tumbling_rad_s`] (1.5 rad/s) about no dominant axis (the phone tumbles
//! in the hand). It closes when the rate exceeds
//! [`HandlingConfig::max_rotation_rad_s`] (3 rad/s by default); with
//! [`HandlingConfig::release_rad_s`] set (off by default) it opens again only once the rate
//! has fallen below that, or [`HandlingConfig::release_hold_s`] after the rate was last above
//! the maximum: handling slows down between its fast turns, and a single threshold low enough
//! to catch those slower spells also catches walkers who swing the phone. A step is rejected
//! while the gate is closed ([`HandlingConfig::off`] in the papers' preset, which have no
//! such gate).

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;
use wipdr_core::TimestampMs;

/// Settings of the handling gate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HandlingConfig {
    /// Largest smoothed rotation rate (norm of the gyroscope vector, rad/s) at which a
    /// detected step is kept; `None` turns the gate off (the papers' preset,
    /// [`HandlingConfig::off`]). Measured by `wipdr eval --data ../shared/data/ipin2023` and
    /// on the five ILC floors (`docs/results/ipin.md`, `docs/experiments.md`): 1.5 removes
    /// the IPIN logfiles' 33-66 handling steps per walk down to 0-4
    /// and keeps their walking steps, but also drops walking steps of some ILC walks (PDR
    /// 3.04 -> 3.21 m pooled at 2.0); the default 3.0 leaves every ILC figure as it was
    /// without the gate and still takes `pmf` 10.61 -> 8.17 m on the IPIN walks (`ekf` 8.05
    /// -> 7.91).
    /// In TOML, `"off"` stands for `None` ([`wipdr_core::off`]).
    #[serde(with = "wipdr_core::off")]
    pub max_rotation_rad_s: Option<f64>,
    /// Smoothed rotation rate below which a closed gate opens again, rad/s (hysteresis; off
    /// by default, `None`: the gate opens as soon as the rate is back at or below
    /// `max_rotation_rad_s`; the papers' preset has no gate, [`HandlingConfig::off`]). At
    /// most `max_rotation_rad_s`. Measured by `wipdr sweep --config
    /// docs/sweeps/handling-hysteresis.toml --data ../shared/data/ipin2023`
    /// (`docs/experiments.md`): 1.5 (hold 8 s, before the tumbling test was
    /// the default) took IPIN causal `pmf` 6.78 -> 6.70 m, EvAAL 9.43 -> 9.13 (6.71 / 9.18
    /// on top of the tumbling test), but drops walking steps of an ILC site2/F3
    /// walker who handles the phone and then swings it (calibrated PDR p95 there 9.11 ->
    /// 12.92 m), so it stays an option (`docs/configs/ipin.toml`).
    /// In TOML, `"off"` stands for `None` ([`wipdr_core::off`]).
    #[serde(with = "wipdr_core::off")]
    pub release_rad_s: Option<f64>,
    /// Longest time a closed gate stays closed after the rate was last above
    /// `max_rotation_rad_s`, seconds, even while the rate stays above `release_rad_s` (4 s
    /// by default; only used with `release_rad_s`): bounds the steps a walker who swings the
    /// phone after handling it can lose. Measured with `docs/configs/ipin.toml` and
    /// `release_hold_s` changed: 4 s did not rescue the ILC
    /// site2/F3 walker's steps (the calibrated-PDR figures stayed 3.39 / 12.92 m), and on
    /// IPIN 2 / 4 / 8 s give `pmf` EvAAL 9.57 / 9.38 / 9.13.
    pub release_hold_s: f64,
    /// Smoothed rotation rate above which a step is also rejected when the phone tumbles,
    /// rad/s (1.5 by default; `None`: no such test, the single-threshold gate; the papers'
    /// preset has no gate). Tumbling = the rotation is not about one axis: the
    /// largest eigenvalue of the gyroscope's second-moment matrix over `axis_window_s` holds
    /// less than `max_axis_share` of its trace. Handling turns the phone about every axis
    /// (share 0.50 / 0.64 / 0.80 at the 10th / 50th / 90th percentile, IPIN steps before the
    /// first POSI point above 1.5 rad/s), a swung or turned phone about one (0.89 / 0.93 /
    /// 0.95, ILC walking steps above 1.5 rad/s; `cargo run -p wipdr --example handling_steps`).
    /// Measured by `wipdr eval` against `tumbling_rad_s = "off"` (`docs/experiments.md`):
    /// IPIN causal `pmf` 6.78 -> 6.77 m, EvAAL
    /// 9.43 -> 9.31, every causal IPIN scheme better (`tcpf` 9.13 -> 8.38); every ILC
    /// scheme within 0.03 m (`pmf` 4.98 unchanged, PDR from the truth 2.78 -> 2.77); IPIN
    /// offline `pmf` EvAAL 6.38 -> 6.75.
    /// In TOML, `"off"` stands for `None` ([`wipdr_core::off`]).
    #[serde(with = "wipdr_core::off")]
    pub tumbling_rad_s: Option<f64>,
    /// Largest share of the dominant rotation axis at which a fast-turning phone counts as
    /// tumbling (in (0, 1]).
    pub max_axis_share: f64,
    /// Window of the rotation-axis test, seconds.
    pub axis_window_s: f64,
    /// Time constant of the smoothing, seconds.
    pub tau_s: f64,
}

impl Default for HandlingConfig {
    fn default() -> Self {
        Self {
            max_rotation_rad_s: Some(3.0),
            release_rad_s: None,
            release_hold_s: 4.0,
            tumbling_rad_s: Some(1.5),
            max_axis_share: 0.85,
            axis_window_s: 2.0,
            tau_s: 1.0,
        }
    }
}

impl HandlingConfig {
    /// Checks the values a config file could get wrong; the error names the field (under
    /// `handling`) and the value.
    pub fn validate(&self) -> Result<(), wipdr_core::ConfigError> {
        if let Some(m) = self.max_rotation_rad_s
            && !(m.is_finite() && m > 0.0)
        {
            return Err(wipdr_core::ConfigError::new(
                "handling.max_rotation_rad_s",
                format!("must be finite and > 0, got {m}"),
            ));
        }
        if let Some(release) = self.release_rad_s {
            let max = self.max_rotation_rad_s.unwrap_or(f64::INFINITY);
            if !(release.is_finite() && release >= 0.0 && release <= max) {
                return Err(wipdr_core::ConfigError::new(
                    "handling.release_rad_s",
                    format!(
                        "must be finite, >= 0 and <= handling.max_rotation_rad_s ({max}), got \
                         {release}"
                    ),
                ));
            }
        }
        if let Some(t) = self.tumbling_rad_s
            && !(t.is_finite() && t >= 0.0)
        {
            return Err(wipdr_core::ConfigError::new(
                "handling.tumbling_rad_s",
                format!("must be finite and >= 0, got {t}"),
            ));
        }
        let share = self.max_axis_share;
        if !(share.is_finite() && share > 0.0 && share <= 1.0) {
            return Err(wipdr_core::ConfigError::new(
                "handling.max_axis_share",
                format!("must be in (0, 1], got {share}"),
            ));
        }
        if !(self.axis_window_s.is_finite() && self.axis_window_s > 0.0) {
            return Err(wipdr_core::ConfigError::new(
                "handling.axis_window_s",
                format!("must be finite and > 0, got {}", self.axis_window_s),
            ));
        }
        for (field, v) in [
            ("handling.release_hold_s", self.release_hold_s),
            ("handling.tau_s", self.tau_s),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(wipdr_core::ConfigError::new(
                    field,
                    format!("must be finite and >= 0, got {v}"),
                ));
            }
        }
        Ok(())
    }

    /// No gate: every detected step is kept (the papers' PDR).
    pub fn off() -> Self {
        Self {
            max_rotation_rad_s: None,
            ..Self::default()
        }
    }
}

/// The smoothed rotation rate of a stream (exponential, time-aware), the recent gyroscope
/// vectors of the rotation-axis test, and the gate's state.
#[derive(Debug, Clone, Default)]
pub struct HandlingGate {
    rate: Option<(TimestampMs, f64)>,
    closed: bool,
    last_above: TimestampMs,
    recent: VecDeque<(TimestampMs, [f64; 3])>,
}

impl HandlingGate {
    /// Feeds a gyroscope vector (rad/s) at `t`: its norm to [`HandlingGate::push`], the
    /// vector to the rotation-axis test's window (kept only while the gate and the test are
    /// on). Non-finite vectors are ignored.
    pub fn push_vector(&mut self, t: TimestampMs, v: [f64; 3], cfg: &HandlingConfig) {
        if !v.iter().all(|c| c.is_finite()) {
            return;
        }
        self.push(t, (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt(), cfg);
        if cfg.tumbling_rad_s.is_none() || cfg.max_rotation_rad_s.is_none() {
            return;
        }
        self.recent.push_back((t, v));
        let window_ms = (cfg.axis_window_s * 1000.0).clamp(0.0, 3.6e6);
        while self
            .recent
            .front()
            .is_some_and(|(t0, _)| ((t - *t0) as f64) > window_ms)
        {
            self.recent.pop_front();
        }
    }

    /// Share of the rotation's energy about its dominant axis over the window (the largest
    /// eigenvalue of the vectors' second-moment matrix over its trace); 1 with no rotation
    /// in the window.
    pub fn axis_share(&self) -> f64 {
        let moment = self
            .recent
            .iter()
            .map(|(_, v)| {
                let v = Vector3::from(*v);
                v * v.transpose()
            })
            .fold(Matrix3::zeros(), |sum, m| sum + m);
        let trace = moment.trace();
        if !(trace.is_finite() && trace > 1e-12) {
            return 1.0;
        }
        (moment.symmetric_eigenvalues().max() / trace).clamp(0.0, 1.0)
    }

    /// Feeds a gyroscope sample's norm (rad/s) at `t`; non-finite values are ignored.
    pub fn push(&mut self, t: TimestampMs, norm: f64, cfg: &HandlingConfig) {
        if !norm.is_finite() {
            return;
        }
        self.rate = Some(match self.rate {
            Some((t0, r)) if t > t0 => {
                let dt = (t - t0) as f64 / 1000.0;
                let a = if cfg.tau_s > 0.0 {
                    1.0 - (-dt / cfg.tau_s).exp()
                } else {
                    1.0
                };
                (t, r + a * (norm - r))
            }
            Some(prev) => prev,
            None => (t, norm),
        });
        let r = self.rate().unwrap_or(0.0);
        self.closed = match cfg.max_rotation_rad_s {
            None => false,
            Some(max) if r > max => {
                self.last_above = t;
                true
            }
            Some(max) => {
                let held_s = t.saturating_sub(self.last_above) as f64 / 1000.0;
                self.closed
                    && cfg
                        .release_rad_s
                        .is_some_and(|release| r >= release.min(max))
                    && held_s <= cfg.release_hold_s
            }
        };
    }

    /// The smoothed rotation rate, rad/s (`None` before the first sample).
    pub fn rate(&self) -> Option<f64> {
        self.rate.map(|(_, r)| r)
    }

    /// Whether the phone is being handled now (a step now is rejected): the gate closed
    /// when the smoothed rate last rose above `max_rotation_rad_s` and has not fallen below
    /// `release_rad_s` since. Always false when the gate is off.
    pub fn handling(&self, cfg: &HandlingConfig) -> bool {
        cfg.max_rotation_rad_s.is_some() && (self.closed || self.tumbling(cfg))
    }

    /// Whether the phone turns fast (above `tumbling_rad_s`) about no single axis now.
    fn tumbling(&self, cfg: &HandlingConfig) -> bool {
        match (cfg.tumbling_rad_s, self.rate()) {
            (Some(min), Some(r)) if r > min => self.axis_share() < cfg.max_axis_share,
            _ => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_closed_gate_opens_only_below_the_release_rate() {
        let cfg = HandlingConfig {
            release_rad_s: Some(1.5),
            ..HandlingConfig::default()
        };
        let mut g = HandlingGate::default();
        for k in 0..300 {
            g.push(k * 10, 5.0, &cfg);
        }
        assert!(g.handling(&cfg));
        // Slower handling, between release (1.5) and max (3.0): still closed 3 s on.
        for k in 300..600 {
            g.push(k * 10, 2.2, &cfg);
        }
        assert!(g.rate().unwrap() < 3.0);
        assert!(g.handling(&cfg));
        // Falling below the release opens it.
        let mut calm = g.clone();
        for k in 600..1_000 {
            calm.push(k * 10, 1.0, &cfg);
        }
        assert!(!calm.handling(&cfg));
        // So does staying above the release for longer than the hold (4 s): a walker
        // swinging the phone after handling it keeps their steps.
        for k in 600..1_300 {
            g.push(k * 10, 2.2, &cfg);
        }
        assert!((g.rate().unwrap() - 2.2).abs() < 0.01);
        assert!(!g.handling(&cfg));
        // The same rate after the gate opened does not close it: 2.2 < max.
        for k in 2_300..3_300 {
            g.push(k * 10, 2.2, &cfg);
        }
        assert!(!g.handling(&cfg));
        // No release (the default): the single threshold, open as soon as the rate is below max.
        let single = HandlingConfig::default();
        let mut g = HandlingGate::default();
        for k in 0..300 {
            g.push(k * 10, 5.0, &single);
        }
        for k in 300..1_300 {
            g.push(k * 10, 2.2, &single);
        }
        assert!(!g.handling(&single));
    }

    #[test]
    fn tumbling_is_handling_and_a_swing_about_one_axis_is_not() {
        let cfg = HandlingConfig::default();
        // 2 rad/s (between tumbling 1.5 and max 3.0), 100 Hz, 4 s.
        let feed = |f: &dyn Fn(f64) -> [f64; 3]| {
            let mut g = HandlingGate::default();
            for k in 0..400 {
                let t = k as f64 / 100.0;
                g.push_vector(k * 10, f(t), &cfg);
            }
            g
        };
        // A swing: back and forth about the phone's x axis.
        let swing = feed(&|t| {
            let w = 2.0 * (std::f64::consts::TAU * t).sin().signum();
            [w, 0.05, 0.0]
        });
        assert!(swing.axis_share() > 0.95, "{}", swing.axis_share());
        assert!(!swing.handling(&cfg));
        // Tumbling: the axis wanders through all three.
        let tumble = feed(&|t| {
            let (a, b) = (1.3 * t, 2.1 * t);
            [
                2.0 * a.cos() * b.cos(),
                2.0 * a.sin() * b.cos(),
                2.0 * b.sin(),
            ]
        });
        assert!(tumble.axis_share() < 0.85, "{}", tumble.axis_share());
        assert!(tumble.handling(&cfg));
        // Without the test (the single-threshold gate) the same tumbling below 3 rad/s is kept.
        let single = HandlingConfig {
            tumbling_rad_s: None,
            ..cfg
        };
        assert!(!tumble.handling(&single));
        // Non-finite vectors are ignored; an empty window counts as one axis.
        let mut g = HandlingGate::default();
        g.push_vector(0, [f64::NAN, 0.0, 0.0], &cfg);
        assert!(g.rate().is_none());
        assert_eq!(g.axis_share(), 1.0);
    }

    #[test]
    fn fast_turning_is_handling_and_settles() {
        let cfg = HandlingConfig {
            max_rotation_rad_s: Some(1.5),
            ..HandlingConfig::default()
        };
        let mut g = HandlingGate::default();
        assert!(!g.handling(&cfg));
        for k in 0..100 {
            g.push(k * 10, 5.0, &cfg);
        }
        assert!(g.handling(&cfg));
        for k in 100..1_200 {
            g.push(k * 10, 0.3, &cfg);
        }
        assert!(!g.handling(&cfg));
        assert!((g.rate().unwrap() - 0.3).abs() < 0.01);
        let off = HandlingConfig {
            max_rotation_rad_s: None,
            ..cfg
        };
        g.push(5_000, 50.0, &off);
        assert!(!g.handling(&off));
    }
}

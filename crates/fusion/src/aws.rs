//! Adaptive weighted smoothing with the displacement constraint (paper 001 §3.1, eq. 8-9),
//! scheme `aws`.
//!
//! # The algorithm
//!
//! Between Wi-Fi fixes the position is dead-reckoned from the previous fused point. At a fix,
//! `S_PDR` is the PDR displacement since the previous fused point and `S_WIFI` the distance
//! from the previous fused point to the fix. When `|S_WIFI - S_PDR| < delta_S` the fix is
//! weighted `max(w1, w2)` (eq. 8), otherwise the PDR position is (eq. 9); `w1 = 0.4`,
//! `w2 = 0.6`. The paper gives no value for `delta_S`; the default 3 m (about four steps)
//! is ours.

use serde::{Deserialize, Serialize};
use wipdr_core::ConfigError;
use wipdr_core::{Point2, StepEvent, TimestampMs, WifiObservation, angle};

use crate::fix_error::{GainVariance, RadiusConfig};
use crate::{Diagnostics, Estimate, Fuser, FusionError, InputGuard};

/// Parameters of `aws` (001 §3.1).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AwsConfig {
    /// `w1` (0.4).
    pub w1: f64,
    /// `w2` (0.6).
    pub w2: f64,
    /// Displacement threshold `delta_S`, metres (not given in the paper; 3 m).
    pub delta_s_m: f64,
    /// The horizontal uncertainty of the estimate (wipdr's own; the paper gives none):
    /// [`crate::fix_error`], the same in the default and the paper preset.
    pub radius: RadiusConfig,
}

/// The shipped default is tuned for recorded smartphone walks (`docs/sweeps/tune-aws.toml`,
/// docs/results/papers.md: 7.33 -> 7.18 m on the five ILC floors, 8.06 -> 7.28 m on the
/// held-out synthetic floor); [`AwsConfig::paper`] holds the paper's weights.
impl Default for AwsConfig {
    fn default() -> Self {
        Self {
            w1: 0.2,
            w2: 0.8,
            delta_s_m: 1.0,
            radius: RadiusConfig::default(),
        }
    }
}

impl AwsConfig {
    /// The paper's weights (001 §3.1: w1 0.4, w2 0.6) with our 3 m displacement threshold.
    pub fn paper() -> Self {
        Self {
            w1: 0.4,
            w2: 0.6,
            delta_s_m: 3.0,
            radius: RadiusConfig::default(),
        }
    }
}

/// The adaptive weighted smoother.
#[derive(Debug, Clone)]
pub struct AwsFuser {
    cfg: AwsConfig,
    position: Option<Point2>,
    last_fused: Point2,
    t: TimestampMs,
    last_flagged: Option<bool>,
    variance: GainVariance,
    guard: InputGuard,
}

impl AwsFuser {
    /// Builds the smoother; `start` initialises at a known position.
    pub fn new(cfg: AwsConfig, start: Option<Point2>) -> Result<Self, FusionError> {
        for (field, v) in [("w1", cfg.w1), ("w2", cfg.w2)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(FusionError::InvalidConfig(ConfigError::new(
                    field,
                    format!("must be finite and >= 0, got {v}"),
                )));
            }
        }
        if cfg.w1 + cfg.w2 <= 0.0 {
            return Err(FusionError::InvalidConfig(ConfigError::new(
                "w1",
                "w1 + w2 must be > 0",
            )));
        }
        if !(cfg.delta_s_m.is_finite() && cfg.delta_s_m > 0.0) {
            return Err(FusionError::InvalidConfig(ConfigError::new(
                "delta_s_m",
                format!("must be finite and > 0, got {}", cfg.delta_s_m),
            )));
        }
        cfg.radius.validate()?;
        let mut variance = GainVariance::new(cfg.radius.clone());
        if start.is_some() {
            variance.start_known(0.0);
        }
        Ok(Self {
            variance,
            cfg,
            position: start,
            last_fused: start.unwrap_or_else(Point2::origin),
            t: 0,
            last_flagged: None,
            guard: InputGuard::default(),
        })
    }
}

impl Fuser for AwsFuser {
    fn name(&self) -> &'static str {
        "aws"
    }

    fn on_step(&mut self, step: &StepEvent) {
        if !self.guard.accept_step(step) {
            return;
        }
        if let Some(p) = &mut self.position {
            *p += angle::step_displacement(step.length, step.heading);
            self.variance.step(step.length);
            self.t = step.t;
        }
    }

    fn on_wifi(&mut self, obs: &WifiObservation) {
        if !self.guard.accept_wifi(obs) {
            return;
        }
        self.t = obs.t;
        let Some(pdr) = self.position else {
            self.position = Some(obs.estimate);
            self.last_fused = obs.estimate;
            self.variance.start();
            return;
        };
        let s_pdr = (pdr - self.last_fused).norm();
        let s_wifi = (obs.estimate - self.last_fused).norm();
        let (hi, lo) = (self.cfg.w1.max(self.cfg.w2), self.cfg.w1.min(self.cfg.w2));
        let sum = self.cfg.w1 + self.cfg.w2;
        let consistent = (s_wifi - s_pdr).abs() < self.cfg.delta_s_m;
        let fused = if consistent {
            // eq. 8: Wi-Fi weighted more
            Point2::from((obs.estimate.coords * hi + pdr.coords * lo) / sum)
        } else {
            // eq. 9: PDR weighted more
            Point2::from((obs.estimate.coords * lo + pdr.coords * hi) / sum)
        };
        let gain = if consistent { hi / sum } else { lo / sum };
        self.variance.fix(obs.estimate - pdr, gain);
        self.last_flagged = Some(!consistent);
        self.position = Some(fused);
        self.last_fused = fused;
    }

    fn estimate(&self) -> Option<Estimate> {
        self.position.map(|position| Estimate {
            t: self.t,
            position,
            covariance: Some(self.variance.covariance()),
            diagnostics: Diagnostics {
                wifi_flagged: self.last_flagged,
                ..self.guard.diagnostics()
            },
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{obs_at, step};

    #[test]
    fn the_radius_grows_by_dead_reckoning_and_shrinks_at_a_fix() {
        let mut f = AwsFuser::new(AwsConfig::default(), None).unwrap();
        // the second fix is consistent with the 14 m walked: weighted 0.8
        let [at_fix, walked, after] = crate::synthetic::variance_at_fix_walk_fix(&mut f).unwrap();
        assert!(walked > at_fix, "{walked} <= {at_fix}");
        assert!(after < walked);
        let p = f.estimate().unwrap().covariance.unwrap();
        assert_eq!(p[(0, 1)], p[(1, 0)]);
        assert!(p[(0, 0)] > 0.0 && p[(1, 1)] > 0.0);
    }

    #[test]
    fn weights_follow_the_displacement_constraint() {
        // The paper's weights (w1 0.4, w2 0.6, delta_S 3 m) make the arithmetic readable.
        let mut f = AwsFuser::new(AwsConfig::paper(), None).unwrap();
        f.on_wifi(&obs_at(0, 0.0, 0.0));
        for k in 1..=3 {
            f.on_step(&step(k * 500, 1.0, 0.0)); // PDR at (0, 3)
        }
        f.on_wifi(&obs_at(2000, 0.0, 4.0)); // consistent: 0.6 * 4 + 0.4 * 3 = 3.6
        let p = f.estimate().unwrap().position;
        assert!((p.y - 3.6).abs() < 1e-12);
        f.on_wifi(&obs_at(2100, 0.0, 30.0)); // inconsistent: 0.4 * 30 + 0.6 * 3.6
        let p = f.estimate().unwrap().position;
        assert!((p.y - (0.4 * 30.0 + 0.6 * 3.6)).abs() < 1e-12);
        assert_eq!(f.estimate().unwrap().diagnostics.wifi_flagged, Some(true));
    }
}

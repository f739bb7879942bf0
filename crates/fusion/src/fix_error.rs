//! The horizontal uncertainty of schemes whose state carries no covariance of its own (`aws`,
//! `tcpf`, `rof`) or an over-confident one (`pf`, `apf`): **wipdr's own, not from the papers**.
//!
//! # The model
//!
//! Two things are learned or propagated per walk, both causal:
//!
//! - **The Wi-Fi fixes' error variance** `R` (per axis) by covariance matching on the
//!   residuals: each fix's residual `v = z - x` against the scheme's prediction `x`, whose own
//!   variance `P` is known, gives a sample `|v|^2 / 2 - P` of `R` ([`FixErrorTracker`]). A
//!   prior (`prior_wifi_sd_m`, weighted as `prior_fixes` fixes) carries the first fixes; a
//!   sample is capped at `9 R` so that one gross fix does not double it.
//!   A residual counts as a fraction `min(1, walked / decorrelation_m)` of a sample: fixes
//!   taken standing still repeat one error and would teach a small `R`.
//! - **The share of it fusion cannot average away.** Wi-Fi errors along a walk are correlated
//!   (a bias shared by the fixes of one coverage gap), so a scheme that averages fixes under an
//!   independence assumption becomes over-confident. The reported variance keeps
//!   `bias_share x R` on top of what the scheme's own recursion gives.
//!
//! A fixed-gain scheme (`aws`, `tcpf`: `x = (1 - a) x_pdr + a z`) propagates its variance
//! exactly under that model ([`GainVariance`]): `P += pdr_var_per_m x step length` per step,
//! `P = (1 - a)^2 P + a^2 R` per fix.
//!
//! `bias_share` is calibrated on the five ILC floors so that the 95 % radius (2.45 sd) holds
//! the truth at about 95 % of the scored waypoints, and checked on the IPIN building (another
//! building, other phones): `docs/experiments.md` (bias share); measured by `wipdr eval
//! --schemes pf,apf,aws,tcpf,rof --config B.toml` with `radius = { bias_share = B }` per scheme.
//!
//! ```
//! use wipdr_core::Vector2;
//! use wipdr_fusion::fix_error::{GainVariance, RadiusConfig};
//! let mut v = GainVariance::new(RadiusConfig::default());
//! v.start();
//! let before = v.variance();
//! v.step(10.0); // ten metres of dead reckoning: the variance grows
//! assert!(v.variance() > before);
//! v.fix(Vector2::new(30.0, 0.0), 0.8); // a far fix raises the learned Wi-Fi error
//! assert!(v.wifi_variance() > RadiusConfig::default().prior_wifi_sd_m.powi(2));
//! assert!(v.variance().is_finite() && v.variance() > 0.0);
//! ```

use nalgebra::Matrix2;
use serde::{Deserialize, Serialize};
use wipdr_core::ConfigError;
use wipdr_core::Vector2;

use crate::FusionError;

/// Config of the uncertainty model (`[schemes.X.radius]` of `aws`, `tcpf`, `rof`, `pf`, `apf`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RadiusConfig {
    /// Prior standard deviation of one axis of a Wi-Fi fix's error, metres (6 m: the ILC
    /// floors' Wi-Fi fixes, mean error 7.8 m, are a Rayleigh of about that sd).
    pub prior_wifi_sd_m: f64,
    /// Weight of the prior, in fixes.
    pub prior_fixes: f64,
    /// Share of the Wi-Fi error variance the estimate keeps whatever the averaging (the
    /// correlated part of the fixes' error; see the module docs).
    pub bias_share: f64,
    /// Variance growth of a dead-reckoned position, m² per metre walked (fixed-gain schemes).
    pub pdr_var_per_m: f64,
    /// Distance walked over which two fixes' errors decorrelate, metres: a residual counts
    /// `min(1, walked since the previous fix / decorrelation_m)` of a sample, so the fixes
    /// of a walker standing still (one biased answer repeated) do not teach a small `R`.
    /// 0: every residual counts fully. 3 m (default) took the IPIN radii from 73-84 % to
    /// 85-93 % coverage and moved the ILC ones by 0-0.5 points.
    pub decorrelation_m: f64,
}

impl Default for RadiusConfig {
    fn default() -> Self {
        Self {
            prior_wifi_sd_m: 6.0,
            prior_fixes: 3.0,
            bias_share: 0.8,
            pdr_var_per_m: 0.05,
            decorrelation_m: 3.0,
        }
    }
}

impl RadiusConfig {
    /// Checks the fields.
    pub fn validate(&self) -> Result<(), FusionError> {
        let fields = [
            ("radius.prior_wifi_sd_m", self.prior_wifi_sd_m, true),
            ("radius.prior_fixes", self.prior_fixes, true),
            ("radius.bias_share", self.bias_share, false),
            ("radius.pdr_var_per_m", self.pdr_var_per_m, false),
            ("radius.decorrelation_m", self.decorrelation_m, false),
        ];
        for (field, v, strictly_positive) in fields {
            let ok = v.is_finite() && if strictly_positive { v > 0.0 } else { v >= 0.0 };
            if !ok {
                let bound = if strictly_positive { "> 0" } else { ">= 0" };
                return Err(FusionError::InvalidConfig(ConfigError::new(
                    field,
                    format!("must be finite and {bound}, got {v}"),
                )));
            }
        }
        Ok(())
    }
}

/// The Wi-Fi fixes' error variance learned from their residuals (see the module docs).
#[derive(Debug, Clone)]
pub struct FixErrorTracker {
    prior_var: f64,
    prior_fixes: f64,
    decorrelation_m: f64,
    walked_m: f64,
    sum: f64,
    count: f64,
}

impl FixErrorTracker {
    /// A tracker holding only the prior of `cfg`.
    pub fn new(cfg: &RadiusConfig) -> Self {
        Self {
            prior_var: cfg.prior_wifi_sd_m * cfg.prior_wifi_sd_m,
            prior_fixes: cfg.prior_fixes,
            decorrelation_m: cfg.decorrelation_m,
            walked_m: 0.0,
            sum: 0.0,
            count: 0.0,
        }
    }

    /// Notes `length_m` walked (a PDR step) since the previous fix.
    pub fn walk(&mut self, length_m: f64) {
        if length_m.is_finite() && length_m > 0.0 {
            self.walked_m += length_m;
        }
    }

    /// Takes one fix's residual against a prediction of per-axis variance `predicted_var`.
    /// Non-finite inputs are ignored.
    pub fn observe(&mut self, residual: Vector2, predicted_var: f64) {
        let r2 = residual.norm_squared();
        let weight = if self.decorrelation_m > 0.0 {
            (self.walked_m / self.decorrelation_m).min(1.0)
        } else {
            1.0
        };
        self.walked_m = 0.0;
        if !(r2.is_finite() && predicted_var.is_finite()) || weight <= 0.0 {
            return;
        }
        let sample = (0.5 * r2 - predicted_var.max(0.0)).clamp(0.0, 9.0 * self.variance());
        self.sum += weight * sample;
        self.count += weight;
    }

    /// The per-axis variance of a fix's error, m² (positive: the prior keeps it so).
    pub fn variance(&self) -> f64 {
        (self.prior_fixes * self.prior_var + self.sum) / (self.prior_fixes + self.count)
    }
}

/// The variance of a fixed-gain fusion `x = (1 - a) x_pdr + a z` (see the module docs).
#[derive(Debug, Clone)]
pub struct GainVariance {
    cfg: RadiusConfig,
    tracker: FixErrorTracker,
    own: f64,
}

impl GainVariance {
    /// Before the first fix (call [`GainVariance::start`] there).
    pub fn new(cfg: RadiusConfig) -> Self {
        Self {
            tracker: FixErrorTracker::new(&cfg),
            own: 0.0,
            cfg,
        }
    }

    /// The scheme started at a fix: its variance is a fix's.
    pub fn start(&mut self) {
        self.own = self.tracker.variance();
    }

    /// The scheme started at a known position of per-axis variance `var`.
    pub fn start_known(&mut self, var: f64) {
        self.own = var.max(0.0);
    }

    /// One dead-reckoned step of `length_m`.
    pub fn step(&mut self, length_m: f64) {
        if length_m.is_finite() && length_m > 0.0 {
            self.own += self.cfg.pdr_var_per_m * length_m;
            self.tracker.walk(length_m);
        }
    }

    /// One fix with residual `z - x_pdr`, fused with gain `a` (clamped to 0..=1).
    pub fn fix(&mut self, residual: Vector2, gain: f64) {
        self.tracker.observe(residual, self.own);
        let a = if gain.is_finite() {
            gain.clamp(0.0, 1.0)
        } else {
            1.0
        };
        self.own = (1.0 - a).powi(2) * self.own + a * a * self.tracker.variance();
    }

    /// The learned per-axis variance of a Wi-Fi fix, m².
    pub fn wifi_variance(&self) -> f64 {
        self.tracker.variance()
    }

    /// The reported per-axis variance, m²: the recursion's plus the bias share.
    pub fn variance(&self) -> f64 {
        self.own + self.cfg.bias_share * self.tracker.variance()
    }

    /// The reported covariance (isotropic), m².
    pub fn covariance(&self) -> Matrix2<f64> {
        Matrix2::identity() * self.variance()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Every residual a full sample (the decorrelation has its own test).
    fn independent() -> RadiusConfig {
        RadiusConfig {
            decorrelation_m: 0.0,
            ..RadiusConfig::default()
        }
    }

    #[test]
    fn residuals_count_by_the_distance_walked_since_the_previous_fix() {
        let mut t = FixErrorTracker::new(&RadiusConfig::default());
        t.observe(Vector2::new(30.0, 0.0), 0.0); // standing: no sample
        assert_eq!(t.variance(), 36.0);
        t.walk(1.5); // half of the 3 m: half a sample of 324 (the cap, 9 R)
        t.observe(Vector2::new(1000.0, 0.0), 0.0);
        assert!((t.variance() - (3.0 * 36.0 + 0.5 * 324.0) / 3.5).abs() < 1e-9);
        t.walk(10.0); // a full sample, then nothing walked again
        t.observe(Vector2::new(0.0, 0.0), 0.0);
        let after = t.variance();
        t.observe(Vector2::new(1000.0, 0.0), 0.0);
        assert_eq!(t.variance(), after);
    }

    #[test]
    fn the_tracker_learns_the_fixes_spread() {
        let cfg = independent();
        let mut t = FixErrorTracker::new(&cfg);
        assert_eq!(t.variance(), 36.0);
        // residuals of 4 m per axis, a prediction without variance: R -> 16
        for k in 0..200 {
            let s = if k % 2 == 0 { 1.0 } else { -1.0 };
            t.observe(Vector2::new(4.0 * s, 4.0 * s), 0.0);
        }
        assert!((t.variance() - 16.0).abs() < 0.5, "{}", t.variance());
        // the prediction's own variance is not counted as the fixes'
        let mut u = FixErrorTracker::new(&cfg);
        for _ in 0..200 {
            u.observe(Vector2::new(4.0, 4.0), 10.0);
        }
        assert!((u.variance() - 6.0).abs() < 0.5, "{}", u.variance());
    }

    #[test]
    fn one_gross_fix_is_capped() {
        let mut t = FixErrorTracker::new(&independent());
        t.observe(Vector2::new(1000.0, 0.0), 0.0);
        // capped at 9 R = 324: (3 * 36 + 324) / 4
        assert!((t.variance() - 108.0).abs() < 1e-9);
    }

    #[test]
    fn gain_one_is_a_fix_gain_zero_is_dead_reckoning() {
        let cfg = RadiusConfig {
            bias_share: 0.0,
            ..independent()
        };
        let mut v = GainVariance::new(cfg);
        v.start_known(1.0);
        v.step(20.0);
        assert!((v.variance() - 2.0).abs() < 1e-12);
        v.fix(Vector2::zeros(), 0.0);
        assert!((v.variance() - 2.0).abs() < 1e-12);
        v.fix(Vector2::zeros(), 1.0);
        assert!((v.variance() - v.wifi_variance()).abs() < 1e-12);
    }

    #[test]
    fn invalid_configs_name_their_field() {
        let bad = RadiusConfig {
            bias_share: -0.1,
            ..RadiusConfig::default()
        };
        assert!(matches!(
            bad.validate(),
            Err(FusionError::InvalidConfig(e)) if e.path == "radius.bias_share"
        ));
        let bad = RadiusConfig {
            prior_wifi_sd_m: 0.0,
            ..RadiusConfig::default()
        };
        assert!(bad.validate().is_err());
        assert!(RadiusConfig::default().validate().is_ok());
    }

    proptest! {
        #[test]
        fn the_variance_stays_positive_and_finite(
            inputs in proptest::collection::vec((-1e4f64..1e4, -1e4f64..1e4, 0.0f64..1.0, 0.0f64..5.0), 1..60)
        ) {
            let mut v = GainVariance::new(RadiusConfig::default());
            v.start();
            for (x, y, a, len) in inputs {
                v.step(len);
                v.fix(Vector2::new(x, y), a);
                prop_assert!(v.variance().is_finite() && v.variance() > 0.0);
                prop_assert!(v.wifi_variance() > 0.0);
            }
        }
    }
}

//! `rof` — robust offset fusion: **wipdr's own baseline, not from the four papers**.
//!
//! The PDR track has the right shape but an unknown start; Wi-Fi fixes have the right place
//! on average but gross errors. `rof` keeps the PDR track `p(t)` (started at the origin) and
//! estimates the offset `o` that places it on the map as the **geometric median** of the last
//! `window` offsets `w_j - p(t_j)` (Wi-Fi fix minus PDR position at the fix). The geometric
//! median (Weiszfeld iterations) has a 50 % breakdown point: a gross fix, or a wrong first
//! fix, is outvoted by the fixes that agree, which is the "start that waits for consistent
//! evidence" of the project's findings. The window lets the offset follow slow PDR drift.
//! The estimate is `p(t) + o`.
//!
//! ```
//! use wipdr_core::{Point2, StepEvent, WifiObservation, MotionState};
//! use wipdr_fusion::{Fuser, RobustOffset, RobustOffsetConfig};
//! let mut f = RobustOffset::new(RobustOffsetConfig::default());
//! let fix = |t, x: f64| WifiObservation { t, estimate: Point2::new(x, 0.0), candidates: vec![],
//!     visited: 0, floor: None, building: None, likelihood: None };
//! f.on_wifi(&fix(0, 10.0));
//! f.on_wifi(&fix(1, 10.0));
//! f.on_wifi(&fix(2, 90.0)); // a gross error is outvoted
//! assert!((f.estimate().unwrap().position.x - 10.0).abs() < 1e-3);
//! ```

use nalgebra::Matrix2;
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;
use wipdr_core::ConfigError;
use wipdr_core::{Point2, StepEvent, TimestampMs, Vector2, WifiObservation, angle};

use crate::fix_error::{FixErrorTracker, RadiusConfig};
use crate::{Estimate, Fuser, FusionError, InputGuard};

/// Config of `rof`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RobustOffsetConfig {
    /// How many of the latest fixes vote on the offset.
    pub window: usize,
    /// Weiszfeld iterations of the geometric median.
    pub iterations: usize,
    /// Multiplies every step length (1 = as PDR reports).
    pub step_scale: f64,
    /// Each vote is weighted by `best_distance^-quality_power` (the signal distance of the
    /// fix's best candidate: a poor match votes less); 0 weights every fix equally.
    pub quality_power: f64,
    /// The horizontal uncertainty of the estimate: [`crate::fix_error`]'s learned Wi-Fi
    /// variance `R` over the window's fixes (`R (4 / pi) / n`, the spatial median's
    /// efficiency), its bias share, and the PDR growth since the latest fix.
    pub radius: RadiusConfig,
}

impl Default for RobustOffsetConfig {
    fn default() -> Self {
        Self {
            window: 15,
            iterations: 50,
            step_scale: 1.0,
            quality_power: 0.0,
            radius: RadiusConfig::default(),
        }
    }
}

impl RobustOffsetConfig {
    /// `rof` is wipdr's own baseline, in no paper: its preset is the default above.
    pub fn paper() -> Self {
        Self::default()
    }

    /// Checks the fields.
    pub fn validate(&self) -> Result<(), FusionError> {
        if self.window == 0 {
            return Err(FusionError::InvalidConfig(ConfigError::new(
                "window",
                "must be at least 1",
            )));
        }
        if !(self.quality_power.is_finite() && self.quality_power >= 0.0) {
            return Err(FusionError::InvalidConfig(ConfigError::new(
                "quality_power",
                format!("must be finite and >= 0, got {}", self.quality_power),
            )));
        }
        if !(self.step_scale.is_finite() && self.step_scale > 0.0) {
            return Err(FusionError::InvalidConfig(ConfigError::new(
                "step_scale",
                format!("must be positive and finite, got {}", self.step_scale),
            )));
        }
        self.radius.validate()
    }
}

/// Geometric median of `points` by Weiszfeld's algorithm (started at the coordinate-wise
/// mean; a point that coincides with the iterate is handled by stopping there). `None` when
/// `points` is empty.
pub fn geometric_median(points: &[Vector2], iterations: usize) -> Option<Vector2> {
    let weighted: Vec<(Vector2, f64)> = points.iter().map(|&p| (p, 1.0)).collect();
    weighted_geometric_median(&weighted, iterations)
}

/// Weighted geometric median (`argmin sum w_i |p_i - m|`) by Weiszfeld's algorithm. Points
/// with a non-positive or non-finite weight are ignored; `None` when none is left.
pub fn weighted_geometric_median(points: &[(Vector2, f64)], iterations: usize) -> Option<Vector2> {
    let pts: Vec<(Vector2, f64)> = points
        .iter()
        .copied()
        .filter(|(p, w)| w.is_finite() && *w > 0.0 && p.x.is_finite() && p.y.is_finite())
        .collect();
    let wsum: f64 = pts.iter().map(|(_, w)| w).sum();
    if pts.is_empty() || !(wsum.is_finite() && wsum > 0.0) {
        return None;
    }
    let mut m = pts.iter().fold(Vector2::zeros(), |a, (p, w)| a + p * *w) / wsum;
    for _ in 0..iterations {
        let (mut num, mut den) = (Vector2::zeros(), 0.0);
        for (p, w) in &pts {
            let d = (p - m).norm();
            if d < 1e-9 {
                // The iterate sits on a data point; Weiszfeld's update is undefined there and
                // the point is (for practical purposes) the median.
                return Some(*p);
            }
            num += p * (*w / d);
            den += *w / d;
        }
        let next = num / den;
        let moved = (next - m).norm();
        m = next;
        if moved < 1e-6 {
            break;
        }
    }
    Some(m)
}

/// Robust offset fusion (see the module docs).
#[derive(Debug, Clone)]
pub struct RobustOffset {
    cfg: RobustOffsetConfig,
    pdr: Vector2,
    offsets: VecDeque<(Vector2, f64)>,
    offset: Option<Vector2>,
    t: TimestampMs,
    fix_error: FixErrorTracker,
    walked_since_fix: f64,
    guard: InputGuard,
}

impl RobustOffset {
    /// A new filter (call [`RobustOffsetConfig::validate`] first for untrusted configs).
    pub fn new(cfg: RobustOffsetConfig) -> Self {
        Self {
            fix_error: FixErrorTracker::new(&cfg.radius),
            walked_since_fix: 0.0,
            cfg,
            pdr: Vector2::zeros(),
            offsets: VecDeque::new(),
            offset: None,
            t: 0,
            guard: InputGuard::default(),
        }
    }
}

impl RobustOffset {
    /// The estimate's per-axis variance, m² (see [`RobustOffsetConfig::radius`]).
    fn variance(&self) -> f64 {
        self.own_variance() + self.cfg.radius.bias_share * self.fix_error.variance()
    }

    /// The median's and the dead reckoning's part of [`RobustOffset::variance`], without the
    /// bias share: what a fix's residual is predicted to hold besides the fix's own error.
    fn own_variance(&self) -> f64 {
        let n = self.offsets.len().max(1) as f64;
        self.fix_error.variance() * (4.0 / std::f64::consts::PI) / n
            + self.cfg.radius.pdr_var_per_m * self.walked_since_fix
    }
}

impl Fuser for RobustOffset {
    fn name(&self) -> &'static str {
        "rof"
    }

    fn on_step(&mut self, step: &StepEvent) {
        if !self.guard.accept_step(step) {
            return;
        }
        self.pdr += angle::step_displacement(step.length * self.cfg.step_scale, step.heading);
        self.walked_since_fix += step.length * self.cfg.step_scale;
        self.fix_error.walk(step.length * self.cfg.step_scale);
        self.t = step.t;
    }

    fn on_wifi(&mut self, obs: &WifiObservation) {
        if !self.guard.accept_wifi(obs) {
            return;
        }
        let weight = match obs.best_distance() {
            Some(d) if self.cfg.quality_power > 0.0 => d.max(1e-3).powf(-self.cfg.quality_power),
            _ => 1.0,
        };
        if let Some(o) = self.offset {
            let predicted = self.own_variance();
            self.fix_error
                .observe(obs.estimate.coords - (self.pdr + o), predicted);
        }
        self.walked_since_fix = 0.0;
        self.offsets
            .push_back((obs.estimate.coords - self.pdr, weight));
        while self.offsets.len() > self.cfg.window {
            self.offsets.pop_front();
        }
        let pts: Vec<(Vector2, f64)> = self.offsets.iter().copied().collect();
        if let Some(o) = weighted_geometric_median(&pts, self.cfg.iterations) {
            self.offset = Some(o);
        }
        self.t = obs.t;
    }

    fn estimate(&self) -> Option<Estimate> {
        self.offset.map(|o| Estimate {
            t: self.t,
            position: Point2::from(self.pdr + o),
            covariance: Some(Matrix2::identity() * self.variance()),
            diagnostics: self.guard.diagnostics(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn the_radius_shrinks_as_agreeing_fixes_vote() {
        let var = |f: &RobustOffset| f.estimate().unwrap().covariance.unwrap()[(0, 0)];
        let fix = |t, x: f64| WifiObservation {
            t,
            estimate: Point2::new(x, 0.0),
            candidates: vec![],
            visited: 0,
            floor: None,
            building: None,
            likelihood: None,
        };
        let mut f = RobustOffset::new(RobustOffsetConfig::default());
        f.on_wifi(&fix(0, 10.0));
        let one = var(&f);
        for t in 1..6 {
            f.on_wifi(&fix(t, 10.0 + (t % 2) as f64));
        }
        let six = var(&f);
        assert!(six < one, "{six} >= {one}");
        // never below the bias share of the learned Wi-Fi variance
        assert!(six >= RobustOffsetConfig::default().radius.bias_share * f.fix_error.variance());
    }

    #[test]
    fn median_ignores_a_minority_of_outliers() {
        let mut pts = vec![Vector2::new(1.0, 1.0); 6];
        pts.push(Vector2::new(100.0, -50.0));
        pts.push(Vector2::new(-80.0, 40.0));
        let m = geometric_median(&pts, 100).unwrap();
        assert!((m - Vector2::new(1.0, 1.0)).norm() < 1e-6);
        assert!(geometric_median(&[], 10).is_none());
    }

    #[test]
    fn invalid_configs_are_rejected() {
        let bad = RobustOffsetConfig {
            window: 0,
            ..Default::default()
        };
        assert!(bad.validate().is_err());
    }

    proptest! {
        #[test]
        fn median_is_finite_and_inside_the_bounding_box(
            pts in proptest::collection::vec((-1e3f64..1e3, -1e3f64..1e3), 1..30)
        ) {
            let v: Vec<Vector2> = pts.iter().map(|&(x, y)| Vector2::new(x, y)).collect();
            let m = geometric_median(&v, 50).unwrap();
            let (lo_x, hi_x) = v.iter().fold((f64::MAX, f64::MIN), |a, p| (a.0.min(p.x), a.1.max(p.x)));
            let (lo_y, hi_y) = v.iter().fold((f64::MAX, f64::MIN), |a, p| (a.0.min(p.y), a.1.max(p.y)));
            prop_assert!(m.x.is_finite() && m.y.is_finite());
            prop_assert!(m.x >= lo_x - 1e-6 && m.x <= hi_x + 1e-6 && m.y >= lo_y - 1e-6 && m.y <= hi_y + 1e-6);
        }
    }
}

//! Static start (paper 001 §3.2): while the walker stands still at the start, average the
//! Wi-Fi fixes of those seconds after removing gross ones, and start the fusion there.
//!
//! [`StaticStart`] wraps any [`Fuser`]. Until the first PDR step (the walker has not moved)
//! it holds the Wi-Fi fixes back; its estimate meanwhile is their robust average. On the first
//! step it hands the wrapped scheme one fix at the robust average of the held ones (time of
//! the latest), then the step, and from then on passes everything through. The robust average:
//! the geometric median of the held fixes, then the mean of those within `gross_m` of it (when
//! fewer than half are, the median itself). With zero or one fix held it changes nothing.
//!
//! ```
//! use wipdr_core::{MotionState, Point2, StepEvent, WifiObservation};
//! use wipdr_fusion::{Fuser, SchemeConfig, BuildContext};
//! use wipdr_fusion::static_start::{StaticStart, StaticStartConfig};
//! let inner = SchemeConfig::default_for("pdr").unwrap().build(&BuildContext::default()).unwrap();
//! let mut f = StaticStart::new(inner, StaticStartConfig::default());
//! let fix = |t, x: f64| WifiObservation { t, estimate: Point2::new(x, 0.0), candidates: vec![],
//!     visited: 0, floor: None, building: None, likelihood: None };
//! for (t, x) in [(0, 1.0), (1000, -1.0), (2000, 60.0), (3000, 0.5)] {
//!     f.on_wifi(&fix(t, x)); // standing still; the 60 m fix is gross
//! }
//! f.on_step(&StepEvent { t: 3500, length: 0.7, heading: 0.0, heading_change: 0.0,
//!     period_s: 0.5, motion: MotionState::default(), covariance: None });
//! let p = f.estimate().unwrap().position;
//! assert!(p.x.abs() < 1.0 && (p.y - 0.7).abs() < 1e-9);
//! ```

use serde::{Deserialize, Serialize};
use wipdr_core::ConfigError;
use wipdr_core::{Candidate, Point2, StepEvent, Vector2, WifiObservation};

use crate::robust_offset::geometric_median;
use crate::{Diagnostics, Estimate, Fuser, FusionError, WeightedPoint};

/// Config of the static start.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StaticStartConfig {
    /// A held fix farther than this from the geometric median of the held fixes is gross,
    /// metres.
    pub gross_m: f64,
    /// Most fixes held (the latest are kept).
    pub max_fixes: usize,
}

impl Default for StaticStartConfig {
    fn default() -> Self {
        Self {
            gross_m: 10.0,
            max_fixes: 30,
        }
    }
}

impl StaticStartConfig {
    /// Checks the fields.
    pub fn validate(&self) -> Result<(), FusionError> {
        if !(self.gross_m.is_finite() && self.gross_m > 0.0) {
            return Err(FusionError::InvalidConfig(ConfigError::new(
                "static_start.gross_m",
                format!("must be finite and > 0, got {}", self.gross_m),
            )));
        }
        if self.max_fixes == 0 {
            return Err(FusionError::InvalidConfig(ConfigError::new(
                "static_start.max_fixes",
                "must be at least 1",
            )));
        }
        Ok(())
    }
}

/// The robust average of fixes: geometric median, then the mean of the fixes within
/// `gross_m` of it (the median when fewer than half are). `None` for no finite fix.
pub fn robust_average(fixes: &[Point2], gross_m: f64) -> Option<Point2> {
    let pts: Vec<Vector2> = fixes
        .iter()
        .filter(|p| p.x.is_finite() && p.y.is_finite())
        .map(|p| p.coords)
        .collect();
    let median = geometric_median(&pts, 50)?;
    let kept: Vec<Vector2> = pts
        .iter()
        .copied()
        .filter(|p| (p - median).norm() <= gross_m)
        .collect();
    if kept.len() * 2 < pts.len() || kept.is_empty() {
        return Some(Point2::from(median));
    }
    Some(Point2::from(
        kept.iter().fold(Vector2::zeros(), |a, b| a + b) / kept.len() as f64,
    ))
}

/// Any scheme with a static start; see the [module docs](self).
pub struct StaticStart {
    inner: Box<dyn Fuser + Send>,
    cfg: StaticStartConfig,
    held: Vec<WifiObservation>,
    moving: bool,
}

impl StaticStart {
    /// Wraps `inner` (an invalid config falls back to the defaults, logged).
    pub fn new(inner: Box<dyn Fuser + Send>, cfg: StaticStartConfig) -> Self {
        let cfg = match cfg.validate() {
            Ok(()) => cfg,
            Err(e) => {
                tracing::warn!(error = %e, "static start: invalid config, using the defaults");
                StaticStartConfig::default()
            }
        };
        Self {
            inner,
            cfg,
            held: Vec::new(),
            moving: false,
        }
    }

    fn held_average(&self) -> Option<Point2> {
        let pts: Vec<Point2> = self.held.iter().map(|o| o.estimate).collect();
        robust_average(&pts, self.cfg.gross_m)
    }
}

impl Fuser for StaticStart {
    fn name(&self) -> &'static str {
        self.inner.name()
    }

    fn on_step(&mut self, step: &StepEvent) {
        if !self.moving {
            self.moving = true;
            match self.held.len() {
                0 => {}
                1 => self.inner.on_wifi(&self.held[0]),
                _ => {
                    if let Some(avg) = self.held_average() {
                        let last = &self.held[self.held.len() - 1];
                        let start = WifiObservation {
                            t: last.t,
                            estimate: avg,
                            candidates: vec![Candidate {
                                position: avg,
                                distance: last.best_distance().unwrap_or(0.0),
                                weight: 1.0,
                                index: 0,
                                floor: None,
                            }],
                            visited: last.visited,
                            floor: last.floor,
                            building: last.building,
                            // The latest scan's likelihood (the average is a point only).
                            likelihood: last.likelihood.clone(),
                        };
                        self.inner.on_wifi(&start);
                    }
                }
            }
            self.held.clear();
        }
        self.inner.on_step(step);
    }

    fn on_wifi(&mut self, obs: &WifiObservation) {
        if self.moving {
            self.inner.on_wifi(obs);
            return;
        }
        if self.held.last().is_some_and(|l| obs.t < l.t) {
            tracing::warn!(t = obs.t, "static start: fix out of time order skipped");
            return;
        }
        self.held.push(obs.clone());
        if self.held.len() > self.cfg.max_fixes {
            self.held.remove(0);
        }
    }

    fn estimate(&self) -> Option<Estimate> {
        if self.moving || self.held.is_empty() {
            return self.inner.estimate();
        }
        let t = self.held[self.held.len() - 1].t;
        self.held_average()
            .map(|p| Estimate::point(t, p, Diagnostics::default()))
    }

    fn particle_cloud(&self) -> Option<Vec<WeightedPoint>> {
        self.inner.particle_cloud()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{BuildContext, SchemeConfig};
    use wipdr_core::MotionState;

    fn fix(t: i64, x: f64, y: f64) -> WifiObservation {
        WifiObservation {
            t,
            estimate: Point2::new(x, y),
            candidates: vec![],
            visited: 0,
            floor: None,
            building: None,
            likelihood: None,
        }
    }

    fn step(t: i64) -> StepEvent {
        StepEvent {
            t,
            length: 0.7,
            heading: std::f64::consts::FRAC_PI_2,
            heading_change: 0.0,
            period_s: 0.5,
            motion: MotionState::default(),
            covariance: None,
        }
    }

    #[test]
    fn robust_average_drops_gross_fixes() {
        let pts = [
            Point2::new(0.0, 0.0),
            Point2::new(2.0, 0.0),
            Point2::new(1.0, 1.0),
            Point2::new(80.0, 80.0),
        ];
        let a = robust_average(&pts, 10.0).unwrap();
        assert!((a - Point2::new(1.0, 1.0 / 3.0)).norm() < 1e-6, "{a:?}");
        assert!(robust_average(&[], 10.0).is_none());
        let nan = [Point2::new(f64::NAN, 0.0), Point2::new(3.0, 4.0)];
        assert_eq!(robust_average(&nan, 10.0), Some(Point2::new(3.0, 4.0)));
    }

    #[test]
    fn a_walker_who_does_not_stand_still_sees_no_change() {
        let build = || {
            SchemeConfig::default_for("ekf")
                .unwrap()
                .build(&BuildContext::default())
                .unwrap()
        };
        let mut plain = build();
        let mut wrapped = StaticStart::new(build(), StaticStartConfig::default());
        let inputs = [
            (0, true),
            (400, false),
            (900, false),
            (1200, true),
            (1500, false),
        ];
        for (t, wifi) in inputs {
            if wifi {
                plain.on_wifi(&fix(t, 5.0, 3.0));
                wrapped.on_wifi(&fix(t, 5.0, 3.0));
            } else {
                plain.on_step(&step(t));
                wrapped.on_step(&step(t));
            }
            assert_eq!(
                plain.estimate().map(|e| e.position),
                wrapped.estimate().map(|e| e.position)
            );
        }
    }

    #[test]
    fn standing_still_averages_then_walks_from_there() {
        let inner = SchemeConfig::default_for("pdr")
            .unwrap()
            .build(&BuildContext::default())
            .unwrap();
        let mut f = StaticStart::new(inner, StaticStartConfig::default());
        assert!(f.estimate().is_none());
        for (t, x) in [(0, 10.0), (1000, 12.0), (2000, 11.0), (3000, -70.0)] {
            f.on_wifi(&fix(t, x, 0.0));
        }
        let held = f.estimate().unwrap().position;
        assert!((held - Point2::new(11.0, 0.0)).norm() < 1e-6, "{held:?}");
        f.on_step(&step(3500));
        let p = f.estimate().unwrap().position;
        assert!((p - Point2::new(11.7, 0.0)).norm() < 1e-6, "{p:?}");
    }

    #[test]
    fn invalid_configs_are_rejected() {
        assert!(
            StaticStartConfig {
                gross_m: 0.0,
                ..Default::default()
            }
            .validate()
            .is_err()
        );
        assert!(
            StaticStartConfig {
                max_fixes: 0,
                ..Default::default()
            }
            .validate()
            .is_err()
        );
    }
}

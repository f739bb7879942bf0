//! Baselines: `wifi` (the matcher's estimate, held between scans) and `pdr` (dead reckoning
//! from a given start, or from the first Wi-Fi fix when no start is given).

use serde::{Deserialize, Serialize};
use wipdr_core::{Point2, StepEvent, TimestampMs, WifiObservation, angle};

use crate::{Estimate, Fuser, InputGuard};

/// Config of `wifi` (nothing to tune; a struct so that the TOML shape is uniform).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WifiOnlyConfig {}

/// Config of `pdr`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PdrOnlyConfig {
    /// Multiplies every step length (1 = as PDR reports).
    pub step_scale: f64,
}

impl Default for PdrOnlyConfig {
    fn default() -> Self {
        Self { step_scale: 1.0 }
    }
}

impl PdrOnlyConfig {
    /// The papers' PDR: step lengths as the step-length model gives them (the default).
    pub fn paper() -> Self {
        Self::default()
    }
}

/// Wi-Fi only: the latest fix, held until the next one.
#[derive(Debug, Clone)]
pub struct WifiOnly {
    last: Option<(TimestampMs, Point2)>,
    guard: InputGuard,
}

impl WifiOnly {
    /// A Wi-Fi-only "fuser".
    pub fn new(_cfg: WifiOnlyConfig) -> Self {
        Self {
            last: None,
            guard: InputGuard::default(),
        }
    }
}

impl Fuser for WifiOnly {
    fn name(&self) -> &'static str {
        "wifi"
    }
    fn on_step(&mut self, _step: &StepEvent) {}
    fn on_wifi(&mut self, obs: &WifiObservation) {
        if self.guard.accept_wifi(obs) {
            self.last = Some((obs.t, obs.estimate));
        }
    }
    fn estimate(&self) -> Option<Estimate> {
        self.last
            .map(|(t, position)| Estimate::point(t, position, self.guard.diagnostics()))
    }
}

/// PDR only: `p += l (sin psi, cos psi)` per step from the start.
#[derive(Debug, Clone)]
pub struct PdrOnly {
    cfg: PdrOnlyConfig,
    position: Option<Point2>,
    t: TimestampMs,
    guard: InputGuard,
}

impl PdrOnly {
    /// Dead reckoning from `start` (or from the first Wi-Fi fix when `None`).
    pub fn new(cfg: PdrOnlyConfig, start: Option<Point2>) -> Self {
        Self {
            cfg,
            position: start,
            t: 0,
            guard: InputGuard::default(),
        }
    }
}

impl Fuser for PdrOnly {
    fn name(&self) -> &'static str {
        "pdr"
    }
    fn on_step(&mut self, step: &StepEvent) {
        if !self.guard.accept_step(step) {
            return;
        }
        if let Some(p) = &mut self.position {
            *p += angle::step_displacement(step.length * self.cfg.step_scale, step.heading);
            self.t = step.t;
        }
    }
    fn on_wifi(&mut self, obs: &WifiObservation) {
        if self.guard.accept_wifi(obs) && self.position.is_none() {
            self.position = Some(obs.estimate);
            self.t = obs.t;
        }
    }
    fn estimate(&self) -> Option<Estimate> {
        self.position
            .map(|position| Estimate::point(self.t, position, self.guard.diagnostics()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{obs_at, step};

    #[test]
    fn wifi_holds_and_pdr_reckons() {
        let mut w = WifiOnly::new(WifiOnlyConfig::default());
        assert!(w.estimate().is_none());
        w.on_wifi(&obs_at(10, 1.0, 2.0));
        w.on_step(&step(20, 1.0, 0.0));
        assert_eq!(w.estimate().unwrap().position, Point2::new(1.0, 2.0));
        // out of order: skipped and counted
        w.on_wifi(&obs_at(5, 9.0, 9.0));
        assert_eq!(w.estimate().unwrap().diagnostics.skipped_inputs, 1);

        let mut p = PdrOnly::new(PdrOnlyConfig::default(), Some(Point2::new(0.0, 0.0)));
        p.on_step(&step(1, 1.0, std::f64::consts::FRAC_PI_2));
        p.on_wifi(&obs_at(2, 50.0, 50.0));
        let e = p.estimate().unwrap().position;
        assert!((e.x - 1.0).abs() < 1e-12 && e.y.abs() < 1e-12);
        let mut nan = step(3, f64::NAN, 0.0);
        nan.length = f64::NAN;
        p.on_step(&nan);
        assert_eq!(p.estimate().unwrap().diagnostics.skipped_inputs, 1);
    }
}

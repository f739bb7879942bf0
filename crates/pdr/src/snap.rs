//! Heading snapping to the building's dominant directions (heuristic drift elimination,
//! Borenstein et al. 2009, for absolute headings): on a straight stretch whose mean heading
//! lies within `threshold_deg` of one of the four directions `orientation_rad + k * 90 deg`,
//! each step's heading is turned by the stretch's deviation from that direction. Causal: a
//! step sees only itself and the steps before it. wipdr's own (no paper).

use serde::{Deserialize, Serialize};
use std::collections::VecDeque;
use std::f64::consts::FRAC_PI_2;
use wipdr_core::angle::wrap_pi;

/// Settings of [`HeadingSnap`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HeadingSnapConfig {
    /// Snap at all (off by default).
    pub enabled: bool,
    /// The building's grid orientation, radians (headings clockwise from `+y`; taken modulo
    /// 90 deg). The evaluation learns it from the training walks' legs.
    pub orientation_rad: f64,
    /// Largest deviation of a straight stretch from a dominant direction that is snapped, deg.
    pub threshold_deg: f64,
    /// Steps in the stretch (the current one and those before it).
    pub window_steps: usize,
    /// A stretch is straight while every heading in it lies within this of its mean, deg.
    pub straight_tolerance_deg: f64,
}

impl Default for HeadingSnapConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            orientation_rad: 0.0,
            threshold_deg: 15.0,
            window_steps: 5,
            straight_tolerance_deg: 12.0,
        }
    }
}

impl HeadingSnapConfig {
    /// Checks the values a config file could get wrong; the error names the field (under
    /// `heading.snap`) and the value.
    pub fn validate(&self) -> Result<(), wipdr_core::ConfigError> {
        if !self.orientation_rad.is_finite() {
            return Err(wipdr_core::ConfigError::new(
                "heading.snap.orientation_rad",
                format!("must be finite, got {}", self.orientation_rad),
            ));
        }
        for (field, v, hi) in [
            ("heading.snap.threshold_deg", self.threshold_deg, 45.0),
            (
                "heading.snap.straight_tolerance_deg",
                self.straight_tolerance_deg,
                90.0,
            ),
        ] {
            if !(v.is_finite() && v > 0.0 && v <= hi) {
                return Err(wipdr_core::ConfigError::new(
                    field,
                    format!("must be in (0, {hi}] degrees, got {v}"),
                ));
            }
        }
        if self.window_steps == 0 {
            return Err(wipdr_core::ConfigError::new(
                "heading.snap.window_steps",
                "must be >= 1, got 0".to_string(),
            ));
        }
        Ok(())
    }
}

/// The state of the snapping: the recent raw headings.
#[derive(Debug, Clone, Default)]
pub struct HeadingSnap {
    recent: VecDeque<f64>,
}

impl HeadingSnap {
    /// The heading to emit for a step of raw heading `heading` (radians).
    pub fn apply(&mut self, heading: f64, cfg: &HeadingSnapConfig) -> f64 {
        if !cfg.enabled || !heading.is_finite() || cfg.window_steps == 0 {
            return heading;
        }
        self.recent.push_back(heading);
        while self.recent.len() > cfg.window_steps {
            self.recent.pop_front();
        }
        if self.recent.len() < cfg.window_steps {
            return heading;
        }
        let (s, c) = self
            .recent
            .iter()
            .fold((0.0, 0.0), |(s, c), h| (s + h.sin(), c + h.cos()));
        if s == 0.0 && c == 0.0 {
            return heading;
        }
        let mean = s.atan2(c);
        let tol = cfg.straight_tolerance_deg.to_radians();
        if self.recent.iter().any(|h| wrap_pi(h - mean).abs() > tol) {
            return heading;
        }
        let rel = wrap_pi(mean - cfg.orientation_rad);
        let k = (rel / FRAC_PI_2).round();
        let delta = wrap_pi(cfg.orientation_rad + k * FRAC_PI_2 - mean);
        if delta.abs() <= cfg.threshold_deg.to_radians() {
            wrap_pi(heading + delta)
        } else {
            heading
        }
    }
}

/// The headings of a track `(t, length, heading)` snapped in order, as the PDR pipeline
/// snaps its steps (for re-derived tracks, e.g. the calibration protocol's). Unchanged when
/// `cfg` is off.
pub fn snap_track<T>(track: &mut [(T, f64, f64)], cfg: &HeadingSnapConfig) {
    let mut snap = HeadingSnap::default();
    for step in track.iter_mut() {
        step.2 = snap.apply(step.2, cfg);
    }
}

/// The grid orientation (radians, in `[-45, 45)` deg) that the legs `(dx, dy, length)` follow
/// best: the length-weighted circular mean of four times their headings, divided by four,
/// with its concentration in `[0, 1]` (1: every leg on the grid). `None` without legs.
pub fn grid_orientation(legs: impl IntoIterator<Item = (f64, f64)>) -> Option<(f64, f64)> {
    let (mut s, mut c, mut w) = (0.0, 0.0, 0.0);
    for (dx, dy) in legs {
        let l = dx.hypot(dy);
        if !(l.is_finite() && l > 0.0) {
            continue;
        }
        let h = dx.atan2(dy);
        s += l * (4.0 * h).sin();
        c += l * (4.0 * h).cos();
        w += l;
    }
    (w > 0.0).then(|| ((s.atan2(c)) / 4.0, s.hypot(c) / w))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_straight_stretch_near_the_grid_is_snapped() {
        let cfg = HeadingSnapConfig {
            enabled: true,
            orientation_rad: 10f64.to_radians(),
            ..Default::default()
        };
        let mut snap = HeadingSnap::default();
        let mut out = 0.0;
        for _ in 0..5 {
            out = snap.apply(95f64.to_radians(), &cfg);
        }
        assert!(
            (out.to_degrees() - 100.0).abs() < 1e-9,
            "{}",
            out.to_degrees()
        );
    }

    #[test]
    fn a_diagonal_or_turning_stretch_is_left_alone() {
        let cfg = HeadingSnapConfig {
            enabled: true,
            ..Default::default()
        };
        let mut snap = HeadingSnap::default();
        for _ in 0..5 {
            assert_eq!(snap.apply(45f64.to_radians(), &cfg), 45f64.to_radians());
        }
        let mut snap = HeadingSnap::default();
        for i in 0..5 {
            let h = (f64::from(i) * 10.0).to_radians();
            assert_eq!(snap.apply(h, &cfg), h);
        }
    }

    #[test]
    fn the_grid_of_axis_legs_is_found() {
        let a = 20f64.to_radians();
        let legs = (0..8).map(|i| {
            let h = a + f64::from(i) * FRAC_PI_2;
            (h.sin() * 3.0, h.cos() * 3.0)
        });
        let (o, r) = grid_orientation(legs).unwrap();
        assert!((o - a).abs() < 1e-9 && (r - 1.0).abs() < 1e-9);
        assert!(grid_orientation(std::iter::empty()).is_none());
    }

    #[test]
    fn a_snapped_track_equals_step_by_step_snapping() {
        let cfg = HeadingSnapConfig {
            enabled: true,
            ..Default::default()
        };
        let headings = [0.1, 0.12, 0.08, 0.11, 0.09, 0.1, 1.5, 1.6];
        let mut track: Vec<(i64, f64, f64)> = headings.iter().map(|h| (0, 0.7, *h)).collect();
        snap_track(&mut track, &cfg);
        let mut snap = HeadingSnap::default();
        for (h, s) in headings.iter().zip(&track) {
            assert_eq!(snap.apply(*h, &cfg), s.2);
        }
        assert!(track[5].2.abs() < 1e-12, "{}", track[5].2);
    }

    #[test]
    fn bad_settings_name_their_field() {
        let bad = [
            HeadingSnapConfig {
                threshold_deg: f64::NAN,
                ..Default::default()
            },
            HeadingSnapConfig {
                straight_tolerance_deg: -1.0,
                ..Default::default()
            },
            HeadingSnapConfig {
                window_steps: 0,
                ..Default::default()
            },
            HeadingSnapConfig {
                orientation_rad: f64::INFINITY,
                ..Default::default()
            },
        ];
        let fields: Vec<_> = bad.iter().map(|c| c.validate().unwrap_err().path).collect();
        assert_eq!(
            fields,
            [
                "heading.snap.threshold_deg",
                "heading.snap.straight_tolerance_deg",
                "heading.snap.window_steps",
                "heading.snap.orientation_rad"
            ]
        );
        assert!(HeadingSnapConfig::default().validate().is_ok());
    }
}

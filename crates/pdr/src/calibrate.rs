//! Calibration of PDR from walks with waypoints, and its scoring.
//!
//! A *leg* is the stretch between two consecutive waypoints of a walk; the steps of a leg
//! are those detected after its first waypoint's time and up to its second's. From training
//! legs this module fits the step-length coefficients by least squares
//! ([`fit_step_length`]) and the floor's heading offset between the magnetic azimuth and the
//! map frame ([`fit_heading_offset`]); for test walks it measures leg errors
//! ([`leg_errors`]) and PDR-only positions started at the true first waypoint
//! ([`dead_reckon_at_waypoints`]).

use crate::length::{StepLengthConfig, least_squares};
use crate::pipeline::{HeadingSource, StepDetail};
use serde::{Deserialize, Serialize};
use wipdr_core::angle::{diff, heading_of, step_displacement};
use wipdr_core::{Point2, TimestampMs, Vector2, Waypoint};

/// What the step-length fit minimises.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FitObjective {
    /// `Σ_legs |Σ_steps l_i u(psi_i) - D|²`: the PDR displacement of each leg against the
    /// leg's displacement (two rows per leg, uses the headings). Curved legs and turns are
    /// handled, and it is the position error that is minimised.
    #[default]
    Displacement,
    /// `Σ_legs (Σ_steps l_i - |D|)²`: summed step lengths against the leg's straight length.
    Length,
}

/// Settings of the calibration.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CalibrationConfig {
    /// Objective of the step-length fit.
    pub objective: FitObjective,
    /// Heading source whose headings the displacement objective uses.
    pub heading_source: HeadingSource,
    /// Legs shorter than this (m) are not used for fitting nor leg scoring.
    pub min_leg_length: f64,
    /// Legs with fewer steps than this are not used.
    pub min_leg_steps: usize,
    /// Ridge weight pulling the coefficients towards the model's defaults (regularises the
    /// three-coefficient linear model), per leg.
    pub ridge_per_leg: f64,
    /// Whether to fit the heading offset (else it stays 0).
    pub fit_heading_offset: bool,
    /// Least concentration in `[0, 1]` of the training legs about their grid orientation
    /// ([`fit_heading_snap`]) for heading snapping to stay on (below it the legs follow no
    /// grid and snapping is turned off).
    pub min_grid_concentration: f64,
}

impl Default for CalibrationConfig {
    fn default() -> Self {
        Self {
            objective: FitObjective::Displacement,
            heading_source: HeadingSource::RotationVector,
            min_leg_length: 2.0,
            min_leg_steps: 2,
            ridge_per_leg: 0.01,
            fit_heading_offset: true,
            min_grid_concentration: 0.3,
        }
    }
}

impl CalibrationConfig {
    /// Checks the values a config file could get wrong; the error names the field (under
    /// `calibration`) and the value.
    pub fn validate(&self) -> Result<(), wipdr_core::ConfigError> {
        if !(self.min_leg_length.is_finite() && self.min_leg_length >= 0.0) {
            return Err(wipdr_core::ConfigError::new(
                "min_leg_length",
                format!("must be finite and >= 0, got {}", self.min_leg_length),
            ));
        }
        if !(self.ridge_per_leg.is_finite() && self.ridge_per_leg >= 0.0) {
            return Err(wipdr_core::ConfigError::new(
                "ridge_per_leg",
                format!("must be finite and >= 0, got {}", self.ridge_per_leg),
            ));
        }
        let g = self.min_grid_concentration;
        if !(g.is_finite() && (0.0..=1.0).contains(&g)) {
            return Err(wipdr_core::ConfigError::new(
                "min_grid_concentration",
                format!("must be in [0, 1], got {g}"),
            ));
        }
        Ok(())
    }
}

/// One walk's steps and waypoints, the unit calibration and scoring work on.
#[derive(Debug, Clone, Copy)]
pub struct WalkSteps<'a> {
    /// Steps from [`crate::Pdr::run_detailed`].
    pub steps: &'a [StepDetail],
    /// The walk's waypoints, sorted by time.
    pub waypoints: &'a [Waypoint],
}

/// A leg: two consecutive waypoints and the index range of the steps between them.
#[derive(Debug, Clone, PartialEq)]
pub struct Leg {
    /// Start waypoint.
    pub start: Waypoint,
    /// End waypoint.
    pub end: Waypoint,
    /// Steps with `start.t < t <= end.t`.
    pub steps: std::ops::Range<usize>,
}

impl Leg {
    /// The leg's displacement, m.
    pub fn displacement(&self) -> Vector2 {
        self.end.position - self.start.position
    }
}

/// The legs of a walk.
pub fn legs(steps: &[StepDetail], waypoints: &[Waypoint]) -> Vec<Leg> {
    waypoints
        .windows(2)
        .filter(|w| w[1].t > w[0].t)
        .map(|w| {
            let a = steps.partition_point(|s| s.event.t <= w[0].t);
            let b = steps.partition_point(|s| s.event.t <= w[1].t);
            Leg {
                start: w[0],
                end: w[1],
                steps: a..b,
            }
        })
        .collect()
}

fn usable(leg: &Leg, cfg: &CalibrationConfig) -> bool {
    leg.displacement().norm() >= cfg.min_leg_length && leg.steps.len() >= cfg.min_leg_steps
}

/// Fits the coefficients of `model` on the legs of `walks` by least squares (ridge towards
/// the model's current coefficients). Returns the model unchanged (and logs) when there is
/// nothing to fit on or the system is singular.
pub fn fit_step_length(
    model: StepLengthConfig,
    walks: &[WalkSteps<'_>],
    cfg: &CalibrationConfig,
) -> StepLengthConfig {
    let prior = model.model().coefficients();
    let mut rows = Vec::new();
    let mut y = Vec::new();
    for w in walks {
        for leg in legs(w.steps, w.waypoints) {
            if !usable(&leg, cfg) {
                continue;
            }
            let d = leg.displacement();
            let mut sx = vec![0.0; prior.len()];
            let mut sy = vec![0.0; prior.len()];
            let mut sl = vec![0.0; prior.len()];
            let mut ok = true;
            for s in &w.steps[leg.steps.clone()] {
                let phi = model.model().regressors(&s.features);
                let h = match s.headings.get(cfg.heading_source) {
                    Some(h) => h,
                    None => s.event.heading,
                };
                let (sin, cos) = h.sin_cos();
                for (j, p) in phi.iter().enumerate() {
                    sx[j] += p * sin;
                    sy[j] += p * cos;
                    sl[j] += p;
                }
                ok &= phi.iter().all(|p| p.is_finite());
            }
            if !ok {
                continue;
            }
            match cfg.objective {
                FitObjective::Displacement => {
                    rows.push(sx);
                    y.push(d.x);
                    rows.push(sy);
                    y.push(d.y);
                }
                FitObjective::Length => {
                    rows.push(sl);
                    y.push(d.norm());
                }
            }
        }
    }
    let n_legs = match cfg.objective {
        FitObjective::Displacement => rows.len() / 2,
        FitObjective::Length => rows.len(),
    };
    let mut out = model;
    match least_squares(&rows, &y, &prior, cfg.ridge_per_leg * n_legs as f64) {
        Some(theta) => out.model_mut().set_coefficients(&theta),
        None => tracing::warn!(
            legs = n_legs,
            model = model.name(),
            "step-length fit failed: model unchanged"
        ),
    }
    out
}

/// The floor's heading offset (rad) to add to `source`'s headings: the length-weighted
/// circular mean over legs of (leg direction − direction of the PDR displacement), with the
/// step lengths of `model`. `None` without usable legs.
pub fn fit_heading_offset(
    model: &StepLengthConfig,
    source: HeadingSource,
    walks: &[WalkSteps<'_>],
    cfg: &CalibrationConfig,
) -> Option<f64> {
    let (mut s, mut c) = (0.0, 0.0);
    for w in walks {
        for leg in legs(w.steps, w.waypoints) {
            if !usable(&leg, cfg) {
                continue;
            }
            let pdr = leg_displacement(&w.steps[leg.steps.clone()], model, source);
            if pdr.norm() < 1e-6 {
                continue;
            }
            let d = leg.displacement();
            let e = diff(heading_of(d), heading_of(pdr));
            let weight = d.norm();
            s += weight * e.sin();
            c += weight * e.cos();
        }
    }
    (s.abs() > 1e-12 || c.abs() > 1e-12).then(|| s.atan2(c))
}

/// The grid orientation (rad) of the walks' waypoint legs and its concentration in `[0, 1]`
/// ([`crate::snap::grid_orientation`]); `None` without legs.
pub fn fit_grid_orientation(walks: &[WalkSteps<'_>]) -> Option<(f64, f64)> {
    crate::snap::grid_orientation(walks.iter().flat_map(|w| {
        w.waypoints.windows(2).map(|p| {
            (
                p[1].position.x - p[0].position.x,
                p[1].position.y - p[0].position.y,
            )
        })
    }))
}

/// Heading snapping calibrated on the training walks: `snap` with the legs' grid orientation
/// when it is on and the legs' concentration reaches `cfg.min_grid_concentration`, else
/// turned off. Returns it with the legs' grid fit, `(orientation rad, concentration)`
/// ([`fit_grid_orientation`]; `None` without legs or when `snap` is off).
pub fn fit_heading_snap(
    snap: &crate::snap::HeadingSnapConfig,
    walks: &[WalkSteps<'_>],
    cfg: &CalibrationConfig,
) -> (crate::snap::HeadingSnapConfig, Option<(f64, f64)>) {
    let mut out = *snap;
    if !snap.enabled {
        return (out, None);
    }
    let fit = fit_grid_orientation(walks);
    match fit {
        Some((orientation, r)) if r >= cfg.min_grid_concentration => {
            tracing::info!(
                orientation_deg = orientation.to_degrees(),
                concentration = r,
                "heading snap: grid orientation learned"
            );
            out.orientation_rad = orientation;
        }
        _ => {
            tracing::info!(
                concentration = fit.map(|f| f.1),
                "heading snap off: the training legs follow no grid"
            );
            out.enabled = false;
        }
    }
    (out, fit)
}

/// The calibration of a PDR config on steps already run under `base` (the training walks'
/// waypoint legs are training data): the step-length coefficients fitted on the legs, then
/// (when `cal.fit_heading_offset`) the heading offset of `base.heading.source`, added to
/// `base`'s, and (when heading snapping is on) the grid orientation of the legs, snapping
/// turned off where they follow no grid ([`fit_heading_snap`]). Returns `base` with the fitted
/// values (unchanged where there is nothing to fit on) and the legs' grid fit,
/// `(orientation rad, concentration)` (`None` when snapping is off in `base` or there are no
/// legs).
pub fn calibrate_config(
    base: &crate::PdrConfig,
    cal: &CalibrationConfig,
    walks: &[WalkSteps<'_>],
) -> (crate::PdrConfig, Option<(f64, f64)>) {
    let mut out = *base;
    out.step_length = fit_step_length(base.step_length, walks, cal);
    if cal.fit_heading_offset
        && let Some(off) = fit_heading_offset(&out.step_length, base.heading.source, walks, cal)
    {
        out.heading.map_offset_rad = base.heading.map_offset_rad + off;
    }
    let (snap, grid) = fit_heading_snap(&base.heading.snap, walks, cal);
    out.heading.snap = snap;
    (out, grid)
}

/// Length (m) of a step under `model` (clamped to `[min, max]` of the config it came from
/// is the caller's business; here only non-finite values become 0).
fn length_of(s: &StepDetail, model: &StepLengthConfig) -> f64 {
    let l = model.model().length(&s.features);
    if l.is_finite() { l.max(0.0) } else { 0.0 }
}

fn heading_from(s: &StepDetail, source: HeadingSource) -> f64 {
    s.headings.get(source).unwrap_or(s.event.heading)
}

/// The summed displacement of `steps` under `model` and `source`.
pub fn leg_displacement(
    steps: &[StepDetail],
    model: &StepLengthConfig,
    source: HeadingSource,
) -> Vector2 {
    steps
        .iter()
        .map(|s| step_displacement(length_of(s, model), heading_from(s, source)))
        .fold(Vector2::zeros(), |a, b| a + b)
}

/// Errors of one leg.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LegError {
    /// `(Σ l_i − |D|) / |D|`: relative error of the summed step lengths.
    pub length_rel: f64,
    /// Direction of the PDR displacement minus the leg's direction, rad, `(-pi, pi]`.
    pub heading: f64,
}

/// Leg errors of a walk under `model` and `source`, for usable legs.
pub fn leg_errors(
    w: &WalkSteps<'_>,
    model: &StepLengthConfig,
    source: HeadingSource,
    cfg: &CalibrationConfig,
) -> Vec<LegError> {
    legs(w.steps, w.waypoints)
        .into_iter()
        .filter(|l| usable(l, cfg))
        .map(|leg| {
            let steps = &w.steps[leg.steps.clone()];
            let d = leg.displacement();
            let sum: f64 = steps.iter().map(|s| length_of(s, model)).sum();
            let pdr = leg_displacement(steps, model, source);
            LegError {
                length_rel: (sum - d.norm()) / d.norm(),
                heading: diff(heading_of(pdr), heading_of(d)),
            }
        })
        .collect()
}

/// One scored waypoint of a PDR-only run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ScoredWaypoint {
    /// Waypoint time.
    pub t: TimestampMs,
    /// Truth.
    pub truth: Point2,
    /// Latest PDR position at the waypoint's time.
    pub estimate: Point2,
    /// Distance between them, m.
    pub error: f64,
}

/// PDR-only positions started at the true first waypoint: the position at a waypoint's
/// time is the first waypoint plus every step with `first.t < t <= waypoint.t`. Scored at
/// every later waypoint with time after `score_after` (the walk's first Wi-Fi scan in the
/// protocol). `lengths_headings` gives each step's `(t, length, heading)`.
pub fn dead_reckon_at_waypoints(
    lengths_headings: &[(TimestampMs, f64, f64)],
    waypoints: &[Waypoint],
    score_after: Option<TimestampMs>,
) -> Vec<ScoredWaypoint> {
    let Some(first) = waypoints.first() else {
        return Vec::new();
    };
    let mut pos = first.position;
    let mut i = lengths_headings.partition_point(|s| s.0 <= first.t);
    let mut out = Vec::new();
    for w in &waypoints[1..] {
        while i < lengths_headings.len() && lengths_headings[i].0 <= w.t {
            let (_, l, h) = lengths_headings[i];
            pos += step_displacement(l, h);
            i += 1;
        }
        if score_after.is_none_or(|a| w.t > a) {
            out.push(ScoredWaypoint {
                t: w.t,
                truth: w.position,
                estimate: pos,
                error: (pos - w.position).norm(),
            });
        }
    }
    out
}

/// `(t, length, heading)` of each step under `model` (clamped to `[min_len, max_len]`) and
/// `source` (with `offset` added).
pub fn track(
    steps: &[StepDetail],
    model: &StepLengthConfig,
    source: HeadingSource,
    offset: f64,
    min_len: f64,
    max_len: f64,
) -> Vec<(TimestampMs, f64, f64)> {
    steps
        .iter()
        .map(|s| {
            let l = length_of(s, model).max(min_len).min(max_len);
            (s.event.t, l, heading_from(s, source) + offset)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::length::{StepFeatures, Weinberg};
    use crate::pipeline::SourceHeadings;
    use wipdr_core::{MotionState, StepEvent};

    fn step(t: i64, amp: f64, heading: f64) -> StepDetail {
        StepDetail {
            event: StepEvent {
                t,
                length: 0.0,
                heading,
                heading_change: 0.0,
                period_s: 0.5,
                motion: MotionState::default(),
                covariance: None,
            },
            features: StepFeatures {
                period_s: 0.5,
                mean_period_s: 0.5,
                acc_max: 9.81 + amp,
                acc_min: 9.81 - amp,
                peak_detrended: amp,
                acc_variance: 1.0,
                prev_acc_variance: 1.0,
                first: false,
                vertical_excursion: None,
            },
            headings: SourceHeadings {
                rotation_vector: Some(heading),
                ..Default::default()
            },
            sgyr: 0.0,
        }
    }

    fn wp(t: i64, x: f64, y: f64) -> Waypoint {
        Waypoint::new(t, Point2::new(x, y))
    }

    #[test]
    fn weinberg_k_and_offset_recovered() {
        // True K = 0.5 with a_max - a_min = 4 (length 0.5 * sqrt 2); true heading east but the
        // phone reads 0.1 rad less.
        let true_len = 0.5 * 4f64.powf(0.25);
        let steps: Vec<StepDetail> = (1..=40)
            .map(|i| step(i * 500, 2.0, std::f64::consts::FRAC_PI_2 - 0.1))
            .collect();
        let waypoints = vec![
            wp(0, 0.0, 0.0),
            wp(10_000, 20.0 * true_len, 0.0),
            wp(20_000, 40.0 * true_len, 0.0),
        ];
        let walks = [WalkSteps {
            steps: &steps,
            waypoints: &waypoints,
        }];
        let cfg = CalibrationConfig {
            ridge_per_leg: 0.0,
            objective: FitObjective::Length,
            ..Default::default()
        };
        let fitted = fit_step_length(
            StepLengthConfig::Weinberg(Weinberg::default()),
            &walks,
            &cfg,
        );
        let StepLengthConfig::Weinberg(w) = fitted else {
            panic!("model changed")
        };
        assert!((w.k - 0.5).abs() < 1e-9, "{}", w.k);
        let off = fit_heading_offset(&fitted, HeadingSource::RotationVector, &walks, &cfg).unwrap();
        assert!((off - 0.1).abs() < 1e-9, "{off}");
        let errs = leg_errors(&walks[0], &fitted, HeadingSource::RotationVector, &cfg);
        assert_eq!(errs.len(), 2);
        assert!(
            errs.iter()
                .all(|e| e.length_rel.abs() < 1e-9 && (e.heading + 0.1).abs() < 1e-9)
        );
    }

    #[test]
    fn dead_reckoning_scores_after_first_scan() {
        let tr = vec![
            (100, 1.0, 0.0),
            (200, 1.0, 0.0),
            (300, 1.0, std::f64::consts::FRAC_PI_2),
        ];
        let wps = vec![wp(50, 0.0, 0.0), wp(150, 0.0, 1.0), wp(400, 1.0, 2.0)];
        let s = dead_reckon_at_waypoints(&tr, &wps, Some(160));
        assert_eq!(s.len(), 1);
        assert!(s[0].error < 1e-12);
        assert_eq!(dead_reckon_at_waypoints(&tr, &wps, None).len(), 2);
        assert!(dead_reckon_at_waypoints(&tr, &[], None).is_empty());
    }

    #[test]
    fn empty_fit_keeps_model() {
        let m = StepLengthConfig::default();
        assert_eq!(fit_step_length(m, &[], &CalibrationConfig::default()), m);
        assert!(
            fit_heading_offset(&m, HeadingSource::Gyro, &[], &CalibrationConfig::default())
                .is_none()
        );
    }

    #[test]
    fn snapping_learns_the_legs_grid_or_turns_off() {
        let on = crate::snap::HeadingSnapConfig {
            enabled: true,
            ..Default::default()
        };
        let cal = CalibrationConfig::default();
        // An L-shaped walk on a grid turned by 30 deg.
        let a = 30f64.to_radians();
        let grid = vec![
            wp(0, 0.0, 0.0),
            wp(10, 10.0 * a.sin(), 10.0 * a.cos()),
            wp(
                20,
                10.0 * a.sin() + 5.0 * a.cos(),
                10.0 * a.cos() - 5.0 * a.sin(),
            ),
        ];
        let walks = [WalkSteps {
            steps: &[],
            waypoints: &grid,
        }];
        let (snap, r) = fit_heading_snap(&on, &walks, &cal);
        assert!(snap.enabled && (snap.orientation_rad - a).abs() < 1e-9);
        let (orientation, r) = r.unwrap();
        assert!((orientation - a).abs() < 1e-9 && (r - 1.0).abs() < 1e-9);
        // Legs 45 deg apart cancel: no grid, snapping off.
        let star = vec![wp(0, 0.0, 0.0), wp(10, 0.0, 5.0), wp(20, 5.0, 10.0)];
        let walks = [WalkSteps {
            steps: &[],
            waypoints: &star,
        }];
        let (snap, r) = fit_heading_snap(&on, &walks, &cal);
        assert!(!snap.enabled && r.unwrap().1 < cal.min_grid_concentration);
        // Off stays off, untouched.
        let off = crate::snap::HeadingSnapConfig::default();
        assert_eq!(fit_heading_snap(&off, &walks, &cal), (off, None));
    }

    #[test]
    fn bad_calibration_settings_name_their_field() {
        let c = CalibrationConfig {
            min_grid_concentration: 1.5,
            ..Default::default()
        };
        assert_eq!(c.validate().unwrap_err().path, "min_grid_concentration");
        let c = CalibrationConfig {
            min_leg_length: f64::NAN,
            ..Default::default()
        };
        assert_eq!(c.validate().unwrap_err().path, "min_leg_length");
        assert!(CalibrationConfig::default().validate().is_ok());
    }
}

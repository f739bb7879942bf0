//! Model-based radio-map extension: a log-distance path-loss model per access point, fitted
//! on the measured fingerprints, synthesises fingerprints in coverage gaps.
//!
//! **This is wipdr's own addition, not from the four papers.** The log-distance path-loss
//! model is textbook (e.g. T. S. Rappaport, *Wireless Communications: Principles and
//! Practice*, 2nd ed., 2002, §4.9.1); fitting it per AP from fingerprints and predicting RSS
//! where no survey was taken is a classic way to extend a radio map.
//!
//! ## Why
//!
//! A test walk that crosses an area no training walk covered has no reference point there:
//! a k-NN matcher answers some covered place, possibly tens of metres away. Predicting what
//! the APs would read in the gap gives the matcher something to match there.
//!
//! ## The model
//!
//! AP `j` at position `q` with RSS `p0` at 1 m and path-loss exponent `n` reads, at `p`,
//!
//! ```text
//! rss(p) = p0 - 10 n log10(max(|p - q|, 1 m))        (dBm)
//! ```
//!
//! ([`ApModel::predict`]). Walls, bodies and multipath are not modelled: their effect shows
//! up as the fit's RMSE ([`ApModel::rmse_db`]).
//!
//! ## The fit ([`fit_ap_models`])
//!
//! Per AP, from the **measured** reference points ([`ReferencePoint::scans`] > 0;
//! interpolated or synthesised points have 0 and are never used) that heard it, by nonlinear
//! least squares over `(qx, qy, p0, n)`:
//!
//! 1. start `q` at the centroid of the [`PropagationConfig::init_strongest`] strongest
//!    readings weighted by `10^(rss/10)` (their power in mW), at the strongest reading's
//!    position, and at the centroid moved by [`PropagationConfig::start_offset_m`] along
//!    +-x and +-y (six starts; the lowest final cost wins: readings along one corridor leave
//!    the AP's side of it undetermined, and a start on their line is a saddle of the cost);
//! 2. given `q`, `p0` and `n` by linear least squares of `rss` on `-10 log10 d` (`n` clamped
//!    to [`PropagationConfig::exponent_range`]);
//! 3. Levenberg-Marquardt iterations ([`wipdr_core::fit`]: a damped 4x4 normal-equation solve, Marquardt's
//!    diagonal scaling), each step projected onto the bounds: `n` in `exponent_range`, `p0` in
//!    the valid RSSI range `[-120, 0]` dBm, `q` within
//!    [`PropagationConfig::max_ap_outside_m`] of the bounding box of the hearing points.
//!
//! Optionally ([`PropagationConfig::censored_weight`] > 0, off by default) the measured
//! points near the AP that did **not** hear it enter as censored observations: a residual
//! `w (detection_dbm - predicted)` whenever the model predicts them above
//! [`PropagationConfig::detection_dbm`]. On synthetic censored data this reduces the
//! exponent's bias; on ILC site2/F2-F3 it made the RSS predictions worse (see below), so it
//! is off.
//!
//! An AP gets no model (`None`) when fewer than [`PropagationConfig::min_samples`] measured
//! points heard it, when its hearing points span less than 1 m (the position cannot be
//! fitted), when the fit is not finite, or when its RMSE exceeds
//! [`PropagationConfig::max_rmse_db`]. Every returned model is finite. APs are fitted in
//! parallel (rayon).
//!
//! Known bias: an AP is only recorded where it was *heard*, so far from the AP only the
//! lucky strong readings survive; the fitted exponent tends to be too small (censoring). On
//! ILC site2/F2 (fold-0 training map, 468 points, 1890 APs) 1305 APs get a model, median
//! RMSE 3.9 dB, median exponent 2.18, and 414 sit at the lower exponent bound 1.5.
//!
//! ## How good the predictions are (ILC, `examples/propagation.rs`)
//!
//! Held-out measured points, APs with a trusted model: against the baseline "value at the
//! nearest kept point that heard the AP", the model is worse close to measurements (every
//! 5th point held out, site2/F2: 4.3 vs 3.2 dB mean absolute error) and about as good or
//! better 8-20 m from them (a 20 m band held out, site2/F2: 6.3 vs 7.8 dB at 8-14 m; site2/F3:
//! 5.9 vs 5.9 dB): the regime of coverage gaps. The model over-predicts **which** APs are
//! heard: at -90 dBm it predicts ~2.5x as many trusted APs as a scan hears (precision
//! ~0.35); [`PropagationConfig::max_aps`] keeps only the strongest.
//!
//! ## Where a model is trusted, and what [`extend_radio_map`] adds
//!
//! A model is trusted only within [`PropagationConfig::max_extrapolation_m`] of the measured
//! points that heard its AP, so an AP heard only on one side of the floor is not extrapolated
//! across it. On the square lattice `cell_m * (i, j)` covering the measured points' bounding
//! box plus [`PropagationConfig::margin_m`], a lattice point becomes a new reference point
//! when
//!
//! - the caller's `allowed(p)` is true (pass the floor plan's walkability),
//! - no measured point lies within [`PropagationConfig::min_gap_m`] (only gaps are filled),
//! - at least [`PropagationConfig::min_aps`] APs are trusted there and predicted at or above
//!   [`PropagationConfig::min_predicted_dbm`]; those APs (the strongest
//!   [`PropagationConfig::max_aps`] of them if set), and only those, are heard at the point,
//!   with the predicted RSS (clamped to at most 0 dBm).
//!
//! Synthesised points are appended **at the end** of [`RadioMap::points`], in lattice order
//! (by `i`, then `j`): callers tell them apart by index (>= the map's length before the call)
//! or by `scans == 0`. Like interpolated points ([`crate::interpolate`]), each heard entry has
//! sample count 1; its spread is the model's fit RMSE. Floor, building and height come from
//! the nearest measured point.
//!
//! ```
//! use wipdr_core::Point2;
//! use wipdr_fingerprint::propagation::{ApModel, PropagationConfig, extend_radio_map, fit_ap_models};
//! use wipdr_fingerprint::{ApVocabulary, RadioMap, RadioMapConfig, ReferencePoint};
//!
//! // Three APs; reference points on two patches 0..=12 m and 36..=48 m along x (a gap between).
//! let truth = [
//!     ApModel { position: Point2::new(5.0, 3.0), p0_dbm: -35.0, exponent: 2.5, rmse_db: 0.0, samples: 0 },
//!     ApModel { position: Point2::new(40.0, 8.0), p0_dbm: -40.0, exponent: 2.0, rmse_db: 0.0, samples: 0 },
//!     ApModel { position: Point2::new(24.0, 0.0), p0_dbm: -38.0, exponent: 2.2, rmse_db: 0.0, samples: 0 },
//! ];
//! let names = ["a", "b", "c"].iter().map(|s| s.to_string());
//! let mut map = RadioMap::new(ApVocabulary::from_names(names), RadioMapConfig::default());
//! for x in (0..=12).chain(36..=48).step_by(3) {
//!     for y in [0.0, 4.0, 8.0] {
//!         let p = Point2::new(x as f64, y);
//!         let rss: Vec<Option<f32>> = truth.iter().map(|m| Some(m.predict(p) as f32)).collect();
//!         let point = ReferencePoint { position: p, z: None, floor: Some(0), building: None, scans: 1 };
//!         map.push_point(point, &rss, None).unwrap();
//!     }
//! }
//! let cfg = PropagationConfig { min_aps: 3, max_extrapolation_m: 30.0, ..Default::default() };
//! let models = fit_ap_models(&map, &cfg).unwrap();
//! let a = models[0].as_ref().unwrap();
//! assert!((a.position - truth[0].position).norm() < 1.0);
//!
//! let before = map.len();
//! let report = extend_radio_map(&mut map, &models, &cfg, |p| p.y >= 0.0 && p.y <= 8.0).unwrap();
//! assert!(report.points_added > 0);
//! // A synthesised point in the gap (x = 24 m) reads what the model says.
//! let i = (before..map.len()).find(|&i| map.point(i).position == Point2::new(24.0, 3.0)).unwrap();
//! assert_eq!(map.point(i).scans, 0);
//! for (j, m) in truth.iter().enumerate() {
//!     let got = f64::from(map.rss(i, j).unwrap());
//!     assert!((got - m.predict(Point2::new(24.0, 3.0))).abs() < 0.5);
//! }
//! ```

use crate::FingerprintError;
use crate::radio_map::{MAX_VALID_RSSI_DBM, MIN_VALID_RSSI_DBM, RadioMap, ReferencePoint};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use wipdr_core::Point2;
use wipdr_core::fit::{self, BoxBounds, LmConfig};

mod ap_fit;
mod extend;
#[cfg(test)]
mod tests;

pub use ap_fit::{FitReport, fit_ap_models, fit_ap_models_with_report};
pub use extend::{PropagationReport, extend_radio_map};

/// Distances below this count as this in the model (the reference distance of `p0`), metres.
pub const REFERENCE_DISTANCE_M: f64 = 1.0;

/// Hearing points spanning less than this (bounding-box diagonal) give no model: the AP's
/// position cannot be fitted, metres.
pub const MIN_HEARING_SPAN_M: f64 = 1.0;

/// A fitted log-distance path-loss model of one AP.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ApModel {
    /// Fitted AP position in the floor frame, metres.
    pub position: Point2,
    /// RSS at the reference distance of 1 m, dBm.
    pub p0_dbm: f64,
    /// Path-loss exponent `n` (2 in free space).
    pub exponent: f64,
    /// Root-mean-square residual of the fit over its samples, dB.
    pub rmse_db: f64,
    /// Number of measured reference points the fit used (those that heard the AP).
    pub samples: usize,
}

impl ApModel {
    /// Predicted RSS at `p`: `p0 - 10 n log10(max(|p - q|, 1 m))`, dBm.
    pub fn predict(&self, p: Point2) -> f64 {
        let d = (p - self.position).norm().max(REFERENCE_DISTANCE_M);
        self.p0_dbm - 10.0 * self.exponent * d.log10()
    }

    fn is_finite(&self) -> bool {
        self.position.x.is_finite()
            && self.position.y.is_finite()
            && self.p0_dbm.is_finite()
            && self.exponent.is_finite()
            && self.rmse_db.is_finite()
    }
}

/// Settings of the path-loss fit and of the radio-map extension.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PropagationConfig {
    /// Minimum number of measured reference points that heard an AP for it to get a model
    /// (>= 4: the model has four parameters).
    pub min_samples: usize,
    /// Bounds `[low, high]` of the path-loss exponent (0 < low <= high).
    pub exponent_range: [f64; 2],
    /// Models whose fit RMSE exceeds this are dropped, dB.
    pub max_rmse_db: f64,
    /// A model is trusted only within this distance of the measured points that heard its
    /// AP, metres.
    pub max_extrapolation_m: f64,
    /// The fitted AP position stays within this distance of the bounding box of the points
    /// that heard it, metres.
    pub max_ap_outside_m: f64,
    /// The number of strongest readings whose power-weighted centroid starts the fit.
    pub init_strongest: usize,
    /// The fit also starts this far from the centroid, in each of the four axis directions
    /// (walks run along corridors: a start on the line of the readings sits on a saddle of
    /// the cost and cannot leave it), metres; 0 repeats the centroid.
    pub start_offset_m: f64,
    /// Weight of the non-detections in the fit (0 = off): a measured point within
    /// `max_extrapolation_m` of the AP's hearing points' bounding box that did **not** hear
    /// the AP adds the residual `censored_weight * (detection_dbm - predicted)` when the
    /// prediction is above `detection_dbm` (a censored observation, as in Tobit regression).
    pub censored_weight: f64,
    /// The RSS below which an AP is taken as not detectable, for `censored_weight`, dBm.
    pub detection_dbm: f64,
    /// Maximum Levenberg-Marquardt iterations per start.
    pub max_iterations: usize,
    /// Lattice spacing of synthesised points, metres.
    pub cell_m: f64,
    /// A synthesised point lies at least this far from every measured point, metres.
    pub min_gap_m: f64,
    /// How far beyond the measured points' bounding box the lattice reaches, metres.
    pub margin_m: f64,
    /// An AP is heard at a synthesised point only if predicted at or above this, dBm.
    pub min_predicted_dbm: f64,
    /// A synthesised point needs at least this many heard APs.
    pub min_aps: usize,
    /// Keep at most this many APs (the strongest predicted) at a synthesised point; `None`
    /// keeps all. The model predicts every trusted AP above `min_predicted_dbm` as heard,
    /// far more than a real scan hears (on ILC site2/F2, ~300 vs a median of 120): a cap
    /// near the measured points' typical heard count keeps synthesised fingerprints
    /// comparable with real ones under set-based distances.
    pub max_aps: Option<usize>,
    /// Refuse a lattice of more points than this (memory guard): an error, not a silent cut.
    pub max_points: usize,
}

impl Default for PropagationConfig {
    fn default() -> Self {
        Self {
            min_samples: 8,
            exponent_range: [1.5, 5.0],
            max_rmse_db: 8.0,
            max_extrapolation_m: 20.0,
            max_ap_outside_m: 20.0,
            init_strongest: 5,
            start_offset_m: 3.0,
            censored_weight: 0.0,
            detection_dbm: -90.0,
            max_iterations: 50,
            cell_m: 3.0,
            min_gap_m: 8.0,
            margin_m: 20.0,
            min_predicted_dbm: -90.0,
            min_aps: 4,
            max_aps: None,
            max_points: 200_000,
        }
    }
}

fn invalid(path: impl Into<String>, reason: String) -> FingerprintError {
    FingerprintError::InvalidConfig(wipdr_core::ConfigError::new(path, reason))
}

fn positive(name: &str, v: f64) -> Result<(), FingerprintError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(invalid(
            format!("propagation.{name}"),
            format!("must be positive, got {v}"),
        ))
    }
}

fn non_negative(name: &str, v: f64) -> Result<(), FingerprintError> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(invalid(
            format!("propagation.{name}"),
            format!("must be finite and >= 0, got {v}"),
        ))
    }
}

impl PropagationConfig {
    /// Checks the values; the error names the offending field.
    pub fn validate(&self) -> Result<(), FingerprintError> {
        if self.min_samples < 4 {
            return Err(invalid(
                "propagation.min_samples",
                format!(
                    "must be >= 4 (four model parameters), got {}",
                    self.min_samples
                ),
            ));
        }
        let [lo, hi] = self.exponent_range;
        if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && lo <= hi) {
            return Err(invalid(
                "propagation.exponent_range",
                format!("must be finite with 0 < low <= high, got [{lo}, {hi}]"),
            ));
        }
        positive("max_rmse_db", self.max_rmse_db)?;
        positive("max_extrapolation_m", self.max_extrapolation_m)?;
        non_negative("max_ap_outside_m", self.max_ap_outside_m)?;
        if self.init_strongest == 0 {
            return Err(invalid("propagation.init_strongest", "must be >= 1".into()));
        }
        non_negative("start_offset_m", self.start_offset_m)?;
        non_negative("censored_weight", self.censored_weight)?;
        if !(self.detection_dbm >= MIN_VALID_RSSI_DBM && self.detection_dbm <= MAX_VALID_RSSI_DBM) {
            return Err(invalid(
                "propagation.detection_dbm",
                format!(
                    "must lie in [{MIN_VALID_RSSI_DBM}, \
                 {MAX_VALID_RSSI_DBM}] dBm, got {}",
                    self.detection_dbm
                ),
            ));
        }
        if self.max_iterations == 0 {
            return Err(invalid("propagation.max_iterations", "must be >= 1".into()));
        }
        positive("cell_m", self.cell_m)?;
        non_negative("min_gap_m", self.min_gap_m)?;
        non_negative("margin_m", self.margin_m)?;
        if !(self.min_predicted_dbm >= MIN_VALID_RSSI_DBM
            && self.min_predicted_dbm <= MAX_VALID_RSSI_DBM)
        {
            return Err(invalid(
                "propagation.min_predicted_dbm",
                format!(
                    "must lie in [{MIN_VALID_RSSI_DBM}, \
                 {MAX_VALID_RSSI_DBM}] dBm, got {}",
                    self.min_predicted_dbm
                ),
            ));
        }
        if self.min_aps == 0 {
            return Err(invalid("propagation.min_aps", "must be >= 1".into()));
        }
        if let Some(k) = self.max_aps
            && k < self.min_aps
        {
            return Err(invalid(
                "propagation.max_aps",
                format!("({k}) must be >= min_aps ({})", self.min_aps),
            ));
        }
        let ceiling = crate::interpolate::MAX_SPATIAL_POINTS_CEILING;
        if !(1..=ceiling).contains(&self.max_points) {
            return Err(invalid(
                "propagation.max_points",
                format!("must be in 1..={ceiling}, got {}", self.max_points),
            ));
        }
        Ok(())
    }
}

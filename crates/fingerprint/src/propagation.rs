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
//! let i = (before..map.len()).find(|&i| map.points[i].position == Point2::new(24.0, 3.0)).unwrap();
//! assert_eq!(map.points[i].scans, 0);
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

fn invalid(msg: String) -> FingerprintError {
    FingerprintError::InvalidConfig(msg)
}

fn positive(name: &str, v: f64) -> Result<(), FingerprintError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(invalid(format!(
            "propagation.{name} must be positive, got {v}"
        )))
    }
}

fn non_negative(name: &str, v: f64) -> Result<(), FingerprintError> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(invalid(format!(
            "propagation.{name} must be finite and >= 0, got {v}"
        )))
    }
}

impl PropagationConfig {
    /// Checks the values; the error names the offending field.
    pub fn validate(&self) -> Result<(), FingerprintError> {
        if self.min_samples < 4 {
            return Err(invalid(format!(
                "propagation.min_samples must be >= 4 (four model parameters), got {}",
                self.min_samples
            )));
        }
        let [lo, hi] = self.exponent_range;
        if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && lo <= hi) {
            return Err(invalid(format!(
                "propagation.exponent_range must be finite with 0 < low <= high, got [{lo}, {hi}]"
            )));
        }
        positive("max_rmse_db", self.max_rmse_db)?;
        positive("max_extrapolation_m", self.max_extrapolation_m)?;
        non_negative("max_ap_outside_m", self.max_ap_outside_m)?;
        if self.init_strongest == 0 {
            return Err(invalid("propagation.init_strongest must be >= 1".into()));
        }
        non_negative("start_offset_m", self.start_offset_m)?;
        non_negative("censored_weight", self.censored_weight)?;
        if !(self.detection_dbm >= MIN_VALID_RSSI_DBM && self.detection_dbm <= MAX_VALID_RSSI_DBM) {
            return Err(invalid(format!(
                "propagation.detection_dbm must lie in [{MIN_VALID_RSSI_DBM}, \
                 {MAX_VALID_RSSI_DBM}] dBm, got {}",
                self.detection_dbm
            )));
        }
        if self.max_iterations == 0 {
            return Err(invalid("propagation.max_iterations must be >= 1".into()));
        }
        positive("cell_m", self.cell_m)?;
        non_negative("min_gap_m", self.min_gap_m)?;
        non_negative("margin_m", self.margin_m)?;
        if !(self.min_predicted_dbm >= MIN_VALID_RSSI_DBM
            && self.min_predicted_dbm <= MAX_VALID_RSSI_DBM)
        {
            return Err(invalid(format!(
                "propagation.min_predicted_dbm must lie in [{MIN_VALID_RSSI_DBM}, \
                 {MAX_VALID_RSSI_DBM}] dBm, got {}",
                self.min_predicted_dbm
            )));
        }
        if self.min_aps == 0 {
            return Err(invalid("propagation.min_aps must be >= 1".into()));
        }
        if let Some(k) = self.max_aps
            && k < self.min_aps
        {
            return Err(invalid(format!(
                "propagation.max_aps ({k}) must be >= min_aps ({})",
                self.min_aps
            )));
        }
        if self.max_points == 0 {
            return Err(invalid("propagation.max_points must be >= 1".into()));
        }
        Ok(())
    }
}

/// What the fit kept and dropped, per reason.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub struct FitReport {
    /// AP columns of the map.
    pub aps: usize,
    /// Models kept.
    pub fitted: usize,
    /// APs heard at fewer than `min_samples` measured points (including never).
    pub too_few_samples: usize,
    /// APs whose hearing points span less than [`MIN_HEARING_SPAN_M`].
    pub degenerate: usize,
    /// Fits that were not finite.
    pub not_finite: usize,
    /// Fits with an RMSE over `max_rmse_db`.
    pub rmse_too_high: usize,
}

/// Fits one model per AP column of `map` (see the module doc); `None` where an AP gets no
/// model. Only measured reference points (`scans > 0`) are used.
pub fn fit_ap_models(
    map: &RadioMap,
    cfg: &PropagationConfig,
) -> Result<Vec<Option<ApModel>>, FingerprintError> {
    fit_ap_models_with_report(map, cfg).map(|(models, _)| models)
}

/// [`fit_ap_models`] with the counts of what was dropped and why.
pub fn fit_ap_models_with_report(
    map: &RadioMap,
    cfg: &PropagationConfig,
) -> Result<(Vec<Option<ApModel>>, FitReport), FingerprintError> {
    cfg.validate()?;
    let samples = samples_per_ap(map);
    let measured: Vec<usize> = (0..map.len())
        .filter(|&i| {
            let p = map.points[i].position;
            map.points[i].scans > 0 && p.x.is_finite() && p.y.is_finite()
        })
        .collect();
    enum Outcome {
        Fitted(ApModel),
        TooFew,
        Degenerate,
        NotFinite,
        RmseTooHigh,
    }
    let outcomes: Vec<Outcome> = samples
        .par_iter()
        .enumerate()
        .map(|(j, s)| {
            if s.len() < cfg.min_samples {
                return Outcome::TooFew;
            }
            let (lo, hi) = bbox(s.iter().map(|x| x.0));
            let span = (hi - lo).norm();
            if span.is_nan() || span < MIN_HEARING_SPAN_M {
                return Outcome::Degenerate;
            }
            let silent = if cfg.censored_weight > 0.0 {
                let r = cfg.max_extrapolation_m;
                measured
                    .iter()
                    .filter(|&&i| map.rss(i, j).is_none())
                    .map(|&i| map.points[i].position)
                    .filter(|p| {
                        p.x >= lo.x - r && p.x <= hi.x + r && p.y >= lo.y - r && p.y <= hi.y + r
                    })
                    .collect()
            } else {
                Vec::new()
            };
            let data = FitData {
                heard: s,
                silent: &silent,
                weight: cfg.censored_weight,
                detection_dbm: cfg.detection_dbm,
            };
            match fit_one(&data, cfg) {
                None => Outcome::NotFinite,
                Some(m) if !m.is_finite() => Outcome::NotFinite,
                Some(m) if m.rmse_db > cfg.max_rmse_db => Outcome::RmseTooHigh,
                Some(m) => Outcome::Fitted(m),
            }
        })
        .collect();
    let mut report = FitReport {
        aps: map.n_aps(),
        ..Default::default()
    };
    let models = outcomes
        .into_iter()
        .map(|o| match o {
            Outcome::Fitted(m) => {
                report.fitted += 1;
                Some(m)
            }
            Outcome::TooFew => {
                report.too_few_samples += 1;
                None
            }
            Outcome::Degenerate => {
                report.degenerate += 1;
                None
            }
            Outcome::NotFinite => {
                report.not_finite += 1;
                None
            }
            Outcome::RmseTooHigh => {
                report.rmse_too_high += 1;
                None
            }
        })
        .collect();
    tracing::debug!(?report, "path-loss fit");
    Ok((models, report))
}

/// Per AP column, `(position, dBm)` of the measured points that heard it (finite only).
fn samples_per_ap(map: &RadioMap) -> Vec<Vec<(Point2, f64)>> {
    let mut out = vec![Vec::new(); map.n_aps()];
    for (i, point) in map.points.iter().enumerate() {
        let p = point.position;
        if point.scans == 0 || !(p.x.is_finite() && p.y.is_finite()) {
            continue;
        }
        for (j, v) in map.heard(i) {
            let v = f64::from(v);
            if v.is_finite() {
                out[j].push((p, v));
            }
        }
    }
    out
}

/// Lower-left and upper-right corners of the points (NaN-free input assumed).
fn bbox(points: impl Iterator<Item = Point2>) -> (Point2, Point2) {
    let mut lo = Point2::new(f64::INFINITY, f64::INFINITY);
    let mut hi = Point2::new(f64::NEG_INFINITY, f64::NEG_INFINITY);
    for p in points {
        lo = Point2::new(lo.x.min(p.x), lo.y.min(p.y));
        hi = Point2::new(hi.x.max(p.x), hi.y.max(p.y));
    }
    (lo, hi)
}

/// Parameters `[qx, qy, p0, n]` and the box they are projected onto.
type Bounds = BoxBounds<4>;

fn log_distance(q: Point2, p: Point2) -> (f64, f64) {
    let d = (p - q).norm().max(REFERENCE_DISTANCE_M);
    (d, d.log10())
}

/// What one AP's fit sees: the readings, and the non-detections (censored below
/// `detection_dbm`, weighted by `weight`).
struct FitData<'a> {
    heard: &'a [(Point2, f64)],
    silent: &'a [Point2],
    weight: f64,
    detection_dbm: f64,
}

impl FitData<'_> {
    /// Every active term as `(position, target, weight)`: readings always, a non-detection
    /// when predicted above the detection level.
    fn terms<'s>(&'s self, t: &'s [f64; 4]) -> impl Iterator<Item = (Point2, f64, f64)> + 's {
        let q = Point2::new(t[0], t[1]);
        let heard = self.heard.iter().map(|&(p, y)| (p, y, 1.0));
        let silent = self
            .silent
            .iter()
            .filter(move |&&p| t[2] - 10.0 * t[3] * log_distance(q, p).1 > self.detection_dbm)
            .map(|&p| (p, self.detection_dbm, self.weight));
        heard.chain(silent)
    }

    /// Calls `visit(r, J)` for every active term: the weighted residual
    /// `w (y - (p0 - 10 n log10 d))` and the derivatives of the weighted prediction.
    fn residuals(&self, t: &[f64; 4], visit: &mut dyn FnMut(f64, &[f64; 4])) {
        let ln10 = std::f64::consts::LN_10;
        let q = Point2::new(t[0], t[1]);
        for (p, y, w) in self.terms(t) {
            let raw = (p - q).norm();
            let (d, l) = log_distance(q, p);
            let r = y - (t[2] - 10.0 * t[3] * l);
            // d pred / d q = -10 n / ln 10 * (q - p) / d^2 (zero inside the reference distance).
            let (jx, jy) = if raw > REFERENCE_DISTANCE_M {
                let f = -10.0 * t[3] / (ln10 * d * d);
                (f * (q.x - p.x), f * (q.y - p.y))
            } else {
                (0.0, 0.0)
            };
            visit(w * r, &[w * jx, w * jy, w, -10.0 * w * l]);
        }
    }

    fn cost(&self, t: &[f64; 4]) -> f64 {
        let mut c = 0.0;
        self.residuals(t, &mut |r, _| c += r * r);
        c
    }

    /// Sum of squared residuals of the readings alone.
    fn heard_cost(&self, t: &[f64; 4]) -> f64 {
        FitData {
            heard: self.heard,
            silent: &[],
            weight: 0.0,
            detection_dbm: 0.0,
        }
        .cost(t)
    }
}

/// `p0` and `n` by linear least squares given the AP position (n clamped, p0 refitted).
fn linear_p0_n(samples: &[(Point2, f64)], q: Point2, b: &Bounds) -> (f64, f64) {
    let k = samples.len() as f64;
    let xs: Vec<f64> = samples
        .iter()
        .map(|&(p, _)| -10.0 * log_distance(q, p).1)
        .collect();
    let mx = xs.iter().sum::<f64>() / k;
    let my = samples.iter().map(|s| s.1).sum::<f64>() / k;
    let sxx: f64 = xs.iter().map(|x| (x - mx).powi(2)).sum();
    let sxy: f64 = xs
        .iter()
        .zip(samples)
        .map(|(x, s)| (x - mx) * (s.1 - my))
        .sum();
    let n = if sxx > 1e-9 {
        sxy / sxx
    } else {
        0.5 * (b.lo[3] + b.hi[3])
    };
    let n = if n.is_finite() { n } else { b.lo[3] };
    let n = n.clamp(b.lo[3], b.hi[3]);
    let p0 = (my - n * mx).clamp(b.lo[2], b.hi[2]);
    (p0, n)
}

/// Levenberg-Marquardt from `t`, projected onto the bounds; returns the parameters and cost.
fn levenberg_marquardt(
    data: &FitData<'_>,
    t: [f64; 4],
    b: &Bounds,
    max_iterations: usize,
) -> ([f64; 4], f64) {
    let cfg = LmConfig {
        max_iterations,
        ..LmConfig::default()
    };
    let out = fit::levenberg_marquardt(
        t,
        |t| b.project(t),
        &cfg,
        |t, visit| data.residuals(t, visit),
    );
    (out.params, out.cost)
}

fn fit_one(data: &FitData<'_>, cfg: &PropagationConfig) -> Option<ApModel> {
    let samples = data.heard;
    let (lo, hi) = bbox(samples.iter().map(|s| s.0));
    let out = cfg.max_ap_outside_m;
    let bounds = Bounds {
        lo: [
            lo.x - out,
            lo.y - out,
            MIN_VALID_RSSI_DBM,
            cfg.exponent_range[0],
        ],
        hi: [
            hi.x + out,
            hi.y + out,
            MAX_VALID_RSSI_DBM,
            cfg.exponent_range[1],
        ],
    };
    // Starts: the power-weighted centroid of the strongest readings, and the strongest one.
    let mut by_strength: Vec<&(Point2, f64)> = samples.iter().collect();
    by_strength.sort_by(|a, b| b.1.total_cmp(&a.1));
    let strongest = &by_strength[..cfg.init_strongest.min(by_strength.len())];
    let top = strongest[0].1;
    let (mut wx, mut wy, mut ws) = (0.0, 0.0, 0.0);
    for &&(p, v) in strongest {
        // Relative to the strongest reading: no underflow, weight 1 for the strongest.
        let w = 10f64.powf((v - top) / 10.0);
        wx += w * p.x;
        wy += w * p.y;
        ws += w;
    }
    let centroid = Point2::new(wx / ws, wy / ws);
    let o = cfg.start_offset_m;
    let starts = [
        centroid,
        strongest[0].0,
        centroid + wipdr_core::Vector2::new(o, 0.0),
        centroid + wipdr_core::Vector2::new(-o, 0.0),
        centroid + wipdr_core::Vector2::new(0.0, o),
        centroid + wipdr_core::Vector2::new(0.0, -o),
    ];
    let mut best: Option<([f64; 4], f64)> = None;
    for q in starts {
        if !(q.x.is_finite() && q.y.is_finite()) {
            continue;
        }
        let (p0, n) = linear_p0_n(samples, q, &bounds);
        let t0 = bounds.project([q.x, q.y, p0, n]);
        let (t, c) = levenberg_marquardt(data, t0, &bounds, cfg.max_iterations);
        if c.is_finite() && best.is_none_or(|(_, bc)| c < bc) {
            best = Some((t, c));
        }
    }
    let (t, _) = best?;
    let c = data.heard_cost(&t);
    let model = ApModel {
        position: Point2::new(t[0], t[1]),
        p0_dbm: t[2],
        exponent: t[3],
        rmse_db: (c / samples.len() as f64).sqrt(),
        samples: samples.len(),
    };
    model.is_finite().then_some(model)
}

/// What [`extend_radio_map`] looked at, skipped and added.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub struct PropagationReport {
    /// AP models given (`Some`).
    pub models_fitted: usize,
    /// AP columns without a model (`None`).
    pub models_dropped: usize,
    /// Lattice points in the measured points' bounding box plus the margin.
    pub lattice_points: usize,
    /// Lattice points where `allowed` was false.
    pub points_not_allowed: usize,
    /// Lattice points closer than `min_gap_m` to a measured point.
    pub points_too_close: usize,
    /// Lattice points with fewer than `min_aps` trusted APs predicted at or above
    /// `min_predicted_dbm`.
    pub points_skipped_few_aps: usize,
    /// Reference points appended.
    pub points_added: usize,
    /// Heard entries written into the appended points.
    pub entries_added: usize,
    /// Appended points whose heard APs were cut to `max_aps`.
    pub points_capped: usize,
}

/// Appends synthesised reference points in the coverage gaps of `map` (see the module doc)
/// and returns what it did. `models` has one entry per AP column (from [`fit_ap_models`]);
/// `allowed(p)` says where a point may go (e.g. the floor plan's walkability). New points
/// are appended at the end of `map.points`, so indices `>=` the length before the call are
/// the synthesised ones. A map without measured points is left as it is.
pub fn extend_radio_map(
    map: &mut RadioMap,
    models: &[Option<ApModel>],
    cfg: &PropagationConfig,
    allowed: impl Fn(Point2) -> bool + Sync,
) -> Result<PropagationReport, FingerprintError> {
    cfg.validate()?;
    let m = map.n_aps();
    if models.len() != m {
        return Err(FingerprintError::DimensionMismatch {
            expected: m,
            found: models.len(),
        });
    }
    if let Some(j) = models
        .iter()
        .position(|o| o.as_ref().is_some_and(|x| !x.is_finite()))
    {
        return Err(FingerprintError::InvalidInput(format!(
            "path-loss model of AP {} is not finite",
            map.vocabulary.name(j)
        )));
    }
    let mut report = PropagationReport {
        models_fitted: models.iter().filter(|o| o.is_some()).count(),
        models_dropped: models.iter().filter(|o| o.is_none()).count(),
        ..Default::default()
    };
    let measured: Vec<usize> = (0..map.len())
        .filter(|&i| {
            let p = map.points[i].position;
            map.points[i].scans > 0 && p.x.is_finite() && p.y.is_finite()
        })
        .collect();
    if measured.is_empty() {
        tracing::debug!("no measured reference point: nothing to extend");
        return Ok(report);
    }
    let (lo, hi) = bbox(measured.iter().map(|&i| map.points[i].position));
    let c = cfg.cell_m;
    let (i0, i1) = (
        ((lo.x - cfg.margin_m) / c).floor(),
        ((hi.x + cfg.margin_m) / c).ceil(),
    );
    let (j0, j1) = (
        ((lo.y - cfg.margin_m) / c).floor(),
        ((hi.y + cfg.margin_m) / c).ceil(),
    );
    let (nx, ny) = (i1 - i0 + 1.0, j1 - j0 + 1.0);
    if !(nx * ny).is_finite() || nx * ny > cfg.max_points as f64 {
        return Err(invalid(format!(
            "propagation: the lattice has {} points (cell {c} m), over \
             propagation.max_points = {}",
            nx * ny,
            cfg.max_points
        )));
    }
    let (i0, j0, nx, ny) = (i0 as i64, j0 as i64, nx as usize, ny as usize);
    report.lattice_points = nx * ny;
    let cell_position = |k: usize| {
        let (i, j) = ((k / ny) as i64 + i0, (k % ny) as i64 + j0);
        Point2::new(i as f64 * c, j as f64 * c)
    };
    // Nearest measured point of each lattice point, by buckets of side `bucket`.
    let positions: Vec<Point2> = measured.iter().map(|&i| map.points[i].position).collect();
    let grid = Buckets::new(&positions, cfg.min_gap_m.max(c));
    #[derive(Clone, Copy)]
    enum Cell {
        NotAllowed,
        TooClose,
        Candidate(usize), // the nearest measured point, index into `measured`
    }
    let cells: Vec<Cell> = (0..nx * ny)
        .into_par_iter()
        .map(|k| {
            let p = cell_position(k);
            if !allowed(p) {
                return Cell::NotAllowed;
            }
            match grid.nearest(&positions, p) {
                Some((_, d)) if d < cfg.min_gap_m => Cell::TooClose,
                Some((nearest, _)) => Cell::Candidate(nearest),
                None => Cell::Candidate(grid.nearest_brute(&positions, p)),
            }
        })
        .collect();
    // Per AP: the candidate cells within max_extrapolation_m of a hearing point, with the
    // prediction where it reaches min_predicted_dbm.
    let hearing = samples_per_ap(map);
    let r = cfg.max_extrapolation_m;
    let per_ap: Vec<Vec<(u32, f32)>> = models
        .par_iter()
        .zip(&hearing)
        .map(|(model, heard_at)| {
            let Some(model) = model else {
                return Vec::new();
            };
            let mut seen = vec![false; nx * ny];
            let mut out = Vec::new();
            for &(p, _) in heard_at {
                let ia = (((p.x - r) / c).ceil() as i64 - i0).max(0);
                let ib = (((p.x + r) / c).floor() as i64 - i0).min(nx as i64 - 1);
                let ja = (((p.y - r) / c).ceil() as i64 - j0).max(0);
                let jb = (((p.y + r) / c).floor() as i64 - j0).min(ny as i64 - 1);
                for i in ia..=ib {
                    for j in ja..=jb {
                        let k = i as usize * ny + j as usize;
                        if seen[k] || !matches!(cells[k], Cell::Candidate(_)) {
                            continue;
                        }
                        let q = cell_position(k);
                        if (q - p).norm() > r {
                            continue;
                        }
                        seen[k] = true;
                        let v = model.predict(q);
                        if v.is_finite() && v >= cfg.min_predicted_dbm {
                            out.push((k as u32, v.min(MAX_VALID_RSSI_DBM) as f32));
                        }
                    }
                }
            }
            out
        })
        .collect();
    // Gather per cell: (column, dBm).
    let mut heard_in: Vec<Vec<(usize, f32)>> = vec![Vec::new(); nx * ny];
    for (j, list) in per_ap.into_iter().enumerate() {
        for (k, v) in list {
            heard_in[k as usize].push((j, v));
        }
    }
    let mut mean = vec![None; m];
    let mut counts = vec![0u16; m];
    let mut spread = vec![0f32; m];
    for (k, cell) in cells.iter().enumerate() {
        let nearest = match *cell {
            Cell::NotAllowed => {
                report.points_not_allowed += 1;
                continue;
            }
            Cell::TooClose => {
                report.points_too_close += 1;
                continue;
            }
            Cell::Candidate(nearest) => nearest,
        };
        let heard = &mut heard_in[k];
        if heard.len() < cfg.min_aps {
            report.points_skipped_few_aps += 1;
            continue;
        }
        if let Some(cap) = cfg.max_aps
            && heard.len() > cap
        {
            // The strongest `cap`, ties by column.
            heard.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
            heard.truncate(cap);
            report.points_capped += 1;
        }
        mean.fill(None);
        counts.fill(0);
        spread.fill(0.0);
        for &(j, v) in heard.iter() {
            mean[j] = Some(v);
            counts[j] = 1;
            spread[j] = models[j].map_or(0.0, |x| x.rmse_db as f32);
        }
        let point = ReferencePoint {
            position: cell_position(k),
            scans: 0,
            ..map.points[measured[nearest]]
        };
        map.push_point(point, &mean, Some((&counts, &spread)))?;
        report.points_added += 1;
        report.entries_added += heard.len();
    }
    tracing::debug!(?report, "path-loss radio-map extension");
    Ok(report)
}

/// Square buckets of points, for nearest-point queries within a few buckets.
struct Buckets {
    side: f64,
    map: std::collections::HashMap<(i64, i64), Vec<usize>>,
}

impl Buckets {
    fn new(points: &[Point2], side: f64) -> Self {
        let mut map: std::collections::HashMap<(i64, i64), Vec<usize>> = Default::default();
        for (i, &p) in points.iter().enumerate() {
            map.entry(Self::key(side, p)).or_default().push(i);
        }
        Self { side, map }
    }

    fn key(side: f64, p: Point2) -> (i64, i64) {
        ((p.x / side).floor() as i64, (p.y / side).floor() as i64)
    }

    /// The nearest point among the 3x3 buckets around `p` (exact for distances < `side`),
    /// with its distance; `None` if those buckets are empty (then every point is >= `side`
    /// away).
    fn nearest(&self, points: &[Point2], p: Point2) -> Option<(usize, f64)> {
        let (bi, bj) = Self::key(self.side, p);
        let mut best: Option<(usize, f64)> = None;
        for di in -1..=1 {
            for dj in -1..=1 {
                for &k in self.map.get(&(bi + di, bj + dj)).into_iter().flatten() {
                    let d = (points[k] - p).norm();
                    if best.is_none_or(|(_, bd)| d < bd) {
                        best = Some((k, d));
                    }
                }
            }
        }
        // A point found farther than `side` may not be the nearest: fall back to brute force.
        match best {
            Some((_, d)) if d >= self.side => Some((self.nearest_brute(points, p), d)),
            b => b,
        }
    }

    fn nearest_brute(&self, points: &[Point2], p: Point2) -> usize {
        (0..points.len())
            .min_by(|&a, &b| (points[a] - p).norm().total_cmp(&(points[b] - p).norm()))
            .unwrap_or(0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::radio_map::{ApVocabulary, RadioMapConfig};
    use proptest::prelude::*;
    use rand::rngs::ChaCha8Rng;
    use rand::{RngExt, SeedableRng};

    fn model(x: f64, y: f64, p0: f64, n: f64) -> ApModel {
        ApModel {
            position: Point2::new(x, y),
            p0_dbm: p0,
            exponent: n,
            rmse_db: 0.0,
            samples: 0,
        }
    }

    fn empty_map(aps: usize) -> RadioMap {
        RadioMap::new(
            ApVocabulary::from_names((0..aps).map(|j| format!("ap{j}"))),
            RadioMapConfig::default(),
        )
    }

    fn point(p: Point2, scans: u32) -> ReferencePoint {
        ReferencePoint {
            position: p,
            z: Some(1.5),
            floor: Some(2),
            building: None,
            scans,
        }
    }

    /// A map with the APs' model RSS (plus `noise`) at `positions`, entries below -100 dBm
    /// not heard.
    fn synthetic_map(
        truth: &[ApModel],
        positions: &[Point2],
        mut noise: impl FnMut() -> f64,
    ) -> RadioMap {
        let mut map = empty_map(truth.len());
        for &p in positions {
            let rss: Vec<Option<f32>> = truth
                .iter()
                .map(|m| {
                    let v = m.predict(p) + noise();
                    (v >= -100.0).then_some(v.min(0.0) as f32)
                })
                .collect();
            map.push_point(point(p, 1), &rss, None).unwrap();
        }
        map
    }

    fn grid(
        xs: std::ops::RangeInclusive<i32>,
        ys: std::ops::RangeInclusive<i32>,
        step: usize,
    ) -> Vec<Point2> {
        let mut out = Vec::new();
        for x in xs.step_by(step) {
            for y in ys.clone().step_by(step) {
                out.push(Point2::new(f64::from(x), f64::from(y)));
            }
        }
        out
    }

    /// Standard normal by Box-Muller from a seeded generator.
    fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
        let u1: f64 = rng.random::<f64>().max(1e-300);
        let u2: f64 = rng.random::<f64>();
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }

    #[test]
    fn noise_free_fit_recovers_the_model() {
        let truth = [
            model(12.3, 7.1, -42.0, 2.7),
            model(-4.0, 18.0, -35.0, 2.0),
            model(25.0, 2.0, -50.0, 3.5),
        ];
        let map = synthetic_map(&truth, &grid(0..=30, 0..=21, 3), || 0.0);
        let cfg = PropagationConfig::default();
        let (models, report) = fit_ap_models_with_report(&map, &cfg).unwrap();
        assert_eq!(report.fitted, 3);
        for (j, (m, t)) in models.iter().zip(&truth).enumerate() {
            let m = m.unwrap();
            assert!((m.position - t.position).norm() < 0.01, "{m:?} vs {t:?}");
            assert!((m.p0_dbm - t.p0_dbm).abs() < 0.01, "{m:?} vs {t:?}");
            assert!((m.exponent - t.exponent).abs() < 0.001, "{m:?} vs {t:?}");
            assert!(m.rmse_db < 0.01);
            let heard = (0..map.len()).filter(|&i| map.rss(i, j).is_some()).count();
            assert_eq!(m.samples, heard);
        }
    }

    #[test]
    fn noisy_fit_is_close() {
        // 2 dB Gaussian noise on 88 readings. Expected errors (Cramer-Rao-like estimate
        // from the model's slope of ~1.2 dB/m at 10 m): position ~0.3 m, exponent ~0.07,
        // p0 ~0.7 dB; the tolerances below are about three times those.
        let truth = model(12.3, 7.1, -42.0, 2.7);
        for seed in 0..5 {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let map = synthetic_map(&[truth], &grid(0..=30, 0..=21, 3), || {
                2.0 * gaussian(&mut rng)
            });
            let m = fit_ap_models(&map, &PropagationConfig::default()).unwrap()[0].unwrap();
            assert!(
                (m.position - truth.position).norm() < 1.0,
                "seed {seed}: {m:?}"
            );
            assert!(
                (m.exponent - truth.exponent).abs() < 0.25,
                "seed {seed}: {m:?}"
            );
            assert!((m.p0_dbm - truth.p0_dbm).abs() < 2.5, "seed {seed}: {m:?}");
            assert!(m.rmse_db > 1.5 && m.rmse_db < 2.5, "seed {seed}: {m:?}");
        }
    }

    #[test]
    fn non_detections_reduce_the_censoring_bias() {
        // Readings exist only where the noisy RSS reached -85 dBm: far away only the lucky
        // high readings survive and the heard-only fit flattens the profile (n too low).
        // The censored fit also sees where the AP was not heard.
        let truth = model(15.0, 10.0, -40.0, 3.0);
        let positions = grid(0..=60, 0..=30, 3);
        let (mut err_plain, mut err_censored) = (0.0, 0.0);
        for seed in 0..5 {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let mut map = empty_map(1);
            for &p in &positions {
                let v = truth.predict(p) + 4.0 * gaussian(&mut rng);
                map.push_point(
                    point(p, 1),
                    &[(v >= -85.0).then_some(v.min(0.0) as f32)],
                    None,
                )
                .unwrap();
            }
            let plain = PropagationConfig {
                max_rmse_db: 50.0,
                ..Default::default()
            };
            let censored = PropagationConfig {
                censored_weight: 1.0,
                detection_dbm: -85.0,
                ..plain
            };
            let a = fit_ap_models(&map, &plain).unwrap()[0].unwrap();
            let b = fit_ap_models(&map, &censored).unwrap()[0].unwrap();
            assert!(b.is_finite());
            err_plain += (a.exponent - truth.exponent).abs();
            err_censored += (b.exponent - truth.exponent).abs();
        }
        assert!(
            err_censored < err_plain,
            "censored {err_censored} vs plain {err_plain}"
        );
    }

    #[test]
    fn too_few_samples_give_no_model() {
        let truth = [model(5.0, 5.0, -40.0, 2.0)];
        let positions = grid(0..=6, 0..=3, 3); // 3 x 2 = 6 points
        let map = synthetic_map(&truth, &positions, || 0.0);
        let (models, report) =
            fit_ap_models_with_report(&map, &PropagationConfig::default()).unwrap();
        assert_eq!(models, vec![None]);
        assert_eq!(report.too_few_samples, 1);
        // Enough with a lower threshold.
        let cfg = PropagationConfig {
            min_samples: 6,
            ..Default::default()
        };
        assert!(fit_ap_models(&map, &cfg).unwrap()[0].is_some());
    }

    #[test]
    fn readings_at_one_position_give_no_model() {
        let truth = [model(5.0, 5.0, -40.0, 2.0)];
        let positions = vec![Point2::new(1.0, 1.0); 12];
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let map = synthetic_map(&truth, &positions, || gaussian(&mut rng));
        let (models, report) =
            fit_ap_models_with_report(&map, &PropagationConfig::default()).unwrap();
        assert_eq!(models, vec![None]);
        assert_eq!(report.degenerate, 1);
    }

    #[test]
    fn collinear_points_fit_up_to_the_mirror_image() {
        // On the line y = 0 the AP at (10, +5) and its mirror (10, -5) read the same.
        let truth = [model(10.0, 5.0, -40.0, 2.5)];
        let positions: Vec<Point2> = (0..=20).map(|x| Point2::new(f64::from(x), 0.0)).collect();
        let map = synthetic_map(&truth, &positions, || 0.0);
        let m = fit_ap_models(&map, &PropagationConfig::default()).unwrap()[0].unwrap();
        assert!(m.is_finite());
        assert!((m.position.x - 10.0).abs() < 0.05, "{m:?}");
        assert!((m.position.y.abs() - 5.0).abs() < 0.05, "{m:?}");
        for x in 0..=20 {
            let p = Point2::new(f64::from(x), 0.0);
            assert!((m.predict(p) - truth[0].predict(p)).abs() < 0.05);
        }
    }

    #[test]
    fn unmeasured_points_are_not_used() {
        let truth = [model(12.0, 7.0, -42.0, 2.7)];
        let mut map = synthetic_map(&truth, &grid(0..=30, 0..=21, 3), || 0.0);
        let clean = fit_ap_models(&map, &PropagationConfig::default()).unwrap();
        // Interpolated points (scans 0) with values that contradict the model.
        for p in grid(1..=28, 1..=19, 3) {
            map.push_point(point(p, 0), &[Some(-20.0)], None).unwrap();
        }
        assert_eq!(
            fit_ap_models(&map, &PropagationConfig::default()).unwrap(),
            clean
        );
    }

    #[test]
    fn bad_fits_are_dropped() {
        // Values unrelated to distance: a uniform +-15 dB scatter around -70.
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let positions = grid(0..=30, 0..=21, 3);
        let mut map = empty_map(1);
        for &p in &positions {
            let v = -70.0 + 30.0 * (rng.random::<f64>() - 0.5);
            map.push_point(point(p, 1), &[Some(v as f32)], None)
                .unwrap();
        }
        let (models, report) =
            fit_ap_models_with_report(&map, &PropagationConfig::default()).unwrap();
        assert_eq!(models, vec![None]);
        assert_eq!(report.rmse_too_high, 1);
        let lax = PropagationConfig {
            max_rmse_db: 50.0,
            ..Default::default()
        };
        let m = fit_ap_models(&map, &lax).unwrap()[0].unwrap();
        assert!(m.rmse_db > 8.0 && m.is_finite());
    }

    /// Two measured patches (x in 0..=12 and 42..=54, y in 0..=9) with a gap between.
    fn two_patches() -> (RadioMap, Vec<ApModel>) {
        let truth = vec![
            model(4.0, 3.0, -35.0, 2.5),
            model(50.0, 6.0, -38.0, 2.3),
            model(27.0, 0.0, -40.0, 2.0),
            model(20.0, 9.0, -45.0, 2.0),
            model(6.0, 9.0, -40.0, 3.0), // heard on the left patch only (below -100 on the right)
        ];
        let mut positions = grid(0..=12, 0..=9, 3);
        positions.extend(grid(42..=54, 0..=9, 3));
        (synthetic_map(&truth, &positions, || 0.0), truth)
    }

    #[test]
    fn extension_fills_gaps_only_where_allowed() {
        let (mut map, truth) = two_patches();
        let cfg = PropagationConfig {
            min_aps: 3,
            max_extrapolation_m: 25.0,
            ..Default::default()
        };
        let models = fit_ap_models(&map, &cfg).unwrap();
        assert!(models.iter().all(Option::is_some));
        let before = map.len();
        let measured: Vec<Point2> = map.points.iter().map(|p| p.position).collect();
        let allowed = |p: Point2| (-3.0..=12.0).contains(&p.y) && !(30.0..36.0).contains(&p.x);
        let report = extend_radio_map(&mut map, &models, &cfg, allowed).unwrap();
        assert!(report.points_added > 0);
        assert_eq!(map.len(), before + report.points_added);
        assert_eq!(
            report.points_not_allowed
                + report.points_too_close
                + report.points_skipped_few_aps
                + report.points_added,
            report.lattice_points
        );
        let mut entries = 0;
        for i in before..map.len() {
            let pt = map.points[i];
            let p = pt.position;
            assert_eq!(pt.scans, 0);
            assert_eq!((pt.floor, pt.z), (Some(2), Some(1.5)));
            assert!(allowed(p), "{p:?}");
            let gap = measured
                .iter()
                .map(|&q| (q - p).norm())
                .fold(f64::INFINITY, f64::min);
            assert!(
                gap >= cfg.min_gap_m,
                "{p:?} is {gap} m from a measured point"
            );
            let heard: Vec<(usize, f32)> = map.heard(i).collect();
            assert!(heard.len() >= cfg.min_aps);
            entries += heard.len();
            for (j, v) in heard {
                let v = f64::from(v);
                assert!(v >= cfg.min_predicted_dbm && v <= MAX_VALID_RSSI_DBM);
                assert!((v - truth[j].predict(p).min(0.0)).abs() < 0.05);
                assert_eq!(map.count(i, j), 1);
                // Only within max_extrapolation_m of a measured point that heard the AP.
                let near = (0..before)
                    .filter(|&k| map.rss(k, j).is_some())
                    .any(|k| (map.points[k].position - p).norm() <= cfg.max_extrapolation_m);
                assert!(near, "AP {j} at {p:?}");
            }
        }
        assert_eq!(entries, report.entries_added);
        // The gap's middle is covered, the forbidden band is not.
        assert!(
            map.points[before..]
                .iter()
                .any(|p| p.position == Point2::new(27.0, 3.0))
        );
        assert!(report.points_not_allowed > 0);
        // AP 4 is only heard on the left: never on the far side of the gap.
        for i in before..map.len() {
            if map.points[i].position.x > 12.0 + cfg.max_extrapolation_m {
                assert_eq!(map.rss(i, 4), None);
            }
        }
    }

    #[test]
    fn extension_caps_the_heard_aps_to_the_strongest() {
        let (map, truth) = two_patches();
        let cfg = PropagationConfig {
            min_aps: 2,
            max_aps: Some(2),
            max_extrapolation_m: 25.0,
            ..Default::default()
        };
        let models = fit_ap_models(&map, &cfg).unwrap();
        let mut capped = map.clone();
        let report = extend_radio_map(&mut capped, &models, &cfg, |_| true).unwrap();
        let mut full = map.clone();
        let uncapped = PropagationConfig {
            max_aps: None,
            ..cfg
        };
        let full_report = extend_radio_map(&mut full, &models, &uncapped, |_| true).unwrap();
        assert_eq!(report.points_added, full_report.points_added);
        assert!(report.points_capped > 0);
        for i in map.len()..capped.len() {
            let kept: Vec<(usize, f32)> = capped.heard(i).collect();
            let all: Vec<(usize, f32)> = full.heard(i).collect();
            assert_eq!(kept.len(), all.len().min(2));
            let weakest_kept = kept.iter().map(|e| e.1).fold(f32::INFINITY, f32::min);
            for (j, v) in all {
                if !kept.iter().any(|e| e.0 == j) {
                    assert!(v <= weakest_kept, "dropped AP {j} ({v}) over a kept one");
                }
            }
            let p = capped.points[i].position;
            assert!(
                kept.iter()
                    .all(|&(j, v)| (f64::from(v) - truth[j].predict(p).min(0.0)).abs() < 0.05)
            );
        }
    }

    #[test]
    fn extension_errors_are_typed() {
        let (mut map, _) = two_patches();
        let cfg = PropagationConfig::default();
        let models = fit_ap_models(&map, &cfg).unwrap();
        let err = extend_radio_map(&mut map, &models[..2], &cfg, |_| true).unwrap_err();
        assert!(matches!(err, FingerprintError::DimensionMismatch { .. }));
        let small = PropagationConfig {
            max_points: 10,
            ..Default::default()
        };
        let err = extend_radio_map(&mut map, &models, &small, |_| true).unwrap_err();
        assert!(err.to_string().contains("max_points"), "{err}");
        let mut bad = models.clone();
        bad[0] = Some(model(f64::NAN, 0.0, -40.0, 2.0));
        assert!(extend_radio_map(&mut map, &bad, &cfg, |_| true).is_err());
        // Nothing measured: nothing added.
        let mut empty = empty_map(models.len());
        let r = extend_radio_map(&mut empty, &models, &cfg, |_| true).unwrap();
        assert_eq!(r.points_added, 0);
    }

    #[test]
    fn invalid_configs_name_the_field() {
        let d = PropagationConfig::default();
        assert!(d.validate().is_ok());
        let cases: Vec<(PropagationConfig, &str)> = vec![
            (
                PropagationConfig {
                    min_samples: 3,
                    ..d
                },
                "min_samples",
            ),
            (
                PropagationConfig {
                    exponent_range: [3.0, 2.0],
                    ..d
                },
                "exponent_range",
            ),
            (
                PropagationConfig {
                    exponent_range: [0.0, 2.0],
                    ..d
                },
                "exponent_range",
            ),
            (
                PropagationConfig {
                    exponent_range: [1.0, f64::NAN],
                    ..d
                },
                "exponent_range",
            ),
            (
                PropagationConfig {
                    max_rmse_db: 0.0,
                    ..d
                },
                "max_rmse_db",
            ),
            (
                PropagationConfig {
                    max_extrapolation_m: -1.0,
                    ..d
                },
                "max_extrapolation_m",
            ),
            (
                PropagationConfig {
                    max_ap_outside_m: f64::INFINITY,
                    ..d
                },
                "max_ap_outside_m",
            ),
            (
                PropagationConfig {
                    init_strongest: 0,
                    ..d
                },
                "init_strongest",
            ),
            (
                PropagationConfig {
                    max_iterations: 0,
                    ..d
                },
                "max_iterations",
            ),
            (
                PropagationConfig {
                    start_offset_m: -1.0,
                    ..d
                },
                "start_offset_m",
            ),
            (
                PropagationConfig {
                    cell_m: f64::NAN,
                    ..d
                },
                "cell_m",
            ),
            (
                PropagationConfig {
                    min_gap_m: -0.5,
                    ..d
                },
                "min_gap_m",
            ),
            (
                PropagationConfig {
                    margin_m: f64::NAN,
                    ..d
                },
                "margin_m",
            ),
            (
                PropagationConfig {
                    min_predicted_dbm: 5.0,
                    ..d
                },
                "min_predicted_dbm",
            ),
            (PropagationConfig { min_aps: 0, ..d }, "min_aps"),
            (PropagationConfig { max_points: 0, ..d }, "max_points"),
            (
                PropagationConfig {
                    max_aps: Some(3),
                    ..d
                },
                "max_aps",
            ),
            (
                PropagationConfig {
                    censored_weight: -1.0,
                    ..d
                },
                "censored_weight",
            ),
            (
                PropagationConfig {
                    detection_dbm: -130.0,
                    ..d
                },
                "detection_dbm",
            ),
        ];
        let map = empty_map(1);
        for (cfg, field) in cases {
            let err = cfg.validate().unwrap_err();
            assert!(matches!(err, FingerprintError::InvalidConfig(_)));
            assert!(err.to_string().contains(field), "{field}: {err}");
            assert!(fit_ap_models(&map, &cfg).is_err());
        }
    }

    #[test]
    fn config_serde_defaults_and_unknown_fields() {
        let c: PropagationConfig =
            serde_json::from_str(r#"{"cell_m": 2.0, "exponent_range": [2.0, 4.0]}"#).unwrap();
        assert_eq!(c.cell_m, 2.0);
        assert_eq!(c.exponent_range, [2.0, 4.0]);
        assert_eq!(c.min_aps, PropagationConfig::default().min_aps);
        assert!(serde_json::from_str::<PropagationConfig>(r#"{"cell": 2.0}"#).is_err());
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn fitted_models_and_predictions_are_finite(
            aps in prop::collection::vec(
                (-20.0..70.0f64, -20.0..70.0f64, -70.0..-20.0f64, 1.0..6.0f64),
                1..4,
            ),
            positions in prop::collection::vec((0.0..50.0f64, 0.0..50.0f64), 4..40),
            duplicate in any::<bool>(),
            seed in any::<u64>(),
            noise_db in 0.0..10.0f64,
        ) {
            let truth: Vec<ApModel> = aps.iter().map(|&(x, y, p0, n)| model(x, y, p0, n)).collect();
            let mut positions: Vec<Point2> =
                positions.iter().map(|&(x, y)| Point2::new(x, y)).collect();
            if duplicate {
                let p = positions[0];
                positions.iter_mut().take(6).for_each(|q| *q = p);
            }
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let map = synthetic_map(&truth, &positions, || noise_db * gaussian(&mut rng));
            let cfg = PropagationConfig { min_samples: 4, max_rmse_db: 100.0, ..Default::default() };
            let models = fit_ap_models(&map, &cfg).unwrap();
            prop_assert_eq!(models.len(), truth.len());
            for m in models.iter().flatten() {
                prop_assert!(m.is_finite());
                prop_assert!(m.rmse_db >= 0.0);
                prop_assert!(m.exponent >= cfg.exponent_range[0] && m.exponent <= cfg.exponent_range[1]);
                for &p in &positions {
                    prop_assert!(m.predict(p).is_finite());
                }
                prop_assert!(m.predict(m.position).is_finite());
            }
            let mut extended = map.clone();
            let cfg = PropagationConfig { min_aps: 1, min_gap_m: 3.0, ..cfg };
            let report = extend_radio_map(&mut extended, &models, &cfg, |_| true).unwrap();
            prop_assert_eq!(extended.len(), map.len() + report.points_added);
            for i in map.len()..extended.len() {
                for (_, v) in extended.heard(i) {
                    prop_assert!(v.is_finite() && f64::from(v) >= cfg.min_predicted_dbm && v <= 0.0);
                }
            }
        }
    }
}

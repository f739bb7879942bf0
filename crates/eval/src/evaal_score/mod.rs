//! The IPIN competition's official scoring (the EvAAL framework), reproduced: estimates posted
//! through the EvAAL API scored against a trial's ground truth, with the figures and rules of
//! the organisers' scorer (`wipdr score` prints them). On the two estimate files the
//! organisers published for the 2023 Track 3 scoring trials this gives their printed results
//! in every column (test `evaal_official`).
//!
//! **The rules**, as the organisers' scorer applies them:
//!
//! 1. **Swapped coordinates.** If the median of the estimates' latitude column is under
//!    [`SWAPPED_BELOW_DEG`] (10 degrees), longitude and latitude were swapped by the
//!    competitor: they are swapped back, for every estimate ([`coordinates_swapped`]). The
//!    check can only tell where the longitude is under 10 degrees too: at the 2023 venue
//!    (11.1 E, 49.5 N) swapped estimates would stay as written, far off.
//! 2. **Estimate choice.** Each ground-truth point is scored with the latest estimate whose
//!    time is at most [`TIME_SLACK_S`] (0.01 s) after the point's time ([`choose_estimate`]);
//!    "latest" is by time, and between estimates of one time the later in the file. A point
//!    without any such estimate is an error ([`EvaalScoreError::NoEstimateBefore`]): the API
//!    always has one (the trial's initial position), so it means estimates and truth do not
//!    belong together.
//! 3. **Horizontal error.** Both positions go to east/north metres of a local tangent plane
//!    ([`TangentPlane`]: WGS84 ellipsoid, origin at the smallest latitude and the smallest
//!    longitude of the truth, altitude [`EVAAL_ALTITUDE_M`] = 314 m for the origin and every
//!    point); the error is the east/north distance.
//! 4. **Sample error** = horizontal error + [`FLOOR_PENALTY_M`] (15 m) x |floor error|
//!    ([`evaal_sample_error`]).
//! 5. **Figures** over all truth points: EvAAL = the 0.75 quantile of the sample errors and
//!    P95 the 0.95 quantile, both by MATLAB's `quantile` rule ([`quantile_sorted`]); MEAN,
//!    RMSE and MEDIAN of the sample errors; FHR = % of points with the floor right; MPExy =
//!    mean horizontal error; POINTS = truth points whose chosen estimate is at most
//!    [`POINT_WINDOW_S`] (0.5 s) away in time (a count only: every point is scored).
//!
//! `wipdr eval`'s EvAAL column goes through the same metric ([`evaal_metric`]) on its own
//! sample errors ([`crate::scoring::evaal_errors`]).

mod quantile;
mod tangent_plane;

pub use quantile::{quantile, quantile_sorted};
pub use tangent_plane::{EVAAL_ALTITUDE_M, TangentPlane, ecef};

/// Metres of EvAAL error per floor of floor error (the IPIN competition's 15 m).
pub const FLOOR_PENALTY_M: f64 = 15.0;
use serde::{Deserialize, Serialize};
use thiserror::Error;
use wipdr_core::{EvaalEstimate, EvaalTruthPoint};

/// The estimates' coordinates are taken as swapped when the median of their latitude column
/// is under this, degrees.
pub const SWAPPED_BELOW_DEG: f64 = 10.0;

/// An estimate may be this much later than a truth point and still be chosen for it,
/// seconds.
pub const TIME_SLACK_S: f64 = 0.01;

/// A truth point counts in POINTS when its chosen estimate is at most this far in time,
/// seconds.
pub const POINT_WINDOW_S: f64 = 0.5;

/// Largest absolute estimated floor the scorer accepts (beyond it the sample errors would
/// lose all meaning and, far beyond, overflow).
pub const MAX_ABS_ESTIMATE_FLOOR: f64 = 1_000.0;

/// The quantile of the sample errors that is the EvAAL score.
pub const EVAAL_QUANTILE: f64 = 0.75;

/// The organisers' column names, in their order (the fields of [`EvaalScore`]).
pub const EVAAL_COLUMNS: [&str; 8] = [
    "EvAAL", "MEAN", "RMSE", "MEDIAN", "P95", "FHR(%)", "MPExy", "POINTS",
];

/// The figures of the organisers' scorer, in the order of their columns ([`EVAAL_COLUMNS`]).
/// Distances in metres; all finite and non-negative.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EvaalScore {
    /// EvAAL: 0.75 quantile (MATLAB rule) of the sample errors.
    pub evaal: f64,
    /// MEAN of the sample errors.
    pub mean: f64,
    /// RMSE: root mean square of the sample errors.
    pub rmse: f64,
    /// MEDIAN of the sample errors.
    pub median: f64,
    /// P95: 0.95 quantile (MATLAB rule) of the sample errors.
    pub p95: f64,
    /// FHR(%): percentage of the truth points with the floor right.
    pub fhr_percent: f64,
    /// MPExy: mean horizontal error (no floor penalty).
    pub mpe_xy: f64,
    /// POINTS: truth points whose chosen estimate is at most [`POINT_WINDOW_S`] away.
    pub points: usize,
}

/// One scored truth point.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EvaalSample {
    /// The truth point's number.
    pub number: u32,
    /// The truth point's time, seconds.
    pub t_s: f64,
    /// Index (in the given estimates) of the estimate chosen for it.
    pub estimate: usize,
    /// That estimate's time, seconds.
    pub estimate_pts_s: f64,
    /// Horizontal error, metres.
    pub horizontal_m: f64,
    /// |estimated floor - true floor|.
    pub floor_error: f64,
    /// The sample error: horizontal + [`FLOOR_PENALTY_M`] x floor error, metres.
    pub error_m: f64,
}

/// The figures and what they were computed from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvaalScoring {
    /// The figures.
    pub score: EvaalScore,
    /// Each truth point's sample, in the truth's order.
    pub samples: Vec<EvaalSample>,
    /// Whether the estimates' coordinates were taken as swapped (and swapped back).
    pub coordinates_swapped: bool,
    /// The tangent plane's origin, `(latitude, longitude)` degrees.
    pub origin_deg: (f64, f64),
}

/// Inputs the scorer cannot score. Indices are 0-based positions in the given slices.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum EvaalScoreError {
    /// No ground-truth points.
    #[error("no ground-truth points to score")]
    NoTruth,
    /// No estimates.
    #[error("no estimates to score")]
    NoEstimates,
    /// A ground-truth value that is not finite.
    #[error("ground-truth point {index} (number {number}): {field} is not finite")]
    NonFiniteTruth {
        /// Position in the truth slice.
        index: usize,
        /// The point's number.
        number: u32,
        /// The field.
        field: &'static str,
    },
    /// An estimate value that is not finite.
    #[error("estimate {index}: {field} is not finite")]
    NonFiniteEstimate {
        /// Position in the estimates slice.
        index: usize,
        /// The field.
        field: &'static str,
    },
    /// An estimated floor beyond [`MAX_ABS_ESTIMATE_FLOOR`].
    #[error("estimate {index}: floor {floor} is beyond +-1000")]
    FloorOutOfRange {
        /// Position in the estimates slice.
        index: usize,
        /// The floor.
        floor: f64,
    },
    /// A truth point earlier than every estimate (by more than [`TIME_SLACK_S`]).
    #[error(
        "ground-truth point {number} at {t_s} s has no estimate at or before it (the first estimate is at {first_pts_s} s): do truth and estimates belong to one trial?"
    )]
    NoEstimateBefore {
        /// The point's number.
        number: u32,
        /// The point's time, seconds.
        t_s: f64,
        /// The earliest estimate's time, seconds.
        first_pts_s: f64,
    },
}

/// Scores `estimates` against `truth` as the organisers' scorer does (module docs).
///
/// ```
/// use wipdr_core::{EvaalEstimate, EvaalTruthPoint};
/// use wipdr_eval::evaal_score::evaal_score;
///
/// let truth = [
///     EvaalTruthPoint { t_s: 10.0, lon_deg: 11.1110, lat_deg: 49.4610, floor: 0, number: 1 },
///     EvaalTruthPoint { t_s: 20.0, lon_deg: 11.1110, lat_deg: 49.4610, floor: -1, number: 2 },
/// ];
/// let at = |pts_s: f64, lat_deg: f64, floor: f64| EvaalEstimate {
///     pts_s, wall_clock_s: 0.0, horizon_s: 0.5, slack_s: 15.0,
///     lon_deg: 11.1110, lat_deg, floor,
/// };
/// // 10.0: on the point; 19.7: 0.0001 degree (11.1 m) north and one floor off.
/// let estimates = [at(10.0, 49.4610, 0.0), at(19.7, 49.4611, 0.0), at(20.2, 49.4610, -1.0)];
/// let s = evaal_score(&truth, &estimates)?;
/// assert!((s.mpe_xy - 11.12 / 2.0).abs() < 0.01);
/// assert!((s.evaal - 26.12).abs() < 0.01); // 0.75 quantile of [0, 11.12 + 15]
/// assert_eq!((s.fhr_percent, s.points), (50.0, 2));
/// # Ok::<(), wipdr_eval::evaal_score::EvaalScoreError>(())
/// ```
pub fn evaal_score(
    truth: &[EvaalTruthPoint],
    estimates: &[EvaalEstimate],
) -> Result<EvaalScore, EvaalScoreError> {
    evaal_scoring(truth, estimates).map(|s| s.score)
}

/// [`evaal_score`] with each truth point's sample and the rules' decisions.
pub fn evaal_scoring(
    truth: &[EvaalTruthPoint],
    estimates: &[EvaalEstimate],
) -> Result<EvaalScoring, EvaalScoreError> {
    validate(truth, estimates)?;
    let swapped = coordinates_swapped(estimates);
    let origin_lat = truth
        .iter()
        .map(|p| p.lat_deg)
        .fold(f64::INFINITY, f64::min);
    let origin_lon = truth
        .iter()
        .map(|p| p.lon_deg)
        .fold(f64::INFINITY, f64::min);
    let plane = TangentPlane::new(origin_lat, origin_lon, EVAAL_ALTITUDE_M);
    let by_time = time_order(estimates);
    let mut samples = Vec::with_capacity(truth.len());
    for p in truth {
        let Some(i) = choose_in_order(estimates, &by_time, p.t_s) else {
            return Err(EvaalScoreError::NoEstimateBefore {
                number: p.number,
                t_s: p.t_s,
                first_pts_s: estimates[by_time[0]].pts_s,
            });
        };
        let e = &estimates[i];
        let (lat, lon) = if swapped {
            (e.lon_deg, e.lat_deg)
        } else {
            (e.lat_deg, e.lon_deg)
        };
        let [te, tn, _] = plane.enu(p.lat_deg, p.lon_deg, EVAAL_ALTITUDE_M);
        let [ee, en, _] = plane.enu(lat, lon, EVAAL_ALTITUDE_M);
        let horizontal_m = (te - ee).hypot(tn - en);
        let floor_error = (e.floor - f64::from(p.floor)).abs();
        samples.push(EvaalSample {
            number: p.number,
            t_s: p.t_s,
            estimate: i,
            estimate_pts_s: e.pts_s,
            horizontal_m,
            floor_error,
            error_m: evaal_sample_error(horizontal_m, floor_error),
        });
    }
    Ok(EvaalScoring {
        score: score_of(&samples),
        samples,
        coordinates_swapped: swapped,
        origin_deg: (origin_lat, origin_lon),
    })
}

/// The sample error of one point: horizontal error + [`FLOOR_PENALTY_M`] x |floor error|
/// (metres; `floor_error` in floors, its sign ignored).
pub fn evaal_sample_error(horizontal_m: f64, floor_error: f64) -> f64 {
    horizontal_m + FLOOR_PENALTY_M * floor_error.abs()
}

/// The EvAAL metric of a set of sample errors: their [`EVAAL_QUANTILE`] quantile by MATLAB's
/// rule. Non-finite values are left out; `None` without a finite one.
///
/// ```
/// use wipdr_eval::evaal_score::evaal_metric;
/// assert_eq!(evaal_metric(&[4.0, 1.0, 3.0, 2.0]), Some(3.5));
/// assert_eq!(evaal_metric(&[]), None);
/// ```
pub fn evaal_metric(sample_errors: &[f64]) -> Option<f64> {
    quantile(sample_errors, EVAAL_QUANTILE)
}

/// Whether the estimates' longitude and latitude were swapped: the median of the latitude
/// column is under [`SWAPPED_BELOW_DEG`] (`false` without estimates).
pub fn coordinates_swapped(estimates: &[EvaalEstimate]) -> bool {
    let lat: Vec<f64> = estimates.iter().map(|e| e.lat_deg).collect();
    quantile(&lat, 0.5).is_some_and(|m| m < SWAPPED_BELOW_DEG)
}

/// The index of the estimate the scorer chooses for a truth point at `t_s`: the latest (by
/// time, then by position in the slice) with `pts_s <= t_s + TIME_SLACK_S`; `None` if every
/// estimate is later. Estimates with a non-finite time are never chosen.
///
/// ```
/// use wipdr_core::EvaalEstimate;
/// use wipdr_eval::evaal_score::choose_estimate;
/// let at = |pts_s| EvaalEstimate { pts_s, wall_clock_s: 0.0, horizon_s: 0.5, slack_s: 0.0,
///                                  lon_deg: 11.0, lat_deg: 49.0, floor: 0.0 };
/// let est = [at(1.0), at(2.005), at(2.02)];
/// assert_eq!(choose_estimate(&est, 2.0), Some(1)); // 5 ms late is still "at" 2.0
/// assert_eq!(choose_estimate(&est, 0.5), None);
/// ```
pub fn choose_estimate(estimates: &[EvaalEstimate], t_s: f64) -> Option<usize> {
    choose_in_order(estimates, &time_order(estimates), t_s)
}

/// Indices of the finite-time estimates, sorted by time (stable: file order within a time).
fn time_order(estimates: &[EvaalEstimate]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..estimates.len())
        .filter(|&i| estimates[i].pts_s.is_finite())
        .collect();
    order.sort_by(|&a, &b| estimates[a].pts_s.total_cmp(&estimates[b].pts_s));
    order
}

fn choose_in_order(estimates: &[EvaalEstimate], by_time: &[usize], t_s: f64) -> Option<usize> {
    let n = by_time.partition_point(|&i| estimates[i].pts_s <= t_s + TIME_SLACK_S);
    n.checked_sub(1).map(|k| by_time[k])
}

fn score_of(samples: &[EvaalSample]) -> EvaalScore {
    let errors: Vec<f64> = samples.iter().map(|s| s.error_m).collect();
    let mut sorted = errors.clone();
    sorted.sort_by(f64::total_cmp);
    let n = samples.len().max(1) as f64;
    let q = |p| quantile_sorted(&sorted, p).unwrap_or(0.0);
    let hits = samples.iter().filter(|s| s.floor_error == 0.0).count();
    let points = samples
        .iter()
        .filter(|s| (s.t_s - s.estimate_pts_s).abs() <= POINT_WINDOW_S)
        .count();
    EvaalScore {
        evaal: q(EVAAL_QUANTILE),
        mean: errors.iter().sum::<f64>() / n,
        rmse: (errors.iter().map(|e| e * e).sum::<f64>() / n).sqrt(),
        median: q(0.5),
        p95: q(0.95),
        fhr_percent: 100.0 * hits as f64 / n,
        mpe_xy: samples.iter().map(|s| s.horizontal_m).sum::<f64>() / n,
        points,
    }
}

fn validate(truth: &[EvaalTruthPoint], estimates: &[EvaalEstimate]) -> Result<(), EvaalScoreError> {
    if truth.is_empty() {
        return Err(EvaalScoreError::NoTruth);
    }
    if estimates.is_empty() {
        return Err(EvaalScoreError::NoEstimates);
    }
    for (index, p) in truth.iter().enumerate() {
        for (field, v) in [
            ("time", p.t_s),
            ("longitude", p.lon_deg),
            ("latitude", p.lat_deg),
        ] {
            if !v.is_finite() {
                return Err(EvaalScoreError::NonFiniteTruth {
                    index,
                    number: p.number,
                    field,
                });
            }
        }
    }
    for (index, e) in estimates.iter().enumerate() {
        let fields = [
            ("pts", e.pts_s),
            ("longitude", e.lon_deg),
            ("latitude", e.lat_deg),
            ("floor", e.floor),
        ];
        for (field, v) in fields {
            if !v.is_finite() {
                return Err(EvaalScoreError::NonFiniteEstimate { index, field });
            }
        }
        if e.floor.abs() > MAX_ABS_ESTIMATE_FLOOR {
            return Err(EvaalScoreError::FloorOutOfRange {
                index,
                floor: e.floor,
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests;

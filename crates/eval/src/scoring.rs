//! Scoring at waypoints (`docs/evaluation.md`, "Scoring").
//!
//! A scheme emits a causal track: [`TrackPoint`]s (time, position, the scheme's horizontal
//! standard deviation where it has one) in time order, each using only records up to `t`. At each waypoint time the error is the 2D distance between the waypoint and the
//! latest estimate at or before that time. Waypoints before the first estimate, or before the
//! protocol's scoring start (the walk's first Wi-Fi scan, as the reference pipeline scores), are
//! counted as skipped — never silently dropped.
//!
//! **Floors.** Where waypoints carry a floor, the floor error at a waypoint is the stream's
//! floor estimate at or before its time minus the true floor: `Some(0)` is a hit; `None`
//! when the stream had no floor estimate yet. Where the waypoint has no floor (a single ILC
//! floor), the floor error is `Some(0)`. The competition's EvAAL metric
//! ([`evaal_errors`]) adds [`FLOOR_PENALTY_M`] per floor of error (a missing floor counts as
//! one floor off).

use serde::{Deserialize, Serialize};
use wipdr_core::{Point2, TimestampMs, Waypoint};
use wipdr_positioning::PositionEstimate;

/// One estimate of a track: time, position and the scheme's horizontal uncertainty.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TrackPoint {
    /// Time of the input that produced the estimate (ms).
    pub t: TimestampMs,
    /// Estimated position (the floor's metre frame).
    pub position: Point2,
    /// Horizontal standard deviation, metres (`sqrt(trace(P)/2)`,
    /// [`PositionEstimate::sd_m`]); `None` where the scheme carries no covariance.
    pub sd_m: Option<f64>,
}

impl TrackPoint {
    /// A point without an uncertainty.
    pub fn new(t: TimestampMs, position: Point2) -> Self {
        Self {
            t,
            position,
            sd_m: None,
        }
    }

    /// The same point with a horizontal standard deviation (metres).
    pub fn with_sd(mut self, sd_m: Option<f64>) -> Self {
        self.sd_m = sd_m;
        self
    }
}

impl From<&PositionEstimate> for TrackPoint {
    fn from(e: &PositionEstimate) -> Self {
        Self::new(e.t, e.position).with_sd(e.sd_m())
    }
}

/// A causal track of estimates, sorted by time.
pub type Track = Vec<TrackPoint>;

/// The radius of the circle holding 95 % of an isotropic 2D Gaussian, in standard deviations
/// of one axis: `sqrt(-2 ln 0.05)` = 2.4477 (the Rayleigh distribution's 95th percentile).
pub const RADIUS_95_PER_SD: f64 = 2.447_746_830_680_816;

/// A stream's floor estimate: `(time, floor)` at each change, sorted by time.
pub type FloorTrack = Vec<(TimestampMs, i32)>;

#[doc(no_inline)]
pub use crate::evaal_score::FLOOR_PENALTY_M;

/// One scored waypoint: time, 2D error (metres), floor error (estimate minus truth; `None`:
/// no floor estimate yet).
pub type ScoredPoint = (TimestampMs, f64, Option<i32>);

/// The scored waypoints of one walk for one scheme.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct WalkScore {
    /// `(waypoint time, 2D error in metres, floor error)` of every scored waypoint.
    pub errors: Vec<ScoredPoint>,
    /// Waypoints not scored: before the scoring start or before the scheme's first estimate.
    pub skipped: usize,
    /// Scored waypoints with a known true floor.
    #[serde(default)]
    pub floor_scored: usize,
    /// The scheme's horizontal standard deviation (metres) at each scored waypoint, aligned
    /// with `errors`: that of the estimate scored there; empty where the scheme has none.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sd_m: Vec<Option<f64>>,
    /// Distance (metres) of each scored waypoint, aligned with `errors`, to the fold's
    /// nearest measured reference point on its floor ([`crate::coverage`]); empty where
    /// not measured.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub coverage_m: Vec<Option<f64>>,
}

impl WalkScore {
    /// The longest time the walk's floor estimate was wrong, ms, at the sampling of its scored
    /// waypoints: from the first waypoint of a run scored on a wrong floor (or before any
    /// floor estimate) to the next waypoint scored right, or to the walk's last scored
    /// waypoint when none follows (so an upper bound where the run ended between two
    /// waypoints); 0 without a wrong waypoint or without true floors.
    pub fn longest_wrong_floor_ms(&self) -> TimestampMs {
        if self.floor_scored == 0 {
            return 0;
        }
        let mut worst = 0;
        let mut run_start: Option<TimestampMs> = None;
        for e in &self.errors {
            match (e.2 == Some(0), run_start) {
                (false, None) => run_start = Some(e.0),
                (true, Some(s)) => {
                    worst = worst.max(e.0 - s);
                    run_start = None;
                }
                _ => {}
            }
        }
        if let (Some(s), Some(last)) = (run_start, self.errors.last()) {
            worst = worst.max(last.0 - s);
        }
        worst
    }

    /// The 2D error values alone.
    pub fn values(&self) -> Vec<f64> {
        self.errors.iter().map(|e| e.1).collect()
    }

    /// Scored waypoints with a true floor whose floor estimate was right.
    pub fn floor_hits(&self) -> usize {
        // Waypoints without a true floor score `Some(0)` too: count hits among the known.
        let hits = self.errors.iter().filter(|e| e.2 == Some(0)).count();
        hits.saturating_sub(self.errors.len() - self.floor_scored)
    }

    /// `(scored points with an uncertainty, of them the points whose true position lies
    /// inside the 95 % radius [`RADIUS_95_PER_SD`] x `sd_m`)`.
    pub fn radius_95_hits(&self) -> (usize, usize) {
        let mut with_sd = 0;
        let mut inside = 0;
        for (e, sd) in self.errors.iter().zip(&self.sd_m) {
            if let Some(sd) = sd.filter(|sd| sd.is_finite() && *sd >= 0.0) {
                with_sd += 1;
                if e.1 <= RADIUS_95_PER_SD * sd {
                    inside += 1;
                }
            }
        }
        (with_sd, inside)
    }
}

/// The EvAAL error of each scored point: 2D error + [`FLOOR_PENALTY_M`] x |floor error| (a
/// missing floor estimate counts as one floor).
pub fn evaal_errors(points: &[ScoredPoint]) -> Vec<f64> {
    points
        .iter()
        .map(|&(_, e, f)| {
            crate::evaal_score::evaal_sample_error(
                e,
                f.map_or(1.0, |f| f64::from(f.unsigned_abs())),
            )
        })
        .collect()
}

/// Scores `track` at `waypoints` (both time-sorted). Waypoints before `score_from` (if given) or
/// before the first estimate are skipped. Non-finite estimates are treated as missing (the
/// previous finite one stands).
///
/// ```
/// use wipdr_core::{Point2, Waypoint};
/// use wipdr_eval::scoring::{TrackPoint, score_track};
/// let wps = [Waypoint::new(0, Point2::new(0.0, 0.0)),
///            Waypoint::new(10, Point2::new(3.0, 4.0))];
/// let track = vec![TrackPoint::new(5, Point2::new(0.0, 0.0))];
/// let s = score_track(&wps, &track, None);
/// assert_eq!(s.skipped, 1);
/// assert_eq!(s.errors, vec![(10, 5.0, Some(0))]);
/// ```
pub fn score_track(
    waypoints: &[Waypoint],
    track: &[TrackPoint],
    score_from: Option<TimestampMs>,
) -> WalkScore {
    score_track_with_floors(waypoints, track, &[], score_from)
}

/// [`score_track`] with the stream's floor estimate (`floors`: `(time, floor)` at each
/// change, time-sorted), scored where the waypoints have floors (module docs).
pub fn score_track_with_floors(
    waypoints: &[Waypoint],
    track: &[TrackPoint],
    floors: &[(TimestampMs, i32)],
    score_from: Option<TimestampMs>,
) -> WalkScore {
    let mut out = WalkScore::default();
    let mut j = 0usize;
    let mut k = 0usize;
    let mut latest: Option<(Point2, Option<f64>)> = None;
    let mut floor: Option<i32> = None;
    let mut any_sd = false;
    for w in waypoints {
        while j < track.len() && track[j].t <= w.t {
            let p = track[j].position;
            if p.x.is_finite() && p.y.is_finite() {
                let sd = track[j].sd_m.filter(|sd| sd.is_finite() && *sd >= 0.0);
                any_sd |= sd.is_some();
                latest = Some((p, sd));
            }
            j += 1;
        }
        while k < floors.len() && floors[k].0 <= w.t {
            floor = Some(floors[k].1);
            k += 1;
        }
        if score_from.is_some_and(|t0| w.t < t0) {
            out.skipped += 1;
            continue;
        }
        let Some((p, sd)) = latest else {
            out.skipped += 1;
            continue;
        };
        let floor_error = match w.floor {
            None => Some(0),
            Some(truth) => {
                out.floor_scored += 1;
                floor.map(|f| f.saturating_sub(truth))
            }
        };
        out.errors.push((w.t, (p - w.position).norm(), floor_error));
        out.sd_m.push(sd);
    }
    if !any_sd {
        out.sd_m.clear();
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn wp(t: i64, x: f64) -> Waypoint {
        Waypoint::new(t, Point2::new(x, 0.0))
    }

    #[test]
    fn uses_latest_estimate_not_a_future_one() {
        let wps = [wp(10, 0.0), wp(20, 0.0)];
        let track = vec![
            TrackPoint::new(10, Point2::new(1.0, 0.0)),
            TrackPoint::new(11, Point2::new(100.0, 0.0)),
        ];
        let s = score_track(&wps, &track, None);
        assert_eq!(s.errors, vec![(10, 1.0, Some(0)), (20, 100.0, Some(0))]);
    }

    #[test]
    fn score_from_skips_and_counts() {
        let wps = [wp(0, 0.0), wp(10, 0.0), wp(20, 0.0)];
        let track = vec![TrackPoint::new(0, Point2::new(2.0, 0.0))];
        let s = score_track(&wps, &track, Some(10));
        assert_eq!(s.skipped, 1);
        assert_eq!(s.errors.len(), 2);
    }

    #[test]
    fn nan_estimates_are_ignored() {
        let wps = [wp(10, 0.0)];
        let track = vec![
            TrackPoint::new(1, Point2::new(1.0, 0.0)),
            TrackPoint::new(2, Point2::new(f64::NAN, 0.0)),
        ];
        assert_eq!(
            score_track(&wps, &track, None).errors,
            vec![(10, 1.0, Some(0))]
        );
    }

    #[test]
    fn floors_are_scored_with_the_latest_floor_estimate() {
        let wps = [
            wp(10, 0.0).on_floor(0),
            wp(20, 0.0).on_floor(-2),
            wp(30, 0.0).on_floor(-2),
            wp(40, 0.0),
        ];
        let track = vec![TrackPoint::new(5, Point2::new(3.0, 4.0))];
        let s = score_track_with_floors(&wps, &track, &[(12, 0), (25, -2)], None);
        let floor_errors: Vec<Option<i32>> = s.errors.iter().map(|e| e.2).collect();
        assert_eq!(floor_errors, vec![None, Some(2), Some(0), Some(0)]);
        assert_eq!(s.floor_scored, 3);
        assert_eq!(s.floor_hits(), 1);
        assert_eq!(evaal_errors(&s.errors), vec![20.0, 35.0, 5.0, 5.0]);
        // Wrong (or no floor) from 10 until the right one at 30.
        assert_eq!(s.longest_wrong_floor_ms(), 20);
    }

    #[test]
    fn the_longest_wrong_floor_run_counts_to_the_next_right_waypoint_or_the_end() {
        let score = |floors: &[Option<i32>]| WalkScore {
            errors: floors
                .iter()
                .enumerate()
                .map(|(k, f)| (1000 * k as TimestampMs, 1.0, *f))
                .collect(),
            floor_scored: floors.len(),
            ..WalkScore::default()
        };
        assert_eq!(score(&[Some(0), Some(0)]).longest_wrong_floor_ms(), 0);
        let runs = [
            Some(1),
            Some(0),
            Some(-1),
            Some(-1),
            Some(-1),
            Some(0),
            Some(2),
        ];
        assert_eq!(score(&runs).longest_wrong_floor_ms(), 3000);
        assert_eq!(
            score(&[Some(0), Some(1), Some(1)]).longest_wrong_floor_ms(),
            1000
        );
        let mut no_floors = score(&[Some(1), Some(1)]);
        no_floors.floor_scored = 0;
        assert_eq!(no_floors.longest_wrong_floor_ms(), 0);
    }

    #[test]
    fn the_sd_of_the_scored_estimate_is_kept_and_counted_against_the_95_radius() {
        let wps = [wp(10, 0.0), wp(20, 0.0), wp(30, 0.0)];
        let track = vec![
            TrackPoint::new(5, Point2::new(3.0, 4.0)).with_sd(Some(1.0)), // 5 m > 2.45 m
            TrackPoint::new(15, Point2::new(1.0, 0.0)).with_sd(Some(1.0)), // 1 m inside
            TrackPoint::new(25, Point2::new(1.0, 0.0)),                   // no sd
        ];
        let s = score_track(&wps, &track, None);
        assert_eq!(s.sd_m, vec![Some(1.0), Some(1.0), None]);
        assert_eq!(s.radius_95_hits(), (2, 1));
        let no_sd: Track = track.iter().map(|p| p.with_sd(None)).collect();
        assert!(score_track(&wps, &no_sd, None).sd_m.is_empty());
    }

    #[test]
    fn the_95_radius_constant_holds_95_percent_of_a_2d_gaussian() {
        // P(r <= R) = 1 - exp(-R^2 / 2) for unit per-axis sd.
        let p = 1.0 - (-RADIUS_95_PER_SD * RADIUS_95_PER_SD / 2.0).exp();
        assert!((p - 0.95).abs() < 1e-12);
    }

    proptest! {
        #[test]
        fn every_waypoint_is_scored_or_skipped(
            wts in proptest::collection::vec(0i64..1000, 0..30),
            tts in proptest::collection::vec(0i64..1000, 0..30),
            from in proptest::option::of(0i64..1000),
        ) {
            let mut wts = wts; wts.sort();
            let mut tts = tts; tts.sort();
            let wps: Vec<_> = wts.iter().map(|&t| wp(t, t as f64)).collect();
            let track: Track = tts.iter().map(|&t| TrackPoint::new(t, Point2::new(0.0, 0.0))).collect();
            let s = score_track(&wps, &track, from);
            prop_assert_eq!(s.errors.len() + s.skipped, wps.len());
            prop_assert!(s.errors.iter().all(|e| e.1.is_finite() && e.1 >= 0.0));
        }
    }
}

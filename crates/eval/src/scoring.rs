//! Scoring at waypoints (`docs/evaluation.md`, "Scoring").
//!
//! A scheme emits a causal track: `(t, position)` pairs in time order, each using only records
//! up to `t`. At each waypoint time the error is the 2D distance between the waypoint and the
//! latest estimate at or before that time. Waypoints before the first estimate, or before the
//! protocol's scoring start (the walk's first Wi-Fi scan, as the reference pipeline scores), are
//! counted as skipped — never silently dropped.

use serde::{Deserialize, Serialize};
use wipdr_core::{Point2, TimestampMs, Waypoint};

/// A causal track of estimates, sorted by time.
pub type Track = Vec<(TimestampMs, Point2)>;

/// The scored waypoints of one walk for one scheme.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct WalkScore {
    /// `(waypoint time, error in metres)` of every scored waypoint.
    pub errors: Vec<(TimestampMs, f64)>,
    /// Waypoints not scored: before the scoring start or before the scheme's first estimate.
    pub skipped: usize,
}

impl WalkScore {
    /// The error values alone.
    pub fn values(&self) -> Vec<f64> {
        self.errors.iter().map(|e| e.1).collect()
    }
}

/// Scores `track` at `waypoints` (both time-sorted). Waypoints before `score_from` (if given) or
/// before the first estimate are skipped. Non-finite estimates are treated as missing (the
/// previous finite one stands).
///
/// ```
/// use wipdr_core::{Point2, Waypoint};
/// use wipdr_eval::scoring::score_track;
/// let wps = [Waypoint { t: 0, position: Point2::new(0.0, 0.0) },
///            Waypoint { t: 10, position: Point2::new(3.0, 4.0) }];
/// let track = vec![(5, Point2::new(0.0, 0.0))];
/// let s = score_track(&wps, &track, None);
/// assert_eq!(s.skipped, 1);
/// assert_eq!(s.errors, vec![(10, 5.0)]);
/// ```
pub fn score_track(
    waypoints: &[Waypoint],
    track: &[(TimestampMs, Point2)],
    score_from: Option<TimestampMs>,
) -> WalkScore {
    let mut out = WalkScore::default();
    let mut j = 0usize;
    let mut latest: Option<Point2> = None;
    for w in waypoints {
        while j < track.len() && track[j].0 <= w.t {
            let p = track[j].1;
            if p.x.is_finite() && p.y.is_finite() {
                latest = Some(p);
            }
            j += 1;
        }
        if score_from.is_some_and(|t0| w.t < t0) {
            out.skipped += 1;
            continue;
        }
        match latest {
            Some(p) => out.errors.push((w.t, (p - w.position).norm())),
            None => out.skipped += 1,
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn wp(t: i64, x: f64) -> Waypoint {
        Waypoint {
            t,
            position: Point2::new(x, 0.0),
        }
    }

    #[test]
    fn uses_latest_estimate_not_a_future_one() {
        let wps = [wp(10, 0.0), wp(20, 0.0)];
        let track = vec![(10, Point2::new(1.0, 0.0)), (11, Point2::new(100.0, 0.0))];
        let s = score_track(&wps, &track, None);
        assert_eq!(s.errors, vec![(10, 1.0), (20, 100.0)]);
    }

    #[test]
    fn score_from_skips_and_counts() {
        let wps = [wp(0, 0.0), wp(10, 0.0), wp(20, 0.0)];
        let track = vec![(0, Point2::new(2.0, 0.0))];
        let s = score_track(&wps, &track, Some(10));
        assert_eq!(s.skipped, 1);
        assert_eq!(s.errors.len(), 2);
    }

    #[test]
    fn nan_estimates_are_ignored() {
        let wps = [wp(10, 0.0)];
        let track = vec![(1, Point2::new(1.0, 0.0)), (2, Point2::new(f64::NAN, 0.0))];
        assert_eq!(score_track(&wps, &track, None).errors, vec![(10, 1.0)]);
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
            let track: Track = tts.iter().map(|&t| (t, Point2::new(0.0, 0.0))).collect();
            let s = score_track(&wps, &track, from);
            prop_assert_eq!(s.errors.len() + s.skipped, wps.len());
            prop_assert!(s.errors.iter().all(|e| e.1.is_finite() && e.1 >= 0.0));
        }
    }
}

//! What the evaluation report page (`wipdr eval --report`, `wipdr report`) draws of a run:
//! each scheme's track downsampled for drawing, a walk's truth and Wi-Fi fixes, a floor's
//! walls. All positions are in the floor's metre frame, rounded to the centimetre.
//!
//! **Downsampling rule** ([`drawing_indices`]): a track keeps its first and last point and,
//! at every waypoint, the estimate that was scored there (the latest finite one at or before
//! the waypoint's time, as [`crate::scoring::score_track`] takes it), so that the page's
//! marker at a waypoint is the scored estimate itself and its distance to the truth is the
//! error in the tables; between two such points, the points that the Ramer-Douglas-Peucker
//! simplification keeps at [`DRAW_TOLERANCE_M`] (every dropped point lies within that
//! distance of the drawn line). Points with a non-finite position are not drawn.
//!
//! ```
//! use wipdr_core::{Point2, Waypoint};
//! use wipdr_eval::drawing::drawn_track;
//! use wipdr_eval::scoring::TrackPoint;
//! // A straight walk east: the middle points add nothing to the drawn line ...
//! let track: Vec<_> = (0..5).map(|i| TrackPoint::new(i * 1000, Point2::new(i as f64, 0.0))).collect();
//! assert_eq!(drawn_track(&track, &[]).len(), 2);
//! // ... but the estimate scored at a waypoint (t = 2.5 s: the point of t = 2 s) is kept.
//! let truth = [Waypoint::new(2_500, Point2::new(2.5, 1.0))];
//! let drawn = drawn_track(&track, &truth);
//! assert_eq!(drawn.iter().map(|p| p.0).collect::<Vec<_>>(), vec![0, 2000, 4000]);
//! ```

use crate::scoring::TrackPoint;
use wipdr_core::{FloorPlan, Point2, TimestampMs, Waypoint, WifiObservation};

/// Tolerance of the track simplification, metres: a dropped estimate lies at most this far
/// from the drawn line (a fraction of a pixel at the zoom of a walk).
pub const DRAW_TOLERANCE_M: f64 = 0.25;

/// A drawn track point: `(t_ms, x, y, sd_m)` (the JSON's `[t_ms, x, y, sd_m or null]`).
pub type DrawnPoint = (TimestampMs, f64, f64, Option<f64>);

/// A drawn point of a walk: `(t_ms, x, y)`.
pub type TimedPoint = (TimestampMs, f64, f64);

/// A drawn wall: `[x1, y1, x2, y2]`.
pub type DrawnWall = [f64; 4];

/// Rounds metres to the centimetre (the drawing's precision; keeps the JSON short).
pub fn cm(v: f64) -> f64 {
    (v * 100.0).round() / 100.0
}

fn finite(p: Point2) -> bool {
    p.x.is_finite() && p.y.is_finite()
}

/// Indices (ascending) of the points of `track` to draw, by the module's rule, at
/// `tolerance_m`; `waypoint_times` sorted.
pub fn drawing_indices(
    track: &[TrackPoint],
    waypoint_times: &[TimestampMs],
    tolerance_m: f64,
) -> Vec<usize> {
    let valid: Vec<usize> = (0..track.len())
        .filter(|&i| finite(track[i].position))
        .collect();
    if valid.is_empty() {
        return Vec::new();
    }
    // First the points that must be drawn: the ends and the estimate scored at each
    // waypoint (the latest finite point at or before its time) ...
    let mut keep = vec![false; valid.len()];
    keep[0] = true;
    keep[valid.len() - 1] = true;
    let mut k = 0usize;
    for &t in waypoint_times {
        while k < valid.len() && track[valid[k]].t <= t {
            k += 1;
        }
        if k > 0 {
            keep[k - 1] = true;
        }
    }
    // ... then Ramer-Douglas-Peucker between each two consecutive ones (explicit stack).
    let forced: Vec<usize> = (0..valid.len()).filter(|&k| keep[k]).collect();
    let mut stack: Vec<(usize, usize)> = forced.windows(2).map(|w| (w[0], w[1])).collect();
    while let Some((a, b)) = stack.pop() {
        if b <= a + 1 {
            continue;
        }
        let (pa, pb) = (track[valid[a]].position, track[valid[b]].position);
        let (mut far, mut far_d) = (a, -1.0f64);
        for (k, &i) in valid.iter().enumerate().take(b).skip(a + 1) {
            let d = distance_to_segment(track[i].position, pa, pb);
            if d > far_d {
                (far, far_d) = (k, d);
            }
        }
        if far_d > tolerance_m {
            keep[far] = true;
            stack.push((a, far));
            stack.push((far, b));
        }
    }
    valid
        .iter()
        .zip(keep)
        .filter_map(|(&i, kept)| kept.then_some(i))
        .collect()
}

/// Distance from `p` to the segment `a`-`b`, metres.
fn distance_to_segment(p: Point2, a: Point2, b: Point2) -> f64 {
    let ab = b - a;
    let len2 = ab.norm_squared();
    if len2 == 0.0 {
        return (p - a).norm();
    }
    let s = ((p - a).dot(&ab) / len2).clamp(0.0, 1.0);
    (p - (a + ab * s)).norm()
}

/// The drawn form of `track` for a walk with `waypoints`: the points of
/// [`drawing_indices`] at [`DRAW_TOLERANCE_M`], rounded to the centimetre (a non-finite or
/// negative `sd_m` becomes `None`).
pub fn drawn_track(track: &[TrackPoint], waypoints: &[Waypoint]) -> Vec<DrawnPoint> {
    let times: Vec<TimestampMs> = waypoints.iter().map(|w| w.t).collect();
    drawing_indices(track, &times, DRAW_TOLERANCE_M)
        .into_iter()
        .map(|i| {
            let p = &track[i];
            let sd = p.sd_m.filter(|s| s.is_finite() && *s >= 0.0).map(cm);
            (p.t, cm(p.position.x), cm(p.position.y), sd)
        })
        .collect()
}

/// The truth of a walk as drawn: its waypoints `(t, x, y)` (non-finite ones left out).
pub fn drawn_waypoints(waypoints: &[Waypoint]) -> Vec<TimedPoint> {
    waypoints
        .iter()
        .filter(|w| finite(w.position))
        .map(|w| (w.t, cm(w.position.x), cm(w.position.y)))
        .collect()
}

/// The Wi-Fi fixes of a walk as drawn: each observation's estimate `(t, x, y)`.
pub fn drawn_fixes(observations: &[WifiObservation]) -> Vec<TimedPoint> {
    observations
        .iter()
        .filter(|o| finite(o.estimate))
        .map(|o| (o.t, cm(o.estimate.x), cm(o.estimate.y)))
        .collect()
}

/// The walls of a plan as drawn, `[x1, y1, x2, y2]` each (segments shorter than a centimetre
/// after rounding and non-finite ones left out).
pub fn drawn_walls(plan: &FloorPlan) -> Vec<DrawnWall> {
    plan.walls
        .iter()
        .filter(|w| finite(w.a) && finite(w.b))
        .map(|w| [cm(w.a.x), cm(w.a.y), cm(w.b.x), cm(w.b.y)])
        .filter(|w| w[0] != w[2] || w[1] != w[3])
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn tp(t: i64, x: f64, y: f64) -> TrackPoint {
        TrackPoint::new(t, Point2::new(x, y))
    }

    #[test]
    fn corners_are_kept_and_straight_runs_dropped() {
        // East 10 m, then north 10 m, a point every metre.
        let mut track: Vec<TrackPoint> = (0..=10).map(|i| tp(i, i as f64, 0.0)).collect();
        track.extend((1..=10).map(|i| tp(10 + i, 10.0, i as f64)));
        assert_eq!(drawing_indices(&track, &[], 0.25), vec![0, 10, 20]);
    }

    #[test]
    fn non_finite_points_are_not_drawn_and_do_not_count_as_scored() {
        let track = vec![
            tp(0, 0.0, 0.0),
            tp(1, 1.0, 1.0),
            tp(2, f64::NAN, 0.0),
            tp(3, 3.0, 0.0),
        ];
        // The waypoint at t = 2 was scored with the point of t = 1 (the NaN is skipped).
        assert_eq!(drawing_indices(&track, &[2], 100.0), vec![0, 1, 3]);
        assert!(drawing_indices(&[tp(0, f64::NAN, 0.0)], &[0], 0.25).is_empty());
        assert!(drawing_indices(&[], &[0], 0.25).is_empty());
    }

    #[test]
    fn drawn_points_are_rounded_and_bad_sds_dropped() {
        let track = vec![
            tp(0, 1.234_567, 2.0).with_sd(Some(0.123_456)),
            tp(5, 3.0, 4.0).with_sd(Some(f64::NAN)),
        ];
        assert_eq!(
            drawn_track(&track, &[]),
            vec![(0, 1.23, 2.0, Some(0.12)), (5, 3.0, 4.0, None)]
        );
    }

    proptest! {
        /// Every finite point not drawn lies within the tolerance of the drawn polyline, and
        /// every estimate scored at a waypoint is drawn.
        #[test]
        fn dropped_points_lie_near_the_line_and_scored_ones_are_kept(
            steps in proptest::collection::vec((-3.0f64..3.0, -3.0f64..3.0), 1..80),
            wts in proptest::collection::vec(0i64..100, 0..10),
            tol in 0.05f64..2.0,
        ) {
            let mut p = Point2::new(0.0, 0.0);
            let track: Vec<TrackPoint> = steps.iter().enumerate().map(|(i, d)| {
                p = Point2::new(p.x + d.0, p.y + d.1);
                tp(i as i64, p.x, p.y)
            }).collect();
            let mut wts = wts;
            wts.sort();
            let kept = drawing_indices(&track, &wts, tol);
            prop_assert_eq!(kept.first(), Some(&0));
            prop_assert_eq!(kept.last(), Some(&(track.len() - 1)));
            for pair in kept.windows(2) {
                let (a, b) = (track[pair[0]].position, track[pair[1]].position);
                for q in &track[pair[0] + 1..pair[1]] {
                    prop_assert!(distance_to_segment(q.position, a, b) <= tol + 1e-9);
                }
            }
            for &t in &wts {
                if let Some(scored) = track.iter().rposition(|q| q.t <= t) {
                    prop_assert!(kept.contains(&scored), "t {} scored {}", t, scored);
                }
            }
        }
    }
}

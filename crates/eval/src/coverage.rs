//! Error by coverage: how far each scored waypoint lies from the fold's training data.
//!
//! A fingerprinting system can only be as good as its radio map where the walker is: a test
//! walk through an area no training walk crossed gets its Wi-Fi fixes from the nearest
//! covered places, tens of metres off. [`coverage_distance`] measures, for a true position,
//! the 2D distance to the nearest *measured* reference point of the fold's radio map on the
//! same floor (the path-loss extension's synthesised points do not count: they are what a
//! gap is filled with, not data); [`EvalReport::by_coverage`] pools each scheme's errors by
//! that distance, so a results table says how much of a scheme's error sits in coverage gaps
//! (`wipdr eval --by-coverage 5,10,20`).
//!
//! ```
//! use wipdr_core::Point2;
//! use wipdr_eval::coverage::{MeasuredPoint, coverage_distance};
//! let map = [MeasuredPoint { position: Point2::new(0.0, 0.0), floor: Some(0) },
//!            MeasuredPoint { position: Point2::new(3.0, 4.0), floor: Some(-2) }];
//! // On floor 0 the point on floor -2 does not count; without a floor every point does.
//! assert_eq!(coverage_distance(Point2::new(3.0, 4.0), Some(0), &map), Some(5.0));
//! assert_eq!(coverage_distance(Point2::new(3.0, 4.0), None, &map), Some(0.0));
//! assert_eq!(coverage_distance(Point2::new(3.0, 4.0), Some(1), &map), None);
//! ```

use crate::report::EvalReport;
use crate::scoring::WalkScore;
use std::collections::BTreeMap;
use std::fmt::Write;
use wipdr_core::Waypoint;

pub use wipdr_positioning::site_model::{MeasuredPoint, coverage_distance, measured_points};

/// Fills `score.coverage_m` from `waypoint_coverage_m` (aligned with `waypoints`, the
/// waypoints `score` was scored at): the scored points are a time-ordered subsequence of
/// the waypoints, matched by time.
pub fn attach_coverage(
    score: &mut WalkScore,
    waypoints: &[Waypoint],
    waypoint_coverage_m: &[Option<f64>],
) {
    let mut j = 0usize;
    score.coverage_m = score
        .errors
        .iter()
        .map(|&(t, _, _)| {
            while j < waypoints.len() && waypoints[j].t < t {
                j += 1;
            }
            let d = waypoint_coverage_m.get(j).copied().flatten();
            if j < waypoints.len() {
                j += 1;
            }
            d
        })
        .collect();
}

/// One bin of [`EvalReport::by_coverage`]: scored waypoints and their summed error.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CoverageBin {
    /// Scored waypoints in the bin.
    pub count: usize,
    /// Sum of their 2D errors, metres.
    pub error_sum: f64,
}

impl CoverageBin {
    /// Mean 2D error of the bin, metres (`None` when empty).
    pub fn mean(&self) -> Option<f64> {
        (self.count > 0).then(|| self.error_sum / self.count as f64)
    }
}

/// The label of bin `i` of `edges` (metres, increasing): `[a, b)`, the last `b+`, and
/// `unknown` for the points without a coverage distance.
fn bin_label(edges: &[f64], i: usize) -> String {
    match i {
        _ if i == edges.len() + 1 => "unknown".to_string(),
        0 => format!("<{}", edges.first().copied().unwrap_or(f64::INFINITY)),
        _ if i == edges.len() => format!("{}+", edges[i - 1]),
        _ => format!("{}-{}", edges[i - 1], edges[i]),
    }
}

/// Checks bin edges: finite, positive, strictly increasing, at least one.
pub fn validate_edges(edges: &[f64]) -> Result<(), String> {
    if edges.is_empty() {
        return Err("give at least one bin edge (metres), e.g. 5,10,20".into());
    }
    if let Some(e) = edges.iter().find(|e| !(e.is_finite() && **e > 0.0)) {
        return Err(format!("bin edges must be finite and > 0 m, got {e}"));
    }
    if edges.windows(2).any(|w| w[1] <= w[0]) {
        return Err(format!("bin edges must increase, got {edges:?}"));
    }
    Ok(())
}

impl EvalReport {
    /// Pooled errors by the scored waypoint's distance to the fold's nearest measured
    /// reference point ([`coverage_distance`]), in the bins `< edges[0]`, `edges[0]..edges[1]`,
    /// ..., `>= edges[last]`, then one bin of points without a coverage distance (a result
    /// read back from a JSON of an older version): per scheme, one [`CoverageBin`] per bin.
    /// `edges` must pass [`validate_edges`] (otherwise every point lands in the last bins).
    pub fn by_coverage(&self, edges: &[f64]) -> BTreeMap<String, Vec<CoverageBin>> {
        let mut out: BTreeMap<String, Vec<CoverageBin>> = BTreeMap::new();
        for s in &self.schemes {
            out.entry(s.clone())
                .or_insert_with(|| vec![CoverageBin::default(); edges.len() + 2]);
        }
        for w in &self.walks {
            let Some(bins) = out.get_mut(&w.scheme) else {
                continue;
            };
            for (i, (_, e, _)) in w.score.errors.iter().enumerate() {
                if !e.is_finite() {
                    continue;
                }
                let bin = match w.score.coverage_m.get(i).copied().flatten() {
                    Some(d) => edges.iter().take_while(|&&edge| d >= edge).count(),
                    None => edges.len() + 1,
                };
                bins[bin].count += 1;
                bins[bin].error_sum += e;
            }
        }
        out
    }

    /// [`Self::by_coverage`] as a plain-text table: per bin the count and share of the
    /// scored waypoints, and per scheme the mean error there and the bin's share of the
    /// scheme's summed error. The `unknown` row is printed only when it has points.
    pub fn coverage_table(&self, edges: &[f64]) -> String {
        let rows = self.by_coverage(edges);
        let mut out = String::new();
        let _ = write!(out, "  {:<9} {:>6} {:>6}", "gap m", "count", "share");
        for s in &self.schemes {
            let _ = write!(out, " {:>15}", format!("{s} mean/share"));
        }
        let _ = writeln!(out);
        let first = self.schemes.first().and_then(|s| rows.get(s));
        let total_count: usize = first.map_or(0, |r| r.iter().map(|b| b.count).sum());
        for i in 0..edges.len() + 2 {
            let count = first.map_or(0, |r| r[i].count);
            if i == edges.len() + 1 && count == 0 {
                continue;
            }
            let share = if total_count > 0 {
                100.0 * count as f64 / total_count as f64
            } else {
                0.0
            };
            let _ = write!(out, "  {:<9} {count:>6} {share:>5.1}%", bin_label(edges, i));
            for s in &self.schemes {
                let r = &rows[s];
                let total: f64 = r.iter().map(|b| b.error_sum).sum();
                let cell = match r[i].mean() {
                    Some(mean) => {
                        let part = if total > 0.0 {
                            100.0 * r[i].error_sum / total
                        } else {
                            0.0
                        };
                        format!("{mean:.2} / {part:.0}%")
                    }
                    None => "-".to_string(),
                };
                let _ = write!(out, " {cell:>15}");
            }
            let _ = writeln!(out);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::WalkResult;
    use proptest::prelude::*;
    use wipdr_core::Point2;

    fn result(scheme: &str, errs: &[(f64, Option<f64>)]) -> WalkResult {
        let e: Vec<f64> = errs.iter().map(|&(e, _)| e).collect();
        let mut r = crate::report::tests::result_skipping("A", "w", scheme, &e, 0);
        r.score.coverage_m = errs.iter().map(|&(_, d)| d).collect();
        r
    }

    #[test]
    fn nearest_point_on_the_same_floor() {
        let pts = [
            MeasuredPoint {
                position: Point2::new(10.0, 0.0),
                floor: Some(0),
            },
            MeasuredPoint {
                position: Point2::new(1.0, 0.0),
                floor: Some(1),
            },
            MeasuredPoint {
                position: Point2::new(4.0, 0.0),
                floor: None,
            },
        ];
        let at = Point2::new(0.0, 0.0);
        assert_eq!(coverage_distance(at, Some(0), &pts), Some(4.0));
        assert_eq!(coverage_distance(at, Some(1), &pts), Some(1.0));
        assert_eq!(coverage_distance(at, Some(0), &pts[..1]), Some(10.0));
        assert_eq!(coverage_distance(at, None, &[]), None);
    }

    #[test]
    fn bins_add_up_to_the_pooled_figures() {
        let walks = vec![
            result(
                "ekf",
                &[(1.0, Some(2.0)), (3.0, Some(7.0)), (9.0, Some(30.0))],
            ),
            result("ekf", &[(5.0, Some(5.0)), (2.0, None)]),
        ];
        let r = EvalReport::from_walks(vec!["ekf".into()], vec!["A".into()], walks);
        let bins = &r.by_coverage(&[5.0, 10.0])["ekf"];
        let counts: Vec<usize> = bins.iter().map(|b| b.count).collect();
        // <5: 1.0; 5-10: 3.0 and 5.0 (5 is the lower edge); 10+: 9.0; unknown: 2.0.
        assert_eq!(counts, vec![1, 2, 1, 1]);
        assert_eq!(bins[1].mean(), Some(4.0));
        let n: usize = counts.iter().sum();
        let sum: f64 = bins.iter().map(|b| b.error_sum).sum();
        assert_eq!(n, r.pooled["ekf"].count);
        assert!((sum / n as f64 - r.pooled["ekf"].mean).abs() < 1e-12);
        let t = r.coverage_table(&[5.0, 10.0]);
        assert!(t.contains("5-10") && t.contains("4.00 / 40%"), "{t}");
        assert!(t.contains("10+") && t.contains("unknown"), "{t}");
    }

    #[test]
    fn the_unknown_row_is_left_out_when_empty() {
        let r = EvalReport::from_walks(
            vec!["wifi".into()],
            vec!["A".into()],
            vec![result("wifi", &[(1.0, Some(1.0))])],
        );
        let t = r.coverage_table(&[5.0]);
        assert!(!t.contains("unknown") && t.contains("<5"), "{t}");
    }

    #[test]
    fn coverage_is_attached_to_the_scored_waypoints_only() {
        let wps: Vec<Waypoint> = (0..4)
            .map(|i| Waypoint::new(10 * i, Point2::new(0.0, 0.0)))
            .collect();
        let per_waypoint = [Some(1.0), Some(2.0), None, Some(4.0)];
        // Waypoint 0 skipped (before the first estimate).
        let mut score = WalkScore {
            errors: vec![(10, 0.5, Some(0)), (20, 0.5, Some(0)), (30, 0.5, Some(0))],
            ..WalkScore::default()
        };
        attach_coverage(&mut score, &wps, &per_waypoint);
        assert_eq!(score.coverage_m, vec![Some(2.0), None, Some(4.0)]);
    }

    #[test]
    fn edges_are_checked() {
        assert!(validate_edges(&[5.0, 10.0]).is_ok());
        assert!(validate_edges(&[]).is_err());
        assert!(validate_edges(&[10.0, 5.0]).is_err());
        assert!(validate_edges(&[0.0, 5.0]).is_err());
        assert!(validate_edges(&[f64::NAN]).is_err());
    }

    proptest! {
        #[test]
        fn the_distance_is_the_minimum_over_matching_points(
            xs in proptest::collection::vec((-50.0..50.0f64, -50.0..50.0f64, 0..3i32), 1..20),
            qx in -50.0..50.0f64, qy in -50.0..50.0f64, qf in 0..3i32,
        ) {
            let pts: Vec<MeasuredPoint> = xs.iter().map(|&(x, y, f)| MeasuredPoint {
                position: Point2::new(x, y), floor: Some(f) }).collect();
            let q = Point2::new(qx, qy);
            let d = coverage_distance(q, Some(qf), &pts);
            let same: Vec<f64> = pts.iter().filter(|p| p.floor == Some(qf))
                .map(|p| (p.position - q).norm()).collect();
            match d {
                None => prop_assert!(same.is_empty()),
                Some(d) => {
                    prop_assert!(same.iter().all(|&s| d <= s));
                    prop_assert!(same.contains(&d));
                }
            }
        }
    }
}

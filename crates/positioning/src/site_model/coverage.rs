//! Where a site model's radio map has measured fingerprints: the reference points a
//! position's distance to coverage is measured against.

use serde::{Deserialize, Serialize};
use wipdr_core::Point2;
use wipdr_fingerprint::RadioMap;

/// A measured reference point of a radio map: where the training data has fingerprints.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MeasuredPoint {
    /// Position in the floor (or building) frame, metres.
    pub position: Point2,
    /// Floor, where the map has floors.
    pub floor: Option<i32>,
}

/// The reference points of `map` as [`MeasuredPoint`]s (position and floor).
pub fn measured_points(map: &RadioMap) -> Vec<MeasuredPoint> {
    map.points()
        .iter()
        .map(|p| MeasuredPoint {
            position: p.position,
            floor: p.floor,
        })
        .collect()
}

/// The 2D distance (metres) from `position` to the nearest point of `points` on `floor`
/// (a point without a floor, or a `floor` of `None`, matches any floor). `None` when no
/// point matches.
///
/// ```
/// use wipdr_core::Point2;
/// use wipdr_positioning::site_model::{MeasuredPoint, coverage_distance};
/// let map = [MeasuredPoint { position: Point2::new(0.0, 0.0), floor: Some(0) },
///            MeasuredPoint { position: Point2::new(3.0, 4.0), floor: Some(-2) }];
/// // On floor 0 the point on floor -2 does not count; without a floor every point does.
/// assert_eq!(coverage_distance(Point2::new(3.0, 4.0), Some(0), &map), Some(5.0));
/// assert_eq!(coverage_distance(Point2::new(3.0, 4.0), None, &map), Some(0.0));
/// assert_eq!(coverage_distance(Point2::new(3.0, 4.0), Some(1), &map), None);
/// ```
pub fn coverage_distance(
    position: Point2,
    floor: Option<i32>,
    points: &[MeasuredPoint],
) -> Option<f64> {
    points
        .iter()
        .filter(|p| match (floor, p.floor) {
            (Some(f), Some(g)) => f == g,
            _ => true,
        })
        .map(|p| (p.position - position).norm())
        .filter(|d| d.is_finite())
        .min_by(f64::total_cmp)
}

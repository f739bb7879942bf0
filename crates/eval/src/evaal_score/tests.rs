//! The scorer's rules on tiny hand-made trials (the official files: test `evaal_official`).

use super::*;
use proptest::prelude::*;

const LAT0: f64 = 49.4611;
/// East of Greenwich by less than 10 degrees, where the swap check can tell (module docs).
const LON0: f64 = 2.1734;

/// Metres per degree of latitude at [`LAT0`] and the scorer's altitude: `(M + h) pi / 180`
/// with the meridian radius `M` (a first-order figure, good to 1e-5 m over 10 m).
fn metres_per_degree_north() -> f64 {
    use wipdr_core::geo::{WGS84_A, WGS84_E2};
    let s = LAT0.to_radians().sin();
    let m = WGS84_A * (1.0 - WGS84_E2) / (1.0 - WGS84_E2 * s * s).powf(1.5);
    (m + EVAAL_ALTITUDE_M).to_radians()
}

fn truth_at(t_s: f64, floor: i32, number: u32) -> EvaalTruthPoint {
    EvaalTruthPoint {
        t_s,
        lon_deg: LON0,
        lat_deg: LAT0,
        floor,
        number,
    }
}

/// An estimate `north_m` metres north of the truth points.
fn est(pts_s: f64, north_m: f64, floor: f64) -> EvaalEstimate {
    EvaalEstimate {
        pts_s,
        wall_clock_s: 0.0,
        horizon_s: 0.5,
        slack_s: 15.0,
        lon_deg: LON0,
        lat_deg: LAT0 + north_m / metres_per_degree_north(),
        floor,
    }
}

fn swap(e: EvaalEstimate) -> EvaalEstimate {
    EvaalEstimate {
        lon_deg: e.lat_deg,
        lat_deg: e.lon_deg,
        ..e
    }
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() < 1e-4
}

#[test]
fn every_column_of_a_hand_made_trial() {
    let truth = [
        truth_at(10.0, 0, 1),
        truth_at(20.0, 0, 2),
        truth_at(30.0, 0, 3),
        truth_at(40.0, -1, 4),
    ];
    let estimates = [
        est(10.0, 1.0, 0.0),
        est(20.0, 2.0, 0.0),
        est(30.0, 3.0, -0.0),
        est(39.0, 4.0, 0.0), // one floor off, 1 s early
    ];
    let s = evaal_score(&truth, &estimates).unwrap();
    // Sample errors 1, 2, 3, 4 + 15 = 19, at cumulative probabilities 1/8, 3/8, 5/8, 7/8.
    assert!(close(s.evaal, 11.0), "{s:?}"); // halfway between 3 and 19
    assert!(close(s.mean, 6.25), "{s:?}");
    assert!(close(s.rmse, (375.0_f64 / 4.0).sqrt()), "{s:?}");
    assert!(close(s.median, 2.5), "{s:?}");
    assert!(close(s.p95, 19.0), "{s:?}"); // above 7/8: the maximum
    assert_eq!(s.fhr_percent, 75.0);
    assert!(close(s.mpe_xy, 2.5), "{s:?}");
    assert_eq!(s.points, 3); // the last point's estimate is 1 s away
}

#[test]
fn the_latest_estimate_up_to_10_ms_after_the_point_is_chosen() {
    let e = [
        est(0.0, 0.0, 0.0),
        est(1.0, 0.0, 0.0),
        est(1.009, 0.0, 0.0),
        est(1.011, 0.0, 0.0),
        est(3.0, 0.0, 0.0),
        est(3.0, 0.0, 0.0),
    ];
    assert_eq!(choose_estimate(&e, 1.0), Some(2));
    assert_eq!(choose_estimate(&e, 0.998), Some(1));
    assert_eq!(choose_estimate(&e, 2.99), Some(5)); // one time twice: the later in the file
    assert_eq!(choose_estimate(&e, 100.0), Some(5));
    assert_eq!(choose_estimate(&e, -0.011), None);
    assert_eq!(choose_estimate(&e, -0.009), Some(0));
    // By time, not by file order.
    let unsorted = [est(2.0, 0.0, 0.0), est(1.0, 0.0, 0.0)];
    assert_eq!(choose_estimate(&unsorted, 1.5), Some(1));
    assert_eq!(choose_estimate(&unsorted, 2.5), Some(0));
}

#[test]
fn the_chosen_estimate_sets_the_error_and_points_counts_those_within_half_a_second() {
    let truth = [
        truth_at(10.0, 0, 1),
        truth_at(20.0, 0, 2),
        truth_at(30.0, 0, 3),
    ];
    let estimates = [
        est(9.5, 5.0, 0.0),    // 0.5 s before point 1: counted
        est(10.02, 50.0, 0.0), // 20 ms late: never chosen for point 1
        est(19.4, 7.0, 0.0),   // 0.6 s before point 2: not counted
        est(30.005, 2.0, 0.0), // 5 ms late: chosen for point 3
    ];
    let r = evaal_scoring(&truth, &estimates).unwrap();
    let chosen: Vec<usize> = r.samples.iter().map(|s| s.estimate).collect();
    assert_eq!(chosen, vec![0, 2, 3]);
    let horizontal: Vec<f64> = r.samples.iter().map(|s| s.horizontal_m).collect();
    assert!(
        horizontal
            .iter()
            .zip([5.0, 7.0, 2.0])
            .all(|(a, b)| close(*a, b))
    );
    assert_eq!(r.score.points, 2);
}

#[test]
fn a_point_before_every_estimate_is_an_error() {
    let truth = [truth_at(1.0, 0, 7)];
    let e = evaal_score(&truth, &[est(1.02, 0.0, 0.0)]).unwrap_err();
    assert_eq!(
        e,
        EvaalScoreError::NoEstimateBefore {
            number: 7,
            t_s: 1.0,
            first_pts_s: 1.02
        }
    );
}

#[test]
fn swapped_coordinates_are_swapped_back_when_the_latitude_median_is_under_10() {
    let truth = [truth_at(10.0, 0, 1), truth_at(20.0, 0, 2)];
    let straight = [est(10.0, 3.0, 0.0), est(20.0, 4.0, 0.0)];
    let swapped: Vec<EvaalEstimate> = straight.iter().copied().map(swap).collect();
    assert!(!coordinates_swapped(&straight));
    assert!(coordinates_swapped(&swapped));
    let a = evaal_scoring(&truth, &straight).unwrap();
    let b = evaal_scoring(&truth, &swapped).unwrap();
    assert!(!a.coordinates_swapped && b.coordinates_swapped);
    assert_eq!(a.score, b.score);
    assert!(close(a.score.mpe_xy, 3.5));

    // The median decides, not any one estimate: one swapped estimate of three stays as
    // written (and is then thousands of kilometres off).
    let mixed = [straight[0], swap(est(15.0, 0.0, 0.0)), straight[1]];
    assert!(!coordinates_swapped(&mixed));
    let r = evaal_scoring(&[truth_at(15.0, 0, 1)], &mixed).unwrap();
    assert!(r.score.mpe_xy > 1e6);
    // Strictly under 10: a median of exactly 10 is not swapped.
    let mut ten = [est(1.0, 0.0, 0.0), est(2.0, 0.0, 0.0)];
    ten[0].lat_deg = 9.0;
    ten[1].lat_deg = 11.0;
    assert!(!coordinates_swapped(&ten));
    ten[1].lat_deg = 10.99;
    assert!(coordinates_swapped(&ten));
}

#[test]
fn the_tangent_plane_sits_at_the_smallest_latitude_and_longitude_of_the_truth() {
    let mut a = truth_at(10.0, 0, 1);
    let mut b = truth_at(20.0, 0, 2);
    (a.lat_deg, a.lon_deg) = (49.462, 11.110);
    (b.lat_deg, b.lon_deg) = (49.461, 11.112);
    let estimates = [est(0.0, 0.0, 0.0)];
    let r = evaal_scoring(&[a, b], &estimates).unwrap();
    assert_eq!(r.origin_deg, (49.461, 11.110));
    // The distance between two points does not depend on the origin nearby (to 0.1 mm).
    let plane = TangentPlane::new(49.461, 11.110, EVAAL_ALTITUDE_M);
    let [x, y, _] = plane.enu(a.lat_deg, a.lon_deg, EVAAL_ALTITUDE_M);
    let [ex, ey, _] = plane.enu(estimates[0].lat_deg, estimates[0].lon_deg, EVAAL_ALTITUDE_M);
    assert!((r.samples[0].horizontal_m - (x - ex).hypot(y - ey)).abs() < 1e-9);
}

#[test]
fn floor_errors_add_15_m_per_floor_whatever_their_sign() {
    assert_eq!(evaal_sample_error(2.0, -2.0), 32.0);
    assert_eq!(evaal_sample_error(2.0, 1.0), 17.0);
    assert_eq!(evaal_sample_error(2.0, 0.5), 9.5);
    let truth = [truth_at(1.0, -1, 1), truth_at(2.0, -1, 2)];
    let r = evaal_scoring(&truth, &[est(1.0, 0.0, 1.0), est(2.0, 0.0, -1.5)]).unwrap();
    let errors: Vec<f64> = r.samples.iter().map(|s| s.error_m).collect();
    assert!(
        close(errors[0], 30.0) && close(errors[1], 7.5),
        "{errors:?}"
    );
    assert_eq!(r.score.fhr_percent, 0.0);
}

#[test]
fn inputs_that_cannot_be_scored_are_typed_errors() {
    let truth = [truth_at(1.0, 0, 1)];
    let e = [est(0.0, 0.0, 0.0)];
    assert_eq!(evaal_score(&[], &e), Err(EvaalScoreError::NoTruth));
    assert_eq!(evaal_score(&truth, &[]), Err(EvaalScoreError::NoEstimates));
    let mut bad = truth;
    bad[0].lat_deg = f64::NAN;
    assert!(matches!(
        evaal_score(&bad, &e),
        Err(EvaalScoreError::NonFiniteTruth {
            field: "latitude",
            ..
        })
    ));
    let mut bad = [e[0], e[0]];
    bad[1].pts_s = f64::INFINITY;
    assert_eq!(
        evaal_score(&truth, &bad),
        Err(EvaalScoreError::NonFiniteEstimate {
            index: 1,
            field: "pts"
        })
    );
    bad[1].pts_s = 0.5;
    bad[1].floor = 1e300;
    assert_eq!(
        evaal_score(&truth, &bad),
        Err(EvaalScoreError::FloorOutOfRange {
            index: 1,
            floor: 1e300
        })
    );
}

fn finite_and_ordered(s: &EvaalScore, n: usize) -> Result<(), TestCaseError> {
    let figures = [
        s.evaal,
        s.mean,
        s.rmse,
        s.median,
        s.p95,
        s.fhr_percent,
        s.mpe_xy,
    ];
    prop_assert!(figures.iter().all(|v| v.is_finite() && *v >= 0.0), "{s:?}");
    prop_assert!(s.median <= s.evaal && s.evaal <= s.p95, "{s:?}");
    prop_assert!(s.mean <= s.rmse * (1.0 + 1e-12), "{s:?}");
    prop_assert!(s.mpe_xy <= s.mean * (1.0 + 1e-12), "{s:?}");
    prop_assert!(s.fhr_percent <= 100.0 && s.points <= n, "{s:?}");
    Ok(())
}

fn same(a: &EvaalScore, b: &EvaalScore) -> bool {
    let pairs = [
        (a.evaal, b.evaal),
        (a.mean, b.mean),
        (a.rmse, b.rmse),
        (a.median, b.median),
        (a.p95, b.p95),
        (a.fhr_percent, b.fhr_percent),
        (a.mpe_xy, b.mpe_xy),
    ];
    a.points == b.points
        && pairs
            .iter()
            .all(|(x, y)| (x - y).abs() <= 1e-9 * (1.0 + x.abs()))
}

proptest! {
    #[test]
    fn scores_are_finite_ordered_and_independent_of_input_order(
        points in proptest::collection::vec((0.0f64..100.0, -1e-3f64..1e-3, -1e-3f64..1e-3, -2i32..=0), 1..25),
        est_times in proptest::collection::btree_set(0u32..10_000, 1..40),
        offsets in proptest::collection::vec((-1e-3f64..1e-3, -1e-3f64..1e-3, -3i32..=1), 40),
        rotate in 0usize..25,
    ) {
        let truth: Vec<EvaalTruthPoint> = points
            .iter()
            .enumerate()
            .map(|(i, &(t_s, dlat, dlon, floor))| EvaalTruthPoint {
                t_s,
                lon_deg: LON0 + dlon,
                lat_deg: LAT0 + dlat,
                floor,
                number: u32::try_from(i).unwrap_or(u32::MAX),
            })
            .collect();
        // Distinct times (0.01 s steps from -0.5 s), and one before every truth point.
        let estimates: Vec<EvaalEstimate> = est_times
            .iter()
            .zip(&offsets)
            .map(|(&t, &(dlat, dlon, floor))| EvaalEstimate {
                lat_deg: LAT0 + dlat,
                lon_deg: LON0 + dlon,
                floor: f64::from(floor),
                ..est(f64::from(t) * 0.01 - 0.5, 0.0, 0.0)
            })
            .chain(std::iter::once(est(-1.0, 0.0, 0.0)))
            .collect();
        let r = evaal_scoring(&truth, &estimates).unwrap();
        prop_assert!(!r.coordinates_swapped);
        finite_and_ordered(&r.score, truth.len())?;

        // Swapped coordinates are swapped back: the same figures.
        let swapped: Vec<EvaalEstimate> = estimates.iter().copied().map(swap).collect();
        let rs = evaal_scoring(&truth, &swapped).unwrap();
        prop_assert!(rs.coordinates_swapped);
        prop_assert_eq!(rs.score, r.score);

        let mut truth2 = truth.clone();
        truth2.rotate_left(rotate % truth.len());
        truth2.reverse();
        let mut est2 = estimates.clone();
        est2.reverse();
        let s2 = evaal_score(&truth2, &est2).unwrap();
        prop_assert!(same(&r.score, &s2), "{:?} vs {:?}", r.score, s2);
    }
}

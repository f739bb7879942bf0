use super::*;
use crate::radio_map::{ApVocabulary, RadioMapConfig, ReferencePoint};
use proptest::prelude::*;
use wipdr_core::Bssid;

/// APs by position; the noise-free log-distance RSS at `p`.
fn rss(ap: Point2, p: Point2) -> f32 {
    (-30.0 - 25.0 * ((p - ap).norm() + 1.0).log10()) as f32
}

/// A 40 x 20 m floor surveyed every 2 m, four APs in its corners (or the ones given).
fn floor_map(aps: &[Point2], width: f64, height: f64) -> RadioMap {
    let vocabulary = ApVocabulary::from_bssids((0..aps.len() as u64).map(|k| Bssid(k + 1)));
    let mut map = RadioMap::new(vocabulary, RadioMapConfig::default());
    let mut y = 0.0;
    while y <= height {
        let mut x = 0.0;
        while x <= width {
            let p = Point2::new(x, y);
            let rp = ReferencePoint {
                position: p,
                z: None,
                floor: Some(0),
                building: None,
                scans: 1,
            };
            let mean: Vec<Option<f32>> = aps.iter().map(|&a| Some(rss(a, p))).collect();
            map.push_point(rp, &mean, None).unwrap();
            x += 2.0;
        }
        y += 2.0;
    }
    map
}

fn corners() -> Vec<Point2> {
    vec![
        Point2::new(0.0, 0.0),
        Point2::new(40.0, 0.0),
        Point2::new(0.0, 20.0),
        Point2::new(40.0, 20.0),
    ]
}

fn scan_at(aps: &[Point2], p: Point2, offset: f32) -> WifiScan {
    WifiScan::from_readings(
        0,
        aps.iter()
            .enumerate()
            .map(|(k, &a)| (Bssid(k as u64 + 1), f64::from(rss(a, p) + offset))),
    )
}

#[test]
fn the_most_likely_cell_is_where_the_scan_was_taken() {
    let aps = corners();
    let model =
        ScanLikelihood::fit(&floor_map(&aps, 40.0, 20.0), &LikelihoodConfig::default()).unwrap();
    for truth in [
        Point2::new(13.0, 7.0),
        Point2::new(31.0, 15.0),
        Point2::new(4.0, 17.0),
    ] {
        let raster = model
            .raster(Some(0), &scan_at(&aps, truth, 0.0), 0.0)
            .unwrap();
        let best = raster.best().unwrap();
        assert!((best - truth).norm() <= 2.5, "{truth:?}: {best:?}");
        // A device reading 6 dB high, with its offset given, lands at the same place.
        let offset = model
            .raster(Some(0), &scan_at(&aps, truth, 6.0), 6.0)
            .unwrap();
        assert_eq!(offset.best(), Some(best));
    }
}

#[test]
fn the_value_at_a_point_is_its_cells_value_in_the_raster() {
    let aps = corners();
    let config = LikelihoodConfig {
        max_scan_aps: 3,
        ..Default::default()
    };
    let model = ScanLikelihood::fit(&floor_map(&aps, 40.0, 20.0), &config).unwrap();
    // Four APs with a cap of three: the weakest is heard but not scored.
    let scan = scan_at(&aps, Point2::new(13.0, 7.0), 0.0);
    let raster = model.raster(Some(0), &scan, 2.0).unwrap();
    for p in [
        Point2::new(13.0, 7.0),
        Point2::new(0.5, 19.5),
        Point2::new(-8.0, -8.0),
        Point2::new(39.0, 1.0),
    ] {
        let i = raster.grid.index_of(p).unwrap();
        assert_eq!(
            model.at(Some(0), p, &scan, 2.0),
            raster.log_likelihood[i],
            "{p:?}"
        );
    }
    assert_eq!(model.at(Some(0), Point2::new(1e6, 0.0), &scan, 0.0), None);
    assert_eq!(model.at(Some(1), Point2::new(13.0, 7.0), &scan, 0.0), None);
}

#[test]
fn an_unknown_ap_changes_nothing_and_one_wrong_reading_does_not_move_the_best_far() {
    let aps = corners();
    let model =
        ScanLikelihood::fit(&floor_map(&aps, 40.0, 20.0), &LikelihoodConfig::default()).unwrap();
    let truth = Point2::new(13.0, 7.0);
    let scan = scan_at(&aps, truth, 0.0);
    let base = model.raster(Some(0), &scan, 0.0).unwrap();
    let mut with_new = scan.clone();
    with_new
        .entries
        .push(WifiScan::from_readings(0, [(Bssid(99), -40.0)]).entries[0].clone());
    let new = model.raster(Some(0), &with_new, 0.0).unwrap();
    assert_eq!(base.log_likelihood, new.log_likelihood);
    let mut wrong = scan.clone();
    wrong.entries[3].rssi_dbm += 30.0;
    let best = model.raster(Some(0), &wrong, 0.0).unwrap().best().unwrap();
    assert!((best - truth).norm() <= 6.0, "{best:?}");
}

#[test]
fn a_scan_that_fits_two_places_keeps_both() {
    // One AP in the middle of a 40 m corridor: a scan 10 m from it fits x = 10 and x = 30.
    // Untempered (evidence_scale 1), so the two modes stand out; the default only flattens
    // them alike.
    let aps = [Point2::new(20.0, 0.0)];
    let config = LikelihoodConfig {
        evidence_scale: 1.0,
        ..Default::default()
    };
    let model = ScanLikelihood::fit(&floor_map(&aps, 40.0, 0.0), &config).unwrap();
    let raster = model
        .raster(Some(0), &scan_at(&aps, Point2::new(10.0, 0.0), 0.0), 0.0)
        .unwrap();
    let post = raster.posterior().unwrap();
    let mass_near = |x: f64| -> f64 {
        post.iter()
            .enumerate()
            .filter(|(i, _)| (raster.grid.centre_of_index(*i).x - x).abs() <= 4.0)
            .map(|(_, p)| p)
            .sum()
    };
    let (left, right) = (mass_near(10.0), mass_near(30.0));
    assert!(left > 0.3 && right > 0.3, "{left} {right}");
    // The AP's own place (where the scan would read -30 dBm) is at least 5 times less likely than
    // either mode (the kernel blurs its steep field): the column x = 20 against x = 10.
    let column = |x: f64| -> f64 {
        post.iter()
            .enumerate()
            .filter(|(i, _)| (raster.grid.centre_of_index(*i).x - x).abs() < 1.0)
            .map(|(_, p)| p)
            .sum()
    };
    assert!(
        column(20.0) < 0.2 * column(10.0),
        "{} {}",
        column(20.0),
        column(10.0)
    );
    assert!((left - right).abs() < 0.05, "{left} {right}");
}

#[test]
fn cells_out_of_reach_have_no_likelihood_and_the_posterior_sums_to_one() {
    let aps = corners();
    let config = LikelihoodConfig::default();
    let model = ScanLikelihood::fit(&floor_map(&aps, 40.0, 20.0), &config).unwrap();
    let raster = model
        .raster(Some(0), &scan_at(&aps, Point2::new(20.0, 10.0), 0.0), 0.0)
        .unwrap();
    // The raster's corner cells lie farther than support_m from every reference point.
    assert_eq!(raster.log_likelihood[0], None);
    assert!(
        raster
            .log_likelihood
            .iter()
            .flatten()
            .all(|v| v.is_finite())
    );
    let total: f64 = raster.posterior().unwrap().iter().sum();
    assert!((total - 1.0).abs() < 1e-9, "{total}");
    assert!(
        model
            .raster(Some(3), &scan_at(&aps, Point2::new(20.0, 10.0), 0.0), 0.0)
            .is_none()
    );
    assert_eq!(model.floors().collect::<Vec<_>>(), vec![Some(0)]);
}

#[test]
fn bad_settings_and_maps_are_typed_errors_naming_the_field() {
    let map = floor_map(&corners(), 40.0, 20.0);
    let cases = [
        (
            LikelihoodConfig {
                cell_m: 0.0,
                ..Default::default()
            },
            "likelihood.cell_m",
        ),
        (
            LikelihoodConfig {
                kernel_m: f64::NAN,
                ..Default::default()
            },
            "likelihood.kernel_m",
        ),
        (
            LikelihoodConfig {
                support_m: 1.0,
                ..Default::default()
            },
            "likelihood.support_m",
        ),
        (
            LikelihoodConfig {
                outlier: 1.0,
                ..Default::default()
            },
            "likelihood.outlier",
        ),
        (
            LikelihoodConfig {
                detection_prior: -0.1,
                ..Default::default()
            },
            "likelihood.detection_prior",
        ),
        (
            LikelihoodConfig {
                max_scan_aps: 0,
                ..Default::default()
            },
            "likelihood.max_scan_aps",
        ),
        (
            LikelihoodConfig {
                max_cells: 10,
                ..Default::default()
            },
            "likelihood.max_cells",
        ),
        (
            LikelihoodConfig {
                max_field_cells: 10,
                ..Default::default()
            },
            "likelihood.max_field_cells",
        ),
    ];
    for (config, field) in cases {
        let err = ScanLikelihood::fit(&map, &config).unwrap_err().to_string();
        assert!(err.contains(field), "{field}: {err}");
    }
    let empty = RadioMap::new(ApVocabulary::default(), RadioMapConfig::default());
    assert!(matches!(
        ScanLikelihood::fit(&empty, &LikelihoodConfig::default()),
        Err(FingerprintError::EmptyMap)
    ));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    #[test]
    fn any_valid_scan_gives_finite_values_and_a_best_cell(
        readings in proptest::collection::vec(-120.0f64..=0.0, 1..6),
        offset in -20.0f64..20.0,
    ) {
        let aps = corners();
        let model = ScanLikelihood::fit(&floor_map(&aps, 40.0, 20.0), &LikelihoodConfig::default())
            .unwrap();
        let scan = WifiScan::from_readings(
            0,
            readings.iter().enumerate().map(|(k, &r)| (Bssid(k as u64 + 1), r)),
        );
        let raster = model.raster(Some(0), &scan, offset).unwrap();
        prop_assert!(raster.log_likelihood.iter().flatten().all(|v| v.is_finite()));
        prop_assert!(raster.best().is_some());
        let post = raster.posterior().unwrap();
        prop_assert!(post.iter().all(|p| p.is_finite() && *p >= 0.0));
    }

    /// The raster's passes (run by run over each AP's field) give every cell the same bits
    /// as [`ScanLikelihood::at`] (a look-up per scan AP), scored and past-the-cap APs alike.
    #[test]
    fn every_cell_of_the_raster_is_the_value_at_its_centre(
        readings in proptest::collection::vec(-100.0f64..=-30.0, 1..5),
        offset in -10.0f64..10.0,
        cap in 1usize..4,
    ) {
        let aps = corners();
        let config = LikelihoodConfig { max_scan_aps: cap, ..Default::default() };
        let model = ScanLikelihood::fit(&floor_map(&aps, 40.0, 20.0), &config).unwrap();
        let scan = WifiScan::from_readings(
            0,
            readings.iter().enumerate().map(|(k, &r)| (Bssid(k as u64 + 1), r)),
        );
        let raster = model.raster(Some(0), &scan, offset).unwrap();
        for (i, v) in raster.log_likelihood.iter().enumerate() {
            let at = model.at(Some(0), raster.grid.centre_of_index(i), &scan, offset);
            prop_assert_eq!(at.map(f64::to_bits), v.map(f64::to_bits), "cell {}", i);
        }
    }
}

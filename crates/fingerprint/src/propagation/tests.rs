//! Tests of the path-loss fit and the radio-map extension.

use super::ap_fit::*;
use super::extend::*;
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
    let (models, report) = fit_ap_models_with_report(&map, &PropagationConfig::default()).unwrap();
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
    let (models, report) = fit_ap_models_with_report(&map, &PropagationConfig::default()).unwrap();
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
    let (models, report) = fit_ap_models_with_report(&map, &PropagationConfig::default()).unwrap();
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
    let measured: Vec<Point2> = map.points().iter().map(|p| p.position).collect();
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
        let pt = map.points()[i];
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
                .any(|k| (map.point(k).position - p).norm() <= cfg.max_extrapolation_m);
            assert!(near, "AP {j} at {p:?}");
        }
    }
    assert_eq!(entries, report.entries_added);
    // The gap's middle is covered, the forbidden band is not.
    assert!(
        map.points()[before..]
            .iter()
            .any(|p| p.position == Point2::new(27.0, 3.0))
    );
    assert!(report.points_not_allowed > 0);
    // AP 4 is only heard on the left: never on the far side of the gap.
    for i in before..map.len() {
        if map.point(i).position.x > 12.0 + cfg.max_extrapolation_m {
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
        let p = capped.point(i).position;
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

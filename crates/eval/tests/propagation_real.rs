//! The path-loss extension of the radio map ([`wipdr_fingerprint::propagation`]) on a real
//! floor with coverage gaps (ILC site2/F2): the synthesised fingerprints sit only in walkable
//! gaps, and Wi-Fi alone gets closer to the truth with them than without
//! (docs/results/propagation.md: site2/F2 wifi 12.77 -> 11.40 m with `best.toml`). Skips with
//! a reason when the data root (`$WIPDR_DATA`, else `../shared/data`) lacks the data.

mod common;

use common::real_data;
use wipdr_eval::pipeline::{self, EvalConfig, FloorInput};
use wipdr_fingerprint::propagation::{PropagationConfig, extend_radio_map, fit_ap_models};
use wipdr_fingerprint::walk_map::build_from_walks;
use wipdr_io::cache::read_floor_dir_cached;
use wipdr_io::floor::ReadOptions;

/// Site2/F2 of the ILC data, or `None` (the reason printed) without the data.
fn site2_f2() -> Option<FloorInput> {
    let (root, cache) = real_data()?;
    let data =
        read_floor_dir_cached(root.join("site2/F2"), &cache, &ReadOptions::default()).unwrap();
    Some(FloorInput::new("site2/F2", data.into_floor()))
}

#[test]
fn synthesised_fingerprints_fill_walkable_gaps_only() {
    let Some(floor) = site2_f2() else {
        return;
    };
    let ids: Vec<&str> = floor
        .data
        .walks
        .iter()
        .map(|w| w.meta.id.as_str())
        .collect();
    let folds = wipdr_eval::fold_rules::folds_by_name(&ids);
    let training = floor
        .data
        .walks
        .iter()
        .zip(&folds)
        .filter(|(_, f)| **f != 0)
        .map(|(w, _)| w);
    let (mut map, _) = build_from_walks(training, &Default::default()).unwrap();
    let measured: Vec<_> = map.points().iter().map(|p| p.position).collect();
    let cfg = PropagationConfig::default();
    let models = fit_ap_models(&map, &cfg).unwrap();
    let plan = &floor.data.plan;
    let report = extend_radio_map(&mut map, &models, &cfg, |p| plan.is_walkable(p)).unwrap();
    assert!(report.points_added > 20, "{report:?}");
    assert_eq!(map.len(), measured.len() + report.points_added);
    for (i, p) in map.points().iter().enumerate().skip(measured.len()) {
        assert_eq!(p.scans, 0);
        assert!(plan.is_walkable(p.position), "{:?}", p.position);
        let nearest = measured
            .iter()
            .map(|m| (m - p.position).norm())
            .fold(f64::INFINITY, f64::min);
        assert!(nearest >= cfg.min_gap_m - 1e-9, "{nearest}");
        let heard: Vec<f32> = map.heard(i).map(|(_, r)| r).collect();
        assert!(heard.len() >= cfg.min_aps, "{}", heard.len());
        assert!(
            heard
                .iter()
                .all(|&r| f64::from(r) >= cfg.min_predicted_dbm - 1e-3)
        );
    }
}

#[test]
fn wifi_gets_closer_to_the_truth_in_coverage_gaps() {
    let Some(floor) = site2_f2() else {
        return;
    };
    let floors = std::slice::from_ref(&floor);
    let schemes = vec!["wifi".to_string()];
    let mean_of = |cfg: &EvalConfig| {
        let prepared = pipeline::prepare(floors, cfg).unwrap();
        let report = pipeline::run_prepared(floors, &prepared, cfg, &schemes, &|| {}).unwrap();
        report.pooled["wifi"]
    };
    // The defaults extend the map (-85 dBm); without = the same config with it off.
    let with = EvalConfig::default();
    assert_eq!(
        with.fit.propagation.as_ref().map(|p| p.min_predicted_dbm),
        Some(-85.0)
    );
    let mut without = with.clone();
    without.fit.propagation = None;
    let without = mean_of(&without);
    let with = mean_of(&with);
    println!(
        "site2/F2 wifi mean: {:.2} without, {:.2} with the extension",
        without.mean, with.mean
    );
    assert_eq!(with.count, without.count);
    assert!(
        with.mean < without.mean - 0.5,
        "{} vs {}",
        with.mean,
        without.mean
    );
}

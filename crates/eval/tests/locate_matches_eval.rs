//! `wipdr locate`'s protocol (a walk's raw samples streamed one by one through a whole
//! `Positioner`) gives, scored at the walk's waypoints, exactly the per-walk errors of the
//! evaluation, for every scheme: eval runs the same pipeline.

use wipdr_eval::pipeline::{self, EvalConfig};
use wipdr_eval::scoring::{TrackPoint, score_track};

mod common;
use common::fixture_floor;

fn check(cfg: &EvalConfig) {
    let floor = fixture_floor();
    let schemes: Vec<String> = wipdr_fusion::scheme_names()
        .iter()
        .map(|s| s.to_string())
        .collect();
    let report = pipeline::evaluate(std::slice::from_ref(&floor), cfg, &schemes, &|| {}).unwrap();
    let mut compared = 0;
    // One walk of each fold, every scheme.
    for fold in 0..wipdr_eval::fold_rules::FOLDS {
        let result = report
            .walks
            .iter()
            .find(|w| w.fold == fold)
            .expect("a walk in every fold");
        let walk = floor
            .data
            .walks
            .iter()
            .find(|w| w.meta.id == result.walk)
            .unwrap();
        for scheme in &schemes {
            let from_eval = report
                .walks
                .iter()
                .find(|w| w.walk == result.walk && &w.scheme == scheme)
                .unwrap();
            let track: Vec<_> = pipeline::locate(&floor, &result.walk, scheme, cfg)
                .unwrap()
                .into_iter()
                .map(|e| TrackPoint::from(&e))
                .collect();
            let from = cfg
                .score_from_first_scan
                .then(|| walk.wifi.first().map(|s| s.t))
                .flatten();
            let mut located = score_track(&walk.waypoints, &track, from);
            assert!(!located.errors.is_empty(), "{scheme}: nothing scored");
            // The coverage distances annotate the waypoints (scheme-independent), not the
            // estimates: eval attaches them, a located track carries none.
            assert_eq!(from_eval.score.coverage_m.len(), located.errors.len());
            located.coverage_m = from_eval.score.coverage_m.clone();
            assert_eq!(
                located, from_eval.score,
                "{scheme} on walk {}: locate and eval differ",
                result.walk
            );
            compared += 1;
        }
    }
    assert_eq!(compared, wipdr_eval::fold_rules::FOLDS * schemes.len());
}

#[test]
fn locate_equals_eval_for_every_scheme_default_config() {
    check(&EvalConfig::default());
}

#[test]
fn locate_equals_eval_for_every_scheme_with_map_matching_and_med() {
    let cfg = EvalConfig::from_toml(
        "map_matching = true\n[matcher]\nkind = \"med\"\nwindow = 2\n[static_start]\n",
        "test",
    )
    .unwrap();
    check(&cfg);
}

#[test]
fn offline_locate_is_positioner_smooth_and_equals_offline_eval() {
    check(&EvalConfig {
        offline: true,
        ..EvalConfig::default()
    });
}

#[test]
fn locate_equals_eval_with_the_papers_settings() {
    let cfg = EvalConfig::from_toml("preset = \"paper\"\n", "test").unwrap();
    assert_eq!(cfg, EvalConfig::paper());
    check(&cfg);
}

/// With the learned odometry the motion events come from the network, live in `locate` and
/// prepared once in eval: the same errors, causal and offline.
#[test]
fn locate_equals_eval_with_learned_odometry() {
    let cfg = EvalConfig::from_toml("odometry = \"learned\"\n", "test").unwrap();
    assert_eq!(
        cfg.positioner.odometry,
        wipdr_positioning::config::Odometry::Learned
    );
    check(&cfg);
    check(&EvalConfig {
        offline: true,
        ..cfg
    });
}

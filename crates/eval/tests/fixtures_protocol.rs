//! The protocol on the committed synthetic fixtures (`fixtures/sim/`): no test-walk waypoint
//! reaches a scheme, per-walk and pooled figures agree, and an interrupted sweep resumed
//! ends with the same file as an uninterrupted one.

use wipdr_eval::pipeline::{self, EvalConfig, FloorInput};
use wipdr_eval::sweep::{self, SweepOptions, SweepSpec};
use wipdr_fingerprint::MatcherConfig;

mod common;
use common::fixture_floor;

fn fused_schemes() -> Vec<String> {
    wipdr_fusion::scheme_names()
        .iter()
        .filter(|s| **s != "pdr")
        .map(|s| s.to_string())
        .collect()
}

/// A scheme that peeked at a test walk's waypoints would change its track when they move.
#[test]
fn test_walk_waypoints_never_reach_a_scheme() {
    let floor = fixture_floor();
    let cfg = EvalConfig::default();
    let before = pipeline::prepare(std::slice::from_ref(&floor), &cfg).unwrap();
    let victim = before[0].walk.clone();
    let victim_fold = before[0].fold;

    // Move every waypoint of the victim walk far away.
    let mut data = (*floor.data).clone();
    let w = data.walks.iter_mut().find(|w| w.meta.id == victim).unwrap();
    for wp in &mut w.waypoints {
        wp.position += wipdr_core::Vector2::new(500.0, -300.0);
    }
    let moved = FloorInput::new(floor.label.clone(), data);
    let after = pipeline::prepare(std::slice::from_ref(&moved), &cfg).unwrap();

    // Walks of the victim's fold (the victim included) get identical inputs: their radio map
    // and calibration come from the other folds only.
    for (a, b) in before.iter().zip(&after) {
        assert_eq!(a.walk, b.walk);
        if a.fold == victim_fold {
            assert_eq!(a.steps, b.steps, "steps of {} changed", a.walk);
            assert_eq!(
                a.observations, b.observations,
                "observations of {} changed",
                a.walk
            );
        }
    }
    // Every fused scheme's track of the victim is unchanged.
    let (a, b) = (&before[0], &after[0]);
    let mut seeded = cfg.clone();
    seeded.positioner.seed = 7;
    for s in fused_schemes() {
        let scheme = cfg.scheme(&s).unwrap();
        let ta = pipeline::run_scheme(&scheme, a, None, &seeded).unwrap();
        let tb = pipeline::run_scheme(&scheme, b, None, &seeded).unwrap();
        assert_eq!(ta, tb, "scheme {s} depends on the test walk's waypoints");
        assert!(!ta.is_empty(), "scheme {s} produced no estimate");
    }
    // The PDR baseline starts at the true first waypoint, by the protocol (labelled so).
    let pdr = cfg.scheme("pdr").unwrap();
    let ta = pipeline::run_scheme(&pdr, a, None, &seeded).unwrap();
    let tb = pipeline::run_scheme(&pdr, b, None, &seeded).unwrap();
    let shift = tb[0].position - ta[0].position;
    assert!((shift - wipdr_core::Vector2::new(500.0, -300.0)).norm() < 1e-9);
}

#[test]
fn per_walk_and_pooled_figures_agree() {
    let floor = fixture_floor();
    // The plain Euclidean WKNN (the sanity bound below was set for it; the shared-AP default
    // is tuned for recorded walks, not for the simulator's radio model).
    let mut cfg = EvalConfig::default();
    cfg.positioner.matcher = MatcherConfig::Wknn(wipdr_fingerprint::KnnConfig::default());
    let schemes = vec!["wifi".to_string(), "pdr".to_string(), "ekf".to_string()];
    let report = pipeline::evaluate(std::slice::from_ref(&floor), &cfg, &schemes, &|| {}).unwrap();
    for s in &schemes {
        let walks: Vec<_> = report.walks.iter().filter(|w| &w.scheme == s).collect();
        assert_eq!(
            walks.len(),
            floor.data.walks.len(),
            "every walk is tested once"
        );
        let pooled = report.pooled[s];
        let n: usize = walks.iter().map(|w| w.score.errors.len()).sum();
        let skipped: usize = walks.iter().map(|w| w.score.skipped).sum();
        let total_wp: usize = floor.data.walks.iter().map(|w| w.waypoints.len()).sum();
        assert_eq!(pooled.count, n);
        assert_eq!(pooled.skipped, skipped);
        assert_eq!(
            n + skipped,
            total_wp,
            "every waypoint is scored or counted as skipped"
        );
        let mean = walks.iter().flat_map(|w| w.score.values()).sum::<f64>() / n as f64;
        assert!((pooled.mean - mean).abs() < 1e-9);
        assert_eq!(report.floors["fixture"][s], pooled);
        assert!(pooled.mean.is_finite() && pooled.mean > 0.0);
    }
    // On the synthetic floor Wi-Fi works: fixes within a few metres.
    assert!(
        report.pooled["wifi"].mean < 10.0,
        "{:?}",
        report.pooled["wifi"]
    );
}

#[test]
fn interrupted_and_resumed_sweep_equals_uninterrupted() {
    let floor = fixture_floor();
    let floors = [floor];
    let spec: SweepSpec = toml::from_str(
        r#"
        scheme = "ekf"
        objective = "mean"
        [grid]
        "fuser.r_wifi_m2" = [25.0, 100.0]
        [random]
        samples = 2
        seed = 3
        [random.ranges]
        "fuser.q_position_m2" = { min = 0.5, max = 4.0, log = true }
        "#,
    )
    .unwrap();
    let base = EvalConfig::default();
    let dir = tempfile::tempdir().unwrap();
    let full = dir.path().join("full.csv");
    let resumed = dir.path().join("resumed.csv");
    let o = sweep::run_sweep(
        &spec,
        &base,
        &floors,
        &full,
        &SweepOptions::default(),
        &|| {},
    )
    .unwrap();
    assert!(o.complete);
    assert_eq!(o.rows.len(), 4);

    let stop_early = SweepOptions {
        max_configs: Some(1),
        ..SweepOptions::default()
    };
    let o1 = sweep::run_sweep(&spec, &base, &floors, &resumed, &stop_early, &|| {}).unwrap();
    assert!(!o1.complete);
    assert_eq!(o1.rows.len(), 1);
    // Without --resume an existing file is never overwritten.
    assert!(
        sweep::run_sweep(
            &spec,
            &base,
            &floors,
            &resumed,
            &SweepOptions::default(),
            &|| {}
        )
        .is_err()
    );
    let resume = SweepOptions {
        resume: true,
        ..SweepOptions::default()
    };
    let o2 = sweep::run_sweep(&spec, &base, &floors, &resumed, &resume, &|| {}).unwrap();
    assert!(o2.complete);
    assert_eq!(o2.ran, 3);
    assert_eq!(o2.skipped, 1);
    assert_eq!(
        std::fs::read_to_string(&full).unwrap(),
        std::fs::read_to_string(&resumed).unwrap()
    );
    // Shards merged give the same rows too.
    let s0 = dir.path().join("s0.csv");
    let s1 = dir.path().join("s1.csv");
    for (i, p) in [(0, &s0), (1, &s1)] {
        let opt = SweepOptions {
            shard: Some((i, 2)),
            ..SweepOptions::default()
        };
        sweep::run_sweep(&spec, &base, &floors, p, &opt, &|| {}).unwrap();
    }
    let merged = dir.path().join("merged.csv");
    sweep::merge(&[s0, s1], &merged).unwrap();
    assert_eq!(
        std::fs::read_to_string(&full).unwrap(),
        std::fs::read_to_string(&merged).unwrap()
    );
    let best = o
        .rows
        .iter()
        .map(|r| r.objective)
        .fold(f64::INFINITY, f64::min);
    assert!(best.is_finite());
}

/// MED over a window of one scan is single-scan WKNN on the same map (paper 004 eq. 11 with
/// w = 1), so wiring the PDR displacements in cannot change a one-scan result.
#[test]
fn med_with_a_one_scan_window_equals_single_scan_wknn() {
    let floor = fixture_floor();
    // MED's one-scan case is the Euclidean WKNN.
    let mut knn = EvalConfig::default();
    knn.positioner.matcher = MatcherConfig::Wknn(wipdr_fingerprint::KnnConfig::default());
    let mut med = knn.clone();
    med.positioner.matcher = MatcherConfig::Med(wipdr_fingerprint::med::MedConfig {
        window: 1,
        ..Default::default()
    });
    let a = pipeline::prepare(std::slice::from_ref(&floor), &knn).unwrap();
    let b = pipeline::prepare(std::slice::from_ref(&floor), &med).unwrap();
    let mut compared = 0;
    for (wa, wb) in a.iter().zip(&b) {
        assert_eq!(wa.observations.len(), wb.observations.len());
        for (oa, ob) in wa.observations.iter().zip(&wb.observations) {
            assert!(
                (oa.estimate - ob.estimate).norm() < 1e-3,
                "{:?} vs {:?}",
                oa.estimate,
                ob.estimate
            );
            compared += 1;
        }
    }
    assert!(compared > 100);
    // A longer window uses the history and changes some fixes.
    let mut med2 = EvalConfig::default();
    med2.positioner.matcher = MatcherConfig::Med(wipdr_fingerprint::med::MedConfig::default());
    let c = pipeline::prepare(std::slice::from_ref(&floor), &med2).unwrap();
    let changed = a
        .iter()
        .zip(&c)
        .flat_map(|(wa, wc)| wa.observations.iter().zip(&wc.observations))
        .filter(|(oa, oc)| (oa.estimate - oc.estimate).norm() > 1e-3)
        .count();
    assert!(changed > 0);
}

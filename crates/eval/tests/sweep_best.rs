//! Every results row carries the hash of the config it measured: a row is never attributed to
//! another config, the best config written out is only ever one that was measured, and the run
//! identity beside the file is the same for a merged, a resumed and an uninterrupted run.

use std::path::{Path, PathBuf};
use wipdr_eval::pipeline::{EvalConfig, EvalError, FloorInput};
use wipdr_eval::sweep::{self, RunIdentity, SweepOptions, SweepOutcome, SweepSpec};

mod common;
use common::fixture_floor;

/// Four EKF configs: a 2-value grid times 2 random draws (`seed` picks the draws).
fn spec(seed: u64, r_wifi: [f64; 2]) -> SweepSpec {
    toml::from_str(&format!(
        r#"
        scheme = "ekf"
        objective = "mean"
        [grid]
        "fuser.r_wifi_m2" = [{:?}, {:?}]
        [random]
        samples = 2
        seed = {seed}
        [random.ranges]
        "fuser.q_position_m2" = {{ min = 0.2, max = 3.0, log = true }}
        "#,
        r_wifi[0], r_wifi[1]
    ))
    .expect("sweep spec parses")
}

fn run(
    spec: &SweepSpec,
    floors: &[FloorInput],
    out: &Path,
    options: SweepOptions,
) -> Result<SweepOutcome, EvalError> {
    sweep::run_sweep(spec, &EvalConfig::default(), floors, out, &options, &|| {})
}

fn first_configs(n: usize) -> SweepOptions {
    SweepOptions {
        max_configs: Some(n),
        ..SweepOptions::default()
    }
}

fn resume() -> SweepOptions {
    SweepOptions {
        resume: true,
        ..SweepOptions::default()
    }
}

fn text(p: &Path) -> String {
    std::fs::read_to_string(p).expect("results file")
}

#[test]
fn a_row_is_never_attributed_to_another_config() {
    let floors = [fixture_floor()];
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("r.csv");
    let a = spec(5, [16.0, 150.0]);
    let o = run(&a, &floors, &out, first_configs(2)).expect("first part runs");
    // Rows carry their configs' hashes, distinct per config.
    assert_eq!(o.rows.len(), 2);
    assert_eq!(o.rows[0].config_hash.len(), 16);
    assert_ne!(o.rows[0].config_hash, o.rows[1].config_hash);
    // A row edited to claim another config's index is refused on resume.
    let t = text(&out);
    let tampered = t.replacen(&format!("\n{},", o.rows[1].index), "\n3,", 1);
    assert_ne!(t, tampered);
    std::fs::write(&out, tampered).expect("write");
    let msg = run(&a, &floors, &out, resume())
        .expect_err("a row of another config must be refused")
        .to_string();
    assert!(msg.contains("config 3 was measured for"), "{msg}");
}

#[test]
fn the_best_config_is_only_ever_a_measured_one() {
    let floors = [fixture_floor()];
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("r.csv");
    let a = spec(5, [16.0, 150.0]);
    let base = EvalConfig::default();
    let o = run(&a, &floors, &out, SweepOptions::default()).expect("sweep runs");
    let (row, cfg) = sweep::best_config(&a, &base, &o.rows, None)
        .expect("rows of this sweep")
        .expect("a finite objective");
    let best = o
        .rows
        .iter()
        .min_by(|x, y| x.objective.total_cmp(&y.objective))
        .expect("rows");
    assert_eq!(row.index, best.index);
    let points = a.expand().expect("expands");
    assert_eq!(
        cfg,
        sweep::config_for(&base, "ekf", &points[row.index]).expect("config")
    );
    assert_eq!(sweep::config_hash(&cfg).expect("hash"), row.config_hash);
    // Re-evaluating the best config gives the figure its row claims.
    let report = wipdr_eval::pipeline::evaluate(&floors, &cfg, &["ekf".to_string()], &|| {})
        .expect("evaluates");
    assert!((report.pooled["ekf"].mean - row.summary.mean).abs() < 1e-6);

    // Rows of this file are not the measured rows of another sweep's configs.
    let b = spec(6, [16.0, 150.0]);
    let msg = sweep::best_config(&b, &base, &o.rows, None)
        .expect_err("rows of another sweep")
        .to_string();
    assert!(msg.contains("was measured for"), "{msg}");
}

#[test]
fn merged_resumed_and_uninterrupted_runs_have_one_identity() {
    let floors = [fixture_floor()];
    let dir = tempfile::tempdir().expect("temp dir");
    let path = |name: &str| -> PathBuf { dir.path().join(name) };
    let a = spec(5, [16.0, 150.0]);
    for i in 0..2 {
        let opt = SweepOptions {
            shard: Some((i, 2)),
            ..SweepOptions::default()
        };
        run(&a, &floors, &path(&format!("s{i}.csv")), opt).expect("shard runs");
    }
    sweep::merge(&[path("s0.csv"), path("s1.csv")], &path("m.csv")).expect("merge");
    run(&a, &floors, &path("part.csv"), first_configs(1)).expect("part");
    run(&a, &floors, &path("part.csv"), resume()).expect("resumed");
    run(&a, &floors, &path("full.csv"), SweepOptions::default()).expect("full");
    let id = |p: &str| text(&RunIdentity::sidecar_path(&path(p)));
    assert_eq!(id("m.csv"), id("full.csv"));
    assert_eq!(id("part.csv"), id("full.csv"));
    assert_eq!(text(&path("m.csv")), text(&path("full.csv")));
    let identity = RunIdentity::read(&path("full.csv")).expect("identity");
    assert_eq!(identity.configs, 4);
    assert_eq!(identity.shard, None);
    assert_eq!(identity.data.floors.len(), 1);
    assert_eq!(identity.data.floors[0].label, "fixture");
    let shard1 = RunIdentity::read(&path("s1.csv")).expect("identity");
    assert_eq!(shard1.shard.map(|s| (s.index, s.count)), Some((1, 2)));
    // A raised limit is honoured (counted, not expanded, here).
    let mut big = a.clone();
    if let Some(r) = big.random.as_mut() {
        r.samples = 500_000_000;
    }
    assert_eq!(big.check(1_000_000_000).expect("within"), 1_000_000_000);
}

#[test]
fn the_evaal_objective_is_the_2d_75th_percentile_on_walks_without_floors() {
    let floors = [fixture_floor()];
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("r.csv");
    let s: SweepSpec = toml::from_str(
        r#"
        scheme = "ekf"
        objective = "evaal"
        [grid]
        "fuser.r_wifi_m2" = [16.0, 150.0]
        "#,
    )
    .expect("sweep spec parses");
    let o = run(&s, &floors, &out, SweepOptions::default()).expect("the sweep runs");
    assert_eq!(o.rows.len(), 2);
    for r in &o.rows {
        // Floor error 0 on every fixture waypoint: EvAAL is the 2D errors' 75th percentile by
        // the competition's (MATLAB's) rule, a quarter of a rank above numpy's `p75`.
        let evaal = r.summary.evaal.expect("an EvAAL figure");
        assert!(
            r.summary.p75 - 1e-5 <= evaal && evaal <= r.summary.p95 + 1e-5,
            "{evaal} vs p75 {} and p95 {}",
            r.summary.p75,
            r.summary.p95
        );
        assert_eq!(r.objective, evaal);
        assert!(r.summary.p75 > 0.0);
    }
}

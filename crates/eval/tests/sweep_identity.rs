//! A sweep's results are tied to the run that measured them: `resume` refuses a file of another
//! sweep spec, base config, data or shard; `merge` refuses files of different sweeps; a sweep
//! too large to run is refused before anything is allocated for it. (These tests use only the
//! API that predates run identities, so they run, and fail, on the code before it.)

use std::path::{Path, PathBuf};
use wipdr_eval::pipeline::{EvalConfig, EvalError, FloorInput};
use wipdr_eval::sweep::{self, SweepOptions, SweepOutcome, SweepSpec};

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

/// The fixture floor with its last walk left out: other data under the same label.
fn fewer_walks(floor: &FloorInput) -> FloorInput {
    let mut data = (*floor.data).clone();
    data.walks.pop();
    FloorInput::new(floor.label.clone(), data)
}

#[test]
fn resume_with_a_changed_sweep_file_is_refused() {
    let floors = [fixture_floor()];
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("r.csv");
    let a = spec(5, [16.0, 150.0]);
    let o = run(&a, &floors, &out, first_configs(2)).expect("first part runs");
    assert_eq!(o.rows.len(), 2);
    let before = text(&out);

    // Another seed: other draws under the same indices.
    let b = spec(6, [16.0, 150.0]);
    let e = run(&b, &floors, &out, resume()).expect_err("a changed spec must be refused");
    let msg = e.to_string();
    assert!(msg.contains("spec differs"), "{msg}");
    assert!(msg.contains("random.seed: 5 vs 6"), "{msg}");
    // A changed grid value is named too.
    let c = spec(5, [16.0, 50.0]);
    let msg = run(&c, &floors, &out, resume())
        .expect_err("a changed grid must be refused")
        .to_string();
    assert!(msg.contains("grid.fuser.r_wifi_m2"), "{msg}");
    assert_eq!(
        text(&out),
        before,
        "a refused resume leaves the file as it was"
    );

    // Another base config is refused as well.
    let mut base = EvalConfig::default();
    base.positioner.seed = 2;
    let msg = sweep::run_sweep(&a, &base, &floors, &out, &resume(), &|| {})
        .expect_err("another base config must be refused")
        .to_string();
    assert!(
        msg.contains("base config differs") && msg.contains("seed: 1 vs 2"),
        "{msg}"
    );

    // The same spec resumes and completes.
    let o = run(&a, &floors, &out, resume()).expect("the same sweep resumes");
    assert!(o.complete);
    assert_eq!((o.ran, o.skipped), (2, 2));
}

#[test]
fn resume_with_other_data_is_refused() {
    let floor = fixture_floor();
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("r.csv");
    let a = spec(5, [16.0, 150.0]);
    run(&a, std::slice::from_ref(&floor), &out, first_configs(1)).expect("first part runs");
    let before = text(&out);

    let msg = run(&a, &[fewer_walks(&floor)], &out, resume())
        .expect_err("other data must be refused")
        .to_string();
    assert!(msg.contains("data differs"), "{msg}");
    assert!(msg.contains("floor \"fixture\""), "{msg}");
    let relabelled = FloorInput {
        label: "other".into(),
        ..floor.clone()
    };
    let msg = run(&a, &[relabelled], &out, resume())
        .expect_err("other floors must be refused")
        .to_string();
    assert!(
        msg.contains("data differs: floors [\"fixture\"] vs [\"other\"]"),
        "{msg}"
    );
    let msg = run(&a, &[floor.clone(), floor.clone()], &out, resume())
        .expect_err("an added floor must be refused")
        .to_string();
    assert!(msg.contains("data differs"), "{msg}");
    assert_eq!(text(&out), before);

    // The same data parsed again (another Arc, equal content) is the same data.
    let again = fixture_floor();
    let o = run(&a, &[again], &out, first_configs(1).with_resume()).expect("same data resumes");
    assert_eq!((o.ran, o.skipped), (1, 1));
}

trait WithResume {
    fn with_resume(self) -> Self;
}

impl WithResume for SweepOptions {
    fn with_resume(mut self) -> Self {
        self.resume = true;
        self
    }
}

#[test]
fn resume_of_another_shard_is_refused() {
    let floors = [fixture_floor()];
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("s0.csv");
    let a = spec(5, [16.0, 150.0]);
    let shard0 = SweepOptions {
        shard: Some((0, 2)),
        max_configs: Some(1),
        ..SweepOptions::default()
    };
    run(&a, &floors, &out, shard0).expect("shard 0 runs");
    let shard1 = SweepOptions {
        shard: Some((1, 2)),
        resume: true,
        ..SweepOptions::default()
    };
    let msg = run(&a, &floors, &out, shard1)
        .expect_err("another shard must be refused")
        .to_string();
    assert!(
        msg.contains("shard differs: shard 0/2 vs shard 1/2"),
        "{msg}"
    );
    let msg = run(&a, &floors, &out, resume())
        .expect_err("the whole sweep on a shard's file must be refused")
        .to_string();
    assert!(
        msg.contains("shard differs: shard 0/2 vs the whole sweep"),
        "{msg}"
    );
}

#[test]
fn merge_of_unrelated_shards_is_refused() {
    let floor = fixture_floor();
    let dir = tempfile::tempdir().expect("temp dir");
    let path = |name: &str| -> PathBuf { dir.path().join(name) };
    let a = spec(5, [16.0, 150.0]);
    let b = spec(6, [16.0, 150.0]);
    let shard = |i| SweepOptions {
        shard: Some((i, 2)),
        max_configs: Some(1),
        ..SweepOptions::default()
    };
    let floors = std::slice::from_ref(&floor);
    run(&a, floors, &path("a0.csv"), shard(0)).expect("a0");
    run(&a, floors, &path("a1.csv"), shard(1)).expect("a1");
    run(&b, floors, &path("b1.csv"), shard(1)).expect("b1");
    run(&a, &[fewer_walks(&floor)], &path("d1.csv"), shard(1)).expect("d1");

    let msg = sweep::merge(&[path("a0.csv"), path("b1.csv")], &path("m.csv"))
        .expect_err("shards of two specs must be refused")
        .to_string();
    assert!(
        msg.contains("spec differs") && msg.contains("b1.csv"),
        "{msg}"
    );
    let msg = sweep::merge(&[path("a0.csv"), path("d1.csv")], &path("m.csv"))
        .expect_err("shards of two data sets must be refused")
        .to_string();
    assert!(
        msg.contains("data differs") && msg.contains("d1.csv"),
        "{msg}"
    );
    let msg = sweep::merge(&[path("a0.csv"), path("a0.csv")], &path("m.csv"))
        .expect_err("one shard twice must be refused")
        .to_string();
    assert!(msg.contains("shard differs"), "{msg}");
    // Nothing was written by the refused merges.
    assert!(!path("m.csv").exists());

    // The shards of one sweep merge; the merged file resumes (unsharded) to completion and
    // then equals the uninterrupted run.
    let rows = sweep::merge(&[path("a0.csv"), path("a1.csv")], &path("m.csv")).expect("merge");
    assert_eq!(rows.len(), 2);
    let o = run(&a, floors, &path("m.csv"), resume()).expect("the merged file resumes");
    assert!(o.complete);
    assert_eq!((o.ran, o.skipped), (2, 2));
    run(&a, floors, &path("full.csv"), SweepOptions::default()).expect("full run");
    assert_eq!(text(&path("m.csv")), text(&path("full.csv")));
}

#[test]
fn a_billion_samples_are_refused_cleanly() {
    // `1e9` is a float in TOML: not a number of samples at all.
    let float: Result<SweepSpec, _> = toml::from_str(
        r#"
        scheme = "ekf"
        [random]
        samples = 1e9
        [random.ranges]
        "fuser.q_position_m2" = { min = 0.2, max = 3.0 }
        "#,
    );
    assert!(float.is_err());
    let big: SweepSpec = toml::from_str(
        r#"
        scheme = "ekf"
        [random]
        samples = 1_000_000_000
        [random.ranges]
        "fuser.q_position_m2" = { min = 0.2, max = 3.0 }
        "#,
    )
    .expect("parses");
    let msg = big.expand().expect_err("over the limit").to_string();
    assert!(
        msg.contains("1000000000 configs, over the limit of 100000")
            && msg.contains("--config-limit"),
        "{msg}"
    );
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("r.csv");
    let msg = run(&big, &[fixture_floor()], &out, SweepOptions::default())
        .expect_err("over the limit")
        .to_string();
    assert!(msg.contains("over the limit of 100000"), "{msg}");
    assert!(!out.exists(), "nothing is written for a refused sweep");
    // A grid whose product overflows 64 bits is refused, not wrapped.
    let mut huge = big.clone();
    huge.random = None;
    for i in 0..12 {
        huge.grid.insert(
            format!("g{i}"),
            (0..1000).map(serde_json::Value::from).collect(),
        );
    }
    let msg = huge.expand().expect_err("overflowing grid").to_string();
    assert!(
        msg.contains("1000000000000000000000000000000000000 configs"),
        "{msg}"
    );
}

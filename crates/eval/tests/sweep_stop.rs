//! The sweep's stop flag (what `wipdr sweep` sets on Ctrl-C): once set, no new config starts,
//! the configs already finished stay in the file, and `resume` completes the sweep to the same
//! file as an uninterrupted run.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use wipdr_eval::pipeline::{EvalConfig, FloorInput};
use wipdr_eval::sweep::{self, SweepOptions, SweepOutcome, SweepSpec};

mod common;
use common::fixture_floor;

/// Six configs of the EKF: a 3-value grid times 2 random draws.
fn spec() -> SweepSpec {
    toml::from_str(
        r#"
        scheme = "ekf"
        objective = "mean"
        [grid]
        "fuser.r_wifi_m2" = [16.0, 50.0, 150.0]
        [random]
        samples = 2
        seed = 5
        [random.ranges]
        "fuser.q_position_m2" = { min = 0.2, max = 3.0, log = true }
        "#,
    )
    .expect("sweep spec parses")
}

/// Runs a sweep on one worker thread, so that "stop after the first config" is exact.
fn run_on_one_thread(
    floors: &[FloorInput],
    out: &Path,
    options: &SweepOptions,
    on_done: &(dyn Fn() + Sync),
) -> SweepOutcome {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a one-thread pool");
    pool.install(|| {
        sweep::run_sweep(
            &spec(),
            &EvalConfig::default(),
            floors,
            out,
            options,
            on_done,
        )
    })
    .expect("sweep runs")
}

#[test]
fn a_set_stop_flag_stops_early_and_resume_completes_to_the_same_file() {
    let floors = [fixture_floor()];
    let dir = tempfile::tempdir().expect("temp dir");
    let full = dir.path().join("full.csv");
    let stopped = dir.path().join("stopped.csv");

    let uninterrupted = run_on_one_thread(&floors, &full, &SweepOptions::default(), &|| {});
    assert!(uninterrupted.complete && !uninterrupted.stopped);
    assert_eq!(uninterrupted.ran, 6);

    // The flag is raised when the first config finishes (as a Ctrl-C during it would be).
    let flag = Arc::new(AtomicBool::new(false));
    let options = SweepOptions {
        stop: Some(flag.clone()),
        ..SweepOptions::default()
    };
    let raise = {
        let flag = flag.clone();
        move || flag.store(true, Ordering::SeqCst)
    };
    let first = run_on_one_thread(&floors, &stopped, &options, &raise);
    assert!(first.stopped, "the run must report that it stopped");
    assert!(!first.complete);
    assert_eq!(first.ran, 1, "no config may start after the flag is set");
    assert_eq!(first.rows.len(), 1, "the finished config is in the file");
    let lines = std::fs::read_to_string(&stopped).expect("results file");
    assert_eq!(lines.lines().count(), 2, "header and one row:\n{lines}");

    // A flag already set: nothing new starts, the file keeps its row.
    let again = run_on_one_thread(
        &floors,
        &stopped,
        &SweepOptions {
            resume: true,
            stop: Some(flag.clone()),
            ..SweepOptions::default()
        },
        &|| {},
    );
    assert!(again.stopped && !again.complete);
    assert_eq!((again.ran, again.skipped, again.rows.len()), (0, 1, 1));

    // Resume without a stop request finishes the rest.
    let resumed = run_on_one_thread(
        &floors,
        &stopped,
        &SweepOptions {
            resume: true,
            ..SweepOptions::default()
        },
        &|| {},
    );
    assert!(resumed.complete && !resumed.stopped);
    assert_eq!((resumed.ran, resumed.skipped), (5, 1));
    assert_eq!(
        std::fs::read_to_string(&full).expect("full results"),
        std::fs::read_to_string(&stopped).expect("resumed results"),
        "interrupted + resumed must equal the uninterrupted file"
    );
    let sidecar = |p: &Path| {
        let mut s = p.as_os_str().to_owned();
        s.push(".run.json");
        std::fs::read_to_string(std::path::PathBuf::from(s)).expect("run identity")
    };
    assert_eq!(sidecar(&full), sidecar(&stopped), "one run, one identity");
}

#[test]
fn an_unset_flag_changes_nothing() {
    let floors = [fixture_floor()];
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("r.csv");
    let options = SweepOptions {
        stop: Some(Arc::new(AtomicBool::new(false))),
        ..SweepOptions::default()
    };
    let o = run_on_one_thread(&floors, &out, &options, &|| {});
    assert!(o.complete && !o.stopped);
    assert_eq!(o.rows.len(), 6);
    assert_eq!(
        o.rows.iter().map(|r| r.index).collect::<Vec<_>>(),
        (0..6).collect::<Vec<_>>()
    );
}

//! Integration tests of the generator: determinism, walkable space, sensor rates, truth
//! consistency, stale scans, and reading the written floor back with the real readers.

use std::path::Path;
use wipdr_core::{Point2, angle};
use wipdr_sim::{SimConfig, SimFloor, generate, write};

fn small_config() -> SimConfig {
    let mut cfg = SimConfig {
        walks: 3,
        duration_s: 60.0,
        duration_jitter_s: 10.0,
        gross_error_rate: 0.1,
        ..SimConfig::default()
    };
    cfg.survey.spacing_m = 6.0;
    cfg.survey.test_points = 10;
    cfg
}

fn sim() -> SimFloor {
    generate(&small_config(), 7).unwrap()
}

fn all_files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                let rel = p.strip_prefix(dir).unwrap().to_string_lossy().into_owned();
                out.push((rel, std::fs::read(&p).unwrap()));
            }
        }
    }
    out.sort();
    out
}

#[test]
fn same_seed_writes_byte_identical_files() {
    let cfg = small_config();
    let a = tempfile::tempdir().unwrap();
    let b = tempfile::tempdir().unwrap();
    write::write_floor(&generate(&cfg, 11).unwrap(), a.path()).unwrap();
    write::write_floor(&generate(&cfg, 11).unwrap(), b.path()).unwrap();
    let (fa, fb) = (all_files(a.path()), all_files(b.path()));
    assert!(fa.len() >= 3 + 3 + 3 + 2, "{} files", fa.len());
    assert_eq!(fa.len(), fb.len());
    for ((na, da), (nb, db)) in fa.iter().zip(&fb) {
        assert_eq!(na, nb);
        assert!(da == db, "{na} differs between two runs with the same seed");
    }
    // A different seed gives different walks.
    let c = tempfile::tempdir().unwrap();
    write::write_floor(&generate(&cfg, 12).unwrap(), c.path()).unwrap();
    let fc = all_files(c.path());
    let walk = |f: &[(String, Vec<u8>)]| {
        f.iter()
            .find(|(n, _)| n.ends_with("w0000.txt.gz"))
            .unwrap()
            .1
            .clone()
    };
    assert_ne!(walk(&fa), walk(&fc));
}

#[test]
fn walk_i_does_not_depend_on_the_number_of_walks() {
    let mut cfg = small_config();
    let a = generate(&cfg, 3).unwrap();
    cfg.walks = 1;
    let b = generate(&cfg, 3).unwrap();
    assert_eq!(a.walks[0], b.walks[0]);
}

#[test]
fn changing_the_imu_model_leaves_wifi_and_truth_alone() {
    let mut cfg = small_config();
    cfg.walks = 1;
    let a = generate(&cfg, 5).unwrap();
    cfg.imu.accel_noise *= 2.0;
    cfg.imu.gyro_bias_std *= 2.0;
    let b = generate(&cfg, 5).unwrap();
    assert_ne!(a.walks[0].walk.imu, b.walks[0].walk.imu);
    assert_eq!(a.walks[0].walk.wifi, b.walks[0].walk.wifi);
    assert_eq!(a.walks[0].walk.waypoints, b.walks[0].walk.waypoints);
    assert_eq!(a.walks[0].truth.steps, b.walks[0].truth.steps);
}

#[test]
fn walks_stay_in_walkable_space_and_cross_no_wall() {
    let s = sim();
    let plan = &s.world.floor.plan;
    for w in &s.walks {
        let tr = &w.truth.trajectory;
        assert!(tr.len() > 100);
        for pair in tr.windows(2) {
            let (a, b) = (
                Point2::new(pair[0].x, pair[0].y),
                Point2::new(pair[1].x, pair[1].y),
            );
            assert!(
                plan.is_walkable(b),
                "{} leaves walkable space at {b}",
                w.truth.walk_id
            );
            assert!(
                !plan.crosses_wall(a, b),
                "{} crosses a wall {a} -> {b}",
                w.truth.walk_id
            );
        }
        for wp in &w.walk.waypoints {
            assert!(plan.is_walkable(wp.position));
        }
    }
}

#[test]
fn imu_runs_at_about_50_hz_with_jitter() {
    let s = sim();
    for w in &s.walks {
        let acc = &w.walk.imu.accelerometer;
        let rate = wipdr_core::imu::mean_rate_hz(acc.iter().map(|a| a.t)).unwrap();
        assert!((rate - 50.0).abs() < 1.0, "rate {rate}");
        assert!(
            acc.windows(2).all(|p| p[1].t > p[0].t),
            "timestamps strictly increasing"
        );
        let distinct: std::collections::BTreeSet<i64> =
            acc.windows(2).map(|p| p[1].t - p[0].t).collect();
        assert!(distinct.len() > 3, "timestamps are jittered: {distinct:?}");
        for stream in [&w.walk.imu.gyroscope, &w.walk.imu.magnetometer] {
            assert_eq!(stream.len(), acc.len());
        }
        assert_eq!(w.walk.imu.rotation_vector.len(), acc.len());
        // Gravity on the phone's axes: a phone held flat, top slightly raised.
        let mean_z = acc.iter().map(|a| a.v[2]).sum::<f64>() / acc.len() as f64;
        let mean_y = acc.iter().map(|a| a.v[1]).sum::<f64>() / acc.len() as f64;
        assert!(mean_z > 8.0 && mean_y > 0.5, "z {mean_z}, y {mean_y}");
    }
}

#[test]
fn step_truth_is_consistent_with_the_trajectory() {
    let s = sim();
    for w in &s.walks {
        let t = &w.truth;
        assert!(t.steps.len() > 50);
        for st in &t.steps {
            assert!(
                (0.5..=0.95).contains(&st.length),
                "step length {}",
                st.length
            );
            assert!(st.length <= st.arc_length + 1e-6, "chord longer than arc");
            assert!((1.0 / st.period_s) > 1.2 && (1.0 / st.period_s) < 2.6);
        }
        // Summed step displacements reproduce the trajectory end to end.
        let start = t.position_at(t.start_ms).unwrap();
        let end = t.position_at(t.end_ms).unwrap();
        let summed = t.steps.iter().fold(start, |p, st| {
            p + angle::step_displacement(st.length, st.heading)
        });
        assert!(
            (summed - end).norm() < 0.05,
            "{}: dead reckoning with true steps ends {} m off",
            t.walk_id,
            (summed - end).norm()
        );
        // Every step's end is on the trajectory.
        for st in t.steps.iter().step_by(7) {
            assert!(t.position_at(st.t).is_some());
        }
        // Turns are ordered, and their angles match the heading change of the trajectory.
        for turn in &t.turns {
            assert!(turn.t_end >= turn.t_start);
            let before = t
                .steps
                .iter()
                .rev()
                .find(|s| s.t <= turn.t_start)
                .map(|s| s.heading);
            let after = t
                .steps
                .iter()
                .find(|s| s.t >= turn.t_end + 600)
                .map(|s| s.heading);
            if let (Some(b), Some(a)) = (before, after) {
                assert!(
                    angle::diff(angle::diff(a, b), turn.angle).abs() < 0.35,
                    "turn {turn:?}: {b} -> {a}"
                );
            }
        }
    }
}

#[test]
fn scans_are_periodic_with_stale_entries_and_known_gross_errors() {
    let s = sim();
    let mut ages = Vec::new();
    let mut gross = 0;
    for w in &s.walks {
        let scans = &w.walk.wifi;
        assert!(scans.len() >= 20);
        for p in scans.windows(2) {
            let dt = p[1].t - p[0].t;
            assert!((1500..=2500).contains(&dt), "scan interval {dt} ms");
        }
        for sc in scans {
            assert!(
                sc.entries.len() >= 5,
                "scan with {} entries",
                sc.entries.len()
            );
            for e in &sc.entries {
                assert!(e.rssi_dbm >= -95.0 && e.rssi_dbm < 0.0);
                ages.push(e.age_ms(sc.t));
            }
        }
        for g in &w.truth.gross_errors {
            assert!(scans.iter().any(|s| s.t == g.t));
            assert!((g.scan_position - g.true_position).norm() >= 39.9);
            gross += 1;
        }
    }
    ages.sort_unstable();
    let median = ages[ages.len() / 2];
    let over_2s = ages.iter().filter(|&&a| a > 2000).count() as f64 / ages.len() as f64;
    assert!(ages[0] >= 0);
    assert!((2500..=4500).contains(&median), "median age {median} ms");
    assert!(over_2s > 0.45, "fraction over 2 s: {over_2s}");
    assert!(gross > 0, "gross errors injected at rate 0.1");
}

#[test]
fn written_floor_reads_back_with_the_real_readers() {
    let s = sim();
    let dir = tempfile::tempdir().unwrap();
    let floor_dir = write::write_floor(&s, dir.path()).unwrap();
    let data = wipdr_io::read_floor_dir(&floor_dir, &wipdr_io::ReadOptions::default()).unwrap();
    assert_eq!(data.walks.len(), s.walks.len());
    for (read, orig) in data.walks.iter().zip(&s.walks) {
        assert_eq!(
            read.walk, orig.walk,
            "{} changed on the way through the files",
            orig.walk.meta.id
        );
    }
    assert_eq!(data.plan.units.len(), s.world.floor.plan.units.len());
    let truths = wipdr_sim::truth::read_floor_truths(&floor_dir).unwrap();
    assert_eq!(truths.len(), s.walks.len());
    for (t, w) in truths.iter().zip(&s.walks) {
        assert_eq!(t.walk_id, w.truth.walk_id);
        assert_eq!(t.steps.len(), w.truth.steps.len());
        assert_eq!(t.gross_errors, w.truth.gross_errors);
    }
    let (train, test) = wipdr_io::fingerprint_csv::read_dataset(floor_dir.join("survey")).unwrap();
    assert_eq!(train.n_rows(), s.survey.train.len());
    assert_eq!(test.n_rows(), s.survey.test.len());
    assert_eq!(train.n_aps(), s.world.radio.access_points.len());
}

/// Azimuth (clockwise from north) of the phone's `y` axis from a rotation vector: Android's
/// `getOrientation` azimuth `atan2(R01, R11)`.
fn azimuth(q: [f64; 4]) -> f64 {
    let [w, x, y, z] = q;
    let r01 = 2.0 * (x * y - w * z);
    let r11 = 1.0 - 2.0 * (x * x + z * z);
    r01.atan2(r11)
}

#[test]
fn rotation_vector_gyroscope_and_magnetometer_follow_the_true_heading() {
    let s = sim();
    for w in &s.walks {
        let imu = &w.walk.imu;
        let t = &w.truth;
        // Rotation-vector azimuth against the true step headings (plus the phone's known yaw
        // misalignment and the map-to-magnetic offset).
        let mut diffs: Vec<f64> = t
            .steps
            .iter()
            .map(|st| {
                let k = imu
                    .rotation_vector
                    .partition_point(|r| r.t <= st.t)
                    .min(imu.rotation_vector.len() - 1);
                angle::diff(
                    azimuth(imu.rotation_vector[k].quaternion()),
                    st.heading + t.phone.yaw_misalignment + t.map_to_magnetic,
                )
                .abs()
            })
            .collect();
        diffs.sort_by(f64::total_cmp);
        let median = diffs[diffs.len() / 2].to_degrees();
        assert!(
            median < 8.0,
            "{}: median rotation-vector heading error {median} deg",
            t.walk_id
        );
        // Gyroscope z over each turn: a right turn (positive angle) reads negative, scaled by
        // the tilt of the phone's z axis.
        for turn in &t.turns {
            let (a, b) = (turn.t_start - 1000, turn.t_end + 1000);
            let g = &imu.gyroscope;
            let integral: f64 = g
                .windows(2)
                .filter(|p| p[0].t >= a && p[1].t <= b)
                .map(|p| p[0].v[2] * (p[1].t - p[0].t) as f64 / 1000.0)
                .sum();
            let expected = -turn.angle * t.phone.pitch.cos() * t.phone.roll.cos();
            assert!(
                (integral - expected).abs() < 0.2,
                "{}: turn {turn:?}: gyro z integral {integral}, expected {expected}",
                t.walk_id
            );
        }
        // Magnetometer magnitude near the Earth field's (46 µT) away from disturbances.
        let mut norms: Vec<f64> = imu.magnetometer.iter().map(|m| m.norm()).collect();
        norms.sort_by(f64::total_cmp);
        let med = norms[norms.len() / 2];
        assert!((med - 46.1).abs() < 5.0, "median |B| {med}");
    }
}

mod invariants {
    use super::*;
    use proptest::prelude::*;

    /// One 20 s walk, gross Wi-Fi errors at `gross`, one survey test point.
    fn one_short_walk(gross: f64) -> SimConfig {
        let mut cfg = SimConfig {
            walks: 1,
            duration_s: 20.0,
            duration_jitter_s: 0.0,
            gross_error_rate: gross,
            ..SimConfig::default()
        };
        cfg.survey.test_points = 1;
        cfg
    }

    /// The case proptest found: a near-identity rotation increment whose trace rounded past 3
    /// made one gyroscope sample NaN (`nalgebra`'s unclamped `acos`).
    #[test]
    fn the_seed_that_once_gave_a_nan_gyroscope_sample_gives_finite_streams() {
        let cfg = one_short_walk(0.042033473192180905);
        let world = wipdr_sim::SimWorld::build(&cfg, 2307767014909628701).unwrap();
        let imu = world.walk(0).walk.imu;
        assert!(
            imu.gyroscope.len() > 900,
            "{} gyroscope samples",
            imu.gyroscope.len()
        );
        let bad = imu
            .accelerometer
            .iter()
            .chain(&imu.gyroscope)
            .chain(&imu.magnetometer)
            .filter(|s| !s.v.iter().all(|v| v.is_finite()))
            .count();
        assert_eq!(bad, 0, "{bad} non-finite IMU samples");
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 8, .. ProptestConfig::default() })]

        /// For any seed: walks stay walkable, streams are time-sorted, every scan entry is
        /// at most the cache lifetime old, and steps add up to the distance walked.
        #[test]
        fn any_seed_gives_a_sane_walk(seed in any::<u64>(), gross in 0.0f64..0.5) {
            let cfg = one_short_walk(gross);
            let world = wipdr_sim::SimWorld::build(&cfg, seed).unwrap();
            let w = world.walk(0);
            let plan = &world.floor.plan;
            for s in &w.truth.trajectory {
                prop_assert!(plan.is_walkable(Point2::new(s.x, s.y)));
            }
            prop_assert!(w.walk.imu.accelerometer.windows(2).all(|p| p[0].t < p[1].t));
            prop_assert!(w.walk.wifi.windows(2).all(|p| p[0].t < p[1].t));
            prop_assert!(w.walk.waypoints.windows(2).all(|p| p[0].t < p[1].t));
            for scan in &w.walk.wifi {
                for e in &scan.entries {
                    let age = e.age_ms(scan.t);
                    prop_assert!((0..=30_000).contains(&age));
                    prop_assert!(e.rssi_dbm.is_finite());
                }
            }
            let walked: f64 = w.truth.steps.iter().map(|s| s.arc_length).sum();
            prop_assert!((walked - w.truth.distance_m).abs() < 1e-9);
            let all_finite = w.walk.imu.accelerometer.iter().chain(&w.walk.imu.gyroscope).chain(&w.walk.imu.magnetometer)
                .all(|s| s.v.iter().all(|v| v.is_finite()));
            prop_assert!(all_finite);
        }
    }
}

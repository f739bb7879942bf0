//! Bad input (issue 5): gaps, repeated or backwards timestamps, NaN samples, walks without a
//! gyroscope or a magnetometer. Documented behaviour (see `Pdr`), no panic.

use proptest::prelude::*;
use wipdr_core::{RotationVectorSample, Vec3Sample, Walk};
use wipdr_pdr::{CheckedPdrConfig, HeadingSource, Pdr, PdrConfig};
use wipdr_sim::{SimConfig, generate};

fn sim_walk(seed: u64) -> Walk {
    let mut cfg = SimConfig {
        walks: 1,
        duration_s: 60.0,
        duration_jitter_s: 0.0,
        ..Default::default()
    };
    cfg.survey.test_points = 5;
    generate(&cfg, seed)
        .expect("simulation")
        .walks
        .remove(0)
        .walk
}

fn assert_sane(events: &[wipdr_core::StepEvent]) {
    for e in events {
        assert!(e.length.is_finite() && e.length > 0.0);
        assert!(e.heading.is_finite() && e.heading.abs() <= std::f64::consts::PI + 1e-9);
        assert!(e.heading_change.is_finite() && e.period_s.is_finite() && e.period_s > 0.0);
    }
}

#[test]
fn without_gyroscope_falls_back_and_still_walks() {
    let mut walk = sim_walk(3);
    let full = Pdr::run(CheckedPdrConfig::default(), &walk);
    walk.imu.gyroscope.clear();
    let cfg = PdrConfig {
        heading: wipdr_pdr::HeadingConfig {
            source: HeadingSource::Gyro,
            ..Default::default()
        },
        ..Default::default()
    };
    let (steps, diag) = Pdr::run_detailed(cfg.check().unwrap(), &walk);
    assert_eq!(
        steps.len(),
        full.len(),
        "steps come from the accelerometer alone"
    );
    assert!(steps.iter().all(|s| s.headings.gyro.is_none()));
    assert_eq!(diag.steps_with_fallback_heading, steps.len());
    assert_eq!(diag.steps_without_heading, 0);
    assert_sane(&steps.iter().map(|s| s.event).collect::<Vec<_>>());
}

#[test]
fn without_magnetometer_or_rotation_vector() {
    let mut walk = sim_walk(4);
    walk.imu.magnetometer.clear();
    walk.imu.rotation_vector.clear();
    let cfg = PdrConfig {
        heading: wipdr_pdr::HeadingConfig {
            source: HeadingSource::GyroCompassKf,
            ..Default::default()
        },
        ..Default::default()
    };
    let (steps, diag) = Pdr::run_detailed(cfg.check().unwrap(), &walk);
    assert!(!steps.is_empty());
    // The KF runs on the gyro alone, started from gravity with heading 0.
    assert!(
        steps
            .iter()
            .all(|s| s.headings.compass.is_none() && s.headings.gyro_compass_kf.is_some())
    );
    assert_eq!(diag.steps_without_heading, 0);
    assert_sane(&steps.iter().map(|s| s.event).collect::<Vec<_>>());
}

#[test]
fn only_accelerometer_gives_heading_zero_counted() {
    let mut walk = sim_walk(5);
    walk.imu.magnetometer.clear();
    walk.imu.rotation_vector.clear();
    walk.imu.gyroscope.clear();
    let (steps, diag) = Pdr::run_detailed(CheckedPdrConfig::default(), &walk);
    assert!(!steps.is_empty());
    assert_eq!(diag.steps_without_heading, steps.len());
    assert!(steps.iter().all(|s| s.event.heading == 0.0));
}

#[test]
fn gap_splits_and_no_step_spans_it() {
    let mut walk = sim_walk(6);
    let n = walk.imu.accelerometer.len();
    let (t0, t1) = (
        walk.imu.accelerometer[n / 3].t,
        walk.imu.accelerometer[n / 2].t,
    );
    walk.imu.accelerometer.retain(|s| s.t < t0 || s.t > t1);
    let (steps, diag) = Pdr::run_detailed(CheckedPdrConfig::default(), &walk);
    assert!(diag.gaps >= 1);
    assert!(steps.iter().all(|s| s.event.t < t0 || s.event.t > t1));
    let after = steps
        .iter()
        .find(|s| s.event.t > t1)
        .expect("steps after the gap");
    assert!(after.features.first && after.event.motion.stationary);
}

#[test]
fn nan_repeated_and_backwards_samples_are_counted() {
    let mut pdr = Pdr::new(CheckedPdrConfig::default());
    let acc = |t, z| Vec3Sample {
        t,
        v: [0.0, 0.0, z],
        accuracy: 3,
    };
    pdr.push_accelerometer(&acc(100, 9.8));
    pdr.push_accelerometer(&acc(120, f64::NAN));
    pdr.push_accelerometer(&acc(120, 9.8));
    pdr.push_accelerometer(&acc(120, 9.8)); // repeated
    pdr.push_accelerometer(&acc(60, 9.8)); // backwards
    pdr.push_gyroscope(&Vec3Sample {
        t: 50,
        v: [f64::INFINITY, 0.0, 0.0],
        accuracy: 3,
    });
    pdr.push_rotation_vector(&RotationVectorSample {
        t: 50,
        v: [f64::NAN, 0.0, 0.0],
        accuracy: 3,
    });
    pdr.push_magnetometer(&Vec3Sample {
        t: 50,
        v: [1.0, 2.0, 3.0],
        accuracy: 3,
    });
    pdr.push_magnetometer(&Vec3Sample {
        t: 40,
        v: [1.0, 2.0, 3.0],
        accuracy: 3,
    });
    let d = pdr.diagnostics();
    assert_eq!(d.non_finite, 3);
    assert_eq!(d.out_of_order, 3);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    /// Corrupting a real-looking walk at random (NaN, shuffled times, duplicates) never panics
    /// and never lets a NaN out.
    #[test]
    fn corrupted_streams_never_panic(seed in 0u64..4, corrupt in proptest::collection::vec((0usize..4, 0usize..3000, 0u8..3), 0..60)) {
        let mut walk = sim_walk(10 + seed);
        for (stream, idx, kind) in corrupt {
            let imu = &mut walk.imu;
            let v: &mut Vec<Vec3Sample> = match stream {
                0 => &mut imu.accelerometer,
                1 => &mut imu.gyroscope,
                _ => &mut imu.magnetometer,
            };
            if v.is_empty() { continue; }
            let i = idx % v.len();
            match kind {
                0 => v[i].v[idx % 3] = f64::NAN,
                1 => v[i].t -= 5000,
                _ => { let s = v[i]; v.insert(i, s); }
            }
        }
        let events = Pdr::run(CheckedPdrConfig::default(), &walk);
        assert_sane(&events);
    }
}

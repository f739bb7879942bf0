//! `odometry = "learned"` end to end on a recorded walk: the front end's motion events are
//! the network's outputs turned into the map frame, with their covariance; a Positioner and
//! its smoother run on them; `steps` stays the default and emits steps without one.

use std::sync::Arc;
use wipdr_core::{Walk, angle};
use wipdr_pdr::odometry::{LearnedOdometry, rotate_covariance, rotate_heading};
use wipdr_positioning::config::Odometry;
use wipdr_positioning::{
    Frontend, PositionerConfig, SiteConfig, SiteModel, StreamSpec, TrainingData, samples_of,
    track_of,
};

fn walk(i: usize) -> Walk {
    let path = format!(
        "{}/../../fixtures/sim/F1/path_data_files/sim_F1_w000{i}.txt.gz",
        env!("CARGO_MANIFEST_DIR")
    );
    wipdr_io::read_walk(path).unwrap().walk
}

/// A model fit on three fixture walks, with `odometry` and a heading offset that is not 0
/// (so the turn into the map frame is exercised).
fn model(odometry: Odometry) -> SiteModel {
    let walks = [walk(1), walk(2), walk(3)];
    let refs: Vec<&Walk> = walks.iter().collect();
    let mut config = SiteConfig::default();
    config.fit.calibrate_pdr = false;
    config.positioner = PositionerConfig {
        odometry,
        ..PositionerConfig::default()
    };
    config.positioner.pdr.heading.map_offset_rad = 0.3;
    let data = TrainingData {
        name: "sim",
        walks: &refs,
        ..Default::default()
    };
    SiteModel::fit(&data, &config).unwrap()
}

#[test]
fn learned_motion_events_are_the_networks_outputs_in_the_map_frame() {
    let model = model(Odometry::Learned);
    let config = model.config();
    assert_eq!(config.odometry, Odometry::Learned);
    let test = walk(0);
    let mut frontend = Frontend::with_floor_config(
        config.pdr.check().unwrap(),
        model.matcher().stream(config.query),
        config.floor,
    )
    .with_odometry(config.odometry, config.pdr.heading.map_offset_rad)
    .unwrap();
    let events = frontend.record(samples_of(&test)).steps;
    let batch = Arc::new(LearnedOdometry::shipped().unwrap())
        .run(&test)
        .unwrap();
    // every window came live, one event each, but the last when it needs the end of the
    // stream (the walk's last accelerometer sample)
    assert!(
        events.len() <= batch.len() && events.len() + 1 >= batch.len(),
        "{} events, {} windows",
        events.len(),
        batch.len()
    );
    assert_eq!(frontend.counts().odometry_outputs, events.len() as u64);
    assert!(frontend.counts().steps > 0, "the PDR still runs");
    for (e, o) in events.iter().zip(&batch) {
        assert!(e.t >= o.t_end);
        let d = angle::step_displacement(e.length, e.heading);
        let want = rotate_heading(o.displacement, 0.3);
        assert!((d.x - want[0]).abs() < 1e-9 && (d.y - want[1]).abs() < 1e-9);
        let c = e.covariance.unwrap();
        let want = rotate_covariance(o.covariance, 0.3);
        for (a, b) in c.iter().zip(want) {
            assert!((a - b).abs() < 1e-12);
        }
        assert!(e.displacement_covariance().is_some());
    }
}

#[test]
fn a_positioner_runs_causal_and_offline_on_learned_odometry() {
    let model = model(Odometry::Learned);
    let test = walk(0);
    for scheme in ["ekf", "pf", "pmf", "pdr"] {
        let start = (scheme == "pdr").then(|| test.waypoints[0]);
        let mut p = model
            .positioner(
                scheme,
                &StreamSpec {
                    id: Some("w0".into()),
                    start: start.map(|w| w.position),
                    ..Default::default()
                },
            )
            .unwrap();
        let track = track_of(&mut p, samples_of(&test), start.map(|w| (w.t, w.position)));
        assert!(track.len() > 50, "{scheme}: {} estimates", track.len());
        assert!(
            track
                .iter()
                .all(|e| e.position.x.is_finite() && e.position.y.is_finite()),
            "{scheme}"
        );
        assert!(p.counts().odometry_outputs > 50);
        if start.is_none() {
            let smoothed = p.smooth().unwrap();
            assert!(!smoothed.is_empty() && smoothed.iter().all(|e| e.position.x.is_finite()));
        }
    }
}

#[test]
fn steps_stay_the_default_and_carry_no_covariance() {
    let model = model(Odometry::Steps);
    let config = model.config();
    assert_eq!(config.odometry, Odometry::Steps);
    let mut frontend = Frontend::with_floor_config(
        config.pdr.check().unwrap(),
        model.matcher().stream(config.query),
        config.floor,
    );
    assert_eq!(frontend.odometry(), Odometry::Steps);
    let steps = frontend.record(samples_of(&walk(0))).steps;
    assert!(steps.iter().all(|e| e.covariance.is_none()));
    assert_eq!(frontend.counts().steps, steps.len() as u64);
    assert_eq!(frontend.counts().odometry_outputs, 0);
}

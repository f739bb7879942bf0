//! The hand-written forward pass of the learned odometry equals the training framework's
//! (candle's) output on a fixture of real windows, to 1e-4: `fixtures/odometry/` holds the
//! windows and candle's raw outputs for the shipped weights, both written by
//! `tools/odometry-train` (`ship`).

use wipdr_pdr::odometry::LearnedOdometry;
use wipdr_pdr::odometry::features::{CHANNELS, WINDOW};
use wipdr_pdr::odometry::model::OUTPUTS;

#[derive(serde::Deserialize)]
struct Fixture {
    channels: usize,
    window: usize,
    windows: Vec<f32>,
    expected: Vec<f32>,
}

#[test]
fn rust_forward_equals_candle_on_the_fixture() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/odometry/learned.fixture.json"
    );
    let text = std::fs::read(path).unwrap();
    let f: Fixture = serde_json::from_slice(&text).unwrap();
    assert_eq!((f.channels, f.window), (CHANNELS, WINDOW));
    let n = f.windows.len() / (CHANNELS * WINDOW);
    assert!(n >= 5, "fixture has {n} windows");
    assert_eq!(f.expected.len(), n * OUTPUTS);
    let model = LearnedOdometry::shipped().unwrap();
    let mut worst = 0.0f32;
    for (w, want) in f
        .windows
        .chunks_exact(CHANNELS * WINDOW)
        .zip(f.expected.chunks_exact(OUTPUTS))
    {
        let got = model.network().forward(w).unwrap();
        for (g, e) in got.iter().zip(want) {
            worst = worst.max((g - e).abs());
        }
    }
    assert!(worst <= 1e-4, "largest difference {worst}");
}

#[test]
fn shipped_weights_are_small_and_documented() {
    let model = LearnedOdometry::shipped().unwrap();
    let p = model.network().parameters();
    assert!((1_000..=500_000).contains(&p), "{p} parameters");
    let meta = model.network().metadata();
    for key in ["command", "data_sha256", "train_seconds", "seed"] {
        assert!(meta.contains_key(key), "metadata lacks {key}");
    }
}

/// The streaming odometry, fed a recorded walk's IMU one sample at a time in time order and
/// finished, gives exactly the batch outputs (`ImuGrid::from_walk` + windows).
#[test]
fn stream_equals_batch_on_the_fixture_walk() {
    use std::sync::Arc;
    use wipdr_pdr::odometry::OdometryStream;
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/sim/F1/path_data_files/sim_F1_w0000.txt.gz"
    );
    let walk = wipdr_io::trace::read_walk(path).unwrap().walk;
    let model = Arc::new(LearnedOdometry::shipped().unwrap());
    let batch = model.run(&walk).unwrap();
    assert!(batch.len() >= 60, "{} outputs", batch.len());
    let imu = &walk.imu;
    let mut all: Vec<(i64, u8, [f64; 3])> = Vec::new();
    all.extend(imu.accelerometer.iter().map(|s| (s.t, 0, s.v)));
    all.extend(imu.gyroscope.iter().map(|s| (s.t, 1, s.v)));
    all.extend(imu.rotation_vector.iter().map(|s| (s.t, 2, s.v)));
    all.sort_by_key(|&(t, k, _)| (t, k));
    let mut stream = OdometryStream::new(model);
    let mut got = Vec::new();
    let mut live = 0usize;
    for (t, k, v) in all {
        match k {
            0 => stream.push_accelerometer(t, v),
            1 => stream.push_gyroscope(t, v),
            _ => stream.push_rotation_vector(t, v),
        }
        got.extend(std::iter::from_fn(|| stream.pop()));
        live = got.len();
    }
    stream.finish();
    got.extend(std::iter::from_fn(|| stream.pop()));
    // all but the last window come live, before the end of the stream
    assert!(live + 1 >= batch.len(), "{live} live of {}", batch.len());
    assert_eq!(got, batch);
}

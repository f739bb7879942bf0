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

//! A training waypoint at 1e20 or 1e308 (issue 14) no longer crashes the evaluation: the
//! trail raster that such a waypoint makes absurd is skipped with a warning, and the schemes
//! still run on the fixture floor.

use wipdr_core::Point2;
use wipdr_eval::pipeline::{self, EvalConfig, FloorInput};

mod common;
use common::fixture_floor;

#[test]
fn a_far_waypoint_does_not_crash_the_evaluation() {
    for far in [1e20, 1e308] {
        let floor = fixture_floor();
        let mut data = (*floor.data).clone();
        let waypoints = &mut data.walks[0].waypoints;
        assert!(waypoints.len() >= 2, "the fixture walk has a trail");
        let last = waypoints.len() - 1;
        waypoints[last].position = Point2::new(far, 0.0);
        let moved = FloorInput::new(floor.label.clone(), data);
        let schemes = ["wifi".to_string(), "pmf".to_string()];
        let cfg = EvalConfig::default();
        let report = pipeline::evaluate(std::slice::from_ref(&moved), &cfg, &schemes, &|| {})
            .unwrap_or_else(|e| panic!("{far}: {e}"));
        for s in &schemes {
            assert!(report.pooled.contains_key(s), "{far}: no figures for {s}");
        }
    }
}

//! Positions at 1e20, 1e308 and NaN reach the rasters (the trail raster, the walkable grid,
//! `pmf`'s lattice) as typed errors or skips, never as a panic or a wrapped index (issue 14:
//! a waypoint at 1e20 crashed `wipdr eval` through `ceil() as usize + 1` in `trails.rs`).

use std::sync::Arc;
use wipdr_core::ConfigError;

use wipdr_core::{FloorPlan, MotionState, Point2, Polygon, Segment, StepEvent, WifiObservation};
use wipdr_fusion::point_mass::{PointMassConfig, PointMassFilter};
use wipdr_fusion::trails::{self, TrailRaster, trails_of};
use wipdr_fusion::{Fuser, FusionError, WalkableGrid};

/// Far but finite coordinates, of either sign.
const FAR: [f64; 6] = [1e20, -1e20, 1e308, -1e308, f64::MAX, -f64::MAX];

fn seg(ax: f64, ay: f64, bx: f64, by: f64) -> Segment {
    Segment {
        a: Point2::new(ax, ay),
        b: Point2::new(bx, by),
    }
}

fn wp(t: i64, x: f64, y: f64) -> wipdr_core::Waypoint {
    wipdr_core::Waypoint::new(t, Point2::new(x, y))
}

fn fix(t: i64, x: f64, y: f64) -> WifiObservation {
    WifiObservation {
        t,
        estimate: Point2::new(x, y),
        candidates: vec![],
        visited: 0,
        floor: None,
        building: None,
        likelihood: None,
    }
}

fn step(t: i64, length: f64, heading: f64) -> StepEvent {
    StepEvent {
        t,
        length,
        heading,
        heading_change: 0.0,
        period_s: 0.5,
        motion: MotionState::default(),
        covariance: None,
    }
}

/// A trail from a near waypoint to a far one spans more cells than the limit: a typed error
/// that names the limit (the old code wrapped the cell count to 0 and indexed an empty
/// raster, or overflowed `usize::MAX + 1`).
#[test]
fn a_trail_raster_over_a_far_waypoint_is_a_typed_error() {
    for far in FAR {
        for segments in [
            vec![seg(0.0, 0.0, 10.0, 0.0), seg(10.0, 0.0, far, 0.0)],
            vec![seg(0.0, 0.0, 0.0, far)],
            vec![seg(far, far, 0.0, 0.0)],
            vec![seg(-far, 0.0, far, 0.0)],
        ] {
            match TrailRaster::new(&segments, 0.5, 10.0) {
                Err(FusionError::InvalidConfig(ConfigError {
                    path: field,
                    reason,
                })) => {
                    assert_eq!(field, "trails", "{far}: {reason}");
                    assert!(
                        reason.contains(&trails::MAX_CELLS.to_string()),
                        "{far}: {reason}"
                    );
                }
                other => panic!("{far}: expected a typed error, got {other:?}"),
            }
        }
    }
    // The same through the waypoints of a training walk.
    let walk = [wp(0, 0.0, 0.0), wp(1, 5.0, 0.0), wp(2, 1e20, 3.0)];
    let segments = trails_of([&walk[..]]);
    assert!(TrailRaster::new(&segments, 0.5, 10.0).is_err());
}

/// A trail that is far away but small is a valid (far) raster; looking anything up in it
/// answers the cap or a real distance, never panics.
#[test]
fn a_small_far_trail_is_a_raster_and_lookups_never_panic() {
    for far in FAR {
        let r = TrailRaster::new(&[seg(far, far, far, far)], 0.5, 10.0)
            .unwrap_or_else(|e| panic!("{far}: {e}"));
        // At these magnitudes the raster collapses onto the trail's one representable point.
        assert!(r.grid().cell_of(Point2::new(far, far)).is_some(), "{far}");
        assert_eq!(r.distance(Point2::new(far, far)), 0.0, "{far}");
        for p in [
            Point2::new(far, far),
            Point2::new(0.0, 0.0),
            Point2::new(f64::NAN, far),
            Point2::new(f64::INFINITY, f64::NEG_INFINITY),
            Point2::new(-far, far),
        ] {
            let d = r.distance(p);
            assert!((0.0..=10.0).contains(&d), "{far}: {p:?} -> {d}");
        }
        assert_eq!(r.distance(Point2::new(0.0, 0.0)), 10.0);
    }
}

/// NaN (and infinite) segments are skipped; with none left the raster is an error.
#[test]
fn non_finite_trails_are_skipped() {
    let good = seg(0.0, 0.0, 10.0, 0.0);
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let r = TrailRaster::new(&[seg(bad, 0.0, 1.0, 1.0), good], 0.5, 10.0).unwrap();
        let alone = TrailRaster::new(&[good], 0.5, 10.0).unwrap();
        for x in [-5.0, 0.0, 3.3, 12.0] {
            let p = Point2::new(x, 1.7);
            assert_eq!(r.distance(p), alone.distance(p));
        }
        assert!(matches!(
            TrailRaster::new(&[seg(0.0, bad, 1.0, 1.0)], 0.5, 10.0),
            Err(FusionError::InvalidConfig(e)) if e.path == "trails"
        ));
    }
}

fn plan() -> Arc<WalkableGrid> {
    let plan = FloorPlan::new(
        30.0,
        20.0,
        vec![Polygon::rectangle(0.0, 0.0, 30.0, 20.0).unwrap()],
        vec![],
    )
    .unwrap();
    Arc::new(WalkableGrid::new(&plan, 0.5).unwrap())
}

/// `pmf` fed fixes, a start, reference points and steps at 1e20, 1e308, NaN: nothing
/// panics, and whatever it answers is finite.
#[test]
fn pmf_survives_far_and_non_finite_positions() {
    let cfg = PointMassConfig {
        trail_sd_m: 1.0,
        ..PointMassConfig::default()
    };
    let far_trails = TrailRaster::new(&[seg(1e20, 1e20, 1e20, 1e20)], 0.5, 10.0)
        .ok()
        .map(Arc::new);
    let values = FAR.iter().copied().chain([f64::NAN, f64::INFINITY, 3.0]);
    for v in values {
        let coverage = Arc::new(vec![
            Point2::new(v, 1.0),
            Point2::new(1.0, v),
            Point2::new(5.0, 5.0),
        ]);
        for walkable in [None, Some(plan())] {
            for start in [None, Some(Point2::new(v, 2.0)), Some(Point2::new(v, v))] {
                let built = PointMassFilter::new(
                    cfg.clone(),
                    walkable.clone(),
                    Some(coverage.clone()),
                    start,
                );
                let Ok(f) = built else {
                    // A start the lattice cannot be laid around is a typed error.
                    assert!(start.is_some(), "{v}: {built:?}");
                    continue;
                };
                let mut f = f.with_trails(far_trails.clone());
                let mut t = 0;
                let check = |f: &PointMassFilter| {
                    if let Some(e) = f.estimate() {
                        let p = e.position;
                        assert!(p.x.is_finite() && p.y.is_finite(), "{v}: {p:?}");
                    }
                };
                for (x, y) in [(v, 3.0), (4.0, v), (v, v), (5.0, 5.0)] {
                    t += 500;
                    f.on_wifi(&fix(t, x, y));
                    check(&f);
                    for length in [0.7, v.abs(), 1e308] {
                        t += 500;
                        f.on_step(&step(t, length, 0.3));
                        check(&f);
                    }
                }
            }
        }
    }
}

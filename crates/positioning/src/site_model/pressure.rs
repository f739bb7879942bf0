//! Barometric references learned from training walks: the pressure a phone model read on a
//! known floor at a known time, which the floor estimate of a later stream of the same phone
//! model compares its barometer with ([`crate::FloorTracker`]).

use crate::PressureReference;
use wipdr_core::walk::floor_of_waypoints;
use wipdr_core::{TimestampMs, Walk};

/// Length of the stretches a training walk's pressure is averaged over, ms.
pub const REFERENCE_STRETCH_MS: i64 = 30_000;
/// Largest pressure range within a stretch for it to be a reference (a stretch on the
/// stairs is not), hPa.
pub const REFERENCE_MAX_RANGE_HPA: f64 = 0.1;

/// Barometric references from walks with a phone model, a start time (Unix ms) and
/// floors on their waypoints: the mean pressure of each stretch of [`REFERENCE_STRETCH_MS`]
/// within the waypoints' span on one floor, steady within [`REFERENCE_MAX_RANGE_HPA`].
pub fn pressure_references(walks: &[&Walk]) -> Vec<PressureReference> {
    let mut out = Vec::new();
    for w in walks {
        let (Some(model), Some(start)) = (&w.meta.model, w.meta.start_time) else {
            continue;
        };
        let mut stretch: Vec<(TimestampMs, f64)> = Vec::new();
        let mut stretch_floor: Option<i32> = None;
        let mut flush = |stretch: &mut Vec<(TimestampMs, f64)>, floor: Option<i32>| {
            if let (Some(floor), Some(first), Some(last)) = (floor, stretch.first(), stretch.last())
                && stretch.len() >= 5
            {
                let (lo, hi) = stretch
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                        (lo.min(p.1), hi.max(p.1))
                    });
                if hi - lo <= REFERENCE_MAX_RANGE_HPA {
                    let mean = stretch.iter().map(|p| p.1).sum::<f64>() / stretch.len() as f64;
                    out.push(PressureReference {
                        model: model.clone(),
                        t_unix_ms: start.saturating_add((first.0 + last.0) / 2),
                        hpa: mean,
                        floor,
                    });
                }
            }
            stretch.clear();
        };
        for p in &w.pressure {
            let floor = floor_of_waypoints(&w.waypoints, p.t);
            let too_long = stretch
                .first()
                .is_some_and(|f| p.t - f.0 >= REFERENCE_STRETCH_MS);
            if floor != stretch_floor || too_long {
                flush(&mut stretch, stretch_floor);
                stretch_floor = floor;
            }
            if floor.is_some() && p.hpa.is_finite() {
                stretch.push((p.t, p.hpa));
            }
        }
        flush(&mut stretch, stretch_floor);
    }
    out
}

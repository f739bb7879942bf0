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

/// A steady stretch of a walk's barometer on one floor: its middle time (walk ms), mean
/// pressure (hPa) and floor.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Stretch {
    t: TimestampMs,
    hpa: f64,
    floor: i32,
}

/// The steady stretches of one walk: each stretch of [`REFERENCE_STRETCH_MS`] within the
/// waypoints' span on one floor, steady within [`REFERENCE_MAX_RANGE_HPA`], in time order.
fn steady_stretches(w: &Walk) -> Vec<Stretch> {
    let mut out = Vec::new();
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
                out.push(Stretch {
                    t: (first.0 + last.0) / 2,
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
    out
}

/// Barometric references from walks with a phone model, a start time (Unix ms) and
/// floors on their waypoints: the mean pressure of each stretch of [`REFERENCE_STRETCH_MS`]
/// within the waypoints' span on one floor, steady within [`REFERENCE_MAX_RANGE_HPA`].
pub fn pressure_references(walks: &[&Walk]) -> Vec<PressureReference> {
    let mut out = Vec::new();
    for w in walks {
        let (Some(model), Some(start)) = (&w.meta.model, w.meta.start_time) else {
            continue;
        };
        out.extend(steady_stretches(w).into_iter().map(|s| PressureReference {
            model: model.clone(),
            t_unix_ms: start.saturating_add(s.t),
            hpa: s.hpa,
            floor: s.floor,
        }));
    }
    out
}

/// Longest time between two steady stretches of a walk on different floors for their
/// pressure difference to measure the floors' heights, ms (weather drift of 1 hPa an hour
/// moves the pressure by 0.03 hPa in that time, a tenth of a floor).
pub const HEIGHT_PAIR_MAX_MS: i64 = 120_000;

/// Weight of the default gap ([`crate::FloorConfig::hpa_per_floor`]) between adjacent floors
/// against one measured pair of floors in the heights' least squares: small, so that any
/// measurement decides and only floors no walk measured keep the default.
const DEFAULT_GAP_WEIGHT: f64 = 1e-3;

/// The heights of `floors` (sorted, distinct), metres above the lowest: from the training
/// walks' pressure where they change floor (the difference between the steady stretches on
/// either side of each change within [`HEIGHT_PAIR_MAX_MS`], over
/// [`crate::HPA_PER_METRE`]), least squares over every such pair; floors no pair measures
/// are `default_hpa_per_floor` apart from their neighbours. Walks need no phone model or
/// start time (only differences within a walk count).
pub fn floor_heights(walks: &[&Walk], floors: &[i32], default_hpa_per_floor: f64) -> Vec<f64> {
    let n = floors.len();
    if n == 0 {
        return Vec::new();
    }
    let index = |f: i32| floors.binary_search(&f).ok();
    // Normal equations of sum (x_j - x_i - rise)^2 over the measured pairs plus the weak
    // default gaps, x = height as a pressure drop (hPa), x_0 anchored at 0.
    let mut a = nalgebra::DMatrix::<f64>::zeros(n, n);
    let mut b = nalgebra::DVector::<f64>::zeros(n);
    let mut add = |i: usize, j: usize, rise: f64, w: f64| {
        a[(i, i)] += w;
        a[(j, j)] += w;
        a[(i, j)] -= w;
        a[(j, i)] -= w;
        b[j] += w * rise;
        b[i] -= w * rise;
    };
    for k in 1..n {
        let levels = f64::from(floors[k] - floors[k - 1]);
        add(k - 1, k, levels * default_hpa_per_floor, DEFAULT_GAP_WEIGHT);
    }
    let mut pairs = 0usize;
    for w in walks {
        let stretches = steady_stretches(w);
        for pair in stretches.windows(2) {
            let (s, e) = (pair[0], pair[1]);
            if s.floor == e.floor || e.t - s.t > HEIGHT_PAIR_MAX_MS {
                continue;
            }
            let (Some(i), Some(j)) = (index(s.floor), index(e.floor)) else {
                continue;
            };
            // Going up, the pressure drops.
            add(i, j, s.hpa - e.hpa, 1.0);
            pairs += 1;
        }
    }
    a[(0, 0)] += 1.0;
    let x = a.lu().solve(&b);
    let heights: Option<Vec<f64>> = x.map(|x| {
        x.iter()
            .map(|v| (v - x[0]) / crate::HPA_PER_METRE)
            .collect()
    });
    match heights {
        Some(h) if h.iter().all(|v| v.is_finite()) && h.windows(2).all(|w| w[1] > w[0]) => {
            tracing::debug!(pairs, ?floors, heights_m = ?h, "floor heights");
            h
        }
        other => {
            tracing::warn!(pairs, ?floors, heights_m = ?other, "floor heights not increasing with the floor: default heights");
            floors
                .iter()
                .map(|&f| f64::from(f - floors[0]) * default_hpa_per_floor / crate::HPA_PER_METRE)
                .collect()
        }
    }
}

/// The building's floors from the floors the data names: every floor number from the lowest
/// to the highest (a building with floors -2 and 0 has a floor -1, whether or not any data
/// was recorded there).
pub fn building_floors(named: &[i32]) -> Vec<i32> {
    match (named.iter().min(), named.iter().max()) {
        (Some(&lo), Some(&hi)) => (lo..=hi).collect(),
        _ => Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use wipdr_core::{Point2, PressureSample, Waypoint};

    /// A walk on `floors[k]` during minute `k`, its pressure `hpa[k]` there (10 Hz, 10 s
    /// of stairs between floors).
    fn walk(floors: &[i32], hpa: &[f64]) -> Walk {
        let mut w = Walk::default();
        for (k, (&f, &p)) in floors.iter().zip(hpa).enumerate() {
            let t0 = 60_000 * k as i64;
            w.waypoints
                .push(Waypoint::new(t0, Point2::new(0.0, 0.0)).on_floor(f));
            w.waypoints
                .push(Waypoint::new(t0 + 50_000, Point2::new(1.0, 0.0)).on_floor(f));
            for i in 0..600 {
                let t = t0 + 100 * i;
                let prev = if k > 0 { hpa[k - 1] } else { p };
                let a = (i as f64 / 100.0).min(1.0);
                w.pressure.push(PressureSample {
                    t,
                    hpa: prev + a * (p - prev),
                });
            }
        }
        w
    }

    #[test]
    fn heights_come_from_floor_changes_and_the_default_fills_the_rest() {
        // Floor 0 to 2 is 0.9 hPa (7.6 m); floor 3 was never visited.
        let w = walk(&[0, 2, 0], &[1000.0, 999.1, 1000.0]);
        let floors = building_floors(&[0, 2, 3]);
        assert_eq!(floors, vec![0, 1, 2, 3]);
        let h = floor_heights(&[&w], &floors, 0.4);
        assert!((h[2] - 0.9 / crate::HPA_PER_METRE).abs() < 0.05, "{h:?}");
        assert!((h[1] - 0.45 / crate::HPA_PER_METRE).abs() < 0.05, "{h:?}");
        assert!(
            (h[3] - h[2] - 0.4 / crate::HPA_PER_METRE).abs() < 0.05,
            "{h:?}"
        );
        // Without a floor change: the default everywhere.
        let flat = walk(&[1, 1], &[1000.0, 1000.0]);
        let d = floor_heights(&[&flat], &floors, 0.4);
        for (k, v) in d.iter().enumerate() {
            assert!(
                (v - k as f64 * 0.4 / crate::HPA_PER_METRE).abs() < 1e-6,
                "{d:?}"
            );
        }
    }
}

//! Two-filter smoothing of any [`crate::Fuser`]: the scheme run forward, the same scheme run
//! on the time-reversed walk, the two estimates combined at each time.
//!
//! The reversed walk ([`reversed`]) is the same walk walked backwards: an input at `t` is fed
//! at `T - t` (`T` the latest input time), each step's displacement is negated (heading + pi)
//! and the Wi-Fi fixes are unchanged. A filter run on it estimates at each time the position
//! from the inputs *after* it; the forward filter from those up to it. [`combine`] joins the
//! two: the information-weighted mean where both carry a covariance, the plain mean otherwise
//! (both are then estimates of one position with no stated confidence).
//!
//! The joined covariance is covariance intersection's with weight one half (Julier and
//! Uhlmann 1997): `P = (Pf⁻¹ / 2 + Pb⁻¹ / 2)⁻¹`, twice the Gaussian product's, with the
//! product's mean. The two directions see disjoint inputs but share the walk's Wi-Fi bias
//! (a fix error common to the walk: 40 % of the ILC fixes' error variance,
//! `docs/results/fix_errors.py`, docs/experiments.md) and the common prior; covariance
//! intersection is never overconfident whatever that correlation, where the product, which
//! assumes none, shrank the radius: `wipdr eval --offline` measured the offline 95 % radii
//! of `aws`, `tcpf`, `pf`, `apf`, `rof` at 80-84 % coverage on IPIN and 91-93 % on the ILC
//! floors with the product, 91-94 % and 96-97 % with this (docs/results/accuracy.md,
//! docs/experiments.md). No estimate moves.

use nalgebra::Matrix2;
use wipdr_core::{Point2, StepEvent, TimestampMs, WifiObservation, angle};

/// An estimate to combine: time, position, covariance where the scheme has one.
pub type TimedEstimate = (TimestampMs, Point2, Option<Matrix2<f64>>);

/// The walk reversed in time: `(steps, fixes, T)` with inputs at `T - t`, steps walking back
/// (heading + pi, the heading change of the step that follows it forward, negated).
pub fn reversed(
    steps: &[StepEvent],
    fixes: &[WifiObservation],
) -> (Vec<StepEvent>, Vec<WifiObservation>, TimestampMs) {
    let end = steps
        .iter()
        .map(|s| s.t)
        .chain(fixes.iter().map(|f| f.t))
        .max()
        .unwrap_or(0);
    let back_steps = (0..steps.len())
        .rev()
        .map(|i| {
            let s = &steps[i];
            let change = steps.get(i + 1).map_or(0.0, |next| -next.heading_change);
            StepEvent {
                t: end - s.t,
                heading: angle::wrap_two_pi(s.heading + std::f64::consts::PI),
                heading_change: angle::wrap_pi(change),
                ..*s
            }
        })
        .collect();
    let back_fixes = fixes
        .iter()
        .rev()
        .map(|f| WifiObservation {
            t: end - f.t,
            ..f.clone()
        })
        .collect();
    (back_steps, back_fixes, end)
}

/// Joins a forward track (estimates after each input, forward time) and a backward track
/// (estimates after each input of the [`reversed`] walk, in its time) into one estimate at
/// every forward output time: the backward state used at forward time `t` is the one after
/// all inputs later than `t`. Where only one side has an estimate, it stands alone.
pub fn combine(
    forward: &[TimedEstimate],
    backward: &[TimedEstimate],
    end: TimestampMs,
) -> Vec<TimedEstimate> {
    // Backward estimates in forward time, ascending: the state after the input at forward
    // time u covers the inputs at or after u.
    let mut back: Vec<TimedEstimate> = backward.iter().map(|&(t, p, c)| (end - t, p, c)).collect();
    back.reverse();
    let mut times: Vec<TimestampMs> = forward.iter().map(|e| e.0).collect();
    times.extend(back.iter().map(|e| e.0));
    times.sort_unstable();
    times.dedup();
    let mut out = Vec::with_capacity(times.len());
    let (mut i, mut f) = (0usize, None::<TimedEstimate>);
    for t in times {
        while i < forward.len() && forward[i].0 <= t {
            f = Some(forward[i]);
            i += 1;
        }
        // The backward state covering the inputs strictly after t.
        let j = back.partition_point(|e| e.0 <= t);
        let b = back.get(j).copied();
        let joined = match (f, b) {
            (Some(f), Some(b)) => fuse(f.1, f.2, b.1, b.2),
            (Some(f), None) => (f.1, f.2),
            (None, Some(b)) => (b.1, b.2),
            (None, None) => continue,
        };
        if joined.0.x.is_finite() && joined.0.y.is_finite() {
            out.push((t, joined.0, joined.1));
        }
    }
    out
}

/// The information-weighted mean of two Gaussian estimates with covariance intersection's
/// covariance at weight one half (twice the product's; see the module docs); the mean
/// without both covariances.
fn fuse(
    a: Point2,
    pa: Option<Matrix2<f64>>,
    b: Point2,
    pb: Option<Matrix2<f64>>,
) -> (Point2, Option<Matrix2<f64>>) {
    if let (Some(pa), Some(pb)) = (pa, pb)
        && let (Some(ia), Some(ib)) = (pa.try_inverse(), pb.try_inverse())
        && let Some(p) = (ia + ib).try_inverse()
    {
        let mean = p * (ia * a.coords + ib * b.coords);
        // Covariance intersection, weight 1/2: ((ia + ib) / 2)^-1 = 2 p.
        let mut p = p * 2.0;
        crate::kalman::enforce_symmetric_pd(&mut p);
        return (Point2::from(mean), Some(p));
    }
    (Point2::from((a.coords + b.coords) * 0.5), None)
}

#[cfg(test)]
mod tests {
    use super::*;
    use wipdr_core::MotionState;

    fn step(t: i64, heading: f64, change: f64) -> StepEvent {
        StepEvent {
            t,
            length: 0.7,
            heading,
            heading_change: change,
            period_s: 0.5,
            motion: MotionState::default(),
            covariance: None,
        }
    }

    #[test]
    fn the_reversed_walk_retraces_the_forward_one() {
        let steps = vec![
            step(100, 0.0, 0.0),
            step(200, 1.0, 1.0),
            step(300, 2.0, 1.0),
        ];
        let (back, _, end) = reversed(&steps, &[]);
        assert_eq!(end, 300);
        assert_eq!(
            back.iter().map(|s| s.t).collect::<Vec<_>>(),
            vec![0, 100, 200]
        );
        let sum = |s: &[StepEvent]| {
            s.iter()
                .map(|s| angle::step_displacement(s.length, s.heading))
                .sum::<wipdr_core::Vector2>()
        };
        assert!((sum(&steps) + sum(&back)).norm() < 1e-12);
        assert!((back[1].heading_change + 1.0).abs() < 1e-12);
    }

    #[test]
    fn combining_weighs_by_information_and_uses_the_later_inputs_backward() {
        let big = Some(Matrix2::identity() * 9.0);
        let small = Some(Matrix2::identity());
        let forward = vec![
            (10, Point2::new(0.0, 0.0), big),
            (20, Point2::new(0.0, 0.0), big),
        ];
        // Backward (reversed time, end = 20): after the input at forward 20, then at 10.
        let backward = vec![
            (0, Point2::new(10.0, 0.0), small),
            (10, Point2::new(5.0, 0.0), small),
        ];
        let out = combine(&forward, &backward, 20);
        // At forward 10 the backward state after the inputs later than 10: that of forward 20.
        assert_eq!(out[0].0, 10);
        assert!((out[0].1.x - 9.0).abs() < 1e-9, "{:?}", out[0]);
        // At forward 20 nothing is later: forward alone.
        assert_eq!(out[1].1, Point2::new(0.0, 0.0));
        // Covariance intersection at weight 1/2: twice the product's (9 x 1 / 10 = 0.9),
        // and a side standing alone keeps its own.
        let p = out[0].2.unwrap();
        assert!((p - Matrix2::identity() * 1.8).norm() < 1e-9, "{p}");
        assert_eq!(out[1].2, big);
    }

    proptest::proptest! {
        /// The joined covariance is symmetric positive definite and never smaller than the
        /// Gaussian product's (which assumes independent errors): `P - (Pa⁻¹ + Pb⁻¹)⁻¹` is
        /// positive semi-definite; the mean is finite.
        #[test]
        fn the_joined_covariance_is_spd_and_bounds_the_product(
            sa in 0.1f64..50.0, sb in 0.1f64..50.0, rho in -0.9f64..0.9,
            ax in -50.0f64..50.0, bx in -50.0f64..50.0,
        ) {
            let off = rho * sa;
            let pa = Matrix2::new(sa, off, off, sa);
            let pb = Matrix2::identity() * sb;
            let (m, p) = fuse(Point2::new(ax, 0.0), Some(pa), Point2::new(bx, 0.0), Some(pb));
            let p = p.unwrap();
            proptest::prop_assert!((p[(0, 1)] - p[(1, 0)]).abs() < 1e-9);
            proptest::prop_assert!(p[(0, 0)] > 0.0 && p.determinant() > 0.0);
            let product = (pa.try_inverse().unwrap() + pb.try_inverse().unwrap())
                .try_inverse()
                .unwrap();
            let gap = p - product;
            proptest::prop_assert!(gap[(0, 0)] >= -1e-9 && gap.determinant() >= -1e-9);
            proptest::prop_assert!(m.x.is_finite() && m.y.is_finite());
        }
    }

    #[test]
    fn without_covariances_the_mean_is_taken() {
        let forward = vec![(10, Point2::new(0.0, 0.0), None)];
        let backward = vec![
            (0, Point2::new(4.0, 2.0), None),
            (15, Point2::new(2.0, 2.0), None),
        ];
        let out = combine(&forward, &backward, 20);
        // At forward 5 (before the forward's first estimate) the backward state after the
        // input at 20 stands alone.
        assert_eq!(out[0], (5, Point2::new(4.0, 2.0), None));
        assert_eq!(out[1], (10, Point2::new(2.0, 1.0), None));
    }
}

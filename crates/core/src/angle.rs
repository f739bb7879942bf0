//! Angle helpers: wrapping and the heading convention (clockwise from `+y`).

use crate::Vector2;
use std::f64::consts::{PI, TAU};

/// Wraps an angle (radians) into `(-pi, pi]`.
///
/// ```
/// use wipdr_core::angle::wrap_pi;
/// assert!((wrap_pi(3.0 * std::f64::consts::PI) - std::f64::consts::PI).abs() < 1e-12);
/// assert!((wrap_pi(-std::f64::consts::PI) - std::f64::consts::PI).abs() < 1e-12);
/// ```
#[inline]
pub fn wrap_pi(a: f64) -> f64 {
    if !a.is_finite() {
        return a;
    }
    let mut r = a.rem_euclid(TAU); // [0, 2pi)
    if r > PI {
        r -= TAU;
    }
    r
}

/// Wraps an angle (radians) into `[0, 2 pi)`.
#[inline]
pub fn wrap_two_pi(a: f64) -> f64 {
    if !a.is_finite() {
        return a;
    }
    let r = a.rem_euclid(TAU);
    if r >= TAU { 0.0 } else { r }
}

/// The signed difference `a - b` wrapped into `(-pi, pi]`.
#[inline]
pub fn diff(a: f64, b: f64) -> f64 {
    wrap_pi(a - b)
}

/// Displacement of a step of `length` metres at heading `psi` (radians, clockwise from `+y`):
/// `(l sin psi, l cos psi)`.
#[inline]
pub fn step_displacement(length: f64, psi: f64) -> Vector2 {
    Vector2::new(length * psi.sin(), length * psi.cos())
}

/// The heading (clockwise from `+y`) of a displacement; `0` for the zero vector.
#[inline]
pub fn heading_of(d: Vector2) -> f64 {
    if d.x == 0.0 && d.y == 0.0 {
        0.0
    } else {
        d.x.atan2(d.y)
    }
}

/// Circular mean of angles (radians); `None` if empty or the resultant vanishes.
pub fn circular_mean(angles: impl IntoIterator<Item = f64>) -> Option<f64> {
    let (mut s, mut c, mut n) = (0.0, 0.0, 0usize);
    for a in angles {
        s += a.sin();
        c += a.cos();
        n += 1;
    }
    if n == 0 || (s.abs() < 1e-12 && c.abs() < 1e-12) {
        None
    } else {
        Some(s.atan2(c))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn heading_roundtrip() {
        for psi in [-3.0, -1.0, 0.0, 0.5, 2.0, 3.1] {
            let d = step_displacement(1.0, psi);
            assert!((diff(heading_of(d), psi)).abs() < 1e-12);
        }
    }

    #[test]
    fn circular_mean_across_pi() {
        let m = circular_mean([PI - 0.1, -PI + 0.1]).unwrap();
        assert!(diff(m, PI).abs() < 1e-9);
        assert!(circular_mean([]).is_none());
    }

    proptest! {
        #[test]
        fn wrap_in_range(a in -1e6f64..1e6) {
            let w = wrap_pi(a);
            prop_assert!(w > -PI - 1e-12 && w <= PI + 1e-12);
            prop_assert!(((a - w) / TAU - ((a - w) / TAU).round()).abs() < 1e-6);
        }

        #[test]
        fn diff_is_small_for_close_angles(a in -10.0f64..10.0, d in -3.0f64..3.0) {
            prop_assert!((diff(a + d, a) - d).abs() < 1e-9);
        }
    }
}

//! Learned inertial odometry (issue 44): a small network over windows of the phone's IMU
//! gives the displacement of each second of the walk and its covariance, a second motion
//! source beside the step model.
//!
//! - [`features`]: the walk resampled at 50 Hz and rotated into a level frame that turns with
//!   the phone's yaw ([`features::ImuGrid`], [`features::Window`]).
//! - [`model`]: the network's forward pass, hand-written (no training stack in the library),
//!   weights from a safetensors file that the training program `tools/odometry-train`
//!   (candle) writes.
//! - [`LearnedOdometry`]: windows -> [`OdometryOutput`]s (world-frame displacement over the
//!   last second and its 2x2 covariance), and the displacement over any time span
//!   ([`span_displacement`]), as the training loss integrates it over waypoint segments.
//! - [`stream`]: the same outputs from a live stream, samples pushed one at a time
//!   ([`OdometryStream`]).
//!
//! Headings: the displacement comes out in the rotation vector's East-North-Up frame; a
//! floor's map frame differs from it by the same heading offset that the step model's
//! calibration fits (`PdrConfig::heading.map_offset_rad`), which callers add with
//! [`rotate_heading`].

pub mod features;
pub mod model;
pub mod stream;

pub use stream::OdometryStream;

use features::{GRID_MS, ImuGrid, STRIDE, Window, local_to_world};
use model::Network;
use wipdr_core::{TimestampMs, Walk};

/// Errors of the learned odometry.
#[derive(Debug, thiserror::Error)]
pub enum OdometryError {
    /// The weight file is malformed.
    #[error("odometry weights: {0}")]
    Format(String),
    /// A tensor the network needs is missing.
    #[error("odometry weights: tensor `{0}` missing")]
    Missing(String),
    /// An input window has the wrong size.
    #[error("odometry input: {0}")]
    Input(String),
    /// The network produced a non-finite output.
    #[error("odometry network produced a non-finite output")]
    NonFinite,
}

/// Log variances are clamped to this range before exponentiation (variances of about
/// 6e-6 .. 400 m² a second).
pub const LOG_VAR_RANGE: (f32, f32) = (-12.0, 6.0);

/// One output: the displacement over the output interval `(t_end - 1 s, t_end]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometryOutput {
    /// End of the interval, ms.
    pub t_end: TimestampMs,
    /// Displacement `(east, north)` in the rotation vector's frame, m.
    pub displacement: [f64; 2],
    /// Its covariance `(xx, xy, yy)`, m².
    pub covariance: [f64; 3],
}

/// Length of one output interval, ms.
pub const INTERVAL_MS: i64 = STRIDE as i64 * GRID_MS;

/// The network and what it needs to turn windows into displacements.
#[derive(Debug, Clone)]
pub struct LearnedOdometry {
    network: Network,
}

/// The shipped weights (safetensors, trained on the five ILC floors by
/// `tools/odometry-train`; the command, data hash and training time are in the file's
/// metadata, see `docs/results/odometry.md`).
pub const SHIPPED_WEIGHTS: &[u8] = include_bytes!("learned.safetensors");

impl LearnedOdometry {
    /// The odometry of the shipped weights ([`SHIPPED_WEIGHTS`]).
    pub fn shipped() -> Result<Self, OdometryError> {
        Self::from_safetensors(SHIPPED_WEIGHTS)
    }

    /// The shipped weights parsed once per process and shared between streams (a
    /// [`crate::odometry::OdometryStream`] each).
    pub fn shipped_shared() -> Result<std::sync::Arc<Self>, OdometryError> {
        static SHIPPED: std::sync::OnceLock<Result<std::sync::Arc<LearnedOdometry>, String>> =
            std::sync::OnceLock::new();
        SHIPPED
            .get_or_init(|| {
                Self::shipped()
                    .map(std::sync::Arc::new)
                    .map_err(|e| e.to_string())
            })
            .clone()
            .map_err(OdometryError::Format)
    }

    /// The odometry of a safetensors weight file's bytes.
    pub fn from_safetensors(bytes: &[u8]) -> Result<Self, OdometryError> {
        Ok(Self {
            network: Network::from_safetensors(bytes)?,
        })
    }

    /// The network.
    pub fn network(&self) -> &Network {
        &self.network
    }

    /// The output of one window.
    pub fn predict(&self, w: &Window) -> Result<OdometryOutput, OdometryError> {
        let o = self.network.forward(&w.data)?;
        let var = |lv: f32| f64::from(lv.clamp(LOG_VAR_RANGE.0, LOG_VAR_RANGE.1)).exp();
        let (d, cov) = local_to_world(
            w.heading,
            [f64::from(o[0]), f64::from(o[1])],
            [var(o[2]), var(o[3])],
        );
        Ok(OdometryOutput {
            t_end: w.t_end,
            displacement: d,
            covariance: cov,
        })
    }

    /// Every output of a walk (one a second from 2 s after its first accelerometer sample);
    /// empty when the walk has no accelerometer or rotation vector.
    pub fn run(&self, walk: &Walk) -> Result<Vec<OdometryOutput>, OdometryError> {
        let Some(grid) = ImuGrid::from_walk(walk) else {
            tracing::debug!(walk = %walk.meta.id, "no accelerometer or rotation vector: no odometry");
            return Ok(Vec::new());
        };
        grid.windows().iter().map(|w| self.predict(w)).collect()
    }
}

/// The fraction of the output interval `(t_end - INTERVAL_MS, t_end]` that lies in
/// `(t_a, t_b]`, in `[0, 1]`.
pub fn overlap_fraction(t_end: TimestampMs, t_a: TimestampMs, t_b: TimestampMs) -> f64 {
    let lo = (t_end - INTERVAL_MS).max(t_a);
    let hi = t_end.min(t_b);
    if hi <= lo {
        0.0
    } else {
        (hi - lo) as f64 / INTERVAL_MS as f64
    }
}

/// The displacement over `(t_a, t_b]` and its covariance: each output weighted by the
/// fraction of its interval inside the span (the displacement spread evenly over its
/// second, the covariance as a random walk). `None` when the outputs do not cover the span.
pub fn span_displacement(
    outputs: &[OdometryOutput],
    t_a: TimestampMs,
    t_b: TimestampMs,
) -> Option<([f64; 2], [f64; 3])> {
    let first = outputs.first()?;
    let last = outputs.last()?;
    if t_a < first.t_end - INTERVAL_MS || t_b > last.t_end || t_b <= t_a {
        return None;
    }
    let mut d = [0.0; 2];
    let mut c = [0.0; 3];
    for o in outputs {
        let f = overlap_fraction(o.t_end, t_a, t_b);
        if f > 0.0 {
            d[0] += f * o.displacement[0];
            d[1] += f * o.displacement[1];
            for (ci, oc) in c.iter_mut().zip(o.covariance) {
                *ci += f * oc;
            }
        }
    }
    Some((d, c))
}

/// A vector `(east, north)` turned by `offset` rad clockwise (a heading offset: the vector's
/// heading grows by `offset`).
pub fn rotate_heading(v: [f64; 2], offset: f64) -> [f64; 2] {
    let (s, c) = offset.sin_cos();
    [v[0] * c + v[1] * s, -v[0] * s + v[1] * c]
}

/// A covariance `(xx, xy, yy)` turned with its vector by [`rotate_heading`]`(_, offset)`:
/// `R C R^T`.
pub fn rotate_covariance(c: [f64; 3], offset: f64) -> [f64; 3] {
    let (s, co) = offset.sin_cos();
    // R = [[c, s], [-s, c]]
    let [a, b, d] = c;
    let xx = co * co * a + 2.0 * co * s * b + s * s * d;
    let yy = s * s * a - 2.0 * co * s * b + co * co * d;
    let xy = -co * s * a + (co * co - s * s) * b + co * s * d;
    [xx, xy, yy]
}

/// Squared Mahalanobis distance of `r` under the covariance `(xx, xy, yy)`; `None` when the
/// covariance is not positive definite.
pub fn mahalanobis2(r: [f64; 2], cov: [f64; 3]) -> Option<f64> {
    let [a, b, c] = cov;
    let det = a * c - b * b;
    (det > 0.0 && a > 0.0)
        .then(|| (c * r[0] * r[0] - 2.0 * b * r[0] * r[1] + a * r[1] * r[1]) / det)
}

/// The chi-square quantile of 2 degrees of freedom at 95 %: a 2D Gaussian's 95 % ellipse is
/// `mahalanobis2 <= CHI2_2_95`.
pub const CHI2_2_95: f64 = 5.991_464_547_107_979;

#[cfg(test)]
mod tests {
    use super::*;

    fn out(t_end: i64, dx: f64) -> OdometryOutput {
        OdometryOutput {
            t_end,
            displacement: [dx, 0.0],
            covariance: [1.0, 0.0, 1.0],
        }
    }

    #[test]
    fn span_weights_partial_seconds() {
        let outs = [out(1000, 1.0), out(2000, 2.0), out(3000, 4.0)];
        let (d, c) = span_displacement(&outs, 500, 2250).unwrap();
        // half of the first second, all of the second, a quarter of the third
        assert!((d[0] - (0.5 + 2.0 + 1.0)).abs() < 1e-12);
        assert!((c[0] - 1.75).abs() < 1e-12);
        assert!(span_displacement(&outs, -10, 2000).is_none());
        assert!(span_displacement(&outs, 0, 3001).is_none());
    }

    #[test]
    fn rotation_and_ellipse() {
        let v = rotate_heading([0.0, 1.0], std::f64::consts::FRAC_PI_2);
        assert!((v[0] - 1.0).abs() < 1e-12 && v[1].abs() < 1e-12);
        let m = mahalanobis2([2.0, 0.0], [4.0, 0.0, 1.0]).unwrap();
        assert!((m - 1.0).abs() < 1e-12);
        assert!(mahalanobis2([1.0, 0.0], [1.0, 1.0, 1.0]).is_none());
    }

    proptest::proptest! {
        /// A residual and its covariance turned together keep their Mahalanobis distance.
        #[test]
        fn turning_keeps_the_mahalanobis_distance(
            r in proptest::array::uniform2(-5.0f64..5.0),
            var in proptest::array::uniform2(0.01f64..4.0),
            psi in -7.0f64..7.0,
            offset in -7.0f64..7.0,
        ) {
            let (_, cov) = features::local_to_world(psi, [0.0, 0.0], var);
            let before = mahalanobis2(r, cov).unwrap();
            let after =
                mahalanobis2(rotate_heading(r, offset), rotate_covariance(cov, offset)).unwrap();
            proptest::prop_assert!((before - after).abs() <= 1e-9 * before.max(1.0));
        }
    }
}

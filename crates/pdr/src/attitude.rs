//! Attitude and heading: quaternion integration of the gyroscope (paper 004 eq. 1-5), the
//! tilt-compensated compass, the gyro + compass heading Kalman filter (paper 002 eq. 9-12)
//! and the phone's rotation vector.
//!
//! Every orientation here is a unit quaternion rotating the phone frame into East-North-Up
//! (Android's convention). A heading is the azimuth of the phone's `+y` axis (the direction
//! the top of a phone held flat points to), clockwise from north, in `(-pi, pi]`: the
//! project's heading convention.

use nalgebra::{Matrix2, Quaternion, UnitQuaternion, Vector2, Vector3};
use serde::{Deserialize, Serialize};
use wipdr_core::angle::wrap_pi;

/// The orientation of an Android rotation vector `(x, y, z)` with implied scalar part;
/// `None` for non-finite input.
pub fn rotation_vector_quaternion(v: [f64; 3]) -> Option<UnitQuaternion<f64>> {
    if !v.iter().all(|c| c.is_finite()) {
        return None;
    }
    let [x, y, z] = v;
    let w = (1.0 - x * x - y * y - z * z).max(0.0).sqrt();
    let q = Quaternion::new(w, x, y, z);
    (q.norm() > 1e-9).then(|| UnitQuaternion::from_quaternion(q))
}

/// Heading (azimuth of the phone's `+y` axis, clockwise from north) of an orientation:
/// `atan2(R[0][1], R[1][1])`, the yaw of paper 004 eq. 5 in the heading convention. Android's
/// `getOrientation` azimuth, as the sample code computes it.
#[inline]
pub fn heading_of(q: &UnitQuaternion<f64>) -> f64 {
    // Column 1 of R = the phone's +y axis in ENU.
    let y_axis = q * Vector3::y();
    y_axis.x.atan2(y_axis.y)
}

/// Heading rate (rad/s, clockwise positive) of a body angular rate seen through orientation
/// `q`: minus the Up component of the rate in ENU.
#[inline]
pub fn heading_rate(q: &UnitQuaternion<f64>, gyro: [f64; 3]) -> f64 {
    -(q * Vector3::new(gyro[0], gyro[1], gyro[2])).z
}

/// The orientation from gravity (accelerometer) and the magnetic field, as Android's
/// `SensorManager.getRotationMatrix`: `H = m x a` points East, `M = a x H` North, `a` Up.
/// `None` in free fall, in a field parallel to gravity or with non-finite input.
pub fn compass_orientation(acc: [f64; 3], mag: [f64; 3]) -> Option<UnitQuaternion<f64>> {
    let a = Vector3::from(acc);
    let m = Vector3::from(mag);
    if !(a.iter().all(|c| c.is_finite()) && m.iter().all(|c| c.is_finite())) {
        return None;
    }
    let h = m.cross(&a);
    let (hn, an) = (h.norm(), a.norm());
    if an < 0.1 * 9.81 || hn < 0.1 {
        return None;
    }
    let e = h / hn;
    let u = a / an;
    let n = u.cross(&e);
    // Rows of R (phone -> ENU) are E, N, U expressed in the phone frame.
    let r = nalgebra::Matrix3::from_rows(&[e.transpose(), n.transpose(), u.transpose()]);
    Some(UnitQuaternion::from_rotation_matrix(
        &nalgebra::Rotation3::from_matrix_unchecked(r),
    ))
}

/// The orientation from gravity alone with zero heading (no magnetometer): the smallest
/// rotation taking the measured gravity direction to Up.
pub fn gravity_orientation(acc: [f64; 3]) -> Option<UnitQuaternion<f64>> {
    let a = Vector3::from(acc);
    if !a.iter().all(|c| c.is_finite()) || a.norm() < 1e-6 {
        return None;
    }
    UnitQuaternion::rotation_between(&a, &Vector3::z()).or_else(|| {
        // `a` points straight down: turn half a circle about x.
        Some(UnitQuaternion::from_axis_angle(
            &Vector3::x_axis(),
            std::f64::consts::PI,
        ))
    })
}

/// Settings of the gyroscope attitude integration.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GyroAttitudeConfig {
    /// Gain (1/s) of a complementary tilt correction towards the accelerometer's gravity,
    /// applied to roll and pitch only (heading stays gyro-only). 0 = paper 004 eq. 1-5 as
    /// printed: pure integration.
    pub tilt_gain: f64,
    /// Gyro intervals longer than this are not integrated (a gap), seconds; the attitude is
    /// re-initialised from the next absolute orientation (rotation vector or compass).
    pub max_dt_s: f64,
}

impl Default for GyroAttitudeConfig {
    fn default() -> Self {
        Self {
            tilt_gain: 0.5,
            max_dt_s: 0.5,
        }
    }
}

/// Attitude by quaternion integration of the gyroscope (paper 004 eq. 1-5).
///
/// Eq. 2-3 with increments `dtheta = omega * Ts` (eq. 1) is the quaternion product
/// `q_{k+1} = q_k ⊗ [cos(|dtheta|/2), sin(|dtheta|/2) dtheta/|dtheta|]` (body-frame
/// increment), which is what [`GyroAttitude::integrate`] computes; the DCM of eq. 4 and the
/// yaw of eq. 5 are [`heading_of`].
///
/// ```
/// use nalgebra::UnitQuaternion;
/// use wipdr_pdr::attitude::{GyroAttitude, GyroAttitudeConfig, heading_of};
/// let mut att = GyroAttitude::new(GyroAttitudeConfig { tilt_gain: 0.0, ..Default::default() });
/// att.initialise(UnitQuaternion::identity());
/// // Phone flat, turning clockwise (seen from above) at 0.5 rad/s for 1 s: body z rate -0.5.
/// for i in 1..=100 { att.integrate(i * 10, [0.0, 0.0, -0.5], None); }
/// assert!((heading_of(att.orientation().unwrap()) - 0.5).abs() < 1e-2);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct GyroAttitude {
    cfg: GyroAttitudeConfig,
    q: Option<UnitQuaternion<f64>>,
    last_t: Option<i64>,
}

impl GyroAttitude {
    /// An uninitialised attitude.
    pub fn new(cfg: GyroAttitudeConfig) -> Self {
        Self {
            cfg,
            q: None,
            last_t: None,
        }
    }

    /// Sets the orientation (start, or after a gap).
    pub fn initialise(&mut self, q: UnitQuaternion<f64>) {
        self.q = Some(q);
    }

    /// Whether an orientation is known.
    pub fn is_initialised(&self) -> bool {
        self.q.is_some()
    }

    /// The orientation, if initialised.
    pub fn orientation(&self) -> Option<&UnitQuaternion<f64>> {
        self.q.as_ref()
    }

    /// Integrates one gyro sample (rad/s) at time `t` (ms), with optional accelerometer for
    /// the tilt correction. Returns the heading change (rad, clockwise positive) of this
    /// increment, `None` when nothing was integrated (first sample, gap, repeated or
    /// backwards time, non-finite rate, not initialised). A gap un-initialises the attitude.
    pub fn integrate(&mut self, t: i64, gyro: [f64; 3], acc: Option<[f64; 3]>) -> Option<f64> {
        if !gyro.iter().all(|c| c.is_finite()) {
            return None;
        }
        let last = self.last_t;
        if last.is_some_and(|l| t <= l) {
            return None;
        }
        self.last_t = Some(t);
        let dt = (t - last?) as f64 / 1000.0;
        if dt > self.cfg.max_dt_s {
            self.q = None;
            return None;
        }
        let q = self.q?;
        let before = heading_of(&q);
        let w = Vector3::from(gyro);
        // Eq. 1-3: body-frame rotation increment.
        let mut next = q * UnitQuaternion::from_scaled_axis(w * dt);
        if let Some(a) = acc.filter(|_| self.cfg.tilt_gain > 0.0) {
            let a = Vector3::from(a);
            let an = a.norm();
            if an.is_finite() && (0.5 * 9.81..1.5 * 9.81).contains(&an) {
                // Rotate the measured "up" (in ENU) towards the true Up by a fraction.
                let up_measured = next * (a / an);
                if let Some(corr) = UnitQuaternion::rotation_between(&up_measured, &Vector3::z()) {
                    let frac = (self.cfg.tilt_gain * dt).min(1.0);
                    next = corr.powf(frac) * next;
                }
            }
        }
        self.q = Some(next);
        Some(wrap_pi(heading_of(&next) - before))
    }
}

/// Settings of the gyro + compass heading Kalman filter (paper 002 eq. 9-12).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HeadingKfConfig {
    /// Process noise of the angle, rad²/s (the angle row of `phi`, eq. 11, per second).
    pub angle_noise: f64,
    /// Process noise of the rate, (rad/s)²/s (the rate row of `phi`, per second).
    pub rate_noise: f64,
    /// Standard deviation of the compass azimuth, rad (`varphi` of eq. 12 is its square).
    pub compass_std: f64,
    /// Compass innovations beyond this many standard deviations are rejected (magnetic
    /// disturbances indoors); 0 disables the gate.
    pub gate_sigmas: f64,
}

impl Default for HeadingKfConfig {
    fn default() -> Self {
        Self {
            angle_noise: 1e-4,
            rate_noise: 1e-2,
            compass_std: 0.35,
            gate_sigmas: 3.0,
        }
    }
}

/// Heading Kalman filter (paper 002 eq. 9-12): state `S = [angle, rate]`,
/// `S_t = A S_{t-1} + B u_t` with `A = [[1, dt], [0, 1]]`, `B = [dt²/2, dt]` and the gyro's
/// angular acceleration as input `u`; observation `O = C S + r`, `C = [1, 0]`, the compass
/// azimuth. Angle innovations are wrapped to `(-pi, pi]`.
///
/// ```
/// use wipdr_pdr::attitude::{HeadingKf, HeadingKfConfig};
/// let mut kf = HeadingKf::new(HeadingKfConfig::default());
/// kf.initialise(0.0, 0.0);
/// for _ in 0..200 { kf.predict(0.02, 0.0); kf.update(1.0); }
/// assert!((kf.angle().unwrap() - 1.0).abs() < 0.05);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct HeadingKf {
    cfg: HeadingKfConfig,
    state: Option<Vector2<f64>>,
    p: Matrix2<f64>,
    rejected: usize,
}

impl HeadingKf {
    /// An uninitialised filter.
    pub fn new(cfg: HeadingKfConfig) -> Self {
        Self {
            cfg,
            state: None,
            p: Matrix2::identity(),
            rejected: 0,
        }
    }

    /// Starts the filter at `angle` (rad) and `rate` (rad/s), with a loose covariance.
    pub fn initialise(&mut self, angle: f64, rate: f64) {
        if angle.is_finite() && rate.is_finite() {
            self.state = Some(Vector2::new(wrap_pi(angle), rate));
            let s2 = self.cfg.compass_std * self.cfg.compass_std;
            self.p = Matrix2::new(s2, 0.0, 0.0, 0.1);
        }
    }

    /// Whether the filter has a state.
    pub fn is_initialised(&self) -> bool {
        self.state.is_some()
    }

    /// The heading (rad), if initialised.
    pub fn angle(&self) -> Option<f64> {
        self.state.map(|s| s[0])
    }

    /// Number of compass observations rejected by the gate.
    pub fn rejected(&self) -> usize {
        self.rejected
    }

    /// Eq. 11: prediction over `dt` seconds with angular acceleration `u` (rad/s²).
    pub fn predict(&mut self, dt: f64, u: f64) {
        let Some(s) = self.state.as_mut() else { return };
        if !(dt > 0.0 && dt.is_finite() && u.is_finite()) {
            return;
        }
        let a = Matrix2::new(1.0, dt, 0.0, 1.0);
        let b = Vector2::new(dt * dt / 2.0, dt);
        *s = a * *s + b * u;
        s[0] = wrap_pi(s[0]);
        let q = Matrix2::new(
            self.cfg.angle_noise * dt,
            0.0,
            0.0,
            self.cfg.rate_noise * dt,
        );
        self.p = a * self.p * a.transpose() + q;
        self.p = (self.p + self.p.transpose()) * 0.5;
    }

    /// Eq. 12: update with a compass azimuth (rad). Returns whether it was applied.
    pub fn update(&mut self, azimuth: f64) -> bool {
        let Some(s) = self.state.as_mut() else {
            return false;
        };
        if !azimuth.is_finite() {
            return false;
        }
        let r = self.cfg.compass_std * self.cfg.compass_std;
        let innovation = wrap_pi(azimuth - s[0]);
        let sv = self.p[(0, 0)] + r;
        if sv <= 0.0 {
            return false;
        }
        if self.cfg.gate_sigmas > 0.0 && innovation * innovation > self.cfg.gate_sigmas.powi(2) * sv
        {
            self.rejected += 1;
            return false;
        }
        let k = Vector2::new(self.p[(0, 0)], self.p[(1, 0)]) / sv;
        *s += k * innovation;
        s[0] = wrap_pi(s[0]);
        // Joseph form keeps P symmetric positive definite.
        let ikc = Matrix2::identity() - Matrix2::new(k[0], 0.0, k[1], 0.0);
        self.p = ikc * self.p * ikc.transpose() + k * k.transpose() * r;
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    #[test]
    fn identity_points_north() {
        let q = UnitQuaternion::identity();
        assert!(heading_of(&q).abs() < 1e-12);
        // Rotate the phone 90 degrees counter-clockwise about Up: its top points West.
        let q = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), FRAC_PI_2);
        assert!((heading_of(&q) + FRAC_PI_2).abs() < 1e-12);
    }

    #[test]
    fn compass_flat_phone() {
        // Flat phone pointing north: gravity reading +z, field north and down.
        let q = compass_orientation([0.0, 0.0, 9.81], [0.0, 20.0, -40.0]).unwrap();
        assert!(heading_of(&q).abs() < 1e-9);
        // Pointing east: the field comes from the phone's -x side.
        let q = compass_orientation([0.0, 0.0, 9.81], [-20.0, 0.0, -40.0]).unwrap();
        assert!((heading_of(&q) - FRAC_PI_2).abs() < 1e-9);
        assert!(compass_orientation([0.0, 0.0, 0.0], [1.0, 0.0, 0.0]).is_none());
        assert!(compass_orientation([f64::NAN, 0.0, 9.8], [1.0, 0.0, 0.0]).is_none());
    }

    #[test]
    fn rotation_vector_matches_compass_convention() {
        // A rotation vector of a yaw of -90 deg (top to East).
        let half = -FRAC_PI_2 / 2.0;
        let q = rotation_vector_quaternion([0.0, 0.0, half.sin()]).unwrap();
        assert!((heading_of(&q) - FRAC_PI_2).abs() < 1e-9);
        assert!(rotation_vector_quaternion([f64::NAN, 0.0, 0.0]).is_none());
    }

    #[test]
    fn gyro_gap_uninitialises() {
        let mut att = GyroAttitude::new(GyroAttitudeConfig::default());
        att.initialise(UnitQuaternion::identity());
        assert_eq!(att.integrate(0, [0.0; 3], None), None);
        assert!(att.integrate(20, [0.0; 3], None).is_some());
        assert_eq!(att.integrate(20, [0.0; 3], None), None);
        assert_eq!(att.integrate(10, [0.0; 3], None), None);
        assert_eq!(att.integrate(5000, [0.0; 3], None), None);
        assert!(!att.is_initialised());
    }

    #[test]
    fn tilt_correction_pulls_towards_gravity() {
        let mut att = GyroAttitude::new(GyroAttitudeConfig {
            tilt_gain: 2.0,
            max_dt_s: 0.5,
        });
        // Start 10 degrees off in roll while the phone is really flat.
        att.initialise(UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.17));
        for i in 0..500 {
            att.integrate(i * 20, [0.0; 3], Some([0.0, 0.0, 9.81]));
        }
        let up = att.orientation().unwrap() * Vector3::z();
        assert!(up.z > 0.9999, "{up:?}");
    }

    #[test]
    fn kf_wraps_and_gates() {
        let mut kf = HeadingKf::new(HeadingKfConfig::default());
        kf.initialise(3.1, 0.0);
        for _ in 0..100 {
            kf.predict(0.02, 0.0);
            kf.update(-3.1);
        }
        let a = kf.angle().unwrap();
        assert!(wrap_pi(a - (-3.1)).abs() < 0.02, "{a}");
        assert!(!kf.update(0.0)); // a 3 rad jump is gated
        assert_eq!(kf.rejected(), 1);
        assert!(!kf.update(f64::NAN));
    }
}

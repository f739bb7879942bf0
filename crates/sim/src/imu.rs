//! The phone's IMU at ~50 Hz: a phone held flat in front, screen up, top pointing forward.
//!
//! Orientation (phone to magnetic East-North-Up, as Android's rotation vector):
//! `R = Rz(-(psi + delta)) Rx(pitch) Ry(roll)`, where `psi` is the body heading (path heading
//! plus a per-walk misalignment and a yaw sway at stride frequency), `delta` the map-to-magnetic
//! offset, `pitch` the phone's tilt with a bounce at step frequency and `roll` a sway at stride
//! frequency. Then, per sample:
//!
//! - accelerometer = `R^T (a + g)`: the vertical acceleration of the step bounce
//!   `(h/2)(2 pi f)² [cos(2 pi u) + 4 c2 cos(4 pi u)]` (peak at each heel strike `u = 0`, ramped
//!   in over the first step of a bout), a forward surge, a lateral sway, the centripetal
//!   acceleration `v² kappa` in turns, plus the hand's jitter (Gauss-Markov) and white noise;
//! - gyroscope = the body rate from the orientation's time derivative, plus a per-walk bias and
//!   white noise (a right turn reads negative on `z`, as on Android);
//! - magnetometer = `R^T (B_earth + B_local(p))` plus noise, `B_local` a sum of Gaussian bumps
//!   near walls;
//! - rotation vector = the quaternion of `R` with a slowly drifting yaw error
//!   (Ornstein-Uhlenbeck), part of the compass error the local disturbances cause, and small
//!   noise.
//!
//! The vertical acceleration's amplitude is scaled by a per-walk gain (the arm) and a per-step
//! jitter, so a step-length model must be calibrated and still errs step by step.

use crate::config::ImuConfig;
use crate::floor::SimFloorPlan;
use crate::rng::Draw;
use crate::walker::{Timeline, WalkPath};
use nalgebra::{Rotation3, UnitQuaternion, Vector3};
use rand::rngs::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::f64::consts::{PI, TAU};
use wipdr_core::{
    ImuStreams, Point2, RotationVectorSample, TimestampMs, UncalibratedSample, Vec3Sample,
};

/// A local magnetic disturbance: a Gaussian bump of field around a point.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MagDisturbance {
    /// Centre, metres.
    pub centre: Point2,
    /// Field added at the centre, magnetic ENU, µT.
    pub field_ut: [f64; 3],
    /// Fall-off standard deviation, metres.
    pub radius_m: f64,
}

/// Draws disturbances at random points of random walls.
pub fn mag_disturbances(
    cfg: &ImuConfig,
    floor: &SimFloorPlan,
    rng: &mut ChaCha8Rng,
) -> Vec<MagDisturbance> {
    if floor.unique_walls.is_empty() {
        return Vec::new();
    }
    (0..cfg.mag_disturbances)
        .map(|_| {
            let w = floor.unique_walls[rng.index(floor.unique_walls.len())];
            let centre = w.a + (w.b - w.a) * rng.uniform(0.0, 1.0);
            let dir = Vector3::new(rng.normal(), rng.normal(), rng.normal());
            let dir = if dir.norm() > 1e-9 {
                dir / dir.norm()
            } else {
                Vector3::z()
            };
            let m = rng.uniform(0.3, 1.0) * cfg.mag_disturbance_ut;
            MagDisturbance {
                centre,
                field_ut: [dir.x * m, dir.y * m, dir.z * m],
                radius_m: cfg.mag_disturbance_radius_m,
            }
        })
        .collect()
}

fn local_field(dist: &[MagDisturbance], p: Point2) -> Vector3<f64> {
    dist.iter().fold(Vector3::zeros(), |acc, d| {
        let r2 = (p - d.centre).norm_squared();
        let w = (-r2 / (2.0 * d.radius_m * d.radius_m)).exp();
        acc + Vector3::from(d.field_ut) * w
    })
}

/// Per-walk phone pose and sensor errors.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PhonePose {
    /// Pitch (top raised), radians.
    pub pitch: f64,
    /// Roll, radians.
    pub roll: f64,
    /// Yaw misalignment against the walking direction, radians.
    pub yaw_misalignment: f64,
    /// Gyroscope bias, rad/s, phone axes.
    pub gyro_bias: [f64; 3],
    /// Gain between the body's bounce and the phone's vertical acceleration.
    pub bounce_gain: f64,
}

impl PhonePose {
    /// Draws a pose.
    pub fn draw(cfg: &ImuConfig, rng: &mut ChaCha8Rng) -> Self {
        Self {
            pitch: rng.uniform(cfg.pitch_deg[0], cfg.pitch_deg[1]).to_radians(),
            roll: (cfg.roll_std_deg * rng.normal()).to_radians(),
            yaw_misalignment: (cfg.yaw_misalignment_std_deg * rng.normal()).to_radians(),
            gyro_bias: [0; 3].map(|_: i32| cfg.gyro_bias_std * rng.normal()),
            bounce_gain: rng.uniform(cfg.bounce_gain[0], cfg.bounce_gain[1]),
        }
    }
}

/// Everything the IMU synthesis reads.
pub struct ImuScene<'a> {
    /// The configuration.
    pub cfg: &'a ImuConfig,
    /// The path.
    pub path: &'a WalkPath,
    /// The timeline.
    pub timeline: &'a Timeline,
    /// The phone pose.
    pub pose: PhonePose,
    /// Magnetic disturbances.
    pub disturbances: &'a [MagDisturbance],
    /// Walk start, Unix ms.
    pub start_ms: TimestampMs,
}

impl ImuScene<'_> {
    /// Body heading (map frame, unwrapped) at `t` seconds.
    pub fn body_heading(&self, t: f64) -> f64 {
        let k = self.timeline.at(t);
        let (_, psi) = self.path.at(k.s);
        let sway = if k.walking {
            self.cfg.yaw_sway_deg.to_radians()
                * (PI * (k.step_index as f64 + k.phase)).sin()
                * k.ramp
        } else {
            0.0
        };
        psi + self.pose.yaw_misalignment + sway
    }

    /// Phone-to-ENU rotation at `t` seconds, with an extra yaw error (radians).
    fn rotation(&self, t: f64, yaw_error: f64) -> Rotation3<f64> {
        let k = self.timeline.at(t);
        let yaw = -(self.body_heading(t) + self.cfg.map_to_magnetic_deg.to_radians() + yaw_error);
        let (bounce, sway) = if k.walking {
            (
                self.cfg.pitch_bounce_deg.to_radians() * (TAU * k.phase).sin() * k.ramp,
                self.cfg.yaw_sway_deg.to_radians()
                    * 0.5
                    * (PI * (k.step_index as f64 + k.phase)).cos()
                    * k.ramp,
            )
        } else {
            (0.0, 0.0)
        };
        Rotation3::from_axis_angle(&Vector3::z_axis(), yaw)
            * Rotation3::from_axis_angle(&Vector3::x_axis(), self.pose.pitch + bounce)
            * Rotation3::from_axis_angle(&Vector3::y_axis(), self.pose.roll + sway)
    }

    /// Acceleration (without gravity) in magnetic ENU at `t` seconds.
    fn linear_acceleration(&self, t: f64) -> Vector3<f64> {
        let k = self.timeline.at(t);
        if !k.walking {
            return Vector3::zeros();
        }
        let c = self.cfg;
        let w = TAU * k.step_frequency;
        let amp = 0.5 * k.bounce_m * w * w * k.ramp * self.pose.bounce_gain * k.amplitude_factor;
        let u = k.phase;
        let vertical =
            amp * ((TAU * u).cos() + 4.0 * c.vertical_second_harmonic * (2.0 * TAU * u).cos());
        let forward = -c.forward_accel_ratio * amp * (TAU * u).sin();
        let lateral = c.lateral_sway_accel * k.ramp * (PI * (k.step_index as f64 + u)).sin();
        let centripetal = k.speed * k.speed * self.path.curvature(k.s);
        let psi = self.body_heading(t) + c.map_to_magnetic_deg.to_radians();
        let fwd = Vector3::new(psi.sin(), psi.cos(), 0.0);
        let right = Vector3::new(psi.cos(), -psi.sin(), 0.0);
        fwd * forward + right * (lateral + centripetal) + Vector3::z() * vertical
    }

    /// Synthesises all IMU streams at ~`rate_hz` with timestamp jitter and dropped samples.
    pub fn synthesise(&self, rng: &mut ChaCha8Rng) -> ImuStreams {
        let c = self.cfg;
        let dt = 1.0 / c.rate_hz;
        let n = (self.timeline.duration_s / dt).floor() as usize;
        let g = Vector3::new(0.0, 0.0, c.gravity);
        let earth = Vector3::from(c.earth_field_ut);
        let rho = (-dt / c.rotation_vector_drift_time_s.max(dt)).exp();
        let drift_sigma = c.rotation_vector_drift_deg.to_radians();
        let mut yaw_error = drift_sigma * rng.normal();
        let jitter_rho = (-dt / c.hand_jitter_time_s.max(1e-3)).exp();
        let jitter_gain = c.hand_jitter_accel * (1.0 - jitter_rho * jitter_rho).sqrt();
        let mut hand = [0.0; 3];
        let gyro_est_bias: [f64; 3] = [0; 3].map(|_: i32| 0.5 * c.gyro_bias_std * rng.normal());
        let hard_iron: [f64; 3] = [0; 3].map(|_: i32| 20.0 * rng.normal());
        let mut out = ImuStreams::default();
        let h = 0.004; // finite-difference half step for the body rate, seconds
        let mut last_ms = TimestampMs::MIN;
        for i in 0..=n {
            yaw_error = rho * yaw_error + drift_sigma * (1.0 - rho * rho).sqrt() * rng.normal();
            let jitter = rng.uniform(-c.timestamp_jitter_ms, c.timestamp_jitter_ms);
            let dropped = rng.chance(c.drop_probability);
            let noise: [f64; 12] = [0; 12].map(|_: i32| rng.normal());
            for h in &mut hand {
                *h = jitter_rho * *h + jitter_gain * rng.normal();
            }
            if dropped {
                continue;
            }
            let t_nominal = i as f64 * dt;
            let t_ms = self.start_ms + (t_nominal * 1000.0 + jitter).round() as TimestampMs;
            if t_ms <= last_ms {
                continue;
            }
            last_ms = t_ms;
            let t = ((t_ms - self.start_ms) as f64 / 1000.0).clamp(0.0, self.timeline.duration_s);
            let r = self.rotation(t, 0.0);
            let rt = r.transpose();
            let f = rt * (self.linear_acceleration(t) + g);
            let acc = [0, 1, 2]
                .map(|a| quantise(f[a] + hand[a] + c.accel_noise * noise[a], c.accel_quantum));
            let inc = self.rotation(t - h, 0.0).transpose() * self.rotation(t + h, 0.0);
            let omega = rotation_vector(&inc) / (2.0 * h);
            let gyro = [0, 1, 2].map(|a| {
                quantise(
                    omega[a] + self.pose.gyro_bias[a] + c.gyro_noise * noise[3 + a],
                    c.gyro_quantum,
                )
            });
            let (p, _) = self.path.at(self.timeline.at(t).s);
            let local = local_field(self.disturbances, p);
            let b = rt * (earth + local);
            // Heading error a compass would make here: angle from the Earth's horizontal field
            // to the disturbed one (clockwise positive, like headings).
            let disturbed = earth + local;
            let mag_error = if earth.xy().norm() > 1e-9 && disturbed.xy().norm() > 1e-9 {
                wipdr_core::angle::diff(disturbed.x.atan2(disturbed.y), earth.x.atan2(earth.y))
            } else {
                0.0
            };
            let mag = [0, 1, 2].map(|a| quantise(b[a] + c.mag_noise * noise[6 + a], c.mag_quantum));
            let rv_noise = Rotation3::from_scaled_axis(
                Vector3::new(noise[9], noise[10], noise[11])
                    * c.rotation_vector_noise_deg.to_radians(),
            );
            let q = UnitQuaternion::from_rotation_matrix(
                &(self.rotation(t, yaw_error - c.rotation_vector_mag_coupling * mag_error)
                    * rv_noise),
            );
            let s = if q.w < 0.0 { -1.0 } else { 1.0 };
            let rv = [q.i, q.j, q.k].map(|v| quantise(s * v, c.rotation_vector_quantum));
            out.accelerometer.push(Vec3Sample {
                t: t_ms,
                v: acc,
                accuracy: 3,
            });
            out.gyroscope.push(Vec3Sample {
                t: t_ms,
                v: gyro,
                accuracy: 3,
            });
            out.magnetometer.push(Vec3Sample {
                t: t_ms,
                v: mag,
                accuracy: 3,
            });
            out.rotation_vector.push(RotationVectorSample {
                t: t_ms,
                v: rv,
                accuracy: 3,
            });
            if c.uncalibrated {
                out.accelerometer_uncalibrated.push(UncalibratedSample {
                    t: t_ms,
                    v: acc,
                    bias: [0.0; 3],
                    accuracy: 3,
                });
                out.gyroscope_uncalibrated.push(UncalibratedSample {
                    t: t_ms,
                    v: [0, 1, 2].map(|a| quantise(gyro[a] + gyro_est_bias[a], c.gyro_quantum)),
                    bias: gyro_est_bias.map(|v| quantise(v, c.gyro_quantum)),
                    accuracy: 3,
                });
                out.magnetometer_uncalibrated.push(UncalibratedSample {
                    t: t_ms,
                    v: [0, 1, 2].map(|a| quantise(mag[a] + hard_iron[a], c.mag_quantum)),
                    bias: hard_iron.map(|v| quantise(v, c.mag_quantum)),
                    accuracy: 3,
                });
            }
        }
        out
    }
}

/// The rotation's axis times its angle, radians: nalgebra's `Rotation3::scaled_axis` with the
/// cosine clamped to [-1, 1]. Rounding can push the trace of a near-identity rotation to
/// `3 + 4e-16`, where the unclamped `acos` gives NaN (seed 2307767014909628701 of the
/// `any_seed_gives_a_sane_walk` property test); wherever nalgebra's value is finite this one
/// is the same, bit for bit, so generated walks do not move.
fn rotation_vector(r: &Rotation3<f64>) -> Vector3<f64> {
    let m = r.matrix();
    let axis = Vector3::new(
        m[(2, 1)] - m[(1, 2)],
        m[(0, 2)] - m[(2, 0)],
        m[(1, 0)] - m[(0, 1)],
    );
    match nalgebra::Unit::try_new(axis, f64::EPSILON) {
        Some(axis) => {
            let cos = ((m[(0, 0)] + m[(1, 1)] + m[(2, 2)] - 1.0) / 2.0).clamp(-1.0, 1.0);
            axis.into_inner() * cos.acos()
        }
        None => Vector3::zeros(),
    }
}

/// Rounds `v` to a multiple of `quantum`, dividing by the integer inverse when there is one so
/// that decimal quanta print short (`0.123`, not `0.12300000000000001`).
pub(crate) fn quantise(v: f64, quantum: f64) -> f64 {
    if quantum.is_nan() || quantum <= 0.0 || !v.is_finite() {
        return v;
    }
    let inv = 1.0 / quantum;
    let r = if (inv - inv.round()).abs() < 1e-9 * inv && inv >= 1.0 {
        (v * inv.round()).round() / inv.round()
    } else {
        (v / quantum).round() * quantum
    };
    if r == 0.0 { 0.0 } else { r }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantise_prints_short() {
        assert_eq!(format!("{}", quantise(0.123456, 0.001)), "0.123");
        assert_eq!(format!("{}", quantise(-9.80665, 0.001)), "-9.807");
        assert_eq!(format!("{}", quantise(-0.0001, 0.001)), "0");
        assert_eq!(quantise(1.26, 0.5), 1.5);
    }

    #[test]
    fn a_near_identity_rotation_whose_trace_rounds_past_three_has_a_finite_rotation_vector() {
        // The increment that made nalgebra's `scaled_axis` NaN: trace 3 + 6.7e-16.
        let m = nalgebra::Matrix3::<f64>::new(
            1.0000000000000002,
            -7.331409784816501e-13,
            -8.353127009530503e-10,
            7.331392437581741e-13,
            1.0000000000000002,
            7.213396546745798e-13,
            8.353127078919442e-10,
            -7.213674102501955e-13,
            1.0000000000000002,
        );
        let r = Rotation3::from_matrix_unchecked(m);
        assert!(
            r.scaled_axis().iter().any(|v| v.is_nan()),
            "nalgebra clamps now: drop the copy"
        );
        let v = rotation_vector(&r);
        assert!(v.iter().all(|x| x.is_finite()) && v.norm() < 1e-8, "{v:?}");
    }

    proptest::proptest! {
        /// Wherever nalgebra's rotation vector is finite, ours is the same bit for bit, so the
        /// clamp moves no generated walk.
        #[test]
        fn the_rotation_vector_is_nalgebras_where_that_is_finite(
            axis in proptest::array::uniform3(-1.0f64..1.0),
            angle in -3.0f64..3.0,
        ) {
            let r = Rotation3::from_scaled_axis(Vector3::from(axis) * angle);
            let theirs = r.scaled_axis();
            proptest::prop_assume!(theirs.iter().all(|v| v.is_finite()));
            proptest::prop_assert_eq!(rotation_vector(&r), theirs);
        }
    }
}

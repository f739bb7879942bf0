//! # wipdr-pdr — pedestrian dead reckoning
//!
//! Turns a phone's IMU stream into [`StepEvent`](wipdr_core::StepEvent)s: time, length,
//! heading in the map frame, heading change, and the motion state the adaptive filters key
//! on. Streaming and causal ([`Pdr`], sample by sample), with a batch convenience
//! ([`Pdr::run`]). It implements:
//!
//! - step detection (papers 000 §2.2, 002 §4.2): [`detector`];
//! - step length, three models behind one trait (paper 000 eq. 6, paper 002 eq. 8, paper
//!   004 eq. 6-7) plus the competition sample code's stride model as a baseline: [`length`],
//!   with the vertical ZUPT filter of paper 004 Alg. 1 in [`vertical`];
//! - attitude and heading: quaternion gyro integration (paper 004 eq. 1-5), the gyro +
//!   compass Kalman filter (paper 002 eq. 9-12), the rotation vector: [`attitude`];
//! - motion state per step (paper 001 eq. 17-18, paper 000 §4.1, paper 002 §3.2.1):
//!   [`motion`];
//! - calibration from walks with waypoints (least-squares step-length coefficients, the
//!   floor's heading offset) and the leg / position scoring of PDR: [`calibrate`];
//! - learned inertial odometry (a small network over IMU windows: a displacement a second
//!   and its covariance, beside the step model): [`odometry`];
//! - heading snapping to the building's dominant directions on straight stretches (heuristic
//!   drift elimination for absolute headings; wipdr's own, off unless configured): [`snap`].
//!
//! Bad input (NaN samples, repeated or backwards timestamps, gaps, a missing gyroscope or
//! magnetometer) has documented behaviour: see [`Pdr`].
//!
//! ```
//! use wipdr_core::{Vec3Sample, RotationVectorSample};
//! use wipdr_pdr::{Pdr, PdrConfig};
//!
//! // A config is checked before the pipeline takes it (`PdrConfig::check`).
//! let mut pdr = Pdr::new(PdrConfig::default().check().unwrap());
//! let mut steps = Vec::new();
//! for i in 0..1500 {
//!     let t = i * 20; // 50 Hz, 30 s
//!     // Phone flat, pointing east (rotation vector of a -90 degree yaw), walking at 2 Hz.
//!     let half = -std::f64::consts::FRAC_PI_4;
//!     pdr.push_rotation_vector(&RotationVectorSample { t, v: [0.0, 0.0, half.sin()], accuracy: 3 });
//!     let bounce = 2.0 * (2.0 * std::f64::consts::PI * 2.0 * t as f64 / 1000.0).sin();
//!     let acc = Vec3Sample { t, v: [0.0, 0.0, 9.81 + bounce], accuracy: 3 };
//!     steps.extend(pdr.push_accelerometer(&acc));
//! }
//! assert!((58..=60).contains(&steps.len()));
//! assert!(steps.iter().all(|s| (s.heading - std::f64::consts::FRAC_PI_2).abs() < 1e-6));
//! ```

pub mod attitude;
pub mod calibrate;
pub mod detector;
pub mod error_model;
pub mod filter;
pub mod handling;
pub mod length;
pub mod motion;
pub mod odometry;
pub mod pipeline;
pub mod snap;
pub mod vertical;

pub use length::{StepFeatures, StepLengthConfig, StepLengthModel};
pub use pipeline::{
    CheckedPdrConfig, HeadingAt, HeadingConfig, HeadingSource, Pdr, PdrConfig, PdrDiagnostics,
    SourceHeadings, StepDetail,
};

//! IMU samples, as Android `SensorEvent.values`.

use crate::TimestampMs;
use serde::{Deserialize, Serialize};

/// A three-axis sample in the phone frame: accelerometer (m/s²), gyroscope (rad/s) or
/// magnetometer (µT).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Vec3Sample {
    /// Time (Unix ms).
    pub t: TimestampMs,
    /// `x, y, z` in the phone frame.
    pub v: [f64; 3],
    /// Android accuracy code (0-3); -1 when absent.
    pub accuracy: i8,
}

impl Vec3Sample {
    /// Euclidean norm of the vector.
    pub fn norm(&self) -> f64 {
        (self.v[0] * self.v[0] + self.v[1] * self.v[1] + self.v[2] * self.v[2]).sqrt()
    }
}

/// An uncalibrated sample: the raw vector and the estimated bias (Android `*_UNCALIBRATED`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct UncalibratedSample {
    /// Time (Unix ms).
    pub t: TimestampMs,
    /// Raw `x, y, z`.
    pub v: [f64; 3],
    /// Estimated bias `x, y, z`.
    pub bias: [f64; 3],
    /// Android accuracy code; -1 when absent.
    pub accuracy: i8,
}

/// Android rotation vector: `x, y, z` of a unit quaternion whose scalar part is implied
/// (`w = sqrt(max(0, 1 - x² - y² - z²))`). Rotates phone frame into East-North-Up.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RotationVectorSample {
    /// Time (Unix ms).
    pub t: TimestampMs,
    /// `x, y, z` quaternion components.
    pub v: [f64; 3],
    /// Android accuracy code; -1 when absent.
    pub accuracy: i8,
}

impl RotationVectorSample {
    /// The quaternion `(w, x, y, z)` with the implied scalar part.
    pub fn quaternion(&self) -> [f64; 4] {
        let [x, y, z] = self.v;
        let w2 = 1.0 - x * x - y * y - z * z;
        [w2.max(0.0).sqrt(), x, y, z]
    }
}

/// All IMU streams of a walk, each sorted by time.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ImuStreams {
    /// `TYPE_ACCELEROMETER`, m/s².
    pub accelerometer: Vec<Vec3Sample>,
    /// `TYPE_GYROSCOPE`, rad/s.
    pub gyroscope: Vec<Vec3Sample>,
    /// `TYPE_MAGNETIC_FIELD`, µT.
    pub magnetometer: Vec<Vec3Sample>,
    /// `TYPE_ROTATION_VECTOR`.
    pub rotation_vector: Vec<RotationVectorSample>,
    /// `TYPE_ACCELEROMETER_UNCALIBRATED`.
    pub accelerometer_uncalibrated: Vec<UncalibratedSample>,
    /// `TYPE_GYROSCOPE_UNCALIBRATED`.
    pub gyroscope_uncalibrated: Vec<UncalibratedSample>,
    /// `TYPE_MAGNETIC_FIELD_UNCALIBRATED`.
    pub magnetometer_uncalibrated: Vec<UncalibratedSample>,
}

impl ImuStreams {
    /// Sorts every stream by time (stable, so equal times keep file order).
    pub fn sort(&mut self) {
        self.accelerometer.sort_by_key(|s| s.t);
        self.gyroscope.sort_by_key(|s| s.t);
        self.magnetometer.sort_by_key(|s| s.t);
        self.rotation_vector.sort_by_key(|s| s.t);
        self.accelerometer_uncalibrated.sort_by_key(|s| s.t);
        self.gyroscope_uncalibrated.sort_by_key(|s| s.t);
        self.magnetometer_uncalibrated.sort_by_key(|s| s.t);
    }
}

/// Mean sampling rate (Hz) of a time-sorted stream of timestamps; `None` with fewer than two
/// samples or zero span.
pub fn mean_rate_hz(times: impl IntoIterator<Item = TimestampMs>) -> Option<f64> {
    let mut it = times.into_iter();
    let first = it.next()?;
    let (mut last, mut n) = (first, 1usize);
    for t in it {
        last = t;
        n += 1;
    }
    let span = (last - first) as f64 / 1000.0;
    (n >= 2 && span > 0.0).then(|| (n - 1) as f64 / span)
}

//! Raw phone samples, and the one order in which a recorded walk's samples are streamed.

use wipdr_core::{RotationVectorSample, TimestampMs, Vec3Sample, Walk, WifiScan};

pub use wipdr_core::PressureSample;

/// One raw sample of a phone's sensors, as a [`crate::Positioner`] takes them.
#[derive(Debug, Clone, PartialEq)]
pub enum Sample {
    /// Accelerometer, m/s², device frame.
    Accelerometer(Vec3Sample),
    /// Gyroscope, rad/s, device frame.
    Gyroscope(Vec3Sample),
    /// Magnetometer, µT, device frame.
    Magnetometer(Vec3Sample),
    /// Android's rotation vector (attitude), `x, y, z` of the unit quaternion.
    RotationVector(RotationVectorSample),
    /// Barometer.
    Pressure(PressureSample),
    /// One Wi-Fi scan (BSSID + RSSI per AP; other entry fields optional).
    Wifi(WifiScan),
}

impl Sample {
    /// The sample's time.
    pub fn t(&self) -> TimestampMs {
        match self {
            Sample::Accelerometer(s) | Sample::Gyroscope(s) | Sample::Magnetometer(s) => s.t,
            Sample::RotationVector(s) => s.t,
            Sample::Pressure(s) => s.t,
            Sample::Wifi(s) => s.t,
        }
    }

    /// Rank of the sample's kind at equal times (lower first): attitude (rotation vector,
    /// gyroscope, magnetometer) before the accelerometer, so a step sees the orientation of
    /// its own instant; the IMU before pressure; Wi-Fi last, so a scan sees the steps of its
    /// own millisecond (the tie rule of `wipdr_fusion::replay`).
    pub fn tie_rank(&self) -> u8 {
        match self {
            Sample::RotationVector(_) => 0,
            Sample::Gyroscope(_) => 1,
            Sample::Magnetometer(_) => 2,
            Sample::Accelerometer(_) => 3,
            Sample::Pressure(_) => 4,
            Sample::Wifi(_) => 5,
        }
    }
}

/// A recorded walk's raw samples in stream order: by time, ties by [`Sample::tie_rank`],
/// each sensor's own order kept. This is how `wipdr locate`, the evaluation and the tests
/// replay a recorded walk through a [`crate::Positioner`]; a live stream should deliver
/// samples in the same order. Waypoints (ground truth) are not samples and never streamed.
pub fn samples_of(walk: &Walk) -> impl Iterator<Item = Sample> + '_ {
    let imu = &walk.imu;
    let mut cursors = [0usize; 6];
    std::iter::from_fn(move || {
        let times = [
            imu.rotation_vector.get(cursors[0]).map(|s| s.t),
            imu.gyroscope.get(cursors[1]).map(|s| s.t),
            imu.magnetometer.get(cursors[2]).map(|s| s.t),
            imu.accelerometer.get(cursors[3]).map(|s| s.t),
            walk.pressure.get(cursors[4]).map(|s| s.t),
            walk.wifi.get(cursors[5]).map(|s| s.t),
        ];
        // The earliest; among equal times the lowest rank (array order = rank order).
        let (k, _) = times
            .iter()
            .enumerate()
            .filter_map(|(k, t)| t.map(|t| (k, t)))
            .min_by_key(|&(k, t)| (t, k))?;
        let i = cursors[k];
        cursors[k] += 1;
        Some(match k {
            0 => Sample::RotationVector(imu.rotation_vector[i]),
            1 => Sample::Gyroscope(imu.gyroscope[i]),
            2 => Sample::Magnetometer(imu.magnetometer[i]),
            3 => Sample::Accelerometer(imu.accelerometer[i]),
            4 => Sample::Pressure(walk.pressure[i]),
            _ => Sample::Wifi(walk.wifi[i].clone()),
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use wipdr_core::{Bssid, WifiEntry};

    fn v(t: TimestampMs) -> Vec3Sample {
        Vec3Sample {
            t,
            v: [0.0, 0.0, 9.8],
            accuracy: 3,
        }
    }

    #[test]
    fn stream_order_is_time_then_rank() {
        let mut walk = Walk::default();
        walk.imu.accelerometer = vec![v(0), v(10), v(20)];
        walk.imu.gyroscope = vec![v(10)];
        walk.pressure = vec![PressureSample { t: 10, hpa: 976.2 }];
        walk.wifi = vec![WifiScan {
            t: 10,
            entries: vec![WifiEntry::new(Bssid(1), -50.0)],
        }];
        let order: Vec<(TimestampMs, u8)> =
            samples_of(&walk).map(|s| (s.t(), s.tie_rank())).collect();
        assert_eq!(
            order,
            vec![(0, 3), (10, 1), (10, 3), (10, 4), (10, 5), (20, 3)]
        );
    }
}

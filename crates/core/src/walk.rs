//! Recorded walks: metadata, waypoints (ground truth) and time-sorted sensor streams.

use crate::imu::{ImuStreams, RotationVectorSample, UncalibratedSample, Vec3Sample};
use crate::{Point2, TimestampMs, WifiScan};
use serde::{Deserialize, Serialize};

/// A surveyed ground-truth position (ILC `TYPE_WAYPOINT`, IPIN `POSI`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Waypoint {
    /// Time (ms, the walk's clock).
    pub t: TimestampMs,
    /// Position in the floor frame, metres.
    pub position: Point2,
    /// Floor level (0 = ground, -1 = first basement, 1 = first upper floor), where known.
    #[serde(default)]
    pub floor: Option<i32>,
}

impl Waypoint {
    /// A waypoint of unknown floor.
    pub fn new(t: TimestampMs, position: Point2) -> Self {
        Self {
            t,
            position,
            floor: None,
        }
    }

    /// The waypoint on floor level `floor`.
    pub fn on_floor(mut self, floor: i32) -> Self {
        self.floor = Some(floor);
        self
    }
}

/// A barometer reading.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PressureSample {
    /// Time (ms, the stream's clock).
    pub t: TimestampMs,
    /// Pressure, hPa (= mbar).
    pub hpa: f64,
}

/// A Bluetooth Low Energy beacon reading (ILC `TYPE_BEACON`, IPIN `BLE4`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BeaconSample {
    /// Time (Unix ms).
    pub t: TimestampMs,
    /// iBeacon UUID.
    pub uuid: String,
    /// iBeacon major.
    pub major: String,
    /// iBeacon minor.
    pub minor: String,
    /// Calibrated transmit power, dBm (iBeacon frames).
    pub tx_power: Option<f64>,
    /// Received signal strength, dBm.
    pub rssi_dbm: f64,
    /// Distance estimated by the phone, metres (ILC only).
    pub distance: Option<f64>,
    /// MAC address as written.
    pub mac: String,
    /// The beacon's own timestamp field (ms; ILC only).
    pub seen_ms: Option<TimestampMs>,
}

/// Who, where and with what a walk was recorded (from the trace's `#` headers).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct WalkMeta {
    /// Walk id (file name without extensions).
    pub id: String,
    /// Site id, if given.
    pub site_id: Option<String>,
    /// Site name, if given.
    pub site_name: Option<String>,
    /// Floor id, if given.
    pub floor_id: Option<String>,
    /// Floor name, if given.
    pub floor_name: Option<String>,
    /// Phone brand.
    pub brand: Option<String>,
    /// Phone model.
    pub model: Option<String>,
    /// Android version string.
    pub android: Option<String>,
    /// `startTime` header (Unix ms).
    pub start_time: Option<TimestampMs>,
    /// `endTime` header (Unix ms).
    pub end_time: Option<TimestampMs>,
    /// The route walked, where walks repeat routes (IPIN `TrialNN`): the evaluation then
    /// keeps all repetitions of a route in one fold.
    #[serde(default)]
    pub route: Option<String>,
}

/// One recorded walk: every stream sorted by time.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Walk {
    /// Metadata.
    pub meta: WalkMeta,
    /// Ground-truth waypoints, sorted by time. Scoring only: never input to a scheme.
    pub waypoints: Vec<Waypoint>,
    /// Wi-Fi scans, sorted by scan time.
    pub wifi: Vec<WifiScan>,
    /// Beacon readings, sorted by time.
    pub beacons: Vec<BeaconSample>,
    /// IMU streams, each sorted by time.
    pub imu: ImuStreams,
    /// Barometer readings, sorted by time.
    #[serde(default)]
    pub pressure: Vec<PressureSample>,
}

/// One record of a walk, borrowed, for the merged replay.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Record<'a> {
    /// A ground-truth waypoint.
    Waypoint(&'a Waypoint),
    /// A Wi-Fi scan.
    Wifi(&'a WifiScan),
    /// A beacon reading.
    Beacon(&'a BeaconSample),
    /// A barometer reading.
    Pressure(&'a PressureSample),
    /// An accelerometer sample.
    Accelerometer(&'a Vec3Sample),
    /// A gyroscope sample.
    Gyroscope(&'a Vec3Sample),
    /// A magnetometer sample.
    Magnetometer(&'a Vec3Sample),
    /// A rotation-vector sample.
    RotationVector(&'a RotationVectorSample),
    /// An uncalibrated accelerometer sample.
    AccelerometerUncalibrated(&'a UncalibratedSample),
    /// An uncalibrated gyroscope sample.
    GyroscopeUncalibrated(&'a UncalibratedSample),
    /// An uncalibrated magnetometer sample.
    MagnetometerUncalibrated(&'a UncalibratedSample),
}

impl Record<'_> {
    /// The record's time (Unix ms).
    pub fn t(&self) -> TimestampMs {
        match self {
            Record::Waypoint(r) => r.t,
            Record::Wifi(r) => r.t,
            Record::Beacon(r) => r.t,
            Record::Pressure(r) => r.t,
            Record::Accelerometer(r) | Record::Gyroscope(r) | Record::Magnetometer(r) => r.t,
            Record::RotationVector(r) => r.t,
            Record::AccelerometerUncalibrated(r)
            | Record::GyroscopeUncalibrated(r)
            | Record::MagnetometerUncalibrated(r) => r.t,
        }
    }
}

impl Walk {
    /// Sorts every stream by time (stable).
    pub fn sort_streams(&mut self) {
        self.waypoints.sort_by_key(|w| w.t);
        self.wifi.sort_by_key(|s| s.t);
        self.beacons.sort_by_key(|b| b.t);
        self.pressure.sort_by_key(|p| p.t);
        self.imu.sort();
    }

    /// Earliest and latest record time over all streams, `None` for an empty walk.
    pub fn time_span(&self) -> Option<(TimestampMs, TimestampMs)> {
        let mut lo = i64::MAX;
        let mut hi = i64::MIN;
        let mut upd = |first: Option<i64>, last: Option<i64>| {
            if let (Some(a), Some(b)) = (first, last) {
                lo = lo.min(a);
                hi = hi.max(b);
            }
        };
        upd(
            self.waypoints.first().map(|r| r.t),
            self.waypoints.last().map(|r| r.t),
        );
        upd(
            self.wifi.first().map(|r| r.t),
            self.wifi.last().map(|r| r.t),
        );
        upd(
            self.beacons.first().map(|r| r.t),
            self.beacons.last().map(|r| r.t),
        );
        upd(
            self.pressure.first().map(|r| r.t),
            self.pressure.last().map(|r| r.t),
        );
        let imu = &self.imu;
        for s in [&imu.accelerometer, &imu.gyroscope, &imu.magnetometer] {
            upd(s.first().map(|r| r.t), s.last().map(|r| r.t));
        }
        upd(
            imu.rotation_vector.first().map(|r| r.t),
            imu.rotation_vector.last().map(|r| r.t),
        );
        for s in [
            &imu.accelerometer_uncalibrated,
            &imu.gyroscope_uncalibrated,
            &imu.magnetometer_uncalibrated,
        ] {
            upd(s.first().map(|r| r.t), s.last().map(|r| r.t));
        }
        (lo <= hi).then_some((lo, hi))
    }

    /// Duration in seconds (0 for an empty walk).
    pub fn duration_s(&self) -> f64 {
        self.time_span()
            .map(|(a, b)| (b - a) as f64 / 1000.0)
            .unwrap_or(0.0)
    }

    /// The ground-truth position at time `t`, linearly interpolated between the waypoints
    /// around it; `None` outside the waypoints' time span or with no waypoints.
    pub fn position_at(&self, t: TimestampMs) -> Option<Point2> {
        interpolate_waypoints(&self.waypoints, t)
    }

    /// The ground-truth floor at time `t`: the floor of the latest waypoint at or before `t`
    /// (a floor changes on the stairs between two waypoints; the earlier one's floor holds
    /// until the later is reached). `None` outside the waypoints' span or when unknown.
    pub fn floor_at(&self, t: TimestampMs) -> Option<i32> {
        floor_of_waypoints(&self.waypoints, t)
    }

    /// All records of all streams merged into one time-ordered sequence. Records with equal
    /// times come in a fixed stream order (IMU first, then Wi-Fi, pressure, beacons, waypoints), so a
    /// replay is deterministic. Assumes sorted streams ([`Walk::sort_streams`]).
    pub fn replay(&self) -> Vec<Record<'_>> {
        let imu = &self.imu;
        let mut out: Vec<Record<'_>> = Vec::with_capacity(
            imu.accelerometer.len() * 7 + self.wifi.len() + self.waypoints.len(),
        );
        out.extend(imu.accelerometer.iter().map(Record::Accelerometer));
        out.extend(imu.gyroscope.iter().map(Record::Gyroscope));
        out.extend(imu.magnetometer.iter().map(Record::Magnetometer));
        out.extend(imu.rotation_vector.iter().map(Record::RotationVector));
        out.extend(
            imu.accelerometer_uncalibrated
                .iter()
                .map(Record::AccelerometerUncalibrated),
        );
        out.extend(
            imu.gyroscope_uncalibrated
                .iter()
                .map(Record::GyroscopeUncalibrated),
        );
        out.extend(
            imu.magnetometer_uncalibrated
                .iter()
                .map(Record::MagnetometerUncalibrated),
        );
        out.extend(self.wifi.iter().map(Record::Wifi));
        out.extend(self.pressure.iter().map(Record::Pressure));
        out.extend(self.beacons.iter().map(Record::Beacon));
        out.extend(self.waypoints.iter().map(Record::Waypoint));
        // Stable sort keeps the stream order above for equal times.
        out.sort_by_key(|r| r.t());
        out
    }
}

/// Linear interpolation of a time-sorted waypoint list at `t`; `None` outside its span.
pub fn interpolate_waypoints(waypoints: &[Waypoint], t: TimestampMs) -> Option<Point2> {
    let first = waypoints.first()?;
    let last = waypoints.last()?;
    if t < first.t || t > last.t {
        return None;
    }
    let i = waypoints.partition_point(|w| w.t <= t);
    if i == 0 {
        return Some(first.position);
    }
    let a = &waypoints[i - 1];
    if i == waypoints.len() || a.t == t {
        return Some(a.position);
    }
    let b = &waypoints[i];
    let span = (b.t - a.t) as f64;
    if span <= 0.0 {
        return Some(a.position);
    }
    let f = (t - a.t) as f64 / span;
    Some(a.position + (b.position - a.position) * f)
}

/// The floor of the latest waypoint at or before `t` in a time-sorted list; `None` outside its
/// span or when that waypoint's floor is unknown.
pub fn floor_of_waypoints(waypoints: &[Waypoint], t: TimestampMs) -> Option<i32> {
    let last = waypoints.last()?;
    if t > last.t {
        return None;
    }
    let i = waypoints.partition_point(|w| w.t <= t);
    waypoints.get(i.checked_sub(1)?)?.floor
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wp(t: i64, x: f64, y: f64) -> Waypoint {
        Waypoint::new(t, Point2::new(x, y))
    }

    #[test]
    fn interpolation() {
        let w = [
            wp(0, 0.0, 0.0),
            wp(1000, 10.0, 0.0),
            wp(1000, 10.0, 0.0),
            wp(3000, 10.0, 20.0),
        ];
        assert_eq!(interpolate_waypoints(&w, -1), None);
        assert_eq!(interpolate_waypoints(&w, 500), Some(Point2::new(5.0, 0.0)));
        assert_eq!(
            interpolate_waypoints(&w, 2000),
            Some(Point2::new(10.0, 10.0))
        );
        assert_eq!(
            interpolate_waypoints(&w, 3000),
            Some(Point2::new(10.0, 20.0))
        );
        assert_eq!(interpolate_waypoints(&w, 3001), None);
        assert_eq!(interpolate_waypoints(&[], 0), None);
    }

    #[test]
    fn replay_is_time_ordered() {
        let mut walk = Walk {
            waypoints: vec![wp(5, 0.0, 0.0), wp(1, 1.0, 1.0)],
            wifi: vec![WifiScan {
                t: 3,
                entries: vec![],
            }],
            ..Walk::default()
        };
        walk.imu.accelerometer = vec![Vec3Sample {
            t: 3,
            v: [0.0; 3],
            accuracy: 3,
        }];
        walk.sort_streams();
        let r = walk.replay();
        let ts: Vec<i64> = r.iter().map(|r| r.t()).collect();
        assert_eq!(ts, vec![1, 3, 3, 5]);
        assert!(matches!(r[1], Record::Accelerometer(_)));
        assert_eq!(walk.time_span(), Some((1, 5)));
    }
}

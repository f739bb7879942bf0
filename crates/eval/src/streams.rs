//! Which input streams a walk has, and which a scheme needs: a walk without a stream a scheme
//! runs on is not scored for that scheme (its figures would look plausible and mean nothing:
//! PDR without an accelerometer stands still) but counted as a skipped run
//! ([`crate::report::SkippedRun`]).

use serde::{Deserialize, Serialize};
use wipdr_core::Walk;
use wipdr_fusion::SchemeConfig;

/// The accelerometer rate below which a walk has no usable step stream, Hz. Steps come at
/// about 2 Hz and the detector's filter is designed for 50 Hz (`PdrConfig`'s
/// `design_rate_hz`); below 10 Hz a step's peak is not sampled at all. Phones log 50-200
/// Hz; every walk of the ILC and IPIN data is far above it (`wipdr eval` reports no such
/// skip on them).
pub const MIN_ACCELEROMETER_HZ: f64 = 10.0;

/// An input stream a walk lacks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MissingStream {
    /// No accelerometer samples, or fewer than [`MIN_ACCELEROMETER_HZ`] over the walk (all
    /// of them rejected as out of range, say): no steps.
    Accelerometer,
    /// No Wi-Fi scan: no fix.
    WifiScans,
}

impl MissingStream {
    /// What the skip says in tables: "no accelerometer stream".
    pub fn label(self) -> &'static str {
        match self {
            Self::Accelerometer => "no accelerometer stream (under 10 Hz)",
            Self::WifiScans => "no Wi-Fi scan",
        }
    }
}

/// The streams `walk` lacks, in a fixed order.
///
/// ```
/// use wipdr_eval::streams::{missing_streams, MissingStream};
/// let walk = wipdr_core::Walk::default();
/// assert_eq!(missing_streams(&walk), vec![MissingStream::Accelerometer, MissingStream::WifiScans]);
/// ```
pub fn missing_streams(walk: &Walk) -> Vec<MissingStream> {
    let mut missing = Vec::new();
    let samples = walk.imu.accelerometer.len() as f64;
    // A walk of one instant needs one sample; otherwise the mean rate over the whole walk.
    let needed = (walk.duration_s() * MIN_ACCELEROMETER_HZ).max(1.0);
    if samples < needed {
        missing.push(MissingStream::Accelerometer);
    }
    if walk.wifi.is_empty() {
        missing.push(MissingStream::WifiScans);
    }
    missing
}

/// The streams scheme `scheme` runs on: the motion model's (`pdr` and every fusion scheme)
/// and Wi-Fi's (`wifi` and every fusion scheme).
pub fn needed_streams(scheme: &SchemeConfig) -> &'static [MissingStream] {
    match scheme {
        SchemeConfig::Wifi(_) => &[MissingStream::WifiScans],
        SchemeConfig::Pdr(_) => &[MissingStream::Accelerometer],
        _ => &[MissingStream::Accelerometer, MissingStream::WifiScans],
    }
}

/// The first stream `scheme` needs that the walk lacks (`missing`, from
/// [`missing_streams`]), `None` when the walk can be run.
pub fn blocking_stream(scheme: &SchemeConfig, missing: &[MissingStream]) -> Option<MissingStream> {
    needed_streams(scheme)
        .iter()
        .copied()
        .find(|s| missing.contains(s))
}

#[cfg(test)]
mod tests {
    use super::*;
    use wipdr_core::{Vec3Sample, WifiScan};

    fn walk_with(accelerometer_hz: f64, seconds: i64, scans: usize) -> Walk {
        let mut walk = Walk::default();
        let n = (accelerometer_hz * seconds as f64) as i64;
        walk.imu.accelerometer = (0..n)
            .map(|i| Vec3Sample {
                t: i * 1000 * seconds / n.max(1),
                v: [0.0, 0.0, 9.8],
                accuracy: -1,
            })
            .collect();
        walk.wifi = (0..scans)
            .map(|i| WifiScan {
                t: i as i64 * 1000,
                entries: Vec::new(),
            })
            .collect();
        // The walk's span: a last gyroscope sample at the end.
        walk.imu.gyroscope.push(Vec3Sample {
            t: seconds * 1000,
            v: [0.0; 3],
            accuracy: -1,
        });
        walk
    }

    #[test]
    fn a_phone_rate_stream_is_present() {
        assert!(missing_streams(&walk_with(50.0, 60, 10)).is_empty());
    }

    #[test]
    fn a_stream_whose_samples_were_all_rejected_is_missing() {
        let walk = walk_with(0.0, 60, 10);
        assert_eq!(missing_streams(&walk), vec![MissingStream::Accelerometer]);
        let ekf = SchemeConfig::default_for("ekf").unwrap();
        let wifi = SchemeConfig::default_for("wifi").unwrap();
        let pdr = SchemeConfig::default_for("pdr").unwrap();
        let missing = missing_streams(&walk);
        assert_eq!(
            blocking_stream(&ekf, &missing),
            Some(MissingStream::Accelerometer)
        );
        assert_eq!(
            blocking_stream(&pdr, &missing),
            Some(MissingStream::Accelerometer)
        );
        assert_eq!(blocking_stream(&wifi, &missing), None);
    }

    #[test]
    fn a_few_surviving_samples_are_not_a_stream() {
        // 5 Hz over a minute: a step's peak is not sampled.
        let walk = walk_with(5.0, 60, 10);
        assert_eq!(missing_streams(&walk), vec![MissingStream::Accelerometer]);
    }

    #[test]
    fn without_scans_only_pdr_runs() {
        let missing = missing_streams(&walk_with(50.0, 60, 0));
        assert_eq!(missing, vec![MissingStream::WifiScans]);
        for name in wipdr_fusion::scheme_names() {
            let scheme = SchemeConfig::default_for(name).unwrap();
            assert_eq!(
                blocking_stream(&scheme, &missing).is_none(),
                *name == "pdr",
                "{name}"
            );
        }
    }
}

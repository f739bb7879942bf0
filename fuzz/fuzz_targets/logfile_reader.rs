//! Fuzz target: the IPIN logfile reader on arbitrary bytes (plain or gzip, detected by
//! magic). It must never panic, and must stay within its limits; small limits keep runs fast.
#![no_main]

use libfuzzer_sys::fuzz_target;
use wipdr_io::{Limits, logfile::read_logfile_from};

fuzz_target!(|data: &[u8]| {
    let limits = Limits {
        max_line_bytes: 4096,
        max_input_bytes: 1 << 20,
        max_records: 100_000,
        max_scan_entries: 256,
        ..Limits::default()
    };
    if let Ok(log) = read_logfile_from(data, "IPIN_Trial01_repetition01", &limits) {
        let w = &log.walk;
        assert!(w.wifi.iter().all(|s| s.entries.len() <= 256));
        let records = w.imu.accelerometer.len()
            + w.imu.gyroscope.len()
            + w.imu.magnetometer.len()
            + w.imu.rotation_vector.len()
            + w.pressure.len()
            + w.beacons.len()
            + log.ground_truth.len()
            + w.wifi.iter().map(|s| s.entries.len()).sum::<usize>();
        assert!(records <= 100_000);
        assert!(
            log.ground_truth
                .iter()
                .all(|g| g.lat_deg.is_finite() && g.lon_deg.is_finite())
        );
        // The ground truth becomes finite waypoints in a local frame.
        let frame = wipdr_core::GeoFrame::new(49.4613, 11.1109).expect("a valid origin");
        let walk = log.into_walk(&frame).walk;
        assert!(
            walk.waypoints
                .iter()
                .all(|p| p.position.x.is_finite() && p.position.y.is_finite())
        );
    }
});

//! Fuzz target: the ILC trace reader on arbitrary bytes (plain or gzip, detected by magic).
//! It must never panic, and must stay within its limits; small limits keep runs fast.
#![no_main]

use libfuzzer_sys::fuzz_target;
use wipdr_io::{Limits, trace::read_walk_from};

fuzz_target!(|data: &[u8]| {
    let limits = Limits {
        max_line_bytes: 4096,
        max_input_bytes: 1 << 20,
        max_records: 100_000,
        max_scan_entries: 256,
        ..Limits::default()
    };
    if let Ok(parsed) = read_walk_from(data, "fuzz", &limits) {
        let w = &parsed.walk;
        assert!(w.waypoints.windows(2).all(|p| p[0].t <= p[1].t));
        assert!(w.wifi.iter().all(|s| s.entries.len() <= 256));
        assert!(parsed.report.records_kept() <= 100_000);
        // What was read writes back and reads again to the same walk.
        let mut out = Vec::new();
        wipdr_io::trace::write_walk(w, &mut out).expect("kept values are finite");
        let again = read_walk_from(&out[..], "fuzz", &Limits::default()).expect("own output reads");
        assert_eq!(again.walk.waypoints, w.waypoints);
        assert_eq!(again.walk.imu, w.imu);
    }
});

//! Byte-mutation property tests of the trace, IPIN logfile, GeoJSON, fingerprint CSV and cache
//! readers:
//! any flipped, overwritten, inserted or cut bytes give `Ok` or a typed error, never a panic
//! (the stable-toolchain stand-in for `cargo fuzz`, see `fuzz/README.md`).
//!
//! More cases: `PROPTEST_CASES=5000 cargo test -p wipdr-io --test mutation --release`.

use proptest::prelude::*;
use std::path::Path;
use wipdr_core::{FloorPlan, Point2, Walk, Waypoint};
use wipdr_io::cache::{self, CacheOutcome, CacheSettings};
use wipdr_io::{Limits, LonLatBox, ReadOptions, floor, logfile, trace};

/// Cases per property: `PROPTEST_CASES`, else `default`.
fn cases(default: u32) -> u32 {
    std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// A mutation: at a relative position, flip bits, set a byte, insert or cut.
#[derive(Debug, Clone)]
enum Edit {
    Xor(f64, u8),
    Set(f64, u8),
    Insert(f64, Vec<u8>),
    Cut(f64, usize),
    Truncate(f64),
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        (0.0..1.0f64, 1..=255u8).prop_map(|(p, b)| Edit::Xor(p, b)),
        (0.0..1.0f64, any::<u8>()).prop_map(|(p, b)| Edit::Set(p, b)),
        (0.0..1.0f64, proptest::collection::vec(any::<u8>(), 1..16))
            .prop_map(|(p, v)| Edit::Insert(p, v)),
        (0.0..1.0f64, 1..64usize).prop_map(|(p, n)| Edit::Cut(p, n)),
        (0.0..1.0f64).prop_map(Edit::Truncate),
    ]
}

fn apply(bytes: &[u8], edits: &[Edit]) -> Vec<u8> {
    let mut b = bytes.to_vec();
    for e in edits {
        let at = |p: f64, len: usize| ((p * len as f64) as usize).min(len.saturating_sub(1));
        match e {
            Edit::Xor(p, x) if !b.is_empty() => {
                let i = at(*p, b.len());
                b[i] ^= x;
            }
            Edit::Set(p, x) if !b.is_empty() => {
                let i = at(*p, b.len());
                b[i] = *x;
            }
            Edit::Insert(p, v) => {
                let i = at(*p, b.len() + 1);
                b.splice(i..i, v.iter().copied());
            }
            Edit::Cut(p, n) if !b.is_empty() => {
                let i = at(*p, b.len());
                let j = (i + n).min(b.len());
                b.drain(i..j);
            }
            Edit::Truncate(p) => {
                let n = at(*p, b.len() + 1);
                b.truncate(n);
            }
            _ => {}
        }
    }
    b
}

fn sample_walk() -> Walk {
    let text = "#\tstartTime:100\tBrand:B\n\
100\tTYPE_ACCELEROMETER\t1.5\t-2.0\t9.81\t3\n\
101\tTYPE_GYROSCOPE\t0.1\t0.2\t0.3\n\
102\tTYPE_MAGNETIC_FIELD\t30\t-5\t-40\t2\n\
103\tTYPE_ROTATION_VECTOR\t0.06\t0.07\t0.57\t3\n\
104\tTYPE_ACCELEROMETER_UNCALIBRATED\t1\t2\t3\t0.1\t0.2\t0.3\t3\n\
107\tTYPE_WIFI\tnet\ta8:0c:ca:03:9d:d7\t-49\t2422\t90\n\
108\tTYPE_BEACON\tU\t0\t0\t-56\t-93\t45.03\tE0:78:A3:3D:B5:D6\t108\n\
109\tTYPE_WAYPOINT\t1\t2\n\
2109\tTYPE_WAYPOINT\t3\t2\n";
    trace::read_walk_from(text.as_bytes(), "w", &Limits::default())
        .unwrap()
        .walk
}

fn small_limits() -> Limits {
    Limits {
        max_line_bytes: 4096,
        max_input_bytes: 1 << 20,
        max_records: 10_000,
        max_walk_memory_bytes: 8 << 20,
        max_json_values: 100_000,
        max_csv_line_bytes: 4096,
        max_csv_bytes: 1 << 20,
        max_csv_cells: 100_000,
        ..Limits::default()
    }
}

fn trace_inputs() -> (Vec<u8>, Vec<u8>) {
    let mut plain = Vec::new();
    trace::write_walk(&sample_walk(), &mut plain).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let gz = tmp.path().join("w.txt.gz");
    trace::write_walk_file(&sample_walk(), &gz).unwrap();
    (plain, std::fs::read(gz).unwrap())
}

/// An IPIN logfile with every record type the reader reads (and one it ignores), plain
/// and gzip.
fn logfile_inputs() -> (Vec<u8>, Vec<u8>) {
    let text = "% LogFile created by the GetSensorData App for Android.\n\
% Date of creation: Wed Jun 14 10:00:58 GMT+02:00 2023\n\
% Model: \tSM-A520F\n\
ACCE;0.05;100.00;0.1;0.2;9.8;3\n\
ACCE;0.07;100.02;0.1;0.2;9.8;3\n\
GYRO;0.06;100.01;0.01;0.02;0.03;3\n\
MAGN;0.06;100.01;30.0;-5.0;-40.0;3\n\
AHRS;0.08;100.03;1.0;2.0;90.0;0.01;0.02;0.7;3\n\
PRES;0.09;100.04;1013.2;3\n\
WIFI;0.65;100.6;net;20:23:00:00:00:01;2437;-60\n\
WIFI;0.65;100.6;net;20:23:00:00:00:15;2452;-63\n\
BLE4;0.70;iBeacon;E0:78:A3:3D:B5:D6;-80;-59;1;2;FDA50693A4E24FB1AFCFC6EB07647825\n\
POSI;61.4235;1;49.4613;11.1109;0;100\n\
POSI;70.0;2;49.4614;11.1110;-1;100\n\
GNSS;0.96;1.0;49.46;11.11;346;79;9;0.1;22;19\n";
    let mut gz = Vec::new();
    {
        use std::io::Write;
        let mut enc = flate2::write::GzEncoder::new(&mut gz, flate2::Compression::default());
        enc.write_all(text.as_bytes()).unwrap();
        enc.finish().unwrap();
    }
    (text.as_bytes().to_vec(), gz)
}

fn write_floor(dir: &Path) {
    let plan = FloorPlan::rectangle(20.0, 10.0).unwrap();
    let mut w2 = Walk::default();
    w2.meta.id = "v".into();
    w2.waypoints.push(Waypoint::new(5, Point2::new(4.0, 4.0)));
    let mut w = sample_walk();
    w.meta.id = "w".into();
    floor::write_floor_dir(
        dir,
        &plan,
        LonLatBox::around(8.0, 47.0, 20.0, 10.0),
        [&w, &w2],
    )
    .unwrap();
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(cases(256)))]

    #[test]
    fn mutated_traces_read_or_fail_typed(edits in proptest::collection::vec(edit(), 1..6), gz in any::<bool>()) {
        let (plain, gzip) = trace_inputs();
        let bytes = apply(if gz { &gzip } else { &plain }, &edits);
        // Ok (possibly with skips) or a typed error; a panic fails the test.
        match trace::read_walk_from(&bytes[..], "w", &small_limits()) {
            Ok(p) => prop_assert!(p.walk.waypoints.iter().all(|w| w.position.x.is_finite())),
            Err(e) => prop_assert!(!e.full_message().is_empty()),
        }
    }

    #[test]
    fn mutated_logfiles_read_or_fail_typed(edits in proptest::collection::vec(edit(), 1..6), gz in any::<bool>()) {
        let (plain, gzip) = logfile_inputs();
        let bytes = apply(if gz { &gzip } else { &plain }, &edits);
        let limits = small_limits();
        // Ok (possibly with skips) or a typed error; a panic fails the test. What is read
        // stays within the limits: memory bounded whatever the bytes say.
        match logfile::read_logfile_from(&bytes[..], "IPIN_Trial01_repetition01", &limits) {
            Ok(log) => {
                let w = &log.walk;
                let records = w.imu.accelerometer.len() + w.imu.gyroscope.len()
                    + w.imu.magnetometer.len() + w.imu.rotation_vector.len()
                    + w.pressure.len() + w.beacons.len() + log.ground_truth.len()
                    + w.wifi.iter().map(|s| s.entries.len()).sum::<usize>();
                prop_assert!(records <= limits.max_records, "{records} records");
                prop_assert!(w.wifi.iter().all(|s| s.entries.len() <= limits.max_scan_entries));
                prop_assert!(log.ground_truth.iter().all(|g| g.lat_deg.is_finite() && g.lon_deg.is_finite()));
                let frame = wipdr_core::GeoFrame::new(49.4613, 11.1109).unwrap();
                let walk = log.into_walk(&frame).walk;
                prop_assert!(walk.waypoints.iter().all(|p| p.position.x.is_finite() && p.position.y.is_finite()));
            }
            Err(e) => prop_assert!(!e.full_message().is_empty()),
        }
    }

    #[test]
    fn mutated_geojson_reads_or_fails_typed(edits in proptest::collection::vec(edit(), 1..6)) {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("g.json");
        let plan = FloorPlan::rectangle(20.0, 10.0).unwrap();
        wipdr_io::geojson::write_floor_plan(&path, &plan, LonLatBox::around(8.0, 47.0, 20.0, 10.0)).unwrap();
        let bytes = apply(&std::fs::read(&path).unwrap(), &edits);
        std::fs::write(&path, &bytes).unwrap();
        if let Ok(p) = wipdr_io::geojson::read_floor_plan(&path, 20.0, 10.0, &small_limits()) {
            prop_assert!(!p.plan.outline.is_empty());
        }
    }

    #[test]
    fn mutated_fingerprint_csv_reads_or_fails_typed(edits in proptest::collection::vec(edit(), 1..6)) {
        let text = "ap_000,ap_001,x,y,z,floor,building\n-60,100,1.5,2.0,0,0,0\n-70,-80,3,4,0,1,0\n";
        let bytes = apply(text.as_bytes(), &edits);
        if let Ok(t) = wipdr_io::fingerprint_csv::read_fingerprint_csv_from_with(&bytes[..], "t.csv", &small_limits()) {
            prop_assert_eq!(t.rss.len(), t.n_rows() * t.n_aps());
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(cases(64)))]

    #[test]
    fn mutated_cache_files_are_rebuilt(edits in proptest::collection::vec(edit(), 1..4)) {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("site").join("F1");
        write_floor(&dir);
        let settings = CacheSettings::in_dir(tmp.path().join("cache"));
        let opts = ReadOptions::default();
        let (good, o) = cache::read_floor(&dir, &settings, &opts, &|| {}).unwrap();
        prop_assert_eq!(o, CacheOutcome::Miss);
        let file = cache::cache_file(&dir, &settings.dir);
        let bytes = std::fs::read(&file).unwrap();
        let bad = apply(&bytes, &edits);
        std::fs::write(&file, &bad).unwrap();
        let (f, o) = cache::read_floor(&dir, &settings, &opts, &|| {}).unwrap();
        prop_assert_eq!(&f, &good);
        if bad == bytes {
            prop_assert_eq!(o, CacheOutcome::Hit);
        } else {
            prop_assert_eq!(o, CacheOutcome::Rebuilt);
        }
        prop_assert_eq!(std::fs::read(&file).unwrap(), bytes);
    }
}

//! Unit tests of `trace.rs`, kept in their own file.

use super::*;

fn read(text: &str) -> ParsedWalk {
    read_walk_from(text.as_bytes(), "t", &Limits::default()).unwrap()
}

const SAMPLE: &str = "#\tstartTime:1574559495255\n\
#\tSiteID:s1\tSiteName:Mall\tFloorId:f1\tFloorName:F1\n\
#\tBrand:OPPO\tModel:PBCM10\tAndroidName:8.1.0\tAPILevel:27\t\n\
1574559495260\tTYPE_DIST1\t19.39\t8.24\t-5.57\n\
1574559495401\tTYPE_ACCELEROMETER\t-0.85562134\t1.8243561\t9.826508\t2\n\
1574559495401\tTYPE_GYROSCOPE\t-0.39\t-0.079\t0.092\t3\n\
1574559497191\tTYPE_WIFI\tFMI\ta8:0c:ca:03:9d:d7\t-49\t2422\t1574559495450\n\
1574559497191\tTYPE_WIFI\tIPC\t74:ee:2a:cd:eb:43\t-53\t2427\t1574559490742\n\
1574559497191\tTYPE_WIFI\tFMI\ta8:0c:ca:03:9d:d7\t-60\t2422\t1574559496000\n\
1574559495300\tTYPE_ACCELEROMETER\t-0.6\t1.8\t9.9\t2\n\
1574559496436\tTYPE_BEACON\tU\t0\t0\t-56\t-93\t45.03\tE0:78:A3:3D:B5:D6\t1574559496436\n\
1574559495401\tTYPE_GYROSCOPE_UNCALIBRATED\t-0.35\t0.0017\t0.057\t-0.0015\t-6.2561035E-4\t-1.373291E-4\t3\n\
1574559525978\tTYPE_WAYPOINT\t75.371765\t94.800575\n\
1574559495263\tTYPE_WAYPOINT\t81.317215\t93.31349\n\
#\tendTime:1574559526762\n";

#[test]
fn parses_sample() {
    let p = read(SAMPLE);
    let w = &p.walk;
    assert_eq!(w.meta.start_time, Some(1574559495255));
    assert_eq!(w.meta.end_time, Some(1574559526762));
    assert_eq!(w.meta.brand.as_deref(), Some("OPPO"));
    assert_eq!(w.meta.floor_name.as_deref(), Some("F1"));
    assert_eq!(w.meta.android.as_deref(), Some("8.1.0"));
    assert_eq!(w.waypoints.len(), 2);
    assert_eq!(w.waypoints[0].t, 1574559495263);
    assert_eq!(w.imu.accelerometer.len(), 2);
    assert_eq!(w.imu.accelerometer[0].t, 1574559495300);
    assert_eq!(w.imu.accelerometer[1].accuracy, 2);
    assert_eq!(w.imu.gyroscope_uncalibrated[0].bias[1], -6.2561035E-4);
    assert_eq!(w.wifi.len(), 1);
    let scan = &w.wifi[0];
    assert_eq!(scan.entries.len(), 2);
    let fmi = scan.entries.iter().find(|e| e.ssid == "FMI").unwrap();
    assert_eq!(fmi.rssi_dbm, -60.0, "the most recent duplicate is kept");
    assert_eq!(w.beacons.len(), 1);
    let r = &p.report;
    assert_eq!(r.lines, 15);
    assert_eq!(r.header_lines, 4);
    assert_eq!(r.duplicate_bssids_removed, 1);
    assert_eq!(r.skipped_of(SkipKind::UnknownType), 1);
    assert_eq!(r.skipped[&SkipKind::UnknownType].first_lines, vec![4]);
    assert_eq!(r.unknown_types["TYPE_DIST1"], 1);
    assert_eq!(r.records["TYPE_WIFI"], 3);
    assert_eq!(r.records["TYPE_ACCELEROMETER"], 2);
    assert_eq!(
        r.out_of_order, 4,
        "accelerometer, beacon, gyroscope and waypoint written late"
    );
    assert_eq!(r.max_lateness_ms, 1574559525978 - 1574559495263);
    assert_eq!(r.run_on_lines_split, 0);
}

#[test]
fn splits_run_on_lines() {
    // Newline replaced by nothing, and newline replaced by a tab.
    let text = "1000\tTYPE_ACCELEROMETER\t1.0\t2.0\t3.0\t31574559495421\tTYPE_GYROSCOPE\t0.1\t0.2\t0.3\t3\n\
1574559495422\tTYPE_WAYPOINT\t1.0\t2.0\t1574559495423\tTYPE_WAYPOINT\t3.0\t4.0\n\
1574559495424\tTYPE_WIFI\tnet\ta8:0c:ca:03:9d:d7\t-49\t2422\t15745594954501574559495425\tTYPE_WAYPOINT\t5.0\t6.0\n";
    let p = read(text);
    assert_eq!(p.report.run_on_lines_split, 3);
    assert_eq!(p.report.run_on_first_lines, vec![1, 2, 3]);
    assert_eq!(p.walk.imu.accelerometer.len(), 1);
    assert_eq!(p.walk.imu.accelerometer[0].accuracy, 3);
    assert_eq!(p.walk.imu.gyroscope[0].t, 1574559495421);
    assert_eq!(p.walk.waypoints.len(), 3);
    assert_eq!(p.walk.wifi[0].entries[0].last_seen_ms, 1574559495450);
    assert_eq!(p.report.records_skipped(), 0);
}

#[test]
fn counts_malformed_records() {
    let text = "\n\
1000\tTYPE_ACCELEROMETER\t1.0\t2.0\n\
1000\tTYPE_ACCELEROMETER\t1.0\t2.0\t3.0\t3\t9\n\
abc\tTYPE_WAYPOINT\t1.0\t2.0\n\
-9223372036854775808\tTYPE_WAYPOINT\t1.0\t2.0\n\
1000\tTYPE_WAYPOINT\tNaN\t2.0\n\
1000\tTYPE_WIFI\tx\tnot-a-mac\t-49\t2422\t1000\n\
#\tstartTime:soon\n\
1000\n";
    let p = read(text);
    let r = &p.report;
    assert_eq!(r.skipped_of(SkipKind::Blank), 1);
    assert_eq!(r.skipped_of(SkipKind::MissingFields), 2);
    assert_eq!(r.skipped_of(SkipKind::ExtraFields), 1);
    assert_eq!(r.skipped_of(SkipKind::BadTime), 2);
    assert_eq!(r.skipped_of(SkipKind::BadNumber), 1);
    assert_eq!(r.skipped_of(SkipKind::BadBssid), 1);
    assert_eq!(r.skipped_of(SkipKind::BadHeader), 1);
    assert_eq!(r.skipped[&SkipKind::MissingFields].first_lines, vec![2, 9]);
    assert_eq!(r.records_kept(), 0);
}

#[test]
fn limits_are_typed_errors() {
    let limits = Limits {
        max_line_bytes: 100,
        max_scan_entries: 2,
        max_records: 5,
        max_input_bytes: 1000,
        ..Limits::default()
    };
    let long = format!("1\tTYPE_WAYPOINT\t{}\t1\n", "1".repeat(200));
    let e = read_walk_from(long.as_bytes(), "x", &limits).unwrap_err();
    assert!(
        matches!(
            e,
            IoError::LineTooLong {
                line: 1,
                limit: 100,
                ..
            }
        ),
        "{e}"
    );
    let scan = "5\tTYPE_WIFI\ta\t00:00:00:00:00:01\t-1\t1\t1\n".repeat(3);
    let e = read_walk_from(scan.as_bytes(), "x", &limits).unwrap_err();
    assert!(
        matches!(e, IoError::ScanTooLarge { line: 3, t: 5, .. }),
        "{e}"
    );
    let many = "5\tTYPE_WAYPOINT\t1\t1\n".repeat(6);
    let e = read_walk_from(many.as_bytes(), "x", &limits).unwrap_err();
    assert!(matches!(e, IoError::TooManyRecords { line: 6, .. }), "{e}");
    let blanks = "\n".repeat(2000);
    let e = read_walk_from(blanks.as_bytes(), "x", &limits).unwrap_err();
    assert!(matches!(e, IoError::InputTooLarge { .. }), "{e}");
    assert!(e.to_string().starts_with("x: "), "{e}");
}

#[test]
fn writer_is_deterministic_and_round_trips() {
    let p = read(SAMPLE);
    let mut a = Vec::new();
    write_walk(&p.walk, &mut a).unwrap();
    let mut b = Vec::new();
    write_walk(&p.walk, &mut b).unwrap();
    assert_eq!(a, b);
    let back = read_walk_from(&a[..], "t", &Limits::default()).unwrap();
    assert_eq!(back.walk, p.walk);
    assert_eq!(back.report.records_skipped(), 0);
    assert_eq!(back.report.out_of_order, 0);
}

#[test]
fn gz_file_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let p = read(SAMPLE);
    let gz = dir.path().join("walk1.txt.gz");
    write_walk_file(&p.walk, &gz).unwrap();
    let bytes1 = std::fs::read(&gz).unwrap();
    write_walk_file(&p.walk, &gz).unwrap();
    assert_eq!(bytes1, std::fs::read(&gz).unwrap());
    assert_eq!(&bytes1[..2], &[0x1f, 0x8b]);
    let back = read_walk(&gz).unwrap();
    assert_eq!(back.walk.meta.id, "walk1");
    let mut expected = p.walk.clone();
    expected.meta.id = "walk1".into();
    assert_eq!(back.walk, expected);
    let txt = dir.path().join("walk2.txt");
    write_walk_file(&p.walk, &txt).unwrap();
    assert_eq!(read_walk(&txt).unwrap().walk.wifi, p.walk.wifi);
}

#[test]
fn writer_refuses_non_finite() {
    let mut w = Walk::default();
    w.waypoints
        .push(Waypoint::new(1, wipdr_core::Point2::new(f64::NAN, 0.0)));
    let e = write_walk(&w, &mut Vec::new()).unwrap_err();
    assert_eq!(e.kind(), io::ErrorKind::InvalidInput);
}

//! Reads the 29 IPIN 2023 logfiles (when `ipin2023/` is under the data
//! root, `$WIPDR_DATA` else `../shared/data`) and checks what
//! the reader promises on them: every file parses, with a counted report; the traps of the
//! data README (the `% POSI` header line, floors 0/-2 whatever the header says, one walk
//! changing floor, the app clock) are handled.

use std::path::PathBuf;
use wipdr_io::ReadOptions;
use wipdr_io::logfile_folder::read_logfile_dir;

fn data_dir() -> Option<PathBuf> {
    match wipdr_io::real_data("ipin2023") {
        Ok(dir) => Some(dir),
        Err(missing) => {
            println!("skipped: {missing}");
            None
        }
    }
}

#[test]
fn every_logfile_parses_with_floors_and_a_report() {
    let Some(dir) = data_dir() else { return };
    let data = read_logfile_dir(&dir, &ReadOptions::default()).unwrap();
    assert_eq!(data.walks.len(), 29);
    assert!(data.skipped_walks.is_empty(), "{:?}", data.skipped_walks);
    assert!(data.geo_frame.is_some());
    let mut changing = Vec::new();
    for p in &data.walks {
        let w = &p.walk;
        let r = &p.report;
        // 10-26 POSI points per walk (README), each with a floor of the data.
        assert!(
            (10..=26).contains(&w.waypoints.len()),
            "{}: {}",
            w.meta.id,
            w.waypoints.len()
        );
        assert!(
            w.waypoints
                .iter()
                .all(|x| matches!(x.floor, Some(0) | Some(-2)))
        );
        // The `% POSI Reference` header line is a header, not ground truth.
        assert_eq!(r.records.get("POSI"), Some(&w.waypoints.len()));
        assert!(r.header_lines > 20);
        // Ground truth inside the folder's frame and plan.
        for x in &w.waypoints {
            assert!(x.position.x > 0.0 && x.position.x < data.width);
            assert!(x.position.y > 0.0 && x.position.y < data.height);
        }
        // Sensors on the app clock: sorted, starting within a second of the log's start.
        assert!(w.imu.accelerometer.windows(2).all(|a| a[0].t <= a[1].t));
        assert!(
            w.imu.accelerometer[0].t.abs() < 1_000,
            "{}",
            w.imu.accelerometer[0].t
        );
        assert!(!w.wifi.is_empty() && !w.pressure.is_empty() && !w.beacons.is_empty());
        assert!(!w.imu.rotation_vector.is_empty());
        assert!(
            r.ignored.get("GNSS").copied().unwrap_or(0) > 0,
            "GNSS counted"
        );
        assert_eq!(
            r.records_skipped(),
            r.skipped_of(wipdr_io::trace::SkipKind::Blank)
        );
        // Scans: one AppTimestamp each, every ~2 s (SM-G930F) or ~4 s (SM-A520F).
        let span = (w.wifi.last().unwrap().t - w.wifi[0].t) as f64 / 1000.0;
        let every = span / (w.wifi.len() - 1) as f64;
        assert!(
            (1.5..6.0).contains(&every),
            "{}: a scan every {every:.1} s",
            w.meta.id
        );
        let floors: std::collections::BTreeSet<i32> =
            w.waypoints.iter().filter_map(|x| x.floor).collect();
        if floors.len() > 1 {
            changing.push(w.meta.id.clone());
        }
        assert!(
            w.meta
                .route
                .as_deref()
                .is_some_and(|r| r.starts_with("Trial"))
        );
    }
    assert_eq!(
        changing,
        vec!["IPIN2023_T3_TrainingTrial52_repetition01".to_string()]
    );
}

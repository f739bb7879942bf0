//! Reads every walk of the five real ILC 2.0 floors (when they are under the data root,
//! `wipdr_io::data_root()`: `$WIPDR_DATA`, else `../shared/data`) and checks
//! the reader's promises on them.

use std::path::PathBuf;
use wipdr_io::floor::{ReadOptions, read_floor_dir};
use wipdr_io::trace::SkipKind;

const FLOORS: [&str; 5] = ["site1/F1", "site1/F2", "site2/F1", "site2/F2", "site2/F3"];

fn data_dir() -> Option<PathBuf> {
    match wipdr_io::real_data("ilc20") {
        Ok(dir) => Some(dir),
        Err(missing) => {
            println!("skipped: {missing}");
            None
        }
    }
}

fn is_sorted<T>(v: &[T], key: impl Fn(&T) -> i64) -> bool {
    v.windows(2).all(|w| key(&w[0]) <= key(&w[1]))
}

#[test]
fn every_walk_of_the_five_floors() {
    let Some(root) = data_dir() else { return };
    let mut walks = 0usize;
    let mut waypoints = 0usize;
    let mut inside = 0usize;
    let mut wifi_lines = 0usize;
    let mut accel = 0usize;
    let mut duplicates = 0usize;
    let mut out_of_order = 0usize;
    let mut max_lateness_ms = 0i64;
    let mut unknown = 0usize;
    let mut walks_without_wifi = 0usize;
    let mut bad_numbers = 0usize;
    for name in FLOORS {
        let floor = read_floor_dir(root.join(name), &ReadOptions::default())
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(floor.name, name);
        assert!(
            floor.width > 100.0 && floor.height > 100.0,
            "{name}: {} x {}",
            floor.width,
            floor.height
        );
        assert!(
            floor.plan.units.len() > 50,
            "{name}: {} units",
            floor.plan.units.len()
        );
        // The outline's bounding box is the whole floor after the transform.
        let (lo, hi) = floor.plan.outline.iter().map(|p| p.bbox()).fold(
            (
                wipdr_core::Point2::new(f64::MAX, f64::MAX),
                wipdr_core::Point2::new(f64::MIN, f64::MIN),
            ),
            |(lo, hi), (l, h)| {
                (
                    wipdr_core::Point2::new(lo.x.min(l.x), lo.y.min(l.y)),
                    wipdr_core::Point2::new(hi.x.max(h.x), hi.y.max(h.y)),
                )
            },
        );
        assert!(lo.x.abs() < 1e-6 && lo.y.abs() < 1e-6, "{name}: {lo}");
        assert!(
            (hi.x - floor.width).abs() < 1e-6 && (hi.y - floor.height).abs() < 1e-6,
            "{name}: {hi}"
        );
        assert!(
            floor
                .walks
                .windows(2)
                .all(|w| w[0].walk.meta.id < w[1].walk.meta.id)
        );
        let floor_name = name.split('/').nth(1).unwrap();
        for p in &floor.walks {
            let w = &p.walk;
            let id = &w.meta.id;
            assert!(
                w.waypoints.len() >= 2,
                "{name}/{id}: {} waypoints",
                w.waypoints.len()
            );
            assert_eq!(
                w.meta.floor_name.as_deref(),
                Some(floor_name),
                "{name}/{id}"
            );
            assert!(w.meta.start_time.is_some(), "{name}/{id}: no startTime");
            assert!(is_sorted(&w.waypoints, |r| r.t), "{name}/{id}");
            assert!(is_sorted(&w.wifi, |r| r.t), "{name}/{id}");
            assert!(is_sorted(&w.beacons, |r| r.t), "{name}/{id}");
            let imu = &w.imu;
            for s in [&imu.accelerometer, &imu.gyroscope, &imu.magnetometer] {
                assert!(is_sorted(s, |r| r.t), "{name}/{id}");
            }
            assert!(is_sorted(&imu.rotation_vector, |r| r.t), "{name}/{id}");
            for s in [
                &imu.accelerometer_uncalibrated,
                &imu.gyroscope_uncalibrated,
                &imu.magnetometer_uncalibrated,
            ] {
                assert!(is_sorted(s, |r| r.t), "{name}/{id}");
            }
            assert!(
                !imu.accelerometer.is_empty(),
                "{name}/{id}: no accelerometer"
            );
            let replay = w.replay();
            assert!(
                replay.windows(2).all(|r| r[0].t() <= r[1].t()),
                "{name}/{id}"
            );
            for scan in &w.wifi {
                let mut b: Vec<_> = scan.entries.iter().map(|e| e.bssid).collect();
                b.sort();
                b.dedup();
                assert_eq!(
                    b.len(),
                    scan.entries.len(),
                    "{name}/{id}: duplicate BSSID at {}",
                    scan.t
                );
            }
            if w.wifi.is_empty() {
                walks_without_wifi += 1;
            }
            // The real files are clean apart from undocumented types and beacons whose
            // distance is `Infinity` (skipped as bad numbers).
            let r = &p.report;
            bad_numbers += r.skipped_of(SkipKind::BadNumber);
            for kind in [
                SkipKind::MissingFields,
                SkipKind::ExtraFields,
                SkipKind::BadTime,
                SkipKind::BadBssid,
                SkipKind::BadHeader,
            ] {
                assert_eq!(
                    r.skipped_of(kind),
                    0,
                    "{name}/{id}: {kind:?} {:?}",
                    r.skipped.get(&kind)
                );
            }
            assert_eq!(r.run_on_lines_split, 0, "{name}/{id}");
            if let Some(s) = r.skipped.get(&SkipKind::UnknownType) {
                assert!(!s.first_lines.is_empty() && s.first_lines.len() <= 5);
                assert_eq!(s.count, r.unknown_types.values().sum::<usize>());
            }
            walks += 1;
            waypoints += w.waypoints.len();
            inside += w
                .waypoints
                .iter()
                .filter(|p| floor.plan.inside_outline(p.position))
                .count();
            wifi_lines += r.records.get("TYPE_WIFI").copied().unwrap_or(0);
            accel += w.imu.accelerometer.len();
            duplicates += r.duplicate_bssids_removed;
            out_of_order += r.out_of_order;
            max_lateness_ms = max_lateness_ms.max(r.max_lateness_ms);
            unknown += r.skipped_of(SkipKind::UnknownType);
        }
    }
    println!(
        "{walks} walks, {waypoints} waypoints ({inside} inside the outline), {wifi_lines} Wi-Fi lines, \
         {duplicates} duplicate BSSIDs removed, {out_of_order} out-of-order records (latest by {max_lateness_ms} ms), {unknown} unknown-type lines, \
         {walks_without_wifi} walks without Wi-Fi, {bad_numbers} bad numbers"
    );
    // Counts from `zcat */*/path_data_files/*.gz | awk -F'\t' '{print $2}' | sort | uniq -c`.
    assert_eq!(walks, 370);
    assert_eq!(waypoints, 2612);
    assert_eq!(wifi_lines, 1_770_817);
    assert_eq!(accel, 665_926);
    assert_eq!(
        unknown,
        2 * 303_014 + 3 * 370,
        "TYPE_BLUE, TYPE_BLU4, TYPE_DIST1/2, accuracy changes"
    );
    // `zcat ... | grep TYPE_BEACON | grep -ciE '\t-?infinity\t|\tnan\t'` = 341.
    assert_eq!(bad_numbers, 341, "beacon lines with an infinite distance");
    // `awk -F'\t' '$2=="TYPE_WIFI"{k=$1" "$4; if(k in s) d++; s[k]=1} END{print d}'` = 12374.
    assert_eq!(duplicates, 12_374);
    assert!(
        out_of_order > 0 && max_lateness_ms > 10_000,
        "waypoints are written up to 11 s late"
    );
    let share = inside as f64 / waypoints as f64;
    assert!(
        share >= 0.99,
        "only {:.2} % of the waypoints inside the outline",
        share * 100.0
    );
}

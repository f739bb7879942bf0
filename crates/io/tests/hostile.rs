//! Hostile and degenerate input, generated here (no large files committed): each case ends
//! in a typed error or a counted skip, never a panic or a silent wrong answer (issue 14).

use std::path::{Path, PathBuf};
use wipdr_core::{FloorPlan, Point2, Walk, Waypoint};
use wipdr_io::fingerprint_csv::{FingerprintCsvError, read_fingerprint_csv_from_with};
use wipdr_io::trace::{self, SkipKind};
use wipdr_io::{IoError, Limits, LonLatBox, ReadOptions, floor};

fn walk_text(lines: &[String]) -> String {
    let mut t = String::from("#\tstartTime:1000\n");
    for l in lines {
        t.push_str(l);
        t.push('\n');
    }
    t
}

fn read(text: &str, limits: &Limits) -> Result<trace::ParsedWalk, IoError> {
    trace::read_walk_from(text.as_bytes(), "w", limits)
}

#[test]
fn one_entry_scans_are_bounded_by_the_walk_memory_limit() {
    // 20 000 scans of one entry each: far below max_records, but each scan costs memory.
    let lines: Vec<String> = (0..20_000)
        .map(|i| {
            format!(
                "{}\tTYPE_WIFI\tnet\ta8:0c:ca:03:9d:d7\t-49\t2422\t{}",
                1000 + i,
                1000 + i
            )
        })
        .collect();
    let text = walk_text(&lines);
    let ok = read(&text, &Limits::default()).unwrap();
    assert_eq!(ok.walk.wifi.len(), 20_000);
    let limits = Limits {
        max_walk_memory_bytes: 1 << 20,
        ..Limits::default()
    };
    match read(&text, &limits).unwrap_err() {
        IoError::LimitExceeded {
            limit, max, what, ..
        } => {
            assert_eq!((limit, max), ("max_walk_memory_bytes", 1 << 20));
            assert!(what.starts_with("line "), "{what}");
        }
        e => panic!("{e}"),
    }
    let msg = read(&text, &limits).unwrap_err().to_string();
    assert!(
        msg.contains("Limits::max_walk_memory_bytes = 1048576; raise it"),
        "{msg}"
    );
}

#[test]
fn absurd_sensor_values_and_waypoints_are_counted_skips() {
    let lines = [
        "1000\tTYPE_ACCELEROMETER\t1e308\t0\t9.8\t3",
        "1001\tTYPE_ACCELEROMETER\t0.1\t0\t9.8\t3",
        "1002\tTYPE_ACCELEROMETER\t-600\t0\t9.8\t3",
        "1003\tTYPE_GYROSCOPE\t0\t1e200\t0\t3",
        "1004\tTYPE_MAGNETIC_FIELD\t0\t0\t-1e9\t3",
        "1005\tTYPE_ROTATION_VECTOR\t0\t0\t7\t3",
        "1006\tTYPE_GYROSCOPE_UNCALIBRATED\t0\t0\t0\t1e300\t0\t0\t3",
        "1007\tTYPE_WAYPOINT\t1e308\t2",
        "1008\tTYPE_WAYPOINT\t1\t2",
    ]
    .map(String::from);
    let p = read(&walk_text(&lines), &Limits::default()).unwrap();
    assert_eq!(p.walk.imu.accelerometer.len(), 1);
    assert!(p.walk.imu.gyroscope.is_empty());
    assert!(p.walk.imu.magnetometer.is_empty());
    assert!(p.walk.imu.rotation_vector.is_empty());
    assert!(p.walk.imu.gyroscope_uncalibrated.is_empty());
    assert_eq!(p.walk.waypoints.len(), 1);
    assert_eq!(p.report.skipped_of(SkipKind::OutOfRange), 7);
    assert_eq!(
        p.report.skipped[&SkipKind::OutOfRange].first_lines[..2],
        [2, 4]
    );
}

#[test]
fn duplicate_waypoint_times_are_a_counted_skip_keeping_the_first() {
    let lines = [
        "2000\tTYPE_WAYPOINT\t1\t2",
        "2000\tTYPE_WAYPOINT\t50\t60",
        "3000\tTYPE_WAYPOINT\t3\t4",
    ]
    .map(String::from);
    let p = read(&walk_text(&lines), &Limits::default()).unwrap();
    assert_eq!(p.walk.waypoints.len(), 2);
    assert_eq!(p.walk.waypoints[0].position, Point2::new(1.0, 2.0));
    assert_eq!(p.report.skipped_of(SkipKind::DuplicateWaypoint), 1);
    assert_eq!(p.report.records["TYPE_WAYPOINT"], 2);
}

fn floor_with(root: &Path, waypoints: &[(f64, f64)]) -> PathBuf {
    let dir = root.join("site").join("F1");
    let mut walk = Walk::default();
    walk.meta.id = "w".into();
    for (i, &(x, y)) in waypoints.iter().enumerate() {
        walk.waypoints
            .push(Waypoint::new(1000 * i as i64, Point2::new(x, y)));
    }
    let plan = FloorPlan::rectangle(20.0, 10.0).unwrap();
    floor::write_floor_dir(
        &dir,
        &plan,
        LonLatBox::around(8.0, 47.0, 20.0, 10.0),
        [&walk],
    )
    .unwrap();
    dir
}

#[test]
fn waypoints_off_the_floor_are_a_counted_skip() {
    let tmp = tempfile::tempdir().unwrap();
    // 20 x 10 m floor: the margin is 10 + 10 m.
    let dir = floor_with(
        tmp.path(),
        &[
            (1.0, 1.0),
            (-25.0, 5.0),
            (5.0, 1e5),
            (19.0, 9.0),
            (39.0, 29.0),
        ],
    );
    let f = floor::read_floor_dir(&dir, &ReadOptions::default()).unwrap();
    let w = &f.walks[0];
    assert_eq!(w.walk.waypoints.len(), 3);
    assert_eq!(w.report.skipped_of(SkipKind::WaypointOffFloor), 2);
    assert_eq!(f.total_report().skipped_of(SkipKind::WaypointOffFloor), 2);
}

#[test]
fn a_floor_size_of_1e_minus_300_is_a_typed_error() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = floor_with(tmp.path(), &[(1.0, 1.0)]);
    for bad in ["1e-300", "1e300", "0.01"] {
        std::fs::write(
            dir.join(floor::FLOOR_INFO),
            format!(r#"{{"map_info": {{"height": 10, "width": {bad}}}}}"#),
        )
        .unwrap();
        match floor::read_floor_dir(&dir, &ReadOptions::default()).unwrap_err() {
            IoError::Invalid { field, message, .. } => {
                assert_eq!(field, "map_info.width");
                assert!(message.contains("between 0.1 and 100000 m"), "{message}");
            }
            e => panic!("{bad}: {e}"),
        }
    }
}

fn geojson(outline: &str, units: &[&str]) -> String {
    let mut features = vec![format!(
        r#"{{"type":"Feature","properties":{{}},"geometry":{{"type":"Polygon","coordinates":[{outline}]}}}}"#
    )];
    for u in units {
        features.push(format!(
            r#"{{"type":"Feature","properties":{{"name":"u"}},"geometry":{{"type":"Polygon","coordinates":[{u}]}}}}"#
        ));
    }
    format!(
        r#"{{"type":"FeatureCollection","features":[{}]}}"#,
        features.join(",")
    )
}

fn read_plan(text: &str, limits: &Limits) -> Result<wipdr_io::geojson::PlanRead, IoError> {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("g.json");
    std::fs::write(&path, text).unwrap();
    wipdr_io::geojson::read_floor_plan(&path, 20.0, 10.0, limits)
}

#[test]
fn zero_area_and_self_intersecting_polygons_are_counted_skips() {
    let square = "[[0,0],[2,0],[2,1],[0,1],[0,0]]";
    let bowtie = "[[0,0],[2,1],[2,0],[0,1],[0,0]]";
    let flat = "[[0,0],[1,0.5],[2,1],[0,0]]";
    // A MultiPolygon outline: a good part, a bow tie, a flat one.
    let text = format!(
        r#"{{"type":"FeatureCollection","features":[{{"type":"Feature","properties":{{}},"geometry":{{"type":"MultiPolygon","coordinates":[[{square}],[{bowtie}],[{flat}]]}}}},{{"type":"Feature","properties":{{"name":"u"}},"geometry":{{"type":"Polygon","coordinates":[{flat}]}}}}]}}"#
    );
    let p = read_plan(&text, &Limits::default()).unwrap();
    assert_eq!(p.plan.outline.len(), 1);
    assert!(p.plan.units.is_empty());
    assert_eq!(p.skipped_features, 3);
    // An outline of only a bow tie or only a flat ring is a typed error.
    for bad in [bowtie, flat] {
        match read_plan(&geojson(bad, &[]), &Limits::default()).unwrap_err() {
            IoError::Invalid { field, .. } => {
                assert_eq!(field, "features[0].geometry.coordinates")
            }
            e => panic!("{e}"),
        }
    }
}

/// Seen on the old main: unit (room) polygons that cross themselves (bow ties) were kept,
/// and became walls; only the outline was checked. Units and holes are now checked like the
/// outline: the polygon is skipped, counted and logged.
#[test]
fn self_intersecting_unit_polygons_and_holes_are_counted_skips() {
    let outline = "[[0,0],[20,0],[20,10],[0,10],[0,0]]";
    let room = "[[1,1],[3,1],[3,3],[1,3],[1,1]]";
    // Not symmetric: a non-zero signed area, so not skipped as degenerate.
    let bowtie = "[[5,1],[9,3],[9,1],[5,4],[5,1]]";
    // Five vertices, the crossing between the first and the fourth edge.
    let eight = "[[10,1],[13,1],[13,4],[11,0],[10,4],[10,1]]";
    // A good room with a bow-tie hole.
    let holed = "[[13,1],[19,1],[19,8],[13,8],[13,1]],[[14,2],[17,4],[17,2],[14,5],[14,2]]";
    let text = geojson(outline, &[room, bowtie, eight, holed]);
    let p = read_plan(&text, &Limits::default()).unwrap();
    assert_eq!(p.plan.units.len(), 1, "only the square room is kept");
    assert_eq!(p.skipped_features, 3);
    // A MultiPolygon unit: the good part is kept, the bow tie skipped.
    let multi = format!(
        r#"{{"type":"FeatureCollection","features":[{{"type":"Feature","properties":{{}},"geometry":{{"type":"Polygon","coordinates":[{outline}]}}}},{{"type":"Feature","properties":{{"name":"m"}},"geometry":{{"type":"MultiPolygon","coordinates":[[{room}],[{bowtie}]]}}}}]}}"#
    );
    let p = read_plan(&multi, &Limits::default()).unwrap();
    assert_eq!(p.plan.units.len(), 1);
    assert_eq!(p.skipped_features, 1);
}

#[test]
fn geojson_values_are_counted_before_the_tree_is_built() {
    // 300 000 numbers in one position: few vertices, many values.
    let many: Vec<String> = (0..300_000).map(|i| (i % 10).to_string()).collect();
    let text = geojson(
        &format!("[[0,0],[2,0],[2,1],[0,1],[{}]]", many.join(",")),
        &[],
    );
    let limits = Limits {
        max_json_values: 100_000,
        ..Limits::default()
    };
    match read_plan(&text, &limits).unwrap_err() {
        IoError::LimitExceeded { limit, max, .. } => {
            assert_eq!((limit, max), ("max_json_values", 100_000));
        }
        e => panic!("{e}"),
    }
    // Commas inside strings are not values.
    let quoted = geojson("[[0,0],[2,0],[2,1],[0,1],[0,0]]", &[]).replace(
        r#""properties":{}"#,
        &format!(r#""properties":{{"note":"{}"}}"#, ",".repeat(200_000)),
    );
    read_plan(&quoted, &limits).unwrap();
}

fn csv(rows: usize, aps: usize) -> String {
    let mut t: Vec<String> = (0..aps).map(|i| format!("ap_{i:03}")).collect();
    t.extend(["x", "y", "z", "floor", "building"].map(String::from));
    let mut text = t.join(",");
    text.push('\n');
    for r in 0..rows {
        let mut row: Vec<String> = (0..aps).map(|_| "-60".to_string()).collect();
        row.extend([
            format!("{r}"),
            "1".into(),
            "0".into(),
            "0".into(),
            "0".into(),
        ]);
        text.push_str(&row.join(","));
        text.push('\n');
    }
    text
}

fn csv_limit(text: &str, limits: &Limits) -> (&'static str, u64, usize) {
    match read_fingerprint_csv_from_with(text.as_bytes(), "t.csv", limits).unwrap_err() {
        FingerprintCsvError::LimitExceeded {
            limit, max, line, ..
        } => (limit, max, line),
        e => panic!("{e}"),
    }
}

#[test]
fn fingerprint_csv_lines_size_columns_and_cells_are_limited() {
    let text = csv(100, 50);
    read_fingerprint_csv_from_with(text.as_bytes(), "t.csv", &Limits::default()).unwrap();
    let l = Limits {
        max_csv_line_bytes: 100,
        ..Limits::default()
    };
    assert_eq!(csv_limit(&text, &l), ("max_csv_line_bytes", 100, 1));
    let l = Limits {
        max_csv_bytes: 2000,
        ..Limits::default()
    };
    let (limit, _, line) = csv_limit(&text, &l);
    assert_eq!(limit, "max_csv_bytes");
    assert!(line > 1 && line < 20, "{line}");
    let l = Limits {
        max_csv_columns: 20,
        ..Limits::default()
    };
    assert_eq!(csv_limit(&text, &l), ("max_csv_columns", 20, 1));
    let l = Limits {
        max_csv_cells: 50 * 10,
        ..Limits::default()
    };
    assert_eq!(csv_limit(&text, &l), ("max_csv_cells", 500, 12));
    // A single line of megabytes never gets buffered whole.
    let huge = format!("ap_000,x,y,z,floor,building\n{}\n", "1".repeat(4 << 20));
    assert_eq!(
        csv_limit(&huge, &Limits::default()),
        ("max_csv_line_bytes", 1 << 20, 2)
    );
    let msg = read_fingerprint_csv_from_with(huge.as_bytes(), "t.csv", &Limits::default())
        .unwrap_err()
        .to_string();
    assert!(msg.contains("line 2: line length: more than the limit Limits::max_csv_line_bytes = 1048576; raise it"), "{msg}");
}

/// Seen on the old main: a label at x = 1e308 was read, and its error was infinite in 3D
/// and left out of the finite 2D mean. Labels are range-checked on read, as waypoints are.
#[test]
fn fingerprint_labels_beyond_any_building_are_out_of_range() {
    let header = "ap_000,x,y,z,floor,building\n";
    for (row, column, field) in [
        ("-60,1e308,0,0,0,0", 2, "x"),
        ("-60,0,-1e200,0,0,0", 3, "y"),
        ("-60,0,0,1e9,0,0", 4, "z"),
    ] {
        let text = format!("{header}-60,1,2,0,0,0\n{row}\n");
        match read_fingerprint_csv_from_with(text.as_bytes(), "t.csv", &Limits::default()) {
            Err(FingerprintCsvError::OutOfRange {
                line,
                column: c,
                field: f,
                ..
            }) => assert_eq!((line, c, f.as_str()), (3, column, field)),
            other => panic!("{row}: {other:?}"),
        }
    }
    // Projected coordinates of real datasets (UJIIndoorLoc: northings near 4.86e6 m) read.
    let text = format!("{header}-60,-7600.5,4864900.25,0,0,0\n");
    read_fingerprint_csv_from_with(text.as_bytes(), "t.csv", &Limits::default()).unwrap();
}

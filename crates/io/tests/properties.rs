//! Property tests of the trace reader and writer: write-then-read round-trips arbitrary
//! walks; truncated, garbled or empty input never panics and yields a typed error or a
//! parse report.

use proptest::prelude::*;
use std::collections::BTreeMap;
use std::io::Write;
use wipdr_core::{
    BeaconSample, Bssid, Point2, RotationVectorSample, UncalibratedSample, Vec3Sample, Walk,
    WalkMeta, Waypoint, WifiEntry, WifiScan,
};
use wipdr_io::trace::{
    MAX_ABS_ACCELERATION, MAX_ABS_COORDINATE_M, MAX_ABS_MAGNETIC_FIELD, MAX_ABS_ROTATION_RATE,
    read_walk_from, write_walk,
};
use wipdr_io::{IoError, Limits};

fn finite() -> impl Strategy<Value = f64> {
    prop_oneof![
        -1e4..1e4f64,
        any::<f64>().prop_filter("finite", |v| v.is_finite()),
        Just(0.0),
        Just(-0.0),
    ]
}

/// A finite value within `max` (the reader's physical range of a stream: beyond it a
/// sample is skipped, see `hostile.rs`), including the bound itself.
fn bounded(max: f64) -> impl Strategy<Value = f64> {
    prop_oneof![
        -max..=max,
        Just(max),
        Just(-max),
        Just(0.0),
        Just(-0.0),
        -1.0..1.0f64
    ]
}

fn time() -> impl Strategy<Value = i64> {
    const MAX: i64 = wipdr_io::trace::MAX_ABS_TIME_MS;
    prop_oneof![
        1_500_000_000_000i64..1_700_000_000_000,
        -MAX..=MAX,
        Just(MAX),
        Just(-MAX)
    ]
}

/// Strings as phones write them: no tab, CR or LF (the writer turns those into spaces).
fn text() -> impl Strategy<Value = String> {
    "[^\t\r\n]{0,12}"
}

fn vec3(max: f64) -> impl Strategy<Value = Vec3Sample> {
    (
        time(),
        [bounded(max), bounded(max), bounded(max)],
        any::<i8>(),
    )
        .prop_map(|(t, v, accuracy)| Vec3Sample { t, v, accuracy })
}

fn uncal(max: f64) -> impl Strategy<Value = UncalibratedSample> {
    (
        time(),
        [bounded(max), bounded(max), bounded(max)],
        [bounded(max), bounded(max), bounded(max)],
        any::<i8>(),
    )
        .prop_map(|(t, v, bias, accuracy)| UncalibratedSample {
            t,
            v,
            bias,
            accuracy,
        })
}

fn scans() -> impl Strategy<Value = Vec<WifiScan>> {
    let entry = (0..=Bssid::MAX, text(), finite(), any::<u32>(), time());
    prop::collection::btree_map(time(), prop::collection::vec(entry, 1..6), 0..5).prop_map(
        |m: BTreeMap<i64, Vec<_>>| {
            m.into_iter()
                .map(|(t, entries)| {
                    let mut seen = std::collections::HashSet::new();
                    WifiScan {
                        t,
                        entries: entries
                            .into_iter()
                            .filter(|e| seen.insert(e.0))
                            .map(
                                |(b, ssid, rssi_dbm, frequency_mhz, last_seen_ms)| WifiEntry {
                                    bssid: Bssid(b),
                                    ssid,
                                    rssi_dbm,
                                    frequency_mhz,
                                    last_seen_ms,
                                },
                            )
                            .collect(),
                    }
                })
                .collect()
        },
    )
}

fn beacon() -> impl Strategy<Value = BeaconSample> {
    (
        time(),
        (text(), text(), text()),
        (finite(), finite(), finite()),
        "[0-9A-F:]{0,17}",
        time(),
    )
        .prop_map(
            |(t, (uuid, major, minor), (tx_power, rssi_dbm, distance), mac, seen_ms)| {
                BeaconSample {
                    t,
                    uuid,
                    major,
                    minor,
                    tx_power: Some(tx_power),
                    rssi_dbm,
                    distance: Some(distance),
                    mac,
                    seen_ms: Some(seen_ms),
                }
            },
        )
}

fn meta() -> impl Strategy<Value = WalkMeta> {
    let s = || proptest::option::of(text());
    (
        (s(), s(), s(), s()),
        (s(), s(), s()),
        proptest::option::of(time()),
        proptest::option::of(time()),
    )
        .prop_map(
            |((site_id, site_name, floor_id, floor_name), (brand, model, android), start, end)| {
                WalkMeta {
                    id: "prop".into(),
                    site_id,
                    site_name,
                    floor_id,
                    floor_name,
                    brand,
                    model,
                    android,
                    start_time: start,
                    end_time: end,
                    route: None,
                }
            },
        )
}

fn walk() -> impl Strategy<Value = Walk> {
    use prop::collection::vec as v;
    (
        meta(),
        v(
            (
                time(),
                bounded(MAX_ABS_COORDINATE_M),
                bounded(MAX_ABS_COORDINATE_M),
            ),
            0..6,
        ),
        scans(),
        prop::collection::vec(beacon(), 0..3),
        (
            v(vec3(MAX_ABS_ACCELERATION), 0..6),
            v(vec3(MAX_ABS_ROTATION_RATE), 0..6),
            v(vec3(MAX_ABS_MAGNETIC_FIELD), 0..6),
        ),
        prop::collection::vec(
            (
                time(),
                [bounded(2.0), bounded(2.0), bounded(2.0)],
                any::<i8>(),
            ),
            0..6,
        ),
        (
            v(uncal(MAX_ABS_ACCELERATION), 0..6),
            v(uncal(MAX_ABS_ROTATION_RATE), 0..6),
            v(uncal(MAX_ABS_MAGNETIC_FIELD), 0..6),
        ),
    )
        .prop_map(
            |(meta, wps, wifi, beacons, (acc, gyr, mag), rot, (ua, ug, um))| {
                let mut w = Walk {
                    meta,
                    waypoints: wps
                        .into_iter()
                        .map(|(t, x, y)| Waypoint::new(t, Point2::new(x, y)))
                        .collect(),
                    wifi,
                    beacons,
                    imu: Default::default(),
                    pressure: Vec::new(),
                };
                w.imu.accelerometer = acc;
                w.imu.gyroscope = gyr;
                w.imu.magnetometer = mag;
                w.imu.rotation_vector = rot
                    .into_iter()
                    .map(|(t, v, accuracy)| RotationVectorSample { t, v, accuracy })
                    .collect();
                w.imu.accelerometer_uncalibrated = ua;
                w.imu.gyroscope_uncalibrated = ug;
                w.imu.magnetometer_uncalibrated = um;
                w.sort_streams();
                // One waypoint per time (the reader keeps the first of a repeated time).
                w.waypoints.dedup_by_key(|p| p.t);
                w
            },
        )
}

fn written(w: &Walk) -> Vec<u8> {
    let mut out = Vec::new();
    write_walk(w, &mut out).unwrap();
    out
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    enc.write_all(bytes).unwrap();
    enc.finish().unwrap()
}

/// Reading never panics; errors are typed and name the input.
fn read_any(bytes: &[u8]) {
    let limits = Limits {
        max_line_bytes: 4096,
        max_input_bytes: 1 << 20,
        ..Limits::default()
    };
    match read_walk_from(bytes, "input", &limits) {
        Ok(p) => {
            // Whatever was kept is sane: sorted streams, finite numbers.
            let w = &p.walk;
            assert!(w.waypoints.windows(2).all(|a| a[0].t <= a[1].t));
            assert!(w.wifi.windows(2).all(|a| a[0].t <= a[1].t));
            assert!(w.imu.accelerometer.windows(2).all(|a| a[0].t <= a[1].t));
            assert!(
                w.waypoints
                    .iter()
                    .all(|p| p.position.x.is_finite() && p.position.y.is_finite())
            );
            assert!(
                w.wifi
                    .iter()
                    .flat_map(|s| &s.entries)
                    .all(|e| e.rssi_dbm.is_finite())
            );
            assert!(p.report.lines <= bytes.len() + 1);
        }
        Err(e) => assert!(e.to_string().starts_with("input"), "{e}"),
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn write_then_read_round_trips(w in walk()) {
        let bytes = written(&w);
        let back = read_walk_from(&bytes[..], "prop", &Limits::default()).unwrap();
        prop_assert_eq!(&back.walk, &w);
        prop_assert_eq!(back.report.records_skipped(), 0);
        prop_assert_eq!(back.report.out_of_order, 0);
        prop_assert_eq!(back.report.run_on_lines_split, 0);
        // Deterministic, and gzip gives the same walk.
        prop_assert_eq!(written(&back.walk), bytes.clone());
        let gz = read_walk_from(&gzip(&bytes)[..], "prop", &Limits::default()).unwrap();
        prop_assert_eq!(gz.walk, w);
    }

    #[test]
    fn truncated_input_never_panics(w in walk(), cut in any::<prop::sample::Index>()) {
        let bytes = written(&w);
        let n = if bytes.is_empty() { 0 } else { cut.index(bytes.len() + 1) };
        read_any(&bytes[..n]);
        // A truncated gzip stream: a typed read error (or a clean report when the cut
        // happens to keep everything).
        let gz = gzip(&bytes);
        let n = cut.index(gz.len() + 1);
        read_any(&gz[..n]);
    }

    #[test]
    fn garbled_input_never_panics(
        w in walk(),
        edits in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>(), 0u8..3), 1..20),
    ) {
        let mut bytes = written(&w);
        for (at, byte, op) in edits {
            let i = at.index(bytes.len() + 1);
            match op {
                0 if i < bytes.len() => bytes[i] = byte,
                1 => bytes.insert(i, byte),
                _ if i < bytes.len() => { bytes.remove(i); }
                _ => bytes.push(byte),
            }
        }
        read_any(&bytes);
        read_any(&gzip(&bytes));
    }

    #[test]
    fn arbitrary_times_never_panic(t in any::<i64>(), u in any::<i64>(), s in any::<i64>()) {
        let text = format!("{t}\tTYPE_WAYPOINT\t1\t2\n{u}\tTYPE_WAYPOINT\t1\t2\n{s}\tTYPE_WIFI\tx\t00:00:00:00:00:01\t-50\t2412\t{t}\n#\tstartTime:{u}\n");
        read_any(text.as_bytes());
    }

    #[test]
    fn arbitrary_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..2000)) {
        read_any(&bytes);
    }

    #[test]
    fn tab_soup_never_panics(s in "([0-9]{1,14}|TYPE_[A-Z_]{1,12}|[-0-9.eE]{1,8}|[0-9a-f:]{17}|\t|\n|#|:){0,80}") {
        read_any(s.as_bytes());
    }
}

#[test]
fn empty_input_gives_an_empty_report() {
    let p = read_walk_from(&b""[..], "empty", &Limits::default()).unwrap();
    assert_eq!(p.report.lines, 0);
    assert_eq!(p.walk.waypoints.len(), 0);
    let p = read_walk_from(&gzip(b"")[..], "empty", &Limits::default()).unwrap();
    assert_eq!(p.report.lines, 0);
}

#[test]
fn truncated_gzip_is_a_read_error() {
    let mut w = Walk::default();
    for i in 0..2000 {
        w.waypoints.push(Waypoint::new(
            i,
            Point2::new(i as f64 * 0.37, 1.0 / (1.0 + i as f64)),
        ));
    }
    let gz = gzip(&written(&w));
    let e = read_walk_from(&gz[..gz.len() / 2], "cut.txt.gz", &Limits::default()).unwrap_err();
    assert!(matches!(e, IoError::Read { .. }), "{e}");
    assert!(
        e.to_string()
            .starts_with("cut.txt.gz: read failed after line "),
        "{e}"
    );
}

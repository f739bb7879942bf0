//! `wipdr locate`'s CSV, scored at the walk's waypoints (latest estimate at or before each),
//! equals the per-walk errors `wipdr eval --json` reports for that walk, for every scheme
//! (the fixture floor; eval and locate run the same `Positioner`).

use std::path::PathBuf;
use std::process::Command;

fn fixture_dir() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/sim/F1"))
}

mod common;
use common::wipdr;

#[test]
fn locate_csv_scores_as_eval_json_for_every_scheme() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = fixture_dir();
    let data = dir.to_str().unwrap();
    let schemes = wipdr_fusion::scheme_names().join(",");
    let json = tmp.path().join("eval.json");
    wipdr(
        &[
            "eval",
            "--data",
            data,
            "--schemes",
            &schemes,
            "--json",
            json.to_str().unwrap(),
        ],
        tmp.path(),
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let floor = wipdr_io::floor::read_floor_dir(&dir, &Default::default()).unwrap();
    let walk = &floor.walks[0].walk;
    let first_scan = walk.wifi.first().map(|s| s.t);
    for scheme in wipdr_fusion::scheme_names() {
        let csv = tmp.path().join(format!("{scheme}.csv"));
        wipdr(
            &[
                "locate",
                "--data",
                data,
                "--walk",
                &walk.meta.id,
                "--scheme",
                scheme,
                "--out",
                csv.to_str().unwrap(),
            ],
            tmp.path(),
        );
        let text = std::fs::read_to_string(&csv).unwrap();
        let mut lines = text.lines();
        assert_eq!(lines.next(), Some("t_ms,x,y,floor,sd_m"));
        let track: Vec<wipdr_eval::scoring::TrackPoint> = lines
            .map(|l| {
                let f: Vec<&str> = l.split(',').collect();
                wipdr_eval::scoring::TrackPoint::new(
                    f[0].parse().unwrap(),
                    wipdr_core::Point2::new(f[1].parse().unwrap(), f[2].parse().unwrap()),
                )
            })
            .collect();
        let located = wipdr_eval::scoring::score_track(&walk.waypoints, &track, first_scan);
        let from_eval = report["walks"]
            .as_array()
            .unwrap()
            .iter()
            .find(|w| w["walk"] == walk.meta.id.as_str() && w["scheme"] == *scheme)
            .unwrap_or_else(|| panic!("{scheme} in the JSON"));
        let errors: Vec<(i64, f64, Option<i32>)> =
            serde_json::from_value(from_eval["errors"].clone()).unwrap();
        assert!(!errors.is_empty(), "{scheme}");
        assert_eq!(
            located.errors, errors,
            "{scheme}: locate and eval --json differ"
        );
    }
}

#[test]
fn locate_writes_geojson_and_refuses_an_unknown_walk() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = fixture_dir();
    let data = dir.to_str().unwrap();
    let floor = wipdr_io::floor::read_floor_dir(&dir, &Default::default()).unwrap();
    let id = floor.walks[1].walk.meta.id.clone();
    let out = tmp.path().join("t.geojson");
    wipdr(
        &[
            "locate",
            "--data",
            data,
            "--walk",
            &id,
            "--scheme",
            "ekf",
            "--format",
            "geojson",
            "--out",
            out.to_str().unwrap(),
        ],
        tmp.path(),
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(v["geometry"]["type"], "LineString");
    assert!(v["geometry"]["coordinates"].as_array().unwrap().len() > 10);
    let bad = Command::new(env!("CARGO_BIN_EXE_wipdr"))
        .args(["locate", "--data", data, "--walk", "no-such-walk", "--out"])
        .arg(tmp.path().join("x.csv"))
        .current_dir(tmp.path())
        .output()
        .unwrap();
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("no-such-walk"));
}

//! IPIN logfiles end to end through the binary: the fixture floor's walks written as
//! GetSensorData logfiles (three routes, repetitions), then `wipdr inspect`, `wipdr eval`
//! (leave-one-route-out, floor hits and EvAAL, `[t, error, floor error]` points) and
//! `wipdr locate` on one logfile (`t_s,lat,lon,floor` at 2 Hz).

mod common;

use std::path::{Path, PathBuf};
use wipdr_core::{GeoFrame, PressureSample};

fn wipdr(args: &[&str]) -> String {
    common::wipdr(args, Path::new("."))
}

/// The fixture walks as logfiles in `dir/trials`, route `Trial0{i mod 3}`; returns the frame.
fn write_logfiles(dir: &Path) -> (GeoFrame, Vec<PathBuf>) {
    let fixture = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/sim/F1"));
    let floor = wipdr_io::read_floor_dir(&fixture, &Default::default()).unwrap();
    let frame = GeoFrame::new(49.4611, 11.1102).unwrap();
    let trials = dir.join("trials");
    std::fs::create_dir_all(&trials).unwrap();
    let mut files = Vec::new();
    for (i, parsed) in floor.walks.iter().enumerate() {
        let mut walk = parsed.walk.clone();
        for w in &mut walk.waypoints {
            w.floor = Some(0);
        }
        if let Some((t0, t1)) = walk.time_span() {
            walk.pressure = (t0..=t1)
                .step_by(1000)
                .map(|t| PressureSample { t, hpa: 976.2 })
                .collect();
        }
        let name = format!("SIM_Trial0{}_repetition0{}.txt", i % 3, i / 3 + 1);
        let path = trials.join(name);
        let mut file = std::fs::File::create(&path).unwrap();
        wipdr_io::logfile::write_logfile(&walk, &frame, 100, &mut file).unwrap();
        files.push(path);
    }
    (frame, files)
}

#[test]
fn logfiles_inspect_eval_and_locate() {
    let tmp = tempfile::tempdir().unwrap();
    let (frame, files) = write_logfiles(tmp.path());
    let dir = tmp.path().to_str().unwrap();

    let inspect = wipdr(&["--no-cache", "inspect", "--brief", dir]);
    assert!(
        inspect.contains(&format!("{} walks", files.len())),
        "{inspect}"
    );
    assert!(inspect.contains("waypoints by floor {0:"), "{inspect}");

    let json = tmp.path().join("eval.json");
    let eval = wipdr(&[
        "--no-cache",
        "eval",
        "--data",
        dir,
        "--schemes",
        "wifi,pdr,ekf",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(eval.contains("leave-one-route-out (3 routes)"), "{eval}");
    assert!(eval.contains("evaal"), "{eval}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    for scheme in ["wifi", "pdr", "ekf"] {
        let pooled = &report["pooled"][scheme];
        // One floor: every point with a floor estimate is a hit, EvAAL is the 2D errors' 75th
        // percentile by the competition's (MATLAB's) quantile rule.
        assert_eq!(pooled["floor_hit_rate"], 1.0, "{scheme}: {pooled}");
        let errors: Vec<f64> = report["walks"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|w| w["scheme"] == scheme)
            .flat_map(|w| w["errors"].as_array().unwrap().iter())
            .map(|e| e[1].as_f64().unwrap())
            .collect();
        let want = wipdr_eval::evaal_score::evaal_metric(&errors).unwrap();
        let got = pooled["evaal"].as_f64().unwrap();
        assert!((got - want).abs() < 1e-9, "{scheme}: {got} vs {want}");
    }
    let point = &report["walks"][0]["errors"][0];
    assert_eq!(point.as_array().map(Vec::len), Some(3), "{point}");
    assert_eq!(point[2], 0);

    let out = tmp.path().join("track.csv");
    let located = &files[0];
    wipdr(&[
        "--no-cache",
        "locate",
        "--data",
        located.to_str().unwrap(),
        "--scheme",
        "ekf",
        "--out",
        out.to_str().unwrap(),
    ]);
    let text = std::fs::read_to_string(&out).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("t_s,lat,lon,floor"));
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|f| f.parse::<f64>().unwrap()).collect())
        .collect();
    assert!(rows.len() > 10);
    for pair in rows.windows(2) {
        assert!(
            (pair[1][0] - pair[0][0] - 0.5).abs() < 1e-9,
            "2 Hz: {pair:?}"
        );
    }
    // Estimates in degrees near the fixture floor placed at the frame (within 200 m).
    for r in &rows {
        let p = frame.to_local(r[1], r[2]);
        assert!(p.coords.norm() < 200.0, "{r:?} is {p:?} from the origin");
        assert_eq!(r[3], 0.0);
    }
}

//! `wipdr fit` then `wipdr locate --model` in fresh processes gives exactly the per-walk
//! errors of the evaluation for that walk, for every scheme: on the fixture floor, on the
//! fixture walks written as IPIN logfiles, and (when the shared data is beside the
//! repository) on a real ILC floor and the real IPIN logfiles.

mod common;

use common::wipdr;
use std::path::{Path, PathBuf};
use wipdr_core::{GeoFrame, PressureSample, Walk};
use wipdr_eval::pipeline::{self, EvalConfig, FloorInput};
use wipdr_eval::scoring::{TrackPoint, score_track_with_floors};

fn fixture_dir() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/sim/F1"))
}

/// The per-walk errors the evaluation reports for walk `id` of `floor` under `cfg`, for each
/// of `schemes`: the walk's fold prepared and run by the library, as `wipdr eval` does.
fn eval_errors(
    floor: &FloorInput,
    id: &str,
    schemes: &[String],
    cfg: &EvalConfig,
) -> Vec<Vec<(i64, f64, Option<i32>)>> {
    let index = floor
        .data
        .walks
        .iter()
        .position(|w| w.meta.id == id)
        .unwrap();
    let fold = wipdr_eval::fold_model::folds_of(floor)[index];
    let floors = std::slice::from_ref(floor);
    let prepared = pipeline::prepare_items(floors, cfg, &[(0, fold)]).unwrap();
    let report = pipeline::run_prepared(floors, &prepared, cfg, schemes, &|| {}).unwrap();
    schemes
        .iter()
        .map(|s| {
            report
                .walks
                .iter()
                .find(|w| w.walk == id && &w.scheme == s)
                .unwrap_or_else(|| panic!("{s} on {id}"))
                .score
                .errors
                .clone()
        })
        .collect()
}

/// A `wipdr locate` CSV (`t_ms,x,y,floor,sd_m`) scored at `walk`'s waypoints, the floor
/// estimate taken from the CSV's floor column.
fn score_csv(path: &Path, walk: &Walk) -> Vec<(i64, f64, Option<i32>)> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("t_ms,x,y,floor,sd_m"));
    let mut track = Vec::new();
    let mut floors: Vec<(i64, i32)> = Vec::new();
    for l in lines {
        let f: Vec<&str> = l.split(',').collect();
        let t: i64 = f[0].parse().unwrap();
        track.push(TrackPoint::new(
            t,
            wipdr_core::Point2::new(f[1].parse().unwrap(), f[2].parse().unwrap()),
        ));
        if let Ok(floor) = f[3].parse::<i32>()
            && floors.last().is_none_or(|&(_, last)| last != floor)
        {
            floors.push((t, floor));
        }
    }
    let from = walk.wifi.first().map(|s| s.t);
    score_track_with_floors(&walk.waypoints, &track, &floors, from).errors
}

/// Fits the fold of `walk_file`'s walk with `wipdr fit --leave-out-fold-of`, then locates the
/// walk with every scheme of `schemes` through `wipdr locate --model`, each in a new
/// process, and checks the errors equal the evaluation's.
fn check_fit_locate_equals_eval(data: &Path, walk_file: &Path, schemes: &[String], offline: bool) {
    let tmp = tempfile::tempdir().unwrap();
    let floor_data = wipdr_io::any::read_any_dir(
        data,
        &wipdr_io::cache::CacheSettings::disabled(),
        &Default::default(),
        &|| {},
    )
    .unwrap()
    .0;
    let floor = FloorInput::new("floor", floor_data.into_floor());
    let frame = floor.data.geo_frame;
    let walk = wipdr_positioning_walk(walk_file, frame.as_ref());
    let id = walk.meta.id.clone();
    let cfg = EvalConfig {
        offline,
        ..EvalConfig::default()
    };
    let expected = eval_errors(&floor, &id, schemes, &cfg);
    let model = tmp.path().join("site.wipdr");
    let data_arg = data.to_str().unwrap();
    wipdr(
        &[
            "--no-cache",
            "fit",
            "--data",
            data_arg,
            "--leave-out-fold-of",
            &id,
            // The leave-one-out errors change no estimate (checked below by
            // `inspect_plots_where_the_model_is_weak`); not measuring them keeps this fast.
            "--no-leave-one-out",
            "--out",
            model.to_str().unwrap(),
        ],
        tmp.path(),
    );
    for (scheme, expected) in schemes.iter().zip(expected) {
        let csv = tmp.path().join(format!("{scheme}.csv"));
        let mut args = vec![
            "locate",
            "--model",
            model.to_str().unwrap(),
            walk_file.to_str().unwrap(),
            "--scheme",
            scheme,
            "--format",
            "csv",
            "--out",
            csv.to_str().unwrap(),
        ];
        if offline {
            args.push("--offline");
        }
        wipdr(&args, tmp.path());
        let located = score_csv(&csv, &walk);
        assert!(!expected.is_empty(), "{scheme}: nothing scored");
        if let Some(k) = (0..located.len().min(expected.len())).find(|&k| located[k] != expected[k])
        {
            eprintln!(
                "{scheme}: first difference at {k}: located {:?} eval {:?} (lengths {} / {})",
                located[k],
                expected[k],
                located.len(),
                expected.len()
            );
        }
        assert_eq!(
            located, expected,
            "{scheme} (offline {offline}) on {id}: locate --model and eval differ"
        );
    }
}

/// The walk as `locate --model` reads it (logfiles in the model's frame).
fn wipdr_positioning_walk(path: &Path, frame: Option<&GeoFrame>) -> Walk {
    let limits = wipdr_io::Limits::default();
    if wipdr_io::logfile::is_logfile(path) {
        let log = wipdr_io::logfile::read_logfile(path, &limits).unwrap();
        return log
            .into_walk(frame.expect("a logfile folder has a frame"))
            .walk;
    }
    wipdr_io::trace::read_walk_with(path, &limits).unwrap().walk
}

fn all_schemes() -> Vec<String> {
    wipdr_fusion::scheme_names()
        .iter()
        .map(|s| s.to_string())
        .collect()
}

#[test]
fn fixture_floor_fit_save_load_locate_equals_eval_for_every_scheme() {
    let dir = fixture_dir();
    let walk_file = dir.join("path_data_files").join("sim_F1_w0000.txt.gz");
    check_fit_locate_equals_eval(&dir, &walk_file, &all_schemes(), false);
    check_fit_locate_equals_eval(&dir, &walk_file, &["ekf".into(), "pmf".into()], true);
}

/// The fixture walks as IPIN logfiles in `dir` (three routes, repetitions, a barometer).
fn write_logfiles(dir: &Path) -> Vec<PathBuf> {
    let floor = wipdr_io::read_floor_dir(fixture_dir(), &Default::default()).unwrap();
    let frame = GeoFrame::new(49.4611, 11.1102).unwrap();
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
        let path = dir.join(format!("SIM_Trial0{}_repetition0{}.txt", i % 3, i / 3 + 1));
        let mut file = std::fs::File::create(&path).unwrap();
        wipdr_io::logfile::write_logfile(&walk, &frame, 100, &mut file).unwrap();
        files.push(path);
    }
    files
}

#[test]
fn fixture_logfiles_fit_save_load_locate_equals_eval_for_every_scheme() {
    let tmp = tempfile::tempdir().unwrap();
    let files = write_logfiles(tmp.path());
    check_fit_locate_equals_eval(tmp.path(), &files[1], &all_schemes(), false);
}

#[test]
fn real_ilc_floor_and_ipin_logfile_fit_locate_equals_eval() {
    let (floor, trials) = match (
        wipdr_io::real_data("ilc20/site1/F1"),
        wipdr_io::real_data("ipin2023/trials"),
    ) {
        (Ok(floor), Ok(trials)) => (floor, trials),
        (Err(missing), _) | (_, Err(missing)) => {
            println!("skipped: {missing}");
            return;
        }
    };
    let mut walks: Vec<PathBuf> = std::fs::read_dir(floor.join("path_data_files"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    walks.sort();
    check_fit_locate_equals_eval(&floor, &walks[0], &all_schemes(), false);
    let mut logs: Vec<PathBuf> = std::fs::read_dir(&trials)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| wipdr_io::logfile::is_logfile(p))
        .collect();
    logs.sort();
    check_fit_locate_equals_eval(&trials, &logs[0], &all_schemes(), false);
}

#[test]
fn a_plain_stream_locates_as_the_trace_it_was_exported_from() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = fixture_dir();
    let model = tmp.path().join("f1.wipdr");
    let trace = dir.join("path_data_files").join("sim_F1_w0000.txt.gz");
    let stream = PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../fixtures/stream/sim_F1_w0000.csv.gz"
    ));
    let (m, t) = (model.to_str().unwrap(), tmp.path().join("out"));
    wipdr(
        &[
            "--no-cache",
            "fit",
            "--data",
            dir.to_str().unwrap(),
            "--out",
            m,
        ],
        tmp.path(),
    );
    // The committed fixture is the trace exported by `wipdr export-stream`.
    let exported = tmp.path().join("exported.csv.gz");
    wipdr(
        &[
            "export-stream",
            trace.to_str().unwrap(),
            "--out",
            exported.to_str().unwrap(),
        ],
        tmp.path(),
    );
    let text = |p: &Path| {
        let mut s = String::new();
        std::io::Read::read_to_string(
            &mut flate2::read::MultiGzDecoder::new(std::fs::File::open(p).unwrap()),
            &mut s,
        )
        .unwrap();
        s
    };
    assert_eq!(
        text(&exported),
        text(&stream),
        "fixtures/stream is stale: re-export it"
    );
    for scheme in ["ekf", "pmf"] {
        let a = tmp.path().join(format!("trace-{scheme}.csv"));
        let b = tmp.path().join(format!("stream-{scheme}.csv"));
        for (input, out) in [(&trace, &a), (&stream, &b)] {
            wipdr(
                &[
                    "locate",
                    "--model",
                    m,
                    input.to_str().unwrap(),
                    "--scheme",
                    scheme,
                    "--out",
                    out.to_str().unwrap(),
                ],
                tmp.path(),
            );
        }
        let (a, b) = (
            std::fs::read_to_string(a).unwrap(),
            std::fs::read_to_string(b).unwrap(),
        );
        assert!(a.lines().count() > 50, "{scheme}: {a}");
        assert_eq!(a, b, "{scheme}: the stream and the trace differ");
    }
    // Two inputs that would write one output file are refused before any work.
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_wipdr"))
        .args(["locate", "--model", m])
        .arg(&trace)
        .arg(&stream)
        .arg("--out")
        .arg(&t)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("different file names"), "{err}");
}

#[test]
fn locate_refuses_a_file_that_is_not_a_model() {
    let tmp = tempfile::tempdir().unwrap();
    let trace = fixture_dir()
        .join("path_data_files")
        .join("sim_F1_w0000.txt.gz");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_wipdr"))
        .args(["locate", "--model"])
        .arg(&trace)
        .arg(&trace)
        .arg("--out")
        .arg(tmp.path().join("t.csv"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("not a wipdr site model") && err.contains("gzip"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
}

/// The width and height a PNG file's header states (its IHDR chunk), after checking the
/// signature.
fn png_size(path: &Path) -> (u32, u32) {
    let bytes = std::fs::read(path).unwrap();
    assert!(
        bytes.len() > 24,
        "{} is too short for a PNG",
        path.display()
    );
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "not a PNG");
    assert_eq!(&bytes[12..16], b"IHDR");
    let be = |i: usize| u32::from_be_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]);
    (be(16), be(20))
}

/// `wipdr fit` saves the leave-one-walk-out Wi-Fi errors of the training scans (finite,
/// plausible for the fixture floor); `wipdr inspect --plot` prints the per-floor summary
/// and draws a PNG of the size it states; a model fit with `--no-leave-one-out` still
/// plots (distance and APs) and says why the error is missing.
#[test]
fn inspect_plots_where_the_model_is_weak() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = fixture_dir();
    let model = tmp.path().join("f1.wipdr");
    let m = model.to_str().unwrap();
    wipdr(
        &[
            "--no-cache",
            "fit",
            "--data",
            dir.to_str().unwrap(),
            "--out",
            m,
        ],
        tmp.path(),
    );
    let loaded = wipdr_positioning::SiteModel::load(&model).unwrap();
    let d = loaded.data();
    let loo = d.leave_one_out.as_ref().expect("wipdr fit measures them");
    assert_eq!(
        loo.walks + loo.skipped_walks,
        d.provenance.training_walks,
        "every training walk left out once"
    );
    assert_eq!(loo.skipped_walks, 0);
    assert_eq!(loo.points.len(), loo.scans, "no thinning on the fixture");
    assert!(loo.scans * 10 >= d.provenance.scans * 9, "{loo:?}");
    let mut errors: Vec<f64> = loo.points.iter().map(|p| p.error_m).collect();
    assert!(errors.iter().all(|e| e.is_finite() && *e >= 0.0));
    errors.sort_by(f64::total_cmp);
    // The fixture floor is 120 m x 80 m, walked by 10 walks over three routes: a scan is
    // located metres off by the other walks' map, never across the floor.
    let median = errors[errors.len() / 2];
    assert!(median > 0.1 && median < 15.0, "median {median} m");
    assert!(errors[errors.len() - 1] < 144.0, "{errors:?}");
    for p in &loo.points {
        assert!(
            (-1.0..=121.0).contains(&p.position.x) && (-1.0..=81.0).contains(&p.position.y),
            "{p:?}"
        );
    }

    let png = tmp.path().join("plots").join("coverage.png");
    let out = wipdr(&["inspect", m, "--plot", png.to_str().unwrap()], tmp.path());
    assert!(out.contains("Wi-Fi error median"), "{out}");
    assert!(out.contains("farther than 10 m"), "{out}");
    let stated = format!("wrote {}", png.display());
    let line = out
        .lines()
        .find(|l| l.contains(&stated))
        .unwrap_or_else(|| panic!("{out}"));
    let (w, h) = png_size(&png);
    assert!(line.ends_with(&format!("({w} x {h} px)")), "{line}");
    assert!(w >= 1000 && h >= 250, "{w} x {h}");

    // Without the leave-one-out errors: the other panels, and the summary says why.
    let bare = tmp.path().join("bare.wipdr");
    wipdr(
        &[
            "--no-cache",
            "fit",
            "--data",
            dir.to_str().unwrap(),
            "--no-leave-one-out",
            "--out",
            bare.to_str().unwrap(),
        ],
        tmp.path(),
    );
    let bare_model = wipdr_positioning::SiteModel::load(&bare).unwrap();
    assert!(bare_model.data().leave_one_out.is_none());
    // The errors change no estimate: the models differ only there (and in the fit time).
    let mut with = d.clone();
    with.leave_one_out = None;
    with.provenance.created_unix_s = bare_model.data().provenance.created_unix_s;
    with.provenance.sources = bare_model.data().provenance.sources.clone();
    assert_eq!(&with, bare_model.data());
    let png2 = tmp.path().join("bare.png");
    let out = wipdr(
        &[
            "inspect",
            bare.to_str().unwrap(),
            "--plot",
            png2.to_str().unwrap(),
        ],
        tmp.path(),
    );
    assert!(out.contains("no leave-one-walk-out errors"), "{out}");
    assert_eq!(png_size(&png2), (w, h));
}

//! `wipdr evaal` against the official EvAAL API server (revision 3.3, `../shared/tools/
//! evaalapi/`) on loopback: one IPIN logfile served as a trial (POSI lines removed), played
//! with a model fit on its route's other repetitions; the estimates the server recorded are
//! exactly the track of `wipdr locate --model` on the same lines at the same times, and
//! `wipdr score` scores them against the walk's POSI points.
//!
//! Needs a Python with the server's packages (flask, pyyaml, parse, markdown, pygments):
//! `WIPDR_EVAAL_PYTHON` names it (`.ci/run` makes a virtual environment); without it, or
//! without `../shared`, the test prints why and skips.

mod common;

use std::io::Read;
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};
use wipdr_core::GeoFrame;

/// The walk played, and the route's other repetitions the model is fit on.
const WALK: &str = "IPIN2023_T3_TrainingTrial21_repetition01";
const TRAINING: [&str; 3] = [
    "IPIN2023_T3_TrainingTrial21_repetition02",
    "IPIN2023_T3_TrainingTrial21_repetition03",
    "IPIN2023_T3_TrainingTrial21_repetition04",
];
const HORIZON: &str = "0.5";

/// Stops the server when the test ends, however it ends.
struct Server(Child);

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn shared() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared"))
}

/// The server's timestamp of a data line: its first numeric field (`get_line_timestamp`).
fn line_ts(line: &str) -> f64 {
    line.trim()
        .split(';')
        .find_map(|f| f.parse::<f64>().ok())
        .expect("a data line has a timestamp")
}

fn read_gz(path: &Path) -> String {
    let mut text = String::new();
    flate2::read::MultiGzDecoder::new(std::fs::File::open(path).unwrap())
        .read_to_string(&mut text)
        .unwrap();
    text
}

#[test]
fn a_trial_played_through_the_official_server_is_the_locate_track() {
    let Ok(python) = std::env::var("WIPDR_EVAAL_PYTHON") else {
        println!(
            "skipped: WIPDR_EVAAL_PYTHON is not set (a Python with flask pyyaml parse markdown pygments; .ci/run makes one)"
        );
        return;
    };
    let server_py = shared().join("tools/evaalapi/evaalapi.py");
    let trials = shared().join("data/ipin2023/trials");
    if !server_py.is_file() || !trials.is_dir() {
        println!(
            "skipped: {} or {} not found",
            server_py.display(),
            trials.display()
        );
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();

    // The trial: the logfile without its header (the server skips it anyway) and its POSI
    // lines; the POSI points are the ground truth.
    let log = read_gz(&trials.join(format!("{WALK}.txt.gz")));
    let data: Vec<&str> = log
        .lines()
        .filter(|l| !l.starts_with('%') && !l.trim().is_empty())
        .filter(|l| !l.starts_with("POSI"))
        .collect();
    let posi: Vec<Vec<&str>> = log
        .lines()
        .filter(|l| l.starts_with("POSI"))
        .map(|l| l.split(';').collect())
        .collect();
    assert!(posi.len() > 5, "{WALK} has POSI points");
    std::fs::create_dir_all(dir.join("trials")).unwrap();
    std::fs::write(dir.join("trials/t1.txt"), data.join("\n") + "\n").unwrap();
    let truth: String = posi
        .iter()
        .map(|p| format!("{},{},{},{},{}\n", p[1], p[4], p[3], p[5], p[2]))
        .collect();
    std::fs::write(dir.join("GT.csv"), &truth).unwrap();
    let inipos = format!("{},{},{}", posi[0][4], posi[0][3], posi[0][5]);
    std::fs::write(
        dir.join("evaalapi.yaml"),
        format!(
            "t1:\n    datafile: t1.txt\n    commsep: '%'\n    sepch: ';'\n    V: 1\n    S: 15\n    inipos: '{inipos}'\n    reloadable: True\n"
        ),
    )
    .unwrap();
    std::fs::copy(&server_py, dir.join("evaalapi.py")).unwrap();

    // The same lines as `wipdr locate` reads them: a header without phone or date (the trial
    // gives none), sensor lines on the AppTimestamp clock (as the client reads them).
    std::fs::create_dir_all(dir.join("locate")).unwrap();
    let app_clock: Vec<String> = data
        .iter()
        .map(|l| {
            let mut f: Vec<&str> = l.split(';').collect();
            if f.len() > 2 && ["ACCE", "GYRO", "MAGN", "AHRS", "PRES"].contains(&f[0]) {
                f[2] = f[1];
            }
            f.join(";")
        })
        .collect();
    std::fs::write(
        dir.join("locate/t1.txt"),
        format!("% {WALK}, POSI removed\n{}\n", app_clock.join("\n")),
    )
    .unwrap();

    // The model: the route's other repetitions.
    std::fs::create_dir_all(dir.join("train")).unwrap();
    for w in TRAINING {
        let name = format!("{w}.txt.gz");
        std::fs::copy(trials.join(&name), dir.join("train").join(&name)).unwrap();
    }
    let d = |p: &str| dir.join(p).to_str().unwrap().to_string();
    common::wipdr(&["fit", "--data", &d("train"), "--out", &d("m.wipdr")], dir);

    // The server on a free loopback port.
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let _server = Server(
        Command::new(&python)
            .arg("-c")
            .arg(format!(
                "import evaalapi; evaalapi.app.run(host='127.0.0.1', port={port})"
            ))
            .current_dir(dir)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("the server starts"),
    );
    let started = Instant::now();
    while TcpStream::connect(("127.0.0.1", port)).is_err() {
        assert!(
            started.elapsed() < Duration::from_secs(60),
            "the EvAAL server did not listen on port {port}"
        );
        std::thread::sleep(Duration::from_millis(100));
    }

    let server = format!("http://127.0.0.1:{port}/evaalapi");
    common::wipdr(
        &[
            "evaal",
            "--server",
            &server,
            "--trial",
            "t1",
            "--model",
            &d("m.wipdr"),
            "--scheme",
            "pmf",
            "--horizon",
            HORIZON,
            "--out",
            &d("posted.csv"),
        ],
        dir,
    );
    common::wipdr(
        &[
            "locate",
            "--model",
            &d("m.wipdr"),
            &d("locate/t1.txt"),
            "--scheme",
            "pmf",
            "--format",
            "csv",
            "--out",
            &d("track.csv"),
        ],
        dir,
    );

    // The server's estimates: a header, the announced initial position, then one per request
    // that posted one.
    let est = std::fs::read_to_string(dir.join("trials/t1.est")).expect("the trial finished");
    let recorded: Vec<(f64, String)> = est
        .lines()
        .skip(2)
        .map(|l| {
            let f: Vec<&str> = l.splitn(5, ',').collect();
            (f[0].parse().unwrap(), f[4].to_string())
        })
        .collect();
    // The locate track: t_ms, x, y, floor.
    let track_text = std::fs::read_to_string(dir.join("track.csv")).unwrap();
    let track: Vec<(i64, f64, f64, Option<i32>)> = track_text
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (
                f[0].parse().unwrap(),
                f[1].parse().unwrap(),
                f[2].parse().unwrap(),
                f[3].parse().ok(),
            )
        })
        .collect();
    let model = wipdr_positioning::SiteModel::load(dir.join("m.wipdr")).unwrap();
    let frame: GeoFrame = model.data().geo_frame.expect("IPIN models have a frame");

    // What the client posted: request number, the time of the step or fix the estimate is
    // from, the string; the server recorded exactly these, in order.
    let posted_text = std::fs::read_to_string(dir.join("posted.csv")).unwrap();
    let posted: Vec<(usize, i64, String)> = posted_text
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.splitn(3, ',').collect();
            (
                f[0].parse().unwrap(),
                f[1].parse().unwrap(),
                f[2].to_string(),
            )
        })
        .collect();
    assert!(posted.len() > 100, "{} estimates posted", posted.len());
    assert_eq!(
        recorded.iter().map(|r| &r.1).collect::<Vec<_>>(),
        posted.iter().map(|p| &p.2).collect::<Vec<_>>(),
        "the server recorded what the client posted"
    );
    // The server's clock: request n (from 1) is at trial time T = T_0 + (n - 1) h, summed as
    // the server sums it, and has received every line before T.
    let h: f64 = HORIZON.parse().unwrap();
    let mut trial_time = vec![line_ts(data[0])];
    for (n, (request, t_ms, text)) in posted.iter().enumerate() {
        while trial_time.len() < *request {
            let next = trial_time[trial_time.len() - 1] + h;
            trial_time.push(next);
        }
        let at = trial_time[request - 1];
        assert!(
            (recorded[n].0 - at).abs() < 1e-3,
            "request {request} recorded at {} s, sent at {at} s",
            recorded[n].0
        );
        // Causal: the estimate is from a sample before the trial time (times are the lines'
        // AppTimestamps rounded to the ms).
        assert!(
            (*t_ms as f64) <= at * 1000.0 + 0.5,
            "request {request}: estimate from {t_ms} ms after {at} s"
        );
        // The locate track's row of that step or fix, and no later row of a line surely
        // received before the trial time.
        let row = track
            .iter()
            .rev()
            .find(|r| r.0 == *t_ms)
            .unwrap_or_else(|| panic!("request {request}: no locate row at {t_ms} ms"));
        let (lat, lon) = frame.to_lat_lon(wipdr_core::Point2::new(row.1, row.2));
        let floor = row.3.map(|f| f.to_string()).unwrap_or_default();
        assert_eq!(
            text,
            &format!("{lon:.9},{lat:.9},{floor}"),
            "request {request} at {at} s"
        );
        let received = (at * 1000.0).round() as i64 - 1;
        let newest = track
            .iter()
            .rev()
            .find(|r| r.0 <= received)
            .map_or(i64::MIN, |r| r.0);
        assert!(
            newest <= *t_ms,
            "request {request}: locate has a row at {newest} ms, the client posted the one at {t_ms} ms"
        );
    }

    // Scored against the walk's POSI points by the organisers' rules.
    let scored = common::wipdr(
        &["score", "--truth", &d("GT.csv"), &d("trials/t1.est")],
        dir,
    );
    println!(
        "{WALK} played through the EvAAL API ({} estimates):\n{scored}",
        recorded.len()
    );
    let row = scored.lines().nth(1).expect("a score row");
    let evaal: f64 = row
        .split(':')
        .nth(1)
        .and_then(|r| r.split_whitespace().next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("an EvAAL figure in {row:?}"));
    assert!(evaal.is_finite() && evaal >= 0.0, "EvAAL {evaal}");
}

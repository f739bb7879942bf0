//! `wipdr serve` and `wipdr replay` as processes on loopback (port 0) with a real SQLite file:
//! a walk replayed through the server at several batch sizes gives exactly the track
//! `wipdr locate --model` gives (ekf and pmf); `kill -9` loses at most the last flush
//! interval and every stored track is readable after the restart; SIGTERM flushes and exits
//! cleanly; the live map renders the sessions in headless Chromium (skipped, with a printed
//! reason, when no Chromium is installed).

mod common;

use common::{chromium, wipdr};
use serde_json::{Value, json};
use std::io::{BufRead, BufReader, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::OnceLock;
use std::time::Duration;

const TOKEN: &str = "serve-cli-test-token-0123456789";

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn fixture_stream() -> PathBuf {
    root().join("fixtures/stream/sim_F1_w0000.csv.gz")
}

/// A model fit on the fixture floor, once per test binary (in a folder kept for the run).
fn model() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    let dir = DIR.get_or_init(|| {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("fixture.wipdr");
        wipdr(
            &[
                "fit",
                "--data",
                root().join("fixtures/sim/F1").to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ],
            d.path(),
        );
        std::fs::write(d.path().join("tokens"), format!("# test\n{TOKEN}\n")).unwrap();
        d
    });
    dir.path()
}

/// A running `wipdr serve`.
struct Serve {
    child: Child,
    url: String,
}

impl Serve {
    fn start(db: &Path, extra: &[&str]) -> Self {
        let dir = model();
        let mut child = Command::new(env!("CARGO_BIN_EXE_wipdr"))
            .args(["serve", "--model"])
            .arg(dir.join("fixture.wipdr"))
            .args(["--addr", "127.0.0.1:0", "--tokens"])
            .arg(dir.join("tokens"))
            .arg("--db")
            .arg(db)
            .args(["--max-samples-per-s", "1e9", "--flush-ms", "200"])
            .args(extra)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("wipdr serve starts");
        let mut lines = BufReader::new(child.stderr.take().unwrap()).lines();
        let url = loop {
            let line = lines
                .next()
                .expect("wipdr serve printed its address")
                .unwrap();
            if let Some(u) = line.strip_prefix("wipdr serve: listening on ") {
                break u.trim().to_string();
            }
        };
        // Keep draining stderr so the server never blocks on it; keep the lines for asserts.
        let log = std::sync::Arc::new(std::sync::Mutex::new(String::new()));
        let sink = log.clone();
        std::thread::spawn(move || {
            for l in lines.map_while(Result::ok) {
                sink.lock().unwrap().push_str(&l);
                sink.lock().unwrap().push('\n');
            }
        });
        Self { child, url }
    }

    fn addr(&self) -> &str {
        self.url.trim_start_matches("http://")
    }

    /// One HTTP/1.1 request (`Connection: close`): status and body.
    fn call(&self, method: &str, path: &str, body: Option<&Value>) -> (u16, String) {
        let mut s = std::net::TcpStream::connect(self.addr()).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
        let body = body.map(|b| b.to_string()).unwrap_or_default();
        write!(
            s,
            "{method} {path} HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {TOKEN}\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
            body.len()
        )
        .unwrap();
        let mut out = String::new();
        s.read_to_string(&mut out).unwrap();
        let status = out
            .split(' ')
            .nth(1)
            .and_then(|c| c.parse().ok())
            .unwrap_or(0);
        let body = out
            .split_once("\r\n\r\n")
            .map(|(_, b)| b.to_string())
            .unwrap_or_default();
        (status, body)
    }

    fn replay(&self, args: &[&str]) -> String {
        let tokens = model().join("tokens");
        let mut all = vec![
            "replay",
            "--server",
            &self.url,
            "--token-file",
            tokens.to_str().unwrap(),
        ];
        all.extend_from_slice(args);
        wipdr(&all, &root())
    }
}

impl Drop for Serve {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn signal(child: &Child, sig: &str) {
    let ok = Command::new("kill")
        .args([sig, &child.id().to_string()])
        .status()
        .expect("kill runs");
    assert!(ok.success());
}

#[test]
fn a_replayed_walk_gives_exactly_the_locate_track_at_any_batch_size() {
    let dir = tempfile::tempdir().unwrap();
    let server = Serve::start(&dir.path().join("t.sqlite"), &[]);
    let m = model().join("fixture.wipdr");
    for scheme in ["ekf", "pmf"] {
        for format in ["csv", "geojson"] {
            let reference = dir.path().join(format!("locate-{scheme}.{format}"));
            wipdr(
                &[
                    "locate",
                    "--model",
                    m.to_str().unwrap(),
                    fixture_stream().to_str().unwrap(),
                    "--scheme",
                    scheme,
                    "--format",
                    format,
                    "--out",
                    reference.to_str().unwrap(),
                ],
                dir.path(),
            );
            let want = std::fs::read_to_string(&reference).unwrap();
            let batches: &[&str] = if format == "csv" {
                &["1", "100", "1000", "1000000000"]
            } else {
                &["1000"]
            };
            for batch_ms in batches {
                let out = dir.path().join(format!("{scheme}-{format}-{batch_ms}"));
                server.replay(&[
                    "--speed",
                    "0",
                    "--batch-ms",
                    batch_ms,
                    "--scheme",
                    scheme,
                    "--format",
                    format,
                    "--out",
                    out.to_str().unwrap(),
                    fixture_stream().to_str().unwrap(),
                ]);
                let got =
                    std::fs::read_to_string(out.join(format!("sim_F1_w0000.{format}"))).unwrap();
                if format == "csv" {
                    assert!(want.lines().count() > 10, "the walk has a track");
                    assert_eq!(got, want, "{scheme}, batches of {batch_ms} ms");
                } else {
                    let a: Value = serde_json::from_str(&got).unwrap();
                    let b: Value = serde_json::from_str(&want).unwrap();
                    assert_eq!(a, b, "{scheme} geojson");
                }
            }
        }
    }
}

/// `replay --loop`: each phone replays walk after walk, a new session each, until
/// `--duration-s` of stream time; every sample sent is accepted, and the summary counts the
/// sessions. With `--phones 2` over one walk of L s (its last 1 s batch ending L s after its
/// first sample) and a duration of 2 L + 20 s: two whole walks and 20 s of a third a phone.
#[test]
fn looping_phones_replay_walk_after_walk_until_the_duration() {
    let dir = tempfile::tempdir().unwrap();
    let server = Serve::start(&dir.path().join("t.sqlite"), &[]);
    let run = |name: &str, extra: &[&str]| -> Value {
        let summary = dir.path().join(name);
        let mut args = vec![
            "--speed",
            "0",
            "--scheme",
            "ekf",
            "--phones",
            "2",
            "--json",
            summary.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let stream = fixture_stream();
        args.push(stream.to_str().unwrap());
        server.replay(&args);
        serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap()
    };
    let t: Vec<i64> = samples()
        .iter()
        .filter_map(|s| s["t_ms"].as_i64())
        .collect();
    let walk_s = (t[t.len() - 1] - t[0]).div_euclid(1000) + 1;
    let once = run("once.json", &[]);
    let first_20_s = run("twenty.json", &["--duration-s", "20"]);
    let duration = (2 * walk_s + 20).to_string();
    let looped = run("looped.json", &["--loop", "--duration-s", &duration]);
    assert_eq!(once["sessions"], 2);
    assert_eq!(looped["sessions"], 6);
    let count = |v: &Value, k: &str| v[k].as_u64().unwrap();
    for k in ["samples_sent", "batches"] {
        assert_eq!(
            count(&looped, k),
            2 * count(&once, k) + count(&first_20_s, k),
            "{k}"
        );
    }
    assert_eq!(looped["samples_sent"], looped["samples_accepted"]);
    assert!(
        count(&first_20_s, "samples_sent") > 0
            && count(&once, "samples_sent") > count(&first_20_s, "samples_sent") * 3
    );
}

/// The fixture walk's samples in stream order, as plain JSON samples (via the CSV writer's
/// format read back: the same walk `replay` sends).
fn samples() -> Vec<Value> {
    let walk =
        wipdr_io::sample_stream::read_sample_stream(fixture_stream(), &wipdr_io::Limits::default())
            .unwrap();
    wipdr_positioning::samples_of(&walk)
        .map(|s| match s {
            wipdr_positioning::Sample::Accelerometer(v) => json!({"t_ms": v.t, "sensor": "accelerometer", "x": v.v[0], "y": v.v[1], "z": v.v[2]}),
            wipdr_positioning::Sample::Gyroscope(v) => json!({"t_ms": v.t, "sensor": "gyroscope", "x": v.v[0], "y": v.v[1], "z": v.v[2]}),
            wipdr_positioning::Sample::Magnetometer(v) => json!({"t_ms": v.t, "sensor": "magnetometer", "x": v.v[0], "y": v.v[1], "z": v.v[2]}),
            wipdr_positioning::Sample::RotationVector(v) => json!({"t_ms": v.t, "sensor": "rotation_vector", "x": v.v[0], "y": v.v[1], "z": v.v[2]}),
            wipdr_positioning::Sample::Pressure(p) => json!({"t_ms": p.t, "sensor": "pressure", "hpa": p.hpa}),
            wipdr_positioning::Sample::Wifi(w) => json!({"t_ms": w.t, "sensor": "wifi", "aps": w.entries.iter().map(|e| json!({"bssid": e.bssid.to_string(), "rssi_dbm": e.rssi_dbm, "last_seen_ms": e.last_seen_ms})).collect::<Vec<_>>()}),
        })
        .collect()
}

fn open(server: &Serve, device: &str) -> String {
    let (s, body) = server.call(
        "POST",
        "/v1/sessions",
        Some(&json!({"scheme": "ekf", "device": device})),
    );
    assert_eq!(s, 201, "{body}");
    serde_json::from_str::<Value>(&body).unwrap()["id"]
        .as_str()
        .unwrap()
        .to_string()
}

fn post(server: &Serve, id: &str, batch: &[Value]) -> Vec<Value> {
    let (s, body) = server.call(
        "POST",
        &format!("/v1/sessions/{id}/samples"),
        Some(&json!({ "samples": batch })),
    );
    assert_eq!(s, 200, "{body}");
    serde_json::from_str::<Value>(&body).unwrap()["estimates"]
        .as_array()
        .unwrap()
        .clone()
}

fn track(server: &Serve, id: &str) -> Vec<Value> {
    let (s, body) = server.call("GET", &format!("/v1/sessions/{id}/track?format=json"), None);
    assert_eq!(s, 200, "{body}");
    serde_json::from_str::<Value>(&body).unwrap()["estimates"]
        .as_array()
        .unwrap()
        .clone()
}

#[test]
fn kill_9_loses_at_most_the_last_flush_interval_and_sigterm_loses_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("tracks.sqlite");
    let samples = samples();
    let (first, second) = samples.split_at(samples.len() / 2);

    // kill -9: what was answered more than a flush interval (200 ms) before is kept.
    let mut server = Serve::start(&db, &[]);
    let id = open(&server, "killed phone");
    let early = post(&server, &id, first);
    assert!(!early.is_empty());
    // Several flush intervals pass (the flush runs every 200 ms).
    std::thread::sleep(Duration::from_millis(1500));
    let late = post(&server, &id, second);
    server.child.kill().unwrap(); // SIGKILL
    server.child.wait().unwrap();
    let server = Serve::start(&db, &[]);
    let stored = track(&server, &id);
    assert!(
        stored.len() >= early.len(),
        "{} stored, {} answered before the last flush interval",
        stored.len(),
        early.len()
    );
    let all: Vec<Value> = early.iter().chain(&late).cloned().collect();
    assert_eq!(
        stored[..],
        all[..stored.len()],
        "what is stored is what was answered"
    );
    let (_, meta) = server.call("GET", &format!("/v1/sessions/{id}"), None);
    let meta: Value = serde_json::from_str(&meta).unwrap();
    assert_eq!(meta["close_reason"], "restart");
    drop(server);

    // SIGTERM: everything answered is stored, the process exits 0.
    let mut server = Serve::start(&db, &[]);
    let id2 = open(&server, "terminated phone");
    let mut answered = post(&server, &id2, first);
    answered.extend(post(&server, &id2, second));
    signal(&server.child, "-TERM");
    let status = server.child.wait().unwrap();
    assert!(status.success(), "{status}");
    let server = Serve::start(&db, &[]);
    assert_eq!(track(&server, &id2), answered);
    let (_, meta) = server.call("GET", &format!("/v1/sessions/{id2}"), None);
    assert_eq!(
        serde_json::from_str::<Value>(&meta).unwrap()["close_reason"],
        "shutdown"
    );
    // The killed run's track is still readable too.
    assert_eq!(track(&server, &id), stored);
}

#[test]
fn the_live_map_shows_the_replayed_phones_in_chromium() {
    let Some(browser) = chromium() else {
        eprintln!(
            "skipped: no chromium on PATH (nor $WIPDR_CHROMIUM); `apt-get install chromium` brings it"
        );
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let server = Serve::start(&dir.path().join("t.sqlite"), &[]);
    // A phone whose label is markup: it must show as text.
    let evil = "<img src=x onerror=\"document.title='owned'\">";
    let id = open(&server, evil);
    post(&server, &id, &samples()[..3000]);
    // A phone replayed to the end and left open, and one streaming live while the page is open.
    server.replay(&[
        "--speed",
        "0",
        "--keep-open",
        "--scheme",
        "ekf",
        fixture_stream().to_str().unwrap(),
    ]);
    let live = Command::new(env!("CARGO_BIN_EXE_wipdr"))
        .args(["replay", "--server", &server.url, "--token-file"])
        .arg(model().join("tokens"))
        .args([
            // Nine walks one after the other at 20x real time: estimates keep coming for
            // about 40 s, while the page is open, however long the browser takes to start.
            "--speed",
            "20",
            "--concurrency",
            "1",
            "--batch-ms",
            "500",
            "--scheme",
            "pmf",
            "--keep-open",
        ])
        .args((1..10).map(|i| {
            root().join(format!(
                "fixtures/sim/F1/path_data_files/sim_F1_w{i:04}.txt.gz"
            ))
        }))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // The page lists the sessions open when it loads, and its live stream starts with each
    // one's latest estimate: wait (bounded) until the live phone's session is open and has
    // one, so the page's event count does not hang on when the next batch lands in the few
    // real seconds a headless page with a virtual-time budget lives.
    for _ in 0..240 {
        let (_, body) = server.call("GET", "/v1/sessions", None);
        let sessions: Value = serde_json::from_str(&body).unwrap_or(Value::Null);
        let live_has_estimates = sessions["sessions"].as_array().is_some_and(|list| {
            list.iter().any(|s| {
                s["device"]
                    .as_str()
                    .is_some_and(|d| d.contains("sim_F1_w0001"))
                    && s["recent"].as_array().is_some_and(|r| !r.is_empty())
            })
        });
        if live_has_estimates {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(250));
    }
    let profile = tempfile::tempdir().unwrap();
    let out = Command::new(&browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--enable-logging=stderr",
            "--v=0",
            // The page's script runs for 5 s of virtual time; the timeout bounds the run should
            // the open event stream hold virtual time back.
            "--virtual-time-budget=5000",
            "--timeout=20000",
        ])
        .arg(format!("--user-data-dir={}", profile.path().display()))
        .arg("--dump-dom")
        .arg(format!("{}/#token={TOKEN}", server.url))
        .output()
        .expect("chromium runs");
    let mut live = live;
    let _ = live.kill();
    let _ = live.wait();
    let dom = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let items = dom.matches("data-session=").count();
    assert!(items >= 3, "three sessions listed, got {items}:\n{dom}");
    assert!(dom.contains("sim_F1_w0000"), "{dom}");
    assert!(
        dom.contains("sim_F1_w0001"),
        "the live phone is listed: {dom}"
    );
    // The markup label is text: escaped in the DOM, no <img> element, no script ran.
    assert!(dom.contains("&lt;img src=x onerror="), "{dom}");
    assert!(!dom.contains("<img"), "{dom}");
    assert!(
        dom.contains("<title>wipdr live map</title>"),
        "no script of the label ran: {dom}"
    );
    assert!(
        dom.contains("data-status=\"live\""),
        "the page follows the live stream: {dom}"
    );
    let events: usize = dom
        .split("data-events=\"")
        .nth(1)
        .and_then(|r| r.split('"').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or(0);
    assert!(events > 0, "live estimates arrived: {dom}");
    assert!(dom.contains("95 % radius"), "{dom}");
}

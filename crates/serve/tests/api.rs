//! API v1 over real sockets (loopback, port 0) with a real SQLite file: a session's life,
//! the security rules of issue 41 (401, 404 for another token's session, 413, 429, 400 for
//! garbage, the sessions cap, idle expiry) each leaving the other sessions' tracks intact, the
//! restart, the live stream, the metrics and the OpenAPI document.

mod common;

use common::{A, B, Http, fixture_samples, read_stream_to_end, read_stream_until, start};
use hyper::{Method, StatusCode};
use serde_json::{Value, json};
use std::io::{Read, Write};
use std::time::Duration;
use wipdr_serve::ServeConfig;

fn fast_config() -> ServeConfig {
    ServeConfig {
        max_samples_per_s: 1e9,
        flush_interval: Duration::from_millis(200),
        ..ServeConfig::default()
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_session_streams_estimates_and_its_track_survives_a_restart() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("tracks.sqlite");
    let samples = fixture_samples();
    let server = start(&db, fast_config()).await;
    let http = Http::new(server.addr);
    let id = http.open(A, "ekf", "Pixel <7> & \"friends\"").await;
    let mut made = Vec::new();
    for chunk in samples.chunks(2000) {
        let (s, v) = http.post(A, &id, chunk).await;
        assert_eq!(s, StatusCode::OK, "{v}");
        assert_eq!(v["accepted"].as_u64().unwrap() as usize, chunk.len());
        made.extend(v["estimates"].as_array().unwrap().iter().cloned());
        if let Some(last) = made.last() {
            assert_eq!(&v["estimate"], last);
        }
    }
    assert!(made.len() > 10, "the walk makes estimates: {}", made.len());
    let (s, v) = http
        .json(Method::GET, &format!("/v1/sessions/{id}"), Some(A), None)
        .await;
    assert_eq!(s, StatusCode::OK);
    assert_eq!(v["state"], "open");
    assert_eq!(v["device"], "Pixel <7> & \"friends\"");
    assert_eq!(v["samples"].as_u64().unwrap() as usize, samples.len());
    assert_eq!(&v["estimate"], made.last().unwrap());
    // The stored track is what the batches answered.
    assert_eq!(http.track(A, &id).await, Value::Array(made.clone()));
    let (s, body) = http
        .raw(
            Method::GET,
            &format!("/v1/sessions/{id}/track?format=geojson"),
            Some(A),
            vec![],
        )
        .await;
    assert_eq!(s, StatusCode::OK);
    let g: Value = serde_json::from_slice(&body).unwrap();
    assert_eq!(
        g["geometry"]["coordinates"].as_array().unwrap().len(),
        made.len()
    );
    let (s, v) = http
        .json(
            Method::GET,
            &format!("/v1/sessions/{id}/track?format=ipin"),
            Some(A),
            None,
        )
        .await;
    assert_eq!(
        (s, v["error"]["code"].as_str()),
        (StatusCode::CONFLICT, Some("format_unavailable"))
    );
    // An open session when the server stops is closed and flushed (as on SIGTERM).
    server.shutdown().await;
    let server = start(&db, fast_config()).await;
    let http = Http::new(server.addr);
    assert_eq!(http.track(A, &id).await, Value::Array(made.clone()));
    let (_, v) = http
        .json(Method::GET, &format!("/v1/sessions/{id}"), Some(A), None)
        .await;
    assert_eq!(
        (v["state"].as_str(), v["close_reason"].as_str()),
        (Some("closed"), Some("shutdown"))
    );
    let (s, v) = http.post(A, &id, &samples[..1]).await;
    assert_eq!(
        (s, v["error"]["code"].as_str()),
        (StatusCode::CONFLICT, Some("session_closed"))
    );
    // Another token sees nothing of it, after the restart too.
    let (s, _) = http
        .json(
            Method::GET,
            &format!("/v1/sessions/{id}/track"),
            Some(B),
            None,
        )
        .await;
    assert_eq!(s, StatusCode::NOT_FOUND);
    server.shutdown().await;
}

/// A raw request over a socket: headers claiming `len` bytes, then the body written as long
/// as the server reads; returns the status line.
fn raw_post(addr: std::net::SocketAddr, path: &str, token: &str, len: usize) -> String {
    let mut s = std::net::TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    write!(
        s,
        "POST {path} HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {token}\r\nContent-Type: application/json\r\nContent-Length: {len}\r\n\r\n"
    )
    .unwrap();
    let chunk = vec![b' '; 1 << 16];
    let mut sent = 0;
    while sent < len {
        match s.write(&chunk[..chunk.len().min(len - sent)]) {
            Ok(n) => sent += n,
            Err(_) => break, // the server answered and closed: fine
        }
    }
    let mut out = Vec::new();
    let _ = s.read_to_end(&mut out);
    String::from_utf8_lossy(&out)
        .lines()
        .next()
        .unwrap_or("")
        .to_string()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn security_refusals_are_typed_and_leave_other_sessions_intact() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("tracks.sqlite");
    let samples = fixture_samples();
    let config = ServeConfig {
        max_samples_per_s: 200.0,
        burst_s: 10.0,
        max_sessions_per_token: 3,
        flush_interval: Duration::from_millis(200),
        ..ServeConfig::default()
    };
    let server = start(&db, config).await;
    let http = Http::new(server.addr);
    // The bystander: B's session with a track.
    let other = http.open(B, "pmf", "bystander").await;
    let (s, _) = http.post(B, &other, &samples[..1500]).await;
    assert_eq!(s, StatusCode::OK);
    let before = http.track(B, &other).await;
    assert!(!before.as_array().unwrap().is_empty());

    let mine = http.open(A, "pmf", "attacker").await;
    let code = |v: &Value| v["error"]["code"].as_str().unwrap_or("").to_string();
    // No token, a wrong token: 401.
    for token in [None, Some("not-a-token-0123456789")] {
        let (s, v) = http
            .json(Method::GET, &format!("/v1/sessions/{other}"), token, None)
            .await;
        assert_eq!(
            (s, code(&v)),
            (StatusCode::UNAUTHORIZED, "unauthorized".into())
        );
        let (s, _) = http
            .json(
                Method::POST,
                "/v1/sessions",
                token,
                Some(&json!({"device": "x"})),
            )
            .await;
        assert_eq!(s, StatusCode::UNAUTHORIZED);
    }
    // Another token's session: 404 on every route, as for none.
    for (method, path) in [
        (Method::GET, format!("/v1/sessions/{other}")),
        (Method::GET, format!("/v1/sessions/{other}/track")),
        (Method::GET, format!("/v1/sessions/{other}/events")),
        (Method::DELETE, format!("/v1/sessions/{other}")),
        (Method::POST, format!("/v1/sessions/{other}/samples")),
        (Method::GET, "/v1/sessions/no-such-session".to_string()),
    ] {
        let body = (method == Method::POST).then(|| json!({"samples": []}));
        let (s, v) = http
            .json(method.clone(), &path, Some(A), body.as_ref())
            .await;
        assert_eq!(
            (s, code(&v)),
            (StatusCode::NOT_FOUND, "session_not_found".into()),
            "{method} {path}"
        );
    }
    // 20 MB: 413, declared or not.
    let status = tokio::task::spawn_blocking({
        let addr = server.addr;
        let path = format!("/v1/sessions/{mine}/samples");
        move || raw_post(addr, &path, A, 20 << 20)
    })
    .await
    .unwrap();
    assert!(status.contains("413"), "{status}");
    // Garbage bodies: 400, typed.
    let garbage: Vec<(Vec<u8>, &str)> = vec![
        (b"".to_vec(), "malformed_body"),
        (b"{".to_vec(), "malformed_body"),
        (b"\xff\xfe".to_vec(), "malformed_body"),
        (b"[1,2,3]".to_vec(), "malformed_body"),
        (br#"{"samples": [{"t_ms": 1, "sensor": "teleport"}]}"#.to_vec(), "malformed_body"),
        (br#"{"samples": [], "extra": 1}"#.to_vec(), "malformed_body"),
        (br#"{"samples": [{"t_ms": 1, "sensor": "accelerometer", "x": 1e999, "y": 0, "z": 0}]}"#.to_vec(), "malformed_body"),
        (br#"{"samples": [{"t_ms": 1, "sensor": "pressure", "hpa": 1000}, {"t_ms": 0, "sensor": "pressure", "hpa": 1000}]}"#.to_vec(), "out_of_order"),
        (br#"{"samples": [{"t_ms": 99999999999999999, "sensor": "pressure", "hpa": 1000}]}"#.to_vec(), "invalid_sample"),
        (br#"{"samples": [{"t_ms": 1, "sensor": "wifi", "aps": [{"bssid": "zz", "rssi_dbm": -50}]}]}"#.to_vec(), "invalid_sample"),
        (br#"{"samples": [{"t_ms": 1, "sensor": "wifi", "aps": [{"bssid": "aa:bb:cc:dd:ee:ff", "rssi_dbm": 900}]}]}"#.to_vec(), "invalid_sample"),
        (br#"{"samples": [{"sensor": "meta", "phone_model": "x"}]}"#.to_vec(), "invalid_sample"),
        (format!("{}{}", "[".repeat(10000), "]".repeat(10000)).into_bytes(), "malformed_body"),
    ];
    for (body, want) in garbage {
        let (s, b) = http
            .raw(
                Method::POST,
                &format!("/v1/sessions/{mine}/samples"),
                Some(A),
                body.clone(),
            )
            .await;
        let v: Value = serde_json::from_slice(&b).unwrap_or(Value::Null);
        assert_eq!(
            (s, code(&v)),
            (StatusCode::BAD_REQUEST, want.to_string()),
            "{}",
            String::from_utf8_lossy(&body[..body.len().min(80)])
        );
    }
    // The refused batches changed nothing: the session still takes the stream from its start.
    let (s, v) = http.post(A, &mine, &samples[..100]).await;
    assert_eq!(s, StatusCode::OK, "{v}");
    // Out of order against what the session has: 400, nothing applied.
    let (s, v) = http.post(A, &mine, &samples[..1]).await;
    assert_eq!(
        (s, code(&v)),
        (StatusCode::BAD_REQUEST, "out_of_order".into())
    );
    // 10x the allowed rate (200 a second, bucket 2000): 2000 samples a second -> 429 from the
    // second second's batch (the bucket has 100 left and refills 200 a second).
    let (s, v) = http.post(A, &mine, &samples[100..1900]).await;
    assert_eq!(s, StatusCode::OK, "{v}");
    let (s, v) = http.post(A, &mine, &samples[1900..3900]).await;
    assert_eq!(
        (s, code(&v)),
        (StatusCode::TOO_MANY_REQUESTS, "rate_limited".into())
    );
    // What the budget holds still goes in, in stream order after the refused batch.
    let (s, v) = http.post(A, &mine, &samples[1900..2000]).await;
    assert_eq!(s, StatusCode::OK, "{v}");
    // Bad session requests.
    for body in [
        json!({"device": "x", "scheme": "warp"}),
        json!({"device": "x", "scheme": "pdr"}),
        json!({"device": "a\u{0}b"}),
        json!({"device": "x".repeat(500)}),
        json!({"device": "x", "color": 1}),
    ] {
        let (s, v) = http
            .json(Method::POST, "/v1/sessions", Some(A), Some(&body))
            .await;
        assert_eq!(s, StatusCode::BAD_REQUEST, "{body}: {v}");
    }
    // The sessions cap (3 a token): 429.
    http.open(A, "ekf", "second").await;
    http.open(A, "ekf", "third").await;
    let (s, v) = http
        .json(
            Method::POST,
            "/v1/sessions",
            Some(A),
            Some(&json!({"device": "fourth"})),
        )
        .await;
    assert_eq!(
        (s, code(&v)),
        (StatusCode::TOO_MANY_REQUESTS, "too_many_sessions".into())
    );
    // Unknown route: typed 404.
    let (s, v) = http.json(Method::GET, "/v2/anything", Some(A), None).await;
    assert_eq!(
        (s, code(&v)),
        (StatusCode::NOT_FOUND, "route_not_found".into())
    );
    // The bystander's track is exactly what it was, and it still takes its stream.
    assert_eq!(http.track(B, &other).await, before);
    let (s, _) = http.post(B, &other, &samples[1500..1600]).await;
    assert_eq!(s, StatusCode::OK);
    // Every refusal was counted by reason.
    let (s, m) = http.raw(Method::GET, "/metrics", None, vec![]).await;
    assert_eq!(s, StatusCode::OK);
    let m = String::from_utf8_lossy(&m);
    for reason in [
        "unauthorized",
        "session_not_found",
        "body_too_large",
        "malformed_body",
        "out_of_order",
        "rate_limited",
        "too_many_sessions",
        "invalid_sample",
    ] {
        assert!(
            m.contains(&format!(
                "wipdr_serve_rejected_requests_total{{reason=\"{reason}\"}}"
            )),
            "{reason} in\n{m}"
        );
    }
    assert!(m.contains("wipdr_serve_sessions_open 4"), "{m}");
    assert!(m.contains("wipdr_serve_request_duration_seconds_bucket{method=\"POST\",route=\"/v1/sessions/{id}/samples\""), "{m}");
    server.shutdown().await;
}

/// `max_opens_per_s`: opens past the server's rate get 429 `too_many_opens` with the wait,
/// whatever the token; the open sessions keep streaming; a second later an open succeeds.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn opens_past_the_servers_rate_wait_and_leave_the_open_sessions_alone() {
    let dir = tempfile::tempdir().unwrap();
    let samples = fixture_samples();
    let config = ServeConfig {
        max_opens_per_s: Some(2.0),
        ..fast_config()
    };
    let server = start(&dir.path().join("tracks.sqlite"), config).await;
    let http = Http::new(server.addr);
    // The bucket holds one second's opens: two.
    let first = http.open(A, "ekf", "first").await;
    let _second = http.open(B, "ekf", "second").await;
    for token in [A, B] {
        let (s, v) = http
            .json(
                Method::POST,
                "/v1/sessions",
                Some(token),
                Some(&json!({"scheme": "ekf", "device": "third"})),
            )
            .await;
        assert_eq!(s, StatusCode::TOO_MANY_REQUESTS, "{v}");
        assert_eq!(v["error"]["code"], "too_many_opens", "{v}");
        let message = v["error"]["message"].as_str().unwrap_or("");
        assert!(message.ends_with("retry in 1 s"), "{message}");
    }
    let (s, v) = http.post(A, &first, &samples[..500]).await;
    assert_eq!(s, StatusCode::OK, "{v}");
    assert_eq!(v["accepted"], 500);
    tokio::time::sleep(Duration::from_millis(1100)).await;
    let later = http.open(A, "ekf", "later").await;
    assert_ne!(later, first);
    let (s, m) = http.raw(Method::GET, "/metrics", None, Vec::new()).await;
    assert_eq!(s, StatusCode::OK);
    let m = String::from_utf8_lossy(&m);
    assert!(m.contains("too_many_opens"), "{m}");
    server.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn idle_sessions_are_closed_and_keep_their_track() {
    let dir = tempfile::tempdir().unwrap();
    let config = ServeConfig {
        max_samples_per_s: 1e9,
        idle_timeout: Duration::from_millis(300),
        flush_interval: Duration::from_millis(100),
        ..ServeConfig::default()
    };
    let server = start(&dir.path().join("t.sqlite"), config).await;
    let http = Http::new(server.addr);
    let samples = fixture_samples();
    let id = http.open(A, "ekf", "idle phone").await;
    let (s, _) = http.post(A, &id, &samples[..3000]).await;
    assert_eq!(s, StatusCode::OK);
    let track = http.track(A, &id).await;
    // The reaper runs every second: wait for its verdict (bounded), not for a duration.
    let mut state = Value::Null;
    for _ in 0..100 {
        tokio::time::sleep(Duration::from_millis(100)).await;
        let (_, v) = http
            .json(Method::GET, &format!("/v1/sessions/{id}"), Some(A), None)
            .await;
        state = v;
        if state["state"] == "closed" {
            break;
        }
    }
    assert_eq!(
        (state["state"].as_str(), state["close_reason"].as_str()),
        (Some("closed"), Some("idle"))
    );
    assert_eq!(http.track(A, &id).await, track);
    server.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_live_stream_carries_a_sessions_estimates_to_its_owner_only() {
    let dir = tempfile::tempdir().unwrap();
    let server = start(&dir.path().join("t.sqlite"), fast_config()).await;
    let http = Http::new(server.addr);
    let samples = fixture_samples();
    let id = http.open(A, "ekf", "live phone").await;
    // Subscribe (A's live stream, and the session's own) before posting.
    let live_a = http.stream("/v1/live", A).await;
    let events = http.stream(&format!("/v1/sessions/{id}/events"), A).await;
    let live_b = http.stream("/v1/live", B).await;
    assert_eq!(live_a.status(), StatusCode::OK);
    assert_eq!(events.status(), StatusCode::OK);
    assert_eq!(live_a.headers()["content-type"], "text/event-stream");
    let (s, v) = http.post(A, &id, &samples[..4000]).await;
    assert_eq!(s, StatusCode::OK);
    let latest = v["estimate"].clone();
    assert!(latest.is_object());
    let (s, _) = http
        .json(Method::DELETE, &format!("/v1/sessions/{id}"), Some(A), None)
        .await;
    assert_eq!(s, StatusCode::OK);
    for resp in [live_a, events] {
        let text = read_stream_until(resp, |t| t.contains("event: closed")).await;
        let estimate = text
            .split("\n\n")
            .find(|b| b.contains("event: estimate"))
            .and_then(|b| b.lines().find_map(|l| l.strip_prefix("data: ")))
            .map(|d| serde_json::from_str::<Value>(d).unwrap())
            .expect("an estimate event");
        assert_eq!(estimate["session"], id.as_str());
        assert_eq!(estimate["device"], "live phone");
        assert_eq!(estimate["estimate"]["x"], latest["x"]);
        assert!(text.contains("event: closed"), "{text}");
    }
    // B's stream got nothing of A's session: stop the server, which ends the stream.
    server.shutdown().await;
    let text = read_stream_to_end(live_b).await;
    assert!(!text.contains(&id), "{text}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_live_stream_opened_mid_walk_starts_with_each_open_sessions_latest_estimate() {
    let dir = tempfile::tempdir().unwrap();
    let server = start(&dir.path().join("t.sqlite"), fast_config()).await;
    let http = Http::new(server.addr);
    let samples = fixture_samples();
    let id = http.open(A, "ekf", "walking phone").await;
    let quiet = http.open(A, "ekf", "no estimate yet").await;
    // Estimates first, the map opened after.
    let (s, v) = http.post(A, &id, &samples[..4000]).await;
    assert_eq!(s, StatusCode::OK);
    let latest = v["estimate"].clone();
    assert!(latest.is_object(), "{v}");
    let live_a = http.stream("/v1/live", A).await;
    let live_b = http.stream("/v1/live", B).await;
    // The first event A's map reads is the walking phone where it is now, before any new
    // batch; the session without an estimate sends nothing.
    let text = read_stream_until(live_a, |t| t.contains("\n\n")).await;
    let first = text.split("\n\n").next().unwrap();
    assert!(first.contains("event: estimate"), "{text:?}");
    let data: Value = serde_json::from_str(
        first
            .lines()
            .find_map(|l| l.strip_prefix("data: "))
            .expect("a data line"),
    )
    .unwrap();
    assert_eq!(data["session"], id.as_str());
    assert_eq!(data["device"], "walking phone");
    assert_eq!(data["estimate"]["x"], latest["x"]);
    assert_eq!(data["estimate"]["y"], latest["y"]);
    assert!(!text.contains(&quiet), "{text}");
    // B's map gets no snapshot of A's phones.
    server.shutdown().await;
    let text_b = read_stream_to_end(live_b).await;
    assert!(!text_b.contains(&id), "{text_b}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn health_openapi_plan_and_page_are_served() {
    let dir = tempfile::tempdir().unwrap();
    let server = start(&dir.path().join("t.sqlite"), fast_config()).await;
    let http = Http::new(server.addr);
    let (s, b) = http.raw(Method::GET, "/healthz", None, vec![]).await;
    assert_eq!((s, &b[..]), (StatusCode::OK, &b"ok\n"[..]));
    let (s, doc) = http.json(Method::GET, "/v1/openapi.json", None, None).await;
    assert_eq!(s, StatusCode::OK);
    assert_eq!(doc["openapi"], "3.1.0");
    let (s, plan) = http.json(Method::GET, "/v1/plan", Some(A), None).await;
    assert_eq!(s, StatusCode::OK);
    assert!(plan["plan"]["width"].as_f64().unwrap() > 0.0);
    let (s, _) = http.json(Method::GET, "/v1/plan", None, None).await;
    assert_eq!(s, StatusCode::UNAUTHORIZED);
    let (s, page) = http.raw(Method::GET, "/", None, vec![]).await;
    assert_eq!(s, StatusCode::OK);
    assert!(String::from_utf8_lossy(&page).contains("<script src=\"/map.js\">"));
    server.shutdown().await;
}

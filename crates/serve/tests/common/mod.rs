//! Helpers of the serve crate's tests: a small site model fit on the fixture floor (once per
//! test binary), a server on a loopback port 0 with a temporary SQLite file, and a plain HTTP
//! client.
#![allow(dead_code)]

use http_body_util::{BodyExt, Full};
use hyper::body::Bytes;
use hyper::{Method, Request, StatusCode};
use hyper_util::client::legacy::Client;
use hyper_util::client::legacy::connect::HttpConnector;
use hyper_util::rt::TokioExecutor;
use serde_json::Value;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use wipdr_positioning::{SiteModel, TrainingData};
use wipdr_serve::auth::Tokens;
use wipdr_serve::{ServeConfig, Server};

/// Token A.
pub const A: &str = "token-a-0123456789abcdef";
/// Token B.
pub const B: &str = "token-b-0123456789abcdef";

/// The workspace root.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// A site model fit on the fixture floor `fixtures/sim/F1` (every walk), once.
pub fn model() -> SiteModel {
    static MODEL: OnceLock<SiteModel> = OnceLock::new();
    MODEL
        .get_or_init(|| {
            let floor = wipdr_io::floor::read_floor_dir(
                root().join("fixtures/sim/F1"),
                &wipdr_io::floor::ReadOptions::default(),
            )
            .expect("the fixture floor");
            let walks: Vec<&wipdr_core::Walk> = floor
                .walks
                .iter()
                .map(|w| &w.walk)
                .filter(|w| !w.waypoints.is_empty())
                .collect();
            let cfg = wipdr_eval::config::EvalConfig::default().site_config();
            SiteModel::fit(
                &TrainingData {
                    name: "fixture F1",
                    walks: &walks,
                    survey: None,
                    plan: Some(&floor.plan),
                    geo_frame: None,
                },
                &cfg,
            )
            .expect("a model")
        })
        .clone()
}

/// The fixture stream's samples as plain samples, in stream order.
pub fn fixture_samples() -> Vec<Value> {
    let walk = wipdr_io::sample_stream::read_sample_stream(
        root().join("fixtures/stream/sim_F1_w0000.csv.gz"),
        &wipdr_io::Limits::default(),
    )
    .expect("the fixture stream");
    wipdr_positioning::samples_of(&walk)
        .map(|s| plain(&s))
        .collect()
}

/// A sample as the plain stream's JSON.
pub fn plain(s: &wipdr_positioning::Sample) -> Value {
    use serde_json::json;
    use wipdr_positioning::Sample;
    match s {
        Sample::Accelerometer(v) => {
            json!({"t_ms": v.t, "sensor": "accelerometer", "x": v.v[0], "y": v.v[1], "z": v.v[2]})
        }
        Sample::Gyroscope(v) => {
            json!({"t_ms": v.t, "sensor": "gyroscope", "x": v.v[0], "y": v.v[1], "z": v.v[2]})
        }
        Sample::Magnetometer(v) => {
            json!({"t_ms": v.t, "sensor": "magnetometer", "x": v.v[0], "y": v.v[1], "z": v.v[2]})
        }
        Sample::RotationVector(v) => {
            json!({"t_ms": v.t, "sensor": "rotation_vector", "x": v.v[0], "y": v.v[1], "z": v.v[2]})
        }
        Sample::Pressure(p) => json!({"t_ms": p.t, "sensor": "pressure", "hpa": p.hpa}),
        Sample::Wifi(w) => {
            json!({"t_ms": w.t, "sensor": "wifi", "aps": w.entries.iter().map(|e| json!({
            "bssid": e.bssid.to_string(), "rssi_dbm": e.rssi_dbm, "last_seen_ms": e.last_seen_ms})).collect::<Vec<_>>()})
        }
    }
}

/// A running server and its stop switch.
pub struct Running {
    /// Its address.
    pub addr: SocketAddr,
    /// Stops it (graceful: as SIGTERM).
    pub stop: Option<tokio::sync::oneshot::Sender<()>>,
    /// Its task (resolves when it stopped and flushed).
    pub task: tokio::task::JoinHandle<Result<(), wipdr_serve::errors::ServeError>>,
    /// The state.
    pub state: std::sync::Arc<wipdr_serve::AppState>,
}

impl Running {
    /// Stops it and waits for the flush.
    pub async fn shutdown(mut self) {
        if let Some(s) = self.stop.take() {
            let _ = s.send(());
        }
        self.task.await.expect("server task").expect("clean stop");
    }
}

/// A server on `127.0.0.1:0` with tokens A and B.
pub async fn start(db: &Path, config: ServeConfig) -> Running {
    let server = Server::bind(
        "127.0.0.1:0",
        model(),
        Tokens::from_tokens([A, B]),
        db,
        config,
    )
    .await
    .expect("bound");
    let addr = server.local_addr();
    let state = server.state().clone();
    let (tx, rx) = tokio::sync::oneshot::channel::<()>();
    let task = tokio::spawn(server.run(async {
        let _ = rx.await;
    }));
    Running {
        addr,
        stop: Some(tx),
        task,
        state,
    }
}

/// A plain HTTP client.
pub struct Http {
    client: Client<HttpConnector, Full<Bytes>>,
    base: String,
}

impl Http {
    /// A client of the server at `addr`.
    pub fn new(addr: SocketAddr) -> Self {
        Self {
            client: Client::builder(TokioExecutor::new()).build_http(),
            base: format!("http://{addr}"),
        }
    }

    /// A request; returns the status and the body.
    pub async fn raw(
        &self,
        method: Method,
        path: &str,
        token: Option<&str>,
        body: Vec<u8>,
    ) -> (StatusCode, Bytes) {
        let mut req = Request::builder()
            .method(method)
            .uri(format!("{}{path}", self.base))
            .header("content-type", "application/json");
        if let Some(t) = token {
            req = req.header("authorization", format!("Bearer {t}"));
        }
        let resp = self
            .client
            .request(req.body(Full::new(Bytes::from(body))).unwrap())
            .await
            .expect("a response");
        let status = resp.status();
        let body = resp.into_body().collect().await.unwrap().to_bytes();
        (status, body)
    }

    /// Opens an event stream (`GET path` with `token`); the response with its body unread.
    pub async fn stream(&self, path: &str, token: &str) -> hyper::Response<hyper::body::Incoming> {
        let req = Request::get(format!("{}{path}", self.base))
            .header("authorization", format!("Bearer {token}"))
            .body(Full::default())
            .unwrap();
        self.client.request(req).await.expect("a response")
    }

    /// A request with a JSON body (or none); the answer as JSON (`Null` when it is not JSON).
    pub async fn json(
        &self,
        method: Method,
        path: &str,
        token: Option<&str>,
        body: Option<&Value>,
    ) -> (StatusCode, Value) {
        let bytes = body.map(|b| b.to_string().into_bytes()).unwrap_or_default();
        let (s, b) = self.raw(method, path, token, bytes).await;
        (s, serde_json::from_slice(&b).unwrap_or(Value::Null))
    }

    /// Opens a session, returns its id.
    pub async fn open(&self, token: &str, scheme: &str, device: &str) -> String {
        let (s, v) = self
            .json(
                Method::POST,
                "/v1/sessions",
                Some(token),
                Some(&serde_json::json!({"scheme": scheme, "device": device, "stream_id": "sim_F1_w0000"})),
            )
            .await;
        assert_eq!(s, StatusCode::CREATED, "{v}");
        v["id"].as_str().unwrap().to_string()
    }

    /// Posts samples to a session.
    pub async fn post(&self, token: &str, id: &str, samples: &[Value]) -> (StatusCode, Value) {
        self.json(
            Method::POST,
            &format!("/v1/sessions/{id}/samples"),
            Some(token),
            Some(&serde_json::json!({ "samples": samples })),
        )
        .await
    }

    /// A session's track as JSON estimates.
    pub async fn track(&self, token: &str, id: &str) -> Value {
        let (s, v) = self
            .json(
                Method::GET,
                &format!("/v1/sessions/{id}/track?format=json"),
                Some(token),
                None,
            )
            .await;
        assert_eq!(s, StatusCode::OK, "{v}");
        v["estimates"].clone()
    }
}

/// Reads an event stream's body until `done(text so far)` holds, a read waits 30 s, or the
/// stream ends; the text read.
pub async fn read_stream_until(
    resp: hyper::Response<hyper::body::Incoming>,
    done: impl Fn(&str) -> bool,
) -> String {
    let mut body = resp.into_body();
    let mut text = String::new();
    while !done(&text) {
        match tokio::time::timeout(std::time::Duration::from_secs(30), body.frame()).await {
            Ok(Some(Ok(f))) => {
                if let Some(d) = f.data_ref() {
                    text.push_str(&String::from_utf8_lossy(d));
                }
            }
            _ => break,
        }
    }
    text
}

/// The whole body of a stream that ends (after the server stopped), as text.
pub async fn read_stream_to_end(resp: hyper::Response<hyper::body::Incoming>) -> String {
    let bytes = resp
        .into_body()
        .collect()
        .await
        .map(|b| b.to_bytes())
        .unwrap_or_default();
    String::from_utf8_lossy(&bytes).into_owned()
}

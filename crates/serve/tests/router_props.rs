//! No panic reachable from a request: random bodies (bytes, JSON-shaped text, sample batches
//! with extreme finite numbers, times and orders) through the whole router
//! (`tower::ServiceExt::oneshot`), each answered 2xx or a typed 4xx, never a 5xx; another
//! token's session is untouched by all of it.

mod common;

use axum::body::Body;
use axum::http::{Request, StatusCode};
use common::{A, B, fixture_samples, model};
use proptest::prelude::*;
use serde_json::{Value, json};
use std::sync::Arc;
use tower::ServiceExt;
use wipdr_serve::auth::Tokens;
use wipdr_serve::db::Db;
use wipdr_serve::{AppState, ServeConfig};

fn call(
    rt: &tokio::runtime::Runtime,
    app: &axum::Router,
    method: &str,
    path: &str,
    token: Option<&str>,
    body: Vec<u8>,
) -> (StatusCode, Value) {
    let mut req = Request::builder().method(method).uri(path);
    if let Some(t) = token {
        req = req.header("authorization", format!("Bearer {t}"));
    }
    let resp = rt
        .block_on(app.clone().oneshot(req.body(Body::from(body)).unwrap()))
        .unwrap();
    let status = resp.status();
    let bytes = rt
        .block_on(axum::body::to_bytes(resp.into_body(), usize::MAX))
        .unwrap();
    (
        status,
        serde_json::from_slice(&bytes).unwrap_or(Value::Null),
    )
}

fn sensor_sample() -> impl Strategy<Value = Value> {
    let num = prop_oneof![
        any::<f64>().prop_filter("finite", |v| v.is_finite()),
        Just(0.0),
        Just(-0.0),
        Just(f64::MAX),
        Just(f64::MIN_POSITIVE),
        -20.0..20.0f64,
    ];
    let t = prop_oneof![0i64..5000, any::<i64>(), Just(10_000_000_000_000i64)];
    let bssid = prop_oneof![
        Just("aa:bb:cc:dd:ee:01".to_string()),
        "[0-9a-f:]{0,20}",
        Just("ff:ff:ff:ff:ff:ff".to_string())
    ];
    (0usize..7, t, num.clone(), num.clone(), num, bssid, -200.0..40.0f64).prop_map(|(k, t, x, y, z, bssid, rssi)| match k {
        0 => json!({"t_ms": t, "sensor": "accelerometer", "x": x, "y": y, "z": z}),
        1 => json!({"t_ms": t, "sensor": "gyroscope", "x": x, "y": y, "z": z}),
        2 => json!({"t_ms": t, "sensor": "magnetometer", "x": x, "y": y, "z": z}),
        3 => json!({"t_ms": t, "sensor": "rotation_vector", "x": x, "y": y, "z": z}),
        4 => json!({"t_ms": t, "sensor": "pressure", "hpa": x}),
        5 => json!({"t_ms": t, "sensor": "wifi", "aps": [{"bssid": bssid, "rssi_dbm": rssi, "last_seen_ms": t}]}),
        _ => json!({"t_ms": t, "sensor": "wifi", "aps": []}),
    })
}

fn body() -> impl Strategy<Value = Vec<u8>> {
    prop_oneof![
        proptest::collection::vec(any::<u8>(), 0..300),
        "[\\[\\]{}\",:0-9a-z_ .eE+-]{0,200}".prop_map(String::into_bytes),
        proptest::collection::vec(sensor_sample(), 0..40)
            .prop_map(|s| json!({"samples": s}).to_string().into_bytes()),
        (any::<Option<String>>(), ".{0,50}", any::<Option<i64>>()).prop_map(
            |(scheme, device, t)| {
                json!({"scheme": scheme, "device": device, "start_unix_ms": t, "phone_model": "p"})
                    .to_string()
                    .into_bytes()
            }
        ),
    ]
}

const SCHEMES: [&str; 4] = ["ekf", "pmf", "wifi", "pf"];

#[test]
fn no_request_body_reaches_a_panic_or_another_session() {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let db = Db::open(&dir.path().join("t.sqlite"), 0).unwrap();
    let config = ServeConfig {
        max_samples_per_s: 1e12,
        max_sessions_per_token: 1_000_000,
        ..ServeConfig::default()
    };
    let (state, _stop) = AppState::new(model(), Tokens::from_tokens([A, B]), db, config).unwrap();
    let app = rt.block_on(async { wipdr_serve::router::router(Arc::clone(&state)) });
    let (s, v) = call(
        &rt,
        &app,
        "POST",
        "/v1/sessions",
        Some(B),
        json!({"device": "bystander", "scheme": "pmf"})
            .to_string()
            .into_bytes(),
    );
    assert_eq!(s, StatusCode::CREATED, "{v}");
    let other = v["id"].as_str().unwrap().to_string();
    let samples = fixture_samples();
    let (s, _) = call(
        &rt,
        &app,
        "POST",
        &format!("/v1/sessions/{other}/samples"),
        Some(B),
        json!({"samples": &samples[..2000]})
            .to_string()
            .into_bytes(),
    );
    assert_eq!(s, StatusCode::OK);
    let track_path = format!("/v1/sessions/{other}/track?format=json");
    let (_, before) = call(&rt, &app, "GET", &track_path, Some(B), vec![]);
    assert!(!before["estimates"].as_array().unwrap().is_empty());

    let cases = std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(256);
    let mut runner = proptest::test_runner::TestRunner::new(ProptestConfig {
        cases,
        ..ProptestConfig::default()
    });
    runner
        .run(&(body(), body(), 0usize..4), |(b1, b2, route)| {
            // A fresh session of A's per case, fed random batches.
            let (s, v) = call(
                &rt,
                &app,
                "POST",
                "/v1/sessions",
                Some(A),
                json!({"device": "fuzz", "scheme": SCHEMES[route]})
                    .to_string()
                    .into_bytes(),
            );
            prop_assert_eq!(s, StatusCode::CREATED, "{}", v);
            let id = v["id"].as_str().unwrap().to_string();
            for (method, path, body) in [
                ("POST", format!("/v1/sessions/{id}/samples"), b1.clone()),
                ("POST", format!("/v1/sessions/{id}/samples"), b2),
                ("POST", "/v1/sessions".to_string(), b1),
            ] {
                let (s, v) = call(&rt, &app, method, &path, Some(A), body);
                prop_assert!(!s.is_server_error(), "{} {}: {}: {}", method, path, s, v);
                if s.is_client_error() {
                    prop_assert!(v["error"]["code"].is_string(), "typed error: {}", v);
                }
            }
            let (s, v) = call(
                &rt,
                &app,
                "GET",
                &format!("/v1/sessions/{id}/track?format=geojson"),
                Some(A),
                vec![],
            );
            prop_assert_eq!(s, StatusCode::OK, "{}", v);
            let (s, _) = call(
                &rt,
                &app,
                "DELETE",
                &format!("/v1/sessions/{id}"),
                Some(A),
                vec![],
            );
            prop_assert_eq!(s, StatusCode::OK);
            Ok(())
        })
        .unwrap();
    let (_, after) = call(&rt, &app, "GET", &track_path, Some(B), vec![]);
    assert_eq!(after, before);
}

//! The routes of API v1 and their handlers. Every handler authenticates first, returns
//! `Result<_, ApiError>` (a typed JSON error, never a panic), and touches only the session it
//! names, which its token must own (else 404, as for no session).
//!
//! | method | path | what |
//! | --- | --- | --- |
//! | GET | `/` , `/map.js` | the live map page |
//! | GET | `/healthz` | liveness (`ok`), no token |
//! | GET | `/metrics` | Prometheus text, no token (bind it to a private address) |
//! | GET | `/v1/openapi.json` | the API document, no token |
//! | GET | `/v1/plan` | the model's floor plan for the map |
//! | GET, POST | `/v1/sessions` | the token's open sessions; open one |
//! | GET, DELETE | `/v1/sessions/{id}` | a session's state and current estimate; close it |
//! | POST | `/v1/sessions/{id}/samples` | a batch of samples -> the estimates it made |
//! | GET | `/v1/sessions/{id}/track` | the track (`?format=geojson|ipin|csv|json`) |
//! | GET | `/v1/sessions/{id}/events` | the session's estimates, live (Server-Sent Events) |
//! | GET | `/v1/live` | every open session of the token, live (Server-Sent Events) |

use crate::auth::Owner;
use crate::db::{Db, SessionRecord, StoredEstimate, Write};
use crate::errors::{ApiError, ErrorCode, ServeError};
use crate::sessions::{self, Bucket, Session, SessionRef};
use crate::{AppState, LiveEvent, now_unix_ms, radius_95};
use axum::body::Bytes;
use axum::extract::rejection::BytesRejection;
use axum::extract::{DefaultBodyLimit, MatchedPath, Path, Query, Request, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::middleware::Next;
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::{Json, Router};
use futures_util::StreamExt;
use serde::Deserialize;
use serde_json::{Value, json};
use std::convert::Infallible;
use std::sync::Arc;
use std::time::Instant;
use tokio::sync::broadcast;
use wipdr_io::sample_stream::PlainSample;
use wipdr_positioning::track_format::{self, TrackRow};
use wipdr_positioning::{StreamIdentity, StreamSpec};

type St = State<Arc<AppState>>;

/// Every route, `(method, path)`: the OpenAPI document lists exactly these (a test checks).
pub const ROUTES: &[(&str, &str)] = &[
    ("get", "/"),
    ("get", "/map.js"),
    ("get", "/healthz"),
    ("get", "/metrics"),
    ("get", "/v1/openapi.json"),
    ("get", "/v1/plan"),
    ("get", "/v1/sessions"),
    ("post", "/v1/sessions"),
    ("get", "/v1/sessions/{id}"),
    ("delete", "/v1/sessions/{id}"),
    ("post", "/v1/sessions/{id}/samples"),
    ("get", "/v1/sessions/{id}/track"),
    ("get", "/v1/sessions/{id}/events"),
    ("get", "/v1/live"),
];

/// Longest device label, stream id or phone model, characters.
pub const MAX_LABEL_CHARS: usize = 200;

/// The application: routes, the body limit, the metrics and body-size middleware.
pub fn router(state: Arc<AppState>) -> Router {
    let limit = state.config.max_body_bytes;
    Router::new()
        .route("/", get(crate::page::index))
        .route("/map.js", get(crate::page::script))
        .route("/healthz", get(|| async { "ok\n" }))
        .route("/metrics", get(metrics))
        .route(
            "/v1/openapi.json",
            get(|| async { Json(crate::openapi::document()) }),
        )
        .route("/v1/plan", get(plan))
        .route("/v1/sessions", get(list_sessions).post(create_session))
        .route("/v1/sessions/{id}", get(get_session).delete(close_session))
        .route(
            "/v1/sessions/{id}/samples",
            axum::routing::post(post_samples),
        )
        .route("/v1/sessions/{id}/track", get(get_track))
        .route("/v1/sessions/{id}/events", get(session_events))
        .route("/v1/live", get(live))
        .fallback(|| async { ApiError::RouteNotFound })
        .layer(DefaultBodyLimit::max(limit))
        .layer(axum::middleware::from_fn_with_state(state.clone(), observe))
        .with_state(state)
}

/// Measures each request (latency by route; refusals by reason) and refuses a body whose
/// declared length is over the limit before reading it.
async fn observe(State(state): St, req: Request, next: Next) -> Response {
    let t0 = Instant::now();
    let method = req.method().as_str().to_string();
    let route = req
        .extensions()
        .get::<MatchedPath>()
        .map(|p| p.as_str().to_string())
        .unwrap_or_else(|| "unmatched".into());
    let declared = req
        .headers()
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<u64>().ok());
    let limit = state.config.max_body_bytes;
    let response = if declared.is_some_and(|n| n > limit as u64) {
        let mut r = ApiError::BodyTooLarge { limit }.into_response();
        // The body is not read: the connection cannot be reused.
        r.headers_mut()
            .insert(header::CONNECTION, HeaderValue::from_static("close"));
        r
    } else {
        next.run(req).await
    };
    state
        .metrics
        .observe(&method, &route, t0.elapsed().as_secs_f64());
    if let Some(ErrorCode(code)) = response.extensions().get::<ErrorCode>() {
        state.metrics.reject(code);
    }
    response
}

async fn metrics(State(state): St) -> impl IntoResponse {
    (
        [(header::CONTENT_TYPE, "text/plain; version=0.0.4")],
        state.metrics.render(state.registry.len()),
    )
}

fn body_bytes(body: Result<Bytes, BytesRejection>, limit: usize) -> Result<Bytes, ApiError> {
    body.map_err(|r| {
        if r.status() == StatusCode::PAYLOAD_TOO_LARGE {
            ApiError::BodyTooLarge { limit }
        } else {
            ApiError::MalformedBody(r.body_text())
        }
    })
}

fn parse<T: serde::de::DeserializeOwned>(bytes: &[u8]) -> Result<T, ApiError> {
    serde_json::from_slice(bytes).map_err(|e| ApiError::MalformedBody(e.to_string()))
}

fn label(field: &str, v: &str) -> Result<(), ApiError> {
    let bad = |message: String| ApiError::InvalidField {
        field: field.into(),
        message,
    };
    if v.chars().count() > MAX_LABEL_CHARS {
        return Err(bad(format!("at most {MAX_LABEL_CHARS} characters")));
    }
    if v.chars().any(char::is_control) {
        return Err(bad("no control characters".into()));
    }
    Ok(())
}

async fn plan(State(state): St, headers: HeaderMap) -> Result<Json<Value>, ApiError> {
    state.tokens.authenticate(&headers)?;
    let data = state.model.data();
    let ring = |p: &wipdr_core::Polygon| -> Vec<[f64; 2]> {
        p.exterior.iter().map(|q| [q.x, q.y]).collect()
    };
    let plan = data.plan.as_ref().map(|p| {
        json!({
            "width": p.width,
            "height": p.height,
            "outline": p.outline.iter().map(ring).collect::<Vec<_>>(),
            "units": p.units.iter().map(|u| ring(&u.polygon)).collect::<Vec<_>>(),
        })
    });
    Ok(Json(json!({
        "name": state.model.name(),
        "floors": data.floors,
        "wgs84": data.geo_frame.is_some(),
        "plan": plan,
    })))
}

/// The body of `POST /v1/sessions`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct CreateSession {
    /// The scheme (default `pmf`).
    #[serde(default)]
    scheme: Option<String>,
    /// A label for the device (shown on the map as text).
    device: String,
    /// The stream id (the positioner's seed; default: the session id). Give the walk id to
    /// reproduce `wipdr locate` exactly.
    #[serde(default)]
    stream_id: Option<String>,
    /// The phone model (with `start_unix_ms`: the model's barometric references).
    #[serde(default)]
    phone_model: Option<String>,
    /// Unix ms of the stream's `t_ms` 0.
    #[serde(default)]
    start_unix_ms: Option<i64>,
}

fn session_json(r: &SessionRecord, open: Option<&Session>) -> Value {
    json!({
        "id": r.id,
        "scheme": r.scheme,
        "device": r.device,
        "stream_id": r.stream_id,
        "created_unix_ms": r.created_unix_ms,
        "state": if open.is_some() { "open" } else { "closed" },
        "close_reason": r.close_reason,
        "samples": open.map(Session::samples),
        "estimates": open.map(Session::estimates),
        "estimate": open.and_then(Session::latest).map(estimate_json),
    })
}

fn estimate_json(e: StoredEstimate) -> Value {
    json!({
        "t_ms": e.t_ms, "x": e.x, "y": e.y, "floor": e.floor, "sd_m": e.sd_m,
        "r95_m": e.sd_m.map(radius_95),
    })
}

async fn create_session(
    State(state): St,
    headers: HeaderMap,
    body: Result<Bytes, BytesRejection>,
) -> Result<(StatusCode, Json<Value>), ApiError> {
    let owner = state.tokens.authenticate(&headers)?;
    if *state.stopping.borrow() {
        return Err(ApiError::ShuttingDown);
    }
    let req: CreateSession = parse(&body_bytes(body, state.config.max_body_bytes)?)?;
    let scheme = req.scheme.unwrap_or_else(|| "pmf".into());
    label("scheme", &scheme)?;
    label("device", &req.device)?;
    let scheme_cfg = state
        .model
        .scheme(&scheme)
        .map_err(|e| ApiError::InvalidField {
            field: "scheme".into(),
            message: e.to_string(),
        })?;
    if scheme_cfg.name() == "pdr" {
        return Err(ApiError::InvalidField {
            field: "scheme".into(),
            message: "pdr is dead reckoning from a known start, which a live session does not have"
                .into(),
        });
    }
    if let Some(opens) = &state.opens {
        opens
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .take(1, Instant::now())
            .map_err(|e| match e {
                ApiError::RateLimited {
                    rate,
                    retry_after_s,
                    ..
                } => ApiError::TooManyOpens {
                    rate,
                    retry_after_s,
                },
                other => other,
            })?;
    }
    let id = {
        let b: [u8; 16] = rand::random();
        b.iter().map(|b| format!("{b:02x}")).collect::<String>()
    };
    let stream_id = req.stream_id.unwrap_or_else(|| id.clone());
    label("stream_id", &stream_id)?;
    if let Some(m) = &req.phone_model {
        label("phone_model", m)?;
    }
    if let Some(t) = req.start_unix_ms
        && t.abs() > wipdr_io::sample_stream::MAX_ABS_TIME_MS
    {
        return Err(ApiError::InvalidField {
            field: "start_unix_ms".into(),
            message: format!("{t} is out of range"),
        });
    }
    let identity = match (req.phone_model, req.start_unix_ms) {
        (Some(model), Some(start_unix_ms)) => Some(StreamIdentity {
            model,
            start_unix_ms,
        }),
        _ => None,
    };
    let positioner = state
        .model
        .positioner(
            &scheme,
            &StreamSpec {
                id: Some(stream_id.clone()),
                identity,
                start: None,
            },
        )
        .map_err(|e| ApiError::InvalidField {
            field: "scheme".into(),
            message: e.to_string(),
        })?;
    let record = SessionRecord {
        id: id.clone(),
        owner,
        scheme: scheme.clone(),
        device: req.device.clone(),
        stream_id,
        created_unix_ms: now_unix_ms(),
        closed_unix_ms: None,
        close_reason: None,
        last_sample_t_ms: None,
    };
    let c = &state.config;
    let bucket = Bucket::new(
        c.max_samples_per_s,
        c.max_samples_per_s * c.burst_s,
        Instant::now(),
    );
    let session = Session::new(record.clone(), positioner, bucket);
    state
        .registry
        .insert(session, state.config.max_sessions_per_token)?;
    state.db.queue(Write::Session(record.clone()));
    state
        .metrics
        .sessions_opened
        .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    tracing::info!(session = %id, scheme = %scheme, owner = ?owner, "session opened");
    Ok((
        StatusCode::CREATED,
        Json(
            session_json(&record, None)
                .as_object()
                .map(|o| {
                    let mut o = o.clone();
                    o.insert("state".into(), json!("open"));
                    Value::Object(o)
                })
                .unwrap_or(Value::Null),
        ),
    ))
}

async fn list_sessions(State(state): St, headers: HeaderMap) -> Result<Json<Value>, ApiError> {
    let owner = state.tokens.authenticate(&headers)?;
    let list: Vec<Value> = state
        .registry
        .all(Some(owner))
        .iter()
        .map(|s| {
            let s = sessions::lock(s);
            let mut v = session_json(&s.record, Some(&s));
            v["recent"] = json!(
                s.recent()
                    .into_iter()
                    .map(estimate_json)
                    .collect::<Vec<_>>()
            );
            v
        })
        .collect();
    Ok(Json(json!({ "sessions": list })))
}

/// Reads the database off the async threads, after what is queued has gone in (a close or
/// estimates still queued are part of what is read); a failure is logged and answered as an
/// internal error.
async fn read_db<T: Send + 'static>(
    state: &Arc<AppState>,
    read: impl FnOnce(&Db) -> Result<T, ServeError> + Send + 'static,
) -> Result<T, ApiError> {
    state.flush().await.map_err(|e| {
        tracing::error!("{e}");
        ApiError::Internal
    })?;
    let db = state.db.clone();
    tokio::task::spawn_blocking(move || read(&db))
        .await
        .map_err(|e| {
            tracing::error!("database task failed: {e}");
            ApiError::Internal
        })?
        .map_err(|e| {
            tracing::error!("{e}");
            ApiError::Internal
        })
}

/// A stored session of `owner` (404 for none and for another owner's).
async fn stored(state: &Arc<AppState>, owner: Owner, id: &str) -> Result<SessionRecord, ApiError> {
    let key = id.to_string();
    let rec = read_db(state, move |db| db.session(&key)).await?;
    match rec {
        Some(r) if r.owner == owner => Ok(r),
        _ => Err(ApiError::SessionNotFound(id.to_string())),
    }
}

fn open_session(state: &AppState, owner: Owner, id: &str) -> Option<SessionRef> {
    state.registry.get(owner, id)
}

async fn get_session(
    State(state): St,
    headers: HeaderMap,
    Path(id): Path<String>,
) -> Result<Json<Value>, ApiError> {
    let owner = state.tokens.authenticate(&headers)?;
    if let Some(s) = open_session(&state, owner, &id) {
        let s = sessions::lock(&s);
        return Ok(Json(session_json(&s.record, Some(&s))));
    }
    let r = stored(&state, owner, &id).await?;
    Ok(Json(session_json(&r, None)))
}

async fn close_session(
    State(state): St,
    headers: HeaderMap,
    Path(id): Path<String>,
) -> Result<Json<Value>, ApiError> {
    let owner = state.tokens.authenticate(&headers)?;
    if open_session(&state, owner, &id).is_some() && state.close_session(&id, "client") {
        return Ok(Json(
            json!({ "id": id, "state": "closed", "close_reason": "client" }),
        ));
    }
    let r = stored(&state, owner, &id).await?;
    Ok(Json(session_json(&r, None)))
}

/// The body of `POST /v1/sessions/{id}/samples`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Batch {
    samples: Vec<PlainSample>,
}

async fn post_samples(
    State(state): St,
    headers: HeaderMap,
    Path(id): Path<String>,
    body: Result<Bytes, BytesRejection>,
) -> Result<Json<Value>, ApiError> {
    let owner = state.tokens.authenticate(&headers)?;
    let Some(session) = open_session(&state, owner, &id) else {
        let r = stored(&state, owner, &id).await?;
        return Err(ApiError::SessionClosed {
            id,
            reason: r.close_reason.unwrap_or_else(|| "closed".into()),
        });
    };
    let batch: Batch = parse(&body_bytes(body, state.config.max_body_bytes)?)?;
    let mut samples = Vec::with_capacity(batch.samples.len());
    for (index, p) in batch.samples.iter().enumerate() {
        let s =
            sessions::to_sample(p, state.config.max_scan_entries).map_err(|(field, message)| {
                ApiError::InvalidSample {
                    index,
                    field,
                    message,
                }
            })?;
        samples.push(s);
    }
    let now = Instant::now();
    let outcome = {
        let mut s = sessions::lock(&session);
        // A positioner that panics on some input would end this session only.
        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| s.push_batch(&samples, now)))
    };
    let outcome = match outcome {
        Ok(r) => r?,
        Err(_) => {
            tracing::error!(session = %id, "the positioner panicked: session closed");
            state.close_session(&id, "internal error");
            return Err(ApiError::Internal);
        }
    };
    let (record_owner, device, scheme) = {
        let s = sessions::lock(&session);
        (
            s.record.owner,
            s.record.device.clone(),
            s.record.scheme.clone(),
        )
    };
    state.metrics.samples.fetch_add(
        outcome.accepted as u64,
        std::sync::atomic::Ordering::Relaxed,
    );
    if !outcome.estimates.is_empty() {
        state.metrics.estimates.fetch_add(
            outcome.estimates.len() as u64,
            std::sync::atomic::Ordering::Relaxed,
        );
        state.db.queue(Write::Estimates {
            session: id.clone(),
            first_seq: outcome.first_seq,
            estimates: outcome.estimates.clone(),
        });
        if let Some(e) = outcome.estimate
            && state.live.receiver_count() > 0
        {
            let _ = state.live.send(Arc::new(LiveEvent {
                kind: "estimate",
                session: id.clone(),
                owner: record_owner,
                device,
                scheme,
                estimate: Some(e),
                r95_m: e.sd_m.map(radius_95),
            }));
        }
    }
    Ok(Json(json!({
        "accepted": outcome.accepted,
        "estimates": outcome.estimates.into_iter().map(estimate_json).collect::<Vec<_>>(),
        "estimate": outcome.estimate.map(estimate_json),
    })))
}

/// The query of `GET /v1/sessions/{id}/track`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct TrackQuery {
    #[serde(default)]
    format: Option<String>,
}

async fn get_track(
    State(state): St,
    headers: HeaderMap,
    Path(id): Path<String>,
    query: Result<Query<TrackQuery>, axum::extract::rejection::QueryRejection>,
) -> Result<Response, ApiError> {
    let owner = state.tokens.authenticate(&headers)?;
    let Query(q) = query.map_err(|e| ApiError::InvalidField {
        field: "query".into(),
        message: e.body_text(),
    })?;
    let (record, end) = match open_session(&state, owner, &id) {
        Some(s) => {
            let s = sessions::lock(&s);
            (s.record.clone(), s.last_sample_t())
        }
        None => {
            let r = stored(&state, owner, &id).await?;
            let end = r.last_sample_t_ms;
            (r, end)
        }
    };
    let key = id.clone();
    let track = read_db(&state, move |db| db.track(&key)).await?;
    let frame = state.model.data().geo_frame;
    let format = q.format.as_deref().unwrap_or("geojson");
    let rows: Vec<TrackRow> = track.iter().map(StoredEstimate::row).collect();
    Ok(match format {
        "geojson" => (
            [(header::CONTENT_TYPE, "application/geo+json")],
            Json(track_format::geojson(
                &rows,
                &record.stream_id,
                &record.scheme,
                frame.as_ref(),
            )),
        )
            .into_response(),
        "json" => Json(json!({
            "id": record.id,
            "estimates": track.into_iter().map(estimate_json).collect::<Vec<_>>(),
        }))
        .into_response(),
        "csv" => (
            [(header::CONTENT_TYPE, "text/csv")],
            track_format::csv(&rows),
        )
            .into_response(),
        "ipin" => {
            let Some(frame) = frame else {
                return Err(ApiError::FormatUnavailable(
                    "format ipin needs latitude/longitude: the site model has no WGS84 frame"
                        .into(),
                ));
            };
            (
                [(header::CONTENT_TYPE, "text/csv")],
                track_format::ipin(&rows, &frame, end),
            )
                .into_response()
        }
        other => {
            return Err(ApiError::InvalidField {
                field: "format".into(),
                message: format!("{other:?}: one of geojson, ipin, csv, json"),
            });
        }
    })
}

type EventStream =
    std::pin::Pin<Box<dyn futures_util::Stream<Item = Result<Event, Infallible>> + Send>>;

/// Each open session's latest estimate that `keep` lets through, as `estimate` events: a map
/// opened in the middle of a walk shows where every phone is at once, not at its next batch.
fn live_snapshot(state: &AppState, keep: &impl Fn(&LiveEvent) -> bool) -> Vec<Event> {
    state
        .registry
        .all(None)
        .iter()
        .filter_map(|s| {
            let s = sessions::lock(s);
            let e = s.latest()?;
            let ev = LiveEvent {
                kind: "estimate",
                session: s.record.id.clone(),
                owner: s.record.owner,
                device: s.record.device.clone(),
                scheme: s.record.scheme.clone(),
                estimate: Some(e),
                r95_m: e.sd_m.map(radius_95),
            };
            keep(&ev).then(|| live_event(&ev))
        })
        .collect()
}

fn live_event(ev: &LiveEvent) -> Event {
    let data = serde_json::to_string(ev).unwrap_or_default();
    Event::default().event(ev.kind).data(data)
}

/// A live event stream: the snapshot of the open sessions' latest estimates, then every new
/// event `keep` lets through, until the server stops. Subscribing before taking the snapshot
/// means no estimate falls between the two (one may come twice: the map keeps the latest).
fn live_stream(
    state: &Arc<AppState>,
    keep: impl Fn(&LiveEvent) -> bool + Send + 'static,
) -> Response {
    let rx = state.live.subscribe();
    let snapshot = futures_util::stream::iter(
        live_snapshot(state, &keep)
            .into_iter()
            .map(Ok::<_, Infallible>),
    );
    let stopping = state.stopping.clone();
    let stream = futures_util::stream::unfold(
        (rx, stopping, keep),
        |(mut rx, mut stop, keep)| async move {
            loop {
                if *stop.borrow() {
                    return None;
                }
                tokio::select! {
                    changed = stop.changed() => {
                        if changed.is_err() || *stop.borrow() {
                            return None;
                        }
                    }
                    r = rx.recv() => match r {
                        Ok(ev) if keep(&ev) => {
                            return Some((Ok(live_event(&ev)), (rx, stop, keep)));
                        }
                        Ok(_) => continue,
                        Err(broadcast::error::RecvError::Lagged(n)) => {
                            let event = Event::default().event("lagged").data(n.to_string());
                            return Some((Ok(event), (rx, stop, keep)));
                        }
                        Err(broadcast::error::RecvError::Closed) => return None,
                    }
                }
            }
        },
    );
    Sse::new(Box::pin(snapshot.chain(stream)) as EventStream)
        .keep_alive(KeepAlive::default())
        .into_response()
}

async fn session_events(
    State(state): St,
    headers: HeaderMap,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let owner = state.tokens.authenticate(&headers)?;
    if open_session(&state, owner, &id).is_none() {
        let r = stored(&state, owner, &id).await?;
        return Err(ApiError::SessionClosed {
            id,
            reason: r.close_reason.unwrap_or_else(|| "closed".into()),
        });
    }
    Ok(live_stream(&state, move |ev| ev.session == id))
}

async fn live(State(state): St, headers: HeaderMap) -> Result<Response, ApiError> {
    let owner = state.tokens.authenticate(&headers)?;
    Ok(live_stream(&state, move |ev| ev.owner == owner))
}

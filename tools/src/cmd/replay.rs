//! `wipdr replay`: streams recorded walks to a `wipdr serve` as phones would (one session a
//! phone, a batch every `--batch-ms` of the walk's clock, sent when that much time has passed,
//! scaled by `--speed`), and prints the request latency percentiles. It is also the load
//! generator: `--phones N` runs N phones at once over the given walks.
//!
//! ```text
//! wipdr replay --server http://127.0.0.1:8080 --token-file tokens.txt WALK.txt.gz --speed 10
//! wipdr replay --server URL --token-file T --speed 0 --batch-ms 250 walk.csv --out tracks/
//! wipdr replay --server URL --token-file T --phones 500 --duration-s 60 --scheme pmf site1/F1/path_data_files/*.txt.gz
//! ```
//!
//! Each walk is read as `wipdr locate --model` reads it and sent in the order `locate`
//! streams it (`wipdr_positioning::samples_of`), as plain samples; a session's stream id is
//! the walk id (its seed), so with `--out` the tracks written are the ones `locate --model`
//! writes for a plain sample stream (the equivalence test: `tools/tests/serve_cli.rs`).

use anyhow::{Context, Result, bail};
use http_body_util::{BodyExt, Full};
use hyper::body::Bytes;
use hyper::{Method, Request, StatusCode};
use hyper_util::client::legacy::Client;
use hyper_util::client::legacy::connect::HttpConnector;
use hyper_util::rt::TokioExecutor;
use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};
use wipdr_core::Walk;
use wipdr_io::sample_stream::{PlainAp, PlainSample};
use wipdr_positioning::Sample;

/// Track format written with `--out`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// `t_ms,x,y,floor,sd_m`.
    Csv,
    /// A GeoJSON Feature.
    Geojson,
    /// `t_s,lat,lon,floor` at 2 Hz (needs a WGS84 frame).
    Ipin,
}

impl Format {
    fn query(self) -> &'static str {
        match self {
            Self::Csv => "csv",
            Self::Geojson => "geojson",
            Self::Ipin => "ipin",
        }
    }
    fn extension(self) -> &'static str {
        match self {
            Self::Csv => "csv",
            Self::Geojson => "geojson",
            Self::Ipin => "txt",
        }
    }
}

/// Arguments of `wipdr replay`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The server, `http://HOST:PORT`.
    #[arg(long)]
    pub server: String,
    /// The bearer token (visible to other users in the process list: prefer --token-file or
    /// $WIPDR_TOKEN).
    #[arg(long)]
    pub token: Option<String>,
    /// A file whose first token line is the bearer token.
    #[arg(long, conflicts_with = "token")]
    pub token_file: Option<PathBuf>,
    /// Walks to replay: ILC traces, IPIN logfiles, plain sample streams.
    #[arg(value_name = "WALK_FILE", required = true)]
    pub walks: Vec<PathBuf>,
    /// Speed-up against real time (2: twice as fast; 0: as fast as the server answers).
    #[arg(long, default_value_t = 1.0)]
    pub speed: f64,
    /// Phones streaming at once.
    #[arg(long, default_value_t = 64)]
    pub concurrency: usize,
    /// Stream time a batch covers, ms (a phone sends what it measured every this long).
    #[arg(long, default_value_t = 1000)]
    pub batch_ms: i64,
    /// The scheme of the sessions.
    #[arg(long, default_value = "pmf")]
    pub scheme: String,
    /// Phones to run (load generation): phone i replays walk i mod the number of walks;
    /// default one phone a walk.
    #[arg(long)]
    pub phones: Option<usize>,
    /// Stop each phone after this much of its walk's time (with --loop: of its walks' time
    /// together), seconds.
    #[arg(long)]
    pub duration_s: Option<f64>,
    /// Each phone replays walk after walk (the next of the list, a new session each) until
    /// --duration-s: N phones stay N streaming phones for the whole run, as in a building,
    /// instead of going quiet when their walks end.
    #[arg(long = "loop", requires = "duration_s")]
    pub loop_walks: bool,
    /// Spread the phones' starts evenly over this many seconds (default: one batch
    /// interval). A server meets phones arriving over time; the latency while every phone
    /// streams (from the ramp's end to the first phone's --duration-s) is reported apart.
    #[arg(long, conflicts_with = "no_stagger")]
    pub ramp_s: Option<f64>,
    /// Folder receiving each walk's track from the server (`<walk id>.<csv|geojson|txt>`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Format of the tracks written with --out.
    #[arg(long, value_enum, default_value = "csv")]
    pub format: Format,
    /// Leave the sessions open at the end (the live map keeps showing them).
    #[arg(long)]
    pub keep_open: bool,
    /// Write the summary (counts, latency percentiles, server memory) as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Start every phone at once instead of spreading their starts evenly over one batch
    /// interval (the default when paced: phones in the field are out of phase).
    #[arg(long)]
    pub no_stagger: bool,
}

/// One walk ready to send: the session request and the batches.
struct Prepared {
    id: String,
    create: Value,
    /// (stream time at the batch's end since the first sample, body, samples)
    batches: Vec<(i64, Bytes, usize)>,
}

/// A sample as the plain stream format writes it.
pub fn to_plain(s: &Sample) -> PlainSample {
    let xyz = |v: [f64; 3]| (v[0], v[1], v[2]);
    match s {
        Sample::Accelerometer(v) => {
            let (x, y, z) = xyz(v.v);
            PlainSample::Accelerometer { t_ms: v.t, x, y, z }
        }
        Sample::Gyroscope(v) => {
            let (x, y, z) = xyz(v.v);
            PlainSample::Gyroscope { t_ms: v.t, x, y, z }
        }
        Sample::Magnetometer(v) => {
            let (x, y, z) = xyz(v.v);
            PlainSample::Magnetometer { t_ms: v.t, x, y, z }
        }
        Sample::RotationVector(v) => {
            let (x, y, z) = xyz(v.v);
            PlainSample::RotationVector { t_ms: v.t, x, y, z }
        }
        Sample::Pressure(p) => PlainSample::Pressure {
            t_ms: p.t,
            hpa: p.hpa,
        },
        Sample::Wifi(scan) => PlainSample::Wifi {
            t_ms: scan.t,
            aps: scan
                .entries
                .iter()
                .map(|e| PlainAp {
                    bssid: e.bssid.to_string(),
                    rssi_dbm: e.rssi_dbm,
                    last_seen_ms: (e.last_seen_ms.abs()
                        <= wipdr_io::sample_stream::MAX_ABS_TIME_MS)
                        .then_some(e.last_seen_ms),
                })
                .collect(),
        },
    }
}

fn prepare(walk: &Walk, scheme: &str, batch_ms: i64) -> Result<Prepared> {
    let samples: Vec<PlainSample> = wipdr_positioning::samples_of(walk)
        .map(|s| to_plain(&s))
        .collect();
    let Some(t0) = samples.first().and_then(PlainSample::t_ms) else {
        bail!("walk {} has no samples", walk.meta.id);
    };
    let mut batches = Vec::new();
    let mut start = 0usize;
    while start < samples.len() {
        let t = samples[start].t_ms().unwrap_or(t0);
        let end_t = t0 + ((t - t0).div_euclid(batch_ms) + 1) * batch_ms;
        let mut end = start;
        while end < samples.len() && samples[end].t_ms().unwrap_or(t0) < end_t {
            end += 1;
        }
        let body = serde_json::to_vec(&json!({ "samples": &samples[start..end] }))?;
        batches.push((end_t - t0, Bytes::from(body), end - start));
        start = end;
    }
    let mut create = json!({
        "scheme": scheme,
        "device": walk.meta.id,
        "stream_id": walk.meta.id,
    });
    if let (Some(m), Some(t)) = (&walk.meta.model, walk.meta.start_time) {
        create["phone_model"] = json!(m);
        create["start_unix_ms"] = json!(t);
    }
    Ok(Prepared {
        id: walk.meta.id.clone(),
        create,
        batches,
    })
}

type Http = Client<HttpConnector, Full<Bytes>>;

struct Ctx {
    client: Http,
    base: String,
    auth: String,
}

impl Ctx {
    async fn call(
        &self,
        method: Method,
        path: &str,
        body: Option<Bytes>,
    ) -> Result<(StatusCode, Bytes, Duration)> {
        let req = Request::builder()
            .method(method)
            .uri(format!("{}{path}", self.base))
            .header("authorization", &self.auth)
            .header("content-type", "application/json")
            .body(Full::new(body.unwrap_or_default()))?;
        let t0 = Instant::now();
        let resp = self.client.request(req).await?;
        let status = resp.status();
        let bytes = resp.into_body().collect().await?.to_bytes();
        Ok((status, bytes, t0.elapsed()))
    }
}

#[derive(Debug, Default)]
struct PhoneResult {
    /// (seconds since the run's start when the request was sent, latency ms)
    latencies_ms: Vec<(f64, f64)>,
    sessions: usize,
    /// Session opens refused with 429 (the server's open rate) and retried.
    open_retries: usize,
    batches: usize,
    sent: usize,
    accepted: usize,
    refused: BTreeMap<u16, usize>,
    rate_limited: usize,
    failed: usize,
    max_lag_ms: f64,
    error: Option<String>,
}

/// What every phone of a run shares.
struct PhoneSettings {
    /// The run's start (latencies are stamped with their send time since it).
    t0: Instant,
    /// Phones in the run.
    phones: usize,
    speed: f64,
    loop_walks: bool,
    duration_s: Option<f64>,
    out: Option<PathBuf>,
    format: Format,
    keep_open: bool,
}

/// How long phone `i` of `phones` waits before opening its session, when paced: the phones
/// start spread evenly over `ramp_s` seconds of stream time (by default one batch
/// interval), as phones in a building are out of phase with each other (all of them sending
/// in the same instant would measure a burst, not a load). Zero unpaced (`speed` 0), with
/// `stagger` off, or for one phone.
fn start_offset(i: usize, phones: usize, ramp_s: f64, speed: f64, stagger: bool) -> Duration {
    if !stagger || speed <= 0.0 || phones < 2 || ramp_s.is_nan() || ramp_s <= 0.0 {
        return Duration::ZERO;
    }
    let share = i as f64 / phones as f64;
    Duration::try_from_secs_f64(share * ramp_s / speed).unwrap_or(Duration::ZERO)
}

/// One phone: after `offset`, walk `first` of `walks` (with `loop_walks`, then the next one
/// and so on, a session each, until `duration_s` of stream time has passed in all).
async fn phone(
    ctx: Arc<Ctx>,
    walks: Arc<Vec<Arc<Prepared>>>,
    first: usize,
    n: usize,
    offset: Duration,
    args: Arc<PhoneSettings>,
) -> PhoneResult {
    tokio::time::sleep(offset).await;
    let mut r = PhoneResult::default();
    let mut start = Instant::now();
    // Stream time already played by this phone, ms.
    let mut played_ms = 0i64;
    for k in 0.. {
        let walk = &walks[(first + k) % walks.len()];
        // The n-th phone on a walk, or its k-th round: a device label of its own.
        let round = n + k * (args.phones / walks.len()).max(1);
        let budget_ms = args.duration_s.map(|d| d * 1000.0 - played_ms as f64);
        if budget_ms.is_some_and(|b| b <= 1e-9) {
            break;
        }
        let Some(played) = play_walk(
            &ctx, walk, round, &mut start, played_ms, budget_ms, &args, &mut r,
        )
        .await
        else {
            break;
        };
        played_ms += played;
        if !args.loop_walks || played <= 0 {
            break;
        }
    }
    r
}

/// Plays `walk` through one server session, its batches due at `start + (played_ms + t) / speed`; stops
/// after `budget_ms` of its time. Returns the stream time played (the last batch's end), or
/// `None` when the session could not be opened (the error is in `r`).
#[allow(clippy::too_many_arguments)]
async fn play_walk(
    ctx: &Ctx,
    walk: &Prepared,
    round: usize,
    start: &mut Instant,
    played_ms: i64,
    budget_ms: Option<f64>,
    args: &PhoneSettings,
    r: &mut PhoneResult,
) -> Option<i64> {
    let PhoneSettings {
        t0,
        speed,
        out,
        format,
        keep_open,
        ..
    } = args;
    let mut create = walk.create.clone();
    if round > 0 {
        create["device"] = json!(format!("{} #{round}", walk.id));
    }
    // A 429 (the server's open rate) is retried after its Retry-After, as a phone would;
    // the walk's schedule starts when the session opens.
    let mut attempts = 0;
    let opened = loop {
        let t = Instant::now();
        let answer = ctx
            .call(
                Method::POST,
                "/v1/sessions",
                Some(Bytes::from(create.to_string())),
            )
            .await;
        match answer {
            Ok((StatusCode::TOO_MANY_REQUESTS, body, _)) if attempts < 100 => {
                attempts += 1;
                r.open_retries += 1;
                let wait = retry_after_s(&body);
                tokio::time::sleep(Duration::from_secs(wait)).await;
                *start += t.elapsed();
            }
            other => break other,
        }
    };
    let created = match opened {
        Ok((StatusCode::CREATED, body, _)) => serde_json::from_slice::<Value>(&body).ok(),
        Ok((status, body, _)) => {
            r.error = Some(format!(
                "opening a session: {status}: {}",
                String::from_utf8_lossy(&body)
            ));
            return None;
        }
        Err(e) => {
            r.error = Some(format!("opening a session: {e}"));
            return None;
        }
    };
    let Some(id) = created
        .as_ref()
        .and_then(|v| v["id"].as_str())
        .map(str::to_string)
    else {
        r.error = Some("opening a session: no id in the answer".into());
        return None;
    };
    r.sessions += 1;
    let path = format!("/v1/sessions/{id}/samples");
    let mut played = 0i64;
    for (t_end, body, count) in &walk.batches {
        if budget_ms.is_some_and(|b| *t_end as f64 > b + 1e-9) {
            break;
        }
        if *speed > 0.0 {
            let due = *start + Duration::from_secs_f64((played_ms + t_end) as f64 / 1000.0 / speed);
            tokio::time::sleep_until(due.into()).await;
            r.max_lag_ms = r
                .max_lag_ms
                .max(Instant::now().saturating_duration_since(due).as_secs_f64() * 1e3);
        }
        played = *t_end;
        r.batches += 1;
        r.sent += count;
        // A 429 is retried after its Retry-After, as a phone would (at most 20 times).
        let mut attempts = 0;
        loop {
            attempts += 1;
            let sent_s = t0.elapsed().as_secs_f64();
            match ctx.call(Method::POST, &path, Some(body.clone())).await {
                Ok((StatusCode::OK, resp, lat)) => {
                    r.latencies_ms.push((sent_s, lat.as_secs_f64() * 1e3));
                    let v: Value = serde_json::from_slice(&resp).unwrap_or(Value::Null);
                    r.accepted += v["accepted"].as_u64().unwrap_or(0) as usize;
                }
                Ok((StatusCode::TOO_MANY_REQUESTS, resp, lat)) if attempts <= 20 => {
                    r.latencies_ms.push((sent_s, lat.as_secs_f64() * 1e3));
                    r.rate_limited += 1;
                    tokio::time::sleep(Duration::from_secs(retry_after_s(&resp))).await;
                    continue;
                }
                Ok((status, resp, lat)) => {
                    r.latencies_ms.push((sent_s, lat.as_secs_f64() * 1e3));
                    *r.refused.entry(status.as_u16()).or_default() += 1;
                    if r.error.is_none() {
                        r.error = Some(format!(
                            "batch refused: {status}: {}",
                            String::from_utf8_lossy(&resp)
                        ));
                    }
                }
                Err(e) => {
                    r.failed += 1;
                    if r.error.is_none() {
                        r.error = Some(format!("batch failed: {e}"));
                    }
                }
            }
            break;
        }
    }
    if let Some(dir) = out {
        let q = format!("/v1/sessions/{id}/track?format={}", format.query());
        match ctx.call(Method::GET, &q, None).await {
            Ok((StatusCode::OK, body, _)) => {
                let file = dir.join(format!("{}.{}", walk.id, format.extension()));
                if let Err(e) = std::fs::write(&file, &body) {
                    r.error = Some(format!("writing {}: {e}", file.display()));
                }
            }
            Ok((status, body, _)) => {
                r.error = Some(format!(
                    "track: {status}: {}",
                    String::from_utf8_lossy(&body)
                ))
            }
            Err(e) => r.error = Some(format!("track: {e}")),
        }
    }
    if !keep_open
        && let Err(e) = ctx
            .call(Method::DELETE, &format!("/v1/sessions/{id}"), None)
            .await
    {
        r.error.get_or_insert(format!("closing: {e}"));
    }
    Some(played)
}

/// The wait a 429's body asks for ("... retry in N s"), seconds, in [1, 60].
fn retry_after_s(body: &[u8]) -> u64 {
    let v: Value = serde_json::from_slice(body).unwrap_or(Value::Null);
    v["error"]["message"]
        .as_str()
        .and_then(|m| m.rsplit("retry in ").next())
        .and_then(|m| m.trim_end_matches(" s").parse::<u64>().ok())
        .unwrap_or(1)
        .clamp(1, 60)
}

/// The p50, p90, p99 and largest of `lat` (sorted here), ms; NaN for none.
fn latency_summary(mut lat: Vec<f64>) -> (f64, f64, f64, f64) {
    lat.sort_by(f64::total_cmp);
    (
        percentile(&lat, 0.5),
        percentile(&lat, 0.9),
        percentile(&lat, 0.99),
        lat.last().copied().unwrap_or(f64::NAN),
    )
}

fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let k = ((q * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
    sorted[k - 1]
}

/// The server's resident memory and open sessions, from `/metrics`.
async fn server_memory(ctx: &Ctx) -> Option<(f64, f64)> {
    let (status, body, _) = ctx.call(Method::GET, "/metrics", None).await.ok()?;
    if status != StatusCode::OK {
        return None;
    }
    let text = String::from_utf8_lossy(&body);
    let value = |name: &str| {
        text.lines().find_map(|l| {
            l.strip_prefix(name)?
                .strip_prefix(' ')?
                .trim()
                .parse::<f64>()
                .ok()
        })
    };
    Some((
        value("process_resident_memory_bytes")?,
        value("wipdr_serve_sessions_open")?,
    ))
}

fn read_token(args: &Args) -> Result<String> {
    if let Some(t) = &args.token {
        return Ok(t.trim().to_string());
    }
    if let Some(p) = &args.token_file {
        let text =
            std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?;
        if let Some(t) = text
            .lines()
            .map(str::trim)
            .find(|l| !l.is_empty() && !l.starts_with('#'))
        {
            return Ok(t.to_string());
        }
        bail!("{}: no token in the file", p.display());
    }
    if let Ok(t) = std::env::var("WIPDR_TOKEN")
        && !t.trim().is_empty()
    {
        return Ok(t.trim().to_string());
    }
    bail!("give --token-file FILE (or --token T, or $WIPDR_TOKEN)")
}

/// Runs the subcommand.
pub fn run(args: Args) -> Result<()> {
    if args.batch_ms <= 0 {
        bail!("--batch-ms must be > 0");
    }
    if !(args.speed.is_finite() && args.speed >= 0.0) {
        bail!("--speed must be a finite number >= 0 (0: no pacing)");
    }
    let token = read_token(&args)?;
    let base = args.server.trim_end_matches('/').to_string();
    if !base.starts_with("http://") {
        bail!(
            "--server {base}: give http://HOST:PORT (this client speaks plain HTTP; put TLS in a proxy)"
        );
    }
    let mut prepared = Vec::new();
    for p in &args.walks {
        let walk = crate::cmd::locate::read_input(p, None)
            .with_context(|| format!("reading {}", p.display()))?;
        prepared.push(Arc::new(prepare(&walk, &args.scheme, args.batch_ms)?));
    }
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        if args.phones.is_some_and(|n| n > prepared.len()) || args.loop_walks {
            bail!("--out writes one track a walk: give no more --phones than walks, and no --loop");
        }
    }
    let phones = args.phones.unwrap_or(prepared.len());
    let ramp_s = match args.ramp_s {
        Some(r) if !(r.is_finite() && r >= 0.0) => bail!("--ramp-s must be a finite number >= 0"),
        Some(r) => r,
        None => args.batch_ms as f64 / 1000.0,
    };
    if args.duration_s.is_some_and(|d| !(d.is_finite() && d > 0.0)) {
        bail!("--duration-s must be a finite number > 0");
    }
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("starting the async runtime")?;
    let summary = rt.block_on(async {
        let mut connector = HttpConnector::new();
        connector.set_nodelay(true);
        let client: Http = Client::builder(TokioExecutor::new())
            .pool_idle_timeout(Duration::from_secs(30))
            .build(connector);
        let ctx = Arc::new(Ctx {
            client,
            base: base.clone(),
            auth: format!("Bearer {token}"),
        });
        let before = server_memory(&ctx).await;
        let sem = Arc::new(tokio::sync::Semaphore::new(args.concurrency.max(1)));
        let t0 = Instant::now();
        let shared = Arc::new(PhoneSettings {
            t0,
            phones,
            speed: args.speed,
            loop_walks: args.loop_walks,
            duration_s: args.duration_s,
            out: args.out.clone(),
            format: args.format,
            keep_open: args.keep_open,
        });
        let mut tasks = Vec::new();
        let walks = Arc::new(prepared);
        for i in 0..phones {
            let (ctx, sem, shared, walks) =
                (ctx.clone(), sem.clone(), shared.clone(), walks.clone());
            let offset = start_offset(i, phones, ramp_s, args.speed, !args.no_stagger);
            tasks.push(tokio::spawn(async move {
                let _permit = sem.acquire_owned().await;
                let n = i / walks.len();
                phone(ctx, walks, i, n, offset, shared).await
            }));
        }
        // The peak: the server's memory while every phone still has its session open is read
        // by a watcher once all sessions are open (or at the end for short runs).
        let watcher = {
            let ctx = ctx.clone();
            tokio::spawn(async move {
                let mut peak: Option<(f64, f64)> = None;
                loop {
                    tokio::time::sleep(Duration::from_millis(500)).await;
                    if let Some(m) = server_memory(&ctx).await
                        && peak.is_none_or(|p| m.1 >= p.1)
                    {
                        peak = Some(m);
                    }
                    if Arc::strong_count(&ctx) <= 2 {
                        return peak;
                    }
                }
            })
        };
        let mut results = Vec::new();
        for t in tasks {
            results.push(t.await.unwrap_or_else(|e| PhoneResult {
                error: Some(format!("phone task failed: {e}")),
                ..PhoneResult::default()
            }));
        }
        let peak = watcher.await.ok().flatten();
        (results, before, peak, t0.elapsed())
    });
    let (results, before, peak, elapsed) = summary;
    // From the ramp's end until the first phone's --duration-s, every phone streams: the
    // steady state (wall time since the start). Without a ramp: the whole run.
    let paced = args.speed > 0.0 && !args.no_stagger && phones > 1;
    let steady_from_s = if paced { ramp_s / args.speed } else { 0.0 };
    let steady_to_s = match args.duration_s {
        Some(d) if paced => d / args.speed,
        _ => f64::INFINITY,
    };
    let all = latency_summary(
        results
            .iter()
            .flat_map(|r| r.latencies_ms.iter().map(|l| l.1))
            .collect(),
    );
    let steady_lat: Vec<f64> = results
        .iter()
        .flat_map(|r| r.latencies_ms.iter())
        .filter(|l| l.0 >= steady_from_s && l.0 < steady_to_s)
        .map(|l| l.1)
        .collect();
    let steady_requests = steady_lat.len();
    let steady = latency_summary(steady_lat);
    let sessions: usize = results.iter().map(|r| r.sessions).sum();
    let open_retries: usize = results.iter().map(|r| r.open_retries).sum();
    let sent: usize = results.iter().map(|r| r.sent).sum();
    let accepted: usize = results.iter().map(|r| r.accepted).sum();
    let batches: usize = results.iter().map(|r| r.batches).sum();
    let failed: usize = results.iter().map(|r| r.failed).sum();
    let rate_limited: usize = results.iter().map(|r| r.rate_limited).sum();
    let mut refused: BTreeMap<u16, usize> = BTreeMap::new();
    for r in &results {
        for (k, v) in &r.refused {
            *refused.entry(*k).or_default() += v;
        }
    }
    let errors: Vec<&String> = results.iter().filter_map(|r| r.error.as_ref()).collect();
    let max_lag = results.iter().map(|r| r.max_lag_ms).fold(0.0, f64::max);
    let (p50, p90, p99, max) = all;
    println!(
        "replay: {phones} phones ({} scheme), {sessions} sessions ({open_retries} opens retried after a 429), {batches} batches, {sent} samples sent, {accepted} accepted, refused {refused:?}, {rate_limited} rate-limited and retried, {failed} failed, in {:.1} s",
        args.scheme,
        elapsed.as_secs_f64()
    );
    println!(
        "request latency (sample batches): p50 {p50:.2} ms, p90 {p90:.2} ms, p99 {p99:.2} ms, max {max:.2} ms; largest lag behind the schedule {max_lag:.1} ms"
    );
    if steady_from_s > 0.0 {
        println!(
            "every phone streaming ({steady_from_s:.0}-{steady_to_s:.0} s, {steady_requests} requests): p50 {:.2} ms, p90 {:.2} ms, p99 {:.2} ms, max {:.2} ms",
            steady.0, steady.1, steady.2, steady.3
        );
    }
    let per_session = match (before, peak) {
        (Some((b, _)), Some((p, n))) if n > 0.0 => {
            let per = (p - b) / n;
            println!(
                "server memory: {:.1} MB before, {:.1} MB with {n} sessions open: {:.1} kB a session",
                b / 1e6,
                p / 1e6,
                per / 1e3
            );
            Some(per)
        }
        _ => None,
    };
    if let Some(p) = &args.json {
        let doc = json!({
            "phones": phones, "scheme": args.scheme, "batches": batches, "samples_sent": sent,
            "samples_accepted": accepted, "refused": refused, "rate_limited_retried": rate_limited, "failed": failed,
            "sessions": sessions, "open_retries": open_retries, "ramp_s": ramp_s,
            "latency_ms": { "p50": p50, "p90": p90, "p99": p99, "max": max },
            "steady_latency_ms": { "from_s": steady_from_s,
                "to_s": if steady_to_s.is_finite() { json!(steady_to_s) } else { Value::Null },
                "requests": steady_requests,
                "p50": steady.0, "p90": steady.1, "p99": steady.2, "max": steady.3 },
            "max_lag_ms": max_lag, "elapsed_s": elapsed.as_secs_f64(),
            "memory_bytes_before": before.map(|m| m.0), "memory_bytes_peak": peak.map(|m| m.0),
            "sessions_at_peak": peak.map(|m| m.1), "memory_bytes_per_session": per_session,
        });
        std::fs::write(p, serde_json::to_string_pretty(&doc)?)
            .with_context(|| format!("writing {}", p.display()))?;
    }
    if !errors.is_empty() {
        for e in errors.iter().take(5) {
            eprintln!("error: {e}");
        }
        bail!("{} of {phones} phones had errors", errors.len());
    }
    if accepted != sent {
        bail!("{} samples were not accepted", sent - accepted);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paced_phones_start_spread_evenly_over_one_batch_interval() {
        let offsets: Vec<Duration> = (0..4).map(|i| start_offset(i, 4, 1.0, 1.0, true)).collect();
        let ms: Vec<u128> = offsets.iter().map(Duration::as_millis).collect();
        assert_eq!(ms, [0, 250, 500, 750]);
        // Twice real time: half the interval's wall time.
        assert_eq!(start_offset(1, 2, 1.0, 2.0, true).as_millis(), 250);
        // A 30 s ramp: the last of 1,000 phones starts 29.97 s in.
        assert_eq!(start_offset(999, 1000, 30.0, 1.0, true).as_millis(), 29_970);
    }

    #[test]
    fn a_429_asks_for_its_wait_between_one_and_sixty_seconds() {
        let body = |m: &str| format!(r#"{{"error":{{"code":"too_many_opens","message":"{m}"}}}}"#);
        let wait = |m: &str| retry_after_s(body(m).as_bytes());
        assert_eq!(
            wait("the server opens at most 30 sessions a second; retry in 3 s"),
            3
        );
        assert_eq!(wait("retry in 0 s"), 1);
        assert_eq!(wait("retry in 18446744073709551615 s"), 60);
        assert_eq!(wait("no wait given"), 1);
        assert_eq!(retry_after_s(b"not json"), 1);
    }

    #[test]
    fn unpaced_unstaggered_or_single_phones_start_at_once() {
        assert_eq!(start_offset(3, 4, 1.0, 0.0, true), Duration::ZERO);
        assert_eq!(start_offset(3, 4, 1.0, 1.0, false), Duration::ZERO);
        assert_eq!(start_offset(0, 1, 1.0, 1.0, true), Duration::ZERO);
        assert_eq!(start_offset(1, 2, 0.0, 1.0, true), Duration::ZERO);
        assert_eq!(start_offset(1, 2, f64::NAN, 1.0, true), Duration::ZERO);
    }
}

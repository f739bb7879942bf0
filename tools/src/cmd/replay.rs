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
    /// Stop each phone after this much of its walk's time, seconds.
    #[arg(long)]
    pub duration_s: Option<f64>,
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
    latencies_ms: Vec<f64>,
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
    speed: f64,
    duration_s: Option<f64>,
    out: Option<PathBuf>,
    format: Format,
    keep_open: bool,
}

/// How long phone `i` of `phones` waits before opening its session, when paced: the phones
/// start spread evenly over one batch interval, as phones in a building are out of phase
/// with each other (all of them sending in the same instant would measure a burst, not a
/// load). Zero unpaced (`speed` 0), with `stagger` off, or for one phone.
fn start_offset(i: usize, phones: usize, batch_ms: i64, speed: f64, stagger: bool) -> Duration {
    if !stagger || speed <= 0.0 || phones < 2 || batch_ms <= 0 {
        return Duration::ZERO;
    }
    let share = i as f64 / phones as f64;
    Duration::try_from_secs_f64(share * batch_ms as f64 / 1000.0 / speed).unwrap_or(Duration::ZERO)
}

async fn phone(
    ctx: Arc<Ctx>,
    walk: Arc<Prepared>,
    n: usize,
    offset: Duration,
    args: Arc<PhoneSettings>,
) -> PhoneResult {
    let PhoneSettings {
        speed,
        duration_s,
        out,
        format,
        keep_open,
    } = &*args;
    tokio::time::sleep(offset).await;
    let mut r = PhoneResult::default();
    let mut create = walk.create.clone();
    if n > 0 {
        create["device"] = json!(format!("{} #{n}", walk.id));
    }
    let created = match ctx
        .call(
            Method::POST,
            "/v1/sessions",
            Some(Bytes::from(create.to_string())),
        )
        .await
    {
        Ok((StatusCode::CREATED, body, _)) => serde_json::from_slice::<Value>(&body).ok(),
        Ok((status, body, _)) => {
            r.error = Some(format!(
                "opening a session: {status}: {}",
                String::from_utf8_lossy(&body)
            ));
            return r;
        }
        Err(e) => {
            r.error = Some(format!("opening a session: {e}"));
            return r;
        }
    };
    let Some(id) = created
        .as_ref()
        .and_then(|v| v["id"].as_str())
        .map(str::to_string)
    else {
        r.error = Some("opening a session: no id in the answer".into());
        return r;
    };
    let start = Instant::now();
    let path = format!("/v1/sessions/{id}/samples");
    for (t_end, body, count) in &walk.batches {
        if duration_s.is_some_and(|d| *t_end as f64 > d * 1000.0 + 1e-9) {
            break;
        }
        if *speed > 0.0 {
            let due = start + Duration::from_secs_f64(*t_end as f64 / 1000.0 / speed);
            tokio::time::sleep_until(due.into()).await;
            r.max_lag_ms = r
                .max_lag_ms
                .max(Instant::now().saturating_duration_since(due).as_secs_f64() * 1e3);
        }
        r.batches += 1;
        r.sent += count;
        // A 429 is retried after its Retry-After, as a phone would (at most 20 times).
        let mut attempts = 0;
        loop {
            attempts += 1;
            match ctx.call(Method::POST, &path, Some(body.clone())).await {
                Ok((StatusCode::OK, resp, lat)) => {
                    r.latencies_ms.push(lat.as_secs_f64() * 1e3);
                    let v: Value = serde_json::from_slice(&resp).unwrap_or(Value::Null);
                    r.accepted += v["accepted"].as_u64().unwrap_or(0) as usize;
                }
                Ok((StatusCode::TOO_MANY_REQUESTS, resp, lat)) if attempts <= 20 => {
                    r.latencies_ms.push(lat.as_secs_f64() * 1e3);
                    r.rate_limited += 1;
                    let v: Value = serde_json::from_slice(&resp).unwrap_or(Value::Null);
                    let wait = v["error"]["message"]
                        .as_str()
                        .and_then(|m| m.rsplit("retry in ").next())
                        .and_then(|m| m.trim_end_matches(" s").parse::<u64>().ok())
                        .unwrap_or(1)
                        .clamp(1, 60);
                    tokio::time::sleep(Duration::from_secs(wait)).await;
                    continue;
                }
                Ok((status, resp, lat)) => {
                    r.latencies_ms.push(lat.as_secs_f64() * 1e3);
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
    r
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
        if args.phones.is_some_and(|n| n > prepared.len()) {
            bail!("--out writes one track a walk: give no more --phones than walks");
        }
    }
    let phones = args.phones.unwrap_or(prepared.len());
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
        let shared = Arc::new(PhoneSettings {
            speed: args.speed,
            duration_s: args.duration_s,
            out: args.out.clone(),
            format: args.format,
            keep_open: args.keep_open,
        });
        let t0 = Instant::now();
        let mut tasks = Vec::new();
        let walks = prepared.len();
        for i in 0..phones {
            let walk = prepared[i % prepared.len()].clone();
            let (ctx, sem, shared) = (ctx.clone(), sem.clone(), shared.clone());
            let offset = start_offset(i, phones, args.batch_ms, args.speed, !args.no_stagger);
            tasks.push(tokio::spawn(async move {
                let _permit = sem.acquire_owned().await;
                phone(ctx, walk, i / walks, offset, shared).await
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
    let mut lat: Vec<f64> = results
        .iter()
        .flat_map(|r| r.latencies_ms.clone())
        .collect();
    lat.sort_by(f64::total_cmp);
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
    let (p50, p90, p99, max) = (
        percentile(&lat, 0.5),
        percentile(&lat, 0.9),
        percentile(&lat, 0.99),
        lat.last().copied().unwrap_or(f64::NAN),
    );
    println!(
        "replay: {phones} phones ({} scheme), {batches} batches, {sent} samples sent, {accepted} accepted, refused {refused:?}, {rate_limited} rate-limited and retried, {failed} failed, in {:.1} s",
        args.scheme,
        elapsed.as_secs_f64()
    );
    println!(
        "request latency (sample batches): p50 {p50:.2} ms, p90 {p90:.2} ms, p99 {p99:.2} ms, max {max:.2} ms; largest lag behind the schedule {max_lag:.1} ms"
    );
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
            "latency_ms": { "p50": p50, "p90": p90, "p99": p99, "max": max },
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
        let offsets: Vec<Duration> = (0..4)
            .map(|i| start_offset(i, 4, 1000, 1.0, true))
            .collect();
        let ms: Vec<u128> = offsets.iter().map(Duration::as_millis).collect();
        assert_eq!(ms, [0, 250, 500, 750]);
        // Twice real time: half the interval's wall time.
        assert_eq!(start_offset(1, 2, 1000, 2.0, true).as_millis(), 250);
    }

    #[test]
    fn unpaced_unstaggered_or_single_phones_start_at_once() {
        assert_eq!(start_offset(3, 4, 1000, 0.0, true), Duration::ZERO);
        assert_eq!(start_offset(3, 4, 1000, 1.0, false), Duration::ZERO);
        assert_eq!(start_offset(0, 1, 1000, 1.0, true), Duration::ZERO);
        assert_eq!(start_offset(1, 2, 0, 1.0, true), Duration::ZERO);
    }
}

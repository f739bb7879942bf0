//! `wipdr-serve`: wipdr as a service. Phones (or any client) open a **session** over HTTP,
//! post batches of raw samples in the plain sample format (`wipdr_io::sample_stream`, as
//! JSON), and get back the estimates of a [`wipdr_positioning::Positioner`] built from one
//! site model (`site.wipdr`) for that session; tracks and session metadata are kept in SQLite;
//! a live map page at `/` shows every open session of a token on the floor plan. `wipdr serve`
//! runs it; `wipdr replay` streams recorded walks to it (and is its load generator).
//!
//! The stack is **axum on tokio (hyper underneath)**: the Rust community's standard async HTTP
//! stack, maintained by the tokio project, with the tower middleware ecosystem; its extractors
//! make every request field typed and every refusal a value (no panics from input), and it
//! serves Server-Sent Events without another dependency. Only the features used are compiled
//! (HTTP/1, no TLS: a reverse proxy ends TLS in front of it). SQLite through `rusqlite` with
//! the bundled library (no system library; WAL; batched transactions on a flush interval).
//!
//! One concern a file: [`router`] (routes and handlers), [`sessions`] (a positioner per
//! session, stream order, rate budget), [`auth`] (bearer tokens, constant-time), [`db`]
//! (SQLite), [`metrics`] (Prometheus text), [`openapi`] (the API document), [`page`] (the
//! live map), [`errors`] (typed error bodies).
//!
//! **Equivalence**: a walk replayed through a session in stream order gives exactly (`f64`
//! equality) the track `wipdr locate --model` gives for it, at any batch size: the samples are
//! converted as the stream reader converts them and pushed in the same order into a
//! positioner built with the same [`wipdr_positioning::StreamSpec`] (stream id, phone model
//! and start time).
//!
//! ```no_run
//! # async fn run() -> Result<(), wipdr_serve::errors::ServeError> {
//! use wipdr_serve::{ServeConfig, Server, auth::Tokens};
//! let model = wipdr_positioning::SiteModel::load("site.wipdr").expect("a model");
//! let tokens = Tokens::from_tokens(["0123456789abcdef-phone-fleet"]);
//! let server = Server::bind("127.0.0.1:0", model, tokens, "tracks.sqlite".as_ref(), ServeConfig::default()).await?;
//! println!("listening on {}", server.local_addr());
//! server.run(async { let _ = tokio::signal::ctrl_c().await; }).await
//! # }
//! ```

pub mod auth;
pub mod db;
pub mod errors;
pub mod metrics;
pub mod openapi;
pub mod page;
pub mod router;
pub mod sessions;

use crate::auth::Tokens;
use crate::db::{Db, StoredEstimate, Write};
use crate::errors::ServeError;
use crate::metrics::Metrics;
use crate::sessions::Registry;
use serde::Serialize;
use std::future::Future;
use std::net::SocketAddr;
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::{broadcast, watch};
use wipdr_positioning::SiteModel;

/// The server's settings (`wipdr serve` flags).
#[derive(Debug, Clone, PartialEq)]
pub struct ServeConfig {
    /// Largest request body, bytes (larger: 413).
    pub max_body_bytes: usize,
    /// Samples a second a session may send, on average (more: 429).
    pub max_samples_per_s: f64,
    /// Seconds of [`ServeConfig::max_samples_per_s`] a session may send at once (the
    /// bucket's size; a batch larger than it is always refused).
    pub burst_s: f64,
    /// Open sessions a token may have (more: 429).
    pub max_sessions_per_token: usize,
    /// A session without a batch for this long is closed (reason `idle`).
    pub idle_timeout: Duration,
    /// How often queued writes go to the database (what a `kill -9` may lose).
    pub flush_interval: Duration,
    /// Most access points in one scan.
    pub max_scan_entries: usize,
    /// Sessions the server opens a second, over all tokens (more: 429 with Retry-After);
    /// `None`: no limit. A new `pmf` session weighs a lattice over the whole floor until its
    /// first fixes, so a crowd of them at once (every phone reconnecting after a restart)
    /// delays every session's answers; this spreads them (`docs/results/serve.md` measures
    /// a value).
    pub max_opens_per_s: Option<f64>,
}

impl Default for ServeConfig {
    fn default() -> Self {
        Self {
            max_body_bytes: 4 << 20,
            max_samples_per_s: 1000.0,
            burst_s: 10.0,
            max_sessions_per_token: 5000,
            idle_timeout: Duration::from_secs(300),
            flush_interval: Duration::from_secs(1),
            max_scan_entries: wipdr_io::Limits::default().max_scan_entries,
            max_opens_per_s: None,
        }
    }
}

impl ServeConfig {
    /// Checks the settings.
    pub fn check(&self) -> Result<(), ServeError> {
        let bad = |field, message: &str| {
            Err(ServeError::Config {
                field,
                message: message.into(),
            })
        };
        if self.max_body_bytes < 1024 {
            return bad("max_body_bytes", "at least 1024");
        }
        if !(self.max_samples_per_s.is_finite() && self.max_samples_per_s > 0.0) {
            return bad("max_samples_per_s", "a finite number > 0");
        }
        if !(self.burst_s.is_finite() && self.burst_s > 0.0) {
            return bad("burst_s", "a finite number > 0");
        }
        if self.max_sessions_per_token == 0 {
            return bad("max_sessions_per_token", "at least 1");
        }
        if self
            .max_opens_per_s
            .is_some_and(|r| !(r.is_finite() && r > 0.0))
        {
            return bad("max_opens_per_s", "a finite number > 0");
        }
        if self.flush_interval.is_zero() || self.idle_timeout.is_zero() {
            return bad("flush_interval", "intervals are > 0");
        }
        Ok(())
    }
}

/// What the live streams carry: a session's new estimate, or its end.
#[derive(Debug, Clone, Serialize)]
pub struct LiveEvent {
    /// `estimate` or `closed`.
    pub kind: &'static str,
    /// The session.
    pub session: String,
    /// Its owner (not sent).
    #[serde(skip)]
    pub owner: auth::Owner,
    /// Its device label.
    pub device: String,
    /// Its scheme.
    pub scheme: String,
    /// The estimate (`estimate` events).
    pub estimate: Option<StoredEstimate>,
    /// The 95 % radius, metres (`2.4477 sd_m`: a circular Gaussian's 95 % circle).
    pub r95_m: Option<f64>,
}

/// The radius holding 95 % of a circular Gaussian of standard deviation `sd` per axis:
/// `sd sqrt(chi2_2(0.95))`.
pub fn radius_95(sd: f64) -> f64 {
    sd * 5.991_464_547_107_979_f64.sqrt()
}

/// Everything a handler reaches.
#[derive(Debug)]
pub struct AppState {
    /// The site model every session runs on.
    pub model: Arc<SiteModel>,
    /// The accepted tokens.
    pub tokens: Tokens,
    /// The database.
    pub db: Arc<Db>,
    /// The open sessions.
    pub registry: Registry,
    /// The counters.
    pub metrics: Metrics,
    /// The settings.
    pub config: ServeConfig,
    /// The live event bus.
    pub live: broadcast::Sender<Arc<LiveEvent>>,
    /// The bucket of session opens ([`ServeConfig::max_opens_per_s`]; one second's worth).
    pub opens: Option<std::sync::Mutex<sessions::Bucket>>,
    /// Set when the server stops (ends the live streams).
    pub stopping: watch::Receiver<bool>,
}

fn now_unix_ms() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_millis() as i64)
        .unwrap_or(0)
}

impl AppState {
    /// State over an opened database (tests build routers on it without a socket).
    pub fn new(
        model: SiteModel,
        tokens: Tokens,
        db: Db,
        config: ServeConfig,
    ) -> Result<(Arc<Self>, watch::Sender<bool>), ServeError> {
        config.check()?;
        let (live, _) = broadcast::channel(4096);
        let (stop_tx, stopping) = watch::channel(false);
        Ok((
            Arc::new(Self {
                model: Arc::new(model),
                tokens,
                db: Arc::new(db),
                registry: Registry::default(),
                metrics: Metrics::default(),
                opens: config.max_opens_per_s.map(|r| {
                    std::sync::Mutex::new(sessions::Bucket::new(
                        r,
                        r.max(1.0),
                        std::time::Instant::now(),
                    ))
                }),
                config,
                live,
                stopping,
            }),
            stop_tx,
        ))
    }

    /// Closes an open session: out of the registry, its end queued for the database and
    /// announced to the live streams. `false` when it was not open.
    pub fn close_session(&self, id: &str, reason: &str) -> bool {
        let Some(s) = self.registry.get_any(id) else {
            return false;
        };
        if !self.registry.remove(id) {
            return false;
        }
        let s = sessions::lock(&s);
        self.db.queue(Write::Closed {
            session: id.to_string(),
            at_unix_ms: now_unix_ms(),
            reason: reason.to_string(),
            last_sample_t_ms: s.last_sample_t(),
        });
        self.metrics
            .sessions_closed
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let _ = self.live.send(Arc::new(LiveEvent {
            kind: "closed",
            session: id.to_string(),
            owner: s.record.owner,
            device: s.record.device.clone(),
            scheme: s.record.scheme.clone(),
            estimate: None,
            r95_m: None,
        }));
        tracing::info!(session = id, reason, "session closed");
        true
    }

    /// Flushes the database off the async threads.
    pub async fn flush(self: &Arc<Self>) -> Result<usize, ServeError> {
        let db = self.db.clone();
        match tokio::task::spawn_blocking(move || db.flush()).await {
            Ok(r) => r,
            Err(e) => {
                tracing::error!("flush task failed: {e}");
                Ok(0)
            }
        }
    }
}

/// A bound server, ready to [`Server::run`].
#[derive(Debug)]
pub struct Server {
    state: Arc<AppState>,
    stop: watch::Sender<bool>,
    listener: tokio::net::TcpListener,
    addr: SocketAddr,
}

impl Server {
    /// Opens the database (closing sessions a previous run left open) and binds `addr`
    /// (`127.0.0.1:0` for any free port).
    pub async fn bind(
        addr: &str,
        model: SiteModel,
        tokens: Tokens,
        db_path: &Path,
        config: ServeConfig,
    ) -> Result<Self, ServeError> {
        let db = Db::open(db_path, now_unix_ms())?;
        let (state, stop) = AppState::new(model, tokens, db, config)?;
        let sock = |source| ServeError::Socket {
            addr: addr.to_string(),
            source,
        };
        let listener = tokio::net::TcpListener::bind(addr).await.map_err(sock)?;
        let addr = listener.local_addr().map_err(sock)?;
        Ok(Self {
            state,
            stop,
            listener,
            addr,
        })
    }

    /// The bound address.
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    /// The state (for embedding and tests).
    pub fn state(&self) -> &Arc<AppState> {
        &self.state
    }

    /// Serves until `shutdown` completes; then stops taking requests, ends the live streams,
    /// closes every open session (reason `shutdown`) and flushes the database.
    pub async fn run(
        self,
        shutdown: impl Future<Output = ()> + Send + 'static,
    ) -> Result<(), ServeError> {
        let Self {
            state,
            stop,
            listener,
            addr,
        } = self;
        let background = tokio::spawn(background(state.clone()));
        let app = router::router(state.clone());
        let stop_for_signal = stop.clone();
        let served = axum::serve(listener, app)
            .with_graceful_shutdown(async move {
                shutdown.await;
                tracing::info!("stopping: no new requests, live streams ended");
                let _ = stop_for_signal.send(true);
            })
            .await;
        let _ = stop.send(true);
        background.abort();
        let open: Vec<String> = state
            .registry
            .all(None)
            .iter()
            .map(|s| sessions::lock(s).record.id.clone())
            .collect();
        for id in &open {
            state.close_session(id, "shutdown");
        }
        let flushed = state.flush().await;
        tracing::info!(sessions = open.len(), "stopped; database flushed");
        served.map_err(|source| ServeError::Socket {
            addr: addr.to_string(),
            source,
        })?;
        flushed.map(|_| ())
    }
}

/// The periodic jobs: flushes on the flush interval, the samples-a-second gauge and the
/// idle sessions' expiry every second.
async fn background(state: Arc<AppState>) {
    let mut flush = tokio::time::interval(state.config.flush_interval);
    let mut tick = tokio::time::interval(Duration::from_secs(1));
    flush.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        tokio::select! {
            _ = flush.tick() => {
                if let Err(e) = state.flush().await {
                    tracing::error!("flush failed (retried next time): {e}");
                }
            }
            _ = tick.tick() => {
                state.metrics.tick();
                if let Some(cutoff) = Instant::now().checked_sub(state.config.idle_timeout) {
                    for id in state.registry.idle_since(cutoff) {
                        state.close_session(&id, "idle");
                    }
                }
            }
        }
    }
}

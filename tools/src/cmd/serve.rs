//! `wipdr serve`: positioning as a service over HTTP (`wipdr_serve`): sessions of phones post
//! sample batches, a site model's positioner per session answers; tracks in SQLite; a live
//! map at `/`.
//!
//! ```text
//! wipdr serve --model site1.wipdr --addr 127.0.0.1:8080 --tokens tokens.txt --db tracks.sqlite
//! ```
//!
//! Without `--tokens`, a random token is written to `<db>.token` (mode 0600) and the file named
//! (the token itself is never printed or logged). The first line on stderr is `wipdr serve:
//! listening on http://ADDR` (with `--addr 127.0.0.1:0`, the port chosen). SIGTERM or Ctrl-C
//! stops it: no new requests, live streams ended, open sessions closed, the database flushed.

use anyhow::{Context, Result};
use std::path::{Path, PathBuf};
use std::time::Duration;
use wipdr_positioning::SiteModel;
use wipdr_serve::{ServeConfig, Server, auth::Tokens};

/// Arguments of `wipdr serve`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The site model (`wipdr fit`) every session runs on.
    #[arg(long)]
    pub model: PathBuf,
    /// Address to listen on (`127.0.0.1:0`: any free port, printed).
    #[arg(long, default_value = "127.0.0.1:8080")]
    pub addr: String,
    /// Bearer tokens, one a line (`#` comments). Default: a new random token in `<db>.token`.
    #[arg(long)]
    pub tokens: Option<PathBuf>,
    /// The SQLite database of sessions and tracks (created if missing).
    #[arg(long, default_value = "tracks.sqlite")]
    pub db: PathBuf,
    /// How often estimates are written to the database, ms (what a `kill -9` may lose).
    #[arg(long, default_value_t = 1000)]
    pub flush_ms: u64,
    /// Samples a second a session may send on average (more: 429).
    #[arg(long, default_value_t = 1000.0)]
    pub max_samples_per_s: f64,
    /// Seconds of that rate a session may send at once.
    #[arg(long, default_value_t = 10.0)]
    pub burst_s: f64,
    /// Largest request body, bytes (more: 413).
    #[arg(long, default_value_t = 4 << 20)]
    pub max_body_bytes: usize,
    /// Open sessions a token may have (more: 429).
    #[arg(long, default_value_t = 5000)]
    pub max_sessions_per_token: usize,
    /// Sessions the server opens a second, over all tokens (more: 429 with Retry-After):
    /// spreads a crowd of new sessions, e.g. every phone reconnecting after a restart.
    /// Default: no limit. 30 keeps 1,000 shipped-`pmf` phones reconnecting at once under
    /// 50 ms p99 on a 2-core machine (docs/results/serve.md).
    #[arg(long)]
    pub max_opens_per_s: Option<f64>,
    /// Sessions without a batch for this long are closed, seconds.
    #[arg(long, default_value_t = 300)]
    pub idle_timeout_s: u64,
    /// Worker threads (default: one per core).
    #[arg(long)]
    pub workers: Option<usize>,
}

/// Runs the subcommand.
pub fn run(args: Args) -> Result<()> {
    let model = SiteModel::load(&args.model)
        .with_context(|| format!("loading the site model {}", args.model.display()))?;
    let tokens = match &args.tokens {
        Some(p) => Tokens::load(p)?,
        None => {
            let path = token_file_of(&args.db);
            let token = wipdr_serve::auth::generate_token();
            write_private(&path, &format!("{token}\n"))
                .with_context(|| format!("writing {}", path.display()))?;
            eprintln!(
                "wipdr serve: no --tokens: a new token is in {} (send it as Authorization: Bearer TOKEN)",
                path.display()
            );
            Tokens::from_tokens([token.as_str()])
        }
    };
    let config = ServeConfig {
        max_body_bytes: args.max_body_bytes,
        max_samples_per_s: args.max_samples_per_s,
        burst_s: args.burst_s,
        max_sessions_per_token: args.max_sessions_per_token,
        idle_timeout: Duration::from_secs(args.idle_timeout_s),
        flush_interval: Duration::from_millis(args.flush_ms),
        max_opens_per_s: args.max_opens_per_s,
        ..ServeConfig::default()
    };
    let mut rt = tokio::runtime::Builder::new_multi_thread();
    if let Some(n) = args.workers {
        rt.worker_threads(n.max(1));
    }
    let rt = rt
        .enable_all()
        .build()
        .context("starting the async runtime")?;
    rt.block_on(async move {
        let server = Server::bind(&args.addr, model, tokens, &args.db, config).await?;
        eprintln!("wipdr serve: listening on http://{}", server.local_addr());
        server.run(stop_signal()).await?;
        eprintln!("wipdr serve: stopped, database flushed");
        Ok(())
    })
}

/// `<db>.token`.
fn token_file_of(db: &Path) -> PathBuf {
    let mut name = db.as_os_str().to_owned();
    name.push(".token");
    PathBuf::from(name)
}

fn write_private(path: &Path, text: &str) -> std::io::Result<()> {
    use std::io::Write;
    let mut opts = std::fs::OpenOptions::new();
    opts.write(true).create(true).truncate(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        opts.mode(0o600);
    }
    opts.open(path)?.write_all(text.as_bytes())
}

/// SIGTERM or Ctrl-C.
async fn stop_signal() {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{SignalKind, signal};
        match signal(SignalKind::terminate()) {
            Ok(mut term) => {
                tokio::select! {
                    _ = term.recv() => {}
                    _ = tokio::signal::ctrl_c() => {}
                }
            }
            Err(_) => {
                let _ = tokio::signal::ctrl_c().await;
            }
        }
    }
    #[cfg(not(unix))]
    {
        let _ = tokio::signal::ctrl_c().await;
    }
}

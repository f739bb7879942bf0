//! `wipdr` — the command-line program of the wipdr workspace: inspect recorded walks,
//! simulate synthetic ones, plot floors, benchmark matchers, evaluate and sweep fusion schemes,
//! score estimates as the IPIN competition does.
//!
//! Each subcommand lives in its own module under `cmd/` with an `Args` struct and a `run`
//! function. Only this program prints and installs a `tracing` subscriber; the libraries log.

use clap::{Parser, Subcommand};
use std::path::PathBuf;
use tracing_subscriber::EnvFilter;

mod cmd;
mod data;
mod eval_plots;
mod plotting;
mod progress;
mod report;
mod survey_plot;

/// Indoor positioning by Wi-Fi fingerprinting fused with pedestrian dead reckoning.
#[derive(Debug, Parser)]
#[command(name = "wipdr", version, about, long_about = None)]
struct Cli {
    /// More log output (-v info, -vv debug, -vvv trace); RUST_LOG overrides.
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,
    /// Cache folder for parsed floors (default: $WIPDR_CACHE_DIR, else target/wipdr-cache).
    #[arg(long, global = true, value_name = "DIR")]
    cache_dir: Option<PathBuf>,
    /// Read floors from source, bypassing (and not writing) the parse cache.
    #[arg(long, global = true)]
    no_cache: bool,
    /// Size cap of the parse cache, MiB (default: $WIPDR_CACHE_MAX_MB, else 2048); the least
    /// recently used cache files beyond it are removed.
    #[arg(long, global = true, value_name = "MIB")]
    cache_max_mb: Option<u64>,
    /// The subcommand.
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Summarise a walk file or a floor folder, with the parse report.
    Inspect(cmd::inspect::Args),
    /// Generate a synthetic floor with walks and a survey radio map (reproducible from a seed).
    Simulate(cmd::simulate::Args),
    /// Draw pictures: `wipdr plot floor DIR --out FILE.png`.
    Plot(cmd::plot::Args),
    /// Evaluate fingerprint matchers on benchmark datasets (train.csv / test.csv).
    FingerprintEval(cmd::fingerprint_eval::Args),
    /// Cluster a dataset's radio map with affinity propagation.
    Cluster(cmd::cluster::Args),
    /// Fit PDR step-length coefficients and calibration from walks with waypoints.
    PdrFit(cmd::pdr_fit::Args),
    /// Evaluate PDR on recorded walks under the protocol folds.
    PdrEval(cmd::pdr_eval::Args),
    /// Evaluate fusion schemes on recorded walks under the protocol folds.
    Eval(cmd::eval::Args),
    /// The report page of a saved run: `wipdr report RESULTS.json --out FILE.html`.
    Report(cmd::report::Args),
    /// The IPIN competition's official scoring of EvAAL API estimates files against a
    /// trial's ground truth: `wipdr score --truth GT.csv EST_FILE...`.
    Score(cmd::score::Args),
    /// Play an IPIN competition trial through the EvAAL API with a site model (causal).
    Evaal(cmd::evaal::Args),
    /// Learn a site once (radio map, calibration, references) and save it as a model file.
    Fit(cmd::fit::Args),
    /// Write a recorded walk as a plain sample stream (CSV), the format `locate` reads.
    ExportStream(cmd::export_stream::Args),
    /// Position phone logs with a site model, streaming their samples through the Positioner.
    Locate(cmd::locate::Args),
    /// Positioning as a service: an HTTP server of sessions on a site model, with a live map.
    Serve(cmd::serve::Args),
    /// Stream recorded walks to a `wipdr serve` as phones would (also the load generator).
    Replay(cmd::replay::Args),
    /// Run the evaluation on the embedded synthetic fixtures, in seconds.
    Demo(cmd::demo::Args),
    /// Parameter sweeps over scheme configs, resumable and shardable.
    Sweep(cmd::sweep::Args),
    /// Wi-Fi refresh and loss rates against RSSI, with the RR model fit (paper 002 §3.1).
    WifiStats(cmd::wifi_stats::Args),
    /// The parse cache: `wipdr cache info` (location, files, size) or `wipdr cache clear`.
    Cache(cmd::cache::Args),
}

fn main() -> std::process::ExitCode {
    data::exit_quietly_on_broken_pipe();
    let cli = Cli::parse();
    let level = match cli.verbose {
        0 => "warn",
        1 => "info",
        2 => "debug",
        _ => "trace",
    };
    let filter = EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new(level));
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .init();
    match data::resolve_cache(cli.cache_dir, cli.no_cache, cli.cache_max_mb) {
        Ok(settings) => data::set_cache(settings),
        Err(e) => {
            eprintln!("error: {e:#}");
            return std::process::ExitCode::FAILURE;
        }
    }
    let result = match cli.command {
        Command::Inspect(a) => cmd::inspect::run(a),
        Command::Simulate(a) => cmd::simulate::run(a),
        Command::Plot(a) => cmd::plot::run(a),
        Command::FingerprintEval(a) => cmd::fingerprint_eval::run(a),
        Command::Cluster(a) => cmd::cluster::run(a),
        Command::PdrFit(a) => cmd::pdr_fit::run(a),
        Command::PdrEval(a) => cmd::pdr_eval::run(a),
        Command::Eval(a) => cmd::eval::run(a),
        Command::Report(a) => cmd::report::run(a),
        Command::Score(a) => cmd::score::run(a),
        Command::Evaal(a) => cmd::evaal::run(a),
        Command::Fit(a) => cmd::fit::run(a),
        Command::ExportStream(a) => cmd::export_stream::run(a),
        Command::Locate(a) => cmd::locate::run(a),
        Command::Serve(a) => cmd::serve::run(a),
        Command::Replay(a) => cmd::replay::run(a),
        Command::Demo(a) => cmd::demo::run(a),
        Command::Sweep(a) => cmd::sweep::run(a),
        Command::WifiStats(a) => cmd::wifi_stats::run(a),
        Command::Cache(a) => cmd::cache::run(a),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        // The reader of our output went away (`wipdr inspect F | head -1`): not an error.
        Err(e) if data::is_broken_pipe(&e) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

//! `wipdr sweep`: parameter sweeps over any config field, rayon-parallel, resumable,
//! shardable; `wipdr sweep merge` joins shard files.

use crate::{data, progress};
use anyhow::{Context, Result, bail};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};
use wipdr_eval::sweep::{self, RunIdentity, ShardId, SweepOptions, SweepSpec};

/// Arguments of `wipdr sweep`.
#[derive(Debug, clap::Args)]
#[command(args_conflicts_with_subcommands = true)]
pub struct Args {
    /// `merge` joins shard files.
    #[command(subcommand)]
    merge: Option<Sub>,
    /// The sweep file (TOML: scheme, objective, grid and/or random ranges; see `docs/guide.md`).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Floor folders.
    #[arg(long, num_args = 1..)]
    data: Vec<PathBuf>,
    /// Results CSV: one row per finished config, appended and flushed at once; its run
    /// identity is written beside it as `RESULTS.csv.run.json`.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Continue an existing results file, skipping finished configs; refused when the file's
    /// run identity (`RESULTS.run.json`: sweep spec, base config, data, shard) differs.
    #[arg(long)]
    resume: bool,
    /// Run one deterministic slice `I/N` (configs with index % N == I), for batch systems.
    #[arg(long)]
    shard: Option<String>,
    /// Base evaluation config the sweep varies (TOML); defaults otherwise.
    #[arg(long)]
    base: Option<PathBuf>,
    /// Stop after this many configs (the rest can be resumed).
    #[arg(long)]
    max_configs: Option<usize>,
    /// The most configs the sweep file may expand to (all shards together); a larger sweep
    /// is refused before it starts. Default: 100000.
    #[arg(long)]
    config_limit: Option<usize>,
    /// Where to write the best config (default: the results file with `.best.toml`).
    #[arg(long)]
    best_out: Option<PathBuf>,
}

#[derive(Debug, clap::Subcommand)]
enum Sub {
    /// Join shard result files into one, sorted by config index (refused unless all are
    /// shards of one sweep: same spec, base config and data, each shard once).
    Merge {
        /// Output CSV.
        #[arg(long)]
        out: PathBuf,
        /// Shard CSVs.
        #[arg(required = true)]
        shards: Vec<PathBuf>,
    },
}

/// The command line that continues a stopped sweep: this one, with `--resume` added.
fn resume_command(spec: &Path, out: &Path) -> String {
    let args: Vec<String> = std::env::args().collect();
    if args.is_empty() {
        return format!(
            "wipdr sweep --config {} --data ... --out {} --resume",
            spec.display(),
            out.display()
        );
    }
    let mut line: Vec<String> = args.iter().map(|a| shell_quote(a)).collect();
    if !args.iter().any(|a| a == "--resume") {
        line.push("--resume".into());
    }
    line.join(" ")
}

/// Quotes a word for a POSIX shell when it needs it.
fn shell_quote(word: &str) -> String {
    let plain = !word.is_empty()
        && word
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_./=:,@+%".contains(c));
    if plain {
        word.to_string()
    } else {
        format!("'{}'", word.replace('\'', "'\\''"))
    }
}

/// The process's stop flag, with the Ctrl-C handler installed once: the first Ctrl-C stops
/// starting new configs (the running ones finish and are written), a second exits at once.
fn stop_flag() -> Result<Arc<AtomicBool>> {
    static FLAG: OnceLock<Arc<AtomicBool>> = OnceLock::new();
    if let Some(flag) = FLAG.get() {
        return Ok(flag.clone());
    }
    let stop = Arc::new(AtomicBool::new(false));
    let handler_flag = stop.clone();
    ctrlc::set_handler(move || {
        if handler_flag.swap(true, Ordering::SeqCst) {
            // A second Ctrl-C: leave at once. Every finished row is already flushed.
            eprintln!("\nsecond Ctrl-C: exiting now (finished configs are in the file)");
            std::process::exit(130);
        }
        eprintln!(
            "\nCtrl-C: no new configs will start; waiting for the running ones to finish \
             (Ctrl-C again to exit at once)"
        );
    })
    .context("installing the Ctrl-C handler")?;
    Ok(FLAG.get_or_init(|| stop).clone())
}

/// Runs the subcommand.
pub fn run(args: Args) -> Result<()> {
    if let Some(Sub::Merge { out, shards }) = args.merge {
        let rows = sweep::merge(&shards, &out)?;
        let total = RunIdentity::read(&out)?.configs;
        println!(
            "merged {} shard files: {} of {} configs into {}{}",
            shards.len(),
            rows.len(),
            total,
            out.display(),
            if rows.len() < total {
                " (incomplete: shards missing or unfinished; `wipdr sweep --resume` on it runs the rest)"
            } else {
                ""
            }
        );
        return Ok(());
    }
    let spec_path = args.config.context("--config SWEEP.toml is required")?;
    let out = args.out.context("--out RESULTS.csv is required")?;
    if args.data.is_empty() {
        bail!("--data FLOOR_DIR... is required");
    }
    let text = std::fs::read_to_string(&spec_path)
        .with_context(|| format!("reading {}", spec_path.display()))?;
    let spec =
        SweepSpec::from_toml(&text).with_context(|| format!("parsing {}", spec_path.display()))?;
    let base = crate::cmd::eval::load_config(args.base.as_deref())?;
    let shard = args
        .shard
        .as_deref()
        .map(str::parse::<ShardId>)
        .transpose()?
        .map(|s| (s.index, s.count));
    // Checked before reading any data: a sweep too large to run is refused at once.
    let limit = args.config_limit.unwrap_or(sweep::DEFAULT_CONFIG_LIMIT);
    let total = spec.check(limit)?;
    let in_shard = match shard {
        Some((i, n)) => (total + n - 1 - i) / n,
        None => total,
    };
    let floors = data::load_floors(&args.data)?;
    let stop = stop_flag()?;
    stop.store(false, Ordering::SeqCst);
    let options = SweepOptions {
        resume: args.resume,
        shard,
        max_configs: args.max_configs,
        config_limit: Some(limit),
        stop: Some(stop),
    };
    let pb = progress::bar(in_shard as u64, "configs");
    let started = std::time::Instant::now();
    let outcome = sweep::run_sweep(&spec, &base, &floors, &out, &options, &|| pb.inc(1))?;
    pb.finish_and_clear();
    println!(
        "{} configs run, {} already in {}, {:.1} s{}",
        outcome.ran,
        outcome.skipped,
        out.display(),
        started.elapsed().as_secs_f64(),
        if outcome.complete {
            ""
        } else {
            " (incomplete: run again with --resume)"
        }
    );
    if outcome.stopped {
        eprintln!(
            "\nstopped by Ctrl-C: {} of {} configs are in {}. To continue:\n  {}",
            outcome.rows.len(),
            in_shard,
            out.display(),
            resume_command(&spec_path, &out)
        );
        std::process::exit(130);
    }
    let mut best: Vec<&sweep::SweepRow> = outcome.rows.iter().collect();
    best.sort_by(|a, b| a.objective.total_cmp(&b.objective));
    println!("\nbest by {:?} ({}):", spec.objective, spec.scheme);
    for r in best.iter().take(5) {
        println!(
            "  #{:<5} {:>7.3}  mean {:.2}  p95 {:.2}  n {}  {}",
            r.index, r.objective, r.summary.mean, r.summary.p95, r.summary.count, r.id
        );
    }
    // Only from a row measured for this sweep's config at its index (its hash checked).
    match sweep::best_config(&spec, &base, &outcome.rows, Some(limit))? {
        Some((_, cfg)) => {
            let path = args
                .best_out
                .unwrap_or_else(|| out.with_extension("best.toml"));
            std::fs::write(&path, toml::to_string_pretty(&cfg)?)
                .with_context(|| format!("writing {}", path.display()))?;
            println!(
                "\nbest config written to {} (use with `wipdr eval --config`)",
                path.display()
            );
        }
        None => println!("\nno config scored a finite objective: no best config written"),
    }
    Ok(())
}

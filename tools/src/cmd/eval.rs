//! `wipdr eval`: the protocol of `docs/evaluation.md` on recorded walks, for any schemes.

use crate::{data, eval_plots, progress};
use anyhow::{Context, Result};
use std::path::{Path, PathBuf};
use wipdr_eval::pipeline::{self, EvalConfig, FloorInput};
use wipdr_eval::report::EvalReport;

/// Arguments of `wipdr eval`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Floor folders (ILC layout: `path_data_files/`, `floor_info.json`, `geojson_map.json`).
    #[arg(long, num_args = 1.., required = true)]
    pub data: Vec<PathBuf>,
    /// Schemes to run, comma separated (wifi, pdr, ekf, aekf, akf, rkf, arkf, aws, tcpf, pf, apf, rof).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "wifi,pdr,ekf,aekf,akf,rkf,arkf,aws,tcpf,pf,apf,rof,pmf"
    )]
    pub schemes: Vec<String>,
    /// Evaluation config (TOML; see `docs/guide.md`); defaults otherwise.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Write the figures (pooled, per floor, per walk) as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write plots into this folder: trajectories, error CDF, error against time.
    #[arg(long)]
    pub plots: Option<PathBuf>,
    /// How many walks per floor get a trajectory plot.
    #[arg(long, default_value_t = 2)]
    pub plot_walks: usize,
    /// Plot the walks with the largest mean error of the last scheme listed (default: the
    /// first walks of each floor).
    #[arg(long)]
    pub plot_worst: bool,
    /// Also print the pooled error by waypoint index within the walk (0 = the first scored
    /// waypoint), indices from N on in one row: how fast each scheme settles.
    #[arg(long, value_name = "N")]
    pub by_index: Option<usize>,
}

/// Reads an evaluation config file (TOML), or the defaults.
pub fn load_config(path: Option<&Path>) -> Result<EvalConfig> {
    match path {
        None => Ok(EvalConfig::default()),
        Some(p) => {
            let text =
                std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?;
            Ok(EvalConfig::from_toml(&text, &p.display().to_string())?)
        }
    }
}

/// Evaluates and prints; shared with `wipdr demo`.
pub fn evaluate_and_report(
    floors: &[FloorInput],
    cfg: &EvalConfig,
    schemes: &[String],
    json: Option<&Path>,
    plots: Option<&Path>,
    plot_walks: usize,
    plot_worst: bool,
) -> Result<EvalReport> {
    for s in schemes {
        cfg.scheme(s)?;
    }
    let started = std::time::Instant::now();
    let prepared = {
        let pb = progress::bar(floors.len() as u64, "preparing");
        let p = pipeline::prepare(floors, cfg)?;
        pb.finish_and_clear();
        p
    };
    let pb = progress::bar((prepared.len() * schemes.len()) as u64, "running");
    let report = pipeline::run_prepared(floors, &prepared, cfg, schemes, &|| pb.inc(1))?;
    pb.finish_and_clear();
    let unmatched: usize = prepared.iter().map(|p| p.unmatched_scans).sum();
    let off_floor: usize = prepared.iter().map(|p| p.off_floor_fixes).sum();
    let scans: usize =
        prepared.iter().map(|p| p.observations.len()).sum::<usize>() + unmatched + off_floor;
    let folds: Vec<String> = floors
        .iter()
        .map(|f| {
            let n = wipdr_eval::fold::fold_count(f);
            if f.data.walks.iter().all(|w| w.meta.route.is_some()) {
                format!("leave-one-route-out ({n} routes)")
            } else {
                format!("{n}-fold by walk")
            }
        })
        .collect::<std::collections::BTreeSet<_>>()
        .into_iter()
        .collect();
    println!(
        "{} test walks on {} floor(s), {}; {} scans ({} unmatched, {} off the estimated floor); {:.1} s",
        prepared.len(),
        floors.len(),
        folds.join(", "),
        scans,
        unmatched,
        off_floor,
        started.elapsed().as_secs_f64()
    );
    println!(
        "errors in metres at waypoints (pdr starts at the true first waypoint; every other scheme at the first Wi-Fi fix)\n"
    );
    print!("{}", report.table());
    check_scored(&report)?;
    if let Some(path) = json {
        crate::plotting::ensure_parent(path)?;
        let value = report.to_json(cfg);
        std::fs::write(path, serde_json::to_string_pretty(&value)?)
            .with_context(|| format!("writing {}", path.display()))?;
        println!("\nwrote {}", path.display());
    }
    if let Some(dir) = plots {
        let options = eval_plots::PlotOptions {
            walks_per_floor: plot_walks,
            worst_of: plot_worst.then(|| schemes.last().cloned()).flatten(),
            ..eval_plots::PlotOptions::default()
        };
        let files = eval_plots::write_all(dir, floors, &prepared, cfg, schemes, &report, &options)?;
        println!("wrote {} plots into {}", files, dir.display());
    }
    Ok(report)
}

/// Fails when a scheme scored no waypoint (its 0.00 m would read as a result), and reports
/// non-finite errors, which no figure includes.
fn check_scored(report: &EvalReport) -> Result<()> {
    let non_finite: usize = report
        .walks
        .iter()
        .map(|w| wipdr_core::stats::ErrorStats::from_errors(&w.score.values()).non_finite)
        .sum();
    if non_finite > 0 {
        eprintln!("warning: {non_finite} non-finite waypoint errors left out of every figure");
    }
    let empty = report.unscored_schemes();
    if !empty.is_empty() {
        anyhow::bail!(
            "no waypoint was scored for {} (empty test set, no matched query, or a scoring \
             start beyond every waypoint): the table above has no result",
            empty.join(", ")
        );
    }
    Ok(())
}

/// Runs the subcommand.
pub fn run(args: Args) -> Result<()> {
    let cfg = load_config(args.config.as_deref())?;
    let floors = data::load_floors(&args.data)?;
    let report = evaluate_and_report(
        &floors,
        &cfg,
        &args.schemes,
        args.json.as_deref(),
        args.plots.as_deref(),
        args.plot_walks,
        args.plot_worst,
    )?;
    if let Some(last) = args.by_index {
        println!(
            "\npooled error by waypoint index within the walk (mean m / share of the scheme's summed error)"
        );
        print!("{}", report.index_table(last.max(1)));
    }
    Ok(())
}

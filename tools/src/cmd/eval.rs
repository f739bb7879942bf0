//! `wipdr eval`: the protocol of `docs/evaluation.md` on recorded walks, for any schemes;
//! `--shard I/N` runs one slice of it and `wipdr eval merge` joins the slices
//! ([`wipdr_eval::shard`]).

use crate::{data, eval_plots, progress, report as report_page};
use anyhow::{Context, Result, bail};
use std::path::{Path, PathBuf};
use wipdr_eval::pipeline::{self, EvalConfig, FloorInput, PreparedWalk};
use wipdr_eval::report::EvalReport;
use wipdr_eval::shard::{self, EvalIdentity, ShardReport};
use wipdr_eval::sweep::ShardId;

/// Arguments of `wipdr eval`.
#[derive(Debug, clap::Args)]
#[command(args_conflicts_with_subcommands = true)]
pub struct Args {
    /// `merge` joins shard files.
    #[command(subcommand)]
    pub merge: Option<Sub>,
    /// Floor folders (ILC layout: `path_data_files/`, `floor_info.json`, `geojson_map.json`).
    #[arg(long, num_args = 1..)]
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
    /// Put the drawing data (downsampled tracks, truth, Wi-Fi fixes, floor plans) into the
    /// `--json` file too, so that `wipdr report` can draw the walks from it.
    #[arg(long, requires = "json")]
    pub json_tracks: bool,
    /// Write the report page: one self-contained HTML file (tables, error CDF, every walk
    /// drawn on its floor; `docs/guide.md`, "The report page").
    #[arg(long, value_name = "FILE.html")]
    pub report: Option<PathBuf>,
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
    /// Also print the pooled error by each scored waypoint's distance to the fold's nearest
    /// measured reference point on its floor, in bins with these edges (metres, increasing,
    /// e.g. `5,10,20`): how much of each scheme's error sits in coverage gaps.
    #[arg(long, value_name = "M,M,..", value_delimiter = ',')]
    pub by_coverage: Option<Vec<f64>>,
    /// Run one deterministic slice `I/N` of the work items (floor x fold: items k with
    /// k % N == I) and write a shard file with `--json`, for `wipdr eval merge`.
    #[arg(long, requires = "json", conflicts_with = "plots")]
    pub shard: Option<String>,
    /// Offline mode: score each scheme's whole-walk smoothed track (forward and backward
    /// runs combined; estimates use inputs after their time), not the causal one. Same as
    /// `offline = true` in the config.
    #[arg(long)]
    pub offline: bool,
    /// Leave-one-floor-out learned odometry: each floor runs the network in
    /// `DIR/<site>_<floor>.safetensors` (the label with `/` as `_`, e.g. `site1_F1`), the
    /// one trained without that floor (`odometry-train lofo` writes them), instead of the
    /// shipped weights (trained on every ILC floor). Needs `odometry = "learned"` in the
    /// config; a floor without its file is an error.
    #[arg(long, value_name = "DIR", conflicts_with = "shard")]
    pub odometry_holdout: Option<PathBuf>,
}

/// `wipdr eval merge`.
#[derive(Debug, clap::Subcommand)]
pub enum Sub {
    /// Join the shard files of one run (`wipdr eval --shard I/N --json PART`) into the JSON
    /// of the unsharded run (refused unless they are all N shards of one run: same config,
    /// schemes and data, each shard once).
    Merge {
        /// Output JSON (the same document as `wipdr eval --json`).
        #[arg(long)]
        json: PathBuf,
        /// Shard files.
        #[arg(required = true)]
        parts: Vec<PathBuf>,
    },
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

/// What an evaluation writes besides the printed table.
#[derive(Debug, Clone, Copy, Default)]
pub struct Outputs<'a> {
    /// The results JSON.
    pub json: Option<&'a Path>,
    /// Put the drawing data into the results JSON too.
    pub json_tracks: bool,
    /// The report page.
    pub report: Option<&'a Path>,
    /// The folder of PNG plots.
    pub plots: Option<&'a Path>,
    /// Walks per floor with trajectory plots.
    pub plot_walks: usize,
    /// Plot the worst walks of the last scheme.
    pub plot_worst: bool,
    /// Where each floor's learned odometry came from (`--odometry-holdout`), written as
    /// `motion.weights` in the JSON; `None`: the shipped weights, and no such field.
    pub odometry_weights: Option<&'a serde_json::Value>,
}

/// Evaluates and prints; shared with `wipdr demo`.
pub fn evaluate_and_report(
    floors: &[FloorInput],
    cfg: &EvalConfig,
    schemes: &[String],
    out: &Outputs<'_>,
) -> Result<EvalReport> {
    let items = pipeline::work_items(floors)?;
    let drawing = out.json_tracks || out.report.is_some();
    let (prepared, report, store) = evaluate_items(floors, cfg, schemes, &items, drawing)?;
    check_scored(&report)?;
    let mut value = report.json_document(&serde_json::to_value(cfg)?);
    if let (Some(weights), Some(motion)) = (
        out.odometry_weights,
        value
            .get_mut("motion")
            .and_then(serde_json::Value::as_object_mut),
    ) {
        motion.insert("weights".into(), weights.clone());
    }
    if let Some(store) = store {
        let started = std::time::Instant::now();
        report_page::add_drawing(&mut value, floors, &prepared, schemes, store)?;
        tracing::info!(seconds = started.elapsed().as_secs_f64(), "drawing data");
    }
    if let Some(path) = out.json {
        if out.json_tracks || !drawing {
            write_json(path, &value)?;
        } else {
            write_json(path, &without_drawing(&value))?;
        }
    }
    if let Some(path) = out.report {
        report_page::write_page(&value, &path.display().to_string(), path)?;
    }
    if let Some(dir) = out.plots {
        let options = eval_plots::PlotOptions {
            walks_per_floor: out.plot_walks,
            worst_of: out.plot_worst.then(|| schemes.last().cloned()).flatten(),
            ..eval_plots::PlotOptions::default()
        };
        let files = eval_plots::write_all(dir, floors, &prepared, cfg, schemes, &report, &options)?;
        println!("wrote {} plots into {}", files, dir.display());
    }
    Ok(report)
}

/// `value` without the drawing data of [`report_page::add_drawing`] (the `--json` of a run
/// with `--report` but without `--json-tracks`).
fn without_drawing(value: &serde_json::Value) -> serde_json::Value {
    let mut v = value.clone();
    if let Some(o) = v.as_object_mut() {
        for k in report_page::DRAWING_FIELDS {
            o.remove(*k);
        }
    }
    if let Some(walks) = v.get_mut("walks").and_then(serde_json::Value::as_array_mut) {
        for w in walks
            .iter_mut()
            .filter_map(serde_json::Value::as_object_mut)
        {
            w.remove("track");
        }
    }
    v
}

/// Prepares and runs the work items `items` (from [`pipeline::work_items`]) and prints the
/// run's summary line and table.
fn evaluate_items(
    floors: &[FloorInput],
    cfg: &EvalConfig,
    schemes: &[String],
    items: &[(usize, usize)],
    drawing: bool,
) -> Result<(
    Vec<PreparedWalk>,
    EvalReport,
    Option<report_page::TrackStore>,
)> {
    for s in schemes {
        cfg.scheme(s)?;
    }
    let started = std::time::Instant::now();
    let prepared = {
        let pb = progress::bar(floors.len() as u64, "preparing");
        let p = pipeline::prepare_items(floors, cfg, items)?;
        pb.finish_and_clear();
        p
    };
    let pb = progress::bar((prepared.len() * schemes.len()) as u64, "running");
    let store = drawing.then(|| report_page::TrackStore::new(prepared.len(), schemes.len()));
    let report = pipeline::run_prepared_observed(
        floors,
        &prepared,
        cfg,
        schemes,
        &|| pb.inc(1),
        &|w, s, track| {
            if let Some(store) = &store {
                store.keep(&prepared, w, s, track);
            }
        },
    )?;
    pb.finish_and_clear();
    let unmatched: usize = prepared.iter().map(|p| p.unmatched_scans).sum();
    let off_floor: usize = prepared.iter().map(|p| p.off_floor_fixes).sum();
    let scans: usize =
        prepared.iter().map(|p| p.observations.len()).sum::<usize>() + unmatched + off_floor;
    let folds: Vec<String> = floors
        .iter()
        .map(|f| {
            let n = wipdr_eval::fold_model::fold_count(f);
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
        "errors in metres at waypoints ({}; pdr starts at the true first waypoint; every other scheme at the first Wi-Fi fix)\n",
        if cfg.offline {
            "OFFLINE: whole-walk smoothed estimates, forward and backward runs combined"
        } else {
            "causal estimates"
        }
    );
    print!("{}", report.table());
    let motion = report.motion_table(cfg.positioner.odometry.name());
    if !motion.is_empty() {
        print!("\n{motion}");
    }
    let scans = report.scan_likelihood_table();
    if !scans.is_empty() {
        print!("\n{scans}");
    }
    let skips = report.skips_table();
    if !skips.is_empty() {
        print!("\n{skips}");
    }
    Ok((prepared, report, store))
}

/// Writes `document` (an evaluation's JSON) to `path`.
fn write_json(path: &Path, document: &serde_json::Value) -> Result<()> {
    crate::plotting::ensure_parent(path)?;
    std::fs::write(path, serde_json::to_string_pretty(document)?)
        .with_context(|| format!("writing {}", path.display()))?;
    println!("\nwrote {}", path.display());
    Ok(())
}

/// `wipdr eval --shard I/N`: runs the shard's work items and writes its shard file.
fn run_shard(
    floors: &[FloorInput],
    cfg: &EvalConfig,
    schemes: &[String],
    shard: ShardId,
    json: &Path,
) -> Result<EvalReport> {
    for s in schemes {
        cfg.scheme(s)?;
    }
    let identity = EvalIdentity::new(floors, cfg, schemes, shard)?;
    let items = shard::shard_items(&identity.items, shard);
    println!(
        "shard {shard}: {} of {} work items (floor x fold); figures below are this shard's only",
        items.len(),
        identity.items.len()
    );
    let (_, report, _) = evaluate_items(floors, cfg, schemes, &items, false)?;
    ShardReport::new(identity, items, report.clone()).write(json)?;
    println!(
        "\nwrote shard file {} (join all {} with `wipdr eval merge PARTS... --json OUT`)",
        json.display(),
        shard.count
    );
    Ok(report)
}

/// `wipdr eval merge`: the shards' JSON as the unsharded run writes it.
fn run_merge(parts: &[PathBuf], json: &Path) -> Result<()> {
    let merged = shard::merge(parts)?;
    println!(
        "merged {} shard files: {} walk results on {} floor(s)\n",
        merged.count,
        merged.report.walks.len(),
        merged.report.floor_order.len()
    );
    print!("{}", merged.report.table());
    let source = merged
        .config
        .get("odometry")
        .and_then(serde_json::Value::as_str);
    let motion = merged.report.motion_table(source.unwrap_or("steps"));
    if !motion.is_empty() {
        print!("\n{motion}");
    }
    let scans = merged.report.scan_likelihood_table();
    if !scans.is_empty() {
        print!("\n{scans}");
    }
    let skips = merged.report.skips_table();
    if !skips.is_empty() {
        print!("\n{skips}");
    }
    check_scored(&merged.report)?;
    write_json(json, &merged.report.json_document(&merged.config))
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
    let empty: Vec<&str> = report
        .schemes
        .iter()
        .filter(|s| report.pooled.get(*s).is_none_or(|p| p.count == 0))
        .map(String::as_str)
        .collect();
    if !empty.is_empty() {
        anyhow::bail!(
            "no waypoint was scored for {} (empty test set, no matched query, or a scoring \
             start beyond every waypoint): the table above has no result",
            empty.join(", ")
        );
    }
    Ok(())
}

/// The file of `--odometry-holdout DIR` for the floor labelled `label`: `site1/F1` ->
/// `DIR/site1_F1.safetensors` (the names `odometry-train lofo` writes).
fn holdout_weights_path(dir: &Path, label: &str) -> PathBuf {
    dir.join(format!("{}.safetensors", label.replace('/', "_")))
}

/// Gives every floor the learned odometry of `--odometry-holdout DIR` that did not train on
/// it; returns, per floor label, the file it runs (for the JSON's `motion.weights`).
/// Refused unless the config's motion source is `learned` (the weights would be ignored).
fn attach_holdout_odometry(
    floors: &mut [FloorInput],
    dir: &Path,
    cfg: &EvalConfig,
) -> Result<serde_json::Value> {
    use wipdr_positioning::config::Odometry;
    if cfg.positioner.odometry != Odometry::Learned {
        bail!(
            "--odometry-holdout {}: the config's motion source is `{}`, so the weights would \
             not be read; set `odometry = \"learned\"` in the config",
            dir.display(),
            cfg.positioner.odometry.name()
        );
    }
    let mut used = serde_json::Map::new();
    for floor in floors.iter_mut() {
        let path = holdout_weights_path(dir, &floor.label);
        let bytes = std::fs::read(&path).with_context(|| {
            format!(
                "--odometry-holdout: reading {}, the network held out on floor {:?}",
                path.display(),
                floor.label
            )
        })?;
        let model = wipdr_pdr::odometry::LearnedOdometry::from_safetensors(&bytes)
            .with_context(|| format!("--odometry-holdout: {}", path.display()))?;
        floor.odometry = Some(std::sync::Arc::new(model));
        used.insert(
            floor.label.clone(),
            serde_json::Value::from(path.display().to_string()),
        );
    }
    Ok(serde_json::Value::Object(used))
}

/// Runs the subcommand.
pub fn run(args: Args) -> Result<()> {
    if let Some(Sub::Merge { json, parts }) = &args.merge {
        return run_merge(parts, json);
    }
    if args.data.is_empty() {
        bail!("--data FLOOR_DIR... is required");
    }
    let shard = args
        .shard
        .as_deref()
        .map(str::parse::<ShardId>)
        .transpose()?;
    if let Some(edges) = &args.by_coverage {
        wipdr_eval::coverage::validate_edges(edges)
            .map_err(|e| anyhow::anyhow!("--by-coverage: {e}"))?;
    }
    let mut cfg = load_config(args.config.as_deref())?;
    cfg.offline |= args.offline;
    let mut floors = data::load_floors(&args.data)?;
    let odometry_weights = match &args.odometry_holdout {
        Some(dir) => Some(attach_holdout_odometry(&mut floors, dir, &cfg)?),
        None => None,
    };
    let report = match (shard, args.json.as_deref()) {
        (Some(shard), Some(json)) => run_shard(&floors, &cfg, &args.schemes, shard, json)?,
        (Some(_), None) => bail!("--shard writes a shard file: give --json PART.json"),
        (None, _) => evaluate_and_report(
            &floors,
            &cfg,
            &args.schemes,
            &Outputs {
                json: args.json.as_deref(),
                json_tracks: args.json_tracks,
                report: args.report.as_deref(),
                plots: args.plots.as_deref(),
                plot_walks: args.plot_walks,
                plot_worst: args.plot_worst,
                odometry_weights: odometry_weights.as_ref(),
            },
        )?,
    };
    if let Some(last) = args.by_index {
        println!(
            "\npooled error by waypoint index within the walk (mean m / share of the scheme's summed error)"
        );
        print!("{}", report.index_table(last.max(1)));
    }
    if let Some(edges) = &args.by_coverage {
        println!(
            "\npooled error by distance to the nearest measured reference point on the floor (mean m / share of the scheme's summed error)"
        );
        print!("{}", report.coverage_table(edges));
    }
    Ok(())
}

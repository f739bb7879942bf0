//! `wipdr pdr-eval`: PDR on recorded walks under the protocol folds
//! (`docs/evaluation.md`).
//!
//! For each floor and fold, the step-length coefficients (every model) and the heading
//! offset (every source) are fitted on the training walks' waypoint legs by the evaluation's
//! calibration ([`wipdr_eval::pdr_protocol`]); the test walks are then scored:
//! (a) per leg, the relative error of the summed step lengths and the heading error of the
//! PDR displacement against the leg; (b) PDR-only positions started at the true first
//! waypoint, scored at every later waypoint after the walk's first Wi-Fi scan. Reported for
//! the competition sample code's PDR (baseline), the sample code with a per-floor stride
//! scale, the configured pipeline (`--config`, default [`PdrConfig::default`]), and every
//! step-length model x heading source.

use anyhow::{Context, Result};
use plotters::prelude::*;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use wipdr_core::stats::ErrorStats;
use wipdr_core::{TimestampMs, Waypoint};
use wipdr_eval::pdr_protocol::{PdrScheme, SchemeErrors, WalkRun, run_walks, score_schemes};
use wipdr_io::floor::{FloorData, ReadOptions};
use wipdr_pdr::calibrate::CalibrationConfig;
use wipdr_pdr::{HeadingSource, PdrConfig, StepLengthConfig};

/// Arguments of `wipdr pdr-eval`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Floor folders (ILC layout: `path_data_files/`, `floor_info.json`, `geojson_map.json`).
    #[arg(long = "data", required = true, num_args = 1..)]
    pub data: Vec<PathBuf>,
    /// PDR configuration (JSON or TOML) of the proposed pipeline; its step-length
    /// coefficients and heading offset are re-fitted on each fold's training walks.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Calibration settings (JSON or TOML).
    #[arg(long)]
    pub calibration: Option<PathBuf>,
    /// Write the results as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Draw PDR against truth for some walks of each floor into this folder (PNG).
    #[arg(long)]
    pub plot_dir: Option<PathBuf>,
    /// How many walks per floor to plot (the longest).
    #[arg(long, default_value_t = 2)]
    pub plot_walks: usize,
}

/// Reads a config file as JSON (`.json`) or TOML (anything else).
pub(crate) fn read_config<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    if path.extension().is_some_and(|e| e == "json") {
        serde_json::from_str(&text).with_context(|| format!("parsing {}", path.display()))
    } else {
        toml::from_str(&text).with_context(|| format!("parsing {}", path.display()))
    }
}

/// The config of `path` (defaults without one), checked by `check`, which returns the
/// offending field and the reason: an error names the file, the field and the reason.
fn read_checked<T, F>(path: Option<&Path>, check: F) -> Result<T>
where
    T: Default + serde::de::DeserializeOwned,
    F: FnOnce(&T) -> Result<(), wipdr_core::ConfigError>,
{
    let Some(path) = path else {
        return Ok(T::default());
    };
    let cfg: T = read_config(path)?;
    if let Err(e) = check(&cfg) {
        anyhow::bail!("{}: {e}", path.display());
    }
    Ok(cfg)
}

/// The PDR config of `path` (defaults without one), checked by [`PdrConfig::validate`].
pub(crate) fn read_pdr_config(path: Option<&Path>) -> Result<PdrConfig> {
    read_checked(path, PdrConfig::validate)
}

/// The calibration settings of `path` (defaults without one), checked by
/// [`CalibrationConfig::validate`].
pub(crate) fn read_calibration(path: Option<&Path>) -> Result<CalibrationConfig> {
    read_checked(path, CalibrationConfig::validate)
}

/// Reads floor folders (through the cache of this run, `--cache-dir` / `--no-cache`).
pub(crate) fn read_floors(dirs: &[PathBuf]) -> Result<Vec<FloorData>> {
    let opts = ReadOptions::default();
    let cache = crate::data::cache_settings();
    dirs.iter()
        .map(|d| {
            let f = wipdr_io::cache::read_floor(d, &cache, &opts, &|| {}).map(|(f, _)| f);
            let f = f.with_context(|| format!("reading floor {}", d.display()))?;
            if let Some(note) = crate::data::skipped_walks_note(&f) {
                eprintln!("{note}");
            }
            Ok(f)
        })
        .collect()
}

/// Runs `cfg` over every walk of a floor (parallel), with folds.
pub(crate) fn run_floor(floor: &FloorData, cfg: &PdrConfig) -> Result<Vec<WalkRun>> {
    let cfg = cfg
        .check()
        .map_err(|e| anyhow::anyhow!("PDR config: {e}"))?;
    let walks: Vec<&wipdr_core::Walk> = floor.walks.iter().map(|w| &w.walk).collect();
    Ok(run_walks(&walks, &cfg))
}

/// Median and p90 of absolute values.
#[derive(Debug, Clone, Copy, Serialize)]
struct AbsSummary {
    count: usize,
    median: f64,
    p90: f64,
    mean_signed: f64,
}

fn abs_summary(v: &[f64]) -> AbsSummary {
    let a: Vec<f64> = v.iter().map(|x| x.abs()).collect();
    let s = ErrorStats::from_errors(&a);
    let finite: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    let mean_signed = if finite.is_empty() {
        0.0
    } else {
        finite.iter().sum::<f64>() / finite.len() as f64
    };
    AbsSummary {
        count: s.count,
        median: s.p50,
        p90: s.p90,
        mean_signed,
    }
}

/// The position figures of a scheme, as the JSON holds them.
#[derive(Debug, Clone, Serialize)]
struct SchemeReport {
    pooled: ErrorStats,
    floors: BTreeMap<String, ErrorStats>,
    leg_length_rel: AbsSummary,
    leg_heading_deg: AbsSummary,
    heading_offsets_deg: Vec<f64>,
}

#[derive(Debug, Serialize)]
struct Report {
    /// The configured pipeline's PDR-only positions (protocol scoring).
    pooled: ErrorStats,
    /// Per floor, the same.
    floors: BTreeMap<String, ErrorStats>,
    /// The configuration (before per-fold calibration).
    config: PdrConfig,
    /// Every scheme.
    schemes: BTreeMap<String, SchemeReport>,
    /// Steps detected per floor (configured pipeline) and walks.
    steps: BTreeMap<String, (usize, usize)>,
}

fn fmt_stats(s: &ErrorStats) -> String {
    format!(
        "{:>5} {:>6.2} {:>6.2} {:>6.2} {:>6.2} {:>6.2} {:>7.2}",
        s.count, s.mean, s.rms, s.p50, s.p75, s.p95, s.max
    )
}

/// Runs the subcommand.
pub fn run(args: Args) -> Result<()> {
    let cfg = read_pdr_config(args.config.as_deref())?;
    let cal = read_calibration(args.calibration.as_deref())?;
    let floors = read_floors(&args.data)?;
    let base_cfg = PdrConfig::sample_code();

    let scheme = |name: String, model, source, calibrate, fit_offset, on_baseline_run| PdrScheme {
        name,
        model,
        source,
        calibrate,
        fit_offset,
        on_baseline_run,
    };
    let rv = HeadingSource::RotationVector;
    let mut schemes = vec![
        scheme(
            "sample_code".into(),
            base_cfg.step_length,
            rv,
            false,
            false,
            true,
        ),
        scheme(
            "sample_code+scale".into(),
            base_cfg.step_length,
            rv,
            true,
            false,
            true,
        ),
        scheme(
            "configured".into(),
            cfg.step_length,
            cfg.heading.source,
            true,
            cal.fit_heading_offset,
            false,
        ),
    ];
    let mut grid_names = Vec::new();
    for m in StepLengthConfig::all_defaults() {
        for s in HeadingSource::ALL {
            let name = format!("{}/{}", m.name(), s.name());
            grid_names.push(name.clone());
            schemes.push(scheme(name, m, s, true, cal.fit_heading_offset, false));
        }
    }

    let mut per_scheme: Vec<(SchemeErrors, BTreeMap<String, ErrorStats>)> =
        vec![(SchemeErrors::default(), BTreeMap::new()); schemes.len()];
    let mut steps_info = BTreeMap::new();
    let pb = crate::progress::bar(floors.len() as u64, "floors");
    for floor in &floors {
        let base_runs = run_floor(floor, &base_cfg)?;
        let runs = run_floor(floor, &cfg)?;
        steps_info.insert(
            floor.name.clone(),
            (runs.iter().map(|r| r.steps.len()).sum(), runs.len()),
        );
        let scored = score_schemes((&base_runs, &base_cfg), (&runs, &cfg), &schemes, &cal);
        for (i, (col, tracks)) in scored.iter().enumerate() {
            per_scheme[i].0.extend(col);
            per_scheme[i]
                .1
                .insert(floor.name.clone(), ErrorStats::from_errors(&col.positions));
            if let Some(dir) = &args.plot_dir
                && schemes[i].name == "configured"
            {
                let base_tracks = &scored[0].1;
                plot_walks(dir, floor, &runs, tracks, base_tracks, args.plot_walks)?;
            }
        }
        pb.inc(1);
    }
    pb.finish_and_clear();

    let mut reports = BTreeMap::new();
    for (sc, (col, floors_stats)) in schemes.iter().zip(&per_scheme) {
        reports.insert(
            sc.name.clone(),
            SchemeReport {
                pooled: ErrorStats::from_errors(&col.positions),
                floors: floors_stats.clone(),
                leg_length_rel: abs_summary(&col.leg_length_rel),
                leg_heading_deg: abs_summary(&col.leg_heading_deg),
                heading_offsets_deg: col.offsets_deg.clone(),
            },
        );
    }

    // Text report.
    println!("PDR-only from the true first waypoint, scored after the first Wi-Fi scan (m)");
    println!(
        "{:<22} {:<10} {:>5} {:>6} {:>6} {:>6} {:>6} {:>6} {:>7}",
        "scheme", "floor", "n", "mean", "rms", "p50", "p75", "p95", "max"
    );
    for name in ["sample_code", "sample_code+scale", "configured"] {
        let r = &reports[name];
        for (f, s) in &r.floors {
            println!("{:<22} {:<10} {}", name, f, fmt_stats(s));
        }
        println!("{:<22} {:<10} {}", name, "pooled", fmt_stats(&r.pooled));
    }
    println!();
    println!(
        "Every model x heading source (fitted per fold), pooled; legs: |relative length error| and |heading error|"
    );
    println!(
        "{:<34} {:>6} {:>6} {:>6} | {:>6} {:>6} | {:>6} {:>6} | {:>6}",
        "model/source", "mean", "p50", "p95", "len50%", "len90%", "hdg50", "hdg90", "offset"
    );
    for name in std::iter::once("sample_code+scale").chain(grid_names.iter().map(|s| s.as_str())) {
        let r = &reports[name];
        let mean_off = if r.heading_offsets_deg.is_empty() {
            0.0
        } else {
            r.heading_offsets_deg.iter().sum::<f64>() / r.heading_offsets_deg.len() as f64
        };
        println!(
            "{:<34} {:>6.2} {:>6.2} {:>6.2} | {:>6.1} {:>6.1} | {:>6.1} {:>6.1} | {:>6.1}",
            name,
            r.pooled.mean,
            r.pooled.p50,
            r.pooled.p95,
            100.0 * r.leg_length_rel.median,
            100.0 * r.leg_length_rel.p90,
            r.leg_heading_deg.median,
            r.leg_heading_deg.p90,
            mean_off
        );
    }
    for (f, (n, w)) in &steps_info {
        println!("{f}: {n} steps in {w} walks");
    }

    if let Some(path) = &args.json {
        let configured = &reports["configured"];
        let report = Report {
            pooled: configured.pooled,
            floors: configured.floors.clone(),
            config: cfg,
            schemes: reports.clone(),
            steps: steps_info,
        };
        crate::plotting::ensure_parent(path)?;
        std::fs::write(path, serde_json::to_string_pretty(&report)?)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

fn positions_of(tr: &[(TimestampMs, f64, f64)], waypoints: &[Waypoint]) -> Vec<(f64, f64)> {
    let Some(first) = waypoints.first() else {
        return Vec::new();
    };
    let mut p = first.position;
    let mut out = vec![(p.x, p.y)];
    for &(t, l, h) in tr {
        if t <= first.t {
            continue;
        }
        p += wipdr_core::angle::step_displacement(l, h);
        out.push((p.x, p.y));
    }
    out
}

fn plot_walks(
    dir: &Path,
    floor: &FloorData,
    runs: &[WalkRun],
    tracks: &[Vec<(TimestampMs, f64, f64)>],
    base_tracks: &[Vec<(TimestampMs, f64, f64)>],
    n: usize,
) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    // The longest walks (path through the waypoints), ties by name.
    let path_len = |r: &WalkRun| -> f64 {
        r.waypoints
            .windows(2)
            .map(|w| (w[1].position - w[0].position).norm())
            .sum()
    };
    let mut order: Vec<usize> = (0..runs.len()).collect();
    order.sort_by(|&a, &b| {
        path_len(&runs[b])
            .total_cmp(&path_len(&runs[a]))
            .then(runs[a].id.cmp(&runs[b].id))
    });
    for &i in order.iter().take(n) {
        let r = &runs[i];
        let file = dir.join(format!("{}_{}.png", floor.name.replace('/', "_"), r.id));
        let (w, h) = crate::plotting::floor_canvas_size(floor.plan.width, floor.plan.height, 900);
        let root = BitMapBackend::new(&file, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| anyhow::anyhow!("{e}"))?;
        let mut chart = crate::plotting::floor_chart(
            &root,
            &floor.plan,
            &format!(
                "{} {}: truth (black), sample code (red), configured (blue)",
                floor.name, r.id
            ),
        )?;
        crate::plotting::draw_floor_plan(&mut chart, &floor.plan)?;
        let truth: Vec<(f64, f64)> = r
            .waypoints
            .iter()
            .map(|w| (w.position.x, w.position.y))
            .collect();
        let err = |e| anyhow::anyhow!("plot: {e}");
        chart
            .draw_series(LineSeries::new(truth.clone(), BLACK.stroke_width(2)))
            .map_err(err)?;
        chart
            .draw_series(truth.iter().map(|&p| Circle::new(p, 4, BLACK.filled())))
            .map_err(err)?;
        chart
            .draw_series(LineSeries::new(
                positions_of(&base_tracks[i], &r.waypoints),
                RED.stroke_width(2),
            ))
            .map_err(err)?;
        chart
            .draw_series(LineSeries::new(
                positions_of(&tracks[i], &r.waypoints),
                BLUE.stroke_width(2),
            ))
            .map_err(err)?;
        root.present()
            .map_err(|e| anyhow::anyhow!("writing {}: {e}", file.display()))?;
    }
    Ok(())
}

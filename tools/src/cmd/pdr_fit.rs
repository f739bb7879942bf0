//! `wipdr pdr-fit`: fits the step-length coefficients (least squares over waypoint legs) and
//! the heading offset between the magnetic azimuth and the map frame, from walks with
//! waypoints, and saves the calibrated PDR configuration (TOML, or JSON for `.json`).
//!
//! Give one floor to get that floor's offset; with several floors the coefficients and the
//! offset are fitted on all of them together. `--fold K` leaves the walks of protocol fold
//! `K` out (fit on training folds only).

use crate::cmd::pdr_eval::{calibrate, read_config, read_floors, run_floor};
use anyhow::{Context, Result};
use std::path::PathBuf;
use wipdr_pdr::calibrate::{CalibrationConfig, WalkSteps, leg_errors};
use wipdr_pdr::{HeadingSource, PdrConfig, StepLengthConfig};

/// Step-length model to fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ModelName {
    /// Paper 000 eq. 6.
    Linear,
    /// Paper 002 eq. 8.
    Weinberg,
    /// Paper 004 eq. 6-7.
    Pendulum,
    /// The competition sample code's stride model (a scale is fitted).
    SampleCode,
}

/// Heading source.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum SourceName {
    /// Android rotation vector.
    RotationVector,
    /// Gyroscope integration.
    Gyro,
    /// Gyro + compass Kalman filter.
    GyroCompassKf,
    /// Compass.
    Compass,
}

/// Arguments of `wipdr pdr-fit`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Floor folders with walks that have waypoints.
    #[arg(long = "data", required = true, num_args = 1..)]
    pub data: Vec<PathBuf>,
    /// Base configuration (JSON or TOML); default the built-in defaults.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Calibration settings (JSON or TOML).
    #[arg(long)]
    pub calibration: Option<PathBuf>,
    /// Model to fit (default: the base configuration's).
    #[arg(long, value_enum)]
    pub model: Option<ModelName>,
    /// Heading source (default: the base configuration's).
    #[arg(long, value_enum)]
    pub source: Option<SourceName>,
    /// Leave out the walks of this protocol fold (0-4).
    #[arg(long)]
    pub fold: Option<usize>,
    /// Where to save the calibrated configuration.
    #[arg(long)]
    pub out: PathBuf,
    /// Cache folder for parsed floors.
    #[arg(long, default_value = wipdr_io::cache::DEFAULT_CACHE_DIR)]
    pub cache_dir: PathBuf,
    /// Read the walks from source, bypassing the cache.
    #[arg(long)]
    pub no_cache: bool,
}

/// Runs the subcommand.
pub fn run(args: Args) -> Result<()> {
    let mut cfg: PdrConfig = match &args.config {
        Some(p) => read_config(p)?,
        None => PdrConfig::default(),
    };
    let cal: CalibrationConfig = match &args.calibration {
        Some(p) => read_config(p)?,
        None => CalibrationConfig::default(),
    };
    if let Some(f) = args.fold
        && f >= wipdr_core::stats::FOLDS
    {
        anyhow::bail!("--fold must be below {}", wipdr_core::stats::FOLDS);
    }
    if let Some(m) = args.model {
        cfg.step_length = match m {
            ModelName::Linear => StepLengthConfig::Linear(Default::default()),
            ModelName::Weinberg => StepLengthConfig::Weinberg(Default::default()),
            ModelName::Pendulum => StepLengthConfig::Pendulum(Default::default()),
            ModelName::SampleCode => StepLengthConfig::SampleCode(Default::default()),
        };
    }
    if let Some(s) = args.source {
        cfg.heading.source = match s {
            SourceName::RotationVector => HeadingSource::RotationVector,
            SourceName::Gyro => HeadingSource::Gyro,
            SourceName::GyroCompassKf => HeadingSource::GyroCompassKf,
            SourceName::Compass => HeadingSource::Compass,
        };
    }
    // Fit on headings without any offset already in the base configuration.
    let mut run_cfg = cfg;
    run_cfg.heading.map_offset_rad = 0.0;
    let floors = read_floors(&args.data, &args.cache_dir, args.no_cache)?;
    let runs: Vec<_> = floors.iter().flat_map(|f| run_floor(f, &run_cfg)).collect();
    let train: Vec<WalkSteps<'_>> = runs
        .iter()
        .filter(|r| args.fold != Some(r.fold))
        .map(|r| WalkSteps {
            steps: &r.steps,
            waypoints: &r.waypoints,
        })
        .collect();
    if train.is_empty() {
        anyhow::bail!("no walks to fit on");
    }
    let (model, offset) = calibrate(
        cfg.step_length,
        cfg.heading.source,
        cal.fit_heading_offset,
        &train,
        &cal,
    );
    cfg.step_length = model;
    cfg.heading.map_offset_rad = offset;

    let errors: Vec<f64> = train
        .iter()
        .flat_map(|w| leg_errors(w, &model, cfg.heading.source, &cal))
        .map(|e| e.length_rel.abs())
        .collect();
    let s = wipdr_core::stats::ErrorStats::from_errors(&errors);
    println!(
        "{} walks, {} legs: {} coefficients {:?}, heading offset {:.2} deg ({}); training |leg length error| median {:.1} %, p90 {:.1} %",
        train.len(),
        s.count,
        model.name(),
        model.model().coefficients(),
        offset.to_degrees(),
        cfg.heading.source.name(),
        100.0 * s.p50,
        100.0 * s.p90
    );
    crate::plotting::ensure_parent(&args.out)?;
    let text = if args.out.extension().is_some_and(|e| e == "json") {
        serde_json::to_string_pretty(&cfg)?
    } else {
        toml::to_string_pretty(&cfg)?
    };
    std::fs::write(&args.out, text).with_context(|| format!("writing {}", args.out.display()))?;
    println!("saved {}", args.out.display());
    Ok(())
}

//! `wipdr pdr-fit`: fits the step-length coefficients (least squares over waypoint legs) and
//! the heading offset between the magnetic azimuth and the map frame, from walks with
//! waypoints, and saves the calibrated PDR configuration (TOML, or JSON for `.json`).
//!
//! Give one floor to get that floor's offset; with several floors the coefficients and the
//! offset are fitted on all of them together. `--fold K` leaves the walks of protocol fold
//! `K` out (fit on training folds only). The fit is the evaluation's calibration
//! ([`wipdr_eval::pdr_protocol::calibrate_steps`]).
//!
//! It also prints the PDR error expectation (paper 002 eq. 14, §5.3; [`wipdr_pdr::error_model`]):
//! per floor (each with its own heading offset, fitted with the calibrated step-length model on
//! that floor's training walks) and pooled, a Gaussian fitted to the heading errors of the
//! training legs (direction of the leg's PDR displacement minus the leg's direction; also of
//! single steps against their leg's direction), the expected position error per step of eq. 14,
//! the error per metre, and TCPF's `alpha` (eq. 17) for the Wi-Fi mean error
//! `--wifi-mean-error`.

use crate::cmd::pdr_eval::{read_calibration, read_floors, read_pdr_config, run_floor};
use anyhow::{Context, Result};
use serde::Serialize;
use std::path::PathBuf;
use wipdr_core::angle::wrap_pi;
use wipdr_eval::fold_rules::FOLDS;
use wipdr_eval::pdr_protocol::{WalkRun, calibrate_steps_with_grid};
use wipdr_pdr::calibrate::{CalibrationConfig, WalkSteps, fit_heading_offset, leg_errors, track};
use wipdr_pdr::error_model::{
    HeadingErrorFit, IntegrationConfig, error_per_metre, expected_step_error, step_heading_errors,
    tcpf_alpha,
};
use wipdr_pdr::{HeadingSource, StepLengthConfig};

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
    /// Mean Wi-Fi error (m) for TCPF's `alpha` (default: the eval's pooled shared-AP Wi-Fi
    /// mean, docs/results/fusion-real.md).
    #[arg(long, default_value_t = 8.09)]
    pub wifi_mean_error: f64,
    /// Write the error expectation (per floor and pooled) as JSON here.
    #[arg(long)]
    pub error_json: Option<PathBuf>,
}

/// Runs the subcommand.
pub fn run(args: Args) -> Result<()> {
    let mut cfg = read_pdr_config(args.config.as_deref())?;
    let cal = read_calibration(args.calibration.as_deref())?;
    if let Some(f) = args.fold
        && f >= FOLDS
    {
        anyhow::bail!("--fold must be below {}", FOLDS);
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
    if !(args.wifi_mean_error > 0.0 && args.wifi_mean_error.is_finite()) {
        anyhow::bail!("--wifi-mean-error must be > 0");
    }
    let floors = read_floors(&args.data)?;
    let floor_runs: Vec<Vec<WalkRun>> = floors
        .iter()
        .map(|f| run_floor(f, &run_cfg))
        .collect::<Result<_>>()?;
    let train: Vec<WalkSteps<'_>> = floor_runs
        .iter()
        .flat_map(|r| train_of(r, args.fold))
        .collect();
    if train.is_empty() {
        anyhow::bail!("no walks to fit on");
    }
    let (fitted, grid) = calibrate_steps_with_grid(&run_cfg, &cal, &train);
    let (model, offset) = (fitted.step_length, fitted.heading.map_offset_rad);
    cfg.step_length = model;
    cfg.heading.map_offset_rad = offset;
    cfg.heading.snap = fitted.heading.snap;
    if run_cfg.heading.snap.enabled {
        match grid {
            Some((o, r)) => println!(
                "grid of the training legs: orientation {:.1} deg, concentration {:.2} (heading snapping {} at >= {:.2})",
                o.to_degrees(),
                r,
                if cfg.heading.snap.enabled {
                    "on"
                } else {
                    "off"
                },
                cal.min_grid_concentration
            ),
            None => println!("no training legs: heading snapping off"),
        }
    }

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

    // PDR error expectation (002 eq. 14, 17).
    let source = cfg.heading.source;
    let cal_src = CalibrationConfig {
        heading_source: source,
        ..cal
    };
    let mut rows = Vec::new();
    let mut pooled = ErrorSamples::default();
    for (floor, runs) in floors.iter().zip(&floor_runs) {
        let train = train_of(runs, args.fold);
        let offset = fit_heading_offset(&model, source, &train, &cal_src).unwrap_or(0.0);
        let mut samples = ErrorSamples::default();
        for w in &train {
            samples.legs.extend(
                leg_errors(w, &model, source, &cal_src)
                    .iter()
                    .map(|e| wrap_pi(e.heading + offset)),
            );
            samples
                .steps
                .extend(step_heading_errors(w, source, offset, &cal_src));
            samples.lengths.extend(
                track(
                    w.steps,
                    &model,
                    source,
                    offset,
                    cfg.min_step_length,
                    cfg.max_step_length,
                )
                .iter()
                .map(|t| t.1),
            );
        }
        rows.push(samples.summarise(&floor.name, offset, args.wifi_mean_error));
        pooled.extend(samples);
    }
    rows.push(pooled.summarise("pooled", f64::NAN, args.wifi_mean_error));
    print_error_rows(&rows, args.wifi_mean_error);
    if let Some(path) = &args.error_json {
        crate::plotting::ensure_parent(path)?;
        std::fs::write(path, serde_json::to_string_pretty(&rows)?)
            .with_context(|| format!("writing {}", path.display()))?;
        println!("saved {}", path.display());
    }

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

/// The walks of `runs` outside fold `fold` (all when `None`).
fn train_of(runs: &[WalkRun], fold: Option<usize>) -> Vec<WalkSteps<'_>> {
    runs.iter()
        .filter(|r| fold != Some(r.fold))
        .map(|r| WalkSteps {
            steps: &r.steps,
            waypoints: &r.waypoints,
        })
        .collect()
}

/// Heading errors (rad) and step lengths (m) of training walks.
#[derive(Default)]
struct ErrorSamples {
    legs: Vec<f64>,
    steps: Vec<f64>,
    lengths: Vec<f64>,
}

/// The error expectation of one floor (or the pool) under one heading-error fit.
#[derive(Debug, Serialize)]
struct Expectation {
    /// Sigma used, degrees.
    sigma_deg: f64,
    /// Expected error per step at the mean step length, cm (eq. 14).
    per_step_cm: f64,
    /// Expected error per step at 0.75 m (the paper's step), cm.
    per_step_075_cm: f64,
    /// Expected error per metre walked, m/m.
    per_metre: f64,
    /// TCPF `alpha` (eq. 17), 1/m.
    alpha: f64,
}

#[derive(Debug, Serialize)]
struct ErrorRow {
    floor: String,
    /// The floor's heading offset (deg); NaN for the pool (serialised as null).
    offset_deg: Option<f64>,
    mean_step_m: f64,
    legs: Option<HeadingErrorFit>,
    steps: Option<HeadingErrorFit>,
    /// From the legs' robust sigma (the one to use).
    legs_robust: Option<Expectation>,
    /// From the legs' moment sigma.
    legs_moments: Option<Expectation>,
    /// From the single steps' robust sigma.
    steps_robust: Option<Expectation>,
    /// Why a fit is missing.
    problems: Vec<String>,
}

impl ErrorSamples {
    fn extend(&mut self, o: ErrorSamples) {
        self.legs.extend(o.legs);
        self.steps.extend(o.steps);
        self.lengths.extend(o.lengths);
    }

    fn summarise(&self, floor: &str, offset: f64, wifi_mean: f64) -> ErrorRow {
        let mean_step = if self.lengths.is_empty() {
            0.0
        } else {
            self.lengths.iter().sum::<f64>() / self.lengths.len() as f64
        };
        let mut problems = Vec::new();
        let mut fit = |what: &str, e: &[f64]| match HeadingErrorFit::from_errors(e) {
            Ok(f) => Some(f),
            Err(err) => {
                problems.push(format!("{what}: {err}"));
                None
            }
        };
        let legs = fit("legs", &self.legs);
        let steps = fit("steps", &self.steps);
        let integ = IntegrationConfig::default();
        let expect = |sigma: f64, problems: &mut Vec<String>| -> Option<Expectation> {
            let r = (|| {
                Ok::<_, wipdr_pdr::error_model::ErrorModelError>(Expectation {
                    sigma_deg: sigma.to_degrees(),
                    per_step_cm: 100.0 * expected_step_error(sigma, mean_step, &integ)?,
                    per_step_075_cm: 100.0 * expected_step_error(sigma, 0.75, &integ)?,
                    per_metre: error_per_metre(sigma, &integ)?,
                    alpha: tcpf_alpha(error_per_metre(sigma, &integ)?, wifi_mean)?,
                })
            })();
            r.map_err(|e| problems.push(e.to_string())).ok()
        };
        let legs_robust = legs.and_then(|f| expect(f.sigma_robust, &mut problems));
        let legs_moments = legs.and_then(|f| expect(f.sigma_moments, &mut problems));
        let steps_robust = steps.and_then(|f| expect(f.sigma_robust, &mut problems));
        ErrorRow {
            floor: floor.to_string(),
            offset_deg: offset.is_finite().then(|| offset.to_degrees()),
            mean_step_m: mean_step,
            legs,
            steps,
            legs_robust,
            legs_moments,
            steps_robust,
            problems,
        }
    }
}

fn print_error_rows(rows: &[ErrorRow], wifi_mean: f64) {
    println!(
        "\nPDR error expectation (002 eq. 14) and TCPF alpha (eq. 17) for a Wi-Fi mean error of {wifi_mean:.2} m;\n\
         heading errors of the training legs (robust sigma = 1.4826 MAD; moments in brackets) and of single steps"
    );
    println!(
        "{:<10} {:>7} {:>5} {:>6} {:>7} {:>16} {:>9} {:>7} {:>7} {:>8} {:>8} {:>8}",
        "floor",
        "offset",
        "legs",
        "mean",
        "within",
        "sigma leg deg",
        "step deg",
        "step m",
        "E cm",
        "E75 cm",
        "per m",
        "alpha"
    );
    for r in rows {
        let offset = r
            .offset_deg
            .map_or_else(|| "-".to_string(), |o| format!("{o:.1}"));
        match (&r.legs, &r.legs_robust, &r.legs_moments) {
            (Some(l), Some(e), Some(m)) => println!(
                "{:<10} {:>7} {:>5} {:>6.2} {:>6.1}% {:>7.2} ({:>6.2}) {:>9} {:>7.3} {:>7.2} {:>8.2} {:>8.4} {:>8.5}",
                r.floor,
                offset,
                l.count,
                l.mean.to_degrees(),
                100.0 * l.within_10_15_20_deg[0],
                e.sigma_deg,
                m.sigma_deg,
                r.steps_robust
                    .as_ref()
                    .map_or_else(|| "-".to_string(), |s| format!("{:.2}", s.sigma_deg)),
                r.mean_step_m,
                e.per_step_cm,
                e.per_step_075_cm,
                e.per_metre,
                e.alpha
            ),
            _ => println!(
                "{:<10} {:>7} not fitted: {}",
                r.floor,
                offset,
                r.problems.join("; ")
            ),
        }
    }
    println!(
        "(within = legs within ±10°; E = per step at the mean step length, E75 at 0.75 m; \
         paper 002: sigma 8.5916°, E75 8.9675 cm, Wi-Fi 2.68 m)"
    );
}

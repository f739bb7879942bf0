//! `wipdr locate`: one walk's raw samples streamed through the online `Positioner`, its radio
//! map and PDR calibration learned from the other folds' walks of its floor (the evaluation
//! protocol), the track written as CSV or GeoJSON.
//!
//! ```text
//! wipdr locate --data ../shared/data/ilc20/site1/F1 --walk 5dd9e7b3f6a19f0006d1b4f0 \
//!     --scheme pmf --config docs/configs/best.toml --out track.csv
//! ```
//!
//! CSV: `t_ms,x,y,floor,sd_m` (metres in the floor's frame; `floor` and `sd_m` empty where
//! unknown), one row per estimate (after each step or Wi-Fi fix; for `pdr`, first the true
//! start). Scored at the walk's waypoints (latest estimate at or before each), the track
//! gives exactly the per-walk errors of `wipdr eval --json` for that walk and scheme.

use crate::cmd::eval::load_config;
use crate::data;
use anyhow::{Context, Result, bail};
use std::io::Write;
use std::path::PathBuf;
use wipdr_eval::pipeline;
use wipdr_positioning::PositionEstimate;

/// Output format of `wipdr locate`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// `t_ms,x,y,floor,sd_m` with a header.
    Csv,
    /// A GeoJSON Feature with a LineString in the floor's metre frame (properties: walk,
    /// scheme, times).
    Geojson,
}

/// Arguments of `wipdr locate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The floor folder holding the walk (its other walks give the radio map).
    #[arg(long)]
    pub data: PathBuf,
    /// The walk's id (its file name without `.txt[.gz]`).
    #[arg(long)]
    pub walk: String,
    /// The scheme (wifi, pdr, ekf, ..., pmf, or a name configured under `[schemes.*]`).
    #[arg(long, default_value = "pmf")]
    pub scheme: String,
    /// Evaluation config (TOML); defaults otherwise.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Output file.
    #[arg(long)]
    pub out: PathBuf,
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Csv)]
    pub format: Format,
}

/// Runs the subcommand.
pub fn run(args: Args) -> Result<()> {
    let cfg = load_config(args.config.as_deref())?;
    let floors = data::load_floors(std::slice::from_ref(&args.data))?;
    let Some(floor) = floors.first() else {
        bail!("no floor read from {}", args.data.display());
    };
    let track = pipeline::locate(floor, &args.walk, &args.scheme, &cfg)?;
    let file = std::fs::File::create(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let mut out = std::io::BufWriter::new(file);
    match args.format {
        Format::Csv => write_csv(&mut out, &track)?,
        Format::Geojson => write_geojson(&mut out, &track, &args.walk, &args.scheme)?,
    }
    out.flush()
        .with_context(|| format!("writing {}", args.out.display()))?;
    eprintln!(
        "{}: {} estimates of {} on walk {} -> {}",
        floor.label,
        track.len(),
        args.scheme,
        args.walk,
        args.out.display()
    );
    Ok(())
}

fn opt<T: std::fmt::Display>(v: Option<T>) -> String {
    v.map(|v| v.to_string()).unwrap_or_default()
}

/// Writes the CSV track (full precision: `f64` round-trips).
pub fn write_csv(out: &mut impl Write, track: &[PositionEstimate]) -> Result<()> {
    writeln!(out, "t_ms,x,y,floor,sd_m")?;
    for e in track {
        writeln!(
            out,
            "{},{},{},{},{}",
            e.t,
            e.position.x,
            e.position.y,
            opt(e.floor),
            opt(e.sd_m())
        )?;
    }
    Ok(())
}

/// Writes the track as a GeoJSON Feature (LineString, metre frame).
pub fn write_geojson(
    out: &mut impl Write,
    track: &[PositionEstimate],
    walk: &str,
    scheme: &str,
) -> Result<()> {
    let coordinates: Vec<[f64; 2]> = track.iter().map(|e| [e.position.x, e.position.y]).collect();
    let times: Vec<i64> = track.iter().map(|e| e.t).collect();
    let feature = serde_json::json!({
        "type": "Feature",
        "properties": {
            "walk": walk,
            "scheme": scheme,
            "frame": "floor metres (x east, y north, as the floor plan)",
            "t_ms": times,
        },
        "geometry": { "type": "LineString", "coordinates": coordinates },
    });
    serde_json::to_writer(&mut *out, &feature)?;
    writeln!(out)?;
    Ok(())
}

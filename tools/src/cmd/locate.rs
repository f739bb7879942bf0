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
//!
//! IPIN logfiles (the competition's output):
//!
//! ```text
//! wipdr locate --data ../shared/data/ipin2023/trials/IPIN2023_T3_TrainingTrial01_repetition01.txt.gz \
//!     --scheme ekf --out trial01.csv
//! ```
//!
//! `--data` a logfile: the radio map and calibration come from every other logfile of its
//! folder; the output (`--format ipin`, the default where the data has a WGS84 frame) is
//! `t_s,lat,lon,floor` at 2 Hz on the log's clock (every 0.5 s from the first estimate to
//! the walk's last sample, each row the latest estimate at or before its time), as the
//! competition asks. `--data DIR --walk ID` uses the protocol fold instead (as `eval`).

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
    /// The IPIN competition's `t_s,lat,lon,floor` at 2 Hz (needs a WGS84 frame: IPIN
    /// logfiles).
    Ipin,
}

/// Rows per second of [`Format::Ipin`].
pub const IPIN_RATE_HZ: i64 = 2;

/// Arguments of `wipdr locate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The floor folder holding the walk (its other folds' walks give the radio map), or an
    /// IPIN logfile (every other logfile of its folder gives the radio map).
    #[arg(long)]
    pub data: PathBuf,
    /// The walk's id (its file name without `.txt[.gz]`); not needed with a logfile.
    #[arg(long)]
    pub walk: Option<String>,
    /// The scheme (wifi, pdr, ekf, ..., pmf, or a name configured under `[schemes.*]`).
    #[arg(long, default_value = "pmf")]
    pub scheme: String,
    /// Evaluation config (TOML); defaults otherwise.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Output file.
    #[arg(long)]
    pub out: PathBuf,
    /// Output format (default: `ipin` where the data has a WGS84 frame, else `csv`).
    #[arg(long, value_enum)]
    pub format: Option<Format>,
}

/// Runs the subcommand.
pub fn run(args: Args) -> Result<()> {
    let cfg = load_config(args.config.as_deref())?;
    let (dir, walk, training) = if args.data.is_file() {
        let dir = args
            .data
            .parent()
            .map(|p| {
                if p.as_os_str().is_empty() {
                    std::path::Path::new(".")
                } else {
                    p
                }
            })
            .unwrap_or(std::path::Path::new("."))
            .to_path_buf();
        let id = wipdr_io::trace::walk_id_of(&args.data);
        if let Some(w) = &args.walk
            && *w != id
        {
            bail!(
                "--walk {w} names another walk than --data {}",
                args.data.display()
            );
        }
        (dir, id, pipeline::Training::AllOthers)
    } else {
        let Some(walk) = args.walk.clone() else {
            bail!(
                "--walk is needed with a folder (--data {})",
                args.data.display()
            );
        };
        (args.data.clone(), walk, pipeline::Training::ProtocolFold)
    };
    let floors = data::load_floors(std::slice::from_ref(&dir))?;
    let Some(floor) = floors.first() else {
        bail!("no floor read from {}", dir.display());
    };
    let track = pipeline::locate_with(floor, &walk, &args.scheme, &cfg, training)?;
    let format = args.format.unwrap_or(if floor.data.geo_frame.is_some() {
        Format::Ipin
    } else {
        Format::Csv
    });
    let file = std::fs::File::create(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let mut out = std::io::BufWriter::new(file);
    match format {
        Format::Csv => write_csv(&mut out, &track)?,
        Format::Geojson => write_geojson(&mut out, &track, &walk, &args.scheme)?,
        Format::Ipin => {
            let Some(frame) = floor.data.geo_frame else {
                bail!(
                    "--format ipin needs latitude/longitude: {} has no WGS84 frame (IPIN logfiles have one)",
                    dir.display()
                );
            };
            let end = floor
                .data
                .walk(&walk)
                .and_then(|w| w.time_span())
                .map(|(_, end)| end);
            write_ipin(&mut out, &track, &frame, end)?
        }
    }
    out.flush()
        .with_context(|| format!("writing {}", args.out.display()))?;
    eprintln!(
        "{}: {} estimates of {} on walk {} -> {}",
        floor.label,
        track.len(),
        args.scheme,
        walk,
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

/// The track at [`IPIN_RATE_HZ`]: a row at every multiple of the period from the first
/// estimate to `end` (the walk's last sample; the last estimate when `None`), each the latest
/// estimate at or before its time.
pub fn at_rate(
    track: &[PositionEstimate],
    period_ms: i64,
    end: Option<wipdr_core::TimestampMs>,
) -> Vec<PositionEstimate> {
    let (Some(first), Some(last)) = (track.first(), track.last()) else {
        return Vec::new();
    };
    let period = period_ms.max(1);
    let end = end.unwrap_or(last.t).max(last.t);
    let mut t = first.t.div_euclid(period) * period;
    if t < first.t {
        t += period;
    }
    let mut out = Vec::new();
    let mut j = 0usize;
    while t <= end {
        while j + 1 < track.len() && track[j + 1].t <= t {
            j += 1;
        }
        out.push(PositionEstimate { t, ..track[j] });
        t += period;
    }
    out
}

/// Writes `t_s,lat,lon,floor` at [`IPIN_RATE_HZ`] (the IPIN competition's format; `floor`
/// empty where unknown).
pub fn write_ipin(
    out: &mut impl Write,
    track: &[PositionEstimate],
    frame: &wipdr_core::GeoFrame,
    end: Option<wipdr_core::TimestampMs>,
) -> Result<()> {
    writeln!(out, "t_s,lat,lon,floor")?;
    for e in at_rate(track, 1000 / IPIN_RATE_HZ, end) {
        let (lat, lon) = frame.to_lat_lon(e.position);
        writeln!(
            out,
            "{:.3},{:.9},{:.9},{}",
            e.t as f64 / 1000.0,
            lat,
            lon,
            opt(e.floor)
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

#[cfg(test)]
mod tests {
    use super::*;
    use wipdr_core::Point2;

    fn est(t: i64, x: f64) -> PositionEstimate {
        PositionEstimate {
            t,
            position: Point2::new(x, 0.0),
            floor: Some(0),
            covariance: None,
        }
    }

    #[test]
    fn two_hertz_rows_take_the_latest_estimate() {
        let track = [est(120, 1.0), est(700, 2.0), est(1_400, 3.0)];
        let rows = at_rate(&track, 500, Some(2_100));
        let got: Vec<(i64, f64)> = rows.iter().map(|e| (e.t, e.position.x)).collect();
        assert_eq!(
            got,
            vec![(500, 1.0), (1_000, 2.0), (1_500, 3.0), (2_000, 3.0)]
        );
        assert!(at_rate(&[], 500, None).is_empty());
    }

    #[test]
    fn ipin_rows_are_in_degrees() {
        let frame = wipdr_core::GeoFrame::new(49.46, 11.11).unwrap();
        let mut out = Vec::new();
        write_ipin(&mut out, &[est(0, 0.0)], &frame, Some(400)).unwrap();
        let text = String::from_utf8(out).unwrap();
        assert_eq!(
            text,
            "t_s,lat,lon,floor\n0.000,49.460000000,11.110000000,0\n"
        );
    }
}

//! `wipdr locate`: phone logs positioned with a site model (`--model`), or one walk of an
//! evaluation folder under the protocol (`--data`), the track written as CSV, GeoJSON or the
//! IPIN competition's rows.
//!
//! ```text
//! wipdr fit --data $WIPDR_DATA/ilc20/site1 --out site1.wipdr
//! wipdr locate --model site1.wipdr $WIPDR_DATA/ilc20/site1/F1/path_data_files/5dd9e7aac5b77e0006b1732b.txt.gz --out track.csv
//! wipdr locate --model ipin.wipdr LOG1.txt LOG2.txt --scheme ekf --format ipin --out tracks/
//! wipdr locate --model site1.wipdr my_phone.csv --out my_phone.geojson --format geojson
//! ```
//!
//! Inputs: ILC traces (`.txt`, `.txt.gz`), IPIN logfiles (GetSensorData), or plain sample
//! streams (`.csv`, `.jsonl`: the format of `docs/guide.md` "Your own phone logs",
//! `wipdr_io::sample_stream`). One input: `--out` is the file; several: `--out` is a folder
//! that receives `<input file name>.<csv|geojson|txt>` (the name without `.gz` and its format
//! extension).
//!
//! CSV: `t_ms,x,y,floor,sd_m` (metres in the model's frame; `floor` and `sd_m` empty where
//! unknown), one row per estimate (after each step or Wi-Fi fix; for `pdr`, first the true
//! start). IPIN (`--format ipin`, the default where the model has a WGS84 frame):
//! `t_s,lat,lon,floor` at 2 Hz on the log's clock (every 0.5 s from the first estimate to
//! the walk's last sample, each row the latest estimate at or before its time), as the
//! competition asks. GeoJSON: a Feature with the track as a LineString, in longitude and
//! latitude where the model has a WGS84 frame, else in the model's metres (the
//! `frame` property says which).
//!
//! `--data DIR --walk ID` (a protocol helper) fits the walk's fold as `wipdr eval` does and
//! locates it; `--data LOGFILE` fits every other logfile of its folder. Scored at the walk's
//! waypoints (latest estimate at or before each), both give exactly the per-walk errors of
//! `wipdr eval --json` for that walk and scheme, as does `--model` on a model fit with
//! `wipdr fit --leave-out-fold-of WALK`.

use crate::cmd::eval::load_config;
use crate::data;
use anyhow::{Context, Result, bail};
use rayon::prelude::*;
use std::io::Write;
use std::path::{Path, PathBuf};
use wipdr_core::{GeoFrame, Walk};
use wipdr_eval::pipeline;
use wipdr_positioning::PositionEstimate;
use wipdr_positioning::site_model::SiteModel;
use wipdr_positioning::track_format;

/// Output format of `wipdr locate`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// `t_ms,x,y,floor,sd_m` with a header.
    Csv,
    /// A GeoJSON Feature with a LineString (longitude/latitude where the site has a WGS84
    /// frame, else its metres; properties: walk, scheme, times, floors, radii).
    Geojson,
    /// The IPIN competition's `t_s,lat,lon,floor` at 2 Hz (needs a WGS84 frame: IPIN
    /// logfiles).
    Ipin,
}

impl Format {
    fn extension(self) -> &'static str {
        match self {
            Self::Csv => "csv",
            Self::Geojson => "geojson",
            Self::Ipin => "txt",
        }
    }
}

/// Arguments of `wipdr locate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A site model (`wipdr fit`): position the WALK_FILEs with it.
    #[arg(long, conflicts_with_all = ["data", "walk", "config"])]
    pub model: Option<PathBuf>,
    /// Phone logs to position with `--model`: ILC traces, IPIN logfiles, plain sample streams
    /// (`.csv`, `.jsonl`).
    #[arg(value_name = "WALK_FILE", requires = "model")]
    pub inputs: Vec<PathBuf>,
    /// Protocol helper: the floor folder holding the walk (its other folds' walks give the
    /// radio map), or an IPIN logfile (every other logfile of its folder gives the radio map).
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// The walk's id (its file name without `.txt[.gz]`), with a `--data` folder.
    #[arg(long)]
    pub walk: Option<String>,
    /// The scheme (wifi, pdr, ekf, ..., pmf, or a name configured under `[schemes.*]`).
    #[arg(long, default_value = "pmf")]
    pub scheme: String,
    /// Evaluation config (TOML) with `--data`; a model carries its own settings.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Output file (one input) or folder (several inputs).
    #[arg(long)]
    pub out: PathBuf,
    /// Output format (default: `ipin` where the data has a WGS84 frame, else `csv`).
    #[arg(long, value_enum)]
    pub format: Option<Format>,
    /// Whole-walk smoothed estimates, made after the walk ends, instead of causal ones.
    #[arg(long)]
    pub offline: bool,
}

/// Runs the subcommand.
pub fn run(args: Args) -> Result<()> {
    if let Some(model) = &args.model {
        return run_with_model(model, &args);
    }
    let Some(data_path) = args.data.clone() else {
        bail!("give --model SITE.wipdr WALK_FILE... (or the protocol helper --data DIR --walk ID)");
    };
    let mut cfg = load_config(args.config.as_deref())?;
    cfg.offline |= args.offline;
    let (dir, walk, training) = if data_path.is_file() {
        let dir = data_path
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
        let id = wipdr_io::trace::walk_id_of(&data_path);
        if let Some(w) = &args.walk
            && *w != id
        {
            bail!(
                "--walk {w} names another walk than --data {}",
                data_path.display()
            );
        }
        (dir, id, pipeline::Training::AllOthers)
    } else {
        let Some(walk) = args.walk.clone() else {
            bail!(
                "--walk is needed with a folder (--data {})",
                data_path.display()
            );
        };
        (data_path.clone(), walk, pipeline::Training::ProtocolFold)
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
    let end = floor
        .data
        .walk(&walk)
        .and_then(|w| w.time_span())
        .map(|(_, end)| end);
    write_track(
        &args.out,
        format,
        &track,
        &walk,
        &args.scheme,
        floor.data.geo_frame.as_ref(),
        end,
    )?;
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

/// Reads one phone log for a model: a plain sample stream, an IPIN logfile (its ground
/// truth, if any, placed in the model's WGS84 frame, so that it can be scored in the model's
/// metres) or an ILC trace.
pub fn read_input(path: &Path, frame: Option<&GeoFrame>) -> Result<Walk> {
    let limits = wipdr_io::Limits::default();
    if wipdr_io::sample_stream::is_sample_stream(path) {
        return Ok(wipdr_io::sample_stream::read_sample_stream(path, &limits)?);
    }
    if wipdr_io::logfile::is_logfile(path) {
        let log = wipdr_io::logfile::read_logfile(path, &limits)?;
        return Ok(match frame {
            Some(f) => log.into_walk(f).walk,
            None => wipdr_io::any::read_walk_file(path, &limits)?.walk,
        });
    }
    Ok(wipdr_io::trace::read_walk_with(path, &limits)?.walk)
}

fn run_with_model(model_path: &Path, args: &Args) -> Result<()> {
    if args.inputs.is_empty() {
        bail!(
            "--model {}: give the walk files to position",
            model_path.display()
        );
    }
    let model = SiteModel::load(model_path)?;
    let frame = model.data().geo_frame;
    let format = args.format.unwrap_or(if frame.is_some() {
        Format::Ipin
    } else {
        Format::Csv
    });
    if format == Format::Ipin && frame.is_none() {
        bail!(
            "--format ipin needs latitude/longitude: the model {} has no WGS84 frame (IPIN logfile folders have one)",
            model_path.display()
        );
    }
    // Check the scheme once, before reading any input.
    model.scheme(&args.scheme)?;
    let several = args.inputs.len() > 1;
    let stems: Vec<String> = args
        .inputs
        .iter()
        .map(|p| wipdr_io::sample_stream::stream_id_of(p))
        .map(|id| id.strip_suffix(".txt").map(str::to_string).unwrap_or(id))
        .collect();
    let mut seen = std::collections::BTreeMap::new();
    for (stem, input) in stems.iter().zip(&args.inputs) {
        if let Some(first) = seen.insert(stem.clone(), input) {
            bail!(
                "{} and {} would both be written to {}.{}: give the inputs different file names",
                first.display(),
                input.display(),
                stem,
                format.extension()
            );
        }
    }
    if several {
        std::fs::create_dir_all(&args.out)
            .with_context(|| format!("creating the folder {}", args.out.display()))?;
    }
    let results: Vec<Result<(String, usize, PathBuf)>> = args
        .inputs
        .par_iter()
        .zip(&stems)
        .map(|(input, stem)| {
            let walk = read_input(input, frame.as_ref())
                .with_context(|| format!("reading {}", input.display()))?;
            let track = pipeline::locate_walk(&model, &walk, &args.scheme, args.offline)
                .with_context(|| format!("positioning {}", input.display()))?;
            let out = if several {
                args.out.join(format!("{stem}.{}", format.extension()))
            } else {
                args.out.clone()
            };
            let end = walk.time_span().map(|(_, end)| end);
            write_track(
                &out,
                format,
                &track,
                &walk.meta.id,
                &args.scheme,
                frame.as_ref(),
                end,
            )?;
            Ok((walk.meta.id.clone(), track.len(), out))
        })
        .collect();
    let mut failed = 0usize;
    for r in results {
        match r {
            Ok((id, n, out)) => eprintln!(
                "{}: {n} estimates of {} on walk {id} -> {}",
                model.name(),
                args.scheme,
                out.display()
            ),
            Err(e) => {
                failed += 1;
                eprintln!("error: {e:#}");
            }
        }
    }
    if failed > 0 {
        bail!(
            "{failed} of {} inputs could not be positioned",
            args.inputs.len()
        );
    }
    Ok(())
}

/// Writes a track to `path` in `format`.
pub fn write_track(
    path: &Path,
    format: Format,
    track: &[PositionEstimate],
    walk: &str,
    scheme: &str,
    frame: Option<&GeoFrame>,
    end: Option<wipdr_core::TimestampMs>,
) -> Result<()> {
    let file =
        std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
    let mut out = std::io::BufWriter::new(file);
    let rows = track_format::rows_of(track);
    let text = match format {
        Format::Csv => track_format::csv(&rows),
        Format::Geojson => format!("{}\n", track_format::geojson(&rows, walk, scheme, frame)),
        Format::Ipin => {
            let Some(frame) = frame else {
                bail!(
                    "--format ipin needs latitude/longitude: the data has no WGS84 frame (IPIN logfiles have one)"
                );
            };
            track_format::ipin(&rows, frame, end)
        }
    };
    out.write_all(text.as_bytes())
        .with_context(|| format!("writing {}", path.display()))?;
    out.flush()
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

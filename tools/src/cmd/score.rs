//! `wipdr score --truth GT.csv EST_FILE...`: the IPIN competition's official scoring of EvAAL
//! API estimates files against a trial's ground truth ([`wipdr_eval::evaal_score`]), one row
//! per estimates file with the organisers' columns in their order and their layout (fields
//! separated by tabs, shown here as spaces):
//!
//! ```text
//! TeamName-FileId      EvAAL    MEAN     RMSE     MEDIAN   P95      FHR(%)   MPExy    POINTS
//!       S323ZENODOTS01:   5.75     5.01     6.47     3.80    16.34    94.20     4.14   69
//! ```
//!
//! The row's name is the estimates file's name without its extension. With `--json` (no
//! value, or `-`) the figures go to standard output as JSON instead of the table; with
//! `--json FILE` they are written there and the table is printed:
//!
//! ```text
//! { "truth": "GT.csv", "columns": ["EvAAL", ..., "POINTS"],
//!   "results": [ { "id", "file", "coordinates_swapped",
//!                  "score": { "evaal", "mean", "rmse", "median", "p95", "fhr_percent",
//!                             "mpe_xy", "points" } }, ... ] }
//! ```

use anyhow::{Context, Result};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use wipdr_eval::evaal_score::{EVAAL_COLUMNS, EvaalScore, evaal_scoring};
use wipdr_io::Limits;
use wipdr_io::evaal::{read_evaal_estimates, read_evaal_truth};

/// Arguments of `wipdr score`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The trial's ground truth (`GT_*.csv`: time s, longitude, latitude, floor, point number).
    #[arg(long, value_name = "GT.csv")]
    pub truth: PathBuf,
    /// Estimates files (`*.est`, the EvAAL API's estimates log: pts, c, h, s, longitude,
    /// latitude, floor; the first two lines are not estimates). One table row each.
    #[arg(required = true, value_name = "EST_FILE")]
    pub estimates: Vec<PathBuf>,
    /// The figures as JSON: to standard output instead of the table (no value or `-`), or
    /// to FILE.
    #[arg(long, value_name = "FILE", num_args = 0..=1, default_missing_value = "-")]
    pub json: Option<PathBuf>,
}

/// The `--json` document (fields in this order).
#[derive(Debug, Serialize)]
struct Document<'a> {
    truth: &'a Path,
    columns: [&'static str; 8],
    results: &'a [Row],
}

/// One estimates file's figures, as `--json` writes them.
#[derive(Debug, Serialize)]
struct Row {
    id: String,
    file: PathBuf,
    coordinates_swapped: bool,
    score: EvaalScore,
}

/// Runs `wipdr score`.
pub fn run(args: Args) -> Result<()> {
    let limits = Limits::default();
    let truth = read_evaal_truth(&args.truth, &limits)?;
    let mut rows = Vec::with_capacity(args.estimates.len());
    for file in &args.estimates {
        let estimates = read_evaal_estimates(file, &limits)?;
        let scoring = evaal_scoring(&truth, &estimates).with_context(|| {
            format!(
                "{}: cannot be scored against {}",
                file.display(),
                args.truth.display()
            )
        })?;
        rows.push(Row {
            id: file_id(file),
            file: file.clone(),
            coordinates_swapped: scoring.coordinates_swapped,
            score: scoring.score,
        });
    }
    let to_stdout = args.json.as_deref().is_some_and(|p| p == Path::new("-"));
    if let Some(path) = args.json.as_deref() {
        let document = Document {
            truth: &args.truth,
            columns: EVAAL_COLUMNS,
            results: &rows,
        };
        let text = serde_json::to_string_pretty(&document)? + "\n";
        if to_stdout {
            print!("{text}");
        } else {
            std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))?;
        }
    }
    if !to_stdout {
        print!("{}", table(&rows));
        for r in rows.iter().filter(|r| r.coordinates_swapped) {
            eprintln!(
                "note: {}: longitude and latitude were swapped (latitude median under 10 degrees): swapped back",
                r.file.display()
            );
        }
    }
    Ok(())
}

/// The row name of an estimates file: its name without the extension.
fn file_id(file: &Path) -> String {
    file.file_stem()
        .unwrap_or(file.as_os_str())
        .to_string_lossy()
        .into_owned()
}

/// The organisers' table: a header, then one row per file.
fn table(rows: &[Row]) -> String {
    let mut out = format!("{:<20}", "TeamName-FileId");
    for c in EVAAL_COLUMNS {
        let _ = write!(out, "\t{c:<7}");
    }
    let mut out = out.trim_end().to_string();
    out.push('\n');
    for r in rows {
        let s = &r.score;
        let _ = write!(out, "{:>20}:", r.id);
        for v in [
            s.evaal,
            s.mean,
            s.rmse,
            s.median,
            s.p95,
            s.fhr_percent,
            s.mpe_xy,
        ] {
            let _ = write!(out, "\t{v:7.2}");
        }
        let _ = writeln!(out, "\t{}", s.points);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_has_the_organisers_layout() {
        let score = EvaalScore {
            evaal: 5.7549,
            mean: 5.01,
            rmse: 6.47,
            median: 3.8,
            p95: 16.34,
            fhr_percent: 94.2029,
            mpe_xy: 4.14,
            points: 69,
        };
        let rows = [Row {
            id: file_id(Path::new("/x/S323ZENODOTS01.est")),
            file: PathBuf::new(),
            coordinates_swapped: false,
            score,
        }];
        assert_eq!(
            table(&rows),
            "TeamName-FileId     \tEvAAL  \tMEAN   \tRMSE   \tMEDIAN \tP95    \tFHR(%) \tMPExy  \tPOINTS\n      S323ZENODOTS01:\t   5.75\t   5.01\t   6.47\t   3.80\t  16.34\t  94.20\t   4.14\t69\n"
        );
    }
}

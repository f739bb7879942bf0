//! `wipdr report RESULTS.json --out FILE.html`: the report page of a saved run (the JSON of
//! `wipdr eval --json`; with `--json-tracks` the page draws the walks too).

use anyhow::{Context, Result};
use std::path::PathBuf;

/// Arguments of `wipdr report`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A results JSON written by `wipdr eval --json` (best with `--json-tracks`).
    pub results: PathBuf,
    /// The page to write (one self-contained HTML file).
    #[arg(long, value_name = "FILE.html")]
    pub out: PathBuf,
}

/// Runs the subcommand.
pub fn run(args: Args) -> Result<()> {
    let path = &args.results;
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let value: serde_json::Value = serde_json::from_str(&text)
        .with_context(|| format!("{}: not a results JSON", path.display()))?;
    let drawn = value.get("walk_data").is_some();
    if !drawn {
        eprintln!(
            "note: {} has no drawing data (written without --json-tracks): the page has the \
             tables, the CDF and the walk list, but no tracks",
            path.display()
        );
    }
    crate::report::write_page(&value, &path.display().to_string(), &args.out)
}

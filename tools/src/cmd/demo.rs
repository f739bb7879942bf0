//! `wipdr demo`: the evaluation protocol on the embedded synthetic fixtures, in seconds.

use anyhow::{Context, Result};
use std::path::PathBuf;

/// Arguments of `wipdr demo`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Schemes to run, comma separated.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "wifi,pdr,ekf,aekf,akf,rkf,arkf,aws,tcpf,pf,apf,rof,pmf"
    )]
    schemes: Vec<String>,
    /// Write plots into this folder.
    #[arg(long)]
    plots: Option<PathBuf>,
    /// Write the figures as JSON.
    #[arg(long)]
    json: Option<PathBuf>,
}

/// The committed fixtures (`fixtures/sim/`), found relative to this crate's sources.
pub fn fixture_floors() -> Result<Vec<PathBuf>> {
    let root = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/sim"));
    let mut floors: Vec<PathBuf> = std::fs::read_dir(&root)
        .with_context(|| format!("the fixtures folder {} is missing", root.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.join("floor_info.json").is_file())
        .collect();
    floors.sort();
    if floors.is_empty() {
        anyhow::bail!("no floor folder under {}", root.display());
    }
    Ok(floors)
}

/// Runs the subcommand.
pub fn run(args: Args) -> Result<()> {
    let dirs = fixture_floors()?;
    println!(
        "wipdr demo: synthetic fixtures in {}",
        dirs[0].parent().unwrap_or(&dirs[0]).display()
    );
    let floors = crate::data::load_floors(&dirs)?;
    let cfg = wipdr_eval::pipeline::EvalConfig::default();
    let outputs = crate::cmd::eval::Outputs {
        json: args.json.as_deref(),
        plots: args.plots.as_deref(),
        plot_walks: 1,
        ..Default::default()
    };
    crate::cmd::eval::evaluate_and_report(&floors, &cfg, &args.schemes, &outputs)?;
    Ok(())
}

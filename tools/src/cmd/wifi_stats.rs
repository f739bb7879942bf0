//! `wipdr wifi-stats` (not implemented yet).

/// Arguments of `wipdr wifi-stats`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`wipdr wifi-stats` is not implemented yet")
}

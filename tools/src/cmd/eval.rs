//! `wipdr eval` (not implemented yet).

/// Arguments of `wipdr eval`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`wipdr eval` is not implemented yet")
}

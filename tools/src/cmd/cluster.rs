//! `wipdr cluster` (not implemented yet).

/// Arguments of `wipdr cluster`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`wipdr cluster` is not implemented yet")
}

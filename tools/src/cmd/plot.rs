//! `wipdr plot` (not implemented yet).

/// Arguments of `wipdr plot`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`wipdr plot` is not implemented yet")
}

//! `wipdr pdr-fit` (not implemented yet).

/// Arguments of `wipdr pdr-fit`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`wipdr pdr-fit` is not implemented yet")
}

//! `wipdr pdr-eval` (not implemented yet).

/// Arguments of `wipdr pdr-eval`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`wipdr pdr-eval` is not implemented yet")
}

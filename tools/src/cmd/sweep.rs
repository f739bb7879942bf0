//! `wipdr sweep` (not implemented yet).

/// Arguments of `wipdr sweep`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`wipdr sweep` is not implemented yet")
}

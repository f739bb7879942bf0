//! `wipdr inspect` (not implemented yet).

/// Arguments of `wipdr inspect`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`wipdr inspect` is not implemented yet")
}

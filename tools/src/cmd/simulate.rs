//! `wipdr simulate` (not implemented yet).

/// Arguments of `wipdr simulate`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`wipdr simulate` is not implemented yet")
}

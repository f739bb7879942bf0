//! `wipdr demo` (not implemented yet).

/// Arguments of `wipdr demo`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`wipdr demo` is not implemented yet")
}

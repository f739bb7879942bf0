//! `wipdr fingerprint-eval` (not implemented yet).

/// Arguments of `wipdr fingerprint-eval`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`wipdr fingerprint-eval` is not implemented yet")
}

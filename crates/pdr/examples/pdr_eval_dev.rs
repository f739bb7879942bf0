//! Temporary development driver (removed before hand-off).
#![allow(missing_docs, dead_code)]
#[path = "../../../tools/src/plotting.rs"]
mod plotting;
#[path = "../../../tools/src/progress.rs"]
mod progress;
mod cmd {
    #[path = "/work/main/tools/src/cmd/pdr_eval.rs"]
    pub mod pdr_eval;
}
use clap::Parser;
#[derive(Parser)]
struct Cli {
    #[command(flatten)]
    args: cmd::pdr_eval::Args,
}
fn main() -> anyhow::Result<()> {
    tracing_subscriber::fmt().with_env_filter(tracing_subscriber::EnvFilter::from_default_env()).with_writer(std::io::stderr).init();
    cmd::pdr_eval::run(Cli::parse().args)
}

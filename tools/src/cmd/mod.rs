//! One module per subcommand: `Args` (clap) and `run`.

pub mod cache;
pub mod cluster;
pub mod demo;
pub mod evaal;
pub mod eval;
pub mod export_stream;
pub mod fingerprint_eval;
pub mod fit;
pub mod inspect;
pub mod locate;
pub mod pdr_eval;
pub mod pdr_fit;
pub mod plot;
pub mod replay;
pub mod report;
pub mod score;
pub mod serve;
pub mod simulate;
pub mod sweep;
pub mod wifi_stats;

//! The errors of an evaluation: one enum for the protocol, its config, sweeps and shards.

use thiserror::Error;

/// Errors of an evaluation.
#[derive(Debug, Error)]
pub enum EvalError {
    /// A floor has fewer walks than folds.
    #[error("floor {floor}: {walks} walks, need at least {folds} for the protocol folds")]
    TooFewWalks {
        /// Floor label.
        floor: String,
        /// Walks found.
        walks: usize,
        /// Folds required.
        folds: usize,
    },
    /// Walks with routes (leave-one-route-out) of fewer than two routes.
    #[error(
        "floor {floor}: its walks cover {routes} route(s); leave-one-route-out needs at least 2"
    )]
    TooFewRoutes {
        /// Floor label.
        floor: String,
        /// Distinct routes found.
        routes: usize,
    },
    /// Building a radio map or matcher failed.
    #[error("floor {floor}, fold {fold}: {source}")]
    Fingerprint {
        /// Floor label.
        floor: String,
        /// Fold.
        fold: usize,
        /// Cause.
        source: wipdr_fingerprint::FingerprintError,
    },
    /// A sweep could not be set up or recorded.
    #[error("sweep: {0}")]
    Sweep(String),
    /// A config file could not be read (syntax, unknown or removed field, bad value).
    #[error("config {origin}: {reason}")]
    Config {
        /// Where the config came from (a file path).
        origin: String,
        /// What is wrong, with the field path.
        reason: String,
    },
    /// A config value is out of range: the field's dotted path and what is wrong.
    #[error(transparent)]
    InvalidConfig(#[from] wipdr_core::ConfigError),
    /// The positioning pipeline could not be built.
    #[error("floor {floor}: {source}")]
    Positioning {
        /// Floor label.
        floor: String,
        /// Cause.
        source: wipdr_positioning::PositioningError,
    },
    /// A walk asked for is not on the floor.
    #[error("floor {floor}: no walk {walk:?}")]
    UnknownWalk {
        /// Floor label.
        floor: String,
        /// Walk id asked for.
        walk: String,
    },
    /// A fold's site model could not be fit.
    #[error("floor {floor}: site model: {reason}")]
    Site {
        /// Floor label.
        floor: String,
        /// Cause.
        reason: String,
    },
    /// A scheme could not be built from its config.
    #[error("scheme {scheme}: {source}")]
    Scheme {
        /// Scheme name.
        scheme: String,
        /// Cause.
        source: wipdr_fusion::FusionError,
    },
}

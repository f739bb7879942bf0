//! Errors of the positioning pipeline.

use thiserror::Error;

/// Why a [`crate::Positioner`] could not be built or configured.
#[derive(Debug, Error)]
pub enum PositioningError {
    /// The matcher could not be built (empty map, bad settings).
    #[error("matcher: {0}")]
    Matcher(#[from] wipdr_fingerprint::FingerprintError),
    /// The fusion scheme could not be built.
    #[error("scheme {scheme}: {source}")]
    Scheme {
        /// Scheme name.
        scheme: String,
        /// Cause.
        source: wipdr_fusion::FusionError,
    },
    /// A config value is out of range; `path` is the dotted config path.
    #[error("{path}: {reason}")]
    InvalidConfig {
        /// Dotted path of the field (`scheme.r_wifi_m2`, `matcher.k`).
        path: String,
        /// What is wrong, with the value given.
        reason: String,
    },
    /// A config text could not be read (syntax, unknown field, wrong type).
    #[error("config: {0}")]
    Parse(String),
}

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
    /// A config value is out of range; its path is the dotted config path
    /// (`scheme.r_wifi_m2`, `matcher.k`).
    #[error(transparent)]
    InvalidConfig(#[from] wipdr_core::ConfigError),
    /// A config text could not be read (syntax, unknown field, wrong type).
    #[error("config: {0}")]
    Parse(String),
}

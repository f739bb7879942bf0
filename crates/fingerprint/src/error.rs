//! Errors of the fingerprint crate.

use thiserror::Error;

/// Errors of radio-map construction and matching.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum FingerprintError {
    /// A scan with no entries at all.
    #[error("empty scan (no access points)")]
    EmptyScan,
    /// Nothing usable remained after online filtering.
    #[error(
        "no usable access point in the scan: {unknown} unknown to the map, {below_threshold} below \
         the RSSI threshold, {invalid_rssi} with invalid RSSI"
    )]
    NoUsableAps {
        /// Entries whose AP is not in the map's vocabulary.
        unknown: usize,
        /// Entries weaker than the RSSI threshold.
        below_threshold: usize,
        /// Entries with NaN or out-of-range RSSI.
        invalid_rssi: usize,
    },
    /// An RSSI that is NaN or outside `[-120, 0]` dBm, in strict mode.
    #[error("invalid RSSI {value} dBm for AP {ap} (valid: [-120, 0], finite)")]
    InvalidRssi {
        /// The AP (BSSID or column name).
        ap: String,
        /// The offending value.
        value: f64,
    },
    /// A dense query row whose length is not the map's number of APs.
    #[error("query has {found} AP columns, the radio map has {expected}")]
    DimensionMismatch {
        /// The map's number of APs.
        expected: usize,
        /// The query's number of columns.
        found: usize,
    },
    /// A radio map whose reference points hear no access point at all: every query would
    /// be equally far from every point.
    #[error(
        "no access point is heard at any of the radio map's {points} reference points ({aps} AP \
         columns, all \"not heard\"): nothing to match against"
    )]
    NothingHeard {
        /// Reference points.
        points: usize,
        /// AP columns.
        aps: usize,
    },
    /// A radio map without reference points.
    #[error("the radio map has no reference points")]
    EmptyMap,
    /// An invalid configuration value: the field's dotted path and what is wrong.
    #[error(transparent)]
    InvalidConfig(#[from] wipdr_core::ConfigError),
    /// A limit on memory crossed (before the memory is allocated): what was asked for, the
    /// limit's config field and value, and how to raise it (boxed: the error stays small).
    #[error("{0}")]
    LimitExceeded(Box<LimitError>),
    /// Invalid input data while building a map (names the item).
    #[error("invalid input: {0}")]
    InvalidInput(String),
}

impl FingerprintError {
    /// The error as a config error: its [`wipdr_core::ConfigError`] when it is one, else
    /// the message under an empty path (a check that failed for another reason).
    pub fn into_config_error(self) -> wipdr_core::ConfigError {
        match self {
            Self::InvalidConfig(e) => e,
            other => wipdr_core::ConfigError::new("", other.to_string()),
        }
    }
}

/// The details of [`FingerprintError::LimitExceeded`].
#[derive(Debug, Error, Clone, PartialEq)]
#[error("{what}: over the limit `{limit}` = {max}; {hint}")]
pub struct LimitError {
    /// What would have been allocated.
    pub what: String,
    /// The config field of the limit (dotted path).
    pub limit: String,
    /// The limit's value.
    pub max: String,
    /// How to raise it.
    pub hint: String,
}

impl FingerprintError {
    /// A [`FingerprintError::LimitExceeded`].
    pub fn limit_exceeded(
        what: impl Into<String>,
        limit: impl Into<String>,
        max: impl ToString,
        hint: impl Into<String>,
    ) -> Self {
        Self::LimitExceeded(Box::new(LimitError {
            what: what.into(),
            limit: limit.into(),
            max: max.to_string(),
            hint: hint.into(),
        }))
    }
}

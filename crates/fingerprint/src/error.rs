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
    /// A radio map without reference points.
    #[error("the radio map has no reference points")]
    EmptyMap,
    /// An invalid configuration value.
    #[error("invalid configuration: {0}")]
    InvalidConfig(String),
    /// Invalid input data while building a map (names the item).
    #[error("invalid input: {0}")]
    InvalidInput(String),
}

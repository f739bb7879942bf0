//! Errors of the core vocabulary.

use thiserror::Error;

/// Errors raised when core values are built from untrusted parts.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum CoreError {
    /// A BSSID string is not six `:`-separated hex bytes.
    #[error("invalid BSSID {0:?}: expected six ':'-separated hex bytes")]
    InvalidBssid(String),
    /// A value that must be finite is NaN or infinite.
    #[error("non-finite value in field {field}")]
    NonFinite {
        /// The offending field.
        field: &'static str,
    },
    /// A polygon with fewer than three vertices.
    #[error("degenerate polygon with {0} vertices (need at least 3)")]
    DegeneratePolygon(usize),
    /// A floor of non-positive or non-finite size.
    #[error("invalid floor size {width} x {height} m")]
    InvalidFloorSize {
        /// Width in metres.
        width: f64,
        /// Height in metres.
        height: f64,
    },
    /// A value outside its valid range.
    #[error("{field} {value} is out of range")]
    InvalidValue {
        /// The offending field.
        field: &'static str,
        /// The value given.
        value: f64,
    },
}

//! Errors of the core vocabulary.

use thiserror::Error;

/// A configuration value that is out of range or inconsistent: the dotted path of the field
/// in the config file (`schemes.pmf.wifi_sd_m`, `matcher.k`) and what is wrong with it, the
/// value given included. Every crate's config check returns this one shape; a caller that
/// holds the checked config under a section prefixes the path with [`ConfigError::under`].
///
/// ```
/// use wipdr_core::ConfigError;
/// let e = ConfigError::new("wifi_sd_m", "must be finite and > 0, got -1").under("schemes.pmf");
/// assert_eq!(e.to_string(), "schemes.pmf.wifi_sd_m: must be finite and > 0, got -1");
/// assert_eq!(e.path, "schemes.pmf.wifi_sd_m");
/// ```
#[derive(Debug, Error, Clone, PartialEq, Eq)]
#[error("{path}: {reason}")]
pub struct ConfigError {
    /// Dotted path of the field, from the top of the config the caller read.
    pub path: String,
    /// What is wrong, with the value given.
    pub reason: String,
}

impl ConfigError {
    /// The field at `path` is wrong for `reason`.
    pub fn new(path: impl Into<String>, reason: impl Into<String>) -> Self {
        Self {
            path: path.into(),
            reason: reason.into(),
        }
    }

    /// The same error seen from the config holding this one under `section`
    /// (`"scheme"`: `wifi_sd_m` becomes `scheme.wifi_sd_m`); an empty section changes nothing.
    pub fn under(mut self, section: &str) -> Self {
        if !section.is_empty() {
            self.path = if self.path.is_empty() {
                section.to_string()
            } else {
                format!("{section}.{}", self.path)
            };
        }
        self
    }
}

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

//! A fingerprint table: AP columns, a dense row-major RSS matrix and one position label per
//! row (reference points of a radio map, or queries of a benchmark).
//!
//! The table is plain data: files in the benchmark layout are read and written by
//! `wipdr_io::fingerprint_csv`, and users can build one in code:
//!
//! ```
//! use wipdr_core::fingerprint_table::{FingerprintLabel, FingerprintTable};
//! let mut t = FingerprintTable::new(vec!["ap_000".into(), "ap_001".into()]);
//! let label = FingerprintLabel { x: 1.5, y: 2.0, z: 0.0, floor: 0, building: 0 };
//! t.push_row(&[-60.0, FingerprintTable::NOT_HEARD], label).unwrap();
//! assert_eq!(t.n_rows(), 1);
//! assert_eq!(t.rss_at(0, 0), Some(-60.0));
//! assert_eq!(t.rss_at(0, 1), None);
//! ```

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// A row whose length does not match the table's AP columns.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("row has {found} RSS values, table has {expected} APs")]
pub struct RowLengthError {
    /// Number of AP columns of the table.
    pub expected: usize,
    /// Number of RSS values in the row.
    pub found: usize,
}

/// Position and floor/building label of one row.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FingerprintLabel {
    /// East / map-right coordinate, metres.
    pub x: f64,
    /// North / map-up coordinate, metres.
    pub y: f64,
    /// Height, metres.
    pub z: f64,
    /// Floor index.
    pub floor: i32,
    /// Building index.
    pub building: i32,
}

impl FingerprintLabel {
    /// The label of a point at `(x, y)` on `floor`, height 0, building 0.
    pub fn at(x: f64, y: f64, floor: i32) -> Self {
        Self {
            x,
            y,
            z: 0.0,
            floor,
            building: 0,
        }
    }
}

/// AP names, a dense row-major RSS matrix (dBm) and the labels.
///
/// An AP a row did not hear holds [`FingerprintTable::NOT_HEARD`] in [`FingerprintTable::rss`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct FingerprintTable {
    /// The AP column names, in column order.
    pub ap_names: Vec<String>,
    /// RSS in dBm, row-major `n_rows x ap_names.len()`; [`FingerprintTable::NOT_HEARD`] where
    /// not heard.
    pub rss: Vec<f32>,
    /// One label per row.
    pub labels: Vec<FingerprintLabel>,
}

impl FingerprintTable {
    /// The in-memory marker of "AP not heard" in a row. It is the value the public benchmark
    /// files use (`wipdr_io::fingerprint_csv::NOT_DETECTED`), so rows read from those files
    /// pass through unchanged; no valid RSS (`[-120, 0]` dBm) can take it.
    pub const NOT_HEARD: f32 = 100.0;

    /// An empty table with the given AP columns.
    pub fn new(ap_names: Vec<String>) -> Self {
        Self {
            ap_names,
            rss: Vec::new(),
            labels: Vec::new(),
        }
    }

    /// Whether a raw row value means "not heard".
    pub fn is_not_heard(v: f32) -> bool {
        v == Self::NOT_HEARD
    }

    /// Number of rows (reference points or queries).
    pub fn n_rows(&self) -> usize {
        self.labels.len()
    }

    /// Number of AP columns.
    pub fn n_aps(&self) -> usize {
        self.ap_names.len()
    }

    /// The raw RSS row `i` ([`FingerprintTable::NOT_HEARD`] = not heard). Panics if
    /// `i >= n_rows()`.
    pub fn row(&self, i: usize) -> &[f32] {
        let m = self.n_aps();
        &self.rss[i * m..(i + 1) * m]
    }

    /// RSS of AP `ap` in row `i`, `None` when not heard.
    pub fn rss_at(&self, i: usize, ap: usize) -> Option<f32> {
        let v = self.row(i)[ap];
        (!Self::is_not_heard(v)).then_some(v)
    }

    /// Appends a row; `rss` must have `n_aps()` values ([`FingerprintTable::NOT_HEARD`] = not
    /// heard).
    pub fn push_row(&mut self, rss: &[f32], label: FingerprintLabel) -> Result<(), RowLengthError> {
        if rss.len() != self.n_aps() {
            return Err(RowLengthError {
                expected: self.n_aps(),
                found: rss.len(),
            });
        }
        self.rss.extend_from_slice(rss);
        self.labels.push(label);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn push_row_checks_length() {
        let mut t = FingerprintTable::new(vec!["a".into(), "b".into()]);
        let label = FingerprintLabel {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            floor: 0,
            building: 0,
        };
        assert_eq!(
            t.push_row(&[-50.0], label),
            Err(RowLengthError {
                expected: 2,
                found: 1
            })
        );
        t.push_row(&[-50.0, FingerprintTable::NOT_HEARD], label)
            .unwrap();
        assert_eq!(t.n_rows(), 1);
        assert_eq!(t.row(0), &[-50.0, 100.0]);
        assert_eq!(t.rss_at(0, 1), None);
    }
}

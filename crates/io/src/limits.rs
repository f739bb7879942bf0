//! Resource limits that keep the readers bounded on hostile or broken input.
//!
//! ## Limits per input kind (defaults)
//!
//! | input | limit | default | on crossing |
//! | --- | --- | --- | --- |
//! | trace (`.txt`, `.txt.gz`) | [`Limits::max_line_bytes`] | 64 KiB | [`IoError::LineTooLong`] |
//! | trace | [`Limits::max_input_bytes`] (decompressed) | 512 MiB | [`IoError::InputTooLarge`] |
//! | trace | [`Limits::max_records`] | 8 M | [`IoError::TooManyRecords`] |
//! | trace | [`Limits::max_scan_entries`] (one Wi-Fi scan) | 8192 | [`IoError::ScanTooLarge`] |
//! | trace | [`Limits::max_walk_memory_bytes`] (parsed walk, counted per record and Wi-Fi entry) | 512 MiB | [`IoError::LimitExceeded`] |
//! | `floor_info.json`, `geojson_map.json` | [`Limits::max_json_bytes`] | 64 MiB | [`IoError::InputTooLarge`] |
//! | JSON | [`Limits::max_json_values`] (counted on the bytes before parsing) | 8 M | [`IoError::LimitExceeded`] |
//! | GeoJSON | [`Limits::max_geojson_features`] | 100 000 | [`IoError::Invalid`] |
//! | GeoJSON | [`Limits::max_geojson_vertices`] | 2 M | [`IoError::Invalid`] |
//! | fingerprint CSV | [`Limits::max_csv_bytes`] | 256 MiB | [`FingerprintCsvError::LimitExceeded`] |
//! | fingerprint CSV | [`Limits::max_csv_line_bytes`] | 1 MiB | [`FingerprintCsvError::LimitExceeded`] |
//! | fingerprint CSV | [`Limits::max_csv_columns`] | 100 000 | [`FingerprintCsvError::LimitExceeded`] |
//! | fingerprint CSV | [`Limits::max_csv_cells`] (rows x AP columns) | 32 M (128 MiB of RSS) | [`FingerprintCsvError::LimitExceeded`] |
//! | cache file | table [`crate::cache::MAX_TABLE_BYTES`], blobs checked by CRC-32 first | 64 MiB | file removed and rebuilt |
//! | cache folder | [`crate::cache::CacheSettings::max_bytes`] | 2 GiB | least recently used files evicted |
//!
//! Per run, memory is bounded by these per-input limits times the inputs held at once: the
//! walks of the floors being evaluated are all in memory (a floor folder is read whole).
//! Every error names the file, the limit's field name and its value; raise a limit by
//! passing a larger value in [`Limits`] (the `wipdr inspect --limits FILE.toml` option takes
//! these field names).
//!
//! [`IoError::LineTooLong`]: crate::IoError::LineTooLong
//! [`IoError::InputTooLarge`]: crate::IoError::InputTooLarge
//! [`IoError::TooManyRecords`]: crate::IoError::TooManyRecords
//! [`IoError::ScanTooLarge`]: crate::IoError::ScanTooLarge
//! [`IoError::LimitExceeded`]: crate::IoError::LimitExceeded
//! [`IoError::Invalid`]: crate::IoError::Invalid
//! [`FingerprintCsvError::LimitExceeded`]: crate::fingerprint_csv::FingerprintCsvError::LimitExceeded

use serde::{Deserialize, Serialize};

/// Upper bounds the readers enforce; crossing one gives a typed [`crate::IoError`] instead
/// of unbounded memory or time. The defaults are far above anything in the ILC 2.0 data
/// (longest line 134 bytes, largest scan 735 entries, largest decompressed walk a few MB,
/// largest GeoJSON 240 kB, largest fingerprint CSV 41 MB with 7 kB lines) and low enough that
/// one walk stays within about [`Limits::max_walk_memory_bytes`] of parsed data.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Limits {
    /// Longest accepted trace line, bytes (default 64 KiB).
    pub max_line_bytes: usize,
    /// Most (decompressed) bytes read from one trace (default 512 MiB).
    pub max_input_bytes: u64,
    /// Most records (lines) in one trace (default 8 million).
    pub max_records: usize,
    /// Most entries in one Wi-Fi scan (default 8192).
    pub max_scan_entries: usize,
    /// Largest JSON file (`floor_info.json`, `geojson_map.json`), bytes (default 64 MiB).
    pub max_json_bytes: u64,
    /// Most features in a GeoJSON floor plan (default 100 000).
    pub max_geojson_features: usize,
    /// Most vertices over all GeoJSON polygons (default 2 million).
    pub max_geojson_vertices: usize,
    /// Most memory one parsed walk may take, bytes (default 512 MiB): every kept record is
    /// counted with its in-memory size (a Wi-Fi entry with its SSID, a new scan with its own
    /// overhead), so a walk of millions of one-entry scans stops here.
    pub max_walk_memory_bytes: u64,
    /// Most JSON values (numbers, strings, arrays, objects, ...) in one JSON file, counted on
    /// the bytes before parsing (default 8 million, about 400 MB parsed).
    pub max_json_values: u64,
    /// Largest fingerprint CSV file, bytes (default 256 MiB).
    pub max_csv_bytes: u64,
    /// Longest fingerprint CSV line, bytes (default 1 MiB).
    pub max_csv_line_bytes: usize,
    /// Most columns in a fingerprint CSV (default 100 000).
    pub max_csv_columns: usize,
    /// Most RSS cells (rows x AP columns) in a fingerprint CSV (default 32 million).
    pub max_csv_cells: u64,
    /// How many line numbers the parse report keeps per skip kind (default 5).
    pub report_first_lines: usize,
    /// How many distinct unknown record type names the report keeps (default 64); more are
    /// counted under `<other>`.
    pub report_max_unknown_types: usize,
}

impl Limits {
    /// The hard ceiling of each limit a user can raise (`wipdr inspect --limits FILE.toml`),
    /// with the memory it implies: a limit is a promise that the reader stays within it, so
    /// one raised past what a 24 GiB machine can hold is refused rather than tried.
    pub const CEILINGS: [(&'static str, u64, &'static str); 15] = [
        ("max_line_bytes", 64 << 20, "a line is held whole: 64 MiB"),
        (
            "max_input_bytes",
            64 << 30,
            "streamed; the walk's memory is bounded separately",
        ),
        (
            "max_records",
            1_000_000_000,
            "each kept record is counted in max_walk_memory_bytes",
        ),
        (
            "max_scan_entries",
            1_000_000,
            "a scan is held whole: about 100 MB",
        ),
        (
            "max_json_bytes",
            4 << 30,
            "a JSON file is held whole, parsed: about 8x",
        ),
        (
            "max_geojson_features",
            10_000_000,
            "about 1 KiB each parsed",
        ),
        ("max_geojson_vertices", 100_000_000, "16 bytes each, 1.6 GB"),
        ("max_walk_memory_bytes", 16 << 30, "the parsed walk itself"),
        (
            "max_json_values",
            1_000_000_000,
            "about 50 bytes each parsed",
        ),
        (
            "max_csv_bytes",
            16 << 30,
            "streamed; the table is bounded by max_csv_cells",
        ),
        ("max_csv_line_bytes", 256 << 20, "a line is held whole"),
        ("max_csv_columns", 1_000_000, "a header of names"),
        ("max_csv_cells", 2_000_000_000, "4 bytes each, 8 GB"),
        (
            "report_first_lines",
            10_000,
            "line numbers kept per skip kind",
        ),
        (
            "report_max_unknown_types",
            100_000,
            "names kept in the report",
        ),
    ];

    /// Checks every limit against its ceiling ([`Limits::CEILINGS`]); the error names the
    /// field, the value and the ceiling with the memory it stands for.
    pub fn validate(&self) -> Result<(), wipdr_core::ConfigError> {
        let values: [u64; 15] = [
            self.max_line_bytes as u64,
            self.max_input_bytes,
            self.max_records as u64,
            self.max_scan_entries as u64,
            self.max_json_bytes,
            self.max_geojson_features as u64,
            self.max_geojson_vertices as u64,
            self.max_walk_memory_bytes,
            self.max_json_values,
            self.max_csv_bytes,
            self.max_csv_line_bytes as u64,
            self.max_csv_columns as u64,
            self.max_csv_cells,
            self.report_first_lines as u64,
            self.report_max_unknown_types as u64,
        ];
        for ((field, ceiling, why), value) in Self::CEILINGS.iter().zip(values) {
            if value > *ceiling {
                return Err(wipdr_core::ConfigError::new(
                    (*field).to_string(),
                    format!("{value} is above the ceiling {ceiling} ({why})"),
                ));
            }
        }
        Ok(())
    }
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            max_line_bytes: 64 * 1024,
            max_input_bytes: 512 * 1024 * 1024,
            max_records: 8_000_000,
            max_scan_entries: 8192,
            max_json_bytes: 64 * 1024 * 1024,
            max_geojson_features: 100_000,
            max_geojson_vertices: 2_000_000,
            max_walk_memory_bytes: 512 * 1024 * 1024,
            max_json_values: 8_000_000,
            max_csv_bytes: 256 * 1024 * 1024,
            max_csv_line_bytes: 1024 * 1024,
            max_csv_columns: 100_000,
            max_csv_cells: 32_000_000,
            report_first_lines: 5,
            report_max_unknown_types: 64,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_defaults_are_within_the_ceilings_and_a_raised_limit_is_checked() {
        assert_eq!(Limits::default().validate(), Ok(()));
        let raised = Limits {
            max_scan_entries: 10_000_000,
            ..Limits::default()
        };
        let wipdr_core::ConfigError {
            path: field,
            reason: message,
        } = raised.validate().unwrap_err();
        assert_eq!(field, "max_scan_entries");
        assert!(message.contains("above the ceiling 1000000"), "{message}");
        let cells = Limits {
            max_csv_cells: u64::MAX,
            ..Limits::default()
        };
        assert_eq!(cells.validate().unwrap_err().path, "max_csv_cells");
    }
}

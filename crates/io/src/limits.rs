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

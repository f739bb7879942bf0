//! Resource limits that keep the readers bounded on hostile or broken input.

use serde::{Deserialize, Serialize};

/// Upper bounds the readers enforce; crossing one gives a typed [`crate::IoError`] instead
/// of unbounded memory or time. The defaults are far above anything in the ILC 2.0 data
/// (longest line 134 bytes, largest scan 735 entries, largest decompressed walk a few MB,
/// largest GeoJSON 240 kB) and low enough that one walk stays within a few hundred MB.
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
            report_first_lines: 5,
            report_max_unknown_types: 64,
        }
    }
}

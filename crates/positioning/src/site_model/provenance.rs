//! Where a site model came from: the program that fit it, its input files (named by the
//! tool that read them), what the training data held.

use super::fit::TrainingData;
use serde::{Deserialize, Serialize};
use wipdr_fingerprint::RadioMap;

/// An input file of a fit, as the tool that read it names it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct SourceFile {
    /// Path as given (relative to where the fit ran).
    pub path: String,
    /// Size in bytes.
    pub bytes: u64,
    /// SHA-256 of the file's bytes, lowercase hex.
    pub sha256: String,
}

/// Where a site model came from.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, Default)]
pub struct Provenance {
    /// The `wipdr-positioning` version that fit it.
    pub wipdr_version: String,
    /// When it was fit, Unix seconds (set by the caller: the library reads no clock).
    pub created_unix_s: Option<i64>,
    /// The input files (set by the caller that read them; empty for data built in code).
    pub sources: Vec<SourceFile>,
    /// SHA-256 over the sources' digests in order, lowercase hex (set with `sources`).
    pub sources_sha256: Option<String>,
    /// Training walks.
    pub training_walks: usize,
    /// Their waypoints.
    pub waypoints: usize,
    /// Their Wi-Fi scans.
    pub scans: usize,
    /// Survey fingerprints (rows of a survey table).
    pub survey_rows: usize,
    /// Reference points of the radio map.
    pub reference_points: usize,
    /// APs of the radio map.
    pub aps: usize,
}

impl Provenance {
    /// The counts of a fit of `data` that made `map`.
    pub fn of(data: &TrainingData<'_>, map: &RadioMap) -> Self {
        Self {
            wipdr_version: env!("CARGO_PKG_VERSION").to_string(),
            created_unix_s: None,
            sources: Vec::new(),
            sources_sha256: None,
            training_walks: data.walks.len(),
            waypoints: data.walks.iter().map(|w| w.waypoints.len()).sum(),
            scans: data.walks.iter().map(|w| w.wifi.len()).sum(),
            survey_rows: data.survey.map_or(0, |t| t.n_rows()),
            reference_points: map.len(),
            aps: map.n_aps(),
        }
    }
}

//! The error type of every reader and writer in this crate.
//!
//! Following the Rust convention, a variant's message does not repeat its cause: print the
//! whole chain (`{:#}` with anyhow, or walk `Error::source`).

use std::path::PathBuf;
use thiserror::Error;

/// Errors of the readers, writers and the cache. Each names the file and, where it makes
/// sense, the line (1-based) or the JSON field that failed.
#[derive(Debug, Error)]
pub enum IoError {
    /// An operating-system or decompression error while reading or writing a file.
    #[error("{path}: read failed after line {line}", path = path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The last line read completely before the error (0 before the first line).
        line: usize,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A file or directory could not be opened, listed or written.
    #[error("{path}: cannot open, list or write", path = path.display())]
    File {
        /// The file or directory.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A line longer than [`crate::Limits::max_line_bytes`].
    #[error("{path}: line {line}: longer than the limit of {limit} bytes", path = path.display())]
    LineTooLong {
        /// The file.
        path: PathBuf,
        /// The line (1-based).
        line: usize,
        /// The limit in bytes.
        limit: usize,
    },
    /// More (decompressed) input than [`crate::Limits::max_input_bytes`] or
    /// [`crate::Limits::max_json_bytes`].
    #[error("{path}: more than the limit of {limit} bytes of (decompressed) input", path = path.display())]
    InputTooLarge {
        /// The file.
        path: PathBuf,
        /// The limit in bytes.
        limit: u64,
    },
    /// More records than [`crate::Limits::max_records`].
    #[error("{path}: line {line}: more than the limit of {limit} records", path = path.display())]
    TooManyRecords {
        /// The file.
        path: PathBuf,
        /// The line at which the limit was crossed.
        line: usize,
        /// The limit.
        limit: usize,
    },
    /// A Wi-Fi scan (lines sharing one time) with more entries than
    /// [`crate::Limits::max_scan_entries`].
    #[error("{path}: line {line}: field TYPE_WIFI: scan at t={t} has more than the limit of {limit} entries", path = path.display())]
    ScanTooLarge {
        /// The file.
        path: PathBuf,
        /// The line at which the limit was crossed.
        line: usize,
        /// The scan time (Unix ms).
        t: i64,
        /// The limit.
        limit: usize,
    },
    /// Input beyond one of the other [`crate::Limits`] (named by its field).
    #[error("{path}: {what}: more than the limit Limits::{limit} = {max}; raise it (e.g. `wipdr inspect --limits FILE.toml`) if the input is genuine", path = path.display())]
    LimitExceeded {
        /// The file.
        path: PathBuf,
        /// Where in the file (e.g. `line 12`), or what was counted.
        what: String,
        /// The [`crate::Limits`] field.
        limit: &'static str,
        /// Its value.
        max: u64,
    },
    /// A JSON file that is not valid JSON.
    #[error("{path}: invalid JSON", path = path.display())]
    JsonSyntax {
        /// The file.
        path: PathBuf,
        /// The parser's error (with line and column).
        #[source]
        source: serde_json::Error,
    },
    /// A JSON or GeoJSON file whose content is wrong: a missing or invalid field, too many
    /// features or vertices, a degenerate bounding box.
    #[error("{path}: field {field}: {message}", path = path.display())]
    Invalid {
        /// The file.
        path: PathBuf,
        /// The field, as a JSON path (e.g. `features[0].geometry.coordinates`).
        field: String,
        /// What is wrong.
        message: String,
    },
    /// A line of a plain sample stream ([`crate::sample_stream`]) that is not a sample.
    #[error("{path}: line {line}: field {field}: {message}", path = path.display())]
    BadSample {
        /// The file.
        path: PathBuf,
        /// The line (1-based).
        line: usize,
        /// The field (`t_ms`, `sensor`, `x`, `bssid`, ...).
        field: String,
        /// What is wrong.
        message: String,
    },
    /// A folder that does not look like an ILC floor folder.
    #[error("{path}: not a floor folder: {message}", path = path.display())]
    NotAFloor {
        /// The folder.
        path: PathBuf,
        /// What is missing.
        message: String,
    },
    /// A floor folder with walk files none of which could be read (each unreadable walk is
    /// otherwise skipped, see [`crate::floor::SkippedWalk`]). The source is the first
    /// walk's error in file-name order.
    #[error("{path}: none of the {files} walk files could be read", path = path.display())]
    NoReadableWalk {
        /// The floor folder.
        path: PathBuf,
        /// How many walk files the folder has.
        files: usize,
        /// The error of the first walk file (by name).
        #[source]
        first: Box<IoError>,
    },
    /// Two walk files of one walk id in a floor folder (`w.txt` and `w.txt.gz`): the later
    /// one (by name) is not read.
    #[error("{second}: walk id {id:?} is already read from {first}; file skipped", second = second.display(), first = first.display())]
    DuplicateWalk {
        /// The walk id.
        id: String,
        /// The file that was read.
        first: PathBuf,
        /// The file with the same id, skipped.
        second: PathBuf,
    },
    /// A value the writer refuses to write (e.g. a non-finite number).
    #[error("cannot write field {field}: {message}")]
    Unwritable {
        /// The field.
        field: String,
        /// Why.
        message: String,
    },
}

impl IoError {
    /// This error and all its sources, joined by `": "` (e.g. `w.txt.gz: read failed after
    /// line 0: invalid gzip header`): the whole story in one line, for logs and reports.
    pub fn full_message(&self) -> String {
        let mut message = self.to_string();
        let mut source = std::error::Error::source(self);
        while let Some(cause) = source {
            message.push_str(": ");
            message.push_str(&cause.to_string());
            source = cause.source();
        }
        message
    }

    pub(crate) fn file(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::File {
            path: path.into(),
            source,
        }
    }

    pub(crate) fn invalid(
        path: impl Into<PathBuf>,
        field: impl Into<String>,
        message: impl Into<String>,
    ) -> Self {
        Self::Invalid {
            path: path.into(),
            field: field.into(),
            message: message.into(),
        }
    }
}

//! Fingerprint benchmark CSV files: reader and writer.
//!
//! The nine public benchmarks in `fingerprint/` under the data root ([`crate::data_root()`];
//! DSI, LIB, TUT, UJI) share one layout: a header `ap_000,ap_001,…,ap_NNN,x,y,z,floor,building`,
//! then one reference point or query per line. RSS values are in dBm; the value `100` means "not detected"
//! ([`NOT_DETECTED`]). `x, y, z` are metres, `floor` and `building` integers.
//!
//! The reader is strict: a ragged row, a number that does not parse, a non-finite value, an
//! RSS outside `[-120, 0]` dBm (other than `100`) or a label coordinate beyond
//! [`MAX_ABS_LABEL_COORDINATE_M`] is a typed [`FingerprintCsvError`] naming the
//! file, the 1-based line and column and the header field. The writer produces the same layout
//! (the simulator writes its survey maps with it).
//!
//! ```
//! use wipdr_io::fingerprint_csv::{read_fingerprint_csv_from, write_fingerprint_csv_to};
//! let text = "ap_000,ap_001,x,y,z,floor,building\n-60,100,1.5,2.0,0,0,0\n";
//! let table = read_fingerprint_csv_from(text.as_bytes(), "inline").unwrap();
//! assert_eq!(table.n_rows(), 1);
//! assert_eq!(table.rss_at(0, 0), Some(-60.0));
//! assert_eq!(table.rss_at(0, 1), None); // 100 = not detected
//! let mut out = Vec::new();
//! write_fingerprint_csv_to(&mut out, &table).unwrap();
//! assert_eq!(read_fingerprint_csv_from(&out[..], "again").unwrap(), table);
//! ```

use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};
use thiserror::Error;
pub use wipdr_core::fingerprint_table::{FingerprintLabel, FingerprintTable, RowLengthError};

use crate::Limits;

/// The RSS value that means "access point not detected" in the benchmark files. The reader
/// keeps it as is: it is also the in-memory marker [`FingerprintTable::NOT_HEARD`].
pub const NOT_DETECTED: f32 = FingerprintTable::NOT_HEARD;
/// Weakest RSS accepted by the reader, dBm.
pub const MIN_VALID_RSS_DBM: f32 = -120.0;
/// Strongest RSS accepted by the reader, dBm.
pub const MAX_VALID_RSS_DBM: f32 = 0.0;

/// Largest accepted absolute label coordinate (`x`, `y`, `z`), metres: projected
/// coordinates (UTM northings, web-Mercator metres as in UJIIndoorLoc, up to 2e7) pass;
/// absurd values such as `1e308`, whose errors would overflow to infinity in one score and
/// not the other, are [`FingerprintCsvError::OutOfRange`].
pub const MAX_ABS_LABEL_COORDINATE_M: f64 = 1e8;

/// The trailing label columns, in file order.
pub const LABEL_COLUMNS: [&str; 5] = ["x", "y", "z", "floor", "building"];

/// Errors of the fingerprint CSV reader and writer. Lines and columns are 1-based.
#[derive(Debug, Error)]
pub enum FingerprintCsvError {
    /// The file could not be opened, read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The file has no header line.
    #[error("{path}: empty file (no header)")]
    Empty {
        /// The file.
        path: PathBuf,
    },
    /// The header is not `ap_…,x,y,z,floor,building`.
    #[error("{path}: line 1: bad header: {message}")]
    Header {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A row with a different number of fields than the header.
    #[error("{path}: line {line}: ragged row with {found} fields, header has {expected}")]
    Ragged {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// Number of header fields.
        expected: usize,
        /// Number of fields found.
        found: usize,
    },
    /// A field that does not parse as a number (or an integer for floor/building).
    #[error("{path}: line {line}, column {column} ({field}): cannot parse {value:?}")]
    BadNumber {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// 1-based column number.
        column: usize,
        /// The header name of the column.
        field: String,
        /// The offending text (at most 64 characters).
        value: String,
    },
    /// A non-finite value, an RSS outside `[-120, 0]` dBm that is not the not-detected
    /// marker, or a label coordinate beyond [`MAX_ABS_LABEL_COORDINATE_M`].
    #[error(
        "{path}: line {line}, column {column} ({field}): value {} out of range",
        short_number(*value)
    )]
    OutOfRange {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// 1-based column number.
        column: usize,
        /// The header name of the column.
        field: String,
        /// The offending value.
        value: f64,
    },
    /// Input beyond one of the CSV [`crate::Limits`] (named by its field).
    #[error(
        "{path}: line {line}: {what}: more than the limit Limits::{limit} = {max}; raise it if the file is genuine"
    )]
    LimitExceeded {
        /// The file.
        path: PathBuf,
        /// 1-based line number where the limit was crossed.
        line: usize,
        /// What was counted.
        what: String,
        /// The [`crate::Limits`] field.
        limit: &'static str,
        /// Its value.
        max: u64,
    },
    /// A table whose parts disagree in size (writer side).
    #[error("inconsistent table: {0}")]
    Inconsistent(String),
}

/// A number for a message: huge or tiny magnitudes in exponent form (`1e308`, not 309 digits).
fn short_number(v: f64) -> String {
    if v != 0.0 && v.is_finite() && !(1e-6..1e9).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        v.to_string()
    }
}

impl From<RowLengthError> for FingerprintCsvError {
    fn from(e: RowLengthError) -> Self {
        Self::Inconsistent(e.to_string())
    }
}

/// Reads a benchmark CSV file with the default [`Limits`].
pub fn read_fingerprint_csv(
    path: impl AsRef<Path>,
) -> Result<FingerprintTable, FingerprintCsvError> {
    read_fingerprint_csv_with(path, &Limits::default())
}

/// Reads a benchmark CSV file within `limits` ([`Limits::max_csv_bytes`],
/// [`Limits::max_csv_line_bytes`], [`Limits::max_csv_columns`], [`Limits::max_csv_cells`]),
/// streaming line by line: memory stays within a line plus the table.
pub fn read_fingerprint_csv_with(
    path: impl AsRef<Path>,
    limits: &Limits,
) -> Result<FingerprintTable, FingerprintCsvError> {
    let path = path.as_ref();
    let file = std::fs::File::open(path).map_err(|source| FingerprintCsvError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    read_impl(BufReader::with_capacity(1 << 20, file), path, limits)
}

/// Reads a benchmark CSV from any reader; `name` stands for the file in error messages.
pub fn read_fingerprint_csv_from<R: BufRead>(
    reader: R,
    name: &str,
) -> Result<FingerprintTable, FingerprintCsvError> {
    read_impl(reader, Path::new(name), &Limits::default())
}

/// [`read_fingerprint_csv_from`] within `limits`.
pub fn read_fingerprint_csv_from_with<R: BufRead>(
    reader: R,
    name: &str,
    limits: &Limits,
) -> Result<FingerprintTable, FingerprintCsvError> {
    read_impl(reader, Path::new(name), limits)
}

/// Reads one line (with its `\n`, if any) into `line`, refusing to buffer more than `max`
/// bytes; counts the bytes consumed. `Ok(false)` at the end of the input.
fn read_line_limited<R: BufRead>(
    reader: &mut R,
    line: &mut String,
    max: usize,
    consumed: &mut u64,
) -> std::io::Result<Result<bool, ()>> {
    let mut bytes = std::mem::take(line).into_bytes();
    bytes.clear();
    loop {
        let available = match reader.fill_buf() {
            Ok(b) => b,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        if available.is_empty() {
            break;
        }
        let (take, done) = match available.iter().position(|&b| b == b'\n') {
            Some(i) => (i + 1, true),
            None => (available.len(), false),
        };
        if bytes.len() + take > max.saturating_add(1) {
            reader.consume(take);
            return Ok(Err(()));
        }
        bytes.extend_from_slice(&available[..take]);
        reader.consume(take);
        *consumed += take as u64;
        if done {
            break;
        }
    }
    let any = !bytes.is_empty();
    *line = String::from_utf8(bytes)
        .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidData, e.utf8_error()))?;
    Ok(Ok(any))
}

/// Reads `DIR/train.csv` (the radio map) and `DIR/test.csv` (the queries) of one benchmark.
pub fn read_dataset(
    dir: impl AsRef<Path>,
) -> Result<(FingerprintTable, FingerprintTable), FingerprintCsvError> {
    let dir = dir.as_ref();
    let train = read_fingerprint_csv(dir.join("train.csv"))?;
    let test = read_fingerprint_csv(dir.join("test.csv"))?;
    if train.ap_names != test.ap_names {
        return Err(FingerprintCsvError::Header {
            path: dir.join("test.csv"),
            message: "AP columns differ from train.csv".into(),
        });
    }
    Ok((train, test))
}

fn read_impl<R: BufRead>(
    mut reader: R,
    path: &Path,
    limits: &Limits,
) -> Result<FingerprintTable, FingerprintCsvError> {
    let io_err = |source| FingerprintCsvError::Io {
        path: path.to_path_buf(),
        source,
    };
    let over = |line: usize, what: String, limit: &'static str, max: u64| {
        FingerprintCsvError::LimitExceeded {
            path: path.to_path_buf(),
            line,
            what,
            limit,
            max,
        }
    };
    let mut consumed = 0u64;
    let mut next_line = |line: &mut String, lineno: usize| -> Result<bool, FingerprintCsvError> {
        let got = read_line_limited(&mut reader, line, limits.max_csv_line_bytes, &mut consumed)
            .map_err(io_err)?
            .map_err(|()| {
                over(
                    lineno,
                    "line length".into(),
                    "max_csv_line_bytes",
                    limits.max_csv_line_bytes as u64,
                )
            })?;
        if consumed > limits.max_csv_bytes {
            return Err(over(
                lineno,
                "file size".into(),
                "max_csv_bytes",
                limits.max_csv_bytes,
            ));
        }
        Ok(got)
    };
    let mut line = String::new();
    if !next_line(&mut line, 1)? {
        return Err(FingerprintCsvError::Empty {
            path: path.to_path_buf(),
        });
    }
    let columns = line.bytes().filter(|&b| b == b',').count() + 1;
    if columns > limits.max_csv_columns {
        return Err(over(
            1,
            format!("{columns} header columns"),
            "max_csv_columns",
            limits.max_csv_columns as u64,
        ));
    }
    let header: Vec<String> = line
        .trim_end_matches(['\n', '\r'])
        .trim_start_matches('\u{feff}')
        .split(',')
        .map(|s| s.trim().to_string())
        .collect();
    let header_err = |message: String| FingerprintCsvError::Header {
        path: path.to_path_buf(),
        message,
    };
    if header.len() < LABEL_COLUMNS.len() {
        return Err(header_err(format!(
            "{} columns, need at least the 5 label columns",
            header.len()
        )));
    }
    let n_aps = header.len() - LABEL_COLUMNS.len();
    for (k, want) in LABEL_COLUMNS.iter().enumerate() {
        let got = &header[n_aps + k];
        if !got.eq_ignore_ascii_case(want) {
            return Err(header_err(format!(
                "column {} is {got:?}, expected {want:?}",
                n_aps + k + 1
            )));
        }
    }
    if let Some(bad) = header[..n_aps].iter().find(|h| h.is_empty()) {
        return Err(header_err(format!("empty AP column name {bad:?}")));
    }
    let mut table = FingerprintTable::new(header[..n_aps].to_vec());
    let mut lineno = 1usize;
    let mut row = vec![0f32; n_aps];
    loop {
        if !next_line(&mut line, lineno + 1)? {
            break;
        }
        lineno += 1;
        let text = line.trim_end_matches(['\n', '\r']);
        if text.trim().is_empty() {
            continue;
        }
        let found = text.split(',').count();
        if found != header.len() {
            return Err(FingerprintCsvError::Ragged {
                path: path.to_path_buf(),
                line: lineno,
                expected: header.len(),
                found,
            });
        }
        let mut label = [0f64; 5];
        for (col, field) in text.split(',').enumerate() {
            let field = field.trim();
            let bad = || FingerprintCsvError::BadNumber {
                path: path.to_path_buf(),
                line: lineno,
                column: col + 1,
                field: header[col].clone(),
                value: field.chars().take(64).collect(),
            };
            let v: f64 = field.parse().map_err(|_| bad())?;
            let out_of_range = || FingerprintCsvError::OutOfRange {
                path: path.to_path_buf(),
                line: lineno,
                column: col + 1,
                field: header[col].clone(),
                value: v,
            };
            if !v.is_finite() {
                return Err(out_of_range());
            }
            if col < n_aps {
                let r = v as f32;
                if r != NOT_DETECTED && !(MIN_VALID_RSS_DBM..=MAX_VALID_RSS_DBM).contains(&r) {
                    return Err(out_of_range());
                }
                row[col] = r;
            } else {
                let k = col - n_aps;
                if k >= 3 && (v.fract() != 0.0 || v.abs() > f64::from(i32::MAX)) {
                    return Err(bad());
                }
                if k < 3 && v.abs() > MAX_ABS_LABEL_COORDINATE_M {
                    return Err(out_of_range());
                }
                label[k] = v;
            }
        }
        if (table.rss.len() + n_aps) as u64 > limits.max_csv_cells {
            return Err(over(
                lineno,
                format!("{} rows of {n_aps} APs", table.n_rows() + 1),
                "max_csv_cells",
                limits.max_csv_cells,
            ));
        }
        table.rss.extend_from_slice(&row);
        table.labels.push(FingerprintLabel {
            x: label[0],
            y: label[1],
            z: label[2],
            floor: label[3] as i32,
            building: label[4] as i32,
        });
    }
    Ok(table)
}

/// Writes a table as a benchmark CSV file.
pub fn write_fingerprint_csv(
    path: impl AsRef<Path>,
    table: &FingerprintTable,
) -> Result<(), FingerprintCsvError> {
    let path = path.as_ref();
    let io_err = |source| FingerprintCsvError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::create(path).map_err(io_err)?;
    let mut w = BufWriter::new(file);
    write_fingerprint_csv_to(&mut w, table)?;
    w.flush().map_err(io_err)
}

/// Writes a table in the benchmark layout to any writer. RSS values are written with up to
/// two decimals (integers without), positions with four.
pub fn write_fingerprint_csv_to<W: Write>(
    mut w: W,
    table: &FingerprintTable,
) -> Result<(), FingerprintCsvError> {
    let m = table.n_aps();
    if table.rss.len() != m * table.n_rows() {
        return Err(FingerprintCsvError::Inconsistent(format!(
            "{} RSS values for {} rows x {m} APs",
            table.rss.len(),
            table.n_rows()
        )));
    }
    let io_err = |source| FingerprintCsvError::Io {
        path: PathBuf::from("<writer>"),
        source,
    };
    let mut header: Vec<&str> = table.ap_names.iter().map(String::as_str).collect();
    header.extend(LABEL_COLUMNS);
    writeln!(w, "{}", header.join(",")).map_err(io_err)?;
    let mut buf = String::new();
    for (i, label) in table.labels.iter().enumerate() {
        buf.clear();
        for &v in table.row(i) {
            if !v.is_finite() {
                return Err(FingerprintCsvError::Inconsistent(format!(
                    "row {i}: non-finite RSS"
                )));
            }
            if v.fract() == 0.0 {
                buf.push_str(&format!("{},", v as i64));
            } else {
                buf.push_str(&format!("{:.2},", v));
            }
        }
        if !(label.x.is_finite() && label.y.is_finite() && label.z.is_finite()) {
            return Err(FingerprintCsvError::Inconsistent(format!(
                "row {i}: non-finite position"
            )));
        }
        buf.push_str(&format!(
            "{:.4},{:.4},{:.4},{},{}",
            label.x, label.y, label.z, label.floor, label.building
        ));
        writeln!(w, "{buf}").map_err(io_err)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEADER: &str = "ap_000,ap_001,x,y,z,floor,building\n";

    fn read(text: &str) -> Result<FingerprintTable, FingerprintCsvError> {
        read_fingerprint_csv_from(text.as_bytes(), "t.csv")
    }

    #[test]
    fn reads_rows_and_not_detected() {
        let t = read(&format!(
            "{HEADER}-60,100,1.5,2,3.7,1,0\r\n-70.5,-80,0,0,0,0,2\n"
        ))
        .unwrap();
        assert_eq!(t.n_rows(), 2);
        assert_eq!(t.n_aps(), 2);
        assert_eq!(t.rss_at(0, 1), None);
        assert_eq!(t.rss_at(1, 0), Some(-70.5));
        assert_eq!(t.labels[0].floor, 1);
        assert_eq!(t.labels[1].building, 2);
        assert_eq!(t.labels[0].z, 3.7);
    }

    #[test]
    fn ragged_row_names_line() {
        let e = read(&format!("{HEADER}-60,100,1,2,0,0,0\n-60,1,2,0,0,0\n")).unwrap_err();
        match e {
            FingerprintCsvError::Ragged {
                line,
                expected,
                found,
                ..
            } => assert_eq!((line, expected, found), (3, 7, 6)),
            other => panic!("wrong error {other}"),
        }
    }

    #[test]
    fn bad_number_names_line_column_field() {
        let e = read(&format!("{HEADER}-60,abc,1,2,0,0,0\n")).unwrap_err();
        match &e {
            FingerprintCsvError::BadNumber {
                line,
                column,
                field,
                value,
                ..
            } => {
                assert_eq!((*line, *column), (2, 2));
                assert_eq!(field, "ap_001");
                assert_eq!(value, "abc");
            }
            other => panic!("wrong error {other}"),
        }
        assert!(e.to_string().contains("t.csv"));
        let e = read(&format!("{HEADER}-60,-70,1,2,0,1.5,0\n")).unwrap_err();
        assert!(matches!(
            e,
            FingerprintCsvError::BadNumber { column: 6, .. }
        ));
    }

    #[test]
    fn out_of_range_and_nan_rejected() {
        for bad in ["-130", "5", "NaN", "inf"] {
            let e = read(&format!("{HEADER}-60,{bad},1,2,0,0,0\n")).unwrap_err();
            assert!(
                matches!(
                    e,
                    FingerprintCsvError::OutOfRange {
                        line: 2,
                        column: 2,
                        ..
                    }
                ),
                "{bad}: {e}"
            );
        }
        let e = read(&format!("{HEADER}-60,-60,NaN,2,0,0,0\n")).unwrap_err();
        assert!(matches!(
            e,
            FingerprintCsvError::OutOfRange { column: 3, .. }
        ));
    }

    #[test]
    fn header_errors() {
        assert!(matches!(read(""), Err(FingerprintCsvError::Empty { .. })));
        assert!(matches!(
            read("ap_000,x,y,z,floor\n"),
            Err(FingerprintCsvError::Header { .. })
        ));
        assert!(matches!(
            read("x,y\n"),
            Err(FingerprintCsvError::Header { .. })
        ));
    }

    #[test]
    fn writer_roundtrip_and_checks() {
        let mut t = FingerprintTable::new(vec!["ap_000".into(), "ap_001".into()]);
        let label = FingerprintLabel {
            x: 1.25,
            y: -3.5,
            z: 0.0,
            floor: 2,
            building: 1,
        };
        t.push_row(&[-61.0, NOT_DETECTED], label).unwrap();
        t.push_row(&[-61.25, -99.0], label).unwrap();
        assert!(t.push_row(&[-61.0], label).is_err());
        let mut out = Vec::new();
        write_fingerprint_csv_to(&mut out, &t).unwrap();
        let back = read_fingerprint_csv_from(&out[..], "x").unwrap();
        assert_eq!(back, t);
        let mut bad = t.clone();
        bad.rss[0] = f32::NAN;
        assert!(write_fingerprint_csv_to(Vec::new(), &bad).is_err());
    }

    #[test]
    fn file_roundtrip() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("train.csv");
        let mut t = FingerprintTable::new(vec!["ap_000".into()]);
        t.push_row(
            &[-50.0],
            FingerprintLabel {
                x: 0.0,
                y: 1.0,
                z: 0.0,
                floor: 0,
                building: 0,
            },
        )
        .unwrap();
        write_fingerprint_csv(&p, &t).unwrap();
        assert_eq!(read_fingerprint_csv(&p).unwrap(), t);
        let e = read_fingerprint_csv(dir.path().join("missing.csv")).unwrap_err();
        assert!(matches!(e, FingerprintCsvError::Io { .. }));
    }
}

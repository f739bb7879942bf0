//! The IPIN competition's scoring files: a trial's ground truth (`GT_*.csv`) and a
//! competitor's estimates as the EvAAL API logs them (`*.est`), into
//! [`EvaalTruthPoint`]s and [`EvaalEstimate`]s (scored by `wipdr_eval::evaal_score`).
//!
//! | file | one line | notes |
//! | --- | --- | --- |
//! | ground truth | `time, longitude, latitude, floor, point number` | seconds, degrees, integer floor; no header |
//! | estimates | `pts, c, h, s, longitude, latitude, floor` | seconds, seconds, seconds, seconds, degrees, degrees, real floor |
//!
//! Fields are separated by commas; in an estimates line the three position fields may also
//! be separated by `;` (the API stores the posted position string as given). Spaces around a
//! field are ignored, and so are blank lines.
//!
//! **The first two lines of an estimates file are not estimates**, as the organisers' scorer
//! reads them: in the API server's own output they are the `pts,c,h,s,pos` header and the
//! trial's announced initial position; in the files the organisers published, the initial
//! position and a first placeholder line. They are skipped whatever they hold.
//!
//! The readers are strict: a line with the wrong number of fields, a number that does not
//! parse, a non-finite value or a non-integer floor or point number is an
//! [`EvaalFileError`] naming the file, the 1-based line and the field. A file without any
//! record is an error too. Line length, input size and record count are bounded by
//! [`Limits`] like every reader of the crate.
//!
//! ```
//! use wipdr_io::evaal::{read_evaal_estimates_from, read_evaal_truth_from};
//! let truth = "0062.036,11.111180724249,49.461387505780,00,001\n";
//! let truth = read_evaal_truth_from(truth.as_bytes(), "GT.csv", &Default::default()).unwrap();
//! assert_eq!((truth[0].t_s, truth[0].floor, truth[0].number), (62.036, 0, 1));
//!
//! let est = "pts,c,h,s,pos\n\
//!            0.036,0,0,45,11.1111,49.4613,0\n\
//!            0.536,1694680130.4,0.5,45,11.1112,49.4614,-1\n";
//! let est = read_evaal_estimates_from(est.as_bytes(), "run.est", &Default::default()).unwrap();
//! assert_eq!(est.len(), 1);
//! assert_eq!((est[0].pts_s, est[0].floor), (0.536, -1.0));
//!
//! let bad = "0062.036,11.11,49.46,zero,001\n";
//! let err = read_evaal_truth_from(bad.as_bytes(), "GT.csv", &Default::default()).unwrap_err();
//! assert_eq!(err.to_string(), "GT.csv: line 1: field floor: \"zero\" is not an integer");
//! ```

use crate::trace::for_each_line;
use crate::{IoError, Limits};
use std::fs::File;
use std::io::{self, BufReader};
use std::path::{Path, PathBuf};
use thiserror::Error;
use wipdr_core::{EvaalEstimate, EvaalTruthPoint};

/// The fields of a ground-truth line, in file order.
pub const TRUTH_FIELDS: [&str; 5] = ["time", "longitude", "latitude", "floor", "point number"];

/// The fields of an estimates line, in file order.
pub const ESTIMATE_FIELDS: [&str; 7] = ["pts", "c", "h", "s", "longitude", "latitude", "floor"];

/// Lines at the start of an estimates file that are not estimates (module docs).
pub const ESTIMATE_LINES_SKIPPED: usize = 2;

/// Largest absolute floor number accepted in a ground-truth file.
pub const MAX_ABS_TRUTH_FLOOR: i32 = 1_000;

/// Errors of the ground-truth and estimates readers. Lines are 1-based.
#[derive(Debug, Error)]
pub enum EvaalFileError {
    /// The file could not be opened or read, or crossed one of the [`Limits`] (the
    /// [`IoError`] names the file and, where it applies, the line).
    #[error(transparent)]
    Io(#[from] IoError),
    /// A line with the wrong number of fields.
    #[error("{path}: line {line}: {found} fields, expected {expected} ({layout})", path = path.display())]
    FieldCount {
        /// The file.
        path: PathBuf,
        /// The line.
        line: usize,
        /// Fields found.
        found: usize,
        /// Fields expected.
        expected: usize,
        /// The expected layout, field names joined by commas.
        layout: String,
    },
    /// A field whose value is not what the format holds there.
    #[error("{path}: line {line}: field {field}: {value:?} is not {expected}", path = path.display())]
    BadField {
        /// The file.
        path: PathBuf,
        /// The line.
        line: usize,
        /// The field's name ([`TRUTH_FIELDS`] or [`ESTIMATE_FIELDS`]).
        field: &'static str,
        /// The text found (trimmed).
        value: String,
        /// What was expected (e.g. `a finite number`).
        expected: &'static str,
    },
    /// A file without a single record.
    #[error("{path}: no {what}", path = path.display())]
    Empty {
        /// The file.
        path: PathBuf,
        /// What is missing (`ground-truth points` or `estimates after the first two lines`).
        what: &'static str,
    },
}

/// Reads a ground-truth file (`GT_*.csv`).
///
/// ```no_run
/// let gt = wipdr_io::evaal::read_evaal_truth("GT_IPIN2023_T3_ScoringTrial01.csv", &Default::default())?;
/// println!("{} points", gt.len());
/// # Ok::<(), wipdr_io::evaal::EvaalFileError>(())
/// ```
pub fn read_evaal_truth(
    path: impl AsRef<Path>,
    limits: &Limits,
) -> Result<Vec<EvaalTruthPoint>, EvaalFileError> {
    let path = path.as_ref();
    let file = File::open(path).map_err(|e| IoError::file(path, e))?;
    parse_truth(file, path, limits)
}

/// Reads ground truth from any reader; `name` is the file name in errors.
pub fn read_evaal_truth_from(
    reader: impl io::Read,
    name: &str,
    limits: &Limits,
) -> Result<Vec<EvaalTruthPoint>, EvaalFileError> {
    parse_truth(reader, Path::new(name), limits)
}

/// Reads an estimates file (`*.est`), skipping its first two lines (module docs).
///
/// ```no_run
/// let est = wipdr_io::evaal::read_evaal_estimates("S323ZENODOTS01.est", &Default::default())?;
/// println!("{} estimates", est.len());
/// # Ok::<(), wipdr_io::evaal::EvaalFileError>(())
/// ```
pub fn read_evaal_estimates(
    path: impl AsRef<Path>,
    limits: &Limits,
) -> Result<Vec<EvaalEstimate>, EvaalFileError> {
    let path = path.as_ref();
    let file = File::open(path).map_err(|e| IoError::file(path, e))?;
    parse_estimates(file, path, limits)
}

/// Reads estimates from any reader; `name` is the file name in errors.
pub fn read_evaal_estimates_from(
    reader: impl io::Read,
    name: &str,
    limits: &Limits,
) -> Result<Vec<EvaalEstimate>, EvaalFileError> {
    parse_estimates(reader, Path::new(name), limits)
}

/// One line's fields with the file, line and layout, for typed errors.
struct Line<'a> {
    path: &'a Path,
    line: usize,
    names: &'static [&'static str],
    fields: Vec<&'a str>,
}

impl<'a> Line<'a> {
    fn split(
        path: &'a Path,
        line: usize,
        text: &'a str,
        names: &'static [&'static str],
        separators: &[char],
    ) -> Result<Self, EvaalFileError> {
        let fields: Vec<&str> = text.split(separators).map(str::trim).collect();
        if fields.len() != names.len() {
            return Err(EvaalFileError::FieldCount {
                path: path.to_path_buf(),
                line,
                found: fields.len(),
                expected: names.len(),
                layout: names.join(", "),
            });
        }
        Ok(Self {
            path,
            line,
            names,
            fields,
        })
    }

    fn bad(&self, i: usize, expected: &'static str) -> EvaalFileError {
        EvaalFileError::BadField {
            path: self.path.to_path_buf(),
            line: self.line,
            field: self.names[i],
            value: self.fields[i].to_string(),
            expected,
        }
    }

    fn real(&self, i: usize) -> Result<f64, EvaalFileError> {
        match self.fields[i].parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(self.bad(i, "a finite number")),
        }
    }

    fn floor(&self, i: usize) -> Result<i32, EvaalFileError> {
        match self.fields[i].parse::<i32>() {
            Ok(v) if v.abs() <= MAX_ABS_TRUTH_FLOOR => Ok(v),
            Ok(_) => Err(self.bad(i, "a floor number within +-1000")),
            Err(_) => Err(self.bad(i, "an integer")),
        }
    }

    fn number(&self, i: usize) -> Result<u32, EvaalFileError> {
        self.fields[i]
            .parse::<u32>()
            .map_err(|_| self.bad(i, "a non-negative integer"))
    }
}

fn check_records(n: usize, path: &Path, line: usize, limits: &Limits) -> Result<(), IoError> {
    if n >= limits.max_records {
        return Err(IoError::TooManyRecords {
            path: path.to_path_buf(),
            line,
            limit: limits.max_records,
        });
    }
    Ok(())
}

fn parse_truth(
    reader: impl io::Read,
    path: &Path,
    limits: &Limits,
) -> Result<Vec<EvaalTruthPoint>, EvaalFileError> {
    let mut out = Vec::new();
    let mut failure: Option<EvaalFileError> = None;
    for_each_line(BufReader::new(reader), path, limits, |text, line_no| {
        if failure.is_some() || text.trim().is_empty() {
            return Ok(());
        }
        check_records(out.len(), path, line_no, limits)?;
        match truth_line(path, line_no, text) {
            Ok(p) => out.push(p),
            Err(e) => failure = Some(e),
        }
        Ok(())
    })?;
    if let Some(e) = failure {
        return Err(e);
    }
    if out.is_empty() {
        return Err(EvaalFileError::Empty {
            path: path.to_path_buf(),
            what: "ground-truth points",
        });
    }
    Ok(out)
}

fn truth_line(path: &Path, line: usize, text: &str) -> Result<EvaalTruthPoint, EvaalFileError> {
    let l = Line::split(path, line, text, &TRUTH_FIELDS, &[','])?;
    Ok(EvaalTruthPoint {
        t_s: l.real(0)?,
        lon_deg: l.real(1)?,
        lat_deg: l.real(2)?,
        floor: l.floor(3)?,
        number: l.number(4)?,
    })
}

fn parse_estimates(
    reader: impl io::Read,
    path: &Path,
    limits: &Limits,
) -> Result<Vec<EvaalEstimate>, EvaalFileError> {
    let mut out = Vec::new();
    let mut failure: Option<EvaalFileError> = None;
    for_each_line(BufReader::new(reader), path, limits, |text, line_no| {
        if failure.is_some() || line_no <= ESTIMATE_LINES_SKIPPED || text.trim().is_empty() {
            return Ok(());
        }
        check_records(out.len(), path, line_no, limits)?;
        match estimate_line(path, line_no, text) {
            Ok(e) => out.push(e),
            Err(e) => failure = Some(e),
        }
        Ok(())
    })?;
    if let Some(e) = failure {
        return Err(e);
    }
    if out.is_empty() {
        return Err(EvaalFileError::Empty {
            path: path.to_path_buf(),
            what: "estimates after the first two lines",
        });
    }
    Ok(out)
}

fn estimate_line(path: &Path, line: usize, text: &str) -> Result<EvaalEstimate, EvaalFileError> {
    let l = Line::split(path, line, text, &ESTIMATE_FIELDS, &[',', ';'])?;
    Ok(EvaalEstimate {
        pts_s: l.real(0)?,
        wall_clock_s: l.real(1)?,
        horizon_s: l.real(2)?,
        slack_s: l.real(3)?,
        lon_deg: l.real(4)?,
        lat_deg: l.real(5)?,
        floor: l.real(6)?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn truth(text: &str) -> Result<Vec<EvaalTruthPoint>, EvaalFileError> {
        read_evaal_truth_from(text.as_bytes(), "gt.csv", &Limits::default())
    }

    fn estimates(text: &str) -> Result<Vec<EvaalEstimate>, EvaalFileError> {
        read_evaal_estimates_from(text.as_bytes(), "x.est", &Limits::default())
    }

    const HEAD: &str = "0.036,0,0,45,11.1,49.4,0\n0.536,1.0,0.5,45,5.5,24.7,-1\n";

    #[test]
    fn truth_lines_read_as_written() {
        let gt = truth("0062.036, 11.5,49.25 ,-2,007\r\n\n0081.0,11.6,49.3,00,8\n").unwrap();
        assert_eq!(
            gt,
            vec![
                EvaalTruthPoint {
                    t_s: 62.036,
                    lon_deg: 11.5,
                    lat_deg: 49.25,
                    floor: -2,
                    number: 7
                },
                EvaalTruthPoint {
                    t_s: 81.0,
                    lon_deg: 11.6,
                    lat_deg: 49.3,
                    floor: 0,
                    number: 8
                },
            ]
        );
    }

    #[test]
    fn the_first_two_estimate_lines_are_skipped_and_the_position_may_use_semicolons() {
        let est = estimates(&format!(
            "{HEAD}1.036,2.0,0.5,45,11.2;49.5;-2\n\n1.536, 3.0 ,0.5,45,11.3,49.6,-0.000\n"
        ))
        .unwrap();
        assert_eq!(est.len(), 2);
        assert_eq!(
            est[0],
            EvaalEstimate {
                pts_s: 1.036,
                wall_clock_s: 2.0,
                horizon_s: 0.5,
                slack_s: 45.0,
                lon_deg: 11.2,
                lat_deg: 49.5,
                floor: -2.0
            }
        );
        assert_eq!(est[1].floor, 0.0);
        // Whatever the first two lines hold, they are not read.
        assert_eq!(estimates("garbage\n;;;\n1,2,3,4,5,6,7\n").unwrap().len(), 1);
    }

    fn line_and_field(e: &EvaalFileError) -> (usize, Option<&'static str>) {
        match e {
            EvaalFileError::FieldCount { line, .. } => (*line, None),
            EvaalFileError::BadField { line, field, .. } => (*line, Some(*field)),
            other => panic!("unexpected error {other}"),
        }
    }

    #[test]
    fn malformed_truth_lines_are_typed_errors_naming_line_and_field() {
        let ok = "1.0,11.1,49.4,0,1\n";
        let cases = [
            ("1.0,11.1,49.4,0\n", None),
            ("1.0,11.1,49.4,0,1,9\n", None),
            ("x,11.1,49.4,0,1\n", Some("time")),
            ("1.0,,49.4,0,1\n", Some("longitude")),
            ("1.0,11.1,NaN,0,1\n", Some("latitude")),
            ("1.0,11.1,inf,0,1\n", Some("latitude")),
            ("1.0,11.1,49.4,0.5,1\n", Some("floor")),
            ("1.0,11.1,49.4,99999,1\n", Some("floor")),
            ("1.0,11.1,49.4,0,-1\n", Some("point number")),
        ];
        for (bad, field) in cases {
            let e = truth(&format!("{ok}{ok}{bad}")).unwrap_err();
            assert_eq!(line_and_field(&e), (3, field), "{bad}: {e}");
            assert!(e.to_string().starts_with("gt.csv: line 3: "), "{e}");
        }
        assert!(matches!(truth("\n\n"), Err(EvaalFileError::Empty { .. })));
    }

    #[test]
    fn malformed_estimate_lines_are_typed_errors_naming_line_and_field() {
        let ok = "1,2,3,4,5,6,7\n";
        let cases = [
            ("1,2,3,4,5,6\n", None),
            ("1,2,3,4,5,6,7,8\n", None),
            ("1,2,3,4,5,6,7;8\n", None),
            ("a,2,3,4,5,6,7\n", Some("pts")),
            ("1,2,3,4,5,6,floor\n", Some("floor")),
            ("1,2,3,4,5,NaN,7\n", Some("latitude")),
            ("1,2,3,4,1e999,6,7\n", Some("longitude")),
        ];
        for (bad, field) in cases {
            let e = estimates(&format!("{HEAD}{ok}{bad}")).unwrap_err();
            assert_eq!(line_and_field(&e), (4, field), "{bad}: {e}");
            assert!(e.to_string().starts_with("x.est: line 4: "), "{e}");
        }
        assert!(matches!(estimates(HEAD), Err(EvaalFileError::Empty { .. })));
        assert!(matches!(estimates(""), Err(EvaalFileError::Empty { .. })));
    }

    #[test]
    fn limits_and_missing_files_are_typed_errors() {
        let limits = Limits {
            max_line_bytes: 16,
            ..Limits::default()
        };
        let long = format!("1.0,11.1,49.4,0,1{}\n", " ".repeat(40));
        let e = read_evaal_truth_from(long.as_bytes(), "gt.csv", &limits).unwrap_err();
        assert!(
            matches!(e, EvaalFileError::Io(IoError::LineTooLong { line: 1, .. })),
            "{e}"
        );
        let limits = Limits {
            max_records: 1,
            ..Limits::default()
        };
        let two = "1.0,11.1,49.4,0,1\n2.0,11.1,49.4,0,2\n";
        let e = read_evaal_truth_from(two.as_bytes(), "gt.csv", &limits).unwrap_err();
        assert!(
            matches!(
                e,
                EvaalFileError::Io(IoError::TooManyRecords { line: 2, .. })
            ),
            "{e}"
        );
        let e = read_evaal_estimates("/nonexistent/x.est", &Limits::default()).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/x.est"), "{e}");
    }

    proptest::proptest! {
        #[test]
        fn arbitrary_text_never_panics(text in "[0-9,;.\\-a-z \n]{0,200}") {
            let _ = truth(&text);
            let _ = estimates(&text);
        }
    }
}

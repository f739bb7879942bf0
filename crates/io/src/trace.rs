//! ILC 2.0 trace files (`<walk id>.txt` or `.txt.gz`): reader with a parse report, and a
//! deterministic writer of the same format.
//!
//! One record per line, tab separated: Unix time in ms, record type, values. Lines starting
//! with `#` are headers made of tab-separated `key:value` pairs (`startTime`, `SiteID`,
//! `Brand`, ..., `endTime`). The value columns: the README of the ILC 2.0 repository, or
//! `README.md` in the data root ([`crate::data_root()`]).
//!
//! What the reader does with dirty input:
//! - every stream is sorted by time (stable), since records are not written in time order;
//!   records written after a later-timed record are counted ([`ParseReport::out_of_order`]);
//! - a record that lost its newline and runs into the next record
//!   (`...\t3\t1574559495421\tTYPE_GYROSCOPE\t...` or `...\t31574559495421\tTYPE_GYROSCOPE...`)
//!   is split in two; the next record's time must be the 13 digits in front of its
//!   `TYPE_...` column ([`ParseReport::run_on_lines_split`]);
//! - unknown record types (`TYPE_BLUE`, `TYPE_DIST1`, ...) and malformed records are skipped
//!   and counted by [`SkipKind`] with their first line numbers, and logged at `debug`;
//! - Wi-Fi lines sharing a time form one scan; a BSSID listed twice in a scan keeps its most
//!   recent entry ([`WifiScan::dedup_keep_most_recent`]); stale entries are kept;
//! - [`Limits`] bound line length, input size, record count and scan size: crossing one is an
//!   [`IoError`], never unbounded memory or time.

use crate::{IoError, Limits};
use flate2::read::MultiGzDecoder;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{self, BufRead, BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};
use wipdr_core::walk::Record;
use wipdr_core::{
    BeaconSample, Bssid, RotationVectorSample, UncalibratedSample, Vec3Sample, Walk, Waypoint,
    WifiEntry, WifiScan,
};

/// Why a line was skipped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub enum SkipKind {
    /// An empty or all-whitespace line.
    Blank,
    /// A record type the reader does not know (`TYPE_BLUE`, `TYPE_DIST1`, ...).
    UnknownType,
    /// A record with fewer values than its type needs (or no type column).
    MissingFields,
    /// A record with more values than its type allows.
    ExtraFields,
    /// A first column that is not an integer time in ms within +-2^53
    /// ([`MAX_ABS_TIME_MS`]).
    BadTime,
    /// A value that is not a finite number (or an integer where one is needed, or a
    /// last-seen time beyond [`MAX_ABS_TIME_MS`]).
    BadNumber,
    /// A BSSID that is not six `:`-separated hex bytes.
    BadBssid,
    /// A header whose `startTime`/`endTime` is not an integer within [`MAX_ABS_TIME_MS`].
    BadHeader,
    /// A finite value beyond any physical range ([`PHYSICAL_RANGES`]): an acceleration
    /// above 50 g, a rotation rate above 100 rad/s, a field above 10 000 uT, a rotation
    /// vector component beyond 2, a waypoint coordinate beyond 1e6 m.
    OutOfRange,
    /// A second waypoint at the time of an earlier one (the first is kept).
    DuplicateWaypoint,
    /// A waypoint farther than [`crate::floor::OFF_FLOOR_MARGIN_M`] outside the floor's
    /// `[0, width] x [0, height]` (checked when a floor folder is read).
    WaypointOffFloor,
}

/// The physical ranges beyond which a sample is skipped as [`SkipKind::OutOfRange`]: the
/// largest accepted absolute value of each component (and bias), by record type. Phones
/// saturate far below them (16 g, 35 rad/s, 5 000 uT); they only stop absurd values such as
/// `1e308` that are finite, so parse, and would wreck every estimate downstream.
pub const PHYSICAL_RANGES: [(&str, f64); 5] = [
    ("acceleration, m/s^2 (50 g)", MAX_ABS_ACCELERATION),
    ("rotation rate, rad/s", MAX_ABS_ROTATION_RATE),
    ("magnetic field, uT", MAX_ABS_MAGNETIC_FIELD),
    ("rotation vector component", MAX_ABS_ROTATION_VECTOR),
    ("waypoint coordinate, m", MAX_ABS_COORDINATE_M),
];
/// Largest accepted acceleration component (and bias), m/s^2: 50 g.
pub const MAX_ABS_ACCELERATION: f64 = 50.0 * 9.806_65;
/// Largest accepted rotation rate component (and bias), rad/s.
pub const MAX_ABS_ROTATION_RATE: f64 = 100.0;
/// Largest accepted magnetic field component (and bias), uT.
pub const MAX_ABS_MAGNETIC_FIELD: f64 = 10_000.0;
/// Largest accepted rotation vector component (a unit quaternion's are within 1).
pub const MAX_ABS_ROTATION_VECTOR: f64 = 2.0;
/// Largest accepted waypoint coordinate, metres.
pub const MAX_ABS_COORDINATE_M: f64 = 1e6;

pub(crate) fn in_range(v: &[f64], max: f64) -> Result<(), SkipKind> {
    if v.iter().all(|x| x.abs() <= max) {
        Ok(())
    } else {
        Err(SkipKind::OutOfRange)
    }
}

impl SkipKind {
    /// A short lower-case label for tables and logs.
    pub fn label(self) -> &'static str {
        match self {
            SkipKind::Blank => "blank",
            SkipKind::UnknownType => "unknown type",
            SkipKind::MissingFields => "missing fields",
            SkipKind::ExtraFields => "extra fields",
            SkipKind::BadTime => "bad time",
            SkipKind::BadNumber => "bad number",
            SkipKind::BadBssid => "bad BSSID",
            SkipKind::BadHeader => "bad header",
            SkipKind::OutOfRange => "out of physical range",
            SkipKind::DuplicateWaypoint => "duplicate waypoint time",
            SkipKind::WaypointOffFloor => "waypoint off the floor",
        }
    }
}

/// How many lines of one [`SkipKind`] were skipped, and where the first ones are.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct SkipCount {
    /// Number of skipped records.
    pub count: usize,
    /// The first few line numbers (1-based), at most [`Limits::report_first_lines`].
    pub first_lines: Vec<usize>,
}

/// What the reader met in one trace.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ParseReport {
    /// Lines read (headers, records, blanks).
    pub lines: usize,
    /// Header (`#`) lines.
    pub header_lines: usize,
    /// Records kept, by record type (`TYPE_WIFI` counts lines, i.e. scan entries before
    /// duplicate removal).
    pub records: BTreeMap<String, usize>,
    /// Records skipped, by kind.
    pub skipped: BTreeMap<SkipKind, SkipCount>,
    /// Skipped unknown record types by name (at most [`Limits::report_max_unknown_types`]
    /// names; the rest under `<other>`).
    pub unknown_types: BTreeMap<String, usize>,
    /// Wi-Fi entries dropped because their BSSID appeared again in the same scan.
    pub duplicate_bssids_removed: usize,
    /// Lines that held more than one record and were split.
    pub run_on_lines_split: usize,
    /// The first few lines that were split.
    pub run_on_first_lines: Vec<usize>,
    /// Records (Wi-Fi: scans) written after a record with a later time, of any stream (a
    /// waypoint written 11 s late counts); all streams are sorted after reading.
    pub out_of_order: usize,
    /// The largest lateness of an out-of-order record, ms.
    pub max_lateness_ms: i64,
    /// Known record types the reader does not need (IPIN `GNSS`, `LIGH`, `SOUN`, ...), by
    /// name: counted, not read.
    #[serde(default)]
    pub ignored: BTreeMap<String, usize>,
    /// Sensor samples whose own clock disagreed with the app clock (IPIN logfiles; see
    /// [`crate::logfile`]): timed by the app clock instead.
    #[serde(default)]
    pub sensor_clock_outliers: usize,
}

impl ParseReport {
    /// Total records kept.
    pub fn records_kept(&self) -> usize {
        self.records.values().sum()
    }

    /// Total records skipped (all kinds, blanks included).
    pub fn records_skipped(&self) -> usize {
        self.skipped.values().map(|s| s.count).sum()
    }

    /// Skipped records of one kind.
    pub fn skipped_of(&self, kind: SkipKind) -> usize {
        self.skipped.get(&kind).map_or(0, |s| s.count)
    }

    /// Adds another report's counts into this one (line numbers are not merged).
    pub fn merge_counts(&mut self, other: &ParseReport) {
        self.lines += other.lines;
        self.header_lines += other.header_lines;
        for (k, v) in &other.records {
            *self.records.entry(k.clone()).or_default() += v;
        }
        for (k, v) in &other.skipped {
            self.skipped.entry(*k).or_default().count += v.count;
        }
        for (k, v) in &other.unknown_types {
            *self.unknown_types.entry(k.clone()).or_default() += v;
        }
        self.duplicate_bssids_removed += other.duplicate_bssids_removed;
        self.run_on_lines_split += other.run_on_lines_split;
        self.out_of_order += other.out_of_order;
        self.max_lateness_ms = self.max_lateness_ms.max(other.max_lateness_ms);
        for (k, v) in &other.ignored {
            *self.ignored.entry(k.clone()).or_default() += v;
        }
        self.sensor_clock_outliers += other.sensor_clock_outliers;
    }
}

/// A walk with the report of how it was read.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ParsedWalk {
    /// The walk, every stream sorted by time.
    pub walk: Walk,
    /// What the reader met.
    pub report: ParseReport,
}

/// The walk id of a trace path: the file name without `.gz` and `.txt`.
pub fn walk_id_of(path: &Path) -> String {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let name = name.strip_suffix(".gz").unwrap_or(&name);
    let name = name.strip_suffix(".txt").unwrap_or(name);
    name.to_string()
}

/// Reads one trace file, plain or gzip-compressed (detected by its magic bytes, so the
/// extension does not matter), with default [`Limits`].
///
/// ```no_run
/// let parsed = wipdr_io::trace::read_walk("walk.txt.gz").unwrap();
/// println!("{} waypoints, {} skipped", parsed.walk.waypoints.len(), parsed.report.records_skipped());
/// ```
pub fn read_walk(path: impl AsRef<Path>) -> Result<ParsedWalk, IoError> {
    read_walk_with(path, &Limits::default())
}

/// [`read_walk`] with explicit limits.
pub fn read_walk_with(path: impl AsRef<Path>, limits: &Limits) -> Result<ParsedWalk, IoError> {
    let path = path.as_ref();
    let file = File::open(path).map_err(|e| IoError::file(path, e))?;
    let mut buffered = BufReader::with_capacity(256 * 1024, file);
    let is_gzip = buffered
        .fill_buf()
        .map_err(|e| IoError::file(path, e))?
        .starts_with(&[0x1f, 0x8b]);
    let id = walk_id_of(path);
    if is_gzip {
        let reader = BufReader::with_capacity(256 * 1024, MultiGzDecoder::new(buffered));
        parse_trace(reader, path, &id, limits)
    } else {
        parse_trace(buffered, path, &id, limits)
    }
}

/// Reads a trace from any reader (in-memory input, tests, fuzzing), plain or gzip (detected
/// by its magic bytes). `name` is the walk id and the file name used in errors.
///
/// ```
/// use wipdr_io::{trace, Limits};
/// let text = "#\tstartTime:1000\n\
///             1200\tTYPE_WAYPOINT\t1.5\t2.5\n\
///             1100\tTYPE_WAYPOINT\t1.0\t2.0\n\
///             1150\tTYPE_BLUE\t\t16:E5:41:F6:CC:67\t-95\n";
/// let parsed = trace::read_walk_from(text.as_bytes(), "w1", &Limits::default()).unwrap();
/// assert_eq!(parsed.walk.waypoints[0].t, 1100); // sorted
/// assert_eq!(parsed.report.skipped_of(trace::SkipKind::UnknownType), 1);
/// assert_eq!(parsed.walk.meta.start_time, Some(1000));
/// ```
pub fn read_walk_from(
    reader: impl io::Read,
    name: &str,
    limits: &Limits,
) -> Result<ParsedWalk, IoError> {
    let path = Path::new(name);
    let mut buffered = BufReader::with_capacity(64 * 1024, reader);
    let is_gzip = buffered
        .fill_buf()
        .map_err(|e| IoError::file(path, e))?
        .starts_with(&[0x1f, 0x8b]);
    if is_gzip {
        let reader = BufReader::with_capacity(64 * 1024, MultiGzDecoder::new(buffered));
        parse_trace(reader, path, name, limits)
    } else {
        parse_trace(buffered, path, name, limits)
    }
}

enum LineStatus {
    Eof,
    Line,
    TooLong,
}

/// Reads one line (without its `\n`) into `buf`, never buffering more than `max` bytes.
fn read_line_bounded<R: BufRead>(
    reader: &mut R,
    buf: &mut Vec<u8>,
    max: usize,
    consumed: &mut u64,
) -> io::Result<LineStatus> {
    buf.clear();
    loop {
        let available = match reader.fill_buf() {
            Ok(b) => b,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        if available.is_empty() {
            return Ok(if buf.is_empty() {
                LineStatus::Eof
            } else {
                LineStatus::Line
            });
        }
        let (take, done) = match available.iter().position(|&b| b == b'\n') {
            Some(i) => (i + 1, true),
            None => (available.len(), false),
        };
        let content = if done { take - 1 } else { take };
        let too_long = buf.len() + content > max;
        if !too_long {
            buf.extend_from_slice(&available[..content]);
        }
        reader.consume(take);
        *consumed += take as u64;
        if too_long {
            return Ok(LineStatus::TooLong);
        }
        if done {
            return Ok(LineStatus::Line);
        }
    }
}

struct Parser<'l> {
    limits: &'l Limits,
    path: PathBuf,
    walk: Walk,
    report: ParseReport,
    scan_index: HashMap<i64, usize>,
    max_time: i64,
    records_seen: usize,
    /// Estimated bytes of the walk parsed so far ([`Limits::max_walk_memory_bytes`]).
    memory: u64,
}

/// The range of the three calibrated / uncalibrated streams by index: accelerometer,
/// gyroscope, magnetometer.
const SENSOR_MAX: [f64; 3] = [
    MAX_ABS_ACCELERATION,
    MAX_ABS_ROTATION_RATE,
    MAX_ABS_MAGNETIC_FIELD,
];

/// Known record types (the index picks one of three parallel streams).
#[derive(Clone, Copy)]
enum Kind {
    Vec3(usize),
    Uncal(usize),
    Rotation,
    Wifi,
    Beacon,
    Waypoint,
}

fn kind_of(ty: &str) -> Option<Kind> {
    Some(match ty {
        "TYPE_ACCELEROMETER" => Kind::Vec3(0),
        "TYPE_GYROSCOPE" => Kind::Vec3(1),
        "TYPE_MAGNETIC_FIELD" => Kind::Vec3(2),
        "TYPE_ACCELEROMETER_UNCALIBRATED" => Kind::Uncal(0),
        "TYPE_GYROSCOPE_UNCALIBRATED" => Kind::Uncal(1),
        "TYPE_MAGNETIC_FIELD_UNCALIBRATED" => Kind::Uncal(2),
        "TYPE_ROTATION_VECTOR" => Kind::Rotation,
        "TYPE_WIFI" => Kind::Wifi,
        "TYPE_BEACON" => Kind::Beacon,
        "TYPE_WAYPOINT" => Kind::Waypoint,
        _ => return None,
    })
}

fn is_type_token(s: &str) -> bool {
    s.len() > 5
        && s.len() <= 64
        && s.starts_with("TYPE_")
        && s.bytes()
            .all(|b| b.is_ascii_uppercase() || b.is_ascii_digit() || b == b'_')
}

/// Length of a Unix-ms timestamp of the ILC era (2001-2286): 13 digits.
const TIME_DIGITS: usize = 13;

/// If `token` ends with a 13-digit time, the split point (the time's start in `token`).
fn glued_time_start(token: &str) -> Option<usize> {
    let n = token.len();
    if n < TIME_DIGITS {
        return None;
    }
    let start = n - TIME_DIGITS;
    (token.is_char_boundary(start) && token.as_bytes()[start..].iter().all(u8::is_ascii_digit))
        .then_some(start)
}

/// Largest accepted time magnitude, ms: 2^53, so that times and their differences stay exact
/// in `f64` and never overflow `i64` arithmetic downstream.
pub const MAX_ABS_TIME_MS: i64 = 1 << 53;

/// An integer time (Unix ms) within [`MAX_ABS_TIME_MS`].
fn parse_time(s: &str) -> Option<i64> {
    s.trim()
        .parse::<i64>()
        .ok()
        .filter(|t| (-MAX_ABS_TIME_MS..=MAX_ABS_TIME_MS).contains(t))
}

pub(crate) fn parse_f64(s: &str) -> Result<f64, SkipKind> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(SkipKind::BadNumber),
    }
}

pub(crate) fn parse_vec3(v: &[&str]) -> Result<[f64; 3], SkipKind> {
    Ok([parse_f64(v[0])?, parse_f64(v[1])?, parse_f64(v[2])?])
}

fn parse_accuracy(v: Option<&&str>) -> Result<i8, SkipKind> {
    match v {
        None => Ok(-1),
        Some(s) => s.trim().parse::<i8>().map_err(|_| SkipKind::BadNumber),
    }
}

pub(crate) fn check_count(n: usize, min: usize, max: usize) -> Result<(), SkipKind> {
    if n < min {
        Err(SkipKind::MissingFields)
    } else if n > max {
        Err(SkipKind::ExtraFields)
    } else {
        Ok(())
    }
}

impl<'l> Parser<'l> {
    fn new(path: &Path, id: &str, limits: &'l Limits) -> Self {
        let mut walk = Walk::default();
        walk.meta.id = id.to_string();
        Self {
            limits,
            path: path.to_path_buf(),
            walk,
            report: ParseReport::default(),
            scan_index: HashMap::new(),
            max_time: i64::MIN,
            records_seen: 0,
            memory: 0,
        }
    }

    fn skip(&mut self, kind: SkipKind, line: usize) {
        let entry = self.report.skipped.entry(kind).or_default();
        entry.count += 1;
        if entry.first_lines.len() < self.limits.report_first_lines {
            entry.first_lines.push(line);
            tracing::debug!(file = %self.path.display(), line, kind = kind.label(), "skipped trace line");
        }
    }

    fn header(&mut self, line: &str, line_no: usize) {
        self.report.header_lines += 1;
        let meta = &mut self.walk.meta;
        let mut bad = false;
        for pair in line.trim_start_matches('#').split('\t') {
            let Some((key, value)) = pair.split_once(':') else {
                continue;
            };
            let text = || Some(value.to_string());
            match key.trim() {
                "startTime" => match parse_time(value) {
                    Some(t) => meta.start_time = Some(t),
                    None => bad = true,
                },
                "endTime" => match parse_time(value) {
                    Some(t) => meta.end_time = Some(t),
                    None => bad = true,
                },
                "SiteID" => meta.site_id = text(),
                "SiteName" => meta.site_name = text(),
                "FloorId" => meta.floor_id = text(),
                "FloorName" => meta.floor_name = text(),
                "Brand" => meta.brand = text(),
                "Model" => meta.model = text(),
                "AndroidName" => meta.android = text(),
                _ => {}
            }
        }
        if bad {
            self.skip(SkipKind::BadHeader, line_no);
        }
    }

    /// One record's fields (time, type, values...).
    fn record(&mut self, fields: &[&str], line_no: usize) -> Result<(), IoError> {
        self.records_seen += 1;
        if self.records_seen > self.limits.max_records {
            return Err(IoError::TooManyRecords {
                path: self.path.clone(),
                line: line_no,
                limit: self.limits.max_records,
            });
        }
        let mut fields = fields;
        if fields.len() > 2 && fields.last().is_some_and(|f| f.is_empty()) {
            fields = &fields[..fields.len() - 1];
        }
        if fields.len() < 2 {
            self.skip(SkipKind::MissingFields, line_no);
            return Ok(());
        }
        let ty = fields[1].trim();
        let Some(kind) = kind_of(ty) else {
            self.skip(SkipKind::UnknownType, line_no);
            let max_names = self.limits.report_max_unknown_types;
            let names = &mut self.report.unknown_types;
            let name = if names.contains_key(ty) || names.len() < max_names {
                ty.chars().take(64).collect()
            } else {
                "<other>".to_string()
            };
            *names.entry(name).or_default() += 1;
            return Ok(());
        };
        let Some(t) = parse_time(fields[0]) else {
            self.skip(SkipKind::BadTime, line_no);
            return Ok(());
        };
        let text_bytes: usize = fields[2..].iter().map(|f| f.len()).sum();
        let item_bytes = match kind {
            Kind::Vec3(_) | Kind::Rotation => std::mem::size_of::<Vec3Sample>(),
            Kind::Uncal(_) => std::mem::size_of::<UncalibratedSample>(),
            Kind::Waypoint => std::mem::size_of::<Waypoint>(),
            Kind::Beacon => std::mem::size_of::<BeaconSample>() + text_bytes,
            Kind::Wifi => std::mem::size_of::<WifiEntry>() + text_bytes,
        };
        let pushed = self.push(kind, t, &fields[2..], line_no);
        let charge = match (&pushed, kind) {
            // A new scan: its own struct, its entry vector and its time index entry.
            (Ok(true), Kind::Wifi) => {
                item_bytes + std::mem::size_of::<WifiScan>() + 4 * std::mem::size_of::<usize>()
            }
            (Ok(_), _) => item_bytes,
            (Err(_), _) => 0,
        };
        self.memory = self.memory.saturating_add(charge as u64);
        if self.memory > self.limits.max_walk_memory_bytes {
            return Err(IoError::LimitExceeded {
                path: self.path.clone(),
                what: format!("line {line_no}: parsed walk memory"),
                limit: "max_walk_memory_bytes",
                max: self.limits.max_walk_memory_bytes,
            });
        }
        match pushed {
            Ok(true) => {
                if t < self.max_time {
                    self.report.out_of_order += 1;
                    self.report.max_lateness_ms = self
                        .report
                        .max_lateness_ms
                        .max(self.max_time.saturating_sub(t));
                }
                self.max_time = self.max_time.max(t);
                // Counting per type by name: a small fixed set of keys.
                if let Some(c) = self.report.records.get_mut(ty) {
                    *c += 1;
                } else {
                    self.report.records.insert(ty.to_string(), 1);
                }
            }
            Ok(false) => {
                *self.report.records.entry(ty.to_string()).or_default() += 1;
            }
            Err(Ok(kind)) => self.skip(kind, line_no),
            Err(Err(e)) => return Err(e),
        }
        Ok(())
    }

    /// Stores one record. `Ok(true)`: a new item in its stream; `Ok(false)`: an entry added to
    /// an existing scan; `Err(Ok(kind))`: skip; `Err(Err(e))`: a limit was crossed.
    #[allow(clippy::type_complexity)]
    fn push(
        &mut self,
        kind: Kind,
        t: i64,
        v: &[&str],
        line_no: usize,
    ) -> Result<bool, Result<SkipKind, IoError>> {
        let imu = &mut self.walk.imu;
        match kind {
            Kind::Vec3(i) => {
                check_count(v.len(), 3, 4).map_err(Ok)?;
                let sample = Vec3Sample {
                    t,
                    v: parse_vec3(v).map_err(Ok)?,
                    accuracy: parse_accuracy(v.get(3)).map_err(Ok)?,
                };
                in_range(&sample.v, SENSOR_MAX[i]).map_err(Ok)?;
                [
                    &mut imu.accelerometer,
                    &mut imu.gyroscope,
                    &mut imu.magnetometer,
                ][i]
                    .push(sample);
            }
            Kind::Uncal(i) => {
                check_count(v.len(), 6, 7).map_err(Ok)?;
                let sample = UncalibratedSample {
                    t,
                    v: parse_vec3(&v[..3]).map_err(Ok)?,
                    bias: parse_vec3(&v[3..6]).map_err(Ok)?,
                    accuracy: parse_accuracy(v.get(6)).map_err(Ok)?,
                };
                in_range(&sample.v, SENSOR_MAX[i]).map_err(Ok)?;
                in_range(&sample.bias, SENSOR_MAX[i]).map_err(Ok)?;
                [
                    &mut imu.accelerometer_uncalibrated,
                    &mut imu.gyroscope_uncalibrated,
                    &mut imu.magnetometer_uncalibrated,
                ][i]
                    .push(sample);
            }
            Kind::Rotation => {
                check_count(v.len(), 3, 4).map_err(Ok)?;
                let sample = RotationVectorSample {
                    t,
                    v: parse_vec3(v).map_err(Ok)?,
                    accuracy: parse_accuracy(v.get(3)).map_err(Ok)?,
                };
                in_range(&sample.v, MAX_ABS_ROTATION_VECTOR).map_err(Ok)?;
                imu.rotation_vector.push(sample);
            }
            Kind::Waypoint => {
                check_count(v.len(), 2, 2).map_err(Ok)?;
                let x = parse_f64(v[0]).map_err(Ok)?;
                let y = parse_f64(v[1]).map_err(Ok)?;
                in_range(&[x, y], MAX_ABS_COORDINATE_M).map_err(Ok)?;
                self.walk
                    .waypoints
                    .push(Waypoint::new(t, wipdr_core::Point2::new(x, y)));
            }
            Kind::Beacon => {
                check_count(v.len(), 8, 8).map_err(Ok)?;
                let sample = BeaconSample {
                    t,
                    uuid: v[0].to_string(),
                    major: v[1].to_string(),
                    minor: v[2].to_string(),
                    tx_power: Some(parse_f64(v[3]).map_err(Ok)?),
                    rssi_dbm: parse_f64(v[4]).map_err(Ok)?,
                    distance: Some(parse_f64(v[5]).map_err(Ok)?),
                    mac: v[6].to_string(),
                    seen_ms: Some(parse_time(v[7]).ok_or(Ok(SkipKind::BadNumber))?),
                };
                self.walk.beacons.push(sample);
            }
            Kind::Wifi => {
                // ssid (may itself contain tabs), bssid, rssi, frequency, last seen.
                if v.len() < 5 {
                    return Err(Ok(SkipKind::MissingFields));
                }
                let n = v.len();
                let bssid: Bssid = v[n - 4]
                    .trim()
                    .parse()
                    .map_err(|_| Ok(SkipKind::BadBssid))?;
                let rssi_dbm = parse_f64(v[n - 3]).map_err(Ok)?;
                let frequency_mhz: u32 = v[n - 2]
                    .trim()
                    .parse()
                    .map_err(|_| Ok(SkipKind::BadNumber))?;
                let last_seen_ms = parse_time(v[n - 1]).ok_or(Ok(SkipKind::BadNumber))?;
                let ssid = if n == 5 {
                    v[0].to_string()
                } else {
                    v[..n - 4].join("\t")
                };
                let entry = WifiEntry {
                    bssid,
                    ssid,
                    rssi_dbm,
                    frequency_mhz,
                    last_seen_ms,
                };
                if let Some(&i) = self.scan_index.get(&t) {
                    let scan = &mut self.walk.wifi[i];
                    if scan.entries.len() >= self.limits.max_scan_entries {
                        return Err(Err(IoError::ScanTooLarge {
                            path: self.path.clone(),
                            line: line_no,
                            t,
                            limit: self.limits.max_scan_entries,
                        }));
                    }
                    scan.entries.push(entry);
                    return Ok(false);
                }
                self.scan_index.insert(t, self.walk.wifi.len());
                self.walk.wifi.push(WifiScan {
                    t,
                    entries: vec![entry],
                });
            }
        }
        Ok(true)
    }

    /// One non-header line: split run-on records, then parse each.
    fn line(&mut self, line: &str, line_no: usize) -> Result<(), IoError> {
        let fields: Vec<&str> = line.split('\t').collect();
        // Record boundaries inside the line: a `TYPE_...` column at index >= 2 whose
        // previous column ends with a 13-digit time.
        let mut cuts: Vec<(usize, usize)> = Vec::new(); // (field index of the time, byte split)
        for i in 2..fields.len() {
            if is_type_token(fields[i])
                && let Some(split) = glued_time_start(fields[i - 1])
            {
                cuts.push((i - 1, split));
            }
        }
        if cuts.is_empty() {
            return self.record(&fields, line_no);
        }
        self.report.run_on_lines_split += 1;
        if self.report.run_on_first_lines.len() < self.limits.report_first_lines {
            self.report.run_on_first_lines.push(line_no);
        }
        tracing::debug!(file = %self.path.display(), line = line_no, pieces = cuts.len() + 1, "split run-on line");
        let mut start_fields: Vec<&str> = Vec::new();
        let mut from = 0usize;
        for &(time_idx, split) in &cuts {
            let token = fields[time_idx];
            let mut piece: Vec<&str> = std::mem::take(&mut start_fields);
            piece.extend_from_slice(&fields[from..time_idx]);
            if split > 0 {
                piece.push(&token[..split]);
            }
            self.record(&piece, line_no)?;
            start_fields = vec![&token[split..]];
            from = time_idx + 1;
        }
        let mut piece = start_fields;
        piece.extend_from_slice(&fields[from..]);
        self.record(&piece, line_no)
    }

    fn finish(mut self) -> ParsedWalk {
        for scan in &mut self.walk.wifi {
            self.report.duplicate_bssids_removed += scan.dedup_keep_most_recent();
        }
        self.walk.sort_streams();
        // Two waypoints at one time: two truths for one instant. Keep the first in file order
        // (the sort is stable), count the others as skipped.
        let before = self.walk.waypoints.len();
        self.walk.waypoints.dedup_by_key(|w| w.t);
        let duplicates = before - self.walk.waypoints.len();
        if duplicates > 0 {
            tracing::warn!(file = %self.path.display(), duplicates, "waypoints sharing a time with an earlier one skipped");
            self.report
                .skipped
                .entry(SkipKind::DuplicateWaypoint)
                .or_default()
                .count += duplicates;
            if let Some(c) = self.report.records.get_mut("TYPE_WAYPOINT") {
                *c = c.saturating_sub(duplicates);
            }
        }
        ParsedWalk {
            walk: self.walk,
            report: self.report,
        }
    }
}

/// Reads `reader` line by line within `limits` (line length, input size), calling `each`
/// with every line (without its `\n` and a trailing `\r`, invalid UTF-8 replaced) and its
/// 1-based number: the line loop of every text reader here (ILC traces, IPIN logfiles).
pub(crate) fn for_each_line<R: BufRead>(
    mut reader: R,
    path: &Path,
    limits: &Limits,
    mut each: impl FnMut(&str, usize) -> Result<(), IoError>,
) -> Result<(), IoError> {
    let mut buf = Vec::with_capacity(256);
    let mut consumed = 0u64;
    let mut line_no = 0usize;
    loop {
        let status = read_line_bounded(&mut reader, &mut buf, limits.max_line_bytes, &mut consumed)
            .map_err(|source| IoError::Read {
                path: path.to_path_buf(),
                line: line_no,
                source,
            })?;
        if consumed > limits.max_input_bytes {
            return Err(IoError::InputTooLarge {
                path: path.to_path_buf(),
                limit: limits.max_input_bytes,
            });
        }
        match status {
            LineStatus::Eof => return Ok(()),
            LineStatus::TooLong => {
                return Err(IoError::LineTooLong {
                    path: path.to_path_buf(),
                    line: line_no + 1,
                    limit: limits.max_line_bytes,
                });
            }
            LineStatus::Line => {}
        }
        line_no += 1;
        let text = String::from_utf8_lossy(&buf);
        each(text.strip_suffix('\r').unwrap_or(&text), line_no)?;
    }
}

fn parse_trace<R: BufRead>(
    reader: R,
    path: &Path,
    id: &str,
    limits: &Limits,
) -> Result<ParsedWalk, IoError> {
    let mut parser = Parser::new(path, id, limits);
    for_each_line(reader, path, limits, |line, line_no| {
        parser.report.lines += 1;
        if line.trim().is_empty() {
            parser.skip(SkipKind::Blank, line_no);
        } else if line.starts_with('#') {
            parser.header(line, line_no);
        } else {
            parser.line(line, line_no)?;
        }
        Ok(())
    })?;
    Ok(parser.finish())
}

// ---------------------------------------------------------------- writer

/// Replaces the characters that would break the line format (tab, CR, LF) by spaces.
fn clean(s: &str) -> std::borrow::Cow<'_, str> {
    if s.contains(['\t', '\n', '\r']) {
        std::borrow::Cow::Owned(s.replace(['\t', '\n', '\r'], " "))
    } else {
        std::borrow::Cow::Borrowed(s)
    }
}

fn num(v: f64, field: &str) -> io::Result<String> {
    if !v.is_finite() {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            IoError::Unwritable {
                field: field.to_string(),
                message: format!("non-finite value {v}"),
            },
        ));
    }
    // `{:?}` is the shortest representation that parses back to the same f64.
    Ok(format!("{v:?}"))
}

/// Integral values (RSSI, tx power) as integers, like the phones write them.
fn num_int_if_integral(v: f64, field: &str) -> io::Result<String> {
    if v.is_finite() && v.fract() == 0.0 && v.abs() < 1e15 {
        Ok(format!("{}", v as i64))
    } else {
        num(v, field)
    }
}

fn accuracy_suffix(a: i8) -> String {
    if a == -1 {
        String::new()
    } else {
        format!("\t{a}")
    }
}

/// Writes a walk in the ILC 2.0 text format: headers (`startTime`; `SiteID`, `SiteName`,
/// `FloorId`, `FloorName`; `Brand`, `Model`, `AndroidName`, each when present in
/// [`wipdr_core::WalkMeta`]), all records in the merged time order of [`Walk::replay`], then
/// the `endTime` header. Deterministic: the same walk gives the same bytes.
///
/// Tabs and line breaks inside strings (SSIDs, names) are written as spaces; an accuracy of
/// -1 (absent) is omitted; non-finite numbers are refused (`InvalidInput`). Reading the
/// output back with [`read_walk_from`] gives the same walk (up to that cleaning), provided no
/// two scans share a time and no BSSID repeats within a scan.
///
/// ```
/// use wipdr_core::{Point2, Walk, Waypoint};
/// let mut walk = Walk::default();
/// walk.meta.id = "w".into();
/// walk.waypoints.push(Waypoint::new(1000, Point2::new(1.0, 2.5)));
/// let mut bytes = Vec::new();
/// wipdr_io::trace::write_walk(&walk, &mut bytes).unwrap();
/// assert_eq!(String::from_utf8(bytes.clone()).unwrap(), "1000\tTYPE_WAYPOINT\t1.0\t2.5\n");
/// let back = wipdr_io::trace::read_walk_from(&bytes[..], "w", &Default::default()).unwrap();
/// assert_eq!(back.walk, walk);
/// ```
pub fn write_walk(walk: &Walk, out: &mut impl Write) -> io::Result<()> {
    let meta = &walk.meta;
    if let Some(t) = meta.start_time {
        writeln!(out, "#\tstartTime:{t}")?;
    }
    let header = |pairs: &[(&str, &Option<String>)]| -> Option<String> {
        let parts: Vec<String> = pairs
            .iter()
            .filter_map(|(k, v)| v.as_ref().map(|v| format!("{k}:{}", clean(v))))
            .collect();
        (!parts.is_empty()).then(|| format!("#\t{}", parts.join("\t")))
    };
    if let Some(h) = header(&[
        ("SiteID", &meta.site_id),
        ("SiteName", &meta.site_name),
        ("FloorId", &meta.floor_id),
        ("FloorName", &meta.floor_name),
    ]) {
        writeln!(out, "{h}")?;
    }
    if let Some(h) = header(&[
        ("Brand", &meta.brand),
        ("Model", &meta.model),
        ("AndroidName", &meta.android),
    ]) {
        writeln!(out, "{h}")?;
    }
    let vec3 = |s: &Vec3Sample, ty: &str| -> io::Result<String> {
        Ok(format!(
            "{}\t{ty}\t{}\t{}\t{}{}",
            s.t,
            num(s.v[0], ty)?,
            num(s.v[1], ty)?,
            num(s.v[2], ty)?,
            accuracy_suffix(s.accuracy)
        ))
    };
    let uncal = |s: &UncalibratedSample, ty: &str| -> io::Result<String> {
        Ok(format!(
            "{}\t{ty}\t{}\t{}\t{}\t{}\t{}\t{}{}",
            s.t,
            num(s.v[0], ty)?,
            num(s.v[1], ty)?,
            num(s.v[2], ty)?,
            num(s.bias[0], ty)?,
            num(s.bias[1], ty)?,
            num(s.bias[2], ty)?,
            accuracy_suffix(s.accuracy)
        ))
    };
    for record in walk.replay() {
        match record {
            Record::Accelerometer(s) => writeln!(out, "{}", vec3(s, "TYPE_ACCELEROMETER")?)?,
            Record::Gyroscope(s) => writeln!(out, "{}", vec3(s, "TYPE_GYROSCOPE")?)?,
            Record::Magnetometer(s) => writeln!(out, "{}", vec3(s, "TYPE_MAGNETIC_FIELD")?)?,
            Record::RotationVector(s) => writeln!(
                out,
                "{}\tTYPE_ROTATION_VECTOR\t{}\t{}\t{}{}",
                s.t,
                num(s.v[0], "TYPE_ROTATION_VECTOR")?,
                num(s.v[1], "TYPE_ROTATION_VECTOR")?,
                num(s.v[2], "TYPE_ROTATION_VECTOR")?,
                accuracy_suffix(s.accuracy)
            )?,
            Record::AccelerometerUncalibrated(s) => {
                writeln!(out, "{}", uncal(s, "TYPE_ACCELEROMETER_UNCALIBRATED")?)?
            }
            Record::GyroscopeUncalibrated(s) => {
                writeln!(out, "{}", uncal(s, "TYPE_GYROSCOPE_UNCALIBRATED")?)?
            }
            Record::MagnetometerUncalibrated(s) => {
                writeln!(out, "{}", uncal(s, "TYPE_MAGNETIC_FIELD_UNCALIBRATED")?)?
            }
            Record::Wifi(scan) => {
                for e in &scan.entries {
                    writeln!(
                        out,
                        "{}\tTYPE_WIFI\t{}\t{}\t{}\t{}\t{}",
                        scan.t,
                        clean(&e.ssid),
                        e.bssid,
                        num_int_if_integral(e.rssi_dbm, "TYPE_WIFI rssi")?,
                        e.frequency_mhz,
                        e.last_seen_ms
                    )?;
                }
            }
            Record::Beacon(b) => match (b.tx_power, b.distance, b.seen_ms) {
                (Some(tx_power), Some(distance), Some(seen_ms)) => writeln!(
                    out,
                    "{}\tTYPE_BEACON\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}",
                    b.t,
                    clean(&b.uuid),
                    clean(&b.major),
                    clean(&b.minor),
                    num_int_if_integral(tx_power, "TYPE_BEACON tx power")?,
                    num_int_if_integral(b.rssi_dbm, "TYPE_BEACON rssi")?,
                    num(distance, "TYPE_BEACON distance")?,
                    clean(&b.mac),
                    seen_ms
                )?,
                _ => tracing::debug!(
                    t = b.t,
                    "beacon without the ILC power/distance/time fields: not written"
                ),
            },
            Record::Pressure(p) => {
                tracing::debug!(
                    t = p.t,
                    "pressure is not part of the ILC format: not written"
                )
            }
            Record::Waypoint(w) => writeln!(
                out,
                "{}\tTYPE_WAYPOINT\t{}\t{}",
                w.t,
                num(w.position.x, "TYPE_WAYPOINT x")?,
                num(w.position.y, "TYPE_WAYPOINT y")?
            )?,
        }
    }
    if let Some(t) = meta.end_time {
        writeln!(out, "#\tendTime:{t}")?;
    }
    Ok(())
}

/// Writes a walk to `path` with [`write_walk`], gzip-compressed when the path ends in `.gz`
/// (deterministic too: the gzip header carries no time or name).
pub fn write_walk_file(walk: &Walk, path: impl AsRef<Path>) -> Result<(), IoError> {
    let path = path.as_ref();
    let to_err = |e| IoError::file(path, e);
    let file = File::create(path).map_err(to_err)?;
    let gz = path.extension().is_some_and(|e| e == "gz");
    if gz {
        let mut enc = flate2::GzBuilder::new()
            .mtime(0)
            .write(BufWriter::new(file), flate2::Compression::default());
        write_walk(walk, &mut enc).map_err(to_err)?;
        enc.finish().map_err(to_err)?.flush().map_err(to_err)?;
    } else {
        let mut w = BufWriter::new(file);
        write_walk(walk, &mut w).map_err(to_err)?;
        w.flush().map_err(to_err)?;
    }
    Ok(())
}

#[cfg(test)]
#[path = "trace_tests.rs"]
mod tests;

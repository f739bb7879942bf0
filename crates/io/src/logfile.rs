//! IPIN competition logfiles, as written by the GetSensorData Android app (`.txt` or
//! `.txt.gz`), into the core [`Walk`].
//!
//! One record per line, `;`-separated: the record type, then the AppTimestamp in seconds
//! (the app's clock, common to all sensors), then values. Lines starting with `%` are the
//! header. The header documents field lists that do not match the data (`MAGN` has an extra
//! `;;`, `% POSI Reference` is itself a header line), so the reader uses fixed positions:
//!
//! | type | fields after the type | into |
//! | --- | --- | --- |
//! | `ACCE`, `GYRO`, `MAGN` | AppTs, SensorTs, x, y, z, accuracy | [`wipdr_core::ImuStreams`] |
//! | `AHRS` | AppTs, SensorTs, pitch, roll, yaw (deg), quat x, y, z, accuracy | rotation vector (the quaternion's vector part: Android's rotation vector) |
//! | `PRES` | AppTs, SensorTs, pressure (mbar), accuracy | [`Walk::pressure`] |
//! | `WIFI` | AppTs, SensorTs, SSID, BSSID, frequency, RSS | one scan = consecutive lines sharing one AppTs |
//! | `BLE4` | AppTs, `iBeacon`, MAC, RSSI, power, major, minor, UUID (or `Eddystone`, MAC, RSSI, instance) | [`Walk::beacons`] |
//! | `POSI` | Ts, counter, latitude, longitude, floor, building | [`GroundTruthPoint`] (the waypoints, once a [`GeoFrame`] is chosen) |
//!
//! `GNSS`, `LIGH`, `SOUN`, `PROX`, `HUMI`, `TEMP`, `BLUE`, `RFID`, `IMUX`, `IMUL`, `IMUI` are
//! known and not needed: counted in [`ParseReport::ignored`]. Anything else is skipped as
//! [`SkipKind::UnknownType`].
//!
//! **Clocks.** Every time is the AppTimestamp in ms from the log's start. A sensor sample's
//! time is its SensorTimestamp moved onto the app clock by the stream's median
//! `AppTs - SensorTs` (so sampling intervals are the sensor's own, and the stream sits on the
//! common clock); a sample whose AppTs is more than [`SENSOR_CLOCK_TOLERANCE_S`] away from
//! that (a sensor clock jump) keeps its AppTs and is counted in
//! [`ParseReport::sensor_clock_outliers`].
//!
//! **Floors.** `POSI` floors are taken as written (0, -1, -2 in the IPIN 2023 files, whatever
//! the header says); the building number goes to [`wipdr_core::WalkMeta::site_id`].
//!
//! The same [`Limits`] and typed [`IoError`]s as the ILC reader bound every file.

use crate::trace::{
    MAX_ABS_ACCELERATION, MAX_ABS_MAGNETIC_FIELD, MAX_ABS_ROTATION_RATE, MAX_ABS_ROTATION_VECTOR,
    MAX_ABS_TIME_MS, ParseReport, ParsedWalk, SkipKind, check_count, for_each_line, in_range,
    parse_f64, parse_vec3,
};
use crate::{IoError, Limits};
use flate2::read::MultiGzDecoder;
use serde::{Deserialize, Serialize};
use std::fs::File;
use std::io::{self, BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use wipdr_core::{
    BeaconSample, Bssid, GeoFrame, PressureSample, RotationVectorSample, TimestampMs, Vec3Sample,
    Walk, Waypoint, WifiEntry, WifiScan,
};

/// Largest gap, seconds, between a sample's AppTimestamp and its SensorTimestamp moved onto
/// the app clock before the sample is taken as a sensor clock jump.
pub const SENSOR_CLOCK_TOLERANCE_S: f64 = 0.5;

/// Accepted barometer range, hPa (the lowest and highest sea-level records are 870 and
/// 1084; a phone on a mountain reads ~600).
pub const PRESSURE_RANGE_HPA: (f64, f64) = (300.0, 1_200.0);

/// Accepted RSSI range, dBm.
pub const RSSI_RANGE_DBM: (f64, f64) = (-200.0, 30.0);

/// Accepted floor numbers (absolute value).
pub const MAX_ABS_FLOOR: i32 = 200;

/// Record types a logfile may hold that the reader does not need (counted, not read).
pub const IGNORED_TYPES: [&str; 11] = [
    "GNSS", "LIGH", "SOUN", "PROX", "HUMI", "TEMP", "BLUE", "RFID", "IMUX", "IMUL", "IMUI",
];

/// One ground-truth point (`POSI`), in degrees.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GroundTruthPoint {
    /// Time, ms on the app clock.
    pub t: TimestampMs,
    /// The point's counter in the log.
    pub counter: i64,
    /// WGS84 latitude, degrees.
    pub lat_deg: f64,
    /// WGS84 longitude, degrees.
    pub lon_deg: f64,
    /// Floor number as written.
    pub floor: i32,
    /// Building number as written.
    pub building: i32,
}

/// A logfile read: the walk without waypoints, its ground truth in degrees, and the report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ParsedLogfile {
    /// Sensor streams and metadata; [`Walk::waypoints`] is empty until
    /// [`ParsedLogfile::into_walk`] places the ground truth in a metre frame.
    pub walk: Walk,
    /// The `POSI` points, sorted by time, one per time (later duplicates skipped).
    pub ground_truth: Vec<GroundTruthPoint>,
    /// What the reader met.
    pub report: ParseReport,
}

impl ParsedLogfile {
    /// The walk with its ground truth as waypoints in `frame` (metres east/north, with the
    /// `POSI` floor).
    pub fn into_walk(mut self, frame: &GeoFrame) -> ParsedWalk {
        self.walk.waypoints = self
            .ground_truth
            .iter()
            .map(|g| Waypoint::new(g.t, frame.to_local(g.lat_deg, g.lon_deg)).on_floor(g.floor))
            .collect();
        ParsedWalk {
            walk: self.walk,
            report: self.report,
        }
    }
}

/// The route of an IPIN walk id: `TrialNN` in `IPIN2023_T3_TrainingTrial01_repetition02`
/// (all repetitions of a route share it); `None` without a `Trial` followed by digits.
///
/// ```
/// use wipdr_io::logfile::route_of;
/// assert_eq!(route_of("IPIN2023_T3_TrainingTrial01_repetition02").as_deref(), Some("Trial01"));
/// assert_eq!(route_of("walk"), None);
/// ```
pub fn route_of(id: &str) -> Option<String> {
    let at = id.find("Trial")?;
    let digits: String = id[at + 5..]
        .chars()
        .take_while(char::is_ascii_digit)
        .collect();
    (!digits.is_empty()).then(|| format!("Trial{digits}"))
}

/// Whether a file looks like a GetSensorData logfile: its first non-blank line starts with
/// `%` (ILC traces start with `#`). Reads at most the first 64 KiB (decompressed).
pub fn is_logfile(path: impl AsRef<Path>) -> bool {
    let Ok(file) = File::open(path.as_ref()) else {
        return false;
    };
    let mut buffered = BufReader::new(file);
    let Ok(head) = buffered.fill_buf() else {
        return false;
    };
    let mut text = Vec::new();
    let ok = if head.starts_with(&[0x1f, 0x8b]) {
        MultiGzDecoder::new(buffered)
            .take(64 * 1024)
            .read_to_end(&mut text)
            .is_ok()
    } else {
        buffered.take(64 * 1024).read_to_end(&mut text).is_ok()
    };
    ok && String::from_utf8_lossy(&text)
        .lines()
        .find(|l| !l.trim().is_empty())
        .is_some_and(|l| l.starts_with('%'))
}

/// Reads one logfile, plain or gzip (detected by its magic bytes).
///
/// ```no_run
/// let log = wipdr_io::logfile::read_logfile("T01_01.txt.gz", &Default::default()).unwrap();
/// println!("{} scans, {} POSI", log.walk.wifi.len(), log.ground_truth.len());
/// ```
pub fn read_logfile(path: impl AsRef<Path>, limits: &Limits) -> Result<ParsedLogfile, IoError> {
    let path = path.as_ref();
    let file = File::open(path).map_err(|e| IoError::file(path, e))?;
    read_from(file, path, &crate::trace::walk_id_of(path), limits)
}

/// Reads a logfile from any reader (tests, in-memory input); `name` is the walk id and the
/// file name in errors.
///
/// ```
/// use wipdr_io::logfile::read_logfile_from;
/// let text = "% header\n\
///             ACCE;0.05;100.00;0.1;0.2;9.8;3\n\
///             ACCE;0.07;100.02;0.1;0.2;9.8;3\n\
///             WIFI;0.65;100.6;net;20:23:00:00:00:01;2437;-60\n\
///             WIFI;0.65;100.6;net;20:23:00:00:00:15;2452;-63\n\
///             POSI;61.4235;1;49.4613;11.1109;0;100\n\
///             GNSS;0.96;1.0;49.46;11.11;346;79;9;0.1;22;19\n";
/// let log = read_logfile_from(text.as_bytes(), "IPIN_Trial01_repetition01", &Default::default()).unwrap();
/// assert_eq!(log.walk.imu.accelerometer[1].t, 70);
/// assert_eq!(log.walk.wifi[0].entries.len(), 2);
/// assert_eq!(log.ground_truth[0].t, 61_424);
/// assert_eq!(log.report.ignored["GNSS"], 1);
/// assert_eq!(log.walk.meta.route.as_deref(), Some("Trial01"));
/// ```
pub fn read_logfile_from(
    reader: impl io::Read,
    name: &str,
    limits: &Limits,
) -> Result<ParsedLogfile, IoError> {
    read_from(reader, Path::new(name), name, limits)
}

fn read_from(
    reader: impl io::Read,
    path: &Path,
    id: &str,
    limits: &Limits,
) -> Result<ParsedLogfile, IoError> {
    let mut buffered = BufReader::with_capacity(256 * 1024, reader);
    let is_gzip = buffered
        .fill_buf()
        .map_err(|e| IoError::file(path, e))?
        .starts_with(&[0x1f, 0x8b]);
    if is_gzip {
        let reader = BufReader::with_capacity(256 * 1024, MultiGzDecoder::new(buffered));
        parse(reader, path, id, limits)
    } else {
        parse(buffered, path, id, limits)
    }
}

/// Seconds on the app clock to ms, within [`MAX_ABS_TIME_MS`].
fn seconds_to_ms(s: &str) -> Option<TimestampMs> {
    let v = s.trim().parse::<f64>().ok()?;
    let ms = (v * 1000.0).round();
    // `MAX_ABS_TIME_MS` is 2^53: exactly representable, so the cast below is in range.
    (ms.is_finite() && ms.abs() <= MAX_ABS_TIME_MS as f64).then_some(ms as i64)
}

/// Days from 1970-01-01 to a civil date (proleptic Gregorian; H. Hinnant's algorithm).
fn days_from_civil(y: i64, m: i64, d: i64) -> i64 {
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = (m + 9) % 12;
    let doy = (153 * mp + 2) / 5 + d - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// The header's `Date of creation` (Java's `Date.toString()`: `Wed Jun 14 10:00:58
/// GMT+02:00 2023`) as Unix ms; `None` when it does not have that form.
///
/// ```
/// use wipdr_io::logfile::parse_creation_date;
/// assert_eq!(parse_creation_date("Wed Jun 14 10:00:58 GMT+02:00 2023"), Some(1_686_729_658_000));
/// assert_eq!(parse_creation_date("yesterday"), None);
/// ```
pub fn parse_creation_date(text: &str) -> Option<TimestampMs> {
    let parts: Vec<&str> = text.split_whitespace().collect();
    let [_, month, day, clock, zone, year] = parts.as_slice() else {
        return None;
    };
    const MONTHS: [&str; 12] = [
        "Jan", "Feb", "Mar", "Apr", "May", "Jun", "Jul", "Aug", "Sep", "Oct", "Nov", "Dec",
    ];
    let m = MONTHS.iter().position(|x| x == month)? as i64 + 1;
    let d: i64 = day.parse().ok().filter(|d| (1..=31).contains(d))?;
    let y: i64 = year.parse().ok().filter(|y| (1970..=9999).contains(y))?;
    let hms: Vec<i64> = clock
        .split(':')
        .map(|v| v.parse().ok())
        .collect::<Option<_>>()?;
    let [h, mi, se] = hms.as_slice() else {
        return None;
    };
    if !(0..24).contains(h) || !(0..60).contains(mi) || !(0..61).contains(se) {
        return None;
    }
    let offset_min = match zone.strip_prefix("GMT").or(zone.strip_prefix("UTC")) {
        Some("") => 0,
        Some(z) => {
            let sign = match z.as_bytes().first()? {
                b'+' => 1,
                b'-' => -1,
                _ => return None,
            };
            let (oh, om) = z[1..].split_once(':').unwrap_or((&z[1..], "0"));
            let (oh, om): (i64, i64) = (oh.parse().ok()?, om.parse().ok()?);
            if oh > 14 || om > 59 {
                return None;
            }
            sign * (oh * 60 + om)
        }
        None => return None,
    };
    let seconds = days_from_civil(y, m, d) * 86_400 + h * 3600 + mi * 60 + se - offset_min * 60;
    Some(seconds * 1000)
}

/// Sensor streams with a SensorTimestamp, in the order of [`Parser::clocks`].
#[derive(Clone, Copy)]
enum Stream {
    Acce = 0,
    Gyro = 1,
    Magn = 2,
    Ahrs = 3,
    Pres = 4,
}

struct Parser<'l> {
    limits: &'l Limits,
    path: PathBuf,
    walk: Walk,
    report: ParseReport,
    ground_truth: Vec<GroundTruthPoint>,
    /// Per stream, per sample in push order: (AppTs s, SensorTs s).
    clocks: [Vec<(f64, f64)>; 5],
    /// The AppTs text of the scan being filled (consecutive WIFI lines).
    open_scan: Option<String>,
    records_seen: usize,
    memory: u64,
}

fn parse_accuracy(v: Option<&&str>) -> Result<i8, SkipKind> {
    match v.map(|s| s.trim()) {
        None | Some("") => Ok(-1),
        Some(s) => s.parse::<i8>().map_err(|_| SkipKind::BadNumber),
    }
}

fn parse_int(s: &str) -> Result<i64, SkipKind> {
    s.trim().parse::<i64>().map_err(|_| SkipKind::BadNumber)
}

fn parse_seconds(s: &str) -> Result<f64, SkipKind> {
    let v = parse_f64(s).map_err(|_| SkipKind::BadTime)?;
    if (v * 1000.0).abs() <= MAX_ABS_TIME_MS as f64 {
        Ok(v)
    } else {
        Err(SkipKind::BadTime)
    }
}

impl<'l> Parser<'l> {
    fn new(path: &Path, id: &str, limits: &'l Limits) -> Self {
        let mut walk = Walk::default();
        walk.meta.id = id.to_string();
        walk.meta.route = route_of(id);
        Self {
            limits,
            path: path.to_path_buf(),
            walk,
            report: ParseReport::default(),
            ground_truth: Vec::new(),
            clocks: Default::default(),
            open_scan: None,
            records_seen: 0,
            memory: 0,
        }
    }

    fn skip(&mut self, kind: SkipKind, line: usize) {
        let entry = self.report.skipped.entry(kind).or_default();
        entry.count += 1;
        if entry.first_lines.len() < self.limits.report_first_lines {
            entry.first_lines.push(line);
            tracing::debug!(file = %self.path.display(), line, kind = kind.label(), "skipped logfile line");
        }
    }

    fn header(&mut self, line: &str) {
        self.report.header_lines += 1;
        let body = line.trim_start_matches('%').trim();
        let Some((key, value)) = body.split_once(':') else {
            return;
        };
        let value = Some(value.trim().to_string()).filter(|v| !v.is_empty());
        let meta = &mut self.walk.meta;
        match key.trim() {
            "Date of creation" => {
                meta.start_time = value.as_deref().and_then(parse_creation_date);
            }
            "Manufacturer" => meta.brand = value,
            "Model" => meta.model = value,
            "Android version Release" => meta.android = value,
            _ => {}
        }
    }

    fn line(&mut self, line: &str, line_no: usize) -> Result<(), IoError> {
        self.records_seen += 1;
        if self.records_seen > self.limits.max_records {
            return Err(IoError::TooManyRecords {
                path: self.path.clone(),
                line: line_no,
                limit: self.limits.max_records,
            });
        }
        let mut fields: Vec<&str> = line.split(';').collect();
        // A trailing `;` (WIFI lines end with one) leaves an empty last field.
        if fields.len() > 2 && fields.last().is_some_and(|f| f.trim().is_empty()) {
            fields.pop();
        }
        let ty = fields[0].trim();
        if ty != "WIFI" {
            self.open_scan = None;
        }
        let result = match ty {
            "ACCE" | "GYRO" | "MAGN" => self.vec3(ty, &fields),
            "AHRS" => self.ahrs(&fields),
            "PRES" => self.pressure(&fields),
            "WIFI" => self.wifi(&fields, line_no),
            "BLE4" => self.beacon(&fields),
            "POSI" => self.posi(&fields),
            _ if IGNORED_TYPES.contains(&ty) => {
                *self.report.ignored.entry(ty.to_string()).or_default() += 1;
                return Ok(());
            }
            _ => {
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
            }
        };
        match result {
            Ok(bytes) => {
                *self.report.records.entry(ty.to_string()).or_default() += 1;
                self.memory = self.memory.saturating_add(bytes as u64);
                if self.memory > self.limits.max_walk_memory_bytes {
                    return Err(IoError::LimitExceeded {
                        path: self.path.clone(),
                        what: format!("line {line_no}: parsed walk memory"),
                        limit: "max_walk_memory_bytes",
                        max: self.limits.max_walk_memory_bytes,
                    });
                }
            }
            Err(Ok(kind)) => {
                if ty == "WIFI" {
                    // A bad line ends the scan: the next good line starts a new one.
                    self.open_scan = None;
                }
                self.skip(kind, line_no)
            }
            Err(Err(e)) => return Err(e),
        }
        Ok(())
    }

    /// The two clocks of a sensor line (`fields[1]`, `fields[2]`).
    fn clocks_of(fields: &[&str]) -> Result<(f64, f64), SkipKind> {
        Ok((parse_seconds(fields[1])?, parse_seconds(fields[2])?))
    }

    fn vec3(&mut self, ty: &str, f: &[&str]) -> Result<usize, Result<SkipKind, IoError>> {
        check_count(f.len(), 6, 7).map_err(Ok)?;
        let (stream, max) = match ty {
            "ACCE" => (Stream::Acce, MAX_ABS_ACCELERATION),
            "GYRO" => (Stream::Gyro, MAX_ABS_ROTATION_RATE),
            _ => (Stream::Magn, MAX_ABS_MAGNETIC_FIELD),
        };
        let clocks = Self::clocks_of(f).map_err(Ok)?;
        let v = parse_vec3(&f[3..6]).map_err(Ok)?;
        in_range(&v, max).map_err(Ok)?;
        let sample = Vec3Sample {
            t: 0,
            v,
            accuracy: parse_accuracy(f.get(6)).map_err(Ok)?,
        };
        let imu = &mut self.walk.imu;
        match stream {
            Stream::Acce => imu.accelerometer.push(sample),
            Stream::Gyro => imu.gyroscope.push(sample),
            _ => imu.magnetometer.push(sample),
        }
        self.clocks[stream as usize].push(clocks);
        Ok(std::mem::size_of::<Vec3Sample>() + 16)
    }

    fn ahrs(&mut self, f: &[&str]) -> Result<usize, Result<SkipKind, IoError>> {
        check_count(f.len(), 9, 10).map_err(Ok)?;
        let clocks = Self::clocks_of(f).map_err(Ok)?;
        let angles = parse_vec3(&f[3..6]).map_err(Ok)?;
        in_range(&angles, 360.0).map_err(Ok)?;
        let v = parse_vec3(&f[6..9]).map_err(Ok)?;
        in_range(&v, MAX_ABS_ROTATION_VECTOR).map_err(Ok)?;
        self.walk.imu.rotation_vector.push(RotationVectorSample {
            t: 0,
            v,
            accuracy: parse_accuracy(f.get(9)).map_err(Ok)?,
        });
        self.clocks[Stream::Ahrs as usize].push(clocks);
        Ok(std::mem::size_of::<RotationVectorSample>() + 16)
    }

    fn pressure(&mut self, f: &[&str]) -> Result<usize, Result<SkipKind, IoError>> {
        check_count(f.len(), 4, 5).map_err(Ok)?;
        let clocks = Self::clocks_of(f).map_err(Ok)?;
        let hpa = parse_f64(f[3]).map_err(Ok)?;
        if !(PRESSURE_RANGE_HPA.0..=PRESSURE_RANGE_HPA.1).contains(&hpa) {
            return Err(Ok(SkipKind::OutOfRange));
        }
        parse_accuracy(f.get(4)).map_err(Ok)?;
        self.walk.pressure.push(PressureSample { t: 0, hpa });
        self.clocks[Stream::Pres as usize].push(clocks);
        Ok(std::mem::size_of::<PressureSample>() + 16)
    }

    fn wifi(&mut self, f: &[&str], line_no: usize) -> Result<usize, Result<SkipKind, IoError>> {
        // An SSID may hold `;`: BSSID, frequency and RSS are counted from the end.
        if f.len() < 7 {
            return Err(Ok(SkipKind::MissingFields));
        }
        let n = f.len();
        let t = seconds_to_ms(f[1]).ok_or(Ok(SkipKind::BadTime))?;
        let bssid: Bssid = f[n - 3]
            .trim()
            .parse()
            .map_err(|_| Ok(SkipKind::BadBssid))?;
        let frequency = u32::try_from(parse_int(f[n - 2]).map_err(Ok)?)
            .map_err(|_| Ok(SkipKind::OutOfRange))?;
        let rssi = parse_f64(f[n - 1]).map_err(Ok)?;
        if !(RSSI_RANGE_DBM.0..=RSSI_RANGE_DBM.1).contains(&rssi) {
            return Err(Ok(SkipKind::OutOfRange));
        }
        let ssid = f[3..n - 3].join(";");
        let bytes = std::mem::size_of::<WifiEntry>() + ssid.len();
        let entry = WifiEntry::new(bssid, rssi)
            .with_ssid(ssid)
            .with_frequency_mhz(frequency);
        let app_ts = f[1].trim();
        if self.open_scan.as_deref() == Some(app_ts)
            && let Some(scan) = self.walk.wifi.last_mut()
        {
            if scan.entries.len() >= self.limits.max_scan_entries {
                return Err(Err(IoError::ScanTooLarge {
                    path: self.path.clone(),
                    line: line_no,
                    t,
                    limit: self.limits.max_scan_entries,
                }));
            }
            scan.entries.push(entry);
            return Ok(bytes);
        }
        self.open_scan = Some(app_ts.to_string());
        self.walk.wifi.push(WifiScan {
            t,
            entries: vec![entry],
        });
        Ok(bytes + std::mem::size_of::<WifiScan>())
    }

    fn beacon(&mut self, f: &[&str]) -> Result<usize, Result<SkipKind, IoError>> {
        if f.len() < 5 {
            return Err(Ok(SkipKind::MissingFields));
        }
        let t = seconds_to_ms(f[1]).ok_or(Ok(SkipKind::BadTime))?;
        let rssi = parse_f64(f[4]).map_err(Ok)?;
        if !(RSSI_RANGE_DBM.0..=RSSI_RANGE_DBM.1).contains(&rssi) {
            return Err(Ok(SkipKind::OutOfRange));
        }
        let mac = f[3].trim().to_string();
        let sample = match f[2].trim() {
            "iBeacon" => {
                check_count(f.len(), 9, 9).map_err(Ok)?;
                BeaconSample {
                    t,
                    uuid: f[8].trim().to_string(),
                    major: f[6].trim().to_string(),
                    minor: f[7].trim().to_string(),
                    tx_power: Some(parse_f64(f[5]).map_err(Ok)?),
                    rssi_dbm: rssi,
                    distance: None,
                    mac,
                    seen_ms: None,
                }
            }
            "Eddystone" => {
                check_count(f.len(), 6, 10).map_err(Ok)?;
                BeaconSample {
                    t,
                    uuid: f[5].trim().to_string(),
                    major: String::new(),
                    minor: String::new(),
                    tx_power: None,
                    rssi_dbm: rssi,
                    distance: None,
                    mac,
                    seen_ms: None,
                }
            }
            _ => return Err(Ok(SkipKind::UnknownType)),
        };
        let bytes = std::mem::size_of::<BeaconSample>() + sample.uuid.len() + sample.mac.len();
        self.walk.beacons.push(sample);
        Ok(bytes)
    }

    fn posi(&mut self, f: &[&str]) -> Result<usize, Result<SkipKind, IoError>> {
        check_count(f.len(), 7, 7).map_err(Ok)?;
        let t = seconds_to_ms(f[1]).ok_or(Ok(SkipKind::BadTime))?;
        let counter = parse_int(f[2]).map_err(Ok)?;
        let lat = parse_f64(f[3]).map_err(Ok)?;
        let lon = parse_f64(f[4]).map_err(Ok)?;
        if lat.abs() > 89.0 || lon.abs() > 180.0 {
            return Err(Ok(SkipKind::OutOfRange));
        }
        let floor = i32::try_from(parse_int(f[5]).map_err(Ok)?)
            .ok()
            .filter(|v| v.abs() <= MAX_ABS_FLOOR)
            .ok_or(Ok(SkipKind::OutOfRange))?;
        let building =
            i32::try_from(parse_int(f[6]).map_err(Ok)?).map_err(|_| Ok(SkipKind::OutOfRange))?;
        self.ground_truth.push(GroundTruthPoint {
            t,
            counter,
            lat_deg: lat,
            lon_deg: lon,
            floor,
            building,
        });
        Ok(std::mem::size_of::<GroundTruthPoint>())
    }

    fn finish(mut self) -> ParsedLogfile {
        // Sensor times: SensorTs moved onto the app clock by the stream's median offset.
        let imu = &mut self.walk.imu;
        let mut outliers = 0usize;
        {
            let mut place = |clocks: &[(f64, f64)], times: &mut dyn FnMut(usize, i64)| {
                let mut offsets: Vec<f64> = clocks.iter().map(|(a, s)| a - s).collect();
                offsets.sort_by(f64::total_cmp);
                let Some(&median) = offsets.get(offsets.len() / 2) else {
                    return;
                };
                for (i, &(app, sensor)) in clocks.iter().enumerate() {
                    let on_app = sensor + median;
                    let s = if (on_app - app).abs() <= SENSOR_CLOCK_TOLERANCE_S {
                        on_app
                    } else {
                        outliers += 1;
                        app
                    };
                    let ms = (s * 1000.0).round();
                    let ms = if ms.abs() <= MAX_ABS_TIME_MS as f64 {
                        ms as i64
                    } else {
                        // `app` passed the same bound when it was parsed.
                        outliers += 1;
                        (app * 1000.0).round() as i64
                    };
                    times(i, ms);
                }
            };
            place(&self.clocks[Stream::Acce as usize], &mut |i, t| {
                imu.accelerometer[i].t = t
            });
            place(&self.clocks[Stream::Gyro as usize], &mut |i, t| {
                imu.gyroscope[i].t = t
            });
            place(&self.clocks[Stream::Magn as usize], &mut |i, t| {
                imu.magnetometer[i].t = t
            });
            place(&self.clocks[Stream::Ahrs as usize], &mut |i, t| {
                imu.rotation_vector[i].t = t
            });
            let pressure = &mut self.walk.pressure;
            place(&self.clocks[Stream::Pres as usize], &mut |i, t| {
                pressure[i].t = t
            });
        }
        self.report.sensor_clock_outliers = outliers;
        for scan in &mut self.walk.wifi {
            self.report.duplicate_bssids_removed += scan.dedup_keep_most_recent();
        }
        self.walk.sort_streams();
        self.ground_truth.sort_by_key(|g| g.t);
        let before = self.ground_truth.len();
        self.ground_truth.dedup_by_key(|g| g.t);
        let duplicates = before - self.ground_truth.len();
        if duplicates > 0 {
            tracing::warn!(file = %self.path.display(), duplicates, "POSI points sharing a time with an earlier one skipped");
            self.report
                .skipped
                .entry(SkipKind::DuplicateWaypoint)
                .or_default()
                .count += duplicates;
            if let Some(c) = self.report.records.get_mut("POSI") {
                *c = c.saturating_sub(duplicates);
            }
        }
        if let Some(g) = self.ground_truth.first() {
            self.walk.meta.site_id = Some(g.building.to_string());
        }
        ParsedLogfile {
            walk: self.walk,
            ground_truth: self.ground_truth,
            report: self.report,
        }
    }
}

fn parse<R: BufRead>(
    reader: R,
    path: &Path,
    id: &str,
    limits: &Limits,
) -> Result<ParsedLogfile, IoError> {
    let mut parser = Parser::new(path, id, limits);
    for_each_line(reader, path, limits, |line, line_no| {
        parser.report.lines += 1;
        if line.trim().is_empty() {
            parser.skip(SkipKind::Blank, line_no);
            parser.open_scan = None;
        } else if line.starts_with('%') {
            parser.header(line);
        } else {
            parser.line(line, line_no)?;
        }
        Ok(())
    })?;
    Ok(parser.finish())
}

/// Writes a walk as a GetSensorData logfile (for fixtures and round trips through
/// [`read_logfile_from`]): a `%` header with the phone, `ACCE`/`GYRO`/`MAGN`/`AHRS` (the
/// rotation vector as the quaternion's vector part, angles from it), `PRES`, `WIFI` (one line
/// per entry, all with the scan's AppTimestamp), `BLE4` iBeacon lines and `POSI` (waypoints
/// placed in degrees by `frame`, floor 0 where unknown, building `building`), in time order.
/// Times are written in seconds with millisecond digits; SensorTimestamp = AppTimestamp +
/// 1000 s. Non-finite values are refused (`InvalidInput`).
///
/// ```
/// use wipdr_core::{GeoFrame, Point2, Walk, Waypoint};
/// use wipdr_io::logfile::{read_logfile_from, write_logfile};
/// let frame = GeoFrame::new(49.46, 11.11)?;
/// let mut walk = Walk::default();
/// walk.waypoints.push(Waypoint::new(61_000, Point2::new(3.0, 4.0)).on_floor(-2));
/// let mut text = Vec::new();
/// write_logfile(&walk, &frame, 100, &mut text)?;
/// let back = read_logfile_from(&text[..], "w", &Default::default())?.into_walk(&frame).walk;
/// assert_eq!(back.waypoints[0].floor, Some(-2));
/// assert!((back.waypoints[0].position - Point2::new(3.0, 4.0)).norm() < 1e-6);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn write_logfile(
    walk: &Walk,
    frame: &GeoFrame,
    building: i32,
    out: &mut impl io::Write,
) -> io::Result<()> {
    use wipdr_core::walk::Record;
    let finite = |v: &[f64], what: &str| -> io::Result<()> {
        if v.iter().all(|x| x.is_finite()) {
            Ok(())
        } else {
            Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("non-finite {what} value"),
            ))
        }
    };
    let s = |t: TimestampMs| t as f64 / 1000.0;
    let meta = &walk.meta;
    writeln!(out, "% LogFile created by wipdr (GetSensorData format)")?;
    writeln!(
        out,
        "% Manufacturer:            \t{}",
        meta.brand.as_deref().unwrap_or("wipdr")
    )?;
    writeln!(
        out,
        "% Model:                   \t{}",
        meta.model.as_deref().unwrap_or("sim")
    )?;
    writeln!(
        out,
        "% POSI Reference:    \t\t'POSI;Timestamp(s);Counter;Latitude(degrees); Longitude(degrees);floor ID(0,1,2..4);Building ID(0,1,2..3);'"
    )?;
    let mut counter = 0;
    for record in walk.replay() {
        match record {
            Record::Accelerometer(v) | Record::Gyroscope(v) | Record::Magnetometer(v) => {
                finite(&v.v, "IMU")?;
                let ty = match record {
                    Record::Accelerometer(_) => "ACCE",
                    Record::Gyroscope(_) => "GYRO",
                    _ => "MAGN",
                };
                writeln!(
                    out,
                    "{ty};{:.3};{:.3};{:?};{:?};{:?};{}",
                    s(v.t),
                    s(v.t) + 1000.0,
                    v.v[0],
                    v.v[1],
                    v.v[2],
                    v.accuracy.max(0)
                )?;
            }
            Record::RotationVector(r) => {
                finite(&r.v, "rotation vector")?;
                let [w, x, y, z] = r.quaternion();
                let pitch = (2.0 * (w * x + y * z)).atan2(1.0 - 2.0 * (x * x + y * y));
                let roll = (2.0 * (w * y - z * x)).clamp(-1.0, 1.0).asin();
                let yaw = (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z));
                writeln!(
                    out,
                    "AHRS;{:.3};{:.3};{:.6};{:.6};{:.6};{:?};{:?};{:?};{}",
                    s(r.t),
                    s(r.t) + 1000.0,
                    pitch.to_degrees(),
                    roll.to_degrees(),
                    yaw.to_degrees(),
                    r.v[0],
                    r.v[1],
                    r.v[2],
                    r.accuracy.max(0)
                )?;
            }
            Record::Pressure(p) => {
                finite(&[p.hpa], "pressure")?;
                writeln!(
                    out,
                    "PRES;{:.3};{:.3};{:?};3",
                    s(p.t),
                    s(p.t) + 1000.0,
                    p.hpa
                )?;
            }
            Record::Wifi(scan) => {
                for e in &scan.entries {
                    finite(&[e.rssi_dbm], "RSSI")?;
                    writeln!(
                        out,
                        "WIFI;{:.3};{:.3};{};{};{};{}",
                        s(scan.t),
                        s(scan.t) + 1000.0,
                        e.ssid.replace([';', '\n', '\r'], " "),
                        e.bssid,
                        e.frequency_mhz,
                        e.rssi_dbm
                    )?;
                }
            }
            Record::Beacon(b) => {
                finite(&[b.rssi_dbm], "beacon RSSI")?;
                writeln!(
                    out,
                    "BLE4;{:.3};iBeacon;{};{};{};{};{};{}",
                    s(b.t),
                    b.mac.replace(';', " "),
                    b.rssi_dbm,
                    b.tx_power.unwrap_or(-59.0),
                    b.major.replace(';', " "),
                    b.minor.replace(';', " "),
                    b.uuid.replace(';', " ")
                )?;
            }
            Record::Waypoint(w) => {
                finite(&[w.position.x, w.position.y], "waypoint")?;
                counter += 1;
                let (lat, lon) = frame.to_lat_lon(w.position);
                writeln!(
                    out,
                    "POSI;{:.3};{counter};{lat:.12};{lon:.12};{};{building}",
                    s(w.t),
                    w.floor.unwrap_or(0)
                )?;
            }
            Record::AccelerometerUncalibrated(_)
            | Record::GyroscopeUncalibrated(_)
            | Record::MagnetometerUncalibrated(_) => {}
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &str) -> ParsedLogfile {
        read_logfile_from(text.as_bytes(), "t", &Limits::default()).unwrap()
    }

    #[test]
    fn header_lines_are_not_records() {
        let log = read(
            "% POSI Reference:  'POSI;Timestamp(s);Counter;Latitude(degrees)'\n% Model: \tSM-A520F\n",
        );
        assert!(log.ground_truth.is_empty());
        assert_eq!(log.report.header_lines, 2);
        assert_eq!(log.walk.meta.model.as_deref(), Some("SM-A520F"));
    }

    #[test]
    fn sensor_clock_sets_intervals_and_app_clock_sets_the_offset() {
        // AppTs jitters (10, 35, 41 ms apart); SensorTs is regular at 20 ms.
        let log = read(
            "ACCE;1.000;500.000;0;0;9.8;3\nACCE;1.010;500.020;0;0;9.8;3\nACCE;1.045;500.040;0;0;9.8;3\nACCE;1.086;500.060;0;0;9.8;3\n",
        );
        let t: Vec<i64> = log.walk.imu.accelerometer.iter().map(|s| s.t).collect();
        assert_eq!(t[1] - t[0], 20);
        assert_eq!(t[3] - t[2], 20);
        // Median offset app - sensor = 500.990 - ... sorted offsets: -499.0, -499.01, -498.995, -498.974.
        assert!((t[0] - 1000).abs() <= 30, "{t:?}");
        assert_eq!(log.report.sensor_clock_outliers, 0);
    }

    #[test]
    fn a_sensor_clock_jump_keeps_the_app_time_and_is_counted() {
        let log =
            read("GYRO;1.00;500.00;0;0;0;3\nGYRO;1.02;500.02;0;0;0;3\nGYRO;1.04;900.04;0;0;0;3\n");
        assert_eq!(log.report.sensor_clock_outliers, 1);
        assert_eq!(log.walk.imu.gyroscope[2].t, 1040);
    }

    #[test]
    fn consecutive_wifi_lines_of_one_app_time_are_one_scan() {
        let log = read(
            "WIFI;1.0;9;a;20:23:00:00:00:01;2437;-60;\nWIFI;1.0;9;a;b;20:23:00:00:00:02;2437;-61\nACCE;1.1;9.1;0;0;9.8;3\nWIFI;1.0;9;c;20:23:00:00:00:03;2437;-62\nWIFI;5.0;9;c;20:23:00:00:00:03;2437;-62\n",
        );
        assert_eq!(log.walk.wifi.len(), 3);
        assert_eq!(log.walk.wifi[0].entries.len(), 2);
        assert_eq!(log.walk.wifi[0].entries[1].ssid, "a;b");
        assert_eq!(log.walk.wifi[0].entries[0].frequency_mhz, 2437);
    }

    #[test]
    fn bad_lines_are_counted_by_kind() {
        let log = read(
            "ACCE;x;1;0;0;9.8;3\nACCE;1;1;0;0\nWIFI;1;1;s;zz;2437;-60\nPRES;1;1;5000;3\nPOSI;1;1;95;11;0;100\nPOSI;1;1;49;11;9999;100\nFOO;1\nWIFI;2;1;s;20:23:00:00:00:01;2437;-60\n",
        );
        assert_eq!(log.report.skipped_of(SkipKind::BadTime), 1);
        assert_eq!(log.report.skipped_of(SkipKind::MissingFields), 1);
        assert_eq!(log.report.skipped_of(SkipKind::BadBssid), 1);
        assert_eq!(log.report.skipped_of(SkipKind::OutOfRange), 3);
        assert_eq!(log.report.skipped_of(SkipKind::UnknownType), 1);
        assert_eq!(log.walk.wifi.len(), 1);
    }

    #[test]
    fn posi_becomes_waypoints_with_floors_in_a_frame() {
        let log = read("POSI;10;1;49.4612;11.1110;-2;100\nPOSI;5;2;49.4611;11.1109;0;100\n");
        assert_eq!(log.walk.meta.site_id.as_deref(), Some("100"));
        let frame = GeoFrame::new(49.4611, 11.1109).unwrap();
        let walk = log.into_walk(&frame).walk;
        assert_eq!(walk.waypoints.len(), 2);
        assert_eq!(walk.waypoints[0].t, 5_000);
        assert_eq!(walk.waypoints[0].floor, Some(0));
        assert_eq!(walk.waypoints[1].floor, Some(-2));
        assert!((walk.waypoints[1].position.y - 11.12).abs() < 0.01);
    }

    #[test]
    fn limits_are_typed_errors() {
        let limits = Limits {
            max_line_bytes: 16,
            ..Limits::default()
        };
        let e = read_logfile_from(
            "ACCE;1;1;0;0;9.8;3;padding-padding\n".as_bytes(),
            "t",
            &limits,
        )
        .unwrap_err();
        assert!(matches!(e, IoError::LineTooLong { line: 1, .. }), "{e}");
    }
}

//! The plain sample stream: a phone log in the simplest form a user's own logger can write,
//! as CSV or as JSON lines, read into a [`Walk`] (no waypoints: it is positioned, not scored).
//!
//! ## CSV (`.csv`, optionally gzipped)
//!
//! A header line `t_ms,sensor,a,b,c,d`, then one sample per line (`#` lines are comments,
//! except the two metadata lines below). `t_ms` is the sample time in milliseconds on the
//! stream's clock (any origin, non-decreasing per sensor is not required: every stream is
//! sorted after reading).
//!
//! | `sensor` | `a, b, c, d` | unit |
//! | --- | --- | --- |
//! | `accelerometer` | x, y, z | m/s², phone frame, with gravity |
//! | `gyroscope` | x, y, z | rad/s |
//! | `magnetometer` | x, y, z | µT |
//! | `rotation_vector` | x, y, z (Android's vector part) | unit quaternion |
//! | `pressure` | hPa | hPa |
//! | `wifi` | BSSID (`aa:bb:cc:dd:ee:ff`), RSSI dBm, last seen ms (optional) | dBm |
//!
//! Consecutive `wifi` lines with the same `t_ms` form one scan. Metadata (optional, before
//! the first sample): `# phone_model: Pixel 7` and `# start_unix_ms: 1700000000000` (the
//! Unix time of `t_ms` 0): with both, a site model's barometric references of the same phone
//! model are used for the floor.
//!
//! ```text
//! t_ms,sensor,a,b,c,d
//! # phone_model: Pixel 7
//! 0,accelerometer,0.12,0.30,9.79,
//! 0,rotation_vector,0.01,0.02,0.70,
//! 20,gyroscope,0.001,-0.002,0.010,
//! 500,wifi,aa:bb:cc:dd:ee:01,-61,
//! 500,wifi,aa:bb:cc:dd:ee:02,-74,480
//! 1000,pressure,1009.42,,,
//! ```
//!
//! ## JSON lines (`.jsonl`, `.ndjson`, optionally gzipped)
//!
//! One object per line, tagged by `sensor`: `{"t_ms":0,"sensor":"accelerometer","x":0.12,
//! "y":0.3,"z":9.79}`, `{"t_ms":1000,"sensor":"pressure","hpa":1009.42}`,
//! `{"t_ms":500,"sensor":"wifi","aps":[{"bssid":"aa:bb:cc:dd:ee:01","rssi_dbm":-61}]}`
//! (`last_seen_ms` optional per AP), and optionally a first line
//! `{"sensor":"meta","phone_model":"Pixel 7","start_unix_ms":1700000000000}`. The same
//! objects are the sample batches of `wipdr serve`'s API.
//!
//! Every value is checked: a non-finite number, an unknown sensor, a missing field or a bad
//! BSSID is an [`IoError::BadSample`] naming the file, the line and the field; the reader's
//! [`Limits`] bound the line length, the input and the record count.

mod de;

use crate::{IoError, Limits};
use serde::{Deserialize, Serialize};
use std::io::{BufRead, BufReader, Read};
use std::path::Path;
use wipdr_core::{
    Bssid, PressureSample, RotationVectorSample, TimestampMs, Vec3Sample, Walk, WifiEntry, WifiScan,
};

/// One access point of a `wifi` sample.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlainAp {
    /// BSSID, `aa:bb:cc:dd:ee:ff`.
    pub bssid: String,
    /// RSSI, dBm.
    pub rssi_dbm: f64,
    /// When the phone last heard it, ms on the stream's clock (default: the scan time).
    #[serde(default)]
    pub last_seen_ms: Option<TimestampMs>,
}

/// One sample of the plain stream format (one JSON line; one CSV line, or several `wifi`
/// lines for a scan).
/// Read from JSON by a hand-written `Deserialize` (`sample_stream/de.rs`, the derive's
/// checks without its buffering).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "sensor", rename_all = "snake_case")]
pub enum PlainSample {
    /// Stream metadata (first line only).
    Meta {
        /// Phone model (for barometric references).
        #[serde(default)]
        phone_model: Option<String>,
        /// Unix ms of `t_ms` 0.
        #[serde(default)]
        start_unix_ms: Option<TimestampMs>,
    },
    /// Accelerometer, m/s².
    Accelerometer {
        /// Time, ms.
        t_ms: TimestampMs,
        /// x.
        x: f64,
        /// y.
        y: f64,
        /// z.
        z: f64,
    },
    /// Gyroscope, rad/s.
    Gyroscope {
        /// Time, ms.
        t_ms: TimestampMs,
        /// x.
        x: f64,
        /// y.
        y: f64,
        /// z.
        z: f64,
    },
    /// Magnetometer, µT.
    Magnetometer {
        /// Time, ms.
        t_ms: TimestampMs,
        /// x.
        x: f64,
        /// y.
        y: f64,
        /// z.
        z: f64,
    },
    /// Rotation vector (Android's vector part of the unit quaternion).
    RotationVector {
        /// Time, ms.
        t_ms: TimestampMs,
        /// x.
        x: f64,
        /// y.
        y: f64,
        /// z.
        z: f64,
    },
    /// Barometer, hPa.
    Pressure {
        /// Time, ms.
        t_ms: TimestampMs,
        /// Pressure, hPa.
        hpa: f64,
    },
    /// A Wi-Fi scan.
    Wifi {
        /// Scan time, ms.
        t_ms: TimestampMs,
        /// The APs heard.
        aps: Vec<PlainAp>,
    },
}

/// Why a plain sample is invalid: the field and what is wrong.
pub type SampleProblem = (String, String);

fn finite(field: &str, v: f64) -> Result<f64, SampleProblem> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err((field.into(), format!("must be a finite number, got {v}")))
    }
}

/// Largest |time| accepted, ms (about 300 years: beyond it a time is a unit mistake).
pub const MAX_ABS_TIME_MS: TimestampMs = 10_000_000_000_000;

fn time(t: TimestampMs) -> Result<TimestampMs, SampleProblem> {
    if t.abs() <= MAX_ABS_TIME_MS {
        Ok(t)
    } else {
        Err((
            "t_ms".into(),
            format!("{t} is out of range (|t_ms| <= {MAX_ABS_TIME_MS})"),
        ))
    }
}

fn vec3(t: TimestampMs, x: f64, y: f64, z: f64) -> Result<Vec3Sample, SampleProblem> {
    Ok(Vec3Sample {
        t: time(t)?,
        v: [finite("x", x)?, finite("y", y)?, finite("z", z)?],
        accuracy: 3,
    })
}

impl PlainSample {
    /// The sample's time (`None` for metadata).
    pub fn t_ms(&self) -> Option<TimestampMs> {
        match self {
            Self::Meta { .. } => None,
            Self::Accelerometer { t_ms, .. }
            | Self::Gyroscope { t_ms, .. }
            | Self::Magnetometer { t_ms, .. }
            | Self::RotationVector { t_ms, .. }
            | Self::Pressure { t_ms, .. }
            | Self::Wifi { t_ms, .. } => Some(*t_ms),
        }
    }

    /// Checks the sample and appends it to `walk`'s streams (a `wifi` sample is one scan;
    /// metadata sets the walk's phone model and start time).
    pub fn add_to(&self, walk: &mut Walk) -> Result<(), SampleProblem> {
        match self {
            Self::Meta {
                phone_model,
                start_unix_ms,
            } => {
                if let Some(m) = phone_model {
                    walk.meta.model = Some(m.clone());
                }
                if let Some(t) = start_unix_ms {
                    walk.meta.start_time = Some(time(*t)?);
                }
            }
            Self::Accelerometer { t_ms, x, y, z } => {
                walk.imu.accelerometer.push(vec3(*t_ms, *x, *y, *z)?)
            }
            Self::Gyroscope { t_ms, x, y, z } => walk.imu.gyroscope.push(vec3(*t_ms, *x, *y, *z)?),
            Self::Magnetometer { t_ms, x, y, z } => {
                walk.imu.magnetometer.push(vec3(*t_ms, *x, *y, *z)?)
            }
            Self::RotationVector { t_ms, x, y, z } => {
                let v = vec3(*t_ms, *x, *y, *z)?;
                walk.imu.rotation_vector.push(RotationVectorSample {
                    t: v.t,
                    v: v.v,
                    accuracy: 3,
                })
            }
            Self::Pressure { t_ms, hpa } => walk.pressure.push(PressureSample {
                t: time(*t_ms)?,
                hpa: finite("hpa", *hpa)?,
            }),
            Self::Wifi { t_ms, aps } => {
                let t = time(*t_ms)?;
                let mut entries = Vec::with_capacity(aps.len());
                for (i, ap) in aps.iter().enumerate() {
                    let bssid: Bssid = ap.bssid.parse().map_err(|_| {
                        (
                            format!("aps[{i}].bssid"),
                            format!("{:?} is not a BSSID (aa:bb:cc:dd:ee:ff)", ap.bssid),
                        )
                    })?;
                    let rssi = finite(&format!("aps[{i}].rssi_dbm"), ap.rssi_dbm)?;
                    if !(-150.0..=20.0).contains(&rssi) {
                        return Err((
                            format!("aps[{i}].rssi_dbm"),
                            format!("{rssi} dBm is out of range [-150, 20]"),
                        ));
                    }
                    let seen = time(ap.last_seen_ms.unwrap_or(t))?;
                    entries.push(WifiEntry::new(bssid, rssi).seen_at(seen));
                }
                let mut scan = WifiScan { t, entries };
                scan.dedup_keep_most_recent();
                walk.wifi.push(scan);
            }
        }
        Ok(())
    }
}

/// Whether `path` names a plain sample stream (`.csv`, `.jsonl`, `.ndjson`, optionally
/// `.gz`).
pub fn is_sample_stream(path: &Path) -> bool {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let name = name.strip_suffix(".gz").unwrap_or(&name);
    name.ends_with(".csv") || name.ends_with(".jsonl") || name.ends_with(".ndjson")
}

/// Reads a plain sample stream (CSV or JSON lines by the file name; see the
/// [module docs](self)) into a walk whose id is the file name without its extensions.
pub fn read_sample_stream(path: impl AsRef<Path>, limits: &Limits) -> Result<Walk, IoError> {
    let path = path.as_ref();
    let file = std::fs::File::open(path).map_err(|source| IoError::File {
        path: path.to_path_buf(),
        source,
    })?;
    let gz = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gz"));
    let raw: Box<dyn Read> = if gz {
        Box::new(flate2::read::MultiGzDecoder::new(BufReader::new(file)))
    } else {
        Box::new(file)
    };
    let reader = BufReader::new(raw.take(limits.max_input_bytes.saturating_add(1)));
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let json = name.contains(".jsonl") || name.contains(".ndjson");
    let mut walk = read_from(reader, path, limits, json)?;
    walk.meta.id = stream_id_of(path);
    Ok(walk)
}

/// The id of a stream file: its name without `.gz` and its format extension.
pub fn stream_id_of(path: &Path) -> String {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let name = name.strip_suffix(".gz").unwrap_or(&name);
    for ext in [".csv", ".jsonl", ".ndjson"] {
        if let Some(stem) = name.strip_suffix(ext) {
            return stem.to_string();
        }
    }
    name.to_string()
}

/// Reads a plain sample stream from `reader` (`path` names it in errors; `json`: JSON lines,
/// else CSV).
pub fn read_from(
    reader: impl BufRead,
    path: &Path,
    limits: &Limits,
    json: bool,
) -> Result<Walk, IoError> {
    let mut walk = Walk::default();
    let mut records = 0usize;
    let mut bytes = 0u64;
    let mut pending_scan: Option<(TimestampMs, Vec<PlainAp>, usize)> = None;
    let bad = |line: usize, (field, message): SampleProblem| IoError::BadSample {
        path: path.to_path_buf(),
        line,
        field,
        message,
    };
    let mut saw_header = json;
    for (i, line) in reader.split(b'\n').enumerate() {
        let n = i + 1;
        let line = line.map_err(|source| IoError::Read {
            path: path.to_path_buf(),
            line: i,
            source,
        })?;
        bytes += line.len() as u64 + 1;
        if bytes > limits.max_input_bytes {
            return Err(IoError::InputTooLarge {
                path: path.to_path_buf(),
                limit: limits.max_input_bytes,
            });
        }
        if line.len() > limits.max_line_bytes {
            return Err(IoError::LineTooLong {
                path: path.to_path_buf(),
                line: n,
                limit: limits.max_line_bytes,
            });
        }
        let text = String::from_utf8_lossy(&line);
        let text = text.trim();
        if text.is_empty() {
            continue;
        }
        records += 1;
        if records > limits.max_records {
            return Err(IoError::TooManyRecords {
                path: path.to_path_buf(),
                line: n,
                limit: limits.max_records,
            });
        }
        let sample = if json {
            serde_json::from_str::<PlainSample>(text)
                .map_err(|e| bad(n, ("sample".into(), e.to_string())))?
        } else {
            if let Some(comment) = text.strip_prefix('#') {
                csv_meta(comment.trim(), &mut walk).map_err(|p| bad(n, p))?;
                continue;
            }
            if !saw_header {
                if !text.starts_with("t_ms,sensor") {
                    return Err(bad(
                        n,
                        (
                            "header".into(),
                            format!("expected `t_ms,sensor,a,b,c,d`, got {text:?}"),
                        ),
                    ));
                }
                saw_header = true;
                continue;
            }
            match csv_sample(text).map_err(|p| bad(n, p))? {
                CsvLine::Sample(s) => s,
                CsvLine::Ap(t, ap) => {
                    match &mut pending_scan {
                        Some((pt, aps, _)) if *pt == t => {
                            if aps.len() >= limits.max_scan_entries {
                                return Err(IoError::ScanTooLarge {
                                    path: path.to_path_buf(),
                                    line: n,
                                    t,
                                    limit: limits.max_scan_entries,
                                });
                            }
                            aps.push(ap)
                        }
                        _ => {
                            if let Some((pt, aps, line)) = pending_scan.take() {
                                PlainSample::Wifi { t_ms: pt, aps }
                                    .add_to(&mut walk)
                                    .map_err(|p| bad(line, p))?;
                            }
                            pending_scan = Some((t, vec![ap], n));
                        }
                    }
                    continue;
                }
            }
        };
        if let PlainSample::Wifi { aps, .. } = &sample
            && aps.len() > limits.max_scan_entries
        {
            return Err(IoError::ScanTooLarge {
                path: path.to_path_buf(),
                line: n,
                t: sample.t_ms().unwrap_or_default(),
                limit: limits.max_scan_entries,
            });
        }
        if let Some((pt, aps, line)) = pending_scan.take() {
            PlainSample::Wifi { t_ms: pt, aps }
                .add_to(&mut walk)
                .map_err(|p| bad(line, p))?;
        }
        sample.add_to(&mut walk).map_err(|p| bad(n, p))?;
    }
    if let Some((pt, aps, line)) = pending_scan.take() {
        PlainSample::Wifi { t_ms: pt, aps }
            .add_to(&mut walk)
            .map_err(|p| bad(line, p))?;
    }
    if !saw_header {
        return Err(bad(
            0,
            (
                "header".into(),
                "the file is empty (no `t_ms,sensor,...` header)".into(),
            ),
        ));
    }
    walk.imu.sort();
    walk.wifi.sort_by_key(|s| s.t);
    walk.pressure.sort_by_key(|p| p.t);
    Ok(walk)
}

enum CsvLine {
    Sample(PlainSample),
    Ap(TimestampMs, PlainAp),
}

fn csv_meta(comment: &str, walk: &mut Walk) -> Result<(), SampleProblem> {
    if let Some(v) = comment.strip_prefix("phone_model:") {
        walk.meta.model = Some(v.trim().to_string());
    } else if let Some(v) = comment.strip_prefix("start_unix_ms:") {
        let t: TimestampMs = v.trim().parse().map_err(|_| {
            (
                "start_unix_ms".to_string(),
                format!("{:?} is not an integer (ms)", v.trim()),
            )
        })?;
        walk.meta.start_time = Some(time(t)?);
    }
    Ok(())
}

fn csv_sample(text: &str) -> Result<CsvLine, SampleProblem> {
    let fields: Vec<&str> = text.split(',').map(str::trim).collect();
    let get = |i: usize, name: &str| -> Result<&str, SampleProblem> {
        fields
            .get(i)
            .copied()
            .filter(|s| !s.is_empty())
            .ok_or_else(|| (name.to_string(), "missing".to_string()))
    };
    let num = |i: usize, name: &str| -> Result<f64, SampleProblem> {
        let s = get(i, name)?;
        s.parse::<f64>()
            .map_err(|_| (name.to_string(), format!("{s:?} is not a number")))
    };
    let t_text = get(0, "t_ms")?;
    let t: TimestampMs = t_text.parse().map_err(|_| {
        (
            "t_ms".to_string(),
            format!("{t_text:?} is not an integer (ms)"),
        )
    })?;
    let sensor = get(1, "sensor")?;
    let xyz = || -> Result<(f64, f64, f64), SampleProblem> {
        Ok((num(2, "x")?, num(3, "y")?, num(4, "z")?))
    };
    Ok(CsvLine::Sample(match sensor {
        "accelerometer" => {
            let (x, y, z) = xyz()?;
            PlainSample::Accelerometer { t_ms: t, x, y, z }
        }
        "gyroscope" => {
            let (x, y, z) = xyz()?;
            PlainSample::Gyroscope { t_ms: t, x, y, z }
        }
        "magnetometer" => {
            let (x, y, z) = xyz()?;
            PlainSample::Magnetometer { t_ms: t, x, y, z }
        }
        "rotation_vector" => {
            let (x, y, z) = xyz()?;
            PlainSample::RotationVector { t_ms: t, x, y, z }
        }
        "pressure" => PlainSample::Pressure {
            t_ms: t,
            hpa: num(2, "hpa")?,
        },
        "wifi" => {
            let last_seen_ms = match fields.get(4).copied().filter(|s| !s.is_empty()) {
                None => None,
                Some(s) => Some(s.parse().map_err(|_| {
                    (
                        "last_seen_ms".to_string(),
                        format!("{s:?} is not an integer (ms)"),
                    )
                })?),
            };
            return Ok(CsvLine::Ap(
                t,
                PlainAp {
                    bssid: get(2, "bssid")?.to_string(),
                    rssi_dbm: num(3, "rssi_dbm")?,
                    last_seen_ms,
                },
            ));
        }
        other => {
            return Err((
                "sensor".into(),
                format!(
                    "{other:?} is not a sensor (accelerometer, gyroscope, magnetometer, rotation_vector, pressure, wifi)"
                ),
            ));
        }
    }))
}

/// Writes `walk`'s positioning inputs (accelerometer, gyroscope, magnetometer, rotation
/// vector, pressure, Wi-Fi) as a plain CSV sample stream, in time order (at one time: the
/// order of the table in the [module docs](self)), numbers in their shortest exact form: a
/// recorded walk converted for a logger's users, or a test input. Waypoints and the other
/// streams are not written.
pub fn write_csv(walk: &Walk, out: &mut impl std::io::Write) -> std::io::Result<()> {
    writeln!(out, "t_ms,sensor,a,b,c,d")?;
    if let Some(m) = &walk.meta.model {
        writeln!(out, "# phone_model: {m}")?;
    }
    if let Some(t) = walk.meta.start_time {
        writeln!(out, "# start_unix_ms: {t}")?;
    }
    let mut rows: Vec<(TimestampMs, u8, usize)> = Vec::new();
    let imu = &walk.imu;
    rows.extend(
        imu.accelerometer
            .iter()
            .enumerate()
            .map(|(i, s)| (s.t, 0, i)),
    );
    rows.extend(imu.gyroscope.iter().enumerate().map(|(i, s)| (s.t, 1, i)));
    rows.extend(
        imu.magnetometer
            .iter()
            .enumerate()
            .map(|(i, s)| (s.t, 2, i)),
    );
    rows.extend(
        imu.rotation_vector
            .iter()
            .enumerate()
            .map(|(i, s)| (s.t, 3, i)),
    );
    rows.extend(walk.pressure.iter().enumerate().map(|(i, s)| (s.t, 4, i)));
    rows.extend(walk.wifi.iter().enumerate().map(|(i, s)| (s.t, 5, i)));
    rows.sort_unstable();
    for (t, kind, i) in rows {
        let xyz = |name: &str, v: [f64; 3]| format!("{t},{name},{},{},{},", v[0], v[1], v[2]);
        match kind {
            0 => writeln!(out, "{}", xyz("accelerometer", imu.accelerometer[i].v))?,
            1 => writeln!(out, "{}", xyz("gyroscope", imu.gyroscope[i].v))?,
            2 => writeln!(out, "{}", xyz("magnetometer", imu.magnetometer[i].v))?,
            3 => writeln!(out, "{}", xyz("rotation_vector", imu.rotation_vector[i].v))?,
            4 => writeln!(out, "{t},pressure,{},,,", walk.pressure[i].hpa)?,
            _ => {
                for e in &walk.wifi[i].entries {
                    writeln!(
                        out,
                        "{t},wifi,{},{},{}",
                        e.bssid, e.rssi_dbm, e.last_seen_ms
                    )?;
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &str, json: bool) -> Result<Walk, IoError> {
        read_from(
            text.as_bytes(),
            Path::new("s.csv"),
            &Limits::default(),
            json,
        )
    }

    #[test]
    fn csv_and_json_lines_read_the_same_walk() {
        let csv = "t_ms,sensor,a,b,c,d\n# phone_model: P7\n0,accelerometer,0.1,0.2,9.8,\n500,wifi,aa:bb:cc:dd:ee:01,-61,\n500,wifi,aa:bb:cc:dd:ee:02,-74,480\n1000,pressure,1009.5,,,\n20,gyroscope,0,0,0.01\n";
        let json = r#"{"sensor":"meta","phone_model":"P7"}
{"t_ms":0,"sensor":"accelerometer","x":0.1,"y":0.2,"z":9.8}
{"t_ms":500,"sensor":"wifi","aps":[{"bssid":"aa:bb:cc:dd:ee:01","rssi_dbm":-61},{"bssid":"aa:bb:cc:dd:ee:02","rssi_dbm":-74,"last_seen_ms":480}]}
{"t_ms":1000,"sensor":"pressure","hpa":1009.5}
{"t_ms":20,"sensor":"gyroscope","x":0,"y":0,"z":0.01}
"#;
        let a = read(csv, false).unwrap();
        let b = read(json, true).unwrap();
        assert_eq!(a, b);
        assert_eq!(a.meta.model.as_deref(), Some("P7"));
        assert_eq!(a.wifi.len(), 1);
        assert_eq!(a.wifi[0].entries.len(), 2);
        assert_eq!(a.wifi[0].entries[1].last_seen_ms, 480);
        assert_eq!(a.pressure[0].hpa, 1009.5);
    }

    /// A walk written as a stream reads back with the same inputs (every number exact).
    #[test]
    fn a_written_stream_reads_back_as_the_walk() {
        let mut walk = Walk::default();
        walk.meta.model = Some("P7".into());
        walk.meta.start_time = Some(1_700_000_000_000);
        for k in 0..50i64 {
            let t = 20 * k;
            let v = [0.1 * k as f64, -1.0 / 3.0, 9.81 + 1e-9 * k as f64];
            walk.imu
                .accelerometer
                .push(Vec3Sample { t, v, accuracy: 3 });
            walk.imu.gyroscope.push(Vec3Sample {
                t: t + 5,
                v,
                accuracy: 3,
            });
            walk.imu.rotation_vector.push(RotationVectorSample {
                t,
                v: [0.01, 0.02, 0.7],
                accuracy: 3,
            });
        }
        walk.pressure.push(PressureSample {
            t: 300,
            hpa: 1_009.123_456_789,
        });
        walk.wifi.push(WifiScan {
            t: 500,
            entries: vec![
                WifiEntry::new("aa:bb:cc:dd:ee:01".parse().unwrap(), -61.0).seen_at(450),
                WifiEntry::new("aa:bb:cc:dd:ee:02".parse().unwrap(), -74.5).seen_at(500),
            ],
        });
        let mut text = Vec::new();
        write_csv(&walk, &mut text).unwrap();
        let back = read(std::str::from_utf8(&text).unwrap(), false).unwrap();
        assert_eq!(back.imu.accelerometer, walk.imu.accelerometer);
        assert_eq!(back.imu.gyroscope, walk.imu.gyroscope);
        assert_eq!(back.imu.rotation_vector, walk.imu.rotation_vector);
        assert_eq!(back.pressure, walk.pressure);
        assert_eq!(back.wifi.len(), 1);
        for (a, b) in back.wifi[0].entries.iter().zip(&walk.wifi[0].entries) {
            assert_eq!(
                (a.bssid, a.rssi_dbm, a.last_seen_ms),
                (b.bssid, b.rssi_dbm, b.last_seen_ms)
            );
        }
        assert_eq!(back.meta.model, walk.meta.model);
        assert_eq!(back.meta.start_time, walk.meta.start_time);
    }

    #[test]
    fn bad_values_name_line_and_field() {
        let cases = [
            ("t_ms,sensor,a,b,c,d\n0,accelerometer,1,nan,3\n", 2, "y"),
            ("t_ms,sensor,a,b,c,d\n0,compass,1,2,3\n", 2, "sensor"),
            ("t_ms,sensor,a,b,c,d\n\n0,wifi,zz,-60\n", 3, "aps[0].bssid"),
            (
                "t_ms,sensor,a,b,c,d\n0,wifi,aa:bb:cc:dd:ee:01,-600\n",
                2,
                "aps[0].rssi_dbm",
            ),
            ("t_ms,sensor,a,b,c,d\nx,pressure,1000\n", 2, "t_ms"),
            ("0,pressure,1000\n", 1, "header"),
            (
                "t_ms,sensor,a,b,c,d\n99999999999999999,pressure,1000\n",
                2,
                "t_ms",
            ),
        ];
        for (text, line, field) in cases {
            match read(text, false) {
                Err(IoError::BadSample {
                    line: l, field: f, ..
                }) => assert_eq!((l, f.as_str()), (line, field), "{text}"),
                other => panic!("{text}: {other:?}"),
            }
        }
        match read("{\"t_ms\":0,\"sensor\":\"pressure\"}\n", true) {
            Err(IoError::BadSample {
                line: 1, message, ..
            }) => {
                assert!(message.contains("hpa"), "{message}")
            }
            other => panic!("{other:?}"),
        }
    }
}

//! Conversions between Python values and the core vocabulary: numpy arrays of samples,
//! times, BSSIDs and scans, configs. Every bad value is an `InputError` naming the argument
//! and the row.

use crate::errors::{PyErrorKind, input_error, py_error};
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyArrayMethods, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};
use wipdr_core::{Bssid, TimestampMs, WifiEntry, WifiScan};
use wipdr_eval::pipeline::EvalConfig;

/// Largest time accepted, ms (the readers' bound: `f64` holds every such integer exactly).
pub const MAX_ABS_TIME_MS: f64 = 9_007_199_254_740_992.0;

/// A time in ms from a float column: finite, whole, within [`MAX_ABS_TIME_MS`].
pub fn time_of_f64(v: f64, what: &dyn Fn() -> String) -> PyResult<TimestampMs> {
    if v.is_finite() && v.fract() == 0.0 && v.abs() <= MAX_ABS_TIME_MS {
        // In range and whole: the cast is exact.
        #[allow(clippy::cast_possible_truncation)]
        Ok(v as i64)
    } else {
        Err(input_error(format!(
            "{}: time must be a whole number of ms within +-2^53, got {v}",
            what()
        )))
    }
}

/// A time in ms from a Python int or a whole float.
pub fn time_of(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<TimestampMs> {
    if let Ok(t) = obj.extract::<i64>() {
        if (t.unsigned_abs() as f64) <= MAX_ABS_TIME_MS {
            return Ok(t);
        }
        return Err(input_error(format!("{what}: time {t} ms beyond +-2^53")));
    }
    match obj.extract::<f64>() {
        Ok(v) => time_of_f64(v, &|| what.to_string()),
        Err(_) => Err(input_error(format!(
            "{what}: time must be a number of ms, got {}",
            type_name(obj)
        ))),
    }
}

/// A finite float.
pub fn finite(v: f64, what: &dyn Fn() -> String) -> PyResult<f64> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(input_error(format!("{}: must be finite, got {v}", what())))
    }
}

fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "?".into())
}

/// `obj` as a C-contiguous float64 array of shape `(n, cols)` (anything `numpy.asarray`
/// takes; an empty sequence is `(0, cols)`).
pub fn f64_rows(obj: &Bound<'_, PyAny>, cols: usize, name: &str) -> PyResult<Array2<f64>> {
    let py = obj.py();
    let np = py.import("numpy")?;
    let arr = np
        .getattr("ascontiguousarray")?
        .call1((obj, "float64"))
        .map_err(|e| input_error(format!("{name}: not an array of numbers: {e}")))?;
    let arr = if arr.getattr("size")?.extract::<usize>()? == 0 {
        np.getattr("zeros")?.call1(((0usize, cols), "float64"))?
    } else {
        arr
    };
    let arr = arr
        .cast::<PyArray2<f64>>()
        .map_err(|_| {
            input_error(format!(
                "{name}: expected a 2-d array of shape (n, {cols}), got {} dimension(s)",
                arr.getattr("ndim")
                    .and_then(|d| d.extract::<usize>())
                    .unwrap_or(0)
            ))
        })?
        .clone();
    let view: PyReadonlyArray2<f64> = arr.readonly();
    let a = view.as_array();
    if a.ncols() != cols {
        return Err(input_error(format!(
            "{name}: expected shape (n, {cols}), got ({}, {})",
            a.nrows(),
            a.ncols()
        )));
    }
    Ok(a.to_owned())
}

/// Rows of `t_ms` and `cols - 1` finite values.
pub fn timed_rows(
    obj: &Bound<'_, PyAny>,
    cols: usize,
    name: &str,
) -> PyResult<Vec<(TimestampMs, Vec<f64>)>> {
    let a = f64_rows(obj, cols, name)?;
    let mut out = Vec::with_capacity(a.nrows());
    for (i, row) in a.rows().into_iter().enumerate() {
        let what = || format!("{name}[{i}]");
        let t = time_of_f64(row[0], &what)?;
        let mut values = Vec::with_capacity(cols - 1);
        for &v in row.iter().skip(1) {
            values.push(finite(v, &what)?);
        }
        out.push((t, values));
    }
    Ok(out)
}

/// A float64 array of shape `(rows.len(), cols)`.
pub fn to_array<'py>(
    py: Python<'py>,
    cols: usize,
    rows: impl ExactSizeIterator<Item = Vec<f64>>,
) -> Bound<'py, PyArray2<f64>> {
    let n = rows.len();
    let flat: Vec<f64> = rows.flatten().collect();
    match Array2::from_shape_vec((n, cols), flat) {
        Ok(a) => a.into_pyarray(py),
        // Every row has `cols` values by construction.
        Err(_) => Array2::<f64>::zeros((0, cols)).into_pyarray(py),
    }
}

/// A BSSID from `"aa:bb:cc:dd:ee:ff"` or an int below 2^48.
pub fn bssid_of(obj: &Bound<'_, PyAny>, what: &dyn Fn() -> String) -> PyResult<Bssid> {
    if let Ok(s) = obj.extract::<String>() {
        return s
            .parse::<Bssid>()
            .map_err(|e| input_error(format!("{}: {e}", what())));
    }
    if let Ok(v) = obj.extract::<u64>() {
        return Bssid::from_u64(v)
            .ok_or_else(|| input_error(format!("{}: BSSID {v} wider than 48 bits", what())));
    }
    Err(input_error(format!(
        "{}: a BSSID is a string \"aa:bb:cc:dd:ee:ff\" or an int, got {}",
        what(),
        type_name(obj)
    )))
}

/// Scan entries from `[(bssid, rssi), ...]` or `[(bssid, rssi, last_seen_ms), ...]`
/// (`last_seen_ms` `None` or absent: no age known, the staleness filter keeps it).
pub fn entries_of(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<WifiEntry>> {
    let mut out = Vec::new();
    for (i, item) in obj
        .try_iter()
        .map_err(|_| input_error(format!("{what}: expected a list of (bssid, rssi) pairs")))?
        .enumerate()
    {
        let item = item?;
        let at = || format!("{what}[{i}]");
        let tuple = item
            .cast::<PyTuple>()
            .map_err(|_| input_error(format!("{}: expected a (bssid, rssi) tuple", at())))?;
        if !(2..=3).contains(&tuple.len()) {
            return Err(input_error(format!(
                "{}: expected (bssid, rssi) or (bssid, rssi, last_seen_ms), got {} items",
                at(),
                tuple.len()
            )));
        }
        let bssid = bssid_of(&tuple.get_item(0)?, &at)?;
        let rssi: f64 = tuple
            .get_item(1)?
            .extract()
            .map_err(|_| input_error(format!("{}: rssi must be a number", at())))?;
        let mut entry = WifiEntry::new(bssid, finite(rssi, &at)?);
        if tuple.len() == 3 {
            let seen = tuple.get_item(2)?;
            if !seen.is_none() {
                entry = entry.seen_at(time_of(&seen, &at())?);
            }
        }
        out.push(entry);
    }
    Ok(out)
}

/// One scan, duplicates of a BSSID resolved as the readers do (the most recent kept).
pub fn scan_of(t: TimestampMs, entries: Vec<WifiEntry>) -> WifiScan {
    let mut scan = WifiScan { t, entries };
    scan.dedup_keep_most_recent();
    scan
}

/// A scan's entries as `[(bssid, rssi), ...]` or, with `seen`, `[(bssid, rssi,
/// last_seen_ms or None), ...]`.
pub fn entries_to_py<'py>(
    py: Python<'py>,
    scan: &WifiScan,
    seen: bool,
) -> PyResult<Bound<'py, PyList>> {
    let list = PyList::empty(py);
    for e in &scan.entries {
        let bssid = e.bssid.to_string();
        if seen {
            let last = (e.last_seen_ms != TimestampMs::MAX).then_some(e.last_seen_ms);
            list.append((bssid, e.rssi_dbm, last))?;
        } else {
            list.append((bssid, e.rssi_dbm))?;
        }
    }
    Ok(list)
}

/// An evaluation config from Python: `None` (the defaults), a path to a TOML file (as
/// `wipdr eval --config`), or a dict of the same fields (merged onto the defaults the same
/// way, via its TOML form).
pub fn config_of(obj: Option<&Bound<'_, PyAny>>) -> PyResult<EvalConfig> {
    let Some(obj) = obj.filter(|o| !o.is_none()) else {
        return Ok(EvalConfig::default());
    };
    let py = obj.py();
    let config_error =
        |e: wipdr_eval::pipeline::EvalError| py_error(PyErrorKind::Config, e.to_string());
    if let Ok(dict) = obj.cast::<PyDict>() {
        let text: String = py
            .import("json")?
            .getattr("dumps")?
            .call1((dict,))
            .map_err(|e| {
                py_error(
                    PyErrorKind::Config,
                    format!("config dict: not JSON-serialisable: {e}"),
                )
            })?
            .extract()?;
        let value: toml::Value = serde_json::from_str(&text).map_err(|e| {
            py_error(
                PyErrorKind::Config,
                format!("config dict: not a TOML table (no None values): {e}"),
            )
        })?;
        let toml_text = toml::to_string(&value)
            .map_err(|e| py_error(PyErrorKind::Config, format!("config dict: {e}")))?;
        return EvalConfig::from_toml(&toml_text, "config dict").map_err(config_error);
    }
    let path: std::path::PathBuf = obj.extract().map_err(|_| {
        input_error(format!(
            "config: expected None, a path to a TOML file or a dict, got {}",
            type_name(obj)
        ))
    })?;
    let text = std::fs::read_to_string(&path).map_err(|e| {
        py_error(
            PyErrorKind::Data,
            format!("config {}: cannot read: {e}", path.display()),
        )
    })?;
    EvalConfig::from_toml(&text, &path.display().to_string()).map_err(config_error)
}

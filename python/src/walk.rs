//! `wipdr.Walk` and `wipdr.read_walk`: one recorded walk as numpy arrays.

use crate::convert::{entries_of, entries_to_py, scan_of, time_of, timed_rows, to_array};
use crate::errors::{input_error, io_error};
use numpy::PyArray2;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use wipdr_core::{
    Point2, PressureSample, RotationVectorSample, Vec3Sample, Walk as CoreWalk, WalkMeta, Waypoint,
};

/// One recorded walk: ground-truth waypoints and the phone's sensor streams, each sorted by
/// time (ms). Arrays are float64: ``waypoints`` ``(n, 3)`` ``t_ms, x, y`` (metres in the
/// floor's frame); ``accelerometer`` (m/s²), ``gyroscope`` (rad/s), ``magnetometer`` (µT)
/// and ``rotation_vector`` (x, y, z of Android's attitude quaternion) ``(n, 4)``
/// ``t_ms, x, y, z``; ``pressure`` ``(n, 2)`` ``t_ms, hPa``. ``scans`` is a list of
/// ``(t_ms, [(bssid, rssi_dbm), ...])``.
///
/// Built by :func:`read_walk` or from your own arrays (any of them may be left out):
///
/// >>> w = wipdr.Walk("w1", waypoints=[[0, 1.0, 2.0]], scans=[(0, [("aa:bb:cc:dd:ee:ff", -60.0)])])
/// >>> w.waypoints.shape
/// (1, 3)
#[pyclass(module = "wipdr", name = "Walk", from_py_object)]
#[derive(Debug, Clone)]
pub struct PyWalk {
    /// The walk.
    pub inner: CoreWalk,
}

fn vec3(rows: Vec<(i64, Vec<f64>)>) -> Vec<Vec3Sample> {
    rows.into_iter()
        .map(|(t, v)| Vec3Sample {
            t,
            v: [v[0], v[1], v[2]],
            accuracy: 3,
        })
        .collect()
}

fn opt_rows(
    obj: Option<&Bound<'_, PyAny>>,
    cols: usize,
    name: &str,
) -> PyResult<Vec<(i64, Vec<f64>)>> {
    match obj.filter(|o| !o.is_none()) {
        Some(o) => timed_rows(o, cols, name),
        None => Ok(Vec::new()),
    }
}

fn meta_of(id: String, metadata: Option<&Bound<'_, PyDict>>) -> PyResult<WalkMeta> {
    let mut meta = WalkMeta {
        id,
        ..WalkMeta::default()
    };
    let Some(dict) = metadata else {
        return Ok(meta);
    };
    for (key, value) in dict.iter() {
        let key: String = key.extract()?;
        let what = format!("metadata[{key:?}]");
        let text = || -> PyResult<Option<String>> {
            if value.is_none() {
                Ok(None)
            } else {
                value
                    .extract::<String>()
                    .map(Some)
                    .map_err(|_| input_error(format!("{what}: expected a string or None")))
            }
        };
        match key.as_str() {
            "site_id" => meta.site_id = text()?,
            "site_name" => meta.site_name = text()?,
            "floor_id" => meta.floor_id = text()?,
            "floor_name" => meta.floor_name = text()?,
            "brand" => meta.brand = text()?,
            "model" => meta.model = text()?,
            "android" => meta.android = text()?,
            "route" => meta.route = text()?,
            "start_time" | "end_time" => {
                let t = if value.is_none() {
                    None
                } else {
                    Some(time_of(&value, &what)?)
                };
                if key == "start_time" {
                    meta.start_time = t;
                } else {
                    meta.end_time = t;
                }
            }
            "id" => {}
            other => {
                return Err(input_error(format!(
                    "metadata: unknown key {other:?} (known: site_id, site_name, floor_id, \
                     floor_name, brand, model, android, start_time, end_time, route)"
                )));
            }
        }
    }
    Ok(meta)
}

#[pymethods]
impl PyWalk {
    /// A walk from arrays (see the class docs for the shapes); the streams are sorted by
    /// time. ``waypoint_floors`` gives each waypoint's floor level (int or None);
    /// ``metadata`` the fields of :attr:`metadata` (``route`` groups walks into one fold).
    #[new]
    #[pyo3(signature = (id, waypoints=None, *, accelerometer=None, gyroscope=None,
        magnetometer=None, rotation_vector=None, pressure=None, scans=None,
        waypoint_floors=None, metadata=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        id: String,
        waypoints: Option<&Bound<'_, PyAny>>,
        accelerometer: Option<&Bound<'_, PyAny>>,
        gyroscope: Option<&Bound<'_, PyAny>>,
        magnetometer: Option<&Bound<'_, PyAny>>,
        rotation_vector: Option<&Bound<'_, PyAny>>,
        pressure: Option<&Bound<'_, PyAny>>,
        scans: Option<&Bound<'_, PyAny>>,
        waypoint_floors: Option<Vec<Option<i32>>>,
        metadata: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let mut walk = CoreWalk {
            meta: meta_of(id, metadata)?,
            ..CoreWalk::default()
        };
        let points = opt_rows(waypoints, 3, "waypoints")?;
        if let Some(f) = &waypoint_floors
            && f.len() != points.len()
        {
            return Err(input_error(format!(
                "waypoint_floors: {} floors for {} waypoints",
                f.len(),
                points.len()
            )));
        }
        walk.waypoints = points
            .into_iter()
            .enumerate()
            .map(|(i, (t, v))| Waypoint {
                t,
                position: Point2::new(v[0], v[1]),
                floor: waypoint_floors.as_ref().and_then(|f| f[i]),
            })
            .collect();
        walk.imu.accelerometer = vec3(opt_rows(accelerometer, 4, "accelerometer")?);
        walk.imu.gyroscope = vec3(opt_rows(gyroscope, 4, "gyroscope")?);
        walk.imu.magnetometer = vec3(opt_rows(magnetometer, 4, "magnetometer")?);
        walk.imu.rotation_vector = opt_rows(rotation_vector, 4, "rotation_vector")?
            .into_iter()
            .map(|(t, v)| RotationVectorSample {
                t,
                v: [v[0], v[1], v[2]],
                accuracy: 3,
            })
            .collect();
        walk.pressure = opt_rows(pressure, 2, "pressure")?
            .into_iter()
            .map(|(t, v)| PressureSample { t, hpa: v[0] })
            .collect();
        if let Some(scans) = scans.filter(|s| !s.is_none()) {
            for (i, item) in scans
                .try_iter()
                .map_err(|_| input_error("scans: expected a list of (t_ms, entries)"))?
                .enumerate()
            {
                let item = item?;
                let what = format!("scans[{i}]");
                let (t, entries): (Bound<'_, PyAny>, Bound<'_, PyAny>) = item
                    .extract()
                    .map_err(|_| input_error(format!("{what}: expected (t_ms, entries)")))?;
                let t = time_of(&t, &what)?;
                walk.wifi.push(scan_of(
                    t,
                    entries_of(&entries, &format!("{what} entries"))?,
                ));
            }
        }
        walk.sort_streams();
        Ok(Self { inner: walk })
    }

    /// The walk's id (its file name without ``.txt[.gz]`` when read from a file).
    #[getter]
    fn id(&self) -> &str {
        &self.inner.meta.id
    }

    /// Ground truth, ``(n, 3)`` float64: ``t_ms, x, y``.
    #[getter]
    fn waypoints<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let w = &self.inner.waypoints;
        to_array(
            py,
            3,
            w.iter()
                .map(|w| vec![w.t as f64, w.position.x, w.position.y]),
        )
    }

    /// Each waypoint's floor level (0 = ground, -1 first basement, ...; None where unknown).
    #[getter]
    fn waypoint_floors(&self) -> Vec<Option<i32>> {
        self.inner.waypoints.iter().map(|w| w.floor).collect()
    }

    /// Accelerometer, ``(n, 4)`` float64: ``t_ms, x, y, z`` (m/s², device frame).
    #[getter]
    fn accelerometer<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        vec3_array(py, &self.inner.imu.accelerometer)
    }

    /// Gyroscope, ``(n, 4)`` float64: ``t_ms, x, y, z`` (rad/s).
    #[getter]
    fn gyroscope<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        vec3_array(py, &self.inner.imu.gyroscope)
    }

    /// Magnetometer, ``(n, 4)`` float64: ``t_ms, x, y, z`` (µT).
    #[getter]
    fn magnetometer<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        vec3_array(py, &self.inner.imu.magnetometer)
    }

    /// Rotation vector, ``(n, 4)`` float64: ``t_ms, x, y, z`` of the attitude quaternion.
    #[getter]
    fn rotation_vector<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let r = &self.inner.imu.rotation_vector;
        to_array(
            py,
            4,
            r.iter().map(|s| vec![s.t as f64, s.v[0], s.v[1], s.v[2]]),
        )
    }

    /// Barometer, ``(n, 2)`` float64: ``t_ms, hPa``.
    #[getter]
    fn pressure<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let p = &self.inner.pressure;
        to_array(py, 2, p.iter().map(|s| vec![s.t as f64, s.hpa]))
    }

    /// Wi-Fi scans: ``[(t_ms, [(bssid, rssi_dbm), ...]), ...]``.
    #[getter]
    fn scans<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        self.scan_list(py, false)
    }

    /// Wi-Fi scans with each entry's last-seen time: ``[(t_ms, [(bssid, rssi_dbm,
    /// last_seen_ms or None), ...]), ...]``; ``Positioner.push_scan`` takes these entries
    /// (the staleness filter drops entries seen long before their scan).
    #[getter]
    fn scans_with_times<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        self.scan_list(py, true)
    }

    /// The floor name of the walk's header, where it has one.
    #[getter]
    fn floor(&self) -> Option<String> {
        let m = &self.inner.meta;
        m.floor_name.clone().or_else(|| m.floor_id.clone())
    }

    /// The walk's metadata: ``id``, ``site_id``, ``site_name``, ``floor_id``,
    /// ``floor_name``, ``brand``, ``model``, ``android``, ``start_time``, ``end_time``
    /// (Unix ms), ``route`` (None where unknown).
    #[getter]
    fn metadata<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let m = &self.inner.meta;
        let d = PyDict::new(py);
        d.set_item("id", &m.id)?;
        d.set_item("site_id", &m.site_id)?;
        d.set_item("site_name", &m.site_name)?;
        d.set_item("floor_id", &m.floor_id)?;
        d.set_item("floor_name", &m.floor_name)?;
        d.set_item("brand", &m.brand)?;
        d.set_item("model", &m.model)?;
        d.set_item("android", &m.android)?;
        d.set_item("start_time", m.start_time)?;
        d.set_item("end_time", m.end_time)?;
        d.set_item("route", &m.route)?;
        Ok(d)
    }

    /// Duration in seconds over every stream (0 for an empty walk).
    #[getter]
    fn duration_s(&self) -> f64 {
        self.inner.duration_s()
    }

    fn __repr__(&self) -> String {
        let w = &self.inner;
        format!(
            "Walk({:?}: {} waypoints, {} scans, {} accelerometer samples, {:.1} s)",
            w.meta.id,
            w.waypoints.len(),
            w.wifi.len(),
            w.imu.accelerometer.len(),
            w.duration_s()
        )
    }
}

impl PyWalk {
    fn scan_list<'py>(&self, py: Python<'py>, seen: bool) -> PyResult<Bound<'py, PyList>> {
        let list = PyList::empty(py);
        for s in &self.inner.wifi {
            list.append((s.t, entries_to_py(py, s, seen)?))?;
        }
        Ok(list)
    }
}

fn vec3_array<'py>(py: Python<'py>, s: &[Vec3Sample]) -> Bound<'py, PyArray2<f64>> {
    to_array(
        py,
        4,
        s.iter().map(|s| vec![s.t as f64, s.v[0], s.v[1], s.v[2]]),
    )
}

/// Reads one walk file: an ILC 2.0 trace (``.txt``, ``.txt.gz``) or an IPIN GetSensorData
/// logfile (its ground truth in a metre frame of its own, origin 30 m south-west of its
/// POSI points). Dirty records are skipped and counted as ``wipdr inspect`` reports them;
/// an unreadable file or a crossed limit raises :class:`DataError`.
#[pyfunction]
pub fn read_walk(py: Python<'_>, path: std::path::PathBuf) -> PyResult<PyWalk> {
    let parsed = py
        .detach(|| wipdr_io::any::read_walk_file(&path, &wipdr_io::Limits::default()))
        .map_err(|e| io_error(&e))?;
    Ok(PyWalk { inner: parsed.walk })
}

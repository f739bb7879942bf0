//! `wipdr.SiteModel`, `wipdr.Positioner` and `wipdr.Estimate`: a site learned once (and
//! saved), and the online pipeline from Python, one sample at a time.

use crate::convert::{config_of, entries_of, f64_rows, scan_of, time_of, to_array};
use crate::errors::{PyErrorKind, chain, eval_error, input_error, py_error};
use crate::floor::{PyFloor, PyFloorPlan};
use crate::walk::PyWalk;
use numpy::PyArray2;
use pyo3::prelude::*;
use std::sync::{Arc, Mutex};
use wipdr_core::{Bssid, Floor as CoreFloor, Point2, TimestampMs, Walk};
use wipdr_eval::pipeline::{EvalConfig, FloorInput};
use wipdr_fingerprint::RadioMap;
use wipdr_fingerprint::radio_map::ReferencePoint;
use wipdr_positioning::site_model::{
    Provenance, SiteModel, SiteModelData, TrainingData, measured_points,
};
use wipdr_positioning::{PositionEstimate, Sample, Site, StreamIdentity, stream_seed};

/// A site learned once: the radio map with floors (interpolated and extended into coverage
/// gaps as the config says), where it has fingerprints (coverage), where the training walks
/// went (trails, for ``pmf``), the PDR calibrated on them, their barometer on known floors,
/// the floor plan and the settings streams run with. Fit it from walks
/// (:meth:`SiteModel.fit`) or survey records (:meth:`SiteModel.from_records`), save it
/// (:meth:`SiteModel.save`) and load it anywhere (:meth:`SiteModel.load`): the same file
/// ``wipdr fit`` writes and ``wipdr locate --model`` reads.
#[pyclass(module = "wipdr", name = "SiteModel", frozen)]
#[derive(Debug)]
pub struct PySiteModel {
    model: SiteModel,
    /// Whether the model's PDR was calibrated on training walks.
    calibrated: bool,
}

/// `walks` (a list of `Walk` or a `Floor`) as a floor of those walks, with its plan and frame.
fn floor_of(walks: &Bound<'_, PyAny>, floor_plan: Option<&PyFloorPlan>) -> PyResult<FloorInput> {
    if let Ok(floor) = walks.extract::<PyFloor>() {
        let mut input = floor.input();
        if let Some(plan) = floor_plan {
            let mut f = (*input.data).clone();
            f.plan = plan.inner.clone();
            input.data = Arc::new(f);
        }
        return Ok(input);
    }
    let list: Vec<PyWalk> = walks
        .extract()
        .map_err(|_| input_error("walks: expected a list of Walk objects or a Floor"))?;
    let walks: Vec<wipdr_core::Walk> = list.into_iter().map(|w| w.inner).collect();
    let plan = match floor_plan {
        Some(p) => p.inner.clone(),
        None => crate::floor::plan_around_walks(walks.iter())?,
    };
    Ok(FloorInput::new(
        "walks",
        CoreFloor::new("walks", plan, walks),
    ))
}

impl PySiteModel {
    fn fit_walks(
        py: Python<'_>,
        walks: &Bound<'_, PyAny>,
        config: Option<&Bound<'_, PyAny>>,
        floor_plan: Option<PyFloorPlan>,
    ) -> PyResult<Self> {
        let cfg = config_of(config)?;
        let floor = floor_of(walks, floor_plan.as_ref())?;
        if floor.data.walks.is_empty() {
            return Err(input_error("SiteModel.fit: no walks"));
        }
        let model = py
            .detach(|| {
                let training: Vec<&Walk> = floor.data.walks.iter().collect();
                wipdr_eval::fold_model::fit_site(&floor, usize::MAX, &training, &cfg, None)
            })
            .map_err(|e| eval_error(&e))?;
        Ok(Self {
            model,
            calibrated: cfg.fit.calibrate_pdr,
        })
    }
}

#[pymethods]
impl PySiteModel {
    /// Learns a site from training ``walks`` (a list of :class:`Walk` or a :class:`Floor`):
    /// what one fold of the evaluation learns from its training walks, with the same code.
    /// ``config`` as in :func:`evaluate` (its radio map, extension, calibration, positioner
    /// and scheme settings); ``floor_plan`` replaces the floor's plan (walls, walkable
    /// space, the path-loss extension's walkable test).
    #[staticmethod]
    #[pyo3(signature = (walks, config=None, floor_plan=None))]
    fn fit(
        py: Python<'_>,
        walks: &Bound<'_, PyAny>,
        config: Option<&Bound<'_, PyAny>>,
        floor_plan: Option<PyFloorPlan>,
    ) -> PyResult<Self> {
        Self::fit_walks(py, walks, config, floor_plan)
    }

    /// The former name of :meth:`SiteModel.fit` (``RadioMap.from_walks``), kept as an alias.
    #[staticmethod]
    #[pyo3(signature = (walks, config=None, floor_plan=None))]
    fn from_walks(
        py: Python<'_>,
        walks: &Bound<'_, PyAny>,
        config: Option<&Bound<'_, PyAny>>,
        floor_plan: Option<PyFloorPlan>,
    ) -> PyResult<Self> {
        Self::fit_walks(py, walks, config, floor_plan)
    }

    /// Reads a site model file (``wipdr fit``'s output, or :meth:`SiteModel.save`'s).
    #[staticmethod]
    fn load(py: Python<'_>, path: std::path::PathBuf) -> PyResult<Self> {
        let model = py
            .detach(|| SiteModel::load(&path))
            .map_err(|e| py_error(PyErrorKind::Data, chain(&e)))?;
        Ok(Self {
            model,
            calibrated: true,
        })
    }

    /// Writes the model to ``path`` (a checked binary file; see ``docs/guide.md``).
    fn save(&self, py: Python<'_>, path: std::path::PathBuf) -> PyResult<()> {
        py.detach(|| self.model.save(&path))
            .map_err(|e| py_error(PyErrorKind::Data, chain(&e)))
    }

    /// The site's name.
    #[getter]
    fn name(&self) -> String {
        self.model.name().to_string()
    }

    /// The building's floors (sorted; empty for one floor without numbers).
    #[getter]
    fn building_floors(&self) -> Vec<i32> {
        self.model.data().floors.clone()
    }

    /// Where the model came from, as a dict (wipdr version, input files, counts).
    #[getter]
    fn provenance<'py>(&self, py: Python<'py>) -> PyResult<Py<PyAny>> {
        let text = serde_json::to_string(&self.model.data().provenance)
            .map_err(|e| input_error(e.to_string()))?;
        Ok(py
            .import("json")?
            .getattr("loads")?
            .call1((text,))?
            .unbind())
    }

    /// A site model from survey records: ``positions`` ``(n, 2)`` ``x, y`` or ``(n, 3)``
    /// ``x, y, floor``, and for each position the list of ``(bssid, rssi_dbm)`` heard there.
    /// ``config``'s ``[radio_map.radio]`` sets the value of APs not heard; no PDR is learned.
    #[staticmethod]
    #[pyo3(signature = (positions, scans, config=None))]
    fn from_records(
        positions: &Bound<'_, PyAny>,
        scans: Vec<Bound<'_, PyAny>>,
        config: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let cfg = config_of(config)?;
        let cols = positions
            .getattr("shape")
            .ok()
            .and_then(|s| s.get_item(1).ok())
            .and_then(|c| c.extract::<usize>().ok())
            .or_else(|| positions.get_item(0).ok().and_then(|r| r.len().ok()))
            .unwrap_or(2);
        let a = f64_rows(positions, if cols == 3 { 3 } else { 2 }, "positions")?;
        if a.nrows() != scans.len() {
            return Err(input_error(format!(
                "SiteModel.from_records: {} positions but {} scans",
                a.nrows(),
                scans.len()
            )));
        }
        let mut records: Vec<(ReferencePoint, Vec<(Bssid, f64)>)> = Vec::with_capacity(a.nrows());
        for (i, (row, scan)) in a.rows().into_iter().zip(&scans).enumerate() {
            if row.iter().any(|v| !v.is_finite()) {
                return Err(input_error(format!("positions[{i}]: must be finite")));
            }
            let mut point = ReferencePoint::from(Point2::new(row[0], row[1]));
            if row.len() == 3 {
                let f = row[2];
                if f.fract() != 0.0 || f.abs() > 1000.0 {
                    return Err(input_error(format!(
                        "positions[{i}]: floor must be a whole number within +-1000, got {f}"
                    )));
                }
                // Whole and small: the cast is exact.
                #[allow(clippy::cast_possible_truncation)]
                {
                    point.floor = Some(f as i32);
                }
            }
            let heard = entries_of(scan, &format!("scans[{i}]"))?
                .into_iter()
                .map(|e| (e.bssid, e.rssi_dbm))
                .collect();
            records.push((point, heard));
        }
        let map = RadioMap::from_records(records, cfg.fit.radio_map.radio)
            .map_err(|e| input_error(format!("SiteModel.from_records: {e}")))?;
        let plan = crate::floor::plan_around(map.points().iter().map(|p| p.position))?;
        let site = cfg.site_config();
        let mut floors: Vec<i32> = map.points().iter().filter_map(|p| p.floor).collect();
        floors.sort_unstable();
        floors.dedup();
        let mut positioner = site.positioner;
        positioner.floor.fixes_across_floors =
            Some(positioner.floor.fixes_across_floors.unwrap_or(false));
        let data = SiteModelData {
            name: "records".into(),
            config: positioner,
            schemes: site.schemes,
            measured: Arc::new(measured_points(&map)),
            provenance: Provenance::of(&TrainingData::default(), &map),
            radio_map: Arc::new(map),
            coverage_includes_extension: false,
            trail_segments: Vec::new(),
            pressure_references: Arc::new(Vec::new()),
            plan: Some(plan),
            geo_frame: None,
            floors,
            floor_heights_m: Vec::new(),
            leave_one_out: None,
        };
        let model = SiteModel::from_data(data, None)
            .map_err(|e| input_error(format!("SiteModel.from_records: {e}")))?;
        Ok(Self {
            model,
            calibrated: false,
        })
    }

    /// Number of reference points.
    fn __len__(&self) -> usize {
        self.model.radio_map().len()
    }

    /// Number of access points.
    #[getter]
    fn n_aps(&self) -> usize {
        self.model.radio_map().n_aps()
    }

    /// Reference point positions, ``(n, 2)`` float64 ``x, y``.
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let p = self.model.radio_map().points();
        to_array(py, 2, p.iter().map(|p| vec![p.position.x, p.position.y]))
    }

    /// Each reference point's floor (None where unknown).
    #[getter]
    fn floors(&self) -> Vec<Option<i32>> {
        self.model
            .radio_map()
            .points()
            .iter()
            .map(|p| p.floor)
            .collect()
    }

    fn __repr__(&self) -> String {
        format!(
            "SiteModel({:?}: {} points, {} APs)",
            self.model.name(),
            self.model.radio_map().len(),
            self.model.radio_map().n_aps()
        )
    }
}

/// One estimate of a :class:`Positioner`: time (ms), position (metres), floor (None where
/// unknown), horizontal standard deviation and covariance (None where the scheme has none).
#[pyclass(module = "wipdr", name = "Estimate", frozen, get_all)]
#[derive(Debug, Clone)]
pub struct PyEstimate {
    /// Time of the sample that gave the estimate, ms.
    pub t_ms: TimestampMs,
    /// East / x, metres.
    pub x: f64,
    /// North / y, metres.
    pub y: f64,
    /// Floor level, where known.
    pub floor: Option<i32>,
    /// Horizontal standard deviation, metres (``sqrt(trace(P) / 2)``).
    pub sd_m: Option<f64>,
    /// Horizontal covariance ``((xx, xy), (yx, yy))``, m².
    pub covariance: Option<((f64, f64), (f64, f64))>,
}

impl PyEstimate {
    fn of(e: &PositionEstimate) -> Self {
        Self {
            t_ms: e.t,
            x: e.position.x,
            y: e.position.y,
            floor: e.floor,
            sd_m: e.sd_m(),
            covariance: e
                .covariance
                .map(|p| ((p[(0, 0)], p[(0, 1)]), (p[(1, 0)], p[(1, 1)]))),
        }
    }
}

#[pymethods]
impl PyEstimate {
    fn __repr__(&self) -> String {
        format!(
            "Estimate(t_ms={}, x={:.3}, y={:.3}, floor={:?}, sd_m={:?})",
            self.t_ms, self.x, self.y, self.floor, self.sd_m
        )
    }
}

/// Track rows: `t_ms, x, y, floor, sd_m` (NaN where the floor or the deviation is unknown,
/// as the CSV of `wipdr locate` leaves the field empty).
pub fn track_array<'py>(py: Python<'py>, track: &[PositionEstimate]) -> Bound<'py, PyArray2<f64>> {
    to_array(
        py,
        5,
        track.iter().map(|e| {
            vec![
                e.t as f64,
                e.position.x,
                e.position.y,
                e.floor.map_or(f64::NAN, f64::from),
                e.sd_m().unwrap_or(f64::NAN),
            ]
        }),
    )
}

/// The online positioning pipeline for one stream: feed raw samples in time order, get the
/// current estimate. The same pipeline ``wipdr locate`` and ``wipdr eval`` run.
#[pyclass(module = "wipdr", name = "Positioner")]
#[derive(Debug)]
pub struct PyPositioner {
    /// The stream (a mutex: Python objects may be shared between threads).
    inner: Mutex<Stream>,
}

/// A positioner and the track it returned.
#[derive(Debug)]
struct Stream {
    positioner: wipdr_positioning::Positioner,
    start: Option<(TimestampMs, Point2)>,
    track: Vec<PositionEstimate>,
}

#[pymethods]
impl PyPositioner {
    /// A positioner on site ``model`` running ``scheme`` (``wifi``, ``pdr``, ``ekf``,
    /// ``aekf``, ``akf``, ``rkf``, ``arkf``, ``aws``, ``tcpf``, ``pf``, ``apf``, ``rof``,
    /// ``pmf`` or a ``[schemes.LABEL]`` of the model's config). ``config`` (as in
    /// :func:`evaluate`) overrides the model's settings for this stream (its ``matcher``,
    /// ``query``, ``pdr``, schemes, ``map_matching``, ``static_start``, ``floor`` and
    /// ``seed``); the PDR calibrated by :meth:`SiteModel.fit` is kept when it calibrated one.
    /// ``floor_plan`` (default: the model's plan) gives walls and walkable space.
    /// ``stream_id`` is mixed into the seed as the evaluation does with the walk id;
    /// ``start`` = ``(t_ms, x, y)`` a known start (samples before ``t_ms`` only warm the PDR
    /// up); ``identity`` = ``(phone_model, start_unix_ms)`` lets the floor estimate use the
    /// training walks' barometer.
    #[new]
    #[pyo3(signature = (model, scheme="ekf", config=None, floor_plan=None, *,
        stream_id="", start=None, identity=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        model: &PySiteModel,
        scheme: &str,
        config: Option<&Bound<'_, PyAny>>,
        floor_plan: Option<PyFloorPlan>,
        stream_id: &str,
        start: Option<(Bound<'_, PyAny>, f64, f64)>,
        identity: Option<(String, Bound<'_, PyAny>)>,
    ) -> PyResult<Self> {
        let site_model = &model.model;
        let start = match start {
            Some((t, x, y)) => {
                let t = time_of(&t, "start")?;
                if !(x.is_finite() && y.is_finite()) {
                    return Err(input_error("start: x and y must be finite"));
                }
                Some((t, Point2::new(x, y)))
            }
            None => None,
        };
        let identity = match identity {
            Some((phone, t)) => Some(StreamIdentity {
                model: phone,
                start_unix_ms: time_of(&t, "identity start_unix_ms")?,
            }),
            None => None,
        };
        // The stream's settings: the model's, or `config`'s with the model's calibrated PDR
        // and floor resolution.
        let (pcfg, matcher) = match config {
            None => {
                let pcfg = site_model
                    .positioner_config(scheme, stream_seed(site_model.config().seed, stream_id))
                    .map_err(|e| input_error(chain(&e)))?;
                (pcfg, site_model.matcher().clone())
            }
            Some(c) => {
                let cfg: EvalConfig = config_of(Some(c))?;
                let scheme_cfg = cfg.scheme(scheme).map_err(|e| eval_error(&e))?;
                let pdr = if model.calibrated {
                    site_model.config().pdr
                } else {
                    cfg.positioner.pdr
                };
                let mut pcfg = cfg.positioner_for(scheme_cfg, pdr);
                pcfg.seed = stream_seed(cfg.positioner.seed, stream_id);
                pcfg.floor.fixes_across_floors = Some(
                    pcfg.floor
                        .fixes_across_floors
                        .unwrap_or(site_model.data().geo_frame.is_some()),
                );
                let matcher = if pcfg.matcher == site_model.config().matcher {
                    site_model.matcher().clone()
                } else {
                    pcfg.matcher
                        .build(site_model.data().radio_map.clone())
                        .map_err(|e| input_error(format!("Positioner: matcher: {e}")))?
                };
                (pcfg, matcher)
            }
        };
        let positioner = py
            .detach(|| {
                let site = match &floor_plan {
                    Some(plan) => Site {
                        coverage: site_model.site().coverage.clone(),
                        trails: site_model.site().trails.clone(),
                        likelihood: site_model.site().likelihood.clone(),
                        ..Site::from_plan(Some(&plan.inner))
                    },
                    None => site_model.site().clone(),
                };
                let mut p = wipdr_positioning::Positioner::from_parts(
                    &matcher,
                    &site,
                    &pcfg,
                    start.map(|(_, p)| p),
                )?;
                if let Some(id) = identity {
                    p.set_pressure_references(site_model.pressure_references().clone(), id);
                }
                Ok::<_, wipdr_positioning::PositioningError>(p)
            })
            .map_err(|e| input_error(chain(&e)))?;
        let mut track = Vec::new();
        if let (Some((t, _)), Some(mut e)) = (start, positioner.estimate()) {
            e.t = t;
            track.push(e);
        }
        Ok(Self {
            inner: Mutex::new(Stream {
                positioner,
                start,
                track,
            }),
        })
    }

    /// Feeds an accelerometer sample (m/s², device frame). Returns the new estimate when
    /// the sample ended a step, else None.
    fn push_accelerometer(
        &self,
        t_ms: &Bound<'_, PyAny>,
        x: f64,
        y: f64,
        z: f64,
    ) -> PyResult<Option<PyEstimate>> {
        self.push_xyz(t_ms, [x, y, z], Sample::Accelerometer)
    }

    /// Feeds a gyroscope sample (rad/s); returns None (attitude only).
    fn push_gyroscope(
        &self,
        t_ms: &Bound<'_, PyAny>,
        x: f64,
        y: f64,
        z: f64,
    ) -> PyResult<Option<PyEstimate>> {
        self.push_xyz(t_ms, [x, y, z], Sample::Gyroscope)
    }

    /// Feeds a magnetometer sample (µT); returns None (attitude only).
    fn push_magnetometer(
        &self,
        t_ms: &Bound<'_, PyAny>,
        x: f64,
        y: f64,
        z: f64,
    ) -> PyResult<Option<PyEstimate>> {
        self.push_xyz(t_ms, [x, y, z], Sample::Magnetometer)
    }

    /// Feeds a rotation-vector sample (x, y, z of the attitude quaternion); returns None.
    fn push_rotation_vector(
        &self,
        t_ms: &Bound<'_, PyAny>,
        x: f64,
        y: f64,
        z: f64,
    ) -> PyResult<Option<PyEstimate>> {
        self.push_xyz(t_ms, [x, y, z], |s| {
            Sample::RotationVector(wipdr_core::RotationVectorSample {
                t: s.t,
                v: s.v,
                accuracy: s.accuracy,
            })
        })
    }

    /// Feeds a barometer sample (hPa); returns None (it moves the floor estimate only).
    fn push_pressure(&self, t_ms: &Bound<'_, PyAny>, hpa: f64) -> PyResult<Option<PyEstimate>> {
        let t = time_of(t_ms, "t_ms")?;
        if !hpa.is_finite() {
            return Err(input_error(format!(
                "push_pressure: hpa must be finite, got {hpa}"
            )));
        }
        self.push(Sample::Pressure(wipdr_positioning::PressureSample {
            t,
            hpa,
        }))
    }

    /// Feeds a Wi-Fi scan: ``entries`` ``[(bssid, rssi_dbm), ...]`` or ``[(bssid,
    /// rssi_dbm, last_seen_ms), ...]`` (BSSID as ``"aa:bb:cc:dd:ee:ff"`` or an int).
    /// Returns the new estimate when the scan was matched, else None.
    fn push_scan(
        &self,
        t_ms: &Bound<'_, PyAny>,
        entries: &Bound<'_, PyAny>,
    ) -> PyResult<Option<PyEstimate>> {
        let t = time_of(t_ms, "t_ms")?;
        let entries = entries_of(entries, "push_scan entries")?;
        self.push(Sample::Wifi(scan_of(t, entries)))
    }

    /// The current estimate (None until the scheme has one).
    fn estimate(&self) -> PyResult<Option<PyEstimate>> {
        Ok(self
            .stream()?
            .positioner
            .estimate()
            .map(|e| PyEstimate::of(&e)))
    }

    /// Every estimate returned so far (and, with a ``start``, one at its time first), as a
    /// ``(n, 5)`` float64 array ``t_ms, x, y, floor, sd_m`` (NaN where unknown): the rows
    /// ``wipdr locate`` writes.
    fn track<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        Ok(track_array(py, &self.stream()?.track))
    }

    /// The whole stream so far smoothed offline (estimates that use the inputs after their
    /// time: ``pmf``'s forward-backward product on its lattice, the two-filter smoother for
    /// the other schemes), as a ``(n, 5)`` array like :meth:`track`; the
    /// ``wipdr eval --offline`` track of this stream. Raises ``ValueError`` for a positioner
    /// built with a ``start`` (a known start is not smoothed).
    fn smooth<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let track = self
            .stream()?
            .positioner
            .smooth()
            .map_err(|e| input_error(format!("Positioner.smooth: {}", chain(&e))))?;
        Ok(track_array(py, &track))
    }

    /// What the stream received: samples, out_of_order, steps, scans, unmatched_scans,
    /// pressure, off_floor_fixes.
    fn counts(&self) -> PyResult<std::collections::BTreeMap<&'static str, u64>> {
        let c = self.stream()?.positioner.counts();
        Ok([
            ("samples", c.samples),
            ("out_of_order", c.out_of_order),
            ("steps", c.steps),
            ("scans", c.scans),
            ("unmatched_scans", c.unmatched_scans),
            ("pressure", c.pressure),
            ("off_floor_fixes", c.off_floor_fixes),
        ]
        .into_iter()
        .collect())
    }
}

impl PyPositioner {
    fn stream(&self) -> PyResult<std::sync::MutexGuard<'_, Stream>> {
        self.inner.lock().map_err(|_| {
            input_error("Positioner: a push failed in another thread; build a new one")
        })
    }

    /// A three-axis sample (finite values) through [`Self::push`].
    fn push_xyz(
        &self,
        t_ms: &Bound<'_, PyAny>,
        v: [f64; 3],
        make: fn(wipdr_core::Vec3Sample) -> Sample,
    ) -> PyResult<Option<PyEstimate>> {
        let t = time_of(t_ms, "t_ms")?;
        if v.iter().any(|c| !c.is_finite()) {
            return Err(input_error(format!(
                "sample at t_ms={t}: values must be finite, got {v:?}"
            )));
        }
        self.push(make(wipdr_core::Vec3Sample { t, v, accuracy: 3 }))
    }

    /// One sample through the pipeline as `track_of` streams a recorded walk.
    fn push(&self, sample: Sample) -> PyResult<Option<PyEstimate>> {
        let mut s = self.stream()?;
        let t = sample.t();
        if s.start.is_some_and(|(t0, _)| t < t0) {
            s.positioner.warm_up(&sample);
            return Ok(None);
        }
        let Some(mut e) = s.positioner.push(&sample) else {
            return Ok(None);
        };
        e.t = t;
        let out = PyEstimate::of(&e);
        s.track.push(e);
        Ok(Some(out))
    }
}

//! `wipdr.evaluate` and `wipdr.locate`: the evaluation protocol and one located walk.

use crate::convert::config_of;
use crate::errors::{PyErrorKind, eval_error, input_error, io_error, py_error};
use crate::floor::{PyFloor, PyFloorPlan, read_floor_dir};
use crate::positioner::track_array;
use crate::walk::PyWalk;
use numpy::PyArray2;
use pyo3::prelude::*;
use std::path::PathBuf;
use std::sync::Arc;
use wipdr_core::ConfigError;
use wipdr_core::Floor as CoreFloor;
use wipdr_eval::fold_model::FoldModel;
use wipdr_eval::pipeline::{self, FloorInput};

/// One item of `evaluate`'s `data`: a folder to read or a floor already read.
enum DataItem {
    Dir(PathBuf),
    Floor(FloorInput),
}

/// Runs the evaluation protocol of ``wipdr eval`` and returns exactly the document
/// ``wipdr eval --json`` writes: ``{"pooled": {scheme: Summary}, "floors": {floor: {scheme:
/// Summary}}, "walks": [...], "schemes": [...], "config": {...}}`` with ``Summary = {count,
/// skipped, mean, rms, p50, p75, p95, max, floor_hit_rate, evaal}``.
///
/// ``data`` is a list of folder paths (read as :func:`read_floor` reads them, labelled
/// ``parent/name`` as the CLI labels them) or :class:`Floor` objects (labelled by their
/// name); ``schemes`` a list of scheme names; ``config`` None, a path to a TOML config or a
/// dict of its fields. The work runs in Rust on the rayon thread pool (all cores; set
/// ``RAYON_NUM_THREADS`` to limit it) with the GIL released. A scheme that scores no
/// waypoint raises :class:`InputError`, as the CLI fails.
///
/// ``offline=True`` scores every scheme but ``pdr`` on its whole-walk smoothed track (the
/// scheme run forward and on the reversed walk, combined), as ``wipdr eval --offline``;
/// the document's ``"mode"`` says which.
#[pyfunction]
#[pyo3(signature = (data, schemes, config=None, offline=false))]
pub fn evaluate(
    py: Python<'_>,
    data: Vec<Bound<'_, PyAny>>,
    schemes: Vec<String>,
    config: Option<&Bound<'_, PyAny>>,
    offline: bool,
) -> PyResult<Py<PyAny>> {
    if data.is_empty() {
        return Err(input_error("evaluate: data is empty"));
    }
    if schemes.is_empty() {
        return Err(input_error("evaluate: schemes is empty"));
    }
    let mut cfg = config_of(config)?;
    cfg.offline |= offline;
    for s in &schemes {
        cfg.scheme(s).map_err(|e| eval_error(&e))?;
    }
    let mut items = Vec::with_capacity(data.len());
    for (i, d) in data.iter().enumerate() {
        if let Ok(floor) = d.extract::<PyFloor>() {
            items.push(DataItem::Floor(floor.input()));
        } else if let Ok(path) = d.extract::<PathBuf>() {
            items.push(DataItem::Dir(path));
        } else {
            return Err(input_error(format!(
                "evaluate: data[{i}]: expected a folder path or a Floor"
            )));
        }
    }
    let mut floors = Vec::with_capacity(items.len());
    for item in items {
        floors.push(match item {
            DataItem::Floor(f) => f,
            DataItem::Dir(dir) => {
                if !dir.is_dir() {
                    return Err(py_error(
                        PyErrorKind::Data,
                        format!("{}: not a folder", dir.display()),
                    ));
                }
                let floor = py
                    .detach(|| read_floor_dir(&dir, None))
                    .map_err(|e| io_error(&e))?;
                floor.input().with_dir(dir)
            }
        });
    }
    let text = py
        .detach(|| -> Result<String, wipdr_eval::pipeline::EvalError> {
            let report = pipeline::evaluate(&floors, &cfg, &schemes, &|| {})?;
            let unscored = report.unscored_schemes();
            if !unscored.is_empty() {
                return Err(wipdr_eval::pipeline::EvalError::InvalidConfig(
                    ConfigError::new(
                        "schemes",
                        format!(
                            "no waypoint was scored for {} (empty test set, no matched query, or \
                         a scoring start beyond every waypoint)",
                            unscored.join(", ")
                        ),
                    ),
                ));
            }
            Ok(report.to_json(&cfg).to_string())
        })
        .map_err(|e| match e {
            wipdr_eval::pipeline::EvalError::InvalidConfig(ConfigError { path, reason })
                if path == "schemes" =>
            {
                input_error(reason)
            }
            e => eval_error(&e),
        })?;
    Ok(py
        .import("json")?
        .getattr("loads")?
        .call1((text,))?
        .unbind())
}

/// Locates ``walk`` as ``wipdr locate`` does: a radio map, coverage, trails, PDR
/// calibration and barometric references learned from ``training`` (a list of
/// :class:`Walk` or a :class:`Floor`; a training walk with ``walk``'s id is left out), then
/// the walk's raw samples streamed one by one through a :class:`Positioner` running
/// ``scheme`` (seed mixed with the walk's id; ``pdr`` starts at the true first waypoint).
/// Returns the track, ``(n, 5)`` float64 ``t_ms, x, y, floor, sd_m`` (NaN where unknown), one
/// row per estimate (after each step or matched scan).
///
/// To reproduce ``wipdr locate --data FLOOR --walk ID`` on an ILC floor (the protocol's
/// fold), pass the walks of the other folds (:meth:`Floor.folds`); for an IPIN logfile
/// (every other logfile of its folder), pass the floor.
#[pyfunction]
#[pyo3(signature = (walk, training, scheme, config=None, floor_plan=None))]
pub fn locate<'py>(
    py: Python<'py>,
    walk: PyWalk,
    training: &Bound<'py, PyAny>,
    scheme: &str,
    config: Option<&Bound<'py, PyAny>>,
    floor_plan: Option<PyFloorPlan>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let cfg = config_of(config)?;
    cfg.scheme(scheme).map_err(|e| eval_error(&e))?;
    let (name, plan, geo_frame, mut walks) = if let Ok(floor) = training.extract::<PyFloor>() {
        let f = &floor.inner;
        (f.name.clone(), f.plan.clone(), f.geo_frame, f.walks.clone())
    } else {
        let list: Vec<PyWalk> = training
            .extract()
            .map_err(|_| input_error("training: expected a list of Walk objects or a Floor"))?;
        let walks: Vec<wipdr_core::Walk> = list.into_iter().map(|w| w.inner).collect();
        let all = walks.iter().chain(std::iter::once(&walk.inner));
        let plan = crate::floor::plan_around_walks(all)?;
        ("walks".to_string(), plan, None, walks)
    };
    let id = walk.inner.meta.id.clone();
    walks.retain(|w| w.meta.id != id);
    if walks.is_empty() {
        return Err(input_error(format!(
            "locate: no training walk besides {id:?}"
        )));
    }
    let plan = floor_plan.map(|p| p.inner).unwrap_or(plan);
    walks.push(walk.inner);
    let mut floor = CoreFloor::new(name.clone(), plan, walks);
    floor.geo_frame = geo_frame;
    let input = FloorInput {
        label: name,
        data: Arc::new(floor),
        dir: None,
        odometry: None,
        input_skips: Default::default(),
    };
    let index = input
        .data
        .walks
        .iter()
        .position(|w| w.meta.id == id)
        .ok_or_else(|| input_error("locate: the walk was lost"))?;
    let training: Vec<usize> = (0..input.data.walks.len())
        .filter(|&i| i != index)
        .collect();
    let track = py
        .detach(|| {
            let model =
                FoldModel::build_on(&input, usize::MAX, &training, vec![index], &cfg, None)?;
            pipeline::locate_on_model(&input, &model, index, scheme, &cfg)
        })
        .map_err(|e| eval_error(&e))?;
    Ok(track_array(py, &track))
}

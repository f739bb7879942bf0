//! `wipdr.FloorPlan`, `wipdr.Floor` and `wipdr.read_floor`.

use crate::convert::{f64_rows, to_array};
use crate::errors::{PyErrorKind, input_error, io_error, py_error};
use crate::walk::PyWalk;
use numpy::PyArray2;
use pyo3::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use wipdr_core::{Floor as CoreFloor, FloorPlan, Point2, Polygon, Segment};
use wipdr_eval::pipeline::FloorInput;
use wipdr_io::cache::CacheSettings;

/// A floor plan in the walks' metre frame: its extent, outline polygons (walkable space)
/// and wall segments (the edges of the outline and units, plus any given).
///
/// >>> plan = wipdr.FloorPlan(20.0, 10.0, outline=[[[0, 0], [20, 0], [20, 10], [0, 10]]])
/// >>> plan.walls.shape
/// (4, 4)
#[pyclass(module = "wipdr", name = "FloorPlan", from_py_object)]
#[derive(Debug, Clone)]
pub struct PyFloorPlan {
    /// The plan.
    pub inner: FloorPlan,
}

#[pymethods]
impl PyFloorPlan {
    /// A plan of ``width`` x ``height`` metres; ``outline`` a list of polygons, each a
    /// ``(k, 2)`` array of vertices (none: no walkable space is known, so map matching and
    /// ``pmf``'s walkability are off); ``walls`` a ``(n, 4)`` array of extra segments
    /// ``x0, y0, x1, y1``.
    #[new]
    #[pyo3(signature = (width, height, *, outline=None, walls=None))]
    fn new(
        width: f64,
        height: f64,
        outline: Option<Vec<Bound<'_, PyAny>>>,
        walls: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let mut polygons = Vec::new();
        for (i, p) in outline.unwrap_or_default().iter().enumerate() {
            let name = format!("outline[{i}]");
            let a = f64_rows(p, 2, &name)?;
            let vertices: Vec<Point2> = a
                .rows()
                .into_iter()
                .map(|r| Point2::new(r[0], r[1]))
                .collect();
            polygons.push(
                Polygon::new(vertices, Vec::new())
                    .map_err(|e| input_error(format!("{name}: {e}")))?,
            );
        }
        let mut plan = FloorPlan::new(width, height, polygons, Vec::new())
            .map_err(|e| input_error(format!("FloorPlan: {e}")))?;
        if let Some(walls) = walls.filter(|w| !w.is_none()) {
            let a = f64_rows(walls, 4, "walls")?;
            for (i, r) in a.rows().into_iter().enumerate() {
                if r.iter().any(|v| !v.is_finite()) {
                    return Err(input_error(format!(
                        "walls[{i}]: coordinates must be finite"
                    )));
                }
                plan.walls.push(Segment {
                    a: Point2::new(r[0], r[1]),
                    b: Point2::new(r[2], r[3]),
                });
            }
        }
        Ok(Self { inner: plan })
    }

    /// Width (x extent), metres.
    #[getter]
    fn width(&self) -> f64 {
        self.inner.width
    }

    /// Height (y extent), metres.
    #[getter]
    fn height(&self) -> f64 {
        self.inner.height
    }

    /// Wall segments, ``(n, 4)`` float64: ``x0, y0, x1, y1``.
    #[getter]
    fn walls<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let w = &self.inner.walls;
        to_array(py, 4, w.iter().map(|s| vec![s.a.x, s.a.y, s.b.x, s.b.y]))
    }

    /// Outline polygons, each a ``(k, 2)`` float64 array of vertices.
    #[getter]
    fn outline<'py>(&self, py: Python<'py>) -> Vec<Bound<'py, PyArray2<f64>>> {
        self.inner
            .outline
            .iter()
            .map(|p| to_array(py, 2, p.exterior.iter().map(|v| vec![v.x, v.y])))
            .collect()
    }

    fn __repr__(&self) -> String {
        format!(
            "FloorPlan({} x {} m, {} outline polygons, {} walls)",
            self.inner.width,
            self.inner.height,
            self.inner.outline.len(),
            self.inner.walls.len()
        )
    }
}

/// A floor (or a building of several floors): a plan and walks, as :func:`read_floor`
/// reads an ILC floor folder, an ILC site folder or a folder of IPIN logfiles, or built
/// from your own :class:`Walk` objects. Walks are sorted by id (the protocol's folds follow
/// that order).
#[pyclass(module = "wipdr", name = "Floor", from_py_object)]
#[derive(Debug, Clone)]
pub struct PyFloor {
    /// The floor.
    pub inner: Arc<CoreFloor>,
    /// Walk files that could not be read (file, error).
    pub skipped: Vec<(String, String)>,
    /// What the readers skipped, by kind (empty for a floor built from arrays): the
    /// evaluation reports them as `wipdr eval` does (`skips`).
    pub skip_counts: wipdr_eval::report::InputSkips,
}

/// Margin of a plan made from the waypoints' extent, metres (as IPIN folders).
pub const DEFAULT_PLAN_MARGIN_M: f64 = 30.0;

/// A plan without outline or walls covering `points`, [`DEFAULT_PLAN_MARGIN_M`] beyond
/// the largest coordinates.
pub fn plan_around(points: impl Iterator<Item = Point2>) -> PyResult<FloorPlan> {
    let (mut w, mut h) = (1.0f64, 1.0f64);
    for p in points {
        w = w.max(p.x);
        h = h.max(p.y);
    }
    let m = DEFAULT_PLAN_MARGIN_M;
    FloorPlan::new(w + m, h + m, Vec::new(), Vec::new())
        .map_err(|e| input_error(format!("plan from the positions: {e}")))
}

/// [`plan_around`] the waypoints of `walks`.
pub fn plan_around_walks<'a>(
    walks: impl Iterator<Item = &'a wipdr_core::Walk>,
) -> PyResult<FloorPlan> {
    plan_around(walks.flat_map(|w| &w.waypoints).map(|w| w.position))
}

#[pymethods]
impl PyFloor {
    /// A floor of ``walks`` (:class:`Walk` objects) with ``plan`` (:class:`FloorPlan`;
    /// none: a plan without outline or walls reaching 30 m beyond the largest waypoint
    /// coordinates, so wall- and walkability-aware schemes run without a map).
    #[new]
    #[pyo3(signature = (walks, plan=None, name="floor".to_string()))]
    fn new(walks: Vec<PyWalk>, plan: Option<PyFloorPlan>, name: String) -> PyResult<Self> {
        let walks: Vec<wipdr_core::Walk> = walks.into_iter().map(|w| w.inner).collect();
        let mut ids: Vec<&str> = walks.iter().map(|w| w.meta.id.as_str()).collect();
        ids.sort_unstable();
        if let Some(pair) = ids.windows(2).find(|p| p[0] == p[1]) {
            return Err(input_error(format!(
                "Floor: two walks with id {:?}",
                pair[0]
            )));
        }
        let plan = match plan {
            Some(p) => p.inner,
            None => plan_around_walks(walks.iter())?,
        };
        Ok(Self {
            inner: Arc::new(CoreFloor::new(name, plan, walks)),
            skipped: Vec::new(),
            skip_counts: Default::default(),
        })
    }

    /// The floor's name (``site1/F1`` for a folder: its parent's name and its own).
    #[getter]
    fn name(&self) -> &str {
        &self.inner.name
    }

    /// The floor plan.
    #[getter]
    fn plan(&self) -> PyFloorPlan {
        PyFloorPlan {
            inner: self.inner.plan.clone(),
        }
    }

    /// The walks, sorted by id (copies: changing one does not change the floor).
    #[getter]
    fn walks(&self) -> Vec<PyWalk> {
        self.inner
            .walks
            .iter()
            .map(|w| PyWalk { inner: w.clone() })
            .collect()
    }

    /// The walk ids, in the floor's order.
    #[getter]
    fn walk_ids(&self) -> Vec<String> {
        self.inner.walks.iter().map(|w| w.meta.id.clone()).collect()
    }

    /// The walk with id ``walk_id``; KeyError when there is none.
    fn walk(&self, walk_id: &str) -> PyResult<PyWalk> {
        self.inner
            .walks
            .iter()
            .find(|w| w.meta.id == walk_id)
            .map(|w| PyWalk { inner: w.clone() })
            .ok_or_else(|| {
                pyo3::exceptions::PyKeyError::new_err(format!(
                    "floor {}: no walk {walk_id:?}",
                    self.inner.name
                ))
            })
    }

    /// The evaluation protocol's fold of each walk (walk ``i`` in fold ``i mod 5``, or by
    /// route where every walk has one: leave-one-route-out).
    fn folds(&self) -> Vec<usize> {
        wipdr_eval::fold_rules::folds_of_walks(&self.inner.walks).0
    }

    /// Walk files that could not be read when the folder was read: ``[(file, error)]``.
    #[getter]
    fn skipped_walks(&self) -> Vec<(String, String)> {
        self.skipped.clone()
    }

    /// What the readers skipped when the folder was read, ``{kind: count}`` (the ``skips``
    /// of ``wipdr eval --json`` for this floor; empty for a floor built from arrays).
    #[getter]
    fn skips(&self) -> std::collections::BTreeMap<String, usize> {
        self.skip_counts.clone()
    }

    fn __len__(&self) -> usize {
        self.inner.walks.len()
    }

    fn __repr__(&self) -> String {
        format!(
            "Floor({:?}: {} walks, plan {} x {} m)",
            self.inner.name,
            self.inner.walks.len(),
            self.inner.plan.width,
            self.inner.plan.height
        )
    }
}

impl PyFloor {
    /// The floor as an evaluation input, labelled by its name.
    pub fn input(&self) -> FloorInput {
        FloorInput {
            label: self.inner.name.clone(),
            data: self.inner.clone(),
            dir: None,
            odometry: None,
            input_skips: self.skip_counts.clone(),
        }
    }
}

/// The cache of this run: `$WIPDR_CACHE_DIR` when set (as the CLI), else off.
fn cache_settings(cache_dir: Option<PathBuf>) -> CacheSettings {
    let dir = cache_dir.or_else(|| {
        std::env::var_os("WIPDR_CACHE_DIR")
            .filter(|v| !v.is_empty())
            .map(PathBuf::from)
    });
    match dir {
        Some(dir) => CacheSettings::in_dir(dir),
        None => CacheSettings::disabled(),
    }
}

/// Reads a folder as `wipdr eval --data` does, labelled as the CLI labels it.
pub fn read_floor_dir(
    dir: &Path,
    cache_dir: Option<PathBuf>,
) -> Result<PyFloor, wipdr_io::IoError> {
    let settings = cache_settings(cache_dir);
    let (data, _) =
        wipdr_io::any::read_any_dir(dir, &settings, &wipdr_io::ReadOptions::default(), &|| {})?;
    let skip_counts = data.skip_counts();
    let skipped = data
        .skipped_walks
        .iter()
        .map(|s| (s.path.display().to_string(), s.error.clone()))
        .collect();
    let mut floor = data.into_floor();
    floor.name = wipdr_io::floor::floor_name(dir);
    Ok(PyFloor {
        inner: Arc::new(floor),
        skipped,
        skip_counts,
    })
}

/// Reads a floor folder: an ILC 2.0 floor (``path_data_files/``, ``floor_info.json``,
/// ``geojson_map.json``), an ILC site folder (``F1/``, ``F2/``, ... as one building) or a
/// folder of IPIN logfiles (one building), exactly as ``wipdr eval --data`` reads it.
/// Unreadable walk files are skipped and listed in :attr:`Floor.skipped_walks`. The parse
/// cache is used when ``cache_dir`` or ``$WIPDR_CACHE_DIR`` names a folder.
#[pyfunction]
#[pyo3(signature = (dir, cache_dir=None))]
pub fn read_floor(py: Python<'_>, dir: PathBuf, cache_dir: Option<PathBuf>) -> PyResult<PyFloor> {
    if !dir.is_dir() {
        return Err(py_error(
            PyErrorKind::Data,
            format!("{}: not a folder", dir.display()),
        ));
    }
    py.detach(|| read_floor_dir(&dir, cache_dir))
        .map_err(|e| io_error(&e))
}

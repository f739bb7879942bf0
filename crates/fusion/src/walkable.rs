//! Walkable space of a floor plan as a raster, and map matching (paper 004 §4: "map matching
//! is used to further reduce the error").
//!
//! [`WalkableGrid`] classifies square cells of a floor plan by their centre: outside the floor
//! outline, inside a unit (a shop, a service room) or walkable (inside the outline and in no
//! unit). Rasterisation is a scanline fill with the even-odd rule over every ring, so holes
//! are handled and building it costs `O(rows x edges)`. Each non-walkable cell also stores the
//! nearest walkable cell (a multi-source breadth-first propagation of nearest seeds over the
//! 8-neighbourhood, which is within a fraction of a cell of the exact Euclidean answer).
//!
//! [`WalkableGrid::map_match`] projects a point that is not walkable onto the nearest walkable
//! point: it first tests the point exactly against the plan's polygons, so a walkable point is
//! never moved, then snaps to the nearest walkable cell and refines onto the boundary between
//! that cell and the point (a bisection on the segment, exact polygon tests), so the answer is
//! walkable and close to the true projection. Only the floor plan is used, never training
//! waypoints.
//!
//! [`MapMatched`] wraps any [`Fuser`] and map-matches its output causally (each estimate on its
//! own, from the plan alone); the wrapped scheme's state is not changed.
//!
//! ```
//! use wipdr_core::{FloorPlan, Point2, Polygon, Unit};
//! use wipdr_fusion::walkable::WalkableGrid;
//!
//! let square = |x0: f64, y0: f64, s: f64| Polygon::new(vec![Point2::new(x0, y0),
//!     Point2::new(x0 + s, y0), Point2::new(x0 + s, y0 + s), Point2::new(x0, y0 + s)], vec![]).unwrap();
//! let plan = FloorPlan::new(20.0, 20.0, vec![square(0.0, 0.0, 20.0)],
//!     vec![Unit { name: "shop".into(), polygon: square(5.0, 5.0, 10.0) }]).unwrap();
//! let grid = WalkableGrid::new(&plan, 0.5).unwrap();
//! // A point in the corridor is kept; a point inside the shop goes to its nearest wall.
//! assert_eq!(grid.map_match(Point2::new(2.0, 2.0)), Point2::new(2.0, 2.0));
//! let p = grid.map_match(Point2::new(6.0, 10.0));
//! assert!(plan.is_walkable(p) && (p.x - 5.0).abs() < 0.6);
//! ```

use std::collections::VecDeque;
use std::sync::Arc;
use wipdr_core::ConfigError;

use serde::{Deserialize, Serialize};
use wipdr_core::{FloorPlan, GridSpec, Point2, Polygon, StepEvent, WifiObservation};

use crate::{Estimate, Fuser, FusionError, WeightedPoint};

/// Class of a grid cell (by its centre).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[repr(u8)]
pub enum CellClass {
    /// Outside every outline polygon.
    Outside = 0,
    /// Inside the outline and inside a unit.
    Unit = 1,
    /// Inside the outline and in no unit.
    Walkable = 2,
}

/// Most cells a grid may have (64 M: a 4 km x 4 km floor at 0.5 m).
pub const MAX_CELLS: usize = 64 << 20;

/// A raster of a floor plan's walkable space; see the [module docs](self).
#[derive(Debug, Clone)]
pub struct WalkableGrid {
    plan: Arc<FloorPlan>,
    unit_boxes: Vec<(Point2, Point2)>,
    grid: GridSpec,
    class: Vec<CellClass>,
    /// For each cell, the index of the nearest walkable cell (`u32::MAX` when the plan has
    /// no walkable cell at all).
    nearest: Vec<u32>,
}

fn fill_rings(rings: &[&[Point2]], grid: &GridSpec, mut set: impl FnMut(usize)) {
    let mut xs: Vec<f64> = Vec::new();
    for row in 0..grid.rows() {
        let y = grid.centre_y(row);
        xs.clear();
        for ring in rings {
            let n = ring.len();
            for i in 0..n {
                let (a, b) = (ring[i], ring[(i + 1) % n]);
                if (a.y > y) != (b.y > y) {
                    xs.push((b.x - a.x) * (y - a.y) / (b.y - a.y) + a.x);
                }
            }
        }
        xs.sort_by(f64::total_cmp);
        for pair in xs.chunks_exact(2) {
            for col in grid.cols_with_centre_in(pair[0], pair[1]) {
                set(grid.index(col, row));
            }
        }
    }
}

fn polygon_rings(p: &Polygon) -> Vec<&[Point2]> {
    std::iter::once(p.exterior.as_slice())
        .chain(p.holes.iter().map(|h| h.as_slice()))
        .collect()
}

impl WalkableGrid {
    /// Rasterises `plan` at `cell_m` metres per cell over the plan's extent (outline bounding
    /// box and `[0, width] x [0, height]`, whichever is larger).
    pub fn new(plan: &FloorPlan, cell_m: f64) -> Result<Self, FusionError> {
        let invalid = |reason: String| {
            FusionError::InvalidConfig(ConfigError::new("walkable.cell_m", reason))
        };
        if !(cell_m.is_finite() && cell_m > 0.0) {
            return Err(invalid(format!("must be finite and > 0, got {cell_m}")));
        }
        let mut lo = Point2::new(0.0, 0.0);
        let mut hi = Point2::new(plan.width, plan.height);
        for o in &plan.outline {
            let (a, b) = o.bbox();
            lo = Point2::new(lo.x.min(a.x), lo.y.min(a.y));
            hi = Point2::new(hi.x.max(b.x), hi.y.max(b.y));
        }
        let grid = GridSpec::covering(lo, hi, cell_m, MAX_CELLS)
            .map_err(|e| invalid(format!("no walkable grid over this plan: {e}")))?;
        let mut class = vec![CellClass::Outside; grid.len()];
        for o in &plan.outline {
            fill_rings(&polygon_rings(o), &grid, |i| class[i] = CellClass::Walkable);
        }
        for u in &plan.units {
            fill_rings(&polygon_rings(&u.polygon), &grid, |i| {
                if class[i] == CellClass::Walkable {
                    class[i] = CellClass::Unit;
                }
            });
        }
        let nearest = nearest_walkable(&class, &grid);
        Ok(Self {
            unit_boxes: plan.units.iter().map(|u| u.polygon.bbox()).collect(),
            plan: Arc::new(plan.clone()),
            grid,
            class,
            nearest,
        })
    }

    /// The plan this grid rasterises.
    pub fn plan(&self) -> &FloorPlan {
        &self.plan
    }

    /// The raster's cells.
    pub fn grid(&self) -> &GridSpec {
        &self.grid
    }

    /// Cell size, metres.
    pub fn cell_m(&self) -> f64 {
        self.grid.cell_m()
    }

    /// Lower-left corner of the grid, metres.
    pub fn origin(&self) -> Point2 {
        self.grid.origin()
    }

    /// Columns and rows.
    pub fn dims(&self) -> (usize, usize) {
        self.grid.dims()
    }

    /// Cell index of `p` (row-major), `None` outside the grid or non-finite.
    pub fn cell_of(&self, p: Point2) -> Option<usize> {
        self.grid.index_of(p)
    }

    /// Centre of cell `i` (row-major index).
    pub fn centre(&self, i: usize) -> Point2 {
        self.grid.centre_of_index(i)
    }

    /// Class of the cell containing `p` (outside the grid: [`CellClass::Outside`]).
    pub fn class_at(&self, p: Point2) -> CellClass {
        self.cell_of(p)
            .map_or(CellClass::Outside, |i| self.class[i])
    }

    /// Class of cell `i`.
    pub fn class_of_cell(&self, i: usize) -> CellClass {
        self.class[i]
    }

    /// Mean over the grid's cells of a per-class weight: 1 for walkable cells, `unit` in a
    /// unit, `outside` outside the outline (`pmf`'s step weight of a hypothesis anywhere).
    pub fn mean_class_weight(&self, unit: f64, outside: f64) -> f64 {
        let sum: f64 = self
            .class
            .iter()
            .map(|c| match c {
                CellClass::Walkable => 1.0,
                CellClass::Unit => unit,
                CellClass::Outside => outside,
            })
            .sum();
        sum / self.class.len().max(1) as f64
    }

    /// Share of walkable cells.
    pub fn walkable_fraction(&self) -> f64 {
        let n = self
            .class
            .iter()
            .filter(|c| **c == CellClass::Walkable)
            .count();
        n as f64 / self.class.len().max(1) as f64
    }

    /// Exact test against the plan's polygons: inside the outline and in no unit.
    pub fn is_walkable(&self, p: Point2) -> bool {
        if !(p.x.is_finite() && p.y.is_finite() && self.plan.inside_outline(p)) {
            return false;
        }
        !self
            .unit_boxes
            .iter()
            .zip(&self.plan.units)
            .any(|((lo, hi), u)| {
                p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y && u.polygon.contains(p)
            })
    }

    /// The nearest walkable point to `p`; `p` itself when it is walkable (exact test), or when
    /// the plan has no walkable space or `p` is not finite.
    pub fn map_match(&self, p: Point2) -> Point2 {
        if !(p.x.is_finite() && p.y.is_finite()) || self.is_walkable(p) {
            return p;
        }
        let target = match self.cell_of(p) {
            Some(i) => self.nearest[i],
            None => {
                // Outside the grid: clamp into it, then look up.
                let (lo, hi) = (self.grid.origin(), self.grid.far_corner());
                let q = Point2::new(p.x.clamp(lo.x, hi.x - 1e-9), p.y.clamp(lo.y, hi.y - 1e-9));
                self.cell_of(q).map_or(u32::MAX, |i| self.nearest[i])
            }
        };
        if target == u32::MAX {
            return p;
        }
        let mut inside = self.centre(target as usize);
        if !self.is_walkable(inside) {
            // A cell centre classed walkable by the raster but not by the exact test (a
            // boundary through the centre): keep the original point rather than guess.
            return p;
        }
        // Bisection towards p along the segment: the walkable point closest to p on it.
        let mut outside = p;
        for _ in 0..20 {
            let mid = Point2::new((inside.x + outside.x) / 2.0, (inside.y + outside.y) / 2.0);
            if self.is_walkable(mid) {
                inside = mid;
            } else {
                outside = mid;
            }
        }
        inside
    }
}

/// Multi-source BFS of the nearest walkable cell (8-neighbourhood, each cell keeps the seed
/// whose centre is closest among those offered by its neighbours).
fn nearest_walkable(class: &[CellClass], grid: &GridSpec) -> Vec<u32> {
    let nx = grid.cols();
    let mut nearest = vec![u32::MAX; class.len()];
    let mut queue = VecDeque::new();
    for (i, c) in class.iter().enumerate() {
        if *c == CellClass::Walkable {
            nearest[i] = i as u32;
            queue.push_back(i);
        }
    }
    let d2 = |a: usize, b: usize| {
        let (ar, ac) = ((a / nx) as i64, (a % nx) as i64);
        let (br, bc) = ((b / nx) as i64, (b % nx) as i64);
        (ar - br).pow(2) + (ac - bc).pow(2)
    };
    while let Some(i) = queue.pop_front() {
        let seed = nearest[i] as usize;
        let (col, row) = grid.col_row(i);
        for (c, r) in grid.neighbours8(col, row) {
            let j = grid.index(c, r);
            if nearest[j] == u32::MAX || d2(j, seed) < d2(j, nearest[j] as usize) {
                let first = nearest[j] == u32::MAX;
                nearest[j] = seed as u32;
                if first || class[j] != CellClass::Walkable {
                    queue.push_back(j);
                }
            }
        }
    }
    nearest
}

/// Any scheme with its output map-matched onto walkable space (paper 004 §4); see the
/// [module docs](self).
pub struct MapMatched {
    inner: Box<dyn Fuser + Send>,
    grid: Arc<WalkableGrid>,
}

impl MapMatched {
    /// Wraps `inner`.
    pub fn new(inner: Box<dyn Fuser + Send>, grid: Arc<WalkableGrid>) -> Self {
        Self { inner, grid }
    }
}

impl Fuser for MapMatched {
    fn name(&self) -> &'static str {
        self.inner.name()
    }
    fn on_step(&mut self, step: &StepEvent) {
        self.inner.on_step(step);
    }
    fn on_wifi(&mut self, obs: &WifiObservation) {
        self.inner.on_wifi(obs);
    }
    fn estimate(&self) -> Option<Estimate> {
        self.inner.estimate().map(|mut e| {
            e.position = self.grid.map_match(e.position);
            e
        })
    }
    fn particle_cloud(&self) -> Option<Vec<WeightedPoint>> {
        self.inner.particle_cloud()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use wipdr_core::Unit;

    fn square(x0: f64, y0: f64, s: f64) -> Polygon {
        Polygon::rectangle(x0, y0, x0 + s, y0 + s).unwrap()
    }

    fn plan() -> FloorPlan {
        FloorPlan::new(
            40.0,
            30.0,
            vec![square(0.0, 0.0, 30.0)],
            vec![
                Unit {
                    name: "a".into(),
                    polygon: square(5.0, 5.0, 8.0),
                },
                Unit {
                    name: "b".into(),
                    polygon: square(18.0, 18.0, 6.0),
                },
            ],
        )
        .unwrap()
    }

    #[test]
    fn raster_agrees_with_exact_test_at_cell_centres() {
        let plan = plan();
        let grid = WalkableGrid::new(&plan, 0.5).unwrap();
        let (nx, ny) = grid.dims();
        assert_eq!((nx, ny), (80, 60));
        for i in 0..nx * ny {
            let c = grid.centre(i);
            let exact = if !plan.inside_outline(c) {
                CellClass::Outside
            } else if plan.unit_at(c).is_some() {
                CellClass::Unit
            } else {
                CellClass::Walkable
            };
            assert_eq!(grid.class_of_cell(i), exact, "cell {i} at {c:?}");
        }
        let expected = (900.0 - 64.0 - 36.0) / 1200.0;
        assert!((grid.walkable_fraction() - expected).abs() < 1e-9);
    }

    #[test]
    fn map_match_goes_to_the_nearest_wall() {
        let plan = plan();
        let grid = WalkableGrid::new(&plan, 0.5).unwrap();
        // Inside unit a near its left wall (x = 5).
        let p = grid.map_match(Point2::new(6.0, 9.0));
        assert!(plan.is_walkable(p));
        assert!((p.x - 5.0).abs() < 0.1 && (p.y - 9.0).abs() < 0.6, "{p:?}");
        // Outside the outline, right of it.
        let q = grid.map_match(Point2::new(35.0, 10.0));
        assert!(plan.is_walkable(q));
        assert!(
            (q.x - 30.0).abs() < 0.1 && (q.y - 10.0).abs() < 0.6,
            "{q:?}"
        );
        // Far outside the grid.
        let r = grid.map_match(Point2::new(-100.0, -100.0));
        assert!(plan.is_walkable(r) && r.x < 1.0 && r.y < 1.0, "{r:?}");
        // Non-finite input is returned as is.
        assert!(grid.map_match(Point2::new(f64::NAN, 0.0)).x.is_nan());
    }

    #[test]
    fn bad_cell_size_is_an_error() {
        assert!(WalkableGrid::new(&plan(), 0.0).is_err());
        assert!(WalkableGrid::new(&plan(), f64::NAN).is_err());
        assert!(WalkableGrid::new(&plan(), 1e-6).is_err());
    }

    proptest! {
        #[test]
        fn map_matching_never_moves_a_walkable_point(x in -5.0f64..45.0, y in -5.0f64..35.0) {
            let plan = plan();
            let grid = WalkableGrid::new(&plan, 0.5).unwrap();
            let p = Point2::new(x, y);
            let m = grid.map_match(p);
            if plan.is_walkable(p) {
                prop_assert_eq!(m, p);
            } else {
                prop_assert!(plan.is_walkable(m), "{:?} -> {:?}", p, m);
                // Never farther than the distance to the nearest walkable cell centre + a cell.
                let exact = plan.walls.iter().map(|w| w.distance_to(p)).fold(f64::INFINITY, f64::min);
                prop_assert!((m - p).norm() <= exact + 0.75, "{:?} -> {:?}, wall at {}", p, m, exact);
            }
        }
    }
}

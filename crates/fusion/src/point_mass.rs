//! `pmf` — a point-mass (grid) filter over the PDR track's placement, with floor-plan
//! walkability and coverage-aware Wi-Fi: **wipdr's own scheme, not from the four papers**
//! (it combines their ingredients: PDR shape, Wi-Fi fixes with gross errors, walls of
//! paper 004 §4.3.3, the "start that waits for consistent evidence" of the project's findings).
//!
//! # The model
//!
//! PDR gives the track's shape `D(t)` (the summed step displacements) well; what is unknown
//! is where it sits: the position is `x(t) = o(t) + D(t)` with an offset `o` that is constant
//! up to slow PDR drift. The filter keeps a probability for every offset on a square lattice
//! (`cell_m`) covering the floor plan plus a margin, so every start the plan allows is a
//! hypothesis from the beginning: nothing has to be guessed from the first fix.
//!
//! - **Step** (prediction and the walls): the offset diffuses by `drift_m2_per_step` (a
//!   binomial blur whenever the accumulated variance reaches half a cell², so the drift of
//!   the PDR heading and length is absorbed); then each hypothesis is weighted by where its
//!   position `o + D` now lies: 1 in walkable space, `unit_likelihood` inside a unit (a shop:
//!   walkers rarely enter them, and the plan's units are approximate), `outside_likelihood`
//!   outside the floor outline. A track shape that only fits the corridors in few places
//!   pins the offset down after a few turns, even with no usable Wi-Fi at all.
//! - **Wi-Fi fix** `f`: each hypothesis is weighted by a robust likelihood of the fix given
//!   its position `x = o + D`: `exp(-|f - x|² / 2 sd²) + outlier` — Gaussian with a floor,
//!   so a gross fix cannot kill the right hypothesis. Coverage-aware (optional): where `x` is
//!   farther than `gap_distance_m` from every reference point of the radio map (training
//!   data), the matcher can only answer some covered place near the walker, so the
//!   likelihood there is a wide Gaussian (`gap_sd_m`) of peak `gap_likelihood` instead.
//! - A floor `recovery` (relative to a uniform spread) is mixed in after each update, so a
//!   hypothesis killed by a long stay in a shop can come back.
//!
//! The estimate is the posterior mean of `o + D` over the cells within `estimate_radius_m` of
//! the most probable cell (the mean of the dominant mode; a plain mean would sit between two
//! modes). It is reported from the first Wi-Fi fix on, as for the other schemes (or from a
//! given start, which collapses the prior there).
//!
//! Work per input is proportional to the *active* cells: a window bounding the cells above
//! the floor, the whole plan early in a walk, a few hundred cells once the filter has
//! converged. Each input makes a few passes over it, a row at a time: the weighting (its
//! look-ups by position, the walkable class and the coverage gap, split into one per row and
//! one per column, since a lattice row shares its y) also sums the result; the normalisation
//! applies the floor and sums again in one pass, renormalises and finds the new window in a
//! second (plus one over the new window when it shrank); the mode search builds a
//! summed-area table and scans its squares a row at a time. About 80 µs per step on a real
//! floor of 260 x 197 cells (`cargo bench -p wipdr-benches --bench fusion -- pmf_real`).
//!
//! ```
//! use wipdr_core::{MotionState, Point2, StepEvent, WifiObservation};
//! use wipdr_fusion::{Fuser, point_mass::{PointMassConfig, PointMassFilter}};
//! let mut f = PointMassFilter::new(PointMassConfig::default(), None, None, None).unwrap();
//! let fix = |t, x: f64, y: f64| WifiObservation { t, estimate: Point2::new(x, y),
//!     candidates: vec![], visited: 0, floor: None, building: None };
//! f.on_wifi(&fix(0, 10.0, 10.0));
//! for k in 1..=10 {
//!     f.on_step(&StepEvent { t: 500 * k, length: 0.7, heading: 0.0, heading_change: 0.0,
//!         period_s: 0.5, motion: MotionState::default() });
//! }
//! f.on_wifi(&fix(6000, 10.0, 17.0));
//! let p = f.estimate().unwrap().position;
//! assert!((p.x - 10.0).abs() < 1.0 && (p.y - 17.0).abs() < 1.5, "{p:?}");
//! ```

use std::collections::VecDeque;
use std::sync::Arc;

use serde::{Deserialize, Serialize};
use wipdr_core::{Point2, StepEvent, TimestampMs, Vector2, WifiObservation, angle};

use crate::trails::TrailRaster;
use crate::walkable::{CellClass, WalkableGrid};
use crate::{Estimate, Fuser, FusionError, InputGuard};

/// Config of `pmf`. The defaults were chosen on the five ILC floors (`docs/sweeps/pmf-grid.toml`
/// and docs/results/fusion-real.md), so they are optimistic there.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PointMassConfig {
    /// Lattice spacing of the offset hypotheses, metres.
    pub cell_m: f64,
    /// Margin around the floor plan (or, without a plan, half-width of the lattice around
    /// the first fix), metres.
    pub margin_m: f64,
    /// Variance added to the offset per step (PDR drift), m².
    pub drift_m2_per_step: f64,
    /// Weight of a hypothesis whose position is inside a unit, per step.
    pub unit_likelihood: f64,
    /// Weight of a hypothesis whose position is outside the floor outline, per step.
    pub outside_likelihood: f64,
    /// Standard deviation of a good Wi-Fi fix, metres.
    pub wifi_sd_m: f64,
    /// Outlier floor of the Wi-Fi likelihood (relative to its peak of 1).
    pub wifi_outlier: f64,
    /// Distance from the nearest reference point beyond which a position counts as a
    /// coverage gap, metres (0: no coverage awareness; also off when the filter is built
    /// without the radio map's reference points).
    pub gap_distance_m: f64,
    /// Peak Wi-Fi likelihood of a hypothesis in a coverage gap (relative to a peak of 1 in
    /// covered space): a fix there lands at some covered place near the walker, so the
    /// likelihood is a wide Gaussian of standard deviation `gap_sd_m` (plus the outlier floor).
    pub gap_likelihood: f64,
    /// Standard deviation of the fix about a walker in a coverage gap, metres.
    pub gap_sd_m: f64,
    /// Recovery floor after each update, as a share of the uniform probability.
    pub recovery: f64,
    /// Radius around the most probable cell over which the estimate is averaged, metres
    /// (0: the whole posterior).
    pub estimate_radius_m: f64,
    /// Signal distance of a fix's best candidate at which its Gaussian part is halved (the
    /// matcher's distance unit; 0: every fix trusted alike).
    pub quality_distance: f64,
    /// Softness of that logistic, in the same unit.
    pub quality_softness: f64,
    /// Half-width of the square over which a mode's probability is summed, metres.
    pub mode_radius_m: f64,
    /// Keep the previous mode while it holds at least this share of the best mode's mass.
    pub mode_hysteresis: f64,
    /// Multiplies every step length (1 = as PDR reports).
    pub step_scale: f64,
    /// Width (a Gaussian's standard deviation, metres) of the training trails
    /// ([`crate::trails`]) in the per-step weight; 0 turns the trail prior off (also off when
    /// the filter is built without trails).
    pub trail_sd_m: f64,
    /// Per-step weight of a hypothesis far from every training trail (relative to 1 on a
    /// trail): the weight is `off + (1 - off) exp(-d² / 2 trail_sd_m²)`.
    pub off_trail_likelihood: f64,
}

impl Default for PointMassConfig {
    fn default() -> Self {
        Self {
            cell_m: 1.0,
            margin_m: 10.0,
            drift_m2_per_step: 0.05,
            unit_likelihood: 0.8,
            outside_likelihood: 0.3,
            wifi_sd_m: 6.0,
            wifi_outlier: 0.1,
            gap_distance_m: 15.0,
            gap_likelihood: 0.3,
            gap_sd_m: 20.0,
            recovery: 1e-6,
            estimate_radius_m: 10.0,
            quality_distance: 0.0,
            quality_softness: 5.0,
            mode_radius_m: 5.0,
            mode_hysteresis: 0.5,
            step_scale: 1.0,
            trail_sd_m: 0.0,
            off_trail_likelihood: 0.5,
        }
    }
}

impl PointMassConfig {
    /// Checks every field.
    pub fn validate(&self) -> Result<(), FusionError> {
        let positive = [
            ("cell_m", self.cell_m),
            ("wifi_sd_m", self.wifi_sd_m),
            ("gap_sd_m", self.gap_sd_m),
            ("quality_softness", self.quality_softness),
            ("step_scale", self.step_scale),
        ];
        for (field, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(FusionError::InvalidConfig {
                    field,
                    reason: format!("must be finite and > 0, got {v}"),
                });
            }
        }
        let non_negative = [
            ("margin_m", self.margin_m),
            ("drift_m2_per_step", self.drift_m2_per_step),
            ("wifi_outlier", self.wifi_outlier),
            ("gap_distance_m", self.gap_distance_m),
            ("recovery", self.recovery),
            ("estimate_radius_m", self.estimate_radius_m),
            ("mode_radius_m", self.mode_radius_m),
            ("quality_distance", self.quality_distance),
            ("trail_sd_m", self.trail_sd_m),
        ];
        for (field, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return Err(FusionError::InvalidConfig {
                    field,
                    reason: format!("must be finite and >= 0, got {v}"),
                });
            }
        }
        let probabilities = [
            ("unit_likelihood", self.unit_likelihood),
            ("outside_likelihood", self.outside_likelihood),
            ("gap_likelihood", self.gap_likelihood),
            ("mode_hysteresis", self.mode_hysteresis),
            ("off_trail_likelihood", self.off_trail_likelihood),
        ];
        for (field, v) in probabilities {
            if !(v.is_finite() && v > 0.0 && v <= 1.0) {
                return Err(FusionError::InvalidConfig {
                    field,
                    reason: format!("must be in (0, 1], got {v}"),
                });
            }
        }
        Ok(())
    }
}

/// Most cells the lattice may have.
pub const MAX_CELLS: usize = 4 << 20;

/// The point-mass filter; see the [module docs](self).
#[derive(Debug)]
pub struct PointMassFilter {
    cfg: PointMassConfig,
    walkable: Option<Arc<WalkableGrid>>,
    coverage: Option<Arc<Vec<Point2>>>,
    trails: Option<Arc<TrailRaster>>,
    /// Lattice: lower-left corner of cell (0, 0), columns, rows.
    origin: Point2,
    nx: usize,
    ny: usize,
    prob: Vec<f64>,
    scratch: Vec<f64>,
    /// Distance class of positions: whether each position cell (same lattice, positions
    /// rather than offsets, over the coverage extent) is in a gap. Built lazily.
    gap: Option<GapRaster>,
    /// Active window (inclusive cell ranges) outside which every cell is at the floor.
    active: (usize, usize, usize, usize),
    floor: f64,
    bg: f64,
    sat: Vec<f64>,
    /// Per-input buffers of one window row (positions, raster columns, weights).
    row_buffers: RowBuffers,
    mode: Option<usize>,
    pdr: Vector2,
    pending_drift: f64,
    initialised: bool,
    reporting: bool,
    t: TimestampMs,
    guard: InputGuard,
}

/// Reused buffers of one active-window row, so that weighing, the blur and the mode search
/// allocate nothing per input.
#[derive(Debug, Default)]
struct RowBuffers {
    /// x of the positions `o + D` of the window's columns (shared by every row).
    xs: Vec<f64>,
    /// Column of each of those x in a raster ([`NO_CELL`] outside it).
    columns: Vec<usize>,
    /// Weights of one row's cells.
    weights: Vec<f64>,
}

/// Marks a coordinate outside a raster in [`raster_index`].
const NO_CELL: usize = usize::MAX;

/// Index along one axis of a raster (`origin`, `cell`, `n` cells) of coordinate `v`, or
/// [`NO_CELL`] outside it or for a non-finite `v`: the per-axis half of the rasters'
/// `cell_of` (`floor((v - origin) / cell)` in `[0, n)`), so a row's y and a column's x can be
/// looked up once instead of once per cell.
fn raster_index(v: f64, origin: f64, cell: f64, n: usize) -> usize {
    let c = ((v - origin) / cell).floor();
    if c >= 0.0 && c < n as f64 {
        c as usize
    } else {
        NO_CELL
    }
}

/// The largest of `values` (NaN ignored; `-inf` for none), in four lanes so that the
/// comparisons do not form one dependency chain (the maximum does not depend on the order).
fn max_of(values: &[f64]) -> f64 {
    let mut lanes = [f64::NEG_INFINITY; 4];
    let chunks = values.chunks_exact(4);
    let rest = chunks.remainder();
    for chunk in chunks {
        for (lane, &v) in lanes.iter_mut().zip(chunk) {
            if v > *lane {
                *lane = v;
            }
        }
    }
    for &v in rest {
        if v > lanes[0] {
            lanes[0] = v;
        }
    }
    lanes
        .into_iter()
        .fold(f64::NEG_INFINITY, |a, v| if v > a { v } else { a })
}

#[derive(Debug)]
struct GapRaster {
    origin: Point2,
    cell_m: f64,
    nx: usize,
    ny: usize,
    gap: Vec<bool>,
}

impl GapRaster {
    /// Cells farther than `distance` from every point (BFS over the 8-neighbourhood with
    /// nearest-seed propagation), over the points' extent plus `margin`.
    fn new(
        points: &[Point2],
        cell_m: f64,
        distance: f64,
        extent: (Point2, Point2),
    ) -> Option<Self> {
        let (lo, hi) = extent;
        let nx = ((hi.x - lo.x) / cell_m).ceil() as usize + 1;
        let ny = ((hi.y - lo.y) / cell_m).ceil() as usize + 1;
        if nx.saturating_mul(ny) > MAX_CELLS || points.is_empty() {
            return None;
        }
        let mut seed = vec![u32::MAX; nx * ny];
        let mut queue = VecDeque::new();
        let seeds: Vec<Point2> = points.to_vec();
        for (k, p) in seeds.iter().enumerate() {
            let cx = ((p.x - lo.x) / cell_m).floor();
            let cy = ((p.y - lo.y) / cell_m).floor();
            if cx >= 0.0 && cy >= 0.0 && (cx as usize) < nx && (cy as usize) < ny {
                let i = cy as usize * nx + cx as usize;
                if seed[i] == u32::MAX {
                    seed[i] = k as u32;
                    queue.push_back(i);
                }
            }
        }
        let centre = |i: usize| {
            Point2::new(
                lo.x + ((i % nx) as f64 + 0.5) * cell_m,
                lo.y + ((i / nx) as f64 + 0.5) * cell_m,
            )
        };
        while let Some(i) = queue.pop_front() {
            let s = seeds[seed[i] as usize];
            let (row, col) = ((i / nx) as i64, (i % nx) as i64);
            for dr in -1..=1i64 {
                for dc in -1..=1i64 {
                    let (r, c) = (row + dr, col + dc);
                    if r < 0 || c < 0 || r >= ny as i64 || c >= nx as i64 {
                        continue;
                    }
                    let j = r as usize * nx + c as usize;
                    if seed[j] == seed[i] {
                        // The same seed: not nearer (and already queued).
                        continue;
                    }
                    let cj = centre(j);
                    let d2 = (cj - s).norm_squared();
                    // Nearer by more than 1e-12 m; the squared distances (no square root)
                    // settle the common case of not nearer at all, since the root is monotone.
                    let better = seed[j] == u32::MAX || {
                        let other2 = (cj - seeds[seed[j] as usize]).norm_squared();
                        d2 < other2 && d2.sqrt() < other2.sqrt() - 1e-12
                    };
                    if better && d2.sqrt() <= distance + 2.0 * cell_m {
                        seed[j] = seed[i];
                        queue.push_back(j);
                    }
                }
            }
        }
        let gap = (0..nx * ny)
            .map(|i| seed[i] == u32::MAX || (centre(i) - seeds[seed[i] as usize]).norm() > distance)
            .collect();
        Some(Self {
            origin: lo,
            cell_m,
            nx,
            ny,
            gap,
        })
    }

    /// Whether `p` is in a gap (everything outside the raster is). The filter looks rows and
    /// columns up separately (`on_wifi`); this is the per-point form the tests check.
    #[cfg(test)]
    fn is_gap(&self, p: Point2) -> bool {
        let column = raster_index(p.x, self.origin.x, self.cell_m, self.nx);
        let row = raster_index(p.y, self.origin.y, self.cell_m, self.ny);
        row == NO_CELL || column == NO_CELL || self.gap[row * self.nx + column]
    }
}

impl PointMassFilter {
    /// Builds `pmf`. With `walkable`, the lattice covers the plan from the start; without, it
    /// is laid around the first Wi-Fi fix (or `start`). `coverage` (reference-point positions
    /// of the radio map) turns on coverage awareness when `gap_distance_m > 0`.
    pub fn new(
        cfg: PointMassConfig,
        walkable: Option<Arc<WalkableGrid>>,
        coverage: Option<Arc<Vec<Point2>>>,
        start: Option<Point2>,
    ) -> Result<Self, FusionError> {
        cfg.validate()?;
        let mut f = Self {
            cfg,
            walkable,
            coverage,
            trails: None,
            origin: Point2::origin(),
            nx: 0,
            ny: 0,
            prob: Vec::new(),
            scratch: Vec::new(),
            gap: None,
            active: (0, 0, 0, 0),
            floor: 0.0,
            bg: 0.0,
            sat: Vec::new(),
            row_buffers: RowBuffers::default(),
            mode: None,
            pdr: Vector2::zeros(),
            pending_drift: 0.0,
            initialised: false,
            reporting: false,
            t: 0,
            guard: InputGuard::default(),
        };
        if let Some(grid) = f.walkable.clone() {
            let (nx, ny) = grid.dims();
            let lo = grid.origin();
            let hi = Point2::new(
                lo.x + nx as f64 * grid.cell_m(),
                lo.y + ny as f64 * grid.cell_m(),
            );
            f.lay_lattice(lo, hi)?;
        }
        if let Some(s) = start {
            if !f.initialised {
                let m = f.cfg.margin_m.max(f.cfg.cell_m);
                f.lay_lattice(s - Vector2::new(m, m), s + Vector2::new(m, m))?;
            }
            f.collapse_at(s);
            f.reporting = true;
        }
        Ok(f)
    }

    /// Adds the training trails ([`crate::trails`]): with `trail_sd_m > 0`, each step weighs
    /// every hypothesis by its position's distance to the nearest trail.
    pub fn with_trails(mut self, trails: Option<Arc<TrailRaster>>) -> Self {
        self.trails = trails;
        self
    }

    /// Lays a uniform lattice over `[lo, hi]` plus the margin.
    fn lay_lattice(&mut self, lo: Point2, hi: Point2) -> Result<(), FusionError> {
        let m = self.cfg.margin_m;
        let h = self.cfg.cell_m;
        let lo = lo - Vector2::new(m, m);
        let hi = hi + Vector2::new(m, m);
        let nx = ((hi.x - lo.x) / h).ceil().max(1.0);
        let ny = ((hi.y - lo.y) / h).ceil().max(1.0);
        if !(nx.is_finite() && ny.is_finite()) || nx * ny > MAX_CELLS as f64 {
            return Err(FusionError::InvalidConfig {
                field: "cell_m",
                reason: format!("a {nx} x {ny} lattice is larger than {MAX_CELLS} cells"),
            });
        }
        self.origin = lo;
        self.nx = nx as usize;
        self.ny = ny as usize;
        let n = self.nx * self.ny;
        self.prob = vec![1.0 / n as f64; n];
        self.scratch = vec![0.0; n];
        self.floor = self.cfg.recovery / n as f64;
        self.bg = 1.0 / n as f64;
        self.active = (0, self.nx - 1, 0, self.ny - 1);
        self.initialised = true;
        // Offsets are relative to the PDR origin at lay time: the lattice holds positions
        // `o + D`, so shift by the displacement so far.
        self.origin -= self.pdr;
        if let Some(cov) = self.coverage.clone()
            && self.cfg.gap_distance_m > 0.0
        {
            let (plo, phi) = (lo, hi);
            self.gap = GapRaster::new(&cov, h, self.cfg.gap_distance_m, (plo, phi));
        }
        Ok(())
    }

    fn collapse_at(&mut self, p: Point2) {
        let o = p.coords - self.pdr;
        let n = self.prob.len();
        self.prob.iter_mut().for_each(|v| *v = 0.0);
        self.bg = 0.0;
        self.active = (0, self.nx - 1, 0, self.ny - 1);
        let cx = ((o.x - self.origin.x) / self.cfg.cell_m).floor();
        let cy = ((o.y - self.origin.y) / self.cfg.cell_m).floor();
        if cx >= 0.0 && cy >= 0.0 && (cx as usize) < self.nx && (cy as usize) < self.ny {
            self.prob[cy as usize * self.nx + cx as usize] = 1.0;
        } else {
            self.prob.iter_mut().for_each(|v| *v = 1.0 / n as f64);
            self.bg = 1.0 / n as f64;
        }
        self.normalise(None);
        self.choose_mode();
    }

    fn offset_of(&self, i: usize) -> Vector2 {
        Vector2::new(
            self.origin.x + ((i % self.nx) as f64 + 0.5) * self.cfg.cell_m,
            self.origin.y + ((i / self.nx) as f64 + 0.5) * self.cfg.cell_m,
        )
    }

    /// The represented total: the background cells plus the active window (rows summed in
    /// order, so that every caller gets the same bits for the same distribution).
    fn active_total(&self) -> f64 {
        let (x0, x1, y0, y1) = self.active;
        let w = x1 - x0 + 1;
        let n_active = (w * (y1 - y0 + 1)) as f64;
        let mut total = self.bg * (self.prob.len() as f64 - n_active);
        for r in y0..=y1 {
            total += self.prob[r * self.nx + x0..][..w].iter().sum::<f64>();
        }
        total
    }

    /// Normalises, applies the recovery floor and recomputes the active window. Cells outside
    /// the window all hold the background probability `bg` (implicitly: their array values
    /// are rewritten when the window grows over them). `sum` is the represented total when
    /// the caller has it ([`Self::weigh`] returns it), else it is summed here. Two passes
    /// over the window (normalise + floor + the second sum; renormalise + the new window),
    /// and one more over the new window when it changed.
    fn normalise(&mut self, sum: Option<f64>) {
        let (x0, x1, y0, y1) = self.active;
        let (nx, w) = (self.nx, x1 - x0 + 1);
        let n = self.prob.len() as f64;
        let n_active = (w * (y1 - y0 + 1)) as f64;
        let sum = sum.unwrap_or_else(|| self.active_total());
        let floor = self.floor;
        // Whether some cell is clearly above the floor (the maximum compared with 1.5 floor,
        // without the maximum's dependency chain).
        let limit = floor * 1.5;
        let mut above = false;
        let mut sum2 = 0.0;
        if sum.is_finite() && sum > 0.0 {
            // Background cells exist only outside a partial window.
            self.bg = if n_active < n {
                (self.bg / sum).max(floor)
            } else {
                floor
            };
            // The total after the floor, summed as `active_total` does.
            sum2 = self.bg * (n - n_active);
            for r in y0..=y1 {
                let mut row_sum = 0.0;
                for v in &mut self.prob[r * nx + x0..][..w] {
                    // `(v / sum).max(floor)` (a NaN quotient also gives the floor).
                    let q = *v / sum;
                    *v = if q > floor { q } else { floor };
                    above |= *v > limit;
                    row_sum += *v;
                }
                sum2 += row_sum;
            }
        }
        if !above {
            // Every explicit hypothesis is at the floor: spread uniformly again (recovery).
            tracing::debug!("pmf: every hypothesis vanished; back to uniform");
            self.prob.iter_mut().for_each(|v| *v = 1.0 / n);
            self.bg = 1.0 / n;
            self.active = (0, self.nx - 1, 0, self.ny - 1);
            return;
        }
        // Re-normalise after the floor, shrink the window to the cells above it.
        if n_active < n {
            self.bg /= sum2;
        }
        let threshold = self.bg * 1.5;
        let (mut a0, mut a1, mut b0, mut b1) = (usize::MAX, 0, usize::MAX, 0);
        for r in y0..=y1 {
            let row = &mut self.prob[r * nx + x0..][..w];
            for v in row.iter_mut() {
                *v /= sum2;
            }
            if let Some(first) = row.iter().position(|v| *v > threshold) {
                let last = row.iter().rposition(|v| *v > threshold).unwrap_or(first);
                a0 = a0.min(x0 + first);
                a1 = a1.max(x0 + last);
                b0 = b0.min(r);
                b1 = b1.max(r);
            }
        }
        if a0 != usize::MAX && (a0, a1, b0, b1) != self.active {
            // Cells dropped from the window now count as background: renormalise so that
            // the represented distribution sums to one exactly.
            self.active = (a0, a1, b0, b1);
            let total = self.active_total();
            self.bg /= total;
            for r in b0..=b1 {
                for v in &mut self.prob[r * nx + a0..=r * nx + a1] {
                    *v /= total;
                }
            }
        }
    }

    /// Grows the active window by one cell on each side, filling new cells with `bg`.
    fn grow(&mut self) {
        let (x0, x1, y0, y1) = self.active;
        let (nx, ny) = (self.nx, self.ny);
        let (a0, a1) = (x0.saturating_sub(1), (x1 + 1).min(nx - 1));
        let (b0, b1) = (y0.saturating_sub(1), (y1 + 1).min(ny - 1));
        for r in b0..=b1 {
            for c in a0..=a1 {
                if r < y0 || r > y1 || c < x0 || c > x1 {
                    self.prob[r * nx + c] = self.bg;
                }
            }
        }
        self.active = (a0, a1, b0, b1);
    }

    /// Multiplies every active cell by a weight of its position `o + D` and returns the
    /// represented total afterwards (summed as [`Self::active_total`] does, for
    /// [`Self::normalise`]). The positions of one window row share their y and those of one
    /// column their x, so the weights are filled a row at a time:
    /// `row_weights(y, xs, columns, weights)` gets the row's y, the x of every column, each
    /// x's raster column `column_of(x)` (looked up once per input, not once per cell) and
    /// fills `weights`.
    fn weigh(
        &mut self,
        column_of: impl Fn(f64) -> usize,
        mut row_weights: impl FnMut(f64, &[f64], &[usize], &mut [f64]),
    ) -> f64 {
        let (x0, x1, y0, y1) = self.active;
        let (nx, w, h) = (self.nx, x1 - x0 + 1, self.cfg.cell_m);
        let mut buf = std::mem::take(&mut self.row_buffers);
        // The same arithmetic as `offset_of(i) + pdr`, so the positions keep their bits.
        buf.xs.clear();
        buf.xs
            .extend((x0..=x1).map(|c| self.origin.x + (c as f64 + 0.5) * h + self.pdr.x));
        buf.columns.clear();
        buf.columns.extend(buf.xs.iter().map(|&x| column_of(x)));
        buf.weights.clear();
        buf.weights.resize(w, 0.0);
        let n_active = (w * (y1 - y0 + 1)) as f64;
        let mut total = self.bg * (self.prob.len() as f64 - n_active);
        for r in y0..=y1 {
            let y = self.origin.y + (r as f64 + 0.5) * h + self.pdr.y;
            row_weights(y, &buf.xs, &buf.columns, &mut buf.weights);
            let mut row_sum = 0.0;
            for (v, weight) in self.prob[r * nx + x0..][..w].iter_mut().zip(&buf.weights) {
                *v *= weight;
                row_sum += *v;
            }
            total += row_sum;
        }
        self.row_buffers = buf;
        total
    }

    /// Binomial blur `[1 2 1] / 4` in x then y over the active window grown by a cell
    /// (cells beyond the window count as background).
    fn blur(&mut self) {
        self.grow();
        let (x0, x1, y0, y1) = self.active;
        let (nx, w, bg) = (self.nx, x1 - x0 + 1, self.bg);
        let mut buf = std::mem::take(&mut self.row_buffers);
        // A row padded with the background on both sides.
        let padded = &mut buf.weights;
        padded.clear();
        padded.resize(w + 2, bg);
        for r in y0..=y1 {
            let i = r * nx + x0;
            padded[1..=w].copy_from_slice(&self.prob[i..i + w]);
            for (s, t) in self.scratch[i..i + w].iter_mut().zip(padded.windows(3)) {
                *s = 0.25 * t[0] + 0.5 * t[1] + 0.25 * t[2];
            }
        }
        let background_row = &mut buf.xs;
        background_row.clear();
        background_row.resize(w, bg);
        for r in y0..=y1 {
            let i = r * nx + x0;
            let s = &self.scratch;
            let down = if r > y0 {
                &s[i - nx..i - nx + w]
            } else {
                &background_row[..]
            };
            let up = if r < y1 {
                &s[i + nx..i + nx + w]
            } else {
                &background_row[..]
            };
            let cells = self.prob[i..i + w].iter_mut().zip(&s[i..i + w]);
            for (((p, mid), d), u) in cells.zip(down).zip(up) {
                *p = 0.25 * d + 0.5 * mid + 0.25 * u;
            }
        }
        self.row_buffers = buf;
    }

    /// The cell whose neighbourhood (a square of half-width `mode_radius_m`) holds the most
    /// probability, over the active window (a summed-area table). The previously chosen cell
    /// is kept while its neighbourhood holds at least `mode_hysteresis` of the best one, so
    /// the estimate does not flip between two near-equal modes.
    fn choose_mode(&mut self) {
        let (x0, x1, y0, y1) = self.active;
        let (w, h) = (x1 - x0 + 1, y1 - y0 + 1);
        let stride = w + 1;
        let sat = &mut self.sat;
        if sat.len() < stride * (h + 1) {
            sat.resize(stride * (h + 1), 0.0);
        }
        // Row 0 and column 0 are zero; every other entry is written below.
        sat[..stride].fill(0.0);
        for r in 0..h {
            let src = &self.prob[(y0 + r) * self.nx + x0..][..w];
            let (done, rest) = sat.split_at_mut((r + 1) * stride);
            let above = &done[r * stride + 1..][..w];
            let (first, cur) = rest[..stride].split_at_mut(1);
            first[0] = 0.0;
            let mut row = 0.0;
            for ((s, a), v) in cur.iter_mut().zip(above).zip(src) {
                row += v;
                *s = a + row;
            }
        }
        let sat = &self.sat[..stride * (h + 1)];
        let k = (self.cfg.mode_radius_m / self.cfg.cell_m).round() as usize;
        let mass = |c: usize, r: usize| {
            let (a0, a1) = (c.saturating_sub(k), (c + k).min(w - 1) + 1);
            let (b0, b1) = (r.saturating_sub(k), (r + k).min(h - 1) + 1);
            sat[b1 * stride + a1] - sat[b0 * stride + a1] - sat[b1 * stride + a0]
                + sat[b0 * stride + a0]
        };
        // Row by row, the squares' columns clipped at the window's left edge, then the
        // interior ones (a run of `2k + 1` columns), then those clipped at the right edge:
        // the same four-term sum as `mass` in the same order, without per-cell clipping.
        let left = k.min(w);
        let right = w.saturating_sub(k).max(left);
        // The first cell (row-major) of the largest mass, found a row at a time: the row's
        // masses, their maximum (in lanes, no dependency chain) and, only when it beats the
        // best so far, its first position. The same cell as comparing cell after cell.
        let mut masses = std::mem::take(&mut self.row_buffers.weights);
        masses.clear();
        masses.resize(w, 0.0);
        let mut best = (0usize, 0usize, f64::NEG_INFINITY);
        for r in 0..h {
            let (b0, b1) = (r.saturating_sub(k), (r + k).min(h - 1) + 1);
            let top = &sat[b1 * stride..][..stride];
            let bottom = &sat[b0 * stride..][..stride];
            for (c, m) in masses[..left].iter_mut().enumerate() {
                let a1 = (c + k).min(w - 1) + 1;
                *m = top[a1] - bottom[a1] - top[0] + bottom[0];
            }
            if right > left {
                // Here left = k: column c's square spans sat columns c - k and c + k + 1.
                let (far, near) = (&top[..=w], &bottom[..=w]);
                let interior = far[2 * k + 1..]
                    .iter()
                    .zip(&near[2 * k + 1..])
                    .zip(far.iter().zip(near));
                for (m, ((t1, b1), (t0, b0))) in masses[left..right].iter_mut().zip(interior) {
                    *m = t1 - b1 - t0 + b0;
                }
            }
            for (c, m) in masses.iter_mut().enumerate().skip(right) {
                let (a0, a1) = (c - k, (c + k).min(w - 1) + 1);
                *m = top[a1] - bottom[a1] - top[a0] + bottom[a0];
            }
            let row_max = max_of(&masses);
            if row_max > best.2 {
                let c = masses.iter().position(|m| *m == row_max).unwrap_or(0);
                best = (c, r, row_max);
            }
        }
        self.row_buffers.weights = masses;
        let chosen = (y0 + best.1) * self.nx + x0 + best.0;
        if let Some(prev) = self.mode {
            let (pc, pr) = (prev % self.nx, prev / self.nx);
            if pc >= x0 && pc <= x1 && pr >= y0 && pr <= y1 {
                let m = mass(pc - x0, pr - y0);
                if m >= self.cfg.mode_hysteresis * best.2 {
                    // Keep the previous mode.
                    return;
                }
            }
        }
        self.mode = Some(chosen);
    }

    fn mean_near(&self, centre: usize, radius: f64) -> Vector2 {
        let c = self.offset_of(centre);
        let h = self.cfg.cell_m;
        let k = if radius > 0.0 {
            (radius / h).ceil() as i64
        } else {
            i64::MAX / 4
        };
        let (cc, cr) = ((centre % self.nx) as i64, (centre / self.nx) as i64);
        let (a0, a1, b0, b1) = self.active;
        let (x0, x1) = (
            (cc - k).max(a0 as i64) as usize,
            (cc + k).min(a1 as i64) as usize,
        );
        let (y0, y1) = (
            (cr - k).max(b0 as i64) as usize,
            (cr + k).min(b1 as i64) as usize,
        );
        let (mut sum, mut w) = (Vector2::zeros(), 0.0);
        for r in y0..=y1 {
            for col in x0..=x1 {
                let i = r * self.nx + col;
                let o = self.offset_of(i);
                if radius > 0.0 && (o - c).norm() > radius {
                    continue;
                }
                sum += self.prob[i] * o;
                w += self.prob[i];
            }
        }
        if w > 0.0 { sum / w } else { c }
    }
}

impl Fuser for PointMassFilter {
    fn name(&self) -> &'static str {
        "pmf"
    }

    fn on_step(&mut self, step: &StepEvent) {
        if !self.guard.accept_step(step) {
            return;
        }
        self.t = step.t;
        self.pdr += angle::step_displacement(step.length * self.cfg.step_scale, step.heading);
        if !self.initialised {
            return;
        }
        let h = self.cfg.cell_m;
        self.pending_drift += self.cfg.drift_m2_per_step;
        while self.pending_drift >= 0.5 * h * h {
            self.blur();
            self.pending_drift -= 0.5 * h * h;
        }
        let trails = self.trails.clone().filter(|_| self.cfg.trail_sd_m > 0.0);
        let (off, trail_inv) = (
            self.cfg.off_trail_likelihood,
            1.0 / (2.0 * self.cfg.trail_sd_m * self.cfg.trail_sd_m),
        );
        let trail_weight = |pos: Point2| match &trails {
            Some(t) => {
                let d = t.distance(pos);
                off + (1.0 - off) * (-d * d * trail_inv).exp()
            }
            None => 1.0,
        };
        let total = if let Some(grid) = self.walkable.clone() {
            let (unit, outside) = (self.cfg.unit_likelihood, self.cfg.outside_likelihood);
            let (lo, cell, (gnx, gny)) = (grid.origin(), grid.cell_m(), grid.dims());
            let class_weight = |row: usize, column: usize| {
                if row == NO_CELL || column == NO_CELL {
                    return outside;
                }
                match grid.class_of_cell(row * gnx + column) {
                    CellClass::Walkable => 1.0,
                    CellClass::Unit => unit,
                    CellClass::Outside => outside,
                }
            };
            Some(self.weigh(
                |x| raster_index(x, lo.x, cell, gnx),
                |y, xs, columns, weights| {
                    // `class_at(pos)` split into its row (once per row) and column lookups.
                    let row = raster_index(y, lo.y, cell, gny);
                    if trails.is_none() {
                        for (weight, &column) in weights.iter_mut().zip(columns) {
                            *weight = class_weight(row, column);
                        }
                    } else {
                        let cells = weights.iter_mut().zip(columns).zip(xs);
                        for ((weight, &column), &x) in cells {
                            *weight = class_weight(row, column) * trail_weight(Point2::new(x, y));
                        }
                    }
                },
            ))
        } else if trails.is_some() {
            Some(self.weigh(
                |_| NO_CELL,
                |y, xs, _, weights| {
                    for (weight, &x) in weights.iter_mut().zip(xs) {
                        *weight = trail_weight(Point2::new(x, y));
                    }
                },
            ))
        } else {
            None
        };
        self.normalise(total);
        self.choose_mode();
    }

    fn on_wifi(&mut self, obs: &WifiObservation) {
        if !self.guard.accept_wifi(obs) {
            return;
        }
        self.t = obs.t;
        if !self.initialised {
            let m = Vector2::new(100.0, 100.0);
            if self
                .lay_lattice(obs.estimate - m, obs.estimate + m)
                .is_err()
            {
                return;
            }
        }
        let f = obs.estimate;
        // Fix quality: a poor best match (large signal distance) is likely a coverage gap or
        // a gross fix, so its Gaussian part is down-weighted (a logistic in the distance).
        let trust = match obs.best_distance() {
            Some(d) if self.cfg.quality_distance > 0.0 && d.is_finite() => {
                1.0 / (1.0 + ((d - self.cfg.quality_distance) / self.cfg.quality_softness).exp())
            }
            _ => 1.0,
        };
        let inv = 1.0 / (2.0 * self.cfg.wifi_sd_m * self.cfg.wifi_sd_m);
        let (outlier, gap_like) = (self.cfg.wifi_outlier, self.cfg.gap_likelihood);
        let gap_inv = 1.0 / (2.0 * self.cfg.gap_sd_m * self.cfg.gap_sd_m);
        // `is_gap(pos)` split into its row and column lookups, as in `on_step`.
        let gap = self.gap.take();
        let total = self.weigh(
            |x| {
                gap.as_ref()
                    .map_or(NO_CELL, |g| raster_index(x, g.origin.x, g.cell_m, g.nx))
            },
            |y, xs, columns, weights| {
                let gap_row = gap
                    .as_ref()
                    .map_or(NO_CELL, |g| raster_index(y, g.origin.y, g.cell_m, g.ny));
                for ((weight, &column), &x) in weights.iter_mut().zip(columns).zip(xs) {
                    let r2 = (f - Point2::new(x, y)).norm_squared();
                    let in_gap = gap.as_ref().is_some_and(|g| {
                        gap_row == NO_CELL || column == NO_CELL || g.gap[gap_row * g.nx + column]
                    });
                    *weight = if in_gap {
                        gap_like * (-r2 * gap_inv).exp() + outlier
                    } else {
                        trust * (-r2 * inv).exp() + outlier
                    };
                }
            },
        );
        self.gap = gap;
        self.normalise(Some(total));
        self.choose_mode();
        self.reporting = true;
    }

    fn estimate(&self) -> Option<Estimate> {
        if !self.reporting || self.prob.is_empty() || self.mode.is_none() {
            return None;
        }
        let o = self.mean_near(self.mode?, self.cfg.estimate_radius_m);
        let p = Point2::from(o + self.pdr);
        (p.x.is_finite() && p.y.is_finite())
            .then(|| Estimate::point(self.t, p, self.guard.diagnostics()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use wipdr_core::{FloorPlan, MotionState, Polygon, Unit};

    fn fix(t: TimestampMs, x: f64, y: f64) -> WifiObservation {
        WifiObservation {
            t,
            estimate: Point2::new(x, y),
            candidates: vec![],
            visited: 0,
            floor: None,
            building: None,
        }
    }

    fn step(t: TimestampMs, heading: f64) -> StepEvent {
        StepEvent {
            t,
            length: 0.7,
            heading,
            heading_change: 0.0,
            period_s: 0.5,
            motion: MotionState::default(),
        }
    }

    fn rect(x0: f64, y0: f64, x1: f64, y1: f64) -> Polygon {
        Polygon::rectangle(x0, y0, x1, y1).unwrap()
    }

    /// A 60 m x 40 m floor whose only walkable space is a 3 m wide ring corridor around
    /// one big unit.
    fn ring_plan() -> Arc<WalkableGrid> {
        let plan = FloorPlan::new(
            60.0,
            40.0,
            vec![rect(0.0, 0.0, 60.0, 40.0)],
            vec![Unit {
                name: "block".into(),
                polygon: rect(3.0, 3.0, 57.0, 37.0),
            }],
        )
        .unwrap();
        Arc::new(WalkableGrid::new(&plan, 0.5).unwrap())
    }

    fn total(f: &PointMassFilter) -> f64 {
        let (x0, x1, y0, y1) = f.active;
        let n_active = (x1 - x0 + 1) * (y1 - y0 + 1);
        let mut s = f.bg * (f.prob.len() - n_active) as f64;
        for r in y0..=y1 {
            for c in x0..=x1 {
                s += f.prob[r * f.nx + c];
            }
        }
        s
    }

    #[test]
    fn walls_and_fixes_find_the_corridor() {
        // Walk north along the left corridor (x = 1.5) from y = 5, then east along the top
        // (y = 38.5). Fixes are 4 m off, one of them 40 m off.
        let mut f = PointMassFilter::new(PointMassConfig::default(), Some(ring_plan()), None, None)
            .unwrap();
        let mut truth = Point2::new(1.5, 5.0);
        let mut t = 0;
        f.on_wifi(&fix(t, truth.x + 4.0, truth.y));
        for k in 0..90 {
            t += 500;
            let heading = if k < 48 {
                0.0
            } else {
                std::f64::consts::FRAC_PI_2
            };
            truth += angle::step_displacement(0.7, heading);
            f.on_step(&step(t, heading));
            if k % 6 == 5 {
                let gross = if k == 35 { 40.0 } else { 0.0 };
                f.on_wifi(&fix(t, truth.x + 3.0, truth.y - 3.0 + gross));
            }
            assert!((total(&f) - 1.0).abs() < 1e-9);
        }
        let p = f.estimate().unwrap().position;
        assert!((p - truth).norm() < 2.5, "estimate {p:?} truth {truth:?}");
        assert!(f.walkable.as_ref().unwrap().class_at(p) == CellClass::Walkable);
    }

    #[test]
    fn trails_pull_the_placement_onto_where_training_walks_went() {
        // No plan: one fix 4 m north of the truth, then a walk east along y = 0, where a
        // training trail runs. Without trails the estimate stays near the fix's y; with the
        // trail prior it moves onto the trail; with `trail_sd_m = 0` the prior is off.
        let trail = [wipdr_core::Segment {
            a: Point2::new(-50.0, 0.0),
            b: Point2::new(50.0, 0.0),
        }];
        let raster = Arc::new(TrailRaster::new(&trail, 0.5, 10.0).unwrap());
        let run = |cfg: PointMassConfig, trails: Option<Arc<TrailRaster>>| {
            let mut f = PointMassFilter::new(cfg, None, None, None)
                .unwrap()
                .with_trails(trails);
            f.on_wifi(&fix(0, 0.0, 4.0));
            for k in 1..=30 {
                f.on_step(&step(500 * k, std::f64::consts::FRAC_PI_2));
                assert!((total(&f) - 1.0).abs() < 1e-9);
            }
            f.estimate().unwrap().position
        };
        let on = PointMassConfig {
            trail_sd_m: 1.0,
            off_trail_likelihood: 0.5,
            ..PointMassConfig::default()
        };
        let without = run(on.clone(), None);
        let with = run(on.clone(), Some(raster.clone()));
        let off = run(
            PointMassConfig {
                trail_sd_m: 0.0,
                ..on
            },
            Some(raster),
        );
        assert!(without.y > 3.0, "{without:?}");
        assert!(with.y.abs() < 1.0, "{with:?}");
        assert_eq!(off, without);
        assert!((with.x - 21.0).abs() < 1.0, "{with:?}");
    }

    #[test]
    fn gap_raster_marks_cells_beyond_the_distance() {
        let points = vec![Point2::new(10.0, 10.0), Point2::new(40.0, 10.0)];
        let g = GapRaster::new(
            &points,
            1.0,
            8.0,
            (Point2::new(0.0, 0.0), Point2::new(60.0, 30.0)),
        )
        .unwrap();
        for (x, y, gap) in [
            (10.0, 10.0, false),
            (16.0, 12.0, false),
            (40.0, 17.0, false),
            (25.0, 10.0, true),
            (10.0, 25.0, true),
            (-5.0, 10.0, true),
        ] {
            assert_eq!(g.is_gap(Point2::new(x, y)), gap, "({x}, {y})");
        }
        assert!(GapRaster::new(&[], 1.0, 8.0, (Point2::origin(), Point2::new(1.0, 1.0))).is_none());
    }

    #[test]
    fn a_given_start_is_kept_by_a_pdr_walk() {
        let mut f = PointMassFilter::new(
            PointMassConfig::default(),
            None,
            None,
            Some(Point2::new(5.0, 5.0)),
        )
        .unwrap();
        for k in 1..=10 {
            f.on_step(&step(k * 500, 0.0));
        }
        let p = f.estimate().unwrap().position;
        assert!((p - Point2::new(5.0, 12.0)).norm() < 1.0, "{p:?}");
    }

    #[test]
    fn invalid_configs_are_rejected() {
        for cfg in [
            PointMassConfig {
                cell_m: 0.0,
                ..Default::default()
            },
            PointMassConfig {
                unit_likelihood: 0.0,
                ..Default::default()
            },
            PointMassConfig {
                wifi_outlier: f64::NAN,
                ..Default::default()
            },
            PointMassConfig {
                cell_m: 0.001,
                ..Default::default()
            },
        ] {
            let with_plan = PointMassFilter::new(cfg, Some(ring_plan()), None, None);
            assert!(with_plan.is_err());
        }
    }

    /// The mode as `choose_mode` chose it before it was split into rows and lanes: a
    /// summed-area table and a cell-by-cell scan with clipped squares (no hysteresis).
    fn mode_cell_by_cell(f: &PointMassFilter) -> usize {
        let (x0, x1, y0, y1) = f.active;
        let (w, h) = (x1 - x0 + 1, y1 - y0 + 1);
        let mut sat = vec![0.0; (w + 1) * (h + 1)];
        for r in 0..h {
            let mut row = 0.0;
            for c in 0..w {
                row += f.prob[(y0 + r) * f.nx + x0 + c];
                sat[(r + 1) * (w + 1) + c + 1] = sat[r * (w + 1) + c + 1] + row;
            }
        }
        let k = (f.cfg.mode_radius_m / f.cfg.cell_m).round() as usize;
        let mut best = (0usize, 0usize, f64::NEG_INFINITY);
        for r in 0..h {
            for c in 0..w {
                let (a0, a1) = (c.saturating_sub(k), (c + k).min(w - 1) + 1);
                let (b0, b1) = (r.saturating_sub(k), (r + k).min(h - 1) + 1);
                let m = sat[b1 * (w + 1) + a1] - sat[b0 * (w + 1) + a1] - sat[b1 * (w + 1) + a0]
                    + sat[b0 * (w + 1) + a0];
                if m > best.2 {
                    best = (c, r, m);
                }
            }
        }
        (y0 + best.1) * f.nx + x0 + best.0
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// The row-wise mode search picks the very cell of the cell-by-cell scan, for windows
        /// narrower and wider than the mode's square, ties included (coarse values).
        #[test]
        fn mode_search_matches_the_cell_by_cell_scan(
            (nx, ny, values) in (1usize..40, 1usize..30).prop_flat_map(|(nx, ny)| {
                (Just(nx), Just(ny), proptest::collection::vec(0u8..6, nx * ny))
            }),
            window in (0.0f64..1.0, 0.0f64..1.0, 0.0f64..1.0, 0.0f64..1.0),
            radius in 0usize..8,
        ) {
            let cfg = PointMassConfig { mode_radius_m: radius as f64, ..Default::default() };
            let mut f = PointMassFilter::new(cfg, None, None, None).unwrap();
            f.nx = nx;
            f.ny = ny;
            f.prob = values.iter().map(|&v| f64::from(v) / 7.0).collect();
            let pick = |a: f64, b: f64, n: usize| {
                let (a, b) = ((a * n as f64) as usize, (b * n as f64) as usize);
                (a.min(b).min(n - 1), a.max(b).min(n - 1))
            };
            let ((x0, x1), (y0, y1)) = (pick(window.0, window.1, nx), pick(window.2, window.3, ny));
            f.active = (x0, x1, y0, y1);
            f.mode = None;
            f.choose_mode();
            prop_assert_eq!(f.mode, Some(mode_cell_by_cell(&f)));
        }

        /// Looking a point's raster row and column up separately finds the raster's own cell.
        #[test]
        fn split_lookups_match_the_raster(
            points in proptest::collection::vec((-20.0f64..80.0, -20.0f64..60.0), 1..200),
            shift in (-1.0f64..1.0, -1.0f64..1.0),
        ) {
            let grid = ring_plan();
            let (lo, cell, (gnx, gny)) = (grid.origin(), grid.cell_m(), grid.dims());
            let odd = [Point2::new(f64::NAN, 1.0), Point2::new(1.0, f64::INFINITY)];
            let all = points.iter().map(|&(x, y)| Point2::new(x + shift.0, y + shift.1));
            for p in all.chain(odd) {
                let (column, row) = (
                    raster_index(p.x, lo.x, cell, gnx),
                    raster_index(p.y, lo.y, cell, gny),
                );
                let split = (row != NO_CELL && column != NO_CELL).then(|| row * gnx + column);
                prop_assert_eq!(split, grid.cell_of(p), "{:?}", p);
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        /// Whatever the inputs (huge, far, out of the plan, into walls), the probabilities
        /// stay a distribution and the estimate stays finite.
        #[test]
        fn probabilities_stay_a_distribution(
            inputs in proptest::collection::vec((any::<bool>(), -1e4f64..1e4, -1e4f64..1e4, -10.0f64..10.0), 1..60),
            with_plan in any::<bool>(),
        ) {
            let plan = with_plan.then(ring_plan);
            let mut f = PointMassFilter::new(PointMassConfig::default(), plan, None, None).unwrap();
            for (k, (is_fix, x, y, h)) in inputs.into_iter().enumerate() {
                let t = k as TimestampMs * 300;
                if is_fix {
                    f.on_wifi(&fix(t, x / 100.0, y / 100.0));
                } else {
                    f.on_step(&step(t, h));
                }
                if f.initialised {
                    prop_assert!((total(&f) - 1.0).abs() < 1e-9, "total {}", total(&f));
                    prop_assert!(f.prob.iter().all(|v| v.is_finite() && *v >= 0.0));
                }
                if let Some(e) = f.estimate() {
                    prop_assert!(e.position.x.is_finite() && e.position.y.is_finite());
                }
            }
        }
    }
}

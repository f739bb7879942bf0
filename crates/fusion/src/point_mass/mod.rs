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
//! The estimate is the geometric median of `o + D` over the cells within `estimate_radius_m`
//! of the most probable cell (`estimate_median`, the default: the point of least expected
//! error; otherwise their mean, as in [`PointMassConfig::paper`]): the dominant mode's
//! centre, where a plain mean would sit between two modes. It is reported from the first
//! Wi-Fi fix on, as for the other schemes (or from a given start, which collapses the prior
//! there).
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
//!     candidates: vec![], visited: 0, floor: None, building: None, likelihood: None };
//! f.on_wifi(&fix(0, 10.0, 10.0));
//! for k in 1..=10 {
//!     f.on_step(&StepEvent { t: 500 * k, length: 0.7, heading: 0.0, heading_change: 0.0,
//!         period_s: 0.5, motion: MotionState::default(), covariance: None });
//! }
//! f.on_wifi(&fix(6000, 10.0, 17.0));
//! let p = f.estimate().unwrap().position;
//! assert!((p.x - 10.0).abs() < 1.0 && (p.y - 17.0).abs() < 1.5, "{p:?}");
//! ```

//!
//! The module's files: `config` (the serde config and its checks), `lattice` (laying the
//! hypotheses, normalisation, the active window, the blur, the weighing pass), `mode` (the
//! mode search and the estimate), `gap` (the coverage-gap raster), `fuser` (the step and
//! Wi-Fi likelihoods behind [`Fuser`]), `smoother` (forward-backward smoothing of a whole
//! walk on the lattice, [`PointMassFilter::smooth_walk`]), `mixture` (one lattice per PDR
//! heading-bias and step-scale hypothesis, weighed by evidence, [`PointMassMixture`]) and the
//! tests.

mod config;
mod fuser;
mod gap;
mod lattice;
mod mixture;
mod mode;
mod smoother;
#[cfg(test)]
mod tests;

use std::sync::Arc;
use wipdr_core::ConfigError;

use wipdr_core::{GridError, GridSpec, Point2, TimestampMs, Vector2};

use crate::trails::TrailRaster;
use crate::walkable::WalkableGrid;
use crate::{BuildContext, FusionError, InputGuard};

pub use config::PointMassConfig;
use gap::GapRaster;
pub use mixture::{MAX_HEADING_HYPOTHESES, PointMassMixture};
pub use smoother::{MAX_STORED_CELLS, SmoothError};

/// Most cells the lattice may have.
pub const MAX_CELLS: usize = 4 << 20;

/// The point-mass filter; see the [module docs](self).
#[derive(Debug, Clone)]
pub struct PointMassFilter {
    cfg: PointMassConfig,
    walkable: Option<Arc<WalkableGrid>>,
    coverage: Option<Arc<Vec<Point2>>>,
    trails: Option<Arc<TrailRaster>>,
    /// Lattice of the offsets `o` (laid over positions, then moved by the PDR displacement
    /// at lay time); a 1 x 1 placeholder until laid (`initialised`).
    lattice: GridSpec,
    prob: Vec<f64>,
    scratch: Vec<f64>,
    /// Distance class of positions: whether each position cell (same lattice, positions
    /// rather than offsets, over the coverage extent) is in a gap. Built lazily.
    gap: Option<GapRaster>,
    /// Active window (inclusive cell ranges) outside which every cell is at the floor.
    active: (usize, usize, usize, usize),
    floor: f64,
    bg: f64,
    /// Step weight of a background hypothesis: the plan's mean class weight (1 without one).
    step_background: f64,
    sat: Vec<f64>,
    /// Per-input buffers of one window row (positions, raster columns, weights).
    row_buffers: RowBuffers,
    mode: Option<usize>,
    pdr: Vector2,
    pending_drift: f64,
    /// Metres walked since the latest fix (`fix_decorrelation_m`).
    walked_since_fix: f64,
    /// Log of the inputs' marginal likelihood so far ([`PointMassFilter::log_evidence`]).
    log_evidence: f64,
    initialised: bool,
    reporting: bool,
    /// The fixes' error variance learned from their residuals (the reported radius).
    fix_error: crate::fix_error::FixErrorTracker,
    t: TimestampMs,
    guard: InputGuard,
}

/// Reused buffers of one active-window row, so that weighing, the blur and the mode search
/// allocate nothing per input.
#[derive(Debug, Clone, Default)]
struct RowBuffers {
    /// x of the positions `o + D` of the window's columns (shared by every row).
    xs: Vec<f64>,
    /// Column of each of those x in a raster ([`NO_CELL`] outside it).
    columns: Vec<usize>,
    /// Weights of one row's cells.
    weights: Vec<f64>,
}

/// Marks a coordinate outside a raster in the per-row and per-column look-ups
/// ([`GridSpec::col_of`], [`GridSpec::row_of`]), which are stored in plain `usize` buffers.
const NO_CELL: usize = usize::MAX;

/// A raster look-up error as a config error of `field`.
fn grid_error(field: &'static str, what: &'static str) -> impl Fn(GridError) -> FusionError {
    move |e| FusionError::InvalidConfig(ConfigError::new(field, format!("{what}: {e}")))
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
        let placeholder = GridSpec::new(Point2::origin(), cfg.cell_m, 1, 1, 1)
            .map_err(grid_error("cell_m", "no lattice"))?;
        let step_background = walkable.as_ref().map_or(1.0, |g| {
            g.mean_class_weight(cfg.unit_likelihood, cfg.outside_likelihood)
        });
        let mut f = Self {
            fix_error: crate::fix_error::FixErrorTracker::new(&cfg.radius),
            cfg,
            step_background,
            walkable,
            coverage,
            trails: None,
            lattice: placeholder,
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
            walked_since_fix: 0.0,
            log_evidence: 0.0,
            initialised: false,
            reporting: false,
            t: 0,
            guard: InputGuard::default(),
        };
        if let Some(grid) = f.walkable.clone() {
            f.lay_lattice(grid.origin(), grid.grid().far_corner())?;
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

    /// Builds `pmf` from what [`crate::SchemeConfig::build`] gets: the plan's walkable space,
    /// the radio map's reference points, a known start and the trails.
    pub fn from_context(cfg: &PointMassConfig, ctx: &BuildContext) -> Result<Self, FusionError> {
        if ctx.walkable.is_none() {
            // Said once per site, where the site is built (`Site::from_plan`), not per stream.
            tracing::debug!("pmf built without a floor plan: no walkability");
        }
        Ok(Self::new(
            cfg.clone(),
            ctx.walkable.clone(),
            ctx.coverage.clone(),
            ctx.start,
        )?
        .with_trails(ctx.trails.clone()))
    }

    /// The log of the marginal likelihood of the inputs taken so far: the sum of the logs of
    /// each input's weighted total (the probability before it summing to 1). Comparable
    /// between filters of the same lattice and likelihoods that differ in a PDR hypothesis
    /// (heading offset, step scale), which is how [`PointMassMixture`](super::point_mass)
    /// weighs them.
    pub fn log_evidence(&self) -> f64 {
        self.log_evidence
    }

    /// Adds the training trails ([`crate::trails`]): with `trail_sd_m > 0` (or, on a plan
    /// without walls, `planless_trail_sd_m > 0`), each step weighs every hypothesis by its
    /// position's distance to the nearest trail.
    pub fn with_trails(mut self, trails: Option<Arc<TrailRaster>>) -> Self {
        self.trails = trails;
        self
    }
}

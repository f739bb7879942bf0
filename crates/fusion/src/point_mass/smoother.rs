//! Forward-backward smoothing of `pmf` over a whole recorded walk: the exact product of the
//! forward posterior (inputs up to `t`) and the backward likelihood (inputs after `t`) on
//! the lattice of placements, rather than the Gaussian product of two estimates
//! ([`crate::offline::two_filter`]), so a posterior with two modes keeps them until the
//! other direction's evidence picks one.
//!
//! The state is the offset `o` of the PDR track (position `o + D(t)`): input `k`'s
//! likelihood `L_k(o)` is evaluated at the forward run's displacement `D_k`, and a step's
//! drift is the same symmetric blur in both directions, so the backward recursion is
//! `beta_{k-1} = Blur^{b_k}(L_k beta_k)` from a uniform `beta` after the last input, and the
//! smoothed distribution at `k` is `alpha_k beta_k`. Its estimate is taken as the forward
//! filter's (the geometric median, or the mean, within `estimate_radius_m` of the dominant
//! mode; covariance from the spread).
//!
//! The forward posteriors are kept (as `f32`, the active window only) until the backward
//! pass meets them; a walk whose windows would exceed [`MAX_STORED_CELLS`] is refused
//! ([`SmoothError::TooLarge`]) so the caller can fall back to the two-filter smoother.

use wipdr_core::{StepEvent, TimestampMs, Vector2, WifiObservation};

use super::PointMassFilter;
use crate::replay::{FusionInput, merged};
use crate::{Estimate, Fuser};

/// Most lattice cells (summed over the inputs) the forward pass may keep for the backward
/// pass: 32 Mi cells, 128 MiB of `f32`.
pub const MAX_STORED_CELLS: usize = 32 << 20;

/// Why a walk was not smoothed on the lattice.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SmoothError {
    /// The forward posteriors would take more than [`MAX_STORED_CELLS`] cells.
    #[error(
        "pmf smoothing: the forward posteriors need {cells} cells, more than {MAX_STORED_CELLS}"
    )]
    TooLarge {
        /// Cells the walk would need (counted up to the refusal).
        cells: usize,
    },
}

/// What the forward pass did with one input.
#[derive(Debug, Clone, Copy)]
enum Applied {
    /// A step taken by the lattice, with the number of drift blurs before its weights.
    Step(usize),
    /// Fix `j` (an index into the walk's fixes) taken by the lattice.
    Fix(usize),
    /// Refused by the input guard (or before the lattice was laid): no likelihood.
    Nothing,
}

/// The forward posterior after one input.
#[derive(Debug)]
struct Snapshot {
    t: TimestampMs,
    pdr: Vector2,
    applied: Applied,
    /// Active window (inclusive column and row ranges) and its cells, row-major.
    window: (usize, usize, usize, usize),
    cells: Vec<f32>,
    /// Probability of every cell outside the window.
    bg: f64,
}

impl PointMassFilter {
    /// The smoothed estimate after every input of a whole walk (steps and fixes, each sorted
    /// by time, merged as [`crate::replay::merged`] does), from a freshly built filter. No
    /// estimate before the lattice is laid (without a floor plan: before the first fix), and
    /// none at all for a walk without a fix the filter took.
    ///
    /// ```
    /// use wipdr_core::{MotionState, Point2, StepEvent, WifiObservation};
    /// use wipdr_fusion::point_mass::{PointMassConfig, PointMassFilter};
    /// let f = PointMassFilter::new(PointMassConfig::default(), None, None, None).unwrap();
    /// let fix = |t, x: f64, y: f64| WifiObservation { t, estimate: Point2::new(x, y),
    ///     candidates: vec![], visited: 0, floor: None, building: None, likelihood: None };
    /// let steps: Vec<StepEvent> = (1..=20).map(|k| StepEvent { t: 500 * k, length: 0.7,
    ///     heading: 0.0, heading_change: 0.0, period_s: 0.5, motion: MotionState::default(), covariance: None })
    ///     .collect();
    /// let fixes = vec![fix(0, 0.0, 0.0), fix(5_000, 0.0, 7.0), fix(10_000, 0.0, 14.0)];
    /// let track = f.smooth_walk(&steps, &fixes).unwrap();
    /// assert_eq!(track.len(), steps.len() + fixes.len());
    /// // The first estimate already knows where the later fixes put the track.
    /// assert!(track[0].position.y.abs() < 1.5, "{:?}", track[0].position);
    /// ```
    pub fn smooth_walk(
        self,
        steps: &[StepEvent],
        fixes: &[WifiObservation],
    ) -> Result<Vec<Estimate>, SmoothError> {
        self.smooth_walk_with_evidence(steps, fixes)
            .map(|(track, _)| track)
    }

    /// [`PointMassFilter::smooth_walk`] with the walk's log evidence (the forward run's
    /// [`PointMassFilter::log_evidence`] after the last input).
    pub fn smooth_walk_with_evidence(
        self,
        steps: &[StepEvent],
        fixes: &[WifiObservation],
    ) -> Result<(Vec<Estimate>, f64), SmoothError> {
        let mut forward = self;
        let mut snapshots: Vec<Snapshot> = Vec::with_capacity(steps.len() + fixes.len());
        let mut stored = 0usize;
        let mut any_fix = false;
        for input in merged(steps, fixes) {
            let applied = match input {
                FusionInput::Step(i) => forward.apply_step(&steps[i]).map(Applied::Step),
                FusionInput::Wifi(j) => forward.apply_fix(&fixes[j]).then_some(Applied::Fix(j)),
            }
            .unwrap_or(Applied::Nothing);
            any_fix |= matches!(applied, Applied::Fix(_));
            if !forward.initialised {
                continue;
            }
            let t = match input {
                FusionInput::Step(i) => steps[i].t,
                FusionInput::Wifi(j) => fixes[j].t,
            };
            let snapshot = forward.snapshot(t, applied);
            stored += snapshot.cells.len();
            if stored > MAX_STORED_CELLS {
                return Err(SmoothError::TooLarge { cells: stored });
            }
            snapshots.push(snapshot);
        }
        let evidence = forward.log_evidence;
        if !any_fix || snapshots.is_empty() {
            return Ok((Vec::new(), evidence));
        }
        // The backward likelihood, on the forward filter's lattice (its walls, gaps and
        // guard state are what the inputs were weighed with); uniform after the last input.
        let mut backward = forward;
        backward.reset_uniform();
        let mut joint = backward.clone();
        joint.reporting = true;
        let mut out = Vec::with_capacity(snapshots.len());
        for snap in snapshots.iter().rev() {
            joint.set_product(snap, &backward);
            if let Some(e) = joint.estimate() {
                out.push(e);
            }
            backward.pdr = snap.pdr;
            match snap.applied {
                Applied::Step(blurs) => {
                    let total = backward.weigh_step();
                    backward.normalise(total);
                    for _ in 0..blurs {
                        backward.blur();
                    }
                }
                Applied::Fix(j) => {
                    let total = backward.weigh_fix(&fixes[j]);
                    backward.normalise(Some(total));
                }
                Applied::Nothing => {}
            }
        }
        out.reverse();
        Ok((out, evidence))
    }

    /// The active window's cells (as `f32`) and the background, after input `applied`.
    fn snapshot(&self, t: TimestampMs, applied: Applied) -> Snapshot {
        let (x0, x1, y0, y1) = self.active;
        let nx = self.lattice.cols();
        let mut cells = Vec::with_capacity((x1 - x0 + 1) * (y1 - y0 + 1));
        for r in y0..=y1 {
            cells.extend(
                self.prob[r * nx + x0..=r * nx + x1]
                    .iter()
                    .map(|&v| v as f32),
            );
        }
        Snapshot {
            t,
            pdr: self.pdr,
            applied,
            window: self.active,
            cells,
            bg: self.bg,
        }
    }

    /// Every cell equally likely, the whole lattice active, no mode.
    fn reset_uniform(&mut self) {
        let n = self.prob.len();
        if n == 0 {
            return;
        }
        let u = 1.0 / n as f64;
        self.prob.iter_mut().for_each(|v| *v = u);
        self.bg = u;
        self.active = (0, self.lattice.cols() - 1, 0, self.lattice.rows() - 1);
        self.mode = None;
    }

    /// This filter's lattice set to the normalised product of a forward snapshot and the
    /// backward likelihood `beta` (same lattice), at the snapshot's time and displacement;
    /// then its mode is chosen (with this filter's hysteresis across calls).
    fn set_product(&mut self, snap: &Snapshot, beta: &PointMassFilter) {
        let nx = self.lattice.cols();
        let (a0, a1, b0, b1) = snap.window;
        let (c0, c1, d0, d1) = beta.active;
        let box_ = (a0.min(c0), a1.max(c1), b0.min(d0), b1.max(d1));
        let width = a1 - a0 + 1;
        for r in box_.2..=box_.3 {
            for c in box_.0..=box_.1 {
                let alpha = if (a0..=a1).contains(&c) && (b0..=b1).contains(&r) {
                    f64::from(snap.cells[(r - b0) * width + (c - a0)])
                } else {
                    snap.bg
                };
                let i = r * nx + c;
                let b = if (c0..=c1).contains(&c) && (d0..=d1).contains(&r) {
                    beta.prob[i]
                } else {
                    beta.bg
                };
                self.prob[i] = alpha * b;
            }
        }
        self.active = box_;
        self.bg = snap.bg * beta.bg;
        self.pdr = snap.pdr;
        self.t = snap.t;
        self.normalise(None);
        self.choose_mode();
    }
}

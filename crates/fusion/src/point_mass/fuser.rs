//! The step likelihood (walkable class, trails) and the Wi-Fi likelihood (robust, coverage
//! aware) of `pmf`, behind [`Fuser`].

use nalgebra::Matrix2;
use wipdr_core::{Point2, StepEvent, Vector2, WifiLikelihood, WifiObservation, angle};

use super::{NO_CELL, PointMassFilter};
use crate::walkable::CellClass;
use crate::{Estimate, Fuser};

/// Most blur passes one motion event with its own covariance may ask for: 64 passes of
/// `0.5 cell²` (32 m² on the default 1 m lattice, a 5.7 m standard deviation in one event).
/// The shipped network's variances are at most about 400 m² a second (`LOG_VAR_RANGE` of
/// `wipdr_pdr::odometry`); the cap bounds an event's cost whatever the input says.
const MAX_EVENT_BLURS: f64 = 64.0;

impl Fuser for PointMassFilter {
    fn name(&self) -> &'static str {
        "pmf"
    }

    fn on_step(&mut self, step: &StepEvent) {
        self.apply_step(step);
    }

    fn on_wifi(&mut self, obs: &WifiObservation) {
        self.apply_fix(obs);
    }

    fn estimate(&self) -> Option<Estimate> {
        let (p, mut covariance) = self.lattice_estimate()?;
        covariance +=
            Matrix2::identity() * (self.cfg.radius.bias_share * self.fix_error.variance());
        covariance += Matrix2::identity() * self.gap_sd_m_at(p).powi(2);
        crate::kalman::enforce_symmetric_pd(&mut covariance);
        Some(Estimate {
            covariance: Some(covariance),
            ..Estimate::point(self.t, p, self.guard.diagnostics())
        })
    }
}

impl PointMassFilter {
    /// The standard deviation the reported covariance adds per axis at `p` for its distance
    /// from the radio map's coverage: `gap_radius_sd_per_m` times the distance from `p`'s
    /// cell to the nearest reference point, capped where the coverage raster's search ends
    /// (`gap_distance_m` plus two cells). 0 without the raster (no reference points given,
    /// `gap_distance_m` 0) or with `gap_radius_sd_per_m` 0.
    pub(super) fn gap_sd_m_at(&self, p: Point2) -> f64 {
        let per_m = self.cfg.gap_radius_sd_per_m;
        match &self.gap {
            Some(g) if per_m > 0.0 => {
                let cap = self.cfg.gap_distance_m + 2.0 * g.grid.cell_m();
                per_m * g.distance_at(p, cap)
            }
            _ => 0.0,
        }
    }

    /// The estimate and the lattice's own covariance (without the learned bias share).
    pub(super) fn lattice_estimate(&self) -> Option<(Point2, Matrix2<f64>)> {
        if !self.reporting || self.prob.is_empty() || self.mode.is_none() {
            return None;
        }
        let (mode, radius) = (self.mode?, self.cfg.estimate_radius_m);
        let cells = self.near_cells(mode, radius);
        let mean = super::mode::mean_of(&cells, self.offset_of(mode));
        let o = if self.cfg.estimate_median {
            super::mode::median_of(&cells, mean, self.cfg.cell_m)
        } else {
            mean
        };
        let p = Point2::from(o + self.pdr);
        (p.x.is_finite() && p.y.is_finite()).then(|| (p, self.spread_about(o)))
    }

    /// A step: the drift blur, then the walls' (and trails') weights at the new position.
    /// `Some(blurs)` (how many blurs the drift made) when the lattice took it, `None` when the
    /// guard refused it or the lattice is not laid yet.
    pub(super) fn apply_step(&mut self, step: &StepEvent) -> Option<usize> {
        if !self.guard.accept_step(step) {
            return None;
        }
        self.t = step.t;
        self.pdr += angle::step_displacement(
            step.length * self.cfg.step_scale,
            step.heading + self.cfg.heading_offset_deg.to_radians(),
        );
        self.walked_since_fix += step.length * self.cfg.step_scale;
        self.fix_error.walk(step.length * self.cfg.step_scale);
        if !self.initialised {
            return None;
        }
        let h = self.cfg.cell_m;
        // A motion event with its own covariance (learned odometry) blurs by its mean
        // per-axis variance instead of the step model's drift, at most MAX_EVENT_BLURS
        // passes (each a lattice sweep) whatever the covariance says.
        self.pending_drift += step
            .displacement_covariance()
            .map_or(self.cfg.drift_m2_per_step, |c| {
                (0.5 * c.trace()).min(MAX_EVENT_BLURS * 0.5 * h * h)
            });
        let mut blurs = 0;
        while self.pending_drift >= 0.5 * h * h {
            self.blur();
            blurs += 1;
            self.pending_drift -= 0.5 * h * h;
        }
        let total = self.weigh_step();
        self.normalise(total);
        self.choose_mode();
        Some(blurs)
    }

    /// A Wi-Fi fix (laying the lattice around the first one when there is no plan); whether
    /// the lattice took it.
    pub(super) fn apply_fix(&mut self, obs: &WifiObservation) -> bool {
        if !self.guard.accept_wifi(obs) {
            return false;
        }
        self.t = obs.t;
        if !self.initialised {
            let m = Vector2::new(100.0, 100.0);
            if self
                .lay_lattice(obs.estimate - m, obs.estimate + m)
                .is_err()
            {
                return false;
            }
        }
        if let Some((p, cov)) = self.lattice_estimate() {
            self.fix_error.observe(obs.estimate - p, 0.5 * cov.trace());
        }
        let total = self.weigh_fix(obs);
        self.normalise(Some(total));
        self.choose_mode();
        self.reporting = true;
        true
    }

    /// The trails' width in the step weight: `trail_sd_m` when set, else
    /// `planless_trail_sd_m` when the filter has no walkable raster, else 0 (off).
    fn trail_sd_m(&self) -> f64 {
        if self.cfg.trail_sd_m > 0.0 {
            self.cfg.trail_sd_m
        } else if self.walkable.is_none() {
            self.cfg.planless_trail_sd_m
        } else {
            0.0
        }
    }

    /// Multiplies the active cells by the step likelihood at the current displacement (the
    /// walkable class, the trails); the represented total, or `None` when neither is there.
    pub(super) fn weigh_step(&mut self) -> Option<f64> {
        let trail_sd = self.trail_sd_m();
        let trails = self.trails.clone().filter(|_| trail_sd > 0.0);
        let (off, trail_inv) = (
            self.cfg.off_trail_likelihood,
            1.0 / (2.0 * trail_sd * trail_sd),
        );
        let trail_weight = |pos: Point2| match &trails {
            Some(t) => {
                let d = t.distance(pos);
                off + (1.0 - off) * (-d * d * trail_inv).exp()
            }
            None => 1.0,
        };
        // A background hypothesis is somewhere on the plan (the plan's mean class weight)
        // and, with the trail prior, most likely off the trails.
        let background = self.step_background * if trails.is_some() { off } else { 1.0 };
        if let Some(grid) = self.walkable.clone() {
            let (unit, outside) = (self.cfg.unit_likelihood, self.cfg.outside_likelihood);
            let raster = *grid.grid();
            let class_weight = |row: usize, column: usize| {
                if row == NO_CELL || column == NO_CELL {
                    return outside;
                }
                match grid.class_of_cell(raster.index(column, row)) {
                    CellClass::Walkable => 1.0,
                    CellClass::Unit => unit,
                    CellClass::Outside => outside,
                }
            };
            Some(self.weigh(
                background,
                |x| raster.col_of(x).unwrap_or(NO_CELL),
                |y, xs, columns, weights| {
                    // `class_at(pos)` split into its row (once per row) and column lookups.
                    let row = raster.row_of(y).unwrap_or(NO_CELL);
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
                background,
                |_| NO_CELL,
                |y, xs, _, weights| {
                    for (weight, &x) in weights.iter_mut().zip(xs) {
                        *weight = trail_weight(Point2::new(x, y));
                    }
                },
            ))
        } else {
            None
        }
    }

    /// Multiplies the active cells by the Wi-Fi likelihood of `obs` (robust, coverage aware)
    /// at the current displacement; the represented total.
    pub(super) fn weigh_fix(&mut self, obs: &WifiObservation) -> f64 {
        let f = obs.estimate;
        // Fix quality: a poor best match (large signal distance) is likely a coverage gap or
        // a gross fix, so its Gaussian part is down-weighted (a logistic in the distance).
        let trust = match obs.best_distance() {
            Some(d) if self.cfg.quality_distance > 0.0 && d.is_finite() => {
                1.0 / (1.0 + ((d - self.cfg.quality_distance) / self.cfg.quality_softness).exp())
            }
            _ => 1.0,
        };
        // Decorrelation: a fix after little walking repeats the previous one's error.
        let power = if self.cfg.fix_decorrelation_m > 0.0 {
            (self.walked_since_fix / self.cfg.fix_decorrelation_m)
                .clamp(self.cfg.min_fix_weight, 1.0)
        } else {
            1.0
        };
        self.walked_since_fix = 0.0;
        let likelihood = obs
            .likelihood
            .clone()
            .filter(|_| self.cfg.wifi_likelihood && self.cfg.likelihood_share > 0.0);
        let share = if likelihood.is_some() {
            self.cfg.likelihood_share
        } else {
            0.0
        };
        if share >= 1.0
            && let Some(likelihood) = &likelihood
        {
            return self.weigh_likelihood(likelihood, power);
        }
        let inv = power / (2.0 * self.cfg.wifi_sd_m * self.cfg.wifi_sd_m);
        let (outlier, gap_like) = (self.cfg.wifi_outlier, self.cfg.gap_likelihood);
        let gap_inv = 1.0 / (2.0 * self.cfg.gap_sd_m * self.cfg.gap_sd_m);
        // `is_gap(pos)` split into its row and column lookups, as in `on_step`.
        let gap = self.gap.take();
        // The likelihood's share of the weight (`likelihood_share`), the Gaussian's the rest.
        let keep = 1.0 - share;
        let background = outlier + likelihood.as_ref().map_or(0.0, |l| share * l.unknown());
        let mut likelihood_columns: Vec<usize> = Vec::new();
        let total = self.weigh(
            background,
            |x| {
                gap.as_ref()
                    .and_then(|g| g.grid.col_of(x))
                    .unwrap_or(NO_CELL)
            },
            |y, xs, columns, weights| {
                let gap_row = gap
                    .as_ref()
                    .and_then(|g| g.grid.row_of(y))
                    .unwrap_or(NO_CELL);
                for ((weight, &column), &x) in weights.iter_mut().zip(columns).zip(xs) {
                    let r2 = (f - Point2::new(x, y)).norm_squared();
                    let in_gap = gap.as_ref().is_some_and(|g| {
                        gap_row == NO_CELL
                            || column == NO_CELL
                            || g.gap[g.grid.index(column, gap_row)]
                    });
                    *weight = if in_gap {
                        gap_like * (-r2 * gap_inv).exp() + outlier
                    } else {
                        trust * (-r2 * inv).exp() + outlier
                    };
                }
                if let Some(l) = &likelihood {
                    let (grid, powered) = (l.grid(), power != 1.0);
                    // The likelihood raster's column of each window column: the same for
                    // every row, so looked up at the first row only.
                    if likelihood_columns.len() != xs.len() {
                        likelihood_columns.clear();
                        likelihood_columns
                            .extend(xs.iter().map(|&x| grid.col_of(x).unwrap_or(NO_CELL)));
                    }
                    let row = grid.row_of(y).unwrap_or(NO_CELL);
                    for (weight, &column) in weights.iter_mut().zip(&likelihood_columns) {
                        let v = l.at_cell(column, row);
                        let v = if powered { v.powf(power) } else { v };
                        *weight = keep * (*weight - outlier) + share * v + outlier;
                    }
                }
            },
        );
        self.gap = gap;
        total
    }

    /// Multiplies the active cells by the scan's likelihood at their positions (relative to
    /// its best cell, raised to the decorrelation `power`) plus the outlier floor
    /// `wifi_outlier`; a position the radio map does not know reads the scan's mean
    /// likelihood over the known places ([`WifiLikelihood::unknown`]), so a coverage gap is
    /// flat instead of a fake fix. The represented total.
    fn weigh_likelihood(&mut self, likelihood: &WifiLikelihood, power: f64) -> f64 {
        let outlier = self.cfg.wifi_outlier;
        let grid = *likelihood.grid();
        let weight = |v: f64| {
            if power == 1.0 {
                v + outlier
            } else {
                v.powf(power) + outlier
            }
        };
        // A background hypothesis is somewhere unknown to the window: the mean likelihood.
        let background = weight(likelihood.unknown());
        self.weigh(
            background,
            |x| grid.col_of(x).unwrap_or(NO_CELL),
            |y, _, columns, weights| {
                let row = grid.row_of(y).unwrap_or(NO_CELL);
                for (w, &column) in weights.iter_mut().zip(columns) {
                    *w = weight(likelihood.at_cell(column, row));
                }
            },
        )
    }
}

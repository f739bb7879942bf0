//! Particle filters of paper 004 §4.3: `pf` (eq. 12-17) and `apf` (walls and the adaptive
//! weight, eq. 18-20, §4.3.3).
//!
//! # The algorithm
//!
//! Each particle carries a position and its own dead-reckoning corrections: a heading offset
//! and a step-length scale (the `L`, `theta` of the state `[L, theta, x, y]` of eq. 14,
//! kept as corrections of the PDR's step length and heading, which is what lets the cloud
//! learn a PDR bias). Per step (eq. 14): `L_i = scale_i l + N(0, sd_L)`,
//! `theta_i = psi + offset_i + N(0, sd_theta)`, `p_i += L_i (sin, cos)(theta_i) + N(0, sd_p)`;
//! the offset and the scale random-walk slowly.
//!
//! A Wi-Fi fix weights each particle by the Gaussian likelihood of the Wi-Fi-minus-DR
//! observation (eq. 15, 17) with `R = wifi_sd_m^2 I` (the paper gives no value; 10 m as the
//! EKF's `R_w`). Weights are handled in the log domain and normalised by their maximum, so
//! they never underflow to all zeros. Systematic resampling when the effective sample size
//! falls below `resample_threshold * N`.
//!
//! `apf` adds (§4.3.3) a zero weight for a particle whose step crosses a wall (an rstar index,
//! [`WallIndex`]) and (eq. 18-20) the adaptive factor at each fix. `dist` (eq. 18) is read as
//! the distance between each particle's current position and its own position at the
//! previous fix ("the distance between current and historical particles", abstract); the
//! circle of figure 5 has the radius `r = walking_speed * dt` the walker can cover since then.
//! As printed, `1 / (1 + e^-dist)` (eq. 19) grows with the distance, against the paper's own
//! text ("the farther away, the lower the weight"); the decreasing
//! `1 / (1 + e^((dist - r) / s))` is implemented, `s` a softness. (Measuring `dist` from the
//! previous *estimate* instead made the cloud lag behind the walker on synthetic walks: it
//! favours particles that moved less.)
//!
//! **Recovery.** When walls kill every particle on a step, the previous set is kept (the step
//! is not applied); after `wall_stuck_steps` such steps in a row the move is applied without
//! the wall test. When `reseed_after` consecutive fixes lie outside the gate
//! (`reseed_gate_sd` standard deviations of `sqrt(R + cloud variance)`) and agree with each
//! other once the raw PDR displacement between them is removed, the cloud is re-seeded around the latest fix (a start from a wrong fix or a lost
//! cloud). Nothing divides by zero.

use std::sync::Arc;
use wipdr_core::ConfigError;

use nalgebra::Matrix2;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::Normal;
use serde::{Deserialize, Serialize};
use wipdr_core::{Point2, Segment, StepEvent, TimestampMs, Vector2, WifiObservation, angle};

use crate::fix_error::{FixErrorTracker, RadiusConfig};
use crate::kalman::enforce_symmetric_pd;
use crate::resample::{effective_sample_size, systematic};
use crate::{Diagnostics, Estimate, Fuser, FusionError, InputGuard, WallIndex};

/// A particle position with its normalised weight (for plots).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WeightedPoint {
    /// Position, metres.
    pub position: Point2,
    /// Normalised weight.
    pub weight: f64,
}

/// Parameters of `pf` and `apf` (004 §4.3). The paper gives no numeric values; these are ours.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PfConfig {
    /// Number of particles.
    pub n_particles: usize,
    /// Step-length noise per step, metres.
    pub step_length_sd_m: f64,
    /// Heading noise per step, degrees.
    pub heading_sd_deg: f64,
    /// Position noise per step, metres (default 0.6; the untuned preset [`PfConfig::paper`]
    /// 0.05: the cloud collapsed to a metre or two and could not follow the fixes, 12.8 m
    /// mean on the IPIN walks against 8.3).
    pub position_sd_m: f64,
    /// Initial spread of the per-particle heading offset, degrees.
    pub heading_offset_sd_deg: f64,
    /// Random walk of the heading offset per step, degrees.
    pub heading_offset_walk_deg: f64,
    /// Initial spread of the per-particle step scale.
    pub step_scale_sd: f64,
    /// Random walk of the step scale per step.
    pub step_scale_walk: f64,
    /// Wi-Fi observation standard deviation (R = sd² I), metres (default 7; preset 10, as
    /// the EKF's `R_w`).
    pub wifi_sd_m: f64,
    /// Spread of the initial cloud around the first fix (or a re-seed), metres.
    pub init_spread_m: f64,
    /// Spread of the initial cloud around a given start, metres.
    pub start_spread_m: f64,
    /// Resample when ESS < threshold * N.
    pub resample_threshold: f64,
    /// Walking speed bounding the adaptive radius `r = speed * dt` (004: 1-1.5 m/s), m/s.
    pub walking_speed_mps: f64,
    /// Softness `s` of the adaptive factor, metres.
    pub adaptive_softness_m: f64,
    /// Steps of consecutive wall wipe-outs before a move is applied without walls.
    pub wall_stuck_steps: u32,
    /// `apf` only: zero weight for a particle whose step crosses a wall (§4.3.3).
    pub use_walls: bool,
    /// `apf` only: the adaptive factor (eq. 18-20).
    pub use_adaptive_factor: bool,
    /// Re-seed after this many consecutive out-of-gate, mutually consistent fixes (0: never).
    pub reseed_after: usize,
    /// Gate in standard deviations.
    pub reseed_gate_sd: f64,
    /// Consistency of the out-of-gate fixes (RMS of their offsets about the mean), metres.
    pub reseed_consistency_m: f64,
    /// The reported uncertainty: the cloud's covariance plus [`crate::fix_error`]'s bias
    /// share of the learned Wi-Fi variance (the cloud alone assumes independent fixes and
    /// held the truth at 46 % of the IPIN points; wipdr's own, the same in both presets).
    pub radius: RadiusConfig,
    /// Weigh particles by the scan's likelihood over the floor as well
    /// ([`wipdr_core::WifiLikelihood`], when the fix carries one): a particle's Wi-Fi weight
    /// is `(1 - likelihood_share) g + likelihood_share l`, `g` the Gaussian about the fix
    /// (eq. 17), `l` the scan's likelihood at the particle relative to its best cell.
    /// wipdr's own (not in paper 004); off by default.
    pub wifi_likelihood: bool,
    /// The likelihood's share of the Wi-Fi weight with `wifi_likelihood`, in `[0, 1]`.
    pub likelihood_share: f64,
}

/// The shipped default differs from the untuned preset in `position_sd_m` and `wifi_sd_m`
/// (a grid on the five ILC floors and the IPIN walks, `docs/experiments.md`, `wipdr sweep`:
/// ILC 6.01 -> 5.77 m, IPIN 12.76 -> 8.34 m mean).
impl Default for PfConfig {
    fn default() -> Self {
        Self {
            position_sd_m: 0.6,
            wifi_sd_m: 7.0,
            ..Self::paper()
        }
    }
}

impl PfConfig {
    /// Paper 004 §4.3 gives no numeric values for its particle filters: its preset is ours,
    /// untuned on recorded walks (the defaults before the grid above).
    pub fn paper() -> Self {
        Self {
            n_particles: 1000,
            step_length_sd_m: 0.1,
            heading_sd_deg: 5.0,
            position_sd_m: 0.05,
            heading_offset_sd_deg: 5.0,
            heading_offset_walk_deg: 0.5,
            step_scale_sd: 0.1,
            step_scale_walk: 0.005,
            wifi_sd_m: 10.0,
            init_spread_m: 5.0,
            start_spread_m: 0.5,
            resample_threshold: 0.5,
            walking_speed_mps: 1.5,
            adaptive_softness_m: 1.0,
            wall_stuck_steps: 3,
            use_walls: true,
            use_adaptive_factor: true,
            reseed_after: 4,
            reseed_gate_sd: 3.0,
            reseed_consistency_m: 10.0,
            radius: RadiusConfig::default(),
            wifi_likelihood: false,
            likelihood_share: 0.5,
        }
    }
}

/// Upper bound of [`PfConfig::n_particles`]: one million particles (about 100 MB of state,
/// seconds per fix); a larger value is a config error, not an allocation failure.
pub const MAX_PARTICLES: usize = 1_000_000;

impl PfConfig {
    /// Checks every field.
    pub fn validate(&self) -> Result<(), FusionError> {
        if !(self.likelihood_share.is_finite() && (0.0..=1.0).contains(&self.likelihood_share)) {
            return Err(FusionError::InvalidConfig(ConfigError::new(
                "likelihood_share",
                format!("must be in [0, 1], got {}", self.likelihood_share),
            )));
        }
        if self.n_particles == 0 || self.n_particles > MAX_PARTICLES {
            return Err(FusionError::InvalidConfig(ConfigError::new(
                "n_particles",
                format!(
                    "must be in 1..={MAX_PARTICLES}, got {} (each particle costs about 100 bytes \
                     and one likelihood per fix)",
                    self.n_particles
                ),
            )));
        }
        let non_negative = [
            ("step_length_sd_m", self.step_length_sd_m),
            ("heading_sd_deg", self.heading_sd_deg),
            ("position_sd_m", self.position_sd_m),
            ("heading_offset_sd_deg", self.heading_offset_sd_deg),
            ("heading_offset_walk_deg", self.heading_offset_walk_deg),
            ("step_scale_sd", self.step_scale_sd),
            ("step_scale_walk", self.step_scale_walk),
            ("init_spread_m", self.init_spread_m),
            ("start_spread_m", self.start_spread_m),
            ("resample_threshold", self.resample_threshold),
        ];
        for (field, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return Err(FusionError::InvalidConfig(ConfigError::new(
                    field,
                    format!("must be finite and >= 0, got {v}"),
                )));
            }
        }
        let positive = [
            ("wifi_sd_m", self.wifi_sd_m),
            ("walking_speed_mps", self.walking_speed_mps),
            ("adaptive_softness_m", self.adaptive_softness_m),
            ("reseed_gate_sd", self.reseed_gate_sd),
            ("reseed_consistency_m", self.reseed_consistency_m),
        ];
        for (field, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(FusionError::InvalidConfig(ConfigError::new(
                    field,
                    format!("must be finite and > 0, got {v}"),
                )));
            }
        }
        self.radius.validate()
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Particle {
    position: Point2,
    /// The particle's position at the previous Wi-Fi fix (eq. 18's historical position).
    anchor: Point2,
    heading_offset: f64,
    step_scale: f64,
}

/// The particle filter; `apf` when built with `adaptive = true` (and walls when given).
#[derive(Debug)]
pub struct ParticleFilter {
    name: &'static str,
    cfg: PfConfig,
    adaptive: bool,
    walls: Option<Arc<WallIndex>>,
    rng: ChaCha8Rng,
    start: Option<Point2>,
    particles: Vec<Particle>,
    weights: Vec<f64>,
    scratch: Vec<Particle>,
    weights_backup: Vec<f64>,
    nearby_walls: Vec<Segment>,
    t: TimestampMs,
    previous_fix_estimate: Option<(TimestampMs, Point2)>,
    out_of_gate: Vec<Vector2>,
    odometry: Vector2,
    wall_stuck: u32,
    fix_error: FixErrorTracker,
    diagnostics: Diagnostics,
    guard: InputGuard,
}

fn normal(sd: f64) -> Normal<f64> {
    // validated finite and >= 0
    Normal::new(0.0, sd).unwrap_or_else(|_| Normal::new(0.0, 0.0).expect("zero sd"))
}

/// `ln(1 / (1 + e^x))`, computed without overflow.
fn log_logistic_decreasing(x: f64) -> f64 {
    if x > 0.0 {
        -x - (-x).exp().ln_1p()
    } else {
        -x.exp().ln_1p()
    }
}

impl ParticleFilter {
    /// Builds `pf` (`adaptive = false`, no walls) or `apf`.
    pub fn new(
        name: &'static str,
        cfg: PfConfig,
        adaptive: bool,
        walls: Option<Arc<WallIndex>>,
        seed: u64,
        start: Option<Point2>,
    ) -> Result<Self, FusionError> {
        cfg.validate()?;
        Ok(Self {
            name,
            adaptive,
            walls,
            rng: ChaCha8Rng::seed_from_u64(seed),
            start,
            particles: Vec::new(),
            weights: Vec::new(),
            scratch: Vec::new(),
            weights_backup: Vec::new(),
            nearby_walls: Vec::new(),
            t: 0,
            previous_fix_estimate: None,
            out_of_gate: Vec::new(),
            odometry: Vector2::zeros(),
            wall_stuck: 0,
            fix_error: FixErrorTracker::new(&cfg.radius),
            diagnostics: Diagnostics::default(),
            guard: InputGuard::default(),
            cfg,
        })
    }

    fn seed_cloud(&mut self, t: TimestampMs, centre: Point2, spread: f64) {
        let n = self.cfg.n_particles;
        let pos = normal(spread);
        let off = normal(self.cfg.heading_offset_sd_deg.to_radians());
        let scale = normal(self.cfg.step_scale_sd);
        self.particles = (0..n)
            .map(|_| {
                let position = centre + Vector2::new(self.rng.sample(pos), self.rng.sample(pos));
                Particle {
                    position,
                    anchor: position,
                    heading_offset: self.rng.sample(off),
                    step_scale: (1.0 + self.rng.sample(scale)).clamp(0.5, 1.5),
                }
            })
            .collect();
        self.weights = vec![1.0 / n as f64; n];
        self.t = t;
        self.out_of_gate.clear();
        self.previous_fix_estimate = Some((t, centre));
        self.diagnostics.particle_count = Some(n);
        self.diagnostics.effective_sample_size = Some(n as f64);
    }

    fn mean_and_cov(&self) -> (Point2, Matrix2<f64>) {
        let mut mean = Vector2::zeros();
        for (p, w) in self.particles.iter().zip(&self.weights) {
            mean += p.position.coords * *w;
        }
        let mut cov = Matrix2::zeros();
        for (p, w) in self.particles.iter().zip(&self.weights) {
            let d = p.position.coords - mean;
            cov += d * d.transpose() * *w;
        }
        enforce_symmetric_pd(&mut cov);
        (Point2::from(mean), cov)
    }

    /// Normalises the weights; returns `false` (weights untouched) when they sum to zero.
    fn normalise(&mut self) -> bool {
        let sum: f64 = self.weights.iter().sum();
        if !(sum > 0.0 && sum.is_finite()) {
            return false;
        }
        for w in &mut self.weights {
            *w /= sum;
        }
        true
    }

    fn maybe_resample(&mut self) {
        let n = self.particles.len();
        let ess = effective_sample_size(&self.weights);
        self.diagnostics.effective_sample_size = Some(ess);
        if ess < self.cfg.resample_threshold * n as f64 {
            let idx = systematic(&self.weights, &mut self.rng);
            self.scratch.clear();
            self.scratch.extend(idx.iter().map(|&i| self.particles[i]));
            std::mem::swap(&mut self.particles, &mut self.scratch);
            self.weights.iter_mut().for_each(|w| *w = 1.0 / n as f64);
        }
    }

    /// Moves every particle by one step into `self.scratch`; with `use_walls`, zeroes the
    /// weight of every particle whose move crosses a wall. The walls near the whole cloud
    /// are fetched with one R-tree query; each move is then tested against that short list
    /// (or against the tree when the list is long).
    fn propagate(&mut self, step: &StepEvent, use_walls: bool) {
        self.scratch.clear();
        let mut lo = Point2::new(f64::INFINITY, f64::INFINITY);
        let mut hi = Point2::new(f64::NEG_INFINITY, f64::NEG_INFINITY);
        match step.displacement_covariance() {
            None => self.move_by_step(step, &mut lo, &mut hi),
            Some(c) => self.move_by_displacement(step, &c, &mut lo, &mut hi),
        }
        self.constrain_by_walls(use_walls, lo, hi);
    }

    /// Moves every particle by the step with the step model's noise (004 eq. 12) and walks
    /// its scale and heading offset; `lo` and `hi` grow to hold every move.
    fn move_by_step(&mut self, step: &StepEvent, lo: &mut Point2, hi: &mut Point2) {
        let c = &self.cfg;
        let (len_n, head_n, pos_n) = (
            normal(c.step_length_sd_m),
            normal(c.heading_sd_deg.to_radians()),
            normal(c.position_sd_m),
        );
        let (off_walk, scale_walk) = (
            normal(c.heading_offset_walk_deg.to_radians()),
            normal(c.step_scale_walk),
        );
        for p in &self.particles {
            let length = (step.length * p.step_scale + self.rng.sample(len_n)).max(0.0);
            let heading = step.heading + p.heading_offset + self.rng.sample(head_n);
            let to = p.position
                + angle::step_displacement(length, heading)
                + Vector2::new(self.rng.sample(pos_n), self.rng.sample(pos_n));
            for q in [p.position, to] {
                *lo = Point2::new(lo.x.min(q.x), lo.y.min(q.y));
                *hi = Point2::new(hi.x.max(q.x), hi.y.max(q.y));
            }
            self.scratch.push(Particle {
                position: to,
                anchor: p.anchor,
                heading_offset: angle::wrap_pi(p.heading_offset + self.rng.sample(off_walk)),
                step_scale: (p.step_scale + self.rng.sample(scale_walk)).clamp(0.5, 1.5),
            });
        }
    }

    /// A motion event with its own covariance `c` (learned odometry,
    /// [`StepEvent::covariance`]): every particle moves by the displacement plus a draw of
    /// that covariance (its lower Cholesky factor times two standard normals). The step
    /// model's per-particle scale and heading offset neither apply nor walk.
    fn move_by_displacement(
        &mut self,
        step: &StepEvent,
        c: &nalgebra::Matrix2<f64>,
        lo: &mut Point2,
        hi: &mut Point2,
    ) {
        let d = angle::step_displacement(step.length, step.heading);
        let l11 = c[(0, 0)].sqrt();
        let l21 = if l11 > 0.0 { c[(1, 0)] / l11 } else { 0.0 };
        let l22 = (c[(1, 1)] - l21 * l21).max(0.0).sqrt();
        let unit = normal(1.0);
        for p in &self.particles {
            let (z1, z2) = (self.rng.sample(unit), self.rng.sample(unit));
            let to = p.position + d + Vector2::new(l11 * z1, l21 * z1 + l22 * z2);
            for q in [p.position, to] {
                *lo = Point2::new(lo.x.min(q.x), lo.y.min(q.y));
                *hi = Point2::new(hi.x.max(q.x), hi.y.max(q.y));
            }
            self.scratch.push(Particle { position: to, ..*p });
        }
    }

    /// With `use_walls`, zeroes the weight of every particle whose move (from `particles`
    /// to `scratch`, inside the box `lo`..`hi`) crosses a wall.
    fn constrain_by_walls(&mut self, use_walls: bool, lo: Point2, hi: Point2) {
        let Some(walls) = self.walls.as_ref().filter(|_| use_walls) else {
            return;
        };
        self.nearby_walls.clear();
        walls.walls_near(lo, hi, &mut self.nearby_walls);
        if self.nearby_walls.is_empty() {
            return;
        }
        let short_list = self.nearby_walls.len() <= 64;
        for ((from, to), w) in self
            .particles
            .iter()
            .zip(&self.scratch)
            .zip(self.weights.iter_mut())
        {
            let crosses = if short_list {
                self.nearby_walls
                    .iter()
                    .any(|s| s.intersects(from.position, to.position))
            } else {
                walls.crosses(from.position, to.position)
            };
            if crosses {
                *w = 0.0;
            }
        }
    }
}

impl Fuser for ParticleFilter {
    fn name(&self) -> &'static str {
        self.name
    }

    fn on_step(&mut self, step: &StepEvent) {
        if !self.guard.accept_step(step) {
            return;
        }
        if self.particles.is_empty() {
            match self.start {
                Some(s) => self.seed_cloud(step.t, s, self.cfg.start_spread_m),
                None => return,
            }
        }
        self.t = step.t;
        self.odometry += angle::step_displacement(step.length, step.heading);
        self.fix_error.walk(step.length);
        let use_walls = self.adaptive && self.cfg.use_walls && self.walls.is_some();
        let stuck = self.wall_stuck >= self.cfg.wall_stuck_steps;
        self.weights_backup.clear();
        self.weights_backup.extend_from_slice(&self.weights);
        self.propagate(step, use_walls && !stuck);
        if !self.normalise() {
            // Walls killed every particle: keep the previous set (004 §4.3.3 recovery).
            std::mem::swap(&mut self.weights, &mut self.weights_backup);
            self.wall_stuck += 1;
            self.diagnostics.wall_recoveries += 1;
            tracing::debug!(t = step.t, "walls killed every particle; previous set kept");
            return;
        }
        self.wall_stuck = 0;
        std::mem::swap(&mut self.particles, &mut self.scratch);
        self.maybe_resample();
    }

    fn on_wifi(&mut self, obs: &WifiObservation) {
        if !self.guard.accept_wifi(obs) {
            return;
        }
        if self.particles.is_empty() {
            match self.start {
                Some(s) => self.seed_cloud(obs.t, s, self.cfg.start_spread_m),
                None => {
                    self.seed_cloud(obs.t, obs.estimate, self.cfg.init_spread_m);
                    self.diagnostics.wifi_flagged = Some(false);
                    return;
                }
            }
        }
        self.t = obs.t;
        let z = obs.estimate;
        let (mean, cov) = self.mean_and_cov();
        let sd = (self.cfg.wifi_sd_m.powi(2) + cov.trace() / 2.0).sqrt();
        let offset = z - mean;
        self.fix_error.observe(offset, cov.trace() / 2.0);
        let out_of_gate = offset.norm() > self.cfg.reseed_gate_sd * sd;
        self.diagnostics.wifi_flagged = Some(out_of_gate);
        if out_of_gate {
            // the fix relative to the raw PDR track: constant while fixes agree with PDR
            self.out_of_gate.push(z.coords - self.odometry);
            let n = self.out_of_gate.len();
            let k = self.cfg.reseed_after;
            if k > 0 && n >= k {
                let recent = &self.out_of_gate[n - k..];
                let m = recent.iter().fold(Vector2::zeros(), |a, v| a + v) / k as f64;
                let rms =
                    (recent.iter().map(|v| (v - m).norm_squared()).sum::<f64>() / k as f64).sqrt();
                if rms <= self.cfg.reseed_consistency_m {
                    tracing::debug!(t = obs.t, "particle cloud re-seeded around the Wi-Fi fix");
                    self.diagnostics.reinitialisations += 1;
                    self.seed_cloud(obs.t, z, self.cfg.init_spread_m);
                    return;
                }
            }
        } else {
            self.out_of_gate.clear();
        }
        // eq. 17 (and eq. 18-20 for apf) in the log domain.
        let inv_2r = 1.0 / (2.0 * self.cfg.wifi_sd_m.powi(2));
        let adaptive = (self.adaptive && self.cfg.use_adaptive_factor).then(|| {
            let t_prev = self.previous_fix_estimate.map_or(obs.t, |(t, _)| t);
            let dt = ((obs.t - t_prev) as f64 / 1000.0).max(0.0);
            (
                self.cfg.walking_speed_mps * dt,
                self.cfg.adaptive_softness_m,
            )
        });
        let likelihood = obs
            .likelihood
            .clone()
            .filter(|_| self.cfg.wifi_likelihood && self.cfg.likelihood_share > 0.0);
        let (share, keep) = (self.cfg.likelihood_share, 1.0 - self.cfg.likelihood_share);
        let mut log_w: Vec<f64> = self
            .particles
            .iter()
            .zip(&self.weights)
            .map(|(p, w)| {
                if w.is_nan() || *w <= 0.0 {
                    return f64::NEG_INFINITY;
                }
                let r2 = (p.position - z).norm_squared() * inv_2r;
                let mut l = match &likelihood {
                    // ln((1 - s) g + s l): 0 when both vanish, which the max below skips.
                    Some(lik) => w.ln() + (keep * (-r2).exp() + share * lik.at(p.position)).ln(),
                    None => w.ln() - r2,
                };
                if let Some((r, s)) = adaptive {
                    let dist = (p.position - p.anchor).norm(); // eq. 18
                    l += log_logistic_decreasing((dist - r) / s); // eq. 19 (decreasing form)
                }
                l
            })
            .collect();
        let max = log_w.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if max.is_finite() {
            for (lw, w) in log_w.iter_mut().zip(self.weights.iter_mut()) {
                // the best particle gets 1, so the sum is >= 1; negligible weights are
                // flushed to zero (subnormal numbers slow every later operation)
                let e = (*lw - max).exp();
                *w = if e < 1e-200 { 0.0 } else { e };
            }
            self.normalise();
        }
        self.maybe_resample();
        for p in &mut self.particles {
            p.anchor = p.position;
        }
        let (new_mean, _) = self.mean_and_cov();
        self.previous_fix_estimate = Some((obs.t, new_mean));
    }

    fn estimate(&self) -> Option<Estimate> {
        if self.particles.is_empty() {
            return None;
        }
        let (position, cloud) = self.mean_and_cov();
        let cov =
            cloud + Matrix2::identity() * (self.cfg.radius.bias_share * self.fix_error.variance());
        let mut diagnostics = self.diagnostics.clone();
        diagnostics.skipped_inputs = self.guard.skipped;
        Some(Estimate {
            t: self.t,
            position,
            covariance: Some(cov),
            diagnostics,
        })
    }

    fn particle_cloud(&self) -> Option<Vec<WeightedPoint>> {
        Some(
            self.particles
                .iter()
                .zip(&self.weights)
                .map(|(p, w)| WeightedPoint {
                    position: p.position,
                    weight: *w,
                })
                .collect(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{SyntheticConfig, SyntheticWalk, obs_at, step};
    use proptest::prelude::*;

    fn small() -> PfConfig {
        PfConfig {
            n_particles: 200,
            ..PfConfig::default()
        }
    }

    /// A motion event with a covariance moves the cloud by its displacement with that
    /// spread: the cloud's mean by the displacement, its covariance grown by about it.
    #[test]
    fn a_displacement_with_covariance_moves_the_cloud_with_that_spread() {
        let cfg = PfConfig {
            n_particles: 4000,
            start_spread_m: 0.0,
            ..PfConfig::default()
        };
        let mut f =
            ParticleFilter::new("pf", cfg, false, None, 5, Some(Point2::new(0.0, 0.0))).unwrap();
        let learned = StepEvent {
            covariance: Some([0.8, 0.3, 0.4]),
            ..step(1000, 5.0, 0.0)
        };
        f.on_step(&learned);
        let cloud = f.particle_cloud().unwrap();
        let n = cloud.len() as f64;
        let mean = cloud
            .iter()
            .fold(Vector2::zeros(), |m, p| m + p.position.coords)
            / n;
        let mut cov = Matrix2::zeros();
        for p in &cloud {
            let r = p.position.coords - mean;
            cov += r * r.transpose() / n;
        }
        assert!(mean.x.abs() < 0.1 && (mean.y - 5.0).abs() < 0.1, "{mean}");
        assert!((cov[(0, 0)] - 0.8).abs() < 0.1, "{cov}");
        assert!((cov[(0, 1)] - 0.3).abs() < 0.1, "{cov}");
        assert!((cov[(1, 1)] - 0.4).abs() < 0.1, "{cov}");
    }

    #[test]
    fn deterministic_for_a_seed() {
        let walk = SyntheticWalk::generate(&SyntheticConfig::default());
        let run = |seed| {
            let mut f = ParticleFilter::new("pf", small(), false, None, seed, None).unwrap();
            for w in &walk.wifi[..5] {
                f.on_wifi(w);
            }
            f.estimate().unwrap().position
        };
        assert_eq!(run(3), run(3));
        assert_ne!(run(3), run(4));
    }

    #[test]
    fn a_wall_across_the_path_keeps_the_cloud_behind_it() {
        // a wall at y = 1 across everything; two steps east stay south of it, then a 5 m
        // step north (even at the smallest step scale, 0.5) takes every particle across
        let walls = Arc::new(WallIndex::new(&[Segment {
            a: Point2::new(-100.0, 1.0),
            b: Point2::new(100.0, 1.0),
        }]));
        // little position noise, so that the cloud stays a tight line south of the wall
        let cfg = PfConfig {
            init_spread_m: 0.1,
            position_sd_m: 0.05,
            ..small()
        };
        let mut f = ParticleFilter::new("apf", cfg, true, Some(walls), 1, None).unwrap();
        f.on_wifi(&obs_at(0, 0.0, 0.0));
        let east = std::f64::consts::FRAC_PI_2;
        for k in 1..=2 {
            f.on_step(&step(500 * k, 0.7, east));
        }
        let before = f.estimate().unwrap();
        assert_eq!(before.diagnostics.wall_recoveries, 0);
        f.on_step(&step(1500, 5.0, 0.0));
        let after = f.estimate().unwrap();
        assert_eq!(after.diagnostics.wall_recoveries, 1);
        assert_eq!(after.position, before.position);
        let sum: f64 = f.particle_cloud().unwrap().iter().map(|p| p.weight).sum();
        assert!((sum - 1.0).abs() < 1e-9);
        // after wall_stuck_steps wipe-outs the move is applied without walls
        for k in 4..=6 {
            f.on_step(&step(500 * k, 5.0, 0.0));
        }
        let e = f.estimate().unwrap();
        assert_eq!(e.diagnostics.wall_recoveries, 3);
        assert!(
            e.position.y > 2.0,
            "{:?} {}",
            e.position,
            e.diagnostics.wall_recoveries
        );
    }

    #[test]
    fn the_radius_is_the_cloud_plus_the_bias_share_of_the_fixes_error() {
        let mut f = ParticleFilter::new("pf", small(), false, None, 2, None).unwrap();
        for k in 0..10 {
            f.on_wifi(&obs_at(k * 2000, (k % 2) as f64 * 6.0, 0.0));
        }
        let p = f.estimate().unwrap().covariance.unwrap();
        let (_, cloud) = f.mean_and_cov();
        let share = f.cfg.radius.bias_share * f.fix_error.variance();
        assert!(share > 0.0);
        assert!((p[(0, 0)] - cloud[(0, 0)] - share).abs() < 1e-9);
        assert!((p[(1, 1)] - cloud[(1, 1)] - share).abs() < 1e-9);
        assert_eq!(p[(0, 1)], p[(1, 0)]);
    }

    #[test]
    fn reseeds_after_a_wrong_start() {
        let mut f = ParticleFilter::new("pf", small(), false, None, 5, None).unwrap();
        f.on_wifi(&obs_at(0, 120.0, 0.0));
        let mut t = 0;
        for k in 0..20 {
            for _ in 0..3 {
                t += 500;
                f.on_step(&step(t, 0.7, 0.0));
            }
            f.on_wifi(&obs_at(t, 0.0, 2.1 * (k + 1) as f64));
        }
        let e = f.estimate().unwrap();
        assert!(e.diagnostics.reinitialisations >= 1);
        assert!(
            (e.position - Point2::new(0.0, 42.0)).norm() < 8.0,
            "{:?}",
            e.position
        );
    }

    #[test]
    fn adaptive_factor_decreases_with_distance() {
        assert!(log_logistic_decreasing(-5.0) > log_logistic_decreasing(0.0));
        assert!(log_logistic_decreasing(0.0) > log_logistic_decreasing(5.0));
        assert!(log_logistic_decreasing(1e6).is_finite());
        assert!((log_logistic_decreasing(-1e6)).abs() < 1e-12);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        #[test]
        fn weights_sum_to_one_and_count_is_kept(
            inputs in prop::collection::vec(
                (any::<bool>(), 0.0f64..3.0, -7.0f64..7.0, -500.0f64..500.0, -500.0f64..500.0), 1..60),
            seed in any::<u64>(),
        ) {
            let plan = SyntheticWalk::generate(&SyntheticConfig::default()).plan;
            let walls = Arc::new(WallIndex::new(&plan.walls));
            let cfg = PfConfig { n_particles: 100, ..PfConfig::default() };
            let mut f = ParticleFilter::new("apf", cfg, true, Some(walls), seed, None).unwrap();
            let mut t = 0;
            for (is_step, len, heading, x, y) in inputs {
                t += 250;
                if is_step { f.on_step(&step(t, len, heading)); } else { f.on_wifi(&obs_at(t, x, y)); }
                if let Some(cloud) = f.particle_cloud().filter(|c| !c.is_empty()) {
                    prop_assert_eq!(cloud.len(), 100);
                    let sum: f64 = cloud.iter().map(|p| p.weight).sum();
                    prop_assert!((sum - 1.0).abs() < 1e-9, "sum {}", sum);
                    prop_assert!(cloud.iter().all(|p| p.weight.is_finite() && p.weight >= 0.0));
                    let e = f.estimate().unwrap();
                    prop_assert!(e.position.x.is_finite() && e.position.y.is_finite());
                }
            }
        }
    }
}

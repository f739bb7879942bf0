//! A small deterministic synthetic walk for tests, the `synthetic_compare` example and benches:
//! a ring corridor around a central block, laps walked along its centre line with turns at
//! the corners; noisy PDR steps (step-length scale error, heading bias, drift and gyro scale
//! error at turns) and Wi-Fi fixes = truth + Gaussian noise, with gross errors injected at
//! known fixes. Seeded, so every figure is reproducible.
//!
//! ```
//! use wipdr_fusion::synthetic::{SyntheticConfig, SyntheticWalk};
//! let walk = SyntheticWalk::generate(&SyntheticConfig::default());
//! assert!(walk.steps.len() > 400 && walk.wifi.len() > 100);
//! assert!(walk.gross.iter().filter(|g| **g).count() > 5);
//! ```

use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::Normal;
use serde::{Deserialize, Serialize};
use wipdr_core::{
    Candidate, FloorPlan, MotionState, Point2, Polygon, SpeedClass, StepEvent, TimestampMs,
    TurnState, Unit, Vector2, WifiObservation, angle,
};

/// Parameters of the synthetic walk.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SyntheticConfig {
    /// Seed of everything random.
    pub seed: u64,
    /// Building size (outer rectangle), metres.
    pub width_m: f64,
    /// Building height, metres.
    pub height_m: f64,
    /// Corridor width around the central block, metres.
    pub corridor_m: f64,
    /// Laps around the ring.
    pub laps: usize,
    /// Wi-Fi period, seconds.
    pub wifi_period_s: f64,
    /// Wi-Fi noise standard deviation per axis, metres.
    pub wifi_noise_sd_m: f64,
    /// Fraction of fixes with a gross error.
    pub gross_rate: f64,
    /// Gross error size range, metres.
    pub gross_min_m: f64,
    /// Gross error size range, metres.
    pub gross_max_m: f64,
    /// Make the first fix a gross error (a start in a coverage gap).
    pub first_fix_gross: bool,
    /// PDR step-length scale error (1.1 = 10 % too long).
    pub step_scale: f64,
    /// PDR step-length white noise, metres.
    pub step_noise_sd_m: f64,
    /// Constant heading bias standard deviation (drawn once per walk), degrees.
    pub heading_bias_sd_deg: f64,
    /// Heading random-walk per step, degrees.
    pub heading_drift_sd_deg: f64,
    /// Heading white noise per step, degrees.
    pub heading_noise_sd_deg: f64,
    /// Gyro scale error: heading error gained per radian turned.
    pub gyro_scale_error: f64,
    /// Number of Wi-Fi candidates per fix.
    pub candidates: usize,
    /// Spatial spread of the candidates around the fix, metres.
    pub candidate_spread_m: f64,
}

impl Default for SyntheticConfig {
    fn default() -> Self {
        Self {
            seed: 1,
            width_m: 60.0,
            height_m: 40.0,
            corridor_m: 5.0,
            laps: 2,
            wifi_period_s: 2.0,
            wifi_noise_sd_m: 3.0,
            gross_rate: 0.1,
            gross_min_m: 20.0,
            gross_max_m: 60.0,
            first_fix_gross: false,
            step_scale: 1.1,
            step_noise_sd_m: 0.05,
            heading_bias_sd_deg: 3.0,
            heading_drift_sd_deg: 0.3,
            heading_noise_sd_deg: 2.0,
            gyro_scale_error: 0.05,
            candidates: 5,
            candidate_spread_m: 2.0,
        }
    }
}

/// A generated walk with its truth.
#[derive(Debug, Clone)]
pub struct SyntheticWalk {
    /// The floor plan (outer walls and the central block).
    pub plan: FloorPlan,
    /// PDR steps, time-ordered.
    pub steps: Vec<StepEvent>,
    /// True position after each step.
    pub truth_steps: Vec<Point2>,
    /// Wi-Fi observations, time-ordered.
    pub wifi: Vec<WifiObservation>,
    /// True position at each fix.
    pub truth_wifi: Vec<Point2>,
    /// Whether each fix carries an injected gross error.
    pub gross: Vec<bool>,
    /// True start position.
    pub start: Point2,
}

/// One input of a merged replay (indices into [`SyntheticWalk::steps`] / [`SyntheticWalk::wifi`]).
pub use crate::replay::FusionInput as Input;

fn rect(x0: f64, y0: f64, x1: f64, y1: f64) -> Polygon {
    Polygon::rectangle(x0, y0, x1, y1).expect("finite corners")
}

fn normal(sd: f64) -> Normal<f64> {
    Normal::new(0.0, sd.max(0.0)).expect("finite non-negative sd")
}

impl SyntheticWalk {
    /// Generates the walk for `cfg` (deterministic for `cfg.seed`).
    pub fn generate(cfg: &SyntheticConfig) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
        let (w, h, c) = (cfg.width_m, cfg.height_m, cfg.corridor_m);
        let plan = FloorPlan::new(
            w,
            h,
            vec![rect(0.0, 0.0, w, h)],
            vec![Unit {
                name: "block".into(),
                polygon: rect(c, c, w - c, h - c),
            }],
        )
        .expect("valid synthetic plan");
        // Corridor centre line, counter-clockwise from the bottom-left corner.
        let m = c / 2.0;
        let corners = [
            Point2::new(m, m),
            Point2::new(w - m, m),
            Point2::new(w - m, h - m),
            Point2::new(m, h - m),
        ];
        let start = Point2::new(m, h / 2.0);
        let mut polyline = vec![start];
        for _ in 0..cfg.laps {
            polyline.extend([corners[0], corners[1], corners[2], corners[3]]);
        }
        polyline.push(start);

        // Walk the polyline leg by leg; each leg gets a speed class.
        let mut truth = vec![start];
        let mut classes = vec![];
        for leg in polyline.windows(2) {
            let class = match rng.random_range(0..4) {
                0 => SpeedClass::Slow,
                1 => SpeedClass::Fast,
                _ => SpeedClass::Normal,
            };
            let step_len = match class {
                SpeedClass::Slow => 0.55,
                SpeedClass::Normal => 0.7,
                SpeedClass::Fast => 0.8,
            };
            let d = leg[1] - leg[0];
            let n = (d.norm() / step_len).round().max(1.0) as usize;
            for k in 1..=n {
                // corners are cut by half a step so that a turn spans two steps
                truth.push(leg[0] + d * (k as f64 / n as f64));
                classes.push(class);
            }
        }
        let mut smoothed = truth.clone();
        for i in 1..truth.len() - 1 {
            smoothed[i] = truth[i] + ((truth[i - 1] - truth[i]) + (truth[i + 1] - truth[i])) * 0.25;
        }
        let truth = smoothed;

        let heading_bias = rng.sample(normal(cfg.heading_bias_sd_deg)).to_radians();
        let mut drift = 0.0;
        let mut gyro_error = 0.0;
        let mut steps = Vec::with_capacity(truth.len());
        let mut times = vec![0i64];
        let mut t_s: f64 = 0.0;
        let mut prev_true_heading = None;
        let mut prev_reported: Option<f64> = None;
        for i in 1..truth.len() {
            let d = truth[i] - truth[i - 1];
            let true_heading = angle::heading_of(d);
            let turn = prev_true_heading.map_or(0.0, |p| angle::diff(true_heading, p));
            prev_true_heading = Some(true_heading);
            gyro_error += cfg.gyro_scale_error * turn;
            drift += rng.sample(normal(cfg.heading_drift_sd_deg)).to_radians();
            let heading = angle::wrap_pi(
                true_heading
                    + heading_bias
                    + drift
                    + gyro_error
                    + rng.sample(normal(cfg.heading_noise_sd_deg)).to_radians(),
            );
            let length =
                (d.norm() * cfg.step_scale + rng.sample(normal(cfg.step_noise_sd_m))).max(0.0);
            let class = classes[i - 1];
            let period = match class {
                SpeedClass::Slow => 0.7,
                SpeedClass::Normal => 0.55,
                SpeedClass::Fast => 0.5,
            };
            t_s += period;
            let t = (t_s * 1000.0).round() as TimestampMs;
            times.push(t);
            let heading_change = prev_reported.map_or(0.0, |p| angle::diff(heading, p));
            prev_reported = Some(heading);
            let turn_state = if turn.abs() > 20f64.to_radians() {
                TurnState::Turning
            } else if heading_change.abs() > 4f64.to_radians() {
                TurnState::PseudoTurning
            } else {
                TurnState::Straight
            };
            steps.push(StepEvent {
                t,
                length,
                heading,
                heading_change,
                period_s: period,
                motion: MotionState {
                    turn: turn_state,
                    speed: class,
                    stationary: false,
                },
                covariance: None,
            });
        }
        let truth_at = |t: TimestampMs| -> Point2 {
            let i = times.partition_point(|&x| x <= t);
            if i == 0 {
                return truth[0];
            }
            if i >= times.len() {
                return truth[truth.len() - 1];
            }
            let (t0, t1) = (times[i - 1] as f64, times[i] as f64);
            let f = if t1 > t0 {
                (t as f64 - t0) / (t1 - t0)
            } else {
                0.0
            };
            truth[i - 1] + (truth[i] - truth[i - 1]) * f
        };

        let end = *times.last().unwrap_or(&0);
        let period_ms = (cfg.wifi_period_s * 1000.0).round().max(1.0) as TimestampMs;
        let mut wifi = vec![];
        let mut truth_wifi = vec![];
        let mut gross = vec![];
        // the first fix comes with the first step so that filters start at the walk's start
        let mut t = 0;
        while t <= end {
            let p = truth_at(t);
            let is_gross = if wifi.is_empty() {
                cfg.first_fix_gross
            } else {
                rng.random_range(0.0..1.0) < cfg.gross_rate
            };
            let noise = Vector2::new(
                rng.sample(normal(cfg.wifi_noise_sd_m)),
                rng.sample(normal(cfg.wifi_noise_sd_m)),
            );
            let mut estimate = p + noise;
            if is_gross {
                let size = rng.random_range(cfg.gross_min_m..=cfg.gross_max_m.max(cfg.gross_min_m));
                let dir = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
                estimate += angle::step_displacement(size, dir);
            }
            let base = if is_gross { 5.0 } else { 3.0 };
            let mut candidates: Vec<Candidate> = (0..cfg.candidates.max(1))
                .map(|k| Candidate {
                    position: estimate
                        + Vector2::new(
                            rng.sample(normal(cfg.candidate_spread_m)),
                            rng.sample(normal(cfg.candidate_spread_m)),
                        ),
                    distance: base + k as f64 * 0.3 + rng.sample(normal(0.8)).abs(),
                    weight: 1.0,
                    index: k,
                    floor: None,
                })
                .collect();
            candidates.sort_by(|a, b| a.distance.total_cmp(&b.distance));
            let n = candidates.len() as f64;
            for c in &mut candidates {
                c.weight = 1.0 / n;
            }
            wifi.push(WifiObservation {
                t,
                estimate,
                candidates,
                visited: 100,
                floor: None,
                building: None,
                likelihood: None,
            });
            truth_wifi.push(p);
            gross.push(is_gross);
            t += period_ms;
        }
        Self {
            plan,
            steps,
            truth_steps: truth[1..].to_vec(),
            wifi,
            truth_wifi,
            gross,
            start,
        }
    }

    /// Steps and fixes merged in time order by the one replay driver
    /// ([`crate::replay::merged`]: a step before a fix at the same time).
    pub fn inputs(&self) -> Vec<Input> {
        crate::replay::merged(&self.steps, &self.wifi).collect()
    }
}

/// What one scheme did on one synthetic walk.
#[derive(Debug, Clone, Default)]
pub struct RunResult {
    /// Position error after each step (once the scheme has an estimate), metres.
    pub step_errors: Vec<f64>,
    /// For each fix, whether the scheme flagged it (`None` when it does not say).
    pub flagged: Vec<Option<bool>>,
    /// Re-initialisations / re-seeds at the end of the walk.
    pub reinitialisations: u32,
}

impl SyntheticWalk {
    /// Runs `config` over the walk (seeded with `seed`, walls of the plan in the context) and
    /// scores it after every step against the truth.
    pub fn run(
        &self,
        config: &crate::SchemeConfig,
        seed: u64,
        start: Option<Point2>,
    ) -> Result<RunResult, crate::FusionError> {
        let mut ctx = crate::BuildContext::with_floor_plan(&self.plan);
        ctx.seed = seed;
        ctx.start = start;
        let mut fuser = config.build(&ctx)?;
        let mut out = RunResult {
            flagged: vec![None; self.wifi.len()],
            ..RunResult::default()
        };
        for input in self.inputs() {
            match input {
                Input::Step(i) => {
                    fuser.on_step(&self.steps[i]);
                    if let Some(e) = fuser.estimate() {
                        out.step_errors
                            .push((e.position - self.truth_steps[i]).norm());
                    }
                }
                Input::Wifi(j) => {
                    fuser.on_wifi(&self.wifi[j]);
                    out.flagged[j] = fuser.estimate().and_then(|e| e.diagnostics.wifi_flagged);
                }
            }
        }
        out.reinitialisations = fuser
            .estimate()
            .map_or(0, |e| e.diagnostics.reinitialisations);
        Ok(out)
    }
}

/// A straight-walking normal-speed step (tests and examples).
pub fn step(t: TimestampMs, length: f64, heading: f64) -> StepEvent {
    StepEvent {
        t,
        length,
        heading,
        heading_change: 0.0,
        period_s: 0.5,
        motion: MotionState::default(),
        covariance: None,
    }
}

/// A Wi-Fi observation at `(x, y)` with one candidate there (tests and examples).
pub fn obs_at(t: TimestampMs, x: f64, y: f64) -> WifiObservation {
    WifiObservation {
        t,
        estimate: Point2::new(x, y),
        candidates: vec![Candidate {
            position: Point2::new(x, y),
            distance: 1.0,
            weight: 1.0,
            index: 0,
            floor: None,
        }],
        visited: 1,
        floor: None,
        building: None,
        likelihood: None,
    }
}

/// The x variance of `fuser`'s estimate (tests of the error radius) at three moments: after a
/// first fix at the origin, after 20 steps of 0.7 m due north, and after a second fix where
/// those steps ended (14 m north). `None` when an estimate carries no covariance.
pub fn variance_at_fix_walk_fix(fuser: &mut dyn crate::Fuser) -> Option<[f64; 3]> {
    let var = |f: &dyn crate::Fuser| f.estimate()?.covariance.map(|p| p[(0, 0)]);
    fuser.on_wifi(&obs_at(0, 0.0, 0.0));
    let at_fix = var(fuser)?;
    for k in 1..=20 {
        fuser.on_step(&step(500 * k, 0.7, 0.0));
    }
    let walked = var(fuser)?;
    fuser.on_wifi(&obs_at(10_500, 0.0, 14.0));
    Some([at_fix, walked, var(fuser)?])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deterministic_and_inside_the_corridor() {
        let cfg = SyntheticConfig::default();
        let a = SyntheticWalk::generate(&cfg);
        let b = SyntheticWalk::generate(&cfg);
        assert_eq!(a.steps, b.steps);
        assert_eq!(a.wifi, b.wifi);
        for p in &a.truth_steps {
            assert!(a.plan.is_walkable(*p), "{p:?}");
        }
        for w in a.truth_steps.windows(2) {
            assert!(!a.plan.crosses_wall(w[0], w[1]));
        }
        let inputs = a.inputs();
        assert_eq!(inputs.len(), a.steps.len() + a.wifi.len());
        assert_eq!(inputs[0], Input::Wifi(0));
        assert!(a.steps.iter().any(|s| s.motion.turn == TurnState::Turning));
    }
}

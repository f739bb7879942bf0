//! Vertical displacement per step for the inverted-pendulum step length (paper 004
//! eq. 6-9, Alg. 1): vertical acceleration in the navigation frame, a Kalman filter on
//! `[Z, V_z]` driven by it (eq. 9) with a zero-velocity update at each step (ZUPT), and the
//! step's vertical excursion `h` (eq. 6).
//!
//! At a ZUPT the filter's velocity error is known; the drift it accumulated during the step
//! is removed by subtracting the straight line through the step's first and last velocities
//! (the fixed-interval smoothing of a velocity random walk between two zero-velocity
//! instants; it also absorbs a constant accelerometer bias) and then the mean velocity (the
//! height is periodic whatever gait phase the step boundary falls on), and `h` is the
//! peak-to-peak of
//! the re-integrated height over the step. The paper writes `h = -∫ V_z dt` over the step:
//! over a whole gait cycle that integral is zero by construction, so the excursion (the
//! pendulum's rise, `L (1 - cos)`) is what is used.

use serde::{Deserialize, Serialize};

/// Settings of the vertical ZUPT filter.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VerticalConfig {
    /// Standard deviation of the vertical acceleration noise, m/s² (process noise of eq. 9).
    pub accel_std: f64,
    /// Standard deviation of the zero-velocity observation, m/s.
    pub zupt_std: f64,
    /// Gravity subtracted from the navigation-frame vertical acceleration, m/s².
    pub gravity: f64,
    /// Steps longer than this are not measured (the buffer is dropped), seconds.
    pub max_step_s: f64,
}

impl Default for VerticalConfig {
    fn default() -> Self {
        Self {
            accel_std: 0.5,
            zupt_std: 0.05,
            gravity: 9.81,
            max_step_s: 2.0,
        }
    }
}

/// Kalman filter on `[Z, V_z]` with ZUPT, and the per-step vertical excursion.
///
/// ```
/// use wipdr_pdr::vertical::{VerticalConfig, VerticalZupt};
/// let mut v = VerticalZupt::new(VerticalConfig::default());
/// // A 0.5 s step with a vertical bounce of amplitude 2 cm: a = -A w² cos(w t).
/// let w = 2.0 * std::f64::consts::PI / 0.5;
/// for i in 0..=25 {
///     let t = i as f64 * 0.02;
///     v.push((t * 1000.0) as i64, 9.81 - 0.02 * w * w * (w * t).cos());
/// }
/// let h = v.zupt().unwrap();
/// assert!((h - 0.04).abs() < 0.005, "{h}");
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct VerticalZupt {
    cfg: VerticalConfig,
    z: f64,
    vz: f64,
    p: [[f64; 2]; 2],
    last: Option<(i64, f64)>,
    /// (time s since step start, velocity) samples of the current step.
    samples: Vec<(f64, f64)>,
    step_start: Option<i64>,
}

impl VerticalZupt {
    /// A filter at rest.
    pub fn new(cfg: VerticalConfig) -> Self {
        Self {
            cfg,
            z: 0.0,
            vz: 0.0,
            p: [[0.0; 2]; 2],
            last: None,
            samples: Vec::with_capacity(64),
            step_start: None,
        }
    }

    /// Current vertical velocity estimate, m/s.
    pub fn velocity(&self) -> f64 {
        self.vz
    }

    /// Eq. 9: propagates with the navigation-frame vertical specific force `a_up` (m/s²,
    /// gravity included) at time `t` (ms). Non-finite values, repeated or backwards times
    /// are ignored; an interval over `max_step_s` drops the current step.
    pub fn push(&mut self, t: i64, a_up: f64) {
        if !a_up.is_finite() {
            return;
        }
        let a = a_up - self.cfg.gravity;
        let start = *self.step_start.get_or_insert(t);
        match self.last {
            Some((lt, _)) if t <= lt => return,
            Some((lt, la)) => {
                let dt = (t - lt) as f64 / 1000.0;
                if dt > self.cfg.max_step_s {
                    self.restart(t);
                } else {
                    // Trapezoidal integration of the acceleration.
                    let am = 0.5 * (a + la);
                    self.z += self.vz * dt + 0.5 * am * dt * dt;
                    self.vz += am * dt;
                    let q = self.cfg.accel_std * self.cfg.accel_std;
                    let p = self.p;
                    let p00 = p[0][0]
                        + dt * (p[1][0] + p[0][1])
                        + dt * dt * p[1][1]
                        + q * dt.powi(4) / 4.0;
                    let p01 = p[0][1] + dt * p[1][1] + q * dt.powi(3) / 2.0;
                    let p11 = p[1][1] + q * dt * dt;
                    self.p = [[p00, p01], [p01, p11]];
                }
            }
            None => {}
        }
        self.last = Some((t, a));
        let s = (t - self.step_start.unwrap_or(start)) as f64 / 1000.0;
        self.samples.push((s, self.vz));
    }

    fn restart(&mut self, t: i64) {
        self.samples.clear();
        self.step_start = Some(t);
        self.z = 0.0;
        self.vz = 0.0;
        self.p = [[0.0; 2]; 2];
    }

    /// Zero-velocity update at a step: applies the `V_z = 0` observation and returns the
    /// step's vertical excursion `h` (m), `None` when the step had fewer than 3 samples or
    /// exceeded `max_step_s`.
    pub fn zupt(&mut self) -> Option<f64> {
        let h = self.excursion();
        // Kalman update with H = [0, 1], z = 0.
        let r = self.cfg.zupt_std * self.cfg.zupt_std;
        let s = self.p[1][1] + r;
        if s > 0.0 {
            let k0 = self.p[0][1] / s;
            let k1 = self.p[1][1] / s;
            let innovation = -self.vz;
            self.z += k0 * innovation;
            self.vz += k1 * innovation;
            let p = self.p;
            let p00 = p[0][0] - k0 * p[1][0];
            let p01 = p[0][1] - k0 * p[1][1];
            let p11 = p[1][1] - k1 * p[1][1];
            self.p = [[p00, p01], [p01, p11.max(0.0)]];
        }
        let t = self.last.map(|(t, _)| t);
        self.samples.clear();
        self.step_start = t;
        self.z = 0.0;
        if let Some(t) = t {
            self.samples.push((0.0, self.vz));
            self.step_start = Some(t);
        }
        h
    }

    fn excursion(&self) -> Option<f64> {
        let n = self.samples.len();
        if n < 3 {
            return None;
        }
        let duration = self.samples[n - 1].0;
        if !(duration > 0.0 && duration <= self.cfg.max_step_s) {
            return None;
        }
        // ZUPT drift removal: the velocity error grows linearly between two zero-velocity
        // instants, so the line through the step's first and last velocities is removed;
        // then the mean, so that the height returns to its start over a periodic step
        // whatever the gait phase the step boundary falls on.
        let (t0, v0) = self.samples[0];
        let (t1, v1) = self.samples[n - 1];
        let span = t1 - t0;
        let line = |t: f64| v0 + (v1 - v0) * (t - t0) / span;
        let mean = self.samples.iter().map(|&(t, v)| v - line(t)).sum::<f64>() / n as f64;
        let detrended = |i: usize| {
            let (t, v) = self.samples[i];
            v - line(t) - mean
        };
        let (mut z, mut zmin, mut zmax) = (0.0f64, 0.0f64, 0.0f64);
        for i in 1..n {
            let dt = self.samples[i].0 - self.samples[i - 1].0;
            z += 0.5 * (detrended(i) + detrended(i - 1)) * dt;
            zmin = zmin.min(z);
            zmax = zmax.max(z);
        }
        let h = zmax - zmin;
        h.is_finite().then_some(h)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn bias_does_not_create_height() {
        let mut v = VerticalZupt::new(VerticalConfig::default());
        for i in 0..=30 {
            v.push(i * 20, 9.81 + 0.3); // a constant bias, no motion
        }
        let h = v.zupt().unwrap();
        assert!(h < 1e-9, "{h}");
        assert!(v.velocity().abs() < 0.5);
    }

    #[test]
    fn repeated_steps_measure_each() {
        let mut v = VerticalZupt::new(VerticalConfig::default());
        let w = 2.0 * PI / 0.6;
        let mut hs = Vec::new();
        for i in 0..=300 {
            let t = i as f64 * 0.02;
            v.push(i * 20, 9.81 - 0.03 * w * w * (w * t).cos());
            if i > 0 && i % 30 == 0 {
                hs.extend(v.zupt());
            }
        }
        assert_eq!(hs.len(), 10);
        for h in hs {
            assert!((h - 0.06).abs() < 0.006, "{h}");
        }
    }

    #[test]
    fn bad_input_ignored() {
        let mut v = VerticalZupt::new(VerticalConfig::default());
        v.push(0, f64::NAN);
        v.push(0, 9.81);
        v.push(0, 9.81);
        v.push(-5, 9.81);
        assert_eq!(v.zupt(), None);
        v.push(10_000, 9.81); // long gap then nothing
        assert_eq!(v.zupt(), None);
    }
}

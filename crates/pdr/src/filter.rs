//! Low-pass filtering of the acceleration magnitude: a Butterworth filter as cascaded
//! second-order sections (bilinear transform), the filter the competition's sample code
//! applies before step detection (4th order, 2 Hz at 50 Hz).

use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// Settings of the Butterworth low-pass.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LowPassConfig {
    /// Filter order (even; an odd order is rounded up to the next even one).
    pub order: usize,
    /// Cut-off frequency, Hz.
    pub cutoff_hz: f64,
    /// Sampling rate the filter is designed for, Hz (the ILC phones log at about 50 Hz).
    pub design_rate_hz: f64,
}

impl Default for LowPassConfig {
    fn default() -> Self {
        Self {
            order: 4,
            cutoff_hz: 2.0,
            design_rate_hz: 50.0,
        }
    }
}

/// One biquad section in transposed direct form II.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Biquad {
    b0: f64,
    b1: f64,
    b2: f64,
    a1: f64,
    a2: f64,
    s1: f64,
    s2: f64,
}

impl Biquad {
    #[inline]
    fn step(&mut self, x: f64) -> f64 {
        let y = self.b0 * x + self.s1;
        self.s1 = self.b1 * x - self.a1 * y + self.s2;
        self.s2 = self.b2 * x - self.a2 * y;
        y
    }

    /// Sets the state to the steady state of a constant input `x` (DC gain 1), as
    /// `scipy.signal.lfilter_zi` does.
    fn settle(&mut self, x: f64) {
        self.s2 = (self.b2 - self.a2) * x;
        self.s1 = (self.b1 - self.a1) * x + self.s2;
    }
}

/// A Butterworth low-pass filter (cascade of biquads).
///
/// ```
/// use wipdr_pdr::filter::{Butterworth, LowPassConfig};
/// let mut f = Butterworth::new(&LowPassConfig::default());
/// f.settle(9.81);
/// assert!((f.step(9.81) - 9.81).abs() < 1e-9);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Butterworth {
    sections: Vec<Biquad>,
}

impl Butterworth {
    /// Designs the filter. Invalid settings (cut-off not below Nyquist, non-positive values)
    /// fall back to a pass-through filter, logged.
    pub fn new(cfg: &LowPassConfig) -> Self {
        let fs = cfg.design_rate_hz;
        let fc = cfg.cutoff_hz;
        if !(fs > 0.0 && fc > 0.0 && fc < fs / 2.0 && cfg.order > 0) {
            tracing::warn!(?cfg, "invalid low-pass settings: filter disabled");
            return Self {
                sections: Vec::new(),
            };
        }
        let n = cfg.order.div_ceil(2) * 2;
        let k = (PI * fc / fs).tan();
        let sections = (1..=n / 2)
            .map(|i| {
                let q = 1.0 / (2.0 * (PI * (2 * i - 1) as f64 / (2 * n) as f64).sin());
                let norm = 1.0 / (1.0 + k / q + k * k);
                let b0 = k * k * norm;
                Biquad {
                    b0,
                    b1: 2.0 * b0,
                    b2: b0,
                    a1: 2.0 * (k * k - 1.0) * norm,
                    a2: (1.0 - k / q + k * k) * norm,
                    s1: 0.0,
                    s2: 0.0,
                }
            })
            .collect();
        Self { sections }
    }

    /// Filters one sample.
    #[inline]
    pub fn step(&mut self, x: f64) -> f64 {
        self.sections.iter_mut().fold(x, |v, s| s.step(v))
    }

    /// Puts the filter in the steady state of a constant input `x`.
    pub fn settle(&mut self, x: f64) {
        for s in &mut self.sections {
            s.settle(x);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passes_dc_and_attenuates_high_frequency() {
        let cfg = LowPassConfig::default();
        let mut f = Butterworth::new(&cfg);
        f.settle(0.0);
        // 10 Hz sine at 50 Hz sampling: far above the 2 Hz cut-off.
        let mut peak: f64 = 0.0;
        for i in 0..500 {
            let y = f.step((2.0 * PI * 10.0 * i as f64 / 50.0).sin());
            if i > 200 {
                peak = peak.max(y.abs());
            }
        }
        assert!(peak < 0.01, "10 Hz leaks through: {peak}");
        // 1 Hz passes with gain near 1.
        let mut f = Butterworth::new(&cfg);
        f.settle(0.0);
        let mut peak: f64 = 0.0;
        for i in 0..1000 {
            let y = f.step((2.0 * PI * 1.0 * i as f64 / 50.0).sin());
            if i > 500 {
                peak = peak.max(y.abs());
            }
        }
        assert!((peak - 1.0).abs() < 0.05, "1 Hz gain {peak}");
    }

    #[test]
    fn matches_scipy_coefficients() {
        // scipy.signal.butter(4, 2/25) has b[0] = 0.00018322; the cascade's overall gain
        // b0 product must match.
        let f = Butterworth::new(&LowPassConfig::default());
        let b0: f64 = f.sections.iter().map(|s| s.b0).product();
        assert!((b0 - 0.000_183_22).abs() < 1e-8, "b0 = {b0}");
    }

    #[test]
    fn invalid_config_is_pass_through() {
        let mut f = Butterworth::new(&LowPassConfig {
            cutoff_hz: 30.0,
            ..Default::default()
        });
        assert_eq!(f.step(3.5), 3.5);
    }
}

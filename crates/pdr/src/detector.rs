//! Step detection (papers 000 §2.2, 002 §4.2): low-pass filtered acceleration magnitude,
//! peak / valley classification against an adaptive threshold, and a minimum step interval.
//!
//! The state machine is the one of the ILC 2.0 sample code (`compute_steps`): a sample is a
//! *peak* when the detrended magnitude rises above `max(previous, threshold)`, a *valley* when
//! it falls below `min(previous, -threshold)`; the threshold is `max(min_threshold,
//! std_factor * std)` over a sliding window. A step is emitted when a valley ends after a
//! peak, at least `min_step_interval_s` after the previous step's valley.
//!
//! Robust to sampling jitter: the sliding window and every interval are measured in time
//! (milliseconds from the timestamps), never in sample counts. A gap longer than
//! `max_gap_s` resets the detector (no step is ever built across a gap). Standing still
//! produces no step because the threshold never drops below `min_threshold`.

use crate::filter::{Butterworth, LowPassConfig};
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;
use wipdr_core::TimestampMs;

/// Settings of the step detector. Defaults are the sample code's values.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StepDetectorConfig {
    /// Low-pass filter of the acceleration magnitude.
    pub low_pass: LowPassConfig,
    /// Length of the sliding window for the running mean (gravity) and std, seconds
    /// (the sample code's 22 samples at 50 Hz).
    pub window_s: f64,
    /// Lower bound of the peak / valley threshold, m/s².
    pub min_threshold: f64,
    /// Threshold as a fraction of the window's standard deviation.
    pub std_factor: f64,
    /// Minimum interval between two valleys (and two peaks) that make steps, seconds.
    pub min_step_interval_s: f64,
    /// A gap between two accelerometer samples longer than this resets the detector, seconds.
    pub max_gap_s: f64,
    /// Gravity the filter is settled on at start and after a reset, m/s².
    pub gravity: f64,
}

impl Default for StepDetectorConfig {
    fn default() -> Self {
        Self {
            low_pass: LowPassConfig::default(),
            window_s: 0.44,
            min_threshold: 0.6,
            std_factor: 0.4,
            min_step_interval_s: 0.25,
            max_gap_s: 1.0,
            gravity: 9.81,
        }
    }
}

/// What the detector knows about one detected step.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StepCandidate {
    /// Time of the step (the end of its valley), Unix ms.
    pub t: TimestampMs,
    /// Filtered acceleration magnitude at the step's peak, m/s².
    pub acc_max: f64,
    /// Filtered acceleration magnitude at the step's valley, m/s².
    pub acc_min: f64,
    /// Peak minus the running mean (gravity) at the peak: the smoothed peak `s_max` of
    /// paper 000 eq. 6, m/s².
    pub peak_detrended: f64,
    /// Variance of the filtered magnitude over the sliding window at the step, (m/s²)².
    pub acc_variance: f64,
    /// Seconds since the previous step, `None` for the first step after a start or reset.
    pub period_s: Option<f64>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Extremum {
    None,
    Peak,
    Valley,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    /// No peak yet.
    Idle,
    /// A peak was seen; waiting for its valley.
    Peaked,
    /// A step was emitted at a valley; waiting for the next peak.
    Stepped,
}

/// Streaming step detector; feed accelerometer samples in time order.
///
/// ```
/// use wipdr_pdr::detector::{StepDetector, StepDetectorConfig};
/// let mut d = StepDetector::new(StepDetectorConfig::default());
/// let mut steps = 0;
/// for i in 0..1000 {
///     // 2 Hz walking bounce around gravity, 50 Hz sampling, 20 s.
///     let t = i as f64 / 50.0;
///     let a = 9.81 + 2.0 * (2.0 * std::f64::consts::PI * 2.0 * t).sin();
///     if d.push((t * 1000.0) as i64, a).is_some() { steps += 1; }
/// }
/// assert!((38..=40).contains(&steps), "{steps}");
/// ```
#[derive(Debug, Clone)]
pub struct StepDetector {
    cfg: StepDetectorConfig,
    filter: Butterworth,
    window: VecDeque<(TimestampMs, f64)>,
    sum: f64,
    sum_sq: f64,
    prev_detrended: f64,
    prev_extremum: Extremum,
    phase: Phase,
    peak: (TimestampMs, f64, f64),
    valley: Option<(TimestampMs, f64)>,
    last_t: Option<TimestampMs>,
    last_step_t: Option<TimestampMs>,
    resets: usize,
}

impl StepDetector {
    /// A detector in its initial state.
    pub fn new(cfg: StepDetectorConfig) -> Self {
        let mut filter = Butterworth::new(&cfg.low_pass);
        filter.settle(cfg.gravity);
        Self {
            cfg,
            filter,
            window: VecDeque::with_capacity(64),
            sum: 0.0,
            sum_sq: 0.0,
            prev_detrended: 0.0,
            prev_extremum: Extremum::None,
            phase: Phase::Idle,
            peak: (0, 0.0, 0.0),
            valley: None,
            last_t: None,
            last_step_t: None,
            resets: 0,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &StepDetectorConfig {
        &self.cfg
    }

    /// Number of resets caused by gaps so far.
    pub fn resets(&self) -> usize {
        self.resets
    }

    /// Forgets everything (as at start), keeping the reset count.
    pub fn reset(&mut self) {
        let resets = self.resets;
        *self = Self::new(self.cfg);
        self.resets = resets;
    }

    /// Feeds one accelerometer magnitude (m/s²) at time `t`; returns a step when one ends
    /// here. Non-finite magnitudes and samples not later than the previous one are ignored
    /// (the caller counts them); a gap longer than `max_gap_s` resets the detector first.
    pub fn push(&mut self, t: TimestampMs, magnitude: f64) -> Option<StepCandidate> {
        if !magnitude.is_finite() {
            return None;
        }
        if let Some(last) = self.last_t {
            if t <= last {
                return None;
            }
            if (t - last) as f64 / 1000.0 > self.cfg.max_gap_s {
                self.reset();
                self.resets += 1;
                tracing::debug!(
                    t,
                    gap_ms = t - last,
                    "accelerometer gap: step detector reset"
                );
            }
        }
        self.last_t = Some(t);
        let filtered = self.filter.step(magnitude);

        // Sliding window over time.
        self.window.push_back((t, filtered));
        self.sum += filtered;
        self.sum_sq += filtered * filtered;
        let window_ms = (self.cfg.window_s * 1000.0) as i64;
        while let Some(&(t0, v0)) = self.window.front() {
            if t - t0 >= window_ms && self.window.len() > 1 {
                self.window.pop_front();
                self.sum -= v0;
                self.sum_sq -= v0 * v0;
            } else {
                break;
            }
        }
        let n = self.window.len() as f64;
        let mean = self.sum / n;
        let variance = (self.sum_sq / n - mean * mean).max(0.0);
        let threshold = self
            .cfg
            .min_threshold
            .max(self.cfg.std_factor * variance.sqrt());

        let detrended = filtered - mean;
        let extremum = if detrended > self.prev_detrended.max(threshold) {
            Extremum::Peak
        } else if detrended < self.prev_detrended.min(-threshold) {
            Extremum::Valley
        } else {
            Extremum::None
        };
        let interval_ms = (self.cfg.min_step_interval_s * 1000.0) as i64;

        // A peak ends.
        if extremum == Extremum::None && self.prev_extremum == Extremum::Peak {
            match self.phase {
                Phase::Idle => {
                    self.peak = (t, filtered, detrended);
                    self.phase = Phase::Peaked;
                }
                Phase::Peaked => {
                    if t - self.peak.0 <= interval_ms && filtered > self.peak.1 {
                        self.peak = (t, filtered, detrended);
                    }
                }
                Phase::Stepped => {
                    if t - self.peak.0 > interval_ms {
                        self.peak = (t, filtered, detrended);
                        self.phase = Phase::Peaked;
                    }
                }
            }
        }

        // A valley ends.
        let mut step = None;
        if extremum == Extremum::None && self.prev_extremum == Extremum::Valley {
            let since_valley = self.valley.map_or(i64::MAX, |(tv, _)| t - tv);
            if self.phase == Phase::Peaked && since_valley > interval_ms {
                self.valley = Some((t, filtered));
                self.phase = Phase::Stepped;
                let period_s = self.last_step_t.map(|p| (t - p) as f64 / 1000.0);
                self.last_step_t = Some(t);
                step = Some(StepCandidate {
                    t,
                    acc_max: self.peak.1,
                    acc_min: filtered,
                    peak_detrended: self.peak.2,
                    acc_variance: variance,
                    period_s,
                });
            } else if self.phase == Phase::Stepped
                && since_valley <= interval_ms
                && self.valley.is_some_and(|(_, v)| filtered < v)
            {
                self.valley = Some((t, filtered));
            }
        }
        self.prev_extremum = extremum;
        self.prev_detrended = detrended;
        step
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn walk_signal(t: f64, freq: f64, amp: f64) -> f64 {
        9.81 + amp * (2.0 * PI * freq * t).sin()
    }

    #[test]
    fn no_steps_while_standing() {
        let mut d = StepDetector::new(StepDetectorConfig::default());
        let mut n = 0;
        for i in 0..3000 {
            // Sensor noise of 0.05 m/s² around gravity.
            let a = 9.81 + 0.05 * ((i * 7919 % 101) as f64 / 50.0 - 1.0);
            if d.push(i * 20, a).is_some() {
                n += 1;
            }
        }
        assert_eq!(n, 0);
    }

    #[test]
    fn counts_steps_under_jitter() {
        // 1.8 steps/s for 60 s = 108 steps; timestamps jitter by up to +-8 ms and the rate
        // wanders between 40 and 60 Hz.
        let mut d = StepDetector::new(StepDetectorConfig::default());
        let mut t_ms = 0i64;
        let mut n = 0;
        let mut i = 0u64;
        while t_ms < 60_000 {
            let a = walk_signal(t_ms as f64 / 1000.0, 1.8, 2.5);
            if d.push(t_ms, a).is_some() {
                n += 1;
            }
            i += 1;
            let nominal = if (i / 500).is_multiple_of(2) { 17 } else { 25 };
            t_ms += nominal + ((i * 2654435761) % 17) as i64 - 8;
        }
        assert!((106..=109).contains(&n), "{n} steps");
    }

    #[test]
    fn gap_resets_and_bad_samples_ignored() {
        let mut d = StepDetector::new(StepDetectorConfig::default());
        for i in 0..100 {
            d.push(i * 20, walk_signal(i as f64 * 0.02, 2.0, 2.0));
        }
        assert_eq!(d.push(5000, f64::NAN), None);
        assert_eq!(d.push(10, 9.8), None); // backwards
        assert_eq!(d.push(1980, 9.8), None); // repeated
        d.push(10_000, 9.81);
        assert_eq!(d.resets(), 1);
    }

    #[test]
    fn period_is_measured_in_time() {
        let mut d = StepDetector::new(StepDetectorConfig::default());
        let mut periods = Vec::new();
        for i in 0..1500 {
            let t = i as f64 / 50.0;
            if let Some(s) = d.push(i * 20, walk_signal(t, 2.0, 2.0)) {
                periods.extend(s.period_s);
            }
        }
        let mean = periods.iter().sum::<f64>() / periods.len() as f64;
        assert!((mean - 0.5).abs() < 0.01, "{mean}");
    }
}

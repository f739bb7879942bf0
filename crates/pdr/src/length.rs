//! Step-length models behind one trait, and their least-squares calibration.
//!
//! - [`Linear`]: `SL = A + B p + C s_max` (paper 000 eq. 6).
//! - [`Weinberg`]: `SL = K (a_max - a_min)^(1/4)` (paper 002 eq. 8; the printed "1/4" is an
//!   exponent, see `docs/algorithms.md`).
//! - [`Pendulum`]: `SL = K · 2 sqrt(2 L h - h²)` (paper 004 eq. 7) with `h` from the vertical
//!   ZUPT filter ([`crate::vertical`]); `K` = 1 is the paper's model, a fitted `K` corrects
//!   the systematic under-estimate of a phone held in the hand rather than on the body.
//! - [`SampleCode`]: the ILC 2.0 sample code's Weinberg-type stride model (`K` varying with
//!   the step frequency and acceleration variance), the baseline, times a scale.
//!
//! Every model is linear in its coefficients (`SL = θ · φ(features)`), which is what makes
//! least-squares fitting from waypoint legs possible ([`StepLengthModel::regressors`]).

use serde::{Deserialize, Serialize};

/// What a step-length model may use about one step.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StepFeatures {
    /// Step period `p` (s): time since the previous step, or the default period for the first.
    pub period_s: f64,
    /// Mean of the last two periods (s), as the sample code uses.
    pub mean_period_s: f64,
    /// Filtered acceleration magnitude at the peak, m/s².
    pub acc_max: f64,
    /// Filtered acceleration magnitude at the valley, m/s².
    pub acc_min: f64,
    /// Smoothed peak above gravity `s_max`, m/s².
    pub peak_detrended: f64,
    /// Variance of the filtered magnitude over the detector window at this step.
    pub acc_variance: f64,
    /// Variance at the previous step (the sample code's `K` uses it), or this step's.
    pub prev_acc_variance: f64,
    /// Whether this is the first step after a start or reset.
    pub first: bool,
    /// Vertical excursion `h` over the step (m) from the ZUPT filter, if measured.
    pub vertical_excursion: Option<f64>,
}

/// A step-length model: a length from step features, linear in its coefficients.
pub trait StepLengthModel {
    /// Step length (m), before clamping to the configured range.
    fn length(&self, f: &StepFeatures) -> f64 {
        let phi = self.regressors(f);
        self.coefficients()
            .iter()
            .zip(&phi)
            .map(|(c, x)| c * x)
            .sum()
    }
    /// The regressors `φ(features)`, so that `length = coefficients · φ`.
    fn regressors(&self, f: &StepFeatures) -> Vec<f64>;
    /// The coefficients `θ`.
    fn coefficients(&self) -> Vec<f64>;
    /// Replaces the coefficients (same length as [`StepLengthModel::coefficients`]).
    fn set_coefficients(&mut self, c: &[f64]);
}

/// Paper 000 eq. 6: `SL = A + B p + C s_max`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Linear {
    /// `A`, m.
    pub a: f64,
    /// `B`, m/s.
    pub b: f64,
    /// `C`, m/(m/s²).
    pub c: f64,
}

impl Default for Linear {
    /// Not printed in the paper (trained per user); defaults give 0.7 m at 0.5 s and 2 m/s².
    /// On all 370 ILC 2.0 walks `wipdr pdr-fit` gives `A = 0.471, B = 0.019, C = 0.051`.
    fn default() -> Self {
        Self {
            a: 0.9,
            b: -0.6,
            c: 0.05,
        }
    }
}

impl StepLengthModel for Linear {
    fn regressors(&self, f: &StepFeatures) -> Vec<f64> {
        vec![1.0, f.period_s, f.peak_detrended]
    }
    fn coefficients(&self) -> Vec<f64> {
        vec![self.a, self.b, self.c]
    }
    fn set_coefficients(&mut self, c: &[f64]) {
        if let [a, b, cc] = *c {
            (self.a, self.b, self.c) = (a, b, cc);
        }
    }
}

/// Paper 002 eq. 8: `SL = K_w (a_max - a_min)^(exponent)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Weinberg {
    /// `K_w`, m/(m/s²)^exponent.
    pub k: f64,
    /// The exponent (paper: 1/4).
    pub exponent: f64,
}

impl Default for Weinberg {
    /// `K_w = 0.45`, exponent 1/4. `K_w` is per person and phone (paper 002 §4.2): fit it with
    /// `wipdr pdr-fit`. On all 370 ILC 2.0 walks of the five floors it fits to 0.427
    /// (`docs/results/pdr.md`); the default stays a round prior so that the protocol's
    /// per-fold fits (ridge towards the default) see nothing of their test walks.
    fn default() -> Self {
        Self {
            k: 0.45,
            exponent: 0.25,
        }
    }
}

impl StepLengthModel for Weinberg {
    fn regressors(&self, f: &StepFeatures) -> Vec<f64> {
        vec![(f.acc_max - f.acc_min).max(0.0).powf(self.exponent)]
    }
    fn coefficients(&self) -> Vec<f64> {
        vec![self.k]
    }
    fn set_coefficients(&mut self, c: &[f64]) {
        if let [k] = *c {
            self.k = k;
        }
    }
}

/// Paper 004 eq. 7: `SL = K · 2 sqrt(2 L h - h²)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Pendulum {
    /// Leg length `L`, m.
    pub leg_length: f64,
    /// Scale `K` (1 = the paper's model).
    pub k: f64,
    /// Length used when `h` is unknown (no attitude yet), before scaling, m.
    pub fallback_length: f64,
}

impl Default for Pendulum {
    /// `L = 0.9 m`, `K = 1` (the paper's model as printed). On all 370 ILC 2.0 walks
    /// `wipdr pdr-fit` gives `K = 1.007`: the uncalibrated pendulum is already right there.
    fn default() -> Self {
        Self {
            leg_length: 0.9,
            k: 1.0,
            fallback_length: 0.7,
        }
    }
}

impl StepLengthModel for Pendulum {
    fn regressors(&self, f: &StepFeatures) -> Vec<f64> {
        let l = self.leg_length;
        let x = match f.vertical_excursion {
            Some(h) if h.is_finite() => {
                let h = h.clamp(0.0, l);
                2.0 * (2.0 * l * h - h * h).max(0.0).sqrt()
            }
            _ => self.fallback_length,
        };
        vec![x]
    }
    fn coefficients(&self) -> Vec<f64> {
        vec![self.k]
    }
    fn set_coefficients(&mut self, c: &[f64]) {
        if let [k] = *c {
            self.k = k;
        }
    }
}

/// The ILC 2.0 sample code's stride model (`compute_stride_length`):
/// `K = clamp(a0 + a1 / p̄ + a2 σ²_prev, K_min, K_max) · K / K_min`, the first step uses
/// `K`, and `SL = scale · K · max(a_max - a_min, 1)^(1/4)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SampleCode {
    /// `K` of the first step.
    pub k: f64,
    /// Lower clamp of the varying `K`.
    pub k_min: f64,
    /// Upper clamp of the varying `K`.
    pub k_max: f64,
    /// `para_a0`.
    pub a0: f64,
    /// `para_a1` (per step frequency).
    pub a1: f64,
    /// `para_a2` (per acceleration variance).
    pub a2: f64,
    /// Overall scale (1 = the sample code).
    pub scale: f64,
}

impl Default for SampleCode {
    fn default() -> Self {
        Self {
            k: 0.4,
            k_min: 0.4,
            k_max: 0.8,
            a0: 0.214_680_84,
            a1: 0.091_545_17,
            a2: 0.023_019_98,
            scale: 1.0,
        }
    }
}

impl StepLengthModel for SampleCode {
    fn regressors(&self, f: &StepFeatures) -> Vec<f64> {
        let k = if f.first || f.mean_period_s <= 0.0 {
            self.k
        } else {
            let raw = self.a0 + self.a1 / f.mean_period_s + self.a2 * f.prev_acc_variance;
            raw.max(self.k_min).min(self.k_max) * (self.k / self.k_min)
        };
        vec![k * (f.acc_max - f.acc_min).max(1.0).powf(0.25)]
    }
    fn coefficients(&self) -> Vec<f64> {
        vec![self.scale]
    }
    fn set_coefficients(&mut self, c: &[f64]) {
        if let [s] = *c {
            self.scale = s;
        }
    }
}

/// Which step-length model, with its coefficients (serde: `{"model": "weinberg", ...}`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "model", rename_all = "snake_case")]
pub enum StepLengthConfig {
    /// Paper 000 eq. 6.
    Linear(Linear),
    /// Paper 002 eq. 8.
    Weinberg(Weinberg),
    /// Paper 004 eq. 6-7.
    Pendulum(Pendulum),
    /// The competition sample code (baseline).
    SampleCode(SampleCode),
}

impl Default for StepLengthConfig {
    /// The inverted pendulum (paper 004 eq. 6-7) with its printed scale `K = 1`: on the
    /// ILC 2.0 walks it is as good as the calibrated models without any calibration
    /// (`docs/results/pdr.md`), the best bet on a floor without training walks.
    fn default() -> Self {
        StepLengthConfig::Pendulum(Pendulum::default())
    }
}

impl StepLengthConfig {
    /// The model as a trait object.
    pub fn model(&self) -> &dyn StepLengthModel {
        match self {
            StepLengthConfig::Linear(m) => m,
            StepLengthConfig::Weinberg(m) => m,
            StepLengthConfig::Pendulum(m) => m,
            StepLengthConfig::SampleCode(m) => m,
        }
    }

    /// The model, mutable.
    pub fn model_mut(&mut self) -> &mut dyn StepLengthModel {
        match self {
            StepLengthConfig::Linear(m) => m,
            StepLengthConfig::Weinberg(m) => m,
            StepLengthConfig::Pendulum(m) => m,
            StepLengthConfig::SampleCode(m) => m,
        }
    }

    /// A short name (`linear`, `weinberg`, `pendulum`, `sample_code`).
    pub fn name(&self) -> &'static str {
        match self {
            StepLengthConfig::Linear(_) => "linear",
            StepLengthConfig::Weinberg(_) => "weinberg",
            StepLengthConfig::Pendulum(_) => "pendulum",
            StepLengthConfig::SampleCode(_) => "sample_code",
        }
    }

    /// The four models with default coefficients.
    pub fn all_defaults() -> [StepLengthConfig; 4] {
        [
            StepLengthConfig::Linear(Linear::default()),
            StepLengthConfig::Weinberg(Weinberg::default()),
            StepLengthConfig::Pendulum(Pendulum::default()),
            StepLengthConfig::SampleCode(SampleCode::default()),
        ]
    }
}

/// Solves the linear least-squares problem `min |X θ - y|² + ridge |θ - prior|²` by the
/// normal equations (Cholesky). Returns `None` when there are no rows, the sizes disagree or
/// the system is singular.
pub fn least_squares(rows: &[Vec<f64>], y: &[f64], prior: &[f64], ridge: f64) -> Option<Vec<f64>> {
    let n = prior.len();
    if rows.is_empty() || rows.len() != y.len() || n == 0 || rows.iter().any(|r| r.len() != n) {
        return None;
    }
    let mut ata = nalgebra::DMatrix::<f64>::zeros(n, n);
    let mut aty = nalgebra::DVector::<f64>::zeros(n);
    for (r, &yi) in rows.iter().zip(y) {
        if !(yi.is_finite() && r.iter().all(|x| x.is_finite())) {
            continue;
        }
        for i in 0..n {
            aty[i] += r[i] * yi;
            for j in 0..n {
                ata[(i, j)] += r[i] * r[j];
            }
        }
    }
    for i in 0..n {
        ata[(i, i)] += ridge;
        aty[i] += ridge * prior[i];
    }
    let chol = ata.cholesky()?;
    let theta = chol.solve(&aty);
    theta
        .iter()
        .all(|v| v.is_finite())
        .then(|| theta.iter().copied().collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn feat(p: f64, amax: f64, amin: f64) -> StepFeatures {
        StepFeatures {
            period_s: p,
            mean_period_s: p,
            acc_max: amax,
            acc_min: amin,
            peak_detrended: amax - 9.81,
            acc_variance: 1.0,
            prev_acc_variance: 1.0,
            first: false,
            vertical_excursion: Some(0.04),
        }
    }

    #[test]
    fn weinberg_exponent() {
        let m = Weinberg {
            k: 0.5,
            exponent: 0.25,
        };
        assert!((m.length(&feat(0.5, 12.0, 8.0)) - 0.5 * 4f64.powf(0.25)).abs() < 1e-12);
        // a_max < a_min cannot give NaN.
        assert_eq!(m.length(&feat(0.5, 8.0, 12.0)), 0.0);
    }

    #[test]
    fn pendulum_formula() {
        let m = Pendulum::default();
        let h: f64 = 0.04;
        let expect = 2.0 * (2.0 * 0.9 * h - h * h).sqrt();
        assert!((m.length(&feat(0.5, 12.0, 8.0)) - expect).abs() < 1e-12);
        let mut f = feat(0.5, 12.0, 8.0);
        f.vertical_excursion = Some(5.0); // absurd h is clamped to L
        assert!(m.length(&f).is_finite());
        f.vertical_excursion = None;
        assert_eq!(m.length(&f), 0.7);
    }

    #[test]
    fn sample_code_matches_python() {
        // compute_stride_length for a step with mean period 0.5 s, variance 2, a_max - a_min
        // = 3: K = clamp(0.2147 + 0.0915/0.5 + 0.0230*2, 0.4, 0.8) = 0.4438.
        let m = SampleCode::default();
        let mut f = feat(0.5, 12.81, 9.81);
        f.prev_acc_variance = 2.0;
        let k: f64 = 0.214_680_84 + 0.091_545_17 / 0.5 + 0.023_019_98 * 2.0;
        assert!((m.length(&f) - k * 3f64.powf(0.25)).abs() < 1e-12);
        f.first = true;
        assert!((m.length(&f) - 0.4 * 3f64.powf(0.25)).abs() < 1e-12);
    }

    #[test]
    fn least_squares_recovers_linear_model() {
        let truth = Linear {
            a: 0.3,
            b: 0.5,
            c: 0.08,
        };
        let mut rows = Vec::new();
        let mut y = Vec::new();
        for i in 0..50 {
            let f = feat(0.4 + 0.01 * i as f64, 11.0 + 0.05 * (i % 7) as f64, 8.0);
            rows.push(truth.regressors(&f));
            y.push(truth.length(&f));
        }
        let th = least_squares(&rows, &y, &[0.0; 3], 0.0).unwrap();
        assert!(
            (th[0] - 0.3).abs() < 1e-6 && (th[1] - 0.5).abs() < 1e-6 && (th[2] - 0.08).abs() < 1e-6
        );
        assert!(least_squares(&[], &[], &[0.0], 0.0).is_none());
        assert!(least_squares(&[vec![0.0]], &[1.0], &[0.0], 0.0).is_none());
    }

    #[test]
    fn config_roundtrip() {
        for c in StepLengthConfig::all_defaults() {
            let s = serde_json::to_string(&c).unwrap();
            let back: StepLengthConfig = serde_json::from_str(&s).unwrap();
            assert_eq!(back, c);
        }
    }
}

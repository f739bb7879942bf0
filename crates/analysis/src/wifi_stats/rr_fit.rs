//! The Refresh Rate model of paper 002 eq. 5 and its bounded least-squares fit.

use super::*;
use wipdr_core::fit::{LmConfig, levenberg_marquardt};

/// The RR model of 002 eq. 5: `eta = eta0 + a / (1 + exp(-(RSSI - RSSI_r) / c))`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RrModel {
    /// Floor of the curve (the rate of the weakest signals).
    pub eta0: f64,
    /// Height of the step (negative for a falling curve such as the loss rate).
    pub a: f64,
    /// Inflection RSSI, dBm.
    pub rssi_r: f64,
    /// Width of the step, dB (> 0).
    pub c: f64,
}

impl RrModel {
    /// The paper's fitted curve (002 §3.1), rates in percent.
    pub const PAPER_PERCENT: RrModel = RrModel {
        eta0: 2.1630,
        a: 82.4917,
        rssi_r: -75.0075,
        c: 1.8464,
    };

    /// The model's value at `rssi`.
    pub fn eval(&self, rssi: f64) -> f64 {
        self.eta0 + self.a * logistic((rssi - self.rssi_r) / self.c)
    }
}

/// `1 / (1 + exp(-z))`, without overflow.
pub(super) fn logistic(z: f64) -> f64 {
    if z >= 0.0 {
        1.0 / (1.0 + (-z).exp())
    } else {
        let e = z.exp();
        e / (1.0 + e)
    }
}

/// Settings of [`fit_rr_model`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FitConfig {
    /// Fewest points accepted (the model has 4 parameters).
    pub min_points: usize,
    /// Grid of start values of `RSSI_r`: this many values evenly over the data's RSSI range.
    pub grid_rssi_r: usize,
    /// Grid of start values of `c`, dB.
    pub grid_c: [f64; 6],
    /// Most Levenberg-Marquardt iterations.
    pub max_iterations: usize,
    /// Converged when a step lowers the SSE by at most this times `1 + SSE`, or the gradient is
    /// at most this times `1 + SSE` ([`wipdr_core::fit::LmConfig`]).
    pub tolerance: f64,
    /// Smallest `c` allowed (dB): a narrower step is a jump the data cannot resolve.
    pub min_c: f64,
    /// Range `[low, high]` that the curve's floor `eta0` and ceiling `eta0 + a` must lie in
    /// (`[0, 100]` for rates in percent); `None`: unbounded. Without it, data that rise
    /// without levelling off let the least squares run away (`a -> inf`, `RSSI_r -> -inf`).
    pub value_bounds: Option<[f64; 2]>,
}

impl Default for FitConfig {
    fn default() -> Self {
        Self {
            min_points: 8,
            grid_rssi_r: 61,
            grid_c: [0.5, 1.0, 2.0, 4.0, 8.0, 16.0],
            max_iterations: 500,
            tolerance: 1e-10,
            min_c: 0.05,
            value_bounds: None,
        }
    }
}

/// A fitted RR model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RrFit {
    /// The parameters.
    pub model: RrModel,
    /// Points fitted.
    pub points: usize,
    /// Sum of squared residuals.
    pub sse: f64,
    /// Root mean squared residual.
    pub rmse: f64,
    /// Correlation coefficient between the fitted and observed values (the paper reports
    /// 0.9285); 0 when either is constant.
    pub correlation: f64,
    /// Levenberg-Marquardt iterations run.
    pub iterations: usize,
    /// Which parameters ended on a bound (then the least squares has no interior optimum
    /// there and the value is the bound, not a measurement).
    pub at_bound: AtBound,
}

/// Parameters of an [`RrFit`] that ended on a bound.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct AtBound {
    /// `eta0` on [`FitConfig::value_bounds`].
    pub floor: bool,
    /// `eta0 + a` on [`FitConfig::value_bounds`].
    pub ceiling: bool,
    /// `RSSI_r` at the smallest or largest RSSI of the data.
    pub rssi_r: bool,
    /// `c` at [`FitConfig::min_c`] or at the data's RSSI range.
    pub c: bool,
}

impl AtBound {
    /// Whether any parameter is on a bound.
    pub fn any(&self) -> bool {
        self.floor || self.ceiling || self.rssi_r || self.c
    }
}

pub(super) fn check_inputs(
    rssi: &[f64],
    eta: &[f64],
    cfg: &FitConfig,
) -> Result<(f64, f64), WifiStatsError> {
    if cfg.min_points < 4 {
        return Err(WifiStatsError::InvalidConfig(wipdr_core::ConfigError::new(
            "min_points",
            format!("the model has 4 parameters, got {}", cfg.min_points),
        )));
    }
    if !(cfg.min_c > 0.0 && cfg.min_c.is_finite()) || cfg.grid_rssi_r < 2 {
        return Err(WifiStatsError::InvalidConfig(wipdr_core::ConfigError::new(
            "min_c / grid_rssi_r",
            "min_c must be > 0 and grid_rssi_r >= 2",
        )));
    }
    if let Some([l, h]) = cfg.value_bounds
        && !(l.is_finite() && h.is_finite() && l < h)
    {
        return Err(WifiStatsError::InvalidConfig(wipdr_core::ConfigError::new(
            "value_bounds",
            format!("need finite low < high, got [{l}, {h}]"),
        )));
    }
    if cfg.grid_c.iter().any(|c| !(c.is_finite() && *c > 0.0)) {
        return Err(WifiStatsError::InvalidConfig(wipdr_core::ConfigError::new(
            "grid_c",
            "every start value must be finite and > 0",
        )));
    }
    if rssi.len() != eta.len() {
        return Err(WifiStatsError::LengthMismatch {
            rssi: rssi.len(),
            eta: eta.len(),
        });
    }
    if rssi.len() < cfg.min_points {
        return Err(WifiStatsError::TooFewPoints {
            have: rssi.len(),
            need: cfg.min_points,
        });
    }
    for (field, v) in [("rssi", rssi), ("eta", eta)] {
        if let Some((index, &value)) = v.iter().enumerate().find(|(_, x)| !x.is_finite()) {
            return Err(WifiStatsError::NonFinite {
                field,
                index,
                value,
            });
        }
    }
    let lo = rssi.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = rssi.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if hi - lo < 1e-6 {
        return Err(WifiStatsError::NoSpread { span_db: hi - lo });
    }
    Ok((lo, hi))
}

/// Sum of squared residuals of `m`.
pub(super) fn sse_of(m: &RrModel, rssi: &[f64], eta: &[f64]) -> f64 {
    rssi.iter()
        .zip(eta)
        .map(|(&x, &y)| (y - m.eval(x)).powi(2))
        .sum()
}

/// With `rssi_r` and `c` fixed, the least-squares `eta0`, `a` (linear in the logistic
/// regressor `s`: `eta = f (1 - s) + g s` with floor `f = eta0`, ceiling `g = eta0 + a`),
/// with `f` and `g` kept in `bounds` (a box-constrained 2-D least squares: the interior
/// solution, else the best of the four edges). `None` when `s` is constant over the data.
pub(super) fn linear_part(
    rssi: &[f64],
    eta: &[f64],
    rssi_r: f64,
    c: f64,
    bounds: Option<[f64; 2]>,
) -> Option<(f64, f64)> {
    let (mut suu, mut suv, mut svv, mut suy, mut svy, mut syy) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for (&x, &y) in rssi.iter().zip(eta) {
        let v = logistic((x - rssi_r) / c);
        let u = 1.0 - v;
        suu += u * u;
        suv += u * v;
        svv += v * v;
        suy += u * y;
        svy += v * y;
        syy += y * y;
    }
    let det = suu * svv - suv * suv;
    if det.abs() <= 1e-12 * (suu * svv).max(f64::MIN_POSITIVE) || suu <= 0.0 || svv <= 0.0 {
        return None;
    }
    let f = (svv * suy - suv * svy) / det;
    let g = (suu * svy - suv * suy) / det;
    let Some([lo, hi]) = bounds else {
        return Some((f, g - f));
    };
    let inside = |v: f64| (lo..=hi).contains(&v);
    if inside(f) && inside(g) {
        return Some((f, g - f));
    }
    let sse = |f: f64, g: f64| {
        syy - 2.0 * f * suy - 2.0 * g * svy + f * f * suu + 2.0 * f * g * suv + g * g * svv
    };
    let mut best: Option<(f64, f64, f64)> = None;
    for edge in [lo, hi] {
        let g = ((svy - edge * suv) / svv).clamp(lo, hi);
        let f = ((suy - edge * suv) / suu).clamp(lo, hi);
        for (f, g) in [(edge, g), (f, edge)] {
            let e = sse(f, g);
            if best.is_none_or(|b| e < b.0) {
                best = Some((e, f, g));
            }
        }
    }
    best.map(|(_, f, g)| (f, g - f))
}

/// Fits the RR model (002 eq. 5) to `(rssi, eta)` by least squares: grid start over
/// `(RSSI_r, c)` with `eta0`, `a` solved exactly, then Levenberg-Marquardt on all four,
/// with each trial point projected onto the bounds.
///
/// Bounds: `RSSI_r` within the data's RSSI range (an inflection outside the data is not
/// identifiable), `c` in `[min_c, RSSI range]`, and the floor and ceiling within
/// [`FitConfig::value_bounds`] when given. [`RrFit::at_bound`] says which ended on one.
/// `a` may come out negative (a falling curve, e.g. the loss rate).
pub fn fit_rr_model(rssi: &[f64], eta: &[f64], cfg: &FitConfig) -> Result<RrFit, WifiStatsError> {
    let (lo, hi) = check_inputs(rssi, eta, cfg)?;
    let max_c = (hi - lo).max(cfg.min_c);
    let project = |m: RrModel| -> RrModel {
        let (mut f, mut g) = (m.eta0, m.eta0 + m.a);
        if let Some([vl, vh]) = cfg.value_bounds {
            f = f.clamp(vl, vh);
            g = g.clamp(vl, vh);
        }
        RrModel {
            eta0: f,
            a: g - f,
            rssi_r: m.rssi_r.clamp(lo, hi),
            c: m.c.clamp(cfg.min_c, max_c),
        }
    };
    // Grid start.
    let mut best: Option<(f64, RrModel)> = None;
    for i in 0..cfg.grid_rssi_r {
        let rssi_r = lo + (hi - lo) * i as f64 / (cfg.grid_rssi_r - 1) as f64;
        for &c in &cfg.grid_c {
            let c = c.clamp(cfg.min_c, max_c);
            if let Some((eta0, a)) = linear_part(rssi, eta, rssi_r, c, cfg.value_bounds) {
                let m = RrModel { eta0, a, rssi_r, c };
                let s = sse_of(&m, rssi, eta);
                if s.is_finite() && best.as_ref().is_none_or(|(b, _)| s < *b) {
                    best = Some((s, m));
                }
            }
        }
    }
    let Some((_, mut m)) = best else {
        return Err(WifiStatsError::NoSpread { span_db: hi - lo });
    };
    // Levenberg-Marquardt (the shared bounded one), each trial projected onto the bounds.
    let lm = LmConfig {
        max_iterations: cfg.max_iterations,
        cost_tolerance: cfg.tolerance,
        gradient_tolerance: cfg.tolerance,
        max_damping_tries: 15,
        ..LmConfig::default()
    };
    let as_model = |t: [f64; 4]| RrModel {
        eta0: t[0],
        a: t[1],
        rssi_r: t[2],
        c: t[3],
    };
    let as_params = |m: RrModel| [m.eta0, m.a, m.rssi_r, m.c];
    let out = levenberg_marquardt(
        as_params(m),
        |t| as_params(project(as_model(t))),
        &lm,
        |t, visit| {
            let m = as_model(*t);
            for (&x, &y) in rssi.iter().zip(eta) {
                let z = (x - m.rssi_r) / m.c;
                let s = logistic(z);
                let ds = s * (1.0 - s);
                visit(
                    y - (m.eta0 + m.a * s),
                    &[1.0, s, -m.a * ds / m.c, -m.a * ds * z / m.c],
                );
            }
        },
    );
    let (converged, iterations) = (out.converged, out.iterations);
    m = as_model(out.params);
    let mut sse = out.cost;
    if !converged {
        return Err(WifiStatsError::NoConvergence { iterations, sse });
    }
    // Polish: the exact (bounded) linear part at the final RSSI_r and c.
    if let Some((eta0, a)) = linear_part(rssi, eta, m.rssi_r, m.c, cfg.value_bounds) {
        let cand = RrModel { eta0, a, ..m };
        let s = sse_of(&cand, rssi, eta);
        if s < sse {
            m = cand;
            sse = s;
        }
    }
    let near = |v: f64, b: f64, scale: f64| (v - b).abs() <= 1e-6 * scale.max(1e-9);
    let vscale = m.eta0.abs().max((m.eta0 + m.a).abs()).max(1.0);
    let at_bound = AtBound {
        floor: cfg
            .value_bounds
            .is_some_and(|[l, h]| near(m.eta0, l, vscale) || near(m.eta0, h, vscale)),
        ceiling: cfg
            .value_bounds
            .is_some_and(|[l, h]| near(m.eta0 + m.a, l, vscale) || near(m.eta0 + m.a, h, vscale)),
        rssi_r: near(m.rssi_r, lo, hi - lo) || near(m.rssi_r, hi, hi - lo),
        c: near(m.c, cfg.min_c, max_c) || near(m.c, max_c, max_c),
    };
    let n = rssi.len();
    let fitted: Vec<f64> = rssi.iter().map(|&x| m.eval(x)).collect();
    tracing::debug!(?m, sse, iterations, ?at_bound, "RR model fitted");
    Ok(RrFit {
        model: m,
        points: n,
        sse,
        rmse: (sse / n as f64).sqrt(),
        correlation: correlation(&fitted, eta),
        iterations,
        at_bound,
    })
}

/// Pearson correlation of two equally long series; 0 when either is constant.
pub(super) fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    if n == 0 {
        return 0.0;
    }
    let ma = a.iter().sum::<f64>() / n as f64;
    let mb = b.iter().sum::<f64>() / n as f64;
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma).powi(2);
        sbb += (y - mb).powi(2);
    }
    let d = (saa * sbb).sqrt();
    if d > 0.0 && d.is_finite() {
        sab / d
    } else {
        0.0
    }
}

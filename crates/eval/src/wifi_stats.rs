//! Wi-Fi signals on the move (paper 002 §3.1, eq. 4-5, Fig. 2-3): the "refresh rate" and
//! "loss rate" of each access point against its mean RSSI, and the least-squares fit of the
//! paper's Refresh Rate (RR) model
//!
//! ```text
//! eta = eta0 + a / (1 + exp(-(RSSI - RSSI_r) / c))          (002 eq. 5)
//! ```
//!
//! (the paper found `eta0 = 2.1630 %`, `a = 82.4917 %`, `RSSI_r = -75.0075 dBm`,
//! `c = 1.8464`).
//!
//! # Refresh and loss on recorded walks
//!
//! A phone's scan result lists every AP seen recently, each with its *last-seen* time; an AP
//! that was not measured again keeps its old entry (and RSSI) for tens of seconds. So the
//! refresh of an entry is read from the last-seen times ([`walk_ap_stats`]), per AP and per
//! walk, over the scans that have a previous scan (the first scan of a walk has nothing to
//! compare with):
//!
//! - the AP's *span* is the scans from its first to its last appearance in the walk;
//! - scan `k` *refreshes* the AP when its entry is present and its last-seen time advanced by
//!   more than [`WifiStatsConfig::refresh_tolerance_ms`] since the AP's entry in scan `k-1`
//!   (recorded last-seen times jitter by a millisecond between scans), or, when the AP was
//!   absent from scan `k-1`, when it was seen after scan `k-1`'s time;
//! - the *fastest update interval* is the walk's median scan interval (an entry cannot be
//!   refreshed more often than once per scan); the AP's *current update interval* is its span's
//!   duration (plus one scan interval) over its number of refreshes; the **refresh rate** is
//!   the fastest over the current interval, in `[0, 1]` (for evenly spaced scans: refreshing
//!   scans over scans in the span);
//! - the **loss rate** is the share of scans of the span in which the AP is missing;
//! - the **mean RSSI** is the mean of the AP's entries in the span, as the phone reports them.
//!
//! # The fit
//!
//! [`fit_rr_model`]: Levenberg-Marquardt ([`wipdr_core::fit`]) on the sum of squared residuals, started from the best
//! point of a grid over `(RSSI_r, c)` at which `eta0` and `a` (linear) are solved exactly.
//! Bad input gives a typed [`WifiStatsError`]: too few points, NaN, no spread of RSSI, no
//! convergence.
//!
//! ```
//! use wipdr_eval::wifi_stats::{fit_rr_model, RrModel, FitConfig};
//!
//! let truth = RrModel { eta0: 2.0, a: 80.0, rssi_r: -75.0, c: 1.85 };
//! let rssi: Vec<f64> = (0..200).map(|i| -95.0 + 0.25 * i as f64).collect();
//! let eta: Vec<f64> = rssi.iter().map(|&x| truth.eval(x)).collect();
//! let fit = fit_rr_model(&rssi, &eta, &FitConfig::default()).unwrap();
//! assert!((fit.model.rssi_r + 75.0).abs() < 1e-6 && (fit.model.c - 1.85).abs() < 1e-6);
//! ```

use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use thiserror::Error;
use wipdr_core::fit::{LmConfig, levenberg_marquardt};
use wipdr_core::{Bssid, TimestampMs, WifiScan};

/// Errors of the Wi-Fi statistics and of the RR fit.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum WifiStatsError {
    /// Fewer points than the fit needs.
    #[error("too few points for the RR fit: {have}, need at least {need}")]
    TooFewPoints {
        /// Points given.
        have: usize,
        /// Points needed.
        need: usize,
    },
    /// The two inputs differ in length.
    #[error("{rssi} RSSI values but {eta} rate values")]
    LengthMismatch {
        /// RSSI values given.
        rssi: usize,
        /// Rate values given.
        eta: usize,
    },
    /// A NaN or infinite input value.
    #[error("non-finite {field} at point {index}: {value}")]
    NonFinite {
        /// `rssi` or `eta`.
        field: &'static str,
        /// Index of the point.
        index: usize,
        /// The value.
        value: f64,
    },
    /// All RSSI values (nearly) equal: the curve's position and width are not identifiable.
    #[error("RSSI values span only {span_db} dB: the RR curve cannot be located")]
    NoSpread {
        /// Largest minus smallest RSSI.
        span_db: f64,
    },
    /// Levenberg-Marquardt did not converge.
    #[error("the RR fit did not converge in {iterations} iterations (last SSE {sse})")]
    NoConvergence {
        /// Iterations run.
        iterations: usize,
        /// Sum of squared residuals at the last accepted point.
        sse: f64,
    },
    /// A configuration value out of range.
    #[error("invalid configuration field {field}: {reason}")]
    InvalidConfig {
        /// The field.
        field: &'static str,
        /// Why.
        reason: String,
    },
}

/// How refresh and loss are read from a walk's scans (see the module docs). These are not
/// constants of the papers (the paper measured at fixed points); the defaults suit Android
/// scan lists.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct WifiStatsConfig {
    /// A last-seen time must advance by more than this (ms) to count as a refresh (recorded
    /// last-seen times of a cached entry jitter by about 1 ms between scans).
    pub refresh_tolerance_ms: i64,
    /// An (AP, walk) pair needs at least this many scans in its span to be kept.
    pub min_span_scans: usize,
}

impl Default for WifiStatsConfig {
    fn default() -> Self {
        Self {
            refresh_tolerance_ms: 200,
            min_span_scans: 5,
        }
    }
}

impl WifiStatsConfig {
    /// Checks every field.
    pub fn validate(&self) -> Result<(), WifiStatsError> {
        if self.refresh_tolerance_ms < 0 {
            return Err(WifiStatsError::InvalidConfig {
                field: "refresh_tolerance_ms",
                reason: format!("must be >= 0, got {}", self.refresh_tolerance_ms),
            });
        }
        if self.min_span_scans == 0 {
            return Err(WifiStatsError::InvalidConfig {
                field: "min_span_scans",
                reason: "must be >= 1".into(),
            });
        }
        Ok(())
    }
}

/// Refresh and loss of one AP over one walk.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ApWalkStats {
    /// The access point.
    pub bssid: Bssid,
    /// Mean RSSI of its entries in the span, dBm.
    pub mean_rssi_dbm: f64,
    /// Refresh rate, `[0, 1]`: fastest over current update interval.
    pub refresh_rate: f64,
    /// Loss rate, `[0, 1]`: share of the span's scans without the AP.
    pub loss_rate: f64,
    /// Scans in the span.
    pub span_scans: usize,
    /// Scans that refreshed the AP.
    pub refreshes: usize,
}

/// What [`walk_ap_stats`] skipped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct WalkStatsSkips {
    /// Walks with fewer than two scans (or no positive scan interval).
    pub walks_too_short: usize,
    /// Entries with a non-finite RSSI, ignored.
    pub non_finite_rssi: usize,
    /// (AP, walk) pairs whose span is shorter than [`WifiStatsConfig::min_span_scans`].
    pub short_spans: usize,
}

impl WalkStatsSkips {
    /// Adds another count.
    pub fn add(&mut self, o: &WalkStatsSkips) {
        self.walks_too_short += o.walks_too_short;
        self.non_finite_rssi += o.non_finite_rssi;
        self.short_spans += o.short_spans;
    }
}

/// Per-AP accumulation over a walk.
#[derive(Debug, Clone, Copy)]
struct ApTrack {
    first_scan: usize,
    last_scan: usize,
    present: usize,
    refreshes: usize,
    rssi_sum: f64,
    /// Last-seen time in the previous scan, when present there.
    prev_last_seen: Option<TimestampMs>,
    /// Index of the previous scan the AP was present in.
    prev_scan: usize,
}

/// Refresh and loss rates of every AP heard in one walk (`scans` sorted by time), see the
/// module docs. Sorted by BSSID. Counts what it skips into `skips`.
pub fn walk_ap_stats(
    scans: &[WifiScan],
    cfg: &WifiStatsConfig,
    skips: &mut WalkStatsSkips,
) -> Vec<ApWalkStats> {
    let mut intervals: Vec<i64> = scans
        .windows(2)
        .map(|w| w[1].t - w[0].t)
        .filter(|&d| d > 0)
        .collect();
    if scans.len() < 2 || intervals.is_empty() {
        skips.walks_too_short += 1;
        return Vec::new();
    }
    intervals.sort_unstable();
    let fastest_ms = intervals[intervals.len() / 2] as f64;
    let mut tracks: HashMap<Bssid, ApTrack> = HashMap::new();
    // Scan 0 only seeds the previous last-seen times.
    for e in &scans[0].entries {
        tracks.insert(
            e.bssid,
            ApTrack {
                first_scan: usize::MAX,
                last_scan: 0,
                present: 0,
                refreshes: 0,
                rssi_sum: 0.0,
                prev_last_seen: Some(e.last_seen_ms),
                prev_scan: 0,
            },
        );
    }
    for (k, scan) in scans.iter().enumerate().skip(1) {
        let prev_t = scans[k - 1].t;
        for e in &scan.entries {
            if !e.rssi_dbm.is_finite() {
                skips.non_finite_rssi += 1;
                continue;
            }
            let tr = tracks.entry(e.bssid).or_insert(ApTrack {
                first_scan: usize::MAX,
                last_scan: 0,
                present: 0,
                refreshes: 0,
                rssi_sum: 0.0,
                prev_last_seen: None,
                prev_scan: 0,
            });
            let was_present = tr.prev_scan + 1 == k && tr.prev_last_seen.is_some();
            let refreshed = match (was_present, tr.prev_last_seen) {
                (true, Some(prev)) => e.last_seen_ms - prev > cfg.refresh_tolerance_ms,
                _ => e.last_seen_ms > prev_t,
            };
            if tr.first_scan == usize::MAX {
                tr.first_scan = k;
            }
            tr.last_scan = k;
            tr.present += 1;
            tr.refreshes += usize::from(refreshed);
            tr.rssi_sum += e.rssi_dbm;
            tr.prev_last_seen = Some(e.last_seen_ms);
            tr.prev_scan = k;
        }
    }
    let mut out: Vec<ApWalkStats> = Vec::new();
    for (bssid, tr) in tracks {
        if tr.present == 0 {
            continue; // only in scan 0
        }
        let span = tr.last_scan - tr.first_scan + 1;
        if span < cfg.min_span_scans {
            skips.short_spans += 1;
            continue;
        }
        let duration = (scans[tr.last_scan].t - scans[tr.first_scan].t) as f64 + fastest_ms;
        let refresh_rate = if tr.refreshes == 0 {
            0.0
        } else {
            (fastest_ms * tr.refreshes as f64 / duration).min(1.0)
        };
        out.push(ApWalkStats {
            bssid,
            mean_rssi_dbm: tr.rssi_sum / tr.present as f64,
            refresh_rate,
            loss_rate: (span - tr.present) as f64 / span as f64,
            span_scans: span,
            refreshes: tr.refreshes,
        });
    }
    out.sort_by_key(|s| s.bssid);
    out
}

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
fn logistic(z: f64) -> f64 {
    if z >= 0.0 {
        1.0 / (1.0 + (-z).exp())
    } else {
        let e = z.exp();
        e / (1.0 + e)
    }
}

/// Settings of [`fit_rr_model`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
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

fn check_inputs(rssi: &[f64], eta: &[f64], cfg: &FitConfig) -> Result<(f64, f64), WifiStatsError> {
    if cfg.min_points < 4 {
        return Err(WifiStatsError::InvalidConfig {
            field: "min_points",
            reason: format!("the model has 4 parameters, got {}", cfg.min_points),
        });
    }
    if !(cfg.min_c > 0.0 && cfg.min_c.is_finite()) || cfg.grid_rssi_r < 2 {
        return Err(WifiStatsError::InvalidConfig {
            field: "min_c / grid_rssi_r",
            reason: "min_c must be > 0 and grid_rssi_r >= 2".into(),
        });
    }
    if let Some([l, h]) = cfg.value_bounds
        && !(l.is_finite() && h.is_finite() && l < h)
    {
        return Err(WifiStatsError::InvalidConfig {
            field: "value_bounds",
            reason: format!("need finite low < high, got [{l}, {h}]"),
        });
    }
    if cfg.grid_c.iter().any(|c| !(c.is_finite() && *c > 0.0)) {
        return Err(WifiStatsError::InvalidConfig {
            field: "grid_c",
            reason: "every start value must be finite and > 0".into(),
        });
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
fn sse_of(m: &RrModel, rssi: &[f64], eta: &[f64]) -> f64 {
    rssi.iter()
        .zip(eta)
        .map(|(&x, &y)| (y - m.eval(x)).powi(2))
        .sum()
}

/// With `rssi_r` and `c` fixed, the least-squares `eta0`, `a` (linear in the logistic
/// regressor `s`: `eta = f (1 - s) + g s` with floor `f = eta0`, ceiling `g = eta0 + a`),
/// with `f` and `g` kept in `bounds` (a box-constrained 2-D least squares: the interior
/// solution, else the best of the four edges). `None` when `s` is constant over the data.
fn linear_part(
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
fn correlation(a: &[f64], b: &[f64]) -> f64 {
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

/// One bin of [`binned_means`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Bin {
    /// Centre of the bin, dBm.
    pub rssi_dbm: f64,
    /// Mean of the values in the bin.
    pub mean: f64,
    /// Values in the bin.
    pub count: usize,
}

/// Means of `values` in RSSI bins `width_db` wide (aligned on multiples of the width), for
/// bins with at least `min_count` points, ascending. Non-finite pairs are ignored.
pub fn binned_means(rssi: &[f64], values: &[f64], width_db: f64, min_count: usize) -> Vec<Bin> {
    if !(width_db > 0.0 && width_db.is_finite()) {
        return Vec::new();
    }
    let mut bins: std::collections::BTreeMap<i64, (f64, usize)> = Default::default();
    for (&x, &y) in rssi.iter().zip(values) {
        if !(x.is_finite() && y.is_finite()) {
            continue;
        }
        let e = bins
            .entry((x / width_db).floor() as i64)
            .or_insert((0.0, 0));
        e.0 += y;
        e.1 += 1;
    }
    bins.into_iter()
        .filter(|(_, (_, n))| *n >= min_count.max(1))
        .map(|(k, (s, n))| Bin {
            rssi_dbm: (k as f64 + 0.5) * width_db,
            mean: s / n as f64,
            count: n,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use wipdr_core::WifiEntry;

    /// SplitMix64 uniform in [0, 1) and a Box-Muller normal: a tiny seeded generator for
    /// the synthetic data (reproducible per seed).
    struct Rng(u64);
    impl Rng {
        fn uniform(&mut self) -> f64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
        }
        fn normal(&mut self) -> f64 {
            let u1 = self.uniform().max(1e-300);
            let u2 = self.uniform();
            (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
        }
    }

    fn synthetic(truth: &RrModel, n: usize, noise: f64, seed: u64) -> (Vec<f64>, Vec<f64>) {
        synthetic_over(truth, n, noise, seed, (-100.0, -45.0))
    }

    /// Noisy samples of `truth` at RSSI values uniform over `range`.
    fn synthetic_over(
        truth: &RrModel,
        n: usize,
        noise: f64,
        seed: u64,
        range: (f64, f64),
    ) -> (Vec<f64>, Vec<f64>) {
        let mut rng = Rng(seed);
        let x: Vec<f64> = (0..n)
            .map(|_| range.0 + (range.1 - range.0) * rng.uniform())
            .collect();
        let y = x
            .iter()
            .map(|&v| truth.eval(v) + noise * rng.normal())
            .collect();
        (x, y)
    }

    fn within(got: f64, want: f64, rel: f64) -> bool {
        (got - want).abs() <= rel * want.abs()
    }

    #[test]
    fn recovers_paper_parameters_from_noisy_data_several_seeds() {
        for seed in 1..=8 {
            let (x, y) = synthetic(&RrModel::PAPER_PERCENT, 2000, 1.0, seed);
            let fit = fit_rr_model(&x, &y, &FitConfig::default()).unwrap();
            let (m, t) = (fit.model, RrModel::PAPER_PERCENT);
            assert!(
                within(m.eta0, t.eta0, 0.05)
                    && within(m.a, t.a, 0.05)
                    && within(m.rssi_r, t.rssi_r, 0.05)
                    && within(m.c, t.c, 0.05),
                "seed {seed}: {m:?}"
            );
            assert!(fit.correlation > 0.99, "{}", fit.correlation);
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        #[test]
        fn recovers_parameters_within_5_percent(
            eta0 in 1.0f64..5.0,
            a in 50.0f64..95.0,
            rssi_r in -85.0f64..-65.0,
            c in 1.0f64..4.0,
            seed in any::<u64>(),
        ) {
            let truth = RrModel { eta0, a, rssi_r, c };
            // Data covering both plateaus (the inflection +- 25 dB, over 6 widths each side):
            // with a plateau barely sampled its level is not identifiable to 5 %.
            let (x, y) = synthetic_over(&truth, 3000, 0.5, seed, (rssi_r - 25.0, rssi_r + 25.0));
            let fit = fit_rr_model(&x, &y, &FitConfig::default()).unwrap();
            let m = fit.model;
            prop_assert!(within(m.eta0, eta0, 0.05), "eta0 {} vs {}", m.eta0, eta0);
            prop_assert!(within(m.a, a, 0.05), "a {} vs {}", m.a, a);
            prop_assert!(within(m.rssi_r, rssi_r, 0.05), "rssi_r {} vs {}", m.rssi_r, rssi_r);
            prop_assert!(within(m.c, c, 0.05), "c {} vs {}", m.c, c);
        }
    }

    #[test]
    fn runaway_data_stay_within_bounds_and_say_so() {
        // A concave rise with no upper level: unbounded least squares runs off to infinity.
        let x: Vec<f64> = (0..60).map(|i| -95.0 + i as f64).collect();
        let y: Vec<f64> = x
            .iter()
            .map(|v| 100.0 - 90.0 * (-(v + 95.0) / 30.0).exp())
            .collect();
        let cfg = FitConfig {
            value_bounds: Some([0.0, 100.0]),
            ..Default::default()
        };
        let fit = fit_rr_model(&x, &y, &cfg).unwrap();
        let m = fit.model;
        assert!(m.eta0 >= 0.0 && m.eta0 + m.a <= 100.0 + 1e-9, "{m:?}");
        assert!((-95.0..=-36.0).contains(&m.rssi_r), "{m:?}");
        assert!(fit.at_bound.any(), "{fit:?}");
        // Interior data are not affected by the bounds.
        let (x, y) = synthetic(&RrModel::PAPER_PERCENT, 2000, 1.0, 11);
        let free = fit_rr_model(&x, &y, &FitConfig::default()).unwrap();
        let bounded = fit_rr_model(&x, &y, &cfg).unwrap();
        assert!(!bounded.at_bound.any(), "{bounded:?}");
        assert!((free.model.rssi_r - bounded.model.rssi_r).abs() < 1e-6);
        let bad = FitConfig {
            value_bounds: Some([1.0, 0.0]),
            ..Default::default()
        };
        assert!(matches!(
            fit_rr_model(&x, &y, &bad),
            Err(WifiStatsError::InvalidConfig { .. })
        ));
    }

    #[test]
    fn falling_curve_has_negative_height() {
        let truth = RrModel {
            eta0: 0.6,
            a: -0.55,
            rssi_r: -85.0,
            c: 2.5,
        };
        let (x, y) = synthetic(&truth, 1500, 0.01, 7);
        let m = fit_rr_model(&x, &y, &FitConfig::default()).unwrap().model;
        assert!(
            within(m.a, -0.55, 0.05) && within(m.rssi_r, -85.0, 0.05),
            "{m:?}"
        );
    }

    #[test]
    fn bad_input_gives_typed_errors() {
        let cfg = FitConfig::default();
        assert_eq!(
            fit_rr_model(&[], &[], &cfg),
            Err(WifiStatsError::TooFewPoints { have: 0, need: 8 })
        );
        let x = [-90.0, -85.0, -80.0, -75.0, -70.0, -65.0, -60.0, -55.0];
        let mut y = [0.0, 0.1, 0.3, 0.5, 0.8, 0.9, 0.9, 0.9];
        assert!(matches!(
            fit_rr_model(&x[..5], &y[..5], &cfg),
            Err(WifiStatsError::TooFewPoints { have: 5, need: 8 })
        ));
        assert!(matches!(
            fit_rr_model(&x, &y[..7], &cfg),
            Err(WifiStatsError::LengthMismatch { rssi: 8, eta: 7 })
        ));
        y[3] = f64::NAN;
        assert!(matches!(
            fit_rr_model(&x, &y, &cfg),
            Err(WifiStatsError::NonFinite {
                field: "eta",
                index: 3,
                ..
            })
        ));
        let flat = [-70.0; 8];
        assert!(matches!(
            fit_rr_model(&flat, &[0.5; 8], &cfg),
            Err(WifiStatsError::NoSpread { .. })
        ));
        let tight = FitConfig {
            max_iterations: 1,
            tolerance: 0.0,
            ..cfg
        };
        let (x, y) = synthetic(&RrModel::PAPER_PERCENT, 500, 2.0, 3);
        assert!(matches!(
            fit_rr_model(&x, &y, &tight),
            Err(WifiStatsError::NoConvergence { iterations: 1, .. })
        ));
    }

    fn entry(b: u64, rssi: f64, last_seen: i64) -> WifiEntry {
        WifiEntry {
            bssid: Bssid(b),
            ssid: String::new(),
            rssi_dbm: rssi,
            frequency_mhz: 2412,
            last_seen_ms: last_seen,
        }
    }

    #[test]
    fn refresh_and_loss_from_last_seen_times() {
        // Scans every 2 s. AP 1 is fresh in every scan; AP 2 is a cached entry refreshed every
        // other scan (its last-seen time jitters by 1 ms when not refreshed); AP 3 is missing
        // from two of the six scans of its span.
        let mut scans = Vec::new();
        for k in 0..8i64 {
            let t = 1_000_000 + 2000 * k;
            let mut entries = vec![entry(1, -50.0, t - 100)];
            let ls2 = if k % 2 == 0 { t - 300 } else { t - 2300 + 1 };
            entries.push(entry(2, -80.0, ls2));
            if (1..=6).contains(&k) && k != 3 && k != 4 {
                entries.push(entry(3, -88.0, t - 50));
            }
            scans.push(WifiScan { t, entries });
        }
        let mut skips = WalkStatsSkips::default();
        let s = walk_ap_stats(&scans, &WifiStatsConfig::default(), &mut skips);
        assert_eq!(skips, WalkStatsSkips::default());
        assert_eq!(s.len(), 3);
        assert_eq!(
            (s[0].refresh_rate, s[0].loss_rate, s[0].span_scans),
            (1.0, 0.0, 7)
        );
        assert_eq!(s[0].mean_rssi_dbm, -50.0);
        // AP 2: scans 2, 4, 6 refresh it out of 7 (1..=7).
        assert_eq!(s[1].refreshes, 3);
        assert!((s[1].refresh_rate - 3.0 / 7.0).abs() < 1e-12);
        // AP 3: span 1..=6, missing in 3 and 4; each appearance is fresh.
        assert_eq!((s[2].span_scans, s[2].refreshes), (6, 4));
        assert!((s[2].loss_rate - 2.0 / 6.0).abs() < 1e-12);
        assert!((s[2].refresh_rate - 4.0 / 6.0).abs() < 1e-12);
    }

    #[test]
    fn short_walks_and_spans_are_counted() {
        let mut skips = WalkStatsSkips::default();
        assert!(walk_ap_stats(&[], &WifiStatsConfig::default(), &mut skips).is_empty());
        let one = [WifiScan {
            t: 0,
            entries: vec![entry(1, -60.0, 0)],
        }];
        assert!(walk_ap_stats(&one, &WifiStatsConfig::default(), &mut skips).is_empty());
        assert_eq!(skips.walks_too_short, 2);
        let scans: Vec<WifiScan> = (0..3)
            .map(|k| WifiScan {
                t: 1000 * k,
                entries: vec![entry(1, if k == 2 { f64::NAN } else { -60.0 }, 1000 * k)],
            })
            .collect();
        let s = walk_ap_stats(&scans, &WifiStatsConfig::default(), &mut skips);
        assert!(s.is_empty());
        assert_eq!((skips.short_spans, skips.non_finite_rssi), (1, 1));
        assert!(
            WifiStatsConfig {
                min_span_scans: 0,
                ..Default::default()
            }
            .validate()
            .is_err()
        );
    }

    #[test]
    fn real_walk_rates_are_sane() {
        let floor = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../../shared/data/ilc20/site1/F1"
        );
        let files = match wipdr_io::floor::walk_files(floor) {
            Ok(f) if !f.is_empty() => f,
            _ => {
                eprintln!("skipped: no real walks under {floor}");
                return;
            }
        };
        let walk = wipdr_io::trace::read_walk(&files[0]).unwrap().walk;
        let mut skips = WalkStatsSkips::default();
        let stats = walk_ap_stats(&walk.wifi, &WifiStatsConfig::default(), &mut skips);
        assert!(stats.len() > 20, "{} pairs", stats.len());
        assert!(stats.iter().all(|s| (0.0..=1.0).contains(&s.refresh_rate)
            && (0.0..=1.0).contains(&s.loss_rate)
            && s.mean_rssi_dbm.is_finite()
            && s.refreshes <= s.span_scans));
        // Stronger APs are refreshed more often on average (002 §3.1).
        let rates = |keep: &dyn Fn(f64) -> bool| -> Vec<f64> {
            stats
                .iter()
                .filter(|s| keep(s.mean_rssi_dbm))
                .map(|s| s.refresh_rate)
                .collect()
        };
        let (strong, weak) = (rates(&|r| r > -75.0), rates(&|r| r < -85.0));
        assert!(!strong.is_empty() && !weak.is_empty());
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        assert!(
            mean(&strong) > mean(&weak),
            "{} vs {}",
            mean(&strong),
            mean(&weak)
        );
    }

    #[test]
    fn bins_average_and_skip_sparse() {
        let b = binned_means(
            &[-70.2, -70.8, -60.5, f64::NAN],
            &[1.0, 3.0, 5.0, 1.0],
            1.0,
            2,
        );
        assert_eq!(b.len(), 1);
        assert_eq!((b[0].rssi_dbm, b[0].mean, b[0].count), (-70.5, 2.0, 2));
    }
}

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
//! use wipdr_analysis::wifi_stats::{fit_rr_model, RrModel, FitConfig};
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
use wipdr_core::{Bssid, TimestampMs, WifiScan};

mod rr_fit;
#[cfg(test)]
mod tests;

pub use rr_fit::{AtBound, FitConfig, RrFit, RrModel, fit_rr_model};

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
    /// A configuration value out of range: the field's path and why.
    #[error(transparent)]
    InvalidConfig(#[from] wipdr_core::ConfigError),
}

/// How refresh and loss are read from a walk's scans (see the module docs). These are not
/// constants of the papers (the paper measured at fixed points); the defaults suit Android
/// scan lists.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
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
            return Err(WifiStatsError::InvalidConfig(wipdr_core::ConfigError::new(
                "refresh_tolerance_ms",
                format!("must be >= 0, got {}", self.refresh_tolerance_ms),
            )));
        }
        if self.min_span_scans == 0 {
            return Err(WifiStatsError::InvalidConfig(wipdr_core::ConfigError::new(
                "min_span_scans",
                "must be >= 1",
            )));
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

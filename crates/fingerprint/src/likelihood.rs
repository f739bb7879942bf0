//! A Wi-Fi scan as a likelihood over the floor, not a point: per AP, its signal field over
//! each floor (the probability of hearing it, the mean and spread of its RSS) learned from a
//! radio map, and the log-likelihood of a whole scan at every cell of a raster. Probabilistic
//! fingerprinting in the manner of Horus (Youssef and Agrawala, MobiSys 2005), with the
//! reference points' statistics spread over the floor by a Gaussian kernel; not from the four
//! papers of this workspace (their matchers answer a point).
//!
//! # The model
//!
//! At a cell centre `p` of floor `f`, the reference points of `f` within `support_m` weigh
//! `w_i = exp(-|p - x_i|² / 2 kernel_m²)`; `W = Σ w_i` is the cell's coverage (no reference
//! point in reach: no coverage, and the cell has no likelihood: an unknown place is left to
//! the caller, not made up). For AP `a`, with `H = Σ w_i [i heard a]`:
//!
//! - hearing probability `P = (H + prior_weight detection_prior) / (W + prior_weight)`;
//! - RSS mean `μ = Σ w_i m_ia / H` and variance `σ² = Σ w_i (s_ia² + (m_ia - μ)²) / H +
//!   min_sd_db²` over the points that heard it (`m`, `s`: the point's mean and spread).
//!
//! A scan heard AP `a` at `r` dBm: `ln((1 - outlier) P N(r - offset; μ, σ) + outlier / range)`
//! (the outlier share keeps a moved or replaced AP from killing the right place; `offset` is the
//! device's RSS offset, `range` the width of valid RSS). An AP heard by some reference point
//! near `p` but not in the scan: `ln(1 - (1 - outlier) P)`. APs the map never heard are the
//! same everywhere and left out. Only a scan's `max_scan_aps` strongest APs count (a bound on
//! the cost; a scan's weak tail is the least informative part).
//!
//! # Cost
//!
//! Fitting touches every (reference point, heard AP) pair once per cell in its support:
//! `O(points x APs heard a point x cells within support_m)`. A raster for one scan costs one
//! pass over the floor's covered cells plus, per scan AP, a pass over that AP's field (the
//! cells where some reference point heard it): `cells + Σ field sizes`, bounded by
//! `max_field_cells`.
//!
//! ```
//! use wipdr_core::{Bssid, Point2, WifiScan};
//! use wipdr_fingerprint::likelihood::{LikelihoodConfig, ScanLikelihood};
//! use wipdr_fingerprint::radio_map::{ApVocabulary, RadioMap, RadioMapConfig, ReferencePoint};
//! let vocabulary = ApVocabulary::from_bssids([Bssid(1), Bssid(2)]);
//! let mut map = RadioMap::new(vocabulary, RadioMapConfig::default());
//! // Two APs at x = 0 and x = 20 m, reference points every 2 m along y = 0.
//! for k in 0..=10 {
//!     let x = 2.0 * k as f64;
//!     let rp = ReferencePoint { position: Point2::new(x, 0.0), z: None, floor: Some(0),
//!         building: None, scans: 1 };
//!     let (a, b) = (-40.0 - 2.0 * x as f32, -80.0 + 2.0 * x as f32);
//!     map.push_point(rp, &[Some(a), Some(b)], None).unwrap();
//! }
//! let model = ScanLikelihood::fit(&map, &LikelihoodConfig::default()).unwrap();
//! let scan = WifiScan::from_readings(0, [(Bssid(1), -52.0), (Bssid(2), -68.0)]);
//! let raster = model.raster(Some(0), &scan, 0.0).unwrap();
//! let best = raster.best().unwrap();
//! assert!((best.x - 6.0).abs() <= 2.0 && best.y.abs() <= 2.0, "{best:?}");
//! ```

use std::collections::HashMap;

use serde::{Deserialize, Serialize};
use wipdr_core::{GridSpec, Point2, WifiLikelihood, WifiScan};

use crate::error::FingerprintError;
use crate::radio_map::RadioMap;

mod field;
use field::{ApField, FieldCell};

/// The width of the valid RSS range, dB (`[-120, 0]`, [`crate::radio_map::is_valid_rssi`]):
/// the density of an outlier reading.
const RSS_RANGE_DB: f64 = 120.0;

/// Settings of [`ScanLikelihood`]. Defaults: a 2 m raster (the lattice filters' scale is
/// 1-3 m), a 3 m kernel (the ILC walks' reference points lie about 1 m apart along the
/// walked paths, corridors 3-6 m wide), support at three kernel widths.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LikelihoodConfig {
    /// Raster cell, metres.
    pub cell_m: f64,
    /// The Gaussian kernel's standard deviation spreading a reference point's statistics,
    /// metres.
    pub kernel_m: f64,
    /// Reference points farther than this from a cell do not inform it, metres.
    pub support_m: f64,
    /// The least RSS standard deviation, dB (a phone's scan-to-scan noise).
    pub min_sd_db: f64,
    /// The prior probability of hearing an AP where no reference point heard it.
    pub detection_prior: f64,
    /// The prior's weight, in units of one reference point at distance 0.
    pub prior_weight: f64,
    /// The share of a heard AP's density that is uniform over the RSS range (robustness to
    /// moved, new or mismeasured APs), in `(0, 1)`.
    pub outlier: f64,
    /// The strongest APs of a scan that count.
    pub max_scan_aps: usize,
    /// Scan entries last seen longer than this before the scan are not scored (heard, so
    /// not silent either), ms; `None` scores them all. Default 5 s, the radio map's own
    /// staleness limit ([`crate::walk_map::WalkMapConfig::max_entry_age_ms`]).
    #[serde(with = "wipdr_core::off")]
    pub max_entry_age_ms: Option<i64>,
    /// The power the likelihood is raised to (its log multiplied by it): the APs of a scan
    /// are not independent evidence (they share the phone's orientation, the body's
    /// shadow, the scan's timing), so the product of their terms is overconfident. 0.1: on
    /// the ILC floors' held-out scans the cells holding 95 % of the tempered posterior hold
    /// the truth at about 95 % (`cargo test -p wipdr-eval --test likelihood_real --
    /// --nocapture` prints it per floor and for other values; 1 holds it at about 30 %).
    pub evidence_scale: f64,
    /// A place the radio map does not reach takes the mean likelihood of the known cells
    /// within this distance (a square's half-width), metres ([`WifiLikelihood::from_log`]):
    /// a scan taken in a coverage gap resembles those of the covered places around it.
    /// 0: every unknown place reads the scan's mean over the floor.
    pub unknown_reach_m: f64,
    /// Learn each walk's device RSS offset from its scans' residuals at the matcher's fixes
    /// ([`RssOffsetEstimate`], at most ±20 dB) and score its scans with it; off: offset 0.
    pub estimate_offset: bool,
    /// The offset estimate's shrinkage: this many scans of residual 0 count in its mean
    /// (at least 1). 12: between the IPIN logfiles (whose phones differ from the survey's;
    /// `pmf` EvAAL 9.05 at 4, 9.19 at 12, 9.27 at 30, 9.67 without the estimate) and the
    /// ILC floors (one kind of phone; causal 4.82 at 4, 4.77 at 12, 4.75 at 30, 4.73
    /// without), `wipdr eval` with `[likelihood] offset_prior_scans = N` on both.
    pub offset_prior_scans: f64,
    /// A floor's raster may hold at most this many cells.
    pub max_cells: usize,
    /// All floors' AP fields together may hold at most this many (cell, AP) entries (16
    /// bytes each).
    pub max_field_cells: usize,
}

impl Default for LikelihoodConfig {
    fn default() -> Self {
        Self {
            cell_m: 2.0,
            kernel_m: 3.0,
            support_m: 9.0,
            min_sd_db: 4.0,
            detection_prior: 0.05,
            prior_weight: 0.5,
            outlier: 0.05,
            max_scan_aps: 20,
            max_entry_age_ms: Some(5_000),
            evidence_scale: 0.1,
            unknown_reach_m: 15.0,
            estimate_offset: true,
            offset_prior_scans: 12.0,
            max_cells: 4_000_000,
            max_field_cells: 50_000_000,
        }
    }
}

impl LikelihoodConfig {
    /// Checks every field; the error names it.
    pub fn check(&self) -> Result<(), FingerprintError> {
        let bad = |field: &str, what: &str| {
            Err(FingerprintError::InvalidConfig(
                wipdr_core::ConfigError::new(format!("likelihood.{field}"), what),
            ))
        };
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if !positive(self.cell_m) {
            return bad("cell_m", "a finite number > 0");
        }
        if !positive(self.kernel_m) {
            return bad("kernel_m", "a finite number > 0");
        }
        if !(positive(self.support_m) && self.support_m >= self.cell_m) {
            return bad("support_m", "a finite number >= cell_m");
        }
        if !positive(self.min_sd_db) {
            return bad("min_sd_db", "a finite number > 0");
        }
        if !(self.detection_prior.is_finite() && (0.0..1.0).contains(&self.detection_prior)) {
            return bad("detection_prior", "in [0, 1)");
        }
        if !positive(self.prior_weight) {
            return bad("prior_weight", "a finite number > 0");
        }
        if !(self.outlier.is_finite() && self.outlier > 0.0 && self.outlier < 1.0) {
            return bad("outlier", "in (0, 1)");
        }
        if self.max_entry_age_ms.is_some_and(|a| a < 0) {
            return bad("max_entry_age_ms", "at least 0, or \"off\"");
        }
        if !(self.evidence_scale.is_finite()
            && self.evidence_scale > 0.0
            && self.evidence_scale <= 1.0)
        {
            return bad("evidence_scale", "in (0, 1]");
        }
        if !(self.unknown_reach_m.is_finite() && self.unknown_reach_m >= 0.0) {
            return bad("unknown_reach_m", "a finite number >= 0");
        }
        if !(self.offset_prior_scans.is_finite() && self.offset_prior_scans >= 1.0) {
            return bad("offset_prior_scans", "a finite number >= 1");
        }
        if self.max_scan_aps == 0 {
            return bad("max_scan_aps", "at least 1");
        }
        if self.max_cells == 0 || self.max_field_cells == 0 {
            return bad("max_cells", "limits are at least 1");
        }
        Ok(())
    }
}

/// One floor's raster and its APs' fields.
#[derive(Debug, Clone)]
struct FloorFields {
    floor: Option<i32>,
    grid: GridSpec,
    /// The term of a scan AP heard at a cell outside its field (no reference point near it
    /// heard it): `ln((1 - outlier) P0 / range + outlier / range)` with `P0` the prior's
    /// share of hearing it there; NaN where the cell has no coverage.
    ln_heard_outside: Vec<f32>,
    /// Σ over the APs whose field holds the cell of their `ln_silent`: the scan that heard
    /// none of them. NaN without coverage.
    silence: Vec<f32>,
    /// AP column -> its field (cells in raster order).
    fields: HashMap<u32, ApField>,
}

/// Each floor's AP signal fields, learned from a radio map ([`ScanLikelihood::fit`]); the
/// log-likelihood of a scan over a floor ([`ScanLikelihood::raster`]).
#[derive(Debug, Clone)]
pub struct ScanLikelihood {
    config: LikelihoodConfig,
    /// BSSID -> AP column, from the radio map's vocabulary.
    columns: HashMap<u64, u32>,
    floors: Vec<FloorFields>,
}

/// A scan's log-likelihood over one floor's raster.
#[derive(Debug, Clone)]
pub struct LikelihoodRaster {
    /// The raster.
    pub grid: GridSpec,
    /// `evidence_scale x ln p(scan | cell centre)`, up to a constant shared by the floor's
    /// cells; `None` where no reference point is in reach (an unknown place).
    pub log_likelihood: Vec<Option<f64>>,
}

impl LikelihoodRaster {
    /// The centre of the most likely cell (the first of equals); `None` without coverage.
    pub fn best(&self) -> Option<Point2> {
        let mut best: Option<(usize, f64)> = None;
        for (i, v) in self.log_likelihood.iter().enumerate() {
            if let Some(v) = *v
                && best.is_none_or(|(_, b)| v > b)
            {
                best = Some((i, v));
            }
        }
        best.map(|(i, _)| self.grid.centre_of_index(i))
    }

    /// The cells' probabilities normalised over the covered cells (uncovered: 0), computed
    /// from the log-likelihood relative to its maximum (no overflow); `None` without
    /// coverage.
    pub fn posterior(&self) -> Option<Vec<f64>> {
        let max = self
            .log_likelihood
            .iter()
            .flatten()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max);
        if !max.is_finite() {
            return None;
        }
        let mut p: Vec<f64> = self
            .log_likelihood
            .iter()
            .map(|v| v.map_or(0.0, |v| (v - max).exp()))
            .collect();
        let total: f64 = p.iter().sum();
        if !(total.is_finite() && total > 0.0) {
            return None;
        }
        p.iter_mut().for_each(|v| *v /= total);
        Some(p)
    }
}

/// A walk's device RSS offset, learned online from its scans' residuals at their fixes
/// ([`ScanLikelihood::rss_residual`]): their sum shrunk towards 0 by `prior_scans` scans of
/// residual 0 (one scan does not move it far), clamped to `±max_db`. A phone reading 6 dB
/// lower than the survey phones gets an offset near -6 dB after a few scans; the likelihood
/// then compares its readings with the fields 6 dB higher.
///
/// ```
/// use wipdr_fingerprint::likelihood::RssOffsetEstimate;
/// let mut e = RssOffsetEstimate::new(4.0, 20.0);
/// for _ in 0..36 {
///     e.observe(-6.0);
/// }
/// assert!((e.offset_db() + 5.4).abs() < 1e-9); // 36 x -6 / (36 + 4)
/// e.observe(f64::NAN); // refused
/// assert!((e.offset_db() + 5.4).abs() < 1e-9);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RssOffsetEstimate {
    sum: f64,
    scans: f64,
    prior_scans: f64,
    max_db: f64,
}

impl RssOffsetEstimate {
    /// An estimate at 0 dB, shrunk by `prior_scans` (at least 1) and clamped to `±max_db`.
    pub fn new(prior_scans: f64, max_db: f64) -> Self {
        let ok = |v: f64, least: f64| if v.is_finite() { v.max(least) } else { least };
        Self {
            sum: 0.0,
            scans: 0.0,
            prior_scans: ok(prior_scans, 1.0),
            max_db: ok(max_db, 0.0),
        }
    }

    /// Adds one scan's residual, dB (a non-finite one is ignored).
    pub fn observe(&mut self, residual_db: f64) {
        if residual_db.is_finite() {
            self.sum += residual_db;
            self.scans += 1.0;
        }
    }

    /// The current offset, dB.
    pub fn offset_db(&self) -> f64 {
        (self.sum / (self.scans + self.prior_scans)).clamp(-self.max_db, self.max_db)
    }
}

/// Per-AP accumulators of one cell while fitting.
#[derive(Debug, Clone, Copy, Default)]
struct Acc {
    /// Whether the cell is in the current AP's list of touched cells.
    touched: bool,
    heard_weight: f64,
    mean_sum: f64,
    square_sum: f64,
}

impl ScanLikelihood {
    /// Learns every floor's AP fields from `map` (its reference points' floors; points
    /// without a floor form one floor of their own). Errors: an invalid config, an empty
    /// map, a raster or the fields over their limits (named), non-finite positions.
    pub fn fit(map: &RadioMap, config: &LikelihoodConfig) -> Result<Self, FingerprintError> {
        config.check()?;
        if map.is_empty() {
            return Err(FingerprintError::EmptyMap);
        }
        let mut by_floor: Vec<(Option<i32>, Vec<usize>)> = Vec::new();
        for (i, p) in map.points().iter().enumerate() {
            if !(p.position.x.is_finite() && p.position.y.is_finite()) {
                return Err(FingerprintError::InvalidInput(format!(
                    "reference point {i}: non-finite position"
                )));
            }
            match by_floor.iter_mut().find(|(f, _)| *f == p.floor) {
                Some((_, list)) => list.push(i),
                None => by_floor.push((p.floor, vec![i])),
            }
        }
        by_floor.sort_by_key(|(f, _)| *f);
        let mut floors = Vec::with_capacity(by_floor.len());
        let mut field_cells = 0usize;
        for (floor, points) in by_floor {
            let f = fit_floor(map, config, floor, &points, &mut field_cells)?;
            tracing::debug!(
                ?floor,
                cells = f.grid.len(),
                aps = f.fields.len(),
                "scan likelihood fields"
            );
            floors.push(f);
        }
        let columns = (0..map.n_aps())
            .filter_map(|j| {
                let b = map.vocabulary().bssid(j)?;
                Some((b.0, u32::try_from(j).ok()?))
            })
            .collect();
        Ok(Self {
            config: config.clone(),
            columns,
            floors,
        })
    }

    /// The settings it was fit with.
    pub fn config(&self) -> &LikelihoodConfig {
        &self.config
    }

    /// The floors it has fields for.
    pub fn floors(&self) -> impl Iterator<Item = Option<i32>> + '_ {
        self.floors.iter().map(|f| f.floor)
    }

    /// The log-likelihood of `scan` over `floor`'s raster, the device's RSS offset
    /// `offset_db` removed from every reading; `None` for a floor without fields. A scan of
    /// APs the map never heard is flat over the covered cells.
    pub fn raster(
        &self,
        floor: Option<i32>,
        scan: &WifiScan,
        offset_db: f64,
    ) -> Option<LikelihoodRaster> {
        let f = self.floors.iter().find(|f| f.floor == floor)?;
        let (aps, beyond) = self.scan_aps(scan);
        // Every scan AP starts as heard outside its field; the cells of its field then trade
        // that term and its silence for the heard density.
        let k = aps.len() as f64;
        let mut ll: Vec<f64> = f
            .silence
            .iter()
            .zip(&f.ln_heard_outside)
            .map(|(&s, &h)| f64::from(s) + k * f64::from(h))
            .collect();
        for (column, rss) in aps {
            if let Some(field) = f.fields.get(&column) {
                field.add_heard(&mut ll, &f.ln_heard_outside, |c, outside| {
                    self.heard_in_field(c, outside, rss - offset_db)
                });
            }
        }
        // The APs the scan heard past the cap: not scored, and not silent either.
        for column in beyond {
            if let Some(field) = f.fields.get(&column) {
                field.remove_silence(&mut ll);
            }
        }
        let scale = self.config.evidence_scale;
        let log_likelihood = ll
            .into_iter()
            .map(|v| v.is_finite().then_some(v * scale))
            .collect();
        Some(LikelihoodRaster {
            grid: f.grid,
            log_likelihood,
        })
    }

    /// The scan's likelihood over `floor` relative to its best cell, in the form the
    /// filters read ([`WifiLikelihood`]): [`ScanLikelihood::raster`] exponentiated. `floor`
    /// `None` on a model of one floor means that floor. `None` for a floor without fields or
    /// a scan no cell of the floor scores.
    pub fn relative(
        &self,
        floor: Option<i32>,
        scan: &WifiScan,
        offset_db: f64,
    ) -> Option<WifiLikelihood> {
        let raster = self.raster(self.resolve_floor(floor), scan, offset_db)?;
        WifiLikelihood::from_log(
            raster.grid,
            &raster.log_likelihood,
            self.config.unknown_reach_m,
        )
    }

    /// `floor` as the fields know it: `None` on a model of one floor means that floor.
    fn resolve_floor(&self, floor: Option<i32>) -> Option<i32> {
        match (floor, self.floors.as_slice()) {
            (None, [only]) => only.floor,
            _ => floor,
        }
    }

    /// The device's RSS offset as one scan at `p` on `floor` shows it: the median of the
    /// scan's scored readings minus the field's mean RSS at `p`'s cell, over the APs whose
    /// field holds that cell; `None` with fewer than three such APs, off the raster or for
    /// a floor without fields. What [`RssOffsetEstimate`] averages over a walk.
    pub fn rss_residual(&self, floor: Option<i32>, p: Point2, scan: &WifiScan) -> Option<f64> {
        let floor = self.resolve_floor(floor);
        let f = self.floors.iter().find(|f| f.floor == floor)?;
        let cell = u32::try_from(f.grid.index_of(p)?).ok()?;
        let (aps, _) = self.scan_aps(scan);
        let mut residuals: Vec<f64> = aps
            .iter()
            .filter_map(|(column, rss)| {
                let c = f.fields.get(column)?.find(cell)?;
                Some(rss - f64::from(c.mean_dbm))
            })
            .filter(|r| r.is_finite())
            .collect();
        if residuals.len() < 3 {
            return None;
        }
        residuals.sort_by(f64::total_cmp);
        Some(wipdr_core::stats::percentile_sorted(&residuals, 50.0))
    }

    /// The log-likelihood of `scan` at `p` on `floor`: its cell's value in
    /// [`ScanLikelihood::raster`] (the same bits), at the cost of one look-up per scan AP
    /// instead of a pass over the floor; `None` off the raster, without coverage there, or
    /// for a floor without fields.
    pub fn at(
        &self,
        floor: Option<i32>,
        p: Point2,
        scan: &WifiScan,
        offset_db: f64,
    ) -> Option<f64> {
        let f = self.floors.iter().find(|f| f.floor == floor)?;
        let i = f.grid.index_of(p)?;
        let cell = u32::try_from(i).ok()?;
        // The raster's sum at one cell, in its order: each AP's field is sorted by cell.
        let in_field = |column: &u32| f.fields.get(column)?.find(cell);
        let (aps, beyond) = self.scan_aps(scan);
        let k = aps.len() as f64;
        let mut v = f64::from(f.silence[i]) + k * f64::from(f.ln_heard_outside[i]);
        for (column, rss) in &aps {
            if let Some(c) = in_field(column) {
                v += self.heard_in_field(c, f.ln_heard_outside[i], rss - offset_db);
            }
        }
        for column in &beyond {
            if let Some(c) = in_field(column) {
                v -= f64::from(c.ln_silent);
            }
        }
        v.is_finite().then_some(v * self.config.evidence_scale)
    }

    /// What a scan AP heard at `r` dBm (offset removed) adds at a cell of its field, beyond
    /// the baseline of that cell (its silence and the heard-outside term, traded for the
    /// heard density).
    /// `ln_heard_outside` is the cell's [`FloorFields::ln_heard_outside`].
    fn heard_in_field(&self, c: &FieldCell, ln_heard_outside: f32, r: f64) -> f64 {
        let outlier_density = self.config.outlier / RSS_RANGE_DB;
        let d = r - f64::from(c.mean_dbm);
        let gaussian = (f64::from(c.ln_scale) - d * d * f64::from(c.inv_two_var)).exp();
        (gaussian + outlier_density).ln() - f64::from(c.ln_silent) - f64::from(ln_heard_outside)
    }

    /// The scan's strongest `max_scan_aps` APs the map knows, as `(column, RSS)` (valid
    /// fresh readings, one per AP: the strongest), and the columns of the other APs it heard
    /// (past the cap, stale or with an invalid reading: heard, so not silent, but not
    /// scored).
    fn scan_aps(&self, scan: &WifiScan) -> (Vec<(u32, f64)>, Vec<u32>) {
        let mut aps: Vec<(u32, f64)> = scan
            .entries
            .iter()
            .filter_map(|e| {
                let column = *self.columns.get(&e.bssid.0)?;
                let fresh = self
                    .config
                    .max_entry_age_ms
                    .is_none_or(|max| e.age_ms(scan.t) <= max);
                let rss = if fresh && crate::radio_map::is_valid_rssi(e.rssi_dbm) {
                    e.rssi_dbm
                } else {
                    f64::NEG_INFINITY
                };
                Some((column, rss))
            })
            .collect();
        // One reading an AP (its strongest), then strongest first.
        aps.sort_by(|a, b| a.0.cmp(&b.0).then(b.1.total_cmp(&a.1)));
        aps.dedup_by_key(|a| a.0);
        aps.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        let scored = aps
            .iter()
            .filter(|a| a.1.is_finite())
            .count()
            .min(self.config.max_scan_aps);
        let beyond = aps[scored..].iter().map(|a| a.0).collect();
        aps.truncate(scored);
        (aps, beyond)
    }
}

fn fit_floor(
    map: &RadioMap,
    config: &LikelihoodConfig,
    floor: Option<i32>,
    points: &[usize],
    field_cells: &mut usize,
) -> Result<FloorFields, FingerprintError> {
    let (mut lo, mut hi) = (
        Point2::new(f64::INFINITY, f64::INFINITY),
        Point2::new(f64::NEG_INFINITY, f64::NEG_INFINITY),
    );
    for &i in points {
        let p = map.point(i).position;
        lo = Point2::new(lo.x.min(p.x), lo.y.min(p.y));
        hi = Point2::new(hi.x.max(p.x), hi.y.max(p.y));
    }
    let margin = config.support_m;
    let grid = GridSpec::covering(
        Point2::new(lo.x - margin, lo.y - margin),
        Point2::new(hi.x + margin, hi.y + margin),
        config.cell_m,
        config.max_cells,
    )
    .map_err(|e| {
        FingerprintError::limit_exceeded(
            format!("the scan likelihood's raster of floor {floor:?}: {e}"),
            "likelihood.max_cells",
            config.max_cells,
            "raise likelihood.cell_m or likelihood.max_cells",
        )
    })?;
    let n = grid.len();
    let inv_two_kernel = 1.0 / (2.0 * config.kernel_m * config.kernel_m);
    let reach = support_cells(config)?;
    // Each point's cells in reach and their weights.
    let weights_of = |i: usize| -> Vec<(usize, f64)> {
        let p = map.point(i).position;
        let mut out = Vec::new();
        let (Some(c0), Some(r0)) = (grid.col_of(p.x), grid.row_of(p.y)) else {
            return out;
        };
        let (cols, rows) = grid.dims();
        for r in r0.saturating_sub(reach)..=(r0 + reach).min(rows - 1) {
            for c in c0.saturating_sub(reach)..=(c0 + reach).min(cols - 1) {
                let d2 = (grid.centre(c, r) - p).norm_squared();
                if d2 <= config.support_m * config.support_m {
                    out.push((grid.index(c, r), (-d2 * inv_two_kernel).exp()));
                }
            }
        }
        out
    };
    // Each point's cells in reach, and per AP the points that heard it (in point order, so
    // that every cell's sums add the points in the same order whatever the AP).
    let mut coverage = vec![0.0f64; n];
    let mut reach_of: Vec<Vec<(usize, f64)>> = Vec::with_capacity(points.len());
    let mut heard_by: std::collections::BTreeMap<u32, Vec<(usize, f64, f64)>> =
        std::collections::BTreeMap::new();
    for (k, &i) in points.iter().enumerate() {
        let cells = weights_of(i);
        for &(c, w) in &cells {
            coverage[c] += w;
        }
        reach_of.push(cells);
        for (j, mean) in map.heard(i) {
            let Ok(ap) = u32::try_from(j) else { continue };
            let spread = f64::from(map.spread(i, j));
            heard_by
                .entry(ap)
                .or_default()
                .push((k, f64::from(mean), spread));
        }
    }
    let (prior_w, prior) = (config.prior_weight, config.detection_prior);
    let (keep, outlier_density) = (1.0 - config.outlier, config.outlier / RSS_RANGE_DB);
    let ln_heard_outside: Vec<f32> = coverage
        .iter()
        .map(|&w| {
            if w > 0.0 {
                let p0 = prior_w * prior / (w + prior_w);
                (keep * p0 / RSS_RANGE_DB + outlier_density).ln() as f32
            } else {
                f32::NAN
            }
        })
        .collect();
    let mut silence: Vec<f32> = coverage
        .iter()
        .map(|&w| if w > 0.0 { 0.0 } else { f32::NAN })
        .collect();
    let min_var = config.min_sd_db * config.min_sd_db;
    let mut fields = HashMap::with_capacity(heard_by.len());
    // One AP at a time into a dense scratch over the floor's cells (no hashing per cell);
    // the APs in column order, so that each cell's silence sums them in a fixed order.
    let mut scratch = vec![Acc::default(); n];
    let mut touched: Vec<usize> = Vec::new();
    for (ap, heard) in heard_by {
        touched.clear();
        for &(k, m, spread) in &heard {
            for &(c, w) in &reach_of[k] {
                let a = &mut scratch[c];
                if !a.touched {
                    a.touched = true;
                    touched.push(c);
                }
                a.heard_weight += w;
                a.mean_sum += w * m;
                a.square_sum += w * (m * m + spread * spread);
            }
        }
        touched.sort_unstable();
        let cells: Vec<(u32, Acc)> = touched
            .iter()
            .filter_map(|&c| {
                let a = std::mem::take(&mut scratch[c]);
                Some((u32::try_from(c).ok()?, a))
            })
            .collect();
        *field_cells += cells.len();
        if *field_cells > config.max_field_cells {
            return Err(FingerprintError::limit_exceeded(
                format!("the scan likelihood's AP fields (over {field_cells} cells)"),
                "likelihood.max_field_cells",
                config.max_field_cells,
                "raise likelihood.cell_m or likelihood.max_field_cells, or lower support_m",
            ));
        }
        let mut list: Vec<FieldCell> = cells
            .into_iter()
            .filter(|(_, a)| a.heard_weight > 0.0)
            .map(|(cell, a)| {
                let w = coverage[cell as usize];
                let p = (a.heard_weight + prior_w * prior) / (w + prior_w);
                let mean = a.mean_sum / a.heard_weight;
                let var = (a.square_sum / a.heard_weight - mean * mean).max(0.0) + min_var;
                let ln_scale = (keep * p).ln() - 0.5 * (2.0 * std::f64::consts::PI * var).ln();
                let ln_silent = (1.0 - keep * p).max(f64::MIN_POSITIVE).ln();
                FieldCell {
                    cell,
                    ln_scale: ln_scale as f32,
                    mean_dbm: mean as f32,
                    inv_two_var: (0.5 / var) as f32,
                    ln_silent: ln_silent as f32,
                }
            })
            .collect();
        list.sort_by_key(|c| c.cell);
        for c in &list {
            silence[c.cell as usize] += c.ln_silent;
        }
        fields.insert(ap, ApField::new(list));
    }
    Ok(FloorFields {
        floor,
        grid,
        ln_heard_outside,
        silence,
        fields,
    })
}

/// The support radius in cells (checked: never a wrapped or huge count).
fn support_cells(config: &LikelihoodConfig) -> Result<usize, FingerprintError> {
    wipdr_core::grid::checked_usize((config.support_m / config.cell_m).ceil(), 1 << 16).ok_or_else(
        || {
            FingerprintError::InvalidConfig(wipdr_core::ConfigError::new(
                "likelihood.support_m",
                "more than 65,536 cells of likelihood.cell_m",
            ))
        },
    )
}

#[cfg(test)]
mod tests;

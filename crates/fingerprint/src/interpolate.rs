//! Radio-map interpolation (paper 004 §5.3, Table 2): a denser radio map from the surveyed
//! fingerprints.
//!
//! Paper 004 surveys with a phone scanning at 0.25 Hz and "improves the spatial resolution of
//! the fingerprint database by interpolation" (5.77 m -> 1.98 m mean error on its data). The
//! paper does not say how; two ways are implemented here, each optional:
//!
//! - **Along the walk** ([`AlongWalkConfig`], [`along_walk`]): between two consecutive scans
//!   of one training walk that are close in time (`max_gap_ms`) and space (`max_gap_m`),
//!   fingerprints are inserted every `spacing_m` metres of the straight line between them. At
//!   time fraction `f` the position is the walk's waypoint interpolation at
//!   `t = t_a + f (t_b - t_a)` and each AP heard in **both** scans gets
//!   `(1 - f) r_a + f r_b`; APs heard in only one scan are left out.
//! - **Spatially** ([`SpatialConfig`], [`spatial`]): each AP's RSS is interpolated onto a square
//!   lattice (`cell_m`) with a Gaussian or inverse-distance kernel over the measured
//!   fingerprints within `radius_m`. A lattice point is created only if at least
//!   `min_sources` measured fingerprints lie within `radius_m` of it, so **no created
//!   fingerprint lies farther than `radius_m` from a measured one**; an AP is heard at the
//!   point when the kernel weight of the sources that heard it is at least `min_heard_share`
//!   of the total, and its RSS is the kernel-weighted mean over those sources.
//!
//! ## What an interpolated reference point holds
//!
//! - [`ReferencePoint::scans`] is **0**: no scan was taken there (measured points have >= 1).
//!   Interpolated points are never sources of spatial interpolation.
//! - The sample count of each heard AP is **1**, the smallest a heard entry can have in a
//!   [`RadioMap`]: an interpolated value is worth at most one measurement.
//! - The spread of each heard AP is the **kernel-weighted standard deviation of the source
//!   values** it was made from (along the walk, `sqrt(f (1 - f)) |r_a - r_b|`): how much the
//!   measurements it stands for disagree, not a sample standard deviation.
//!
//! ```
//! use wipdr_core::Point2;
//! use wipdr_fingerprint::interpolate::{SparsePrint, SpatialConfig, spatial};
//! let sources = vec![
//!     SparsePrint { position: Point2::new(0.0, 0.0), rss: vec![(0, -50.0)] },
//!     SparsePrint { position: Point2::new(4.0, 0.0), rss: vec![(0, -70.0)] },
//! ];
//! let cfg = SpatialConfig { cell_m: 2.0, radius_m: 2.5, min_sources: 2, ..Default::default() };
//! let (made, _) = spatial(&sources, &cfg).unwrap();
//! // Only the lattice point (2, 0) has both sources within 2.5 m: the mean of -50 and -70.
//! assert_eq!(made.len(), 1);
//! assert_eq!(made[0].position, Point2::new(2.0, 0.0));
//! assert!((made[0].rss[0].1 + 60.0).abs() < 1e-4);
//! ```

use crate::FingerprintError;
use crate::radio_map::{
    MAX_VALID_RSSI_DBM, MIN_VALID_RSSI_DBM, RadioMap, ReferencePoint, TableBudget, is_valid_rssi,
};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::collections::{HashMap, HashSet};
use wipdr_core::{Point2, TimestampMs};

/// Which interpolations a radio-map builder runs; both off by default.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
#[serde(default, deny_unknown_fields)]
pub struct InterpolationConfig {
    /// Fingerprints between consecutive scans of a training walk; `None` = off.
    pub along_walk: Option<AlongWalkConfig>,
    /// Kernel interpolation onto a lattice near measured fingerprints; `None` = off.
    pub spatial: Option<SpatialConfig>,
}

impl InterpolationConfig {
    /// Checks every enabled part.
    pub fn validate(&self) -> Result<(), FingerprintError> {
        if let Some(a) = &self.along_walk {
            a.validate()?;
        }
        if let Some(s) = &self.spatial {
            s.validate()?;
        }
        Ok(())
    }
}

/// Most fingerprints [`AlongWalkConfig`] may insert between two scans (`max_gap_m /
/// spacing_m`): a spacing of a nanometre would otherwise allocate without bound.
pub const MAX_POINTS_PER_PAIR: f64 = 10_000.0;

/// Interpolation between consecutive scans of one walk.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AlongWalkConfig {
    /// Distance between inserted fingerprints along the chord between two scans, metres.
    pub spacing_m: f64,
    /// Two scans farther apart in time are not bridged, ms.
    pub max_gap_ms: i64,
    /// Two scans farther apart in space are not bridged, metres. Every inserted point lies
    /// within `max_gap_m / 2` of one of its two scans (points that would not are skipped).
    pub max_gap_m: f64,
    /// Minimum number of APs heard in both scans for the pair to be bridged.
    pub min_shared_aps: usize,
}

impl Default for AlongWalkConfig {
    fn default() -> Self {
        Self {
            spacing_m: 1.0,
            max_gap_ms: 10_000,
            max_gap_m: 10.0,
            min_shared_aps: 3,
        }
    }
}

impl AlongWalkConfig {
    /// Checks the values (positive, finite).
    pub fn validate(&self) -> Result<(), FingerprintError> {
        if !(self.spacing_m.is_finite() && self.spacing_m > 0.0) {
            return Err(invalid(
                "along_walk.spacing_m",
                format!("must be positive, got {}", self.spacing_m),
            ));
        }
        if !(self.max_gap_m.is_finite() && self.max_gap_m > 0.0) {
            return Err(invalid(
                "along_walk.max_gap_m",
                format!("must be positive, got {}", self.max_gap_m),
            ));
        }
        if self.max_gap_ms <= 0 {
            return Err(invalid(
                "along_walk.max_gap_ms",
                format!("must be positive, got {}", self.max_gap_ms),
            ));
        }
        if self.max_gap_m / self.spacing_m > MAX_POINTS_PER_PAIR {
            return Err(invalid(
                "along_walk.spacing_m",
                format!(
                    "=  {} inserts up to {:.0} points between two scans \
                 (max_gap_m / spacing_m); the limit is {MAX_POINTS_PER_PAIR}: raise spacing_m",
                    self.spacing_m,
                    self.max_gap_m / self.spacing_m
                ),
            ));
        }
        Ok(())
    }
}

/// The kernel of spatial interpolation: the weight of a source at distance `d`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Kernel {
    /// `exp(-d^2 / (2 sigma^2))`.
    Gaussian {
        /// Width, metres.
        sigma_m: f64,
    },
    /// Shepard's inverse distance `1 / max(d, 0.01 m)^power`.
    InverseDistance {
        /// Exponent.
        power: f64,
    },
}

impl Default for Kernel {
    fn default() -> Self {
        Kernel::Gaussian { sigma_m: 2.0 }
    }
}

/// Distances below this count as this in the inverse-distance kernel (no division by zero).
pub const IDW_MIN_DISTANCE_M: f64 = 0.01;

impl Kernel {
    /// Weight of a source at distance `d` (metres, >= 0). Finite and positive for valid
    /// kernels.
    pub fn weight(&self, d: f64) -> f64 {
        match *self {
            Kernel::Gaussian { sigma_m } => (-d * d / (2.0 * sigma_m * sigma_m)).exp(),
            Kernel::InverseDistance { power } => IDW_MIN_DISTANCE_M.max(d).powf(-power),
        }
    }

    fn validate(&self) -> Result<(), FingerprintError> {
        match *self {
            Kernel::Gaussian { sigma_m } if !(sigma_m.is_finite() && sigma_m > 0.0) => {
                Err(invalid(
                    "spatial.kernel.sigma_m",
                    format!("must be positive, got {sigma_m}"),
                ))
            }
            Kernel::InverseDistance { power } if !(power.is_finite() && power >= 0.0) => {
                Err(invalid(
                    "spatial.kernel.power",
                    format!("must be finite and >= 0, got {power}"),
                ))
            }
            _ => Ok(()),
        }
    }
}

/// Kernel interpolation of each AP's RSS onto a lattice near the measured fingerprints.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SpatialConfig {
    /// Lattice spacing, metres (points at integer multiples of it).
    pub cell_m: f64,
    /// Sources within this distance of a lattice point are used; farther points are never
    /// created. Metres.
    pub radius_m: f64,
    /// The kernel.
    pub kernel: Kernel,
    /// Minimum number of measured fingerprints within `radius_m` for a point to be created.
    pub min_sources: usize,
    /// An AP is heard at a created point when the kernel weight of the sources that heard it
    /// is at least this share of all sources' weight (0 < share <= 1).
    pub min_heard_share: f64,
    /// No point is created closer than this to a measured fingerprint (it would only repeat
    /// it), metres; 0 disables.
    pub min_gap_m: f64,
    /// Refuse to create more points than this (memory guard): an error, not a silent cut.
    pub max_points: usize,
}

/// Hard ceiling of [`SpatialConfig::max_points`]: 2 M lattice points (a 0.1 m lattice over
/// 140 m x 140 m). The points a lattice may add are also bounded by the radio map's table
/// budget ([`crate::radio_map::RadioMap::set_table_budget`]), checked as the lattice grows.
pub const MAX_SPATIAL_POINTS_CEILING: usize = 2_000_000;

impl Default for SpatialConfig {
    fn default() -> Self {
        Self {
            cell_m: 2.0,
            radius_m: 4.0,
            kernel: Kernel::default(),
            min_sources: 2,
            min_heard_share: 0.5,
            min_gap_m: 0.0,
            max_points: 200_000,
        }
    }
}

impl SpatialConfig {
    /// Checks the values.
    pub fn validate(&self) -> Result<(), FingerprintError> {
        if !(self.cell_m.is_finite() && self.cell_m > 0.0) {
            return Err(invalid(
                "spatial.cell_m",
                format!("must be positive, got {}", self.cell_m),
            ));
        }
        if !(self.radius_m.is_finite() && self.radius_m > 0.0) {
            return Err(invalid(
                "spatial.radius_m",
                format!("must be positive, got {}", self.radius_m),
            ));
        }
        if !(self.min_heard_share > 0.0 && self.min_heard_share <= 1.0) {
            return Err(invalid(
                "spatial.min_heard_share",
                format!("must be in (0, 1], got {}", self.min_heard_share),
            ));
        }
        if !(self.min_gap_m.is_finite() && self.min_gap_m >= 0.0) {
            return Err(invalid(
                "spatial.min_gap_m",
                format!("must be finite and >= 0, got {}", self.min_gap_m),
            ));
        }
        if self.min_sources == 0 {
            return Err(invalid("spatial.min_sources", "must be >= 1".into()));
        }
        if !(1..=MAX_SPATIAL_POINTS_CEILING).contains(&self.max_points) {
            return Err(invalid(
                "spatial.max_points",
                format!(
                    "must be in 1..={MAX_SPATIAL_POINTS_CEILING} (each lattice \
                 point is a row of the radio map's dense table), got {}",
                    self.max_points
                ),
            ));
        }
        self.kernel.validate()
    }
}

fn invalid(path: impl Into<String>, reason: String) -> FingerprintError {
    FingerprintError::InvalidConfig(wipdr_core::ConfigError::new(path, reason))
}

/// A fingerprint in sparse form: position and the heard APs as `(column, dBm)`, sorted by
/// column.
#[derive(Debug, Clone, PartialEq)]
pub struct SparsePrint {
    /// Position in the floor frame, metres.
    pub position: Point2,
    /// Heard APs `(column, dBm)`, sorted by column, no column twice.
    pub rss: Vec<(usize, f32)>,
}

/// One labelled scan of a walk, as [`along_walk`] sees it.
#[derive(Debug, Clone, PartialEq)]
pub struct WalkScan {
    /// Label time, ms.
    pub t: TimestampMs,
    /// Position and heard APs.
    pub print: SparsePrint,
}

/// A created fingerprint: position and, per heard AP, `(column, mean dBm, spread dB)`.
#[derive(Debug, Clone, PartialEq)]
pub struct InterpolatedPrint {
    /// Position in the floor frame, metres.
    pub position: Point2,
    /// Heard APs `(column, mean dBm, spread dB)`, sorted by column.
    pub rss: Vec<(usize, f32, f32)>,
    /// The index (in the sources given) of the nearest source.
    pub nearest_source: usize,
}

/// What an interpolation made and skipped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub struct InterpolationReport {
    /// Consecutive scan pairs looked at (along the walk).
    pub pairs: usize,
    /// Pairs not bridged: too far apart in time (or with equal label times).
    pub pairs_too_long_ms: usize,
    /// Pairs not bridged: too far apart in space.
    pub pairs_too_far_m: usize,
    /// Pairs not bridged: fewer than `min_shared_aps` APs heard in both.
    pub pairs_too_few_shared: usize,
    /// Inserted points skipped because the walk's path strayed more than `max_gap_m / 2`
    /// from both scans (or the waypoints gave no position).
    pub along_walk_off_chord: usize,
    /// Fingerprints created along walks.
    pub along_walk_points: usize,
    /// Lattice points within `radius_m` of a source.
    pub lattice_candidates: usize,
    /// Lattice points skipped: fewer than `min_sources` sources.
    pub lattice_too_few_sources: usize,
    /// Lattice points skipped: a source closer than `min_gap_m`.
    pub lattice_too_close: usize,
    /// Lattice points skipped: no AP reached `min_heard_share`.
    pub lattice_nothing_heard: usize,
    /// Fingerprints created on the lattice.
    pub spatial_points: usize,
}

impl InterpolationReport {
    /// The counts of two reports added (runs on several floors).
    pub fn add(&self, o: &Self) -> Self {
        Self {
            pairs: self.pairs + o.pairs,
            pairs_too_long_ms: self.pairs_too_long_ms + o.pairs_too_long_ms,
            pairs_too_far_m: self.pairs_too_far_m + o.pairs_too_far_m,
            pairs_too_few_shared: self.pairs_too_few_shared + o.pairs_too_few_shared,
            along_walk_off_chord: self.along_walk_off_chord + o.along_walk_off_chord,
            along_walk_points: self.along_walk_points + o.along_walk_points,
            lattice_candidates: self.lattice_candidates + o.lattice_candidates,
            lattice_too_few_sources: self.lattice_too_few_sources + o.lattice_too_few_sources,
            lattice_too_close: self.lattice_too_close + o.lattice_too_close,
            lattice_nothing_heard: self.lattice_nothing_heard + o.lattice_nothing_heard,
            spatial_points: self.spatial_points + o.spatial_points,
        }
    }
}

/// Fingerprints between consecutive scans of **one** walk (`scans` in time order).
///
/// `position_at(t)` gives the walk's position at a label time (the waypoint interpolation);
/// where it gives `None` the chord between the two scans is used. Points whose position lies
/// farther than `max_gap_m / 2` from both scans are skipped and counted. The returned
/// `nearest_source` indexes `scans`.
pub fn along_walk(
    scans: &[WalkScan],
    position_at: impl Fn(TimestampMs) -> Option<Point2>,
    cfg: &AlongWalkConfig,
    report: &mut InterpolationReport,
) -> Result<Vec<InterpolatedPrint>, FingerprintError> {
    cfg.validate()?;
    let mut out = Vec::new();
    let half_gap = cfg.max_gap_m / 2.0;
    for (ia, pair) in scans.windows(2).enumerate() {
        let (a, b) = (&pair[0], &pair[1]);
        report.pairs += 1;
        let dt = b.t - a.t;
        if dt > cfg.max_gap_ms || dt <= 0 {
            report.pairs_too_long_ms += 1;
            continue;
        }
        let chord = b.print.position - a.print.position;
        let dist = chord.norm();
        if dist.is_nan() || dist > cfg.max_gap_m {
            report.pairs_too_far_m += 1;
            continue;
        }
        let shared = shared_aps(&a.print.rss, &b.print.rss);
        if shared.len() < cfg.min_shared_aps.max(1) {
            report.pairs_too_few_shared += 1;
            continue;
        }
        let segments = (dist / cfg.spacing_m).ceil() as usize;
        for k in 1..segments {
            let f = k as f64 / segments as f64;
            let t = a.t + (f * dt as f64).round() as i64;
            let position = position_at(t).unwrap_or(a.print.position + chord * f);
            let (da, db) = (
                (position - a.print.position).norm(),
                (position - b.print.position).norm(),
            );
            let nearest = da.min(db);
            if nearest.is_nan() || nearest > half_gap {
                report.along_walk_off_chord += 1;
                continue;
            }
            let w = f as f32;
            let s = (f * (1.0 - f)).sqrt() as f32;
            let rss = shared
                .iter()
                .map(|&(j, ra, rb)| (j, clamp_rssi((1.0 - w) * ra + w * rb), s * (ra - rb).abs()))
                .collect();
            out.push(InterpolatedPrint {
                position,
                rss,
                nearest_source: if da <= db { ia } else { ia + 1 },
            });
        }
    }
    report.along_walk_points += out.len();
    Ok(out)
}

/// APs heard in both sorted lists: `(column, rss in a, rss in b)`.
fn shared_aps(a: &[(usize, f32)], b: &[(usize, f32)]) -> Vec<(usize, f32, f32)> {
    let (mut i, mut j) = (0, 0);
    let mut out = Vec::new();
    while i < a.len() && j < b.len() {
        match a[i].0.cmp(&b[j].0) {
            std::cmp::Ordering::Less => i += 1,
            std::cmp::Ordering::Greater => j += 1,
            std::cmp::Ordering::Equal => {
                out.push((a[i].0, a[i].1, b[j].1));
                i += 1;
                j += 1;
            }
        }
    }
    out
}

fn clamp_rssi(v: f32) -> f32 {
    v.clamp(MIN_VALID_RSSI_DBM as f32, MAX_VALID_RSSI_DBM as f32)
}

/// Kernel interpolation of the sources' RSS onto the lattice `cell_m * (i, j)`, at lattice
/// points with at least `min_sources` sources within `radius_m` (and none closer than
/// `min_gap_m`). Deterministic: points come in lattice order (by `i`, then `j`).
pub fn spatial(
    sources: &[SparsePrint],
    cfg: &SpatialConfig,
) -> Result<(Vec<InterpolatedPrint>, InterpolationReport), FingerprintError> {
    spatial_within(sources, cfg, None)
}

/// Room for new rows in a radio map's dense table: its budget, its points and APs.
#[derive(Clone, Copy)]
struct Room {
    budget: TableBudget,
    points: usize,
    aps: usize,
}

/// [`spatial`], the lattice also bounded by the table budget of the map it will be added to.
fn spatial_within(
    sources: &[SparsePrint],
    cfg: &SpatialConfig,
    room: Option<Room>,
) -> Result<(Vec<InterpolatedPrint>, InterpolationReport), FingerprintError> {
    cfg.validate()?;
    let mut report = InterpolationReport::default();
    let finite: Vec<usize> = (0..sources.len())
        .filter(|&i| {
            let p = sources[i].position;
            p.x.is_finite() && p.y.is_finite()
        })
        .collect();
    if finite.len() != sources.len() {
        return Err(FingerprintError::InvalidInput(format!(
            "{} interpolation sources have a non-finite position",
            sources.len() - finite.len()
        )));
    }
    // Buckets of side radius_m: the sources within radius of a point lie in its 3x3 buckets.
    let r = cfg.radius_m;
    let bucket_of = |p: Point2| ((p.x / r).floor() as i64, (p.y / r).floor() as i64);
    let mut buckets: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    for (i, s) in sources.iter().enumerate() {
        buckets.entry(bucket_of(s.position)).or_default().push(i);
    }
    // Candidate lattice points: within radius of at least one source.
    let c = cfg.cell_m;
    let per_source = ((2.0 * r / c).ceil() + 1.0).powi(2);
    if per_source > cfg.max_points as f64 {
        return Err(invalid(
            "spatial.max_points",
            format!(
                "spatial interpolation: radius {r} m over cells of {c} m gives {per_source} lattice \
             points per source, over max_points = {}",
                cfg.max_points
            ),
        ));
    }
    let mut lattice: HashSet<(i64, i64)> = HashSet::new();
    for s in sources {
        let p = s.position;
        let (i0, i1) = (
            ((p.x - r) / c).ceil() as i64,
            ((p.x + r) / c).floor() as i64,
        );
        let (j0, j1) = (
            ((p.y - r) / c).ceil() as i64,
            ((p.y + r) / c).floor() as i64,
        );
        for i in i0..=i1 {
            for j in j0..=j1 {
                let q = Point2::new(i as f64 * c, j as f64 * c);
                if (q - p).norm() <= r {
                    lattice.insert((i, j));
                }
            }
            if lattice.len() > cfg.max_points {
                return Err(invalid(
                    "spatial.max_points",
                    format!(
                        "spatial interpolation would create over max_points = {} lattice points \
                     (cell {c} m, radius {r} m, {} sources)",
                        cfg.max_points,
                        sources.len()
                    ),
                ));
            }
            if let Some(room) = room {
                room.budget
                    .check(room.points.saturating_add(lattice.len()), room.aps)?;
            }
        }
    }
    let mut lattice: Vec<(i64, i64)> = lattice.into_iter().collect();
    lattice.sort_unstable();
    report.lattice_candidates = lattice.len();
    enum Outcome {
        Made(InterpolatedPrint),
        TooFew,
        TooClose,
        Nothing,
    }
    let outcomes: Vec<Outcome> = lattice
        .par_iter()
        .map(|&(i, j)| {
            let q = Point2::new(i as f64 * c, j as f64 * c);
            let (bi, bj) = bucket_of(q);
            let mut near: Vec<(usize, f64)> = Vec::new();
            for di in -1..=1 {
                for dj in -1..=1 {
                    if let Some(members) = buckets.get(&(bi + di, bj + dj)) {
                        for &k in members {
                            let d = (sources[k].position - q).norm();
                            if d <= r {
                                near.push((k, d));
                            }
                        }
                    }
                }
            }
            if near.len() < cfg.min_sources {
                return Outcome::TooFew;
            }
            near.sort_unstable_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
            if near[0].1 < cfg.min_gap_m {
                return Outcome::TooClose;
            }
            let mut total = 0f64;
            let mut heard: Vec<(usize, f64, f32)> = Vec::new();
            for &(k, d) in &near {
                let w = cfg.kernel.weight(d);
                total += w;
                heard.extend(sources[k].rss.iter().map(|&(col, v)| (col, w, v)));
            }
            if !(total > 0.0 && total.is_finite()) {
                // Gaussian weights can underflow for radius >> sigma: nothing to weigh.
                return Outcome::Nothing;
            }
            heard.sort_unstable_by_key(|h| h.0);
            let mut rss = Vec::new();
            for group in heard.chunk_by(|a, b| a.0 == b.0) {
                let w: f64 = group.iter().map(|h| h.1).sum();
                if w < cfg.min_heard_share * total || w <= 0.0 {
                    continue;
                }
                let mean = group.iter().map(|h| h.1 * f64::from(h.2)).sum::<f64>() / w;
                let var = group
                    .iter()
                    .map(|h| h.1 * (f64::from(h.2) - mean).powi(2))
                    .sum::<f64>()
                    / w;
                let mean = clamp_rssi(mean as f32);
                if is_valid_rssi(f64::from(mean)) {
                    rss.push((group[0].0, mean, var.max(0.0).sqrt() as f32));
                }
            }
            if rss.is_empty() {
                return Outcome::Nothing;
            }
            Outcome::Made(InterpolatedPrint {
                position: q,
                rss,
                nearest_source: near[0].0,
            })
        })
        .collect();
    let mut made = Vec::new();
    for o in outcomes {
        match o {
            Outcome::Made(p) => made.push(p),
            Outcome::TooFew => report.lattice_too_few_sources += 1,
            Outcome::TooClose => report.lattice_too_close += 1,
            Outcome::Nothing => report.lattice_nothing_heard += 1,
        }
    }
    report.spatial_points = made.len();
    Ok((made, report))
}

/// The measured reference points of a map (`scans > 0`) in sparse form, with their row
/// indices. Interpolated points (`scans == 0`) are left out.
pub fn measured_prints(map: &RadioMap) -> (Vec<SparsePrint>, Vec<usize>) {
    let rows: Vec<usize> = (0..map.len()).filter(|&i| map.point(i).scans > 0).collect();
    let prints = rows
        .iter()
        .map(|&i| SparsePrint {
            position: map.point(i).position,
            rss: map.heard(i).collect(),
        })
        .collect();
    (prints, rows)
}

/// Appends created fingerprints to a map as reference points with `scans = 0`, count 1 and
/// the interpolation's spread per heard AP (see the module doc). `template` gives the floor,
/// building and height of each point from its nearest source.
pub fn push_interpolated(
    map: &mut RadioMap,
    prints: &[InterpolatedPrint],
    template: impl Fn(usize) -> ReferencePoint,
) -> Result<(), FingerprintError> {
    let m = map.n_aps();
    let mut mean = vec![None; m];
    let mut counts = vec![0u16; m];
    let mut spread = vec![0f32; m];
    for p in prints {
        mean.fill(None);
        counts.fill(0);
        spread.fill(0.0);
        for &(j, v, s) in &p.rss {
            if j >= m {
                return Err(FingerprintError::DimensionMismatch {
                    expected: m,
                    found: j + 1,
                });
            }
            mean[j] = Some(v);
            counts[j] = 1;
            spread[j] = if s.is_finite() { s.max(0.0) } else { 0.0 };
        }
        let point = ReferencePoint {
            position: p.position,
            scans: 0,
            ..template(p.nearest_source)
        };
        map.push_point(point, &mean, Some((&counts, &spread)))?;
    }
    Ok(())
}

/// Adds spatially interpolated reference points to a map, from its measured points
/// ([`measured_prints`]); floor, building and height come from the nearest source.
pub fn densify_spatially(
    map: &mut RadioMap,
    cfg: &SpatialConfig,
) -> Result<InterpolationReport, FingerprintError> {
    let (sources, rows) = measured_prints(map);
    let room = map.table_budget().map(|budget| Room {
        budget,
        points: map.len(),
        aps: map.n_aps(),
    });
    let (made, report) = spatial_within(&sources, cfg, room)?;
    let points = map.points().to_vec();
    push_interpolated(map, &made, |k| points[rows[k]])?;
    tracing::debug!(?report, "spatial radio-map interpolation");
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tiny_spacing_is_refused_before_allocating() {
        let c = AlongWalkConfig {
            spacing_m: 1e-9,
            ..AlongWalkConfig::default()
        };
        let e = c.validate().unwrap_err().to_string();
        assert!(e.contains("spacing_m"), "{e}");
        assert!(AlongWalkConfig::default().validate().is_ok());
    }
    use crate::radio_map::{ApVocabulary, RadioMapConfig};
    use proptest::prelude::*;

    fn print(x: f64, y: f64, rss: &[(usize, f32)]) -> SparsePrint {
        SparsePrint {
            position: Point2::new(x, y),
            rss: rss.to_vec(),
        }
    }

    fn scan(t: i64, x: f64, rss: &[(usize, f32)]) -> WalkScan {
        WalkScan {
            t,
            print: print(x, 0.0, rss),
        }
    }

    #[test]
    fn along_walk_interpolates_shared_aps_linearly() {
        let scans = [
            scan(0, 0.0, &[(0, -50.0), (1, -80.0), (2, -60.0)]),
            scan(4_000, 4.0, &[(0, -70.0), (2, -60.0), (3, -40.0)]),
        ];
        let cfg = AlongWalkConfig {
            min_shared_aps: 1,
            ..Default::default()
        };
        let mut rep = InterpolationReport::default();
        let made = along_walk(&scans, |_| None, &cfg, &mut rep).unwrap();
        assert_eq!(made.len(), 3);
        assert_eq!(rep.along_walk_points, 3);
        for (k, p) in made.iter().enumerate() {
            let f = (k + 1) as f64 / 4.0;
            assert!((p.position.x - 4.0 * f).abs() < 1e-12);
            // Only APs 0 and 2 are heard in both.
            assert_eq!(p.rss.iter().map(|e| e.0).collect::<Vec<_>>(), vec![0, 2]);
            let want = -50.0 - 20.0 * f as f32;
            assert!((p.rss[0].1 - want).abs() < 1e-4);
            let spread = (f * (1.0 - f)).sqrt() as f32 * 20.0;
            assert!((p.rss[0].2 - spread).abs() < 1e-4);
            assert_eq!(p.rss[1], (2, -60.0, 0.0));
        }
        assert_eq!(made[0].nearest_source, 0);
        assert_eq!(made[2].nearest_source, 1);
    }

    #[test]
    fn along_walk_uses_the_walk_position_and_respects_gaps() {
        let scans = [
            scan(0, 0.0, &[(0, -50.0)]),
            scan(2_000, 2.0, &[(0, -50.0)]),
            scan(20_000, 4.0, &[(0, -50.0)]),  // too long in time
            scan(21_000, 30.0, &[(0, -50.0)]), // too far in space
            scan(22_000, 32.0, &[(1, -50.0)]), // nothing shared
        ];
        let cfg = AlongWalkConfig {
            min_shared_aps: 1,
            ..Default::default()
        };
        let mut rep = InterpolationReport::default();
        // The walk's true position is 0.5 m off the chord.
        let made = along_walk(
            &scans,
            |t| Some(Point2::new(t as f64 / 1000.0, 0.5)),
            &cfg,
            &mut rep,
        )
        .unwrap();
        assert_eq!(made.len(), 1);
        assert_eq!(made[0].position, Point2::new(1.0, 0.5));
        assert_eq!(rep.pairs, 4);
        assert_eq!(rep.pairs_too_long_ms, 1);
        assert_eq!(rep.pairs_too_far_m, 1);
        assert_eq!(rep.pairs_too_few_shared, 1);
        // A waypoint position far off the chord is skipped.
        let mut rep = InterpolationReport::default();
        let made =
            along_walk(&scans[..2], |_| Some(Point2::new(1.0, 9.0)), &cfg, &mut rep).unwrap();
        assert!(made.is_empty());
        assert_eq!(rep.along_walk_off_chord, 1);
        let bad = AlongWalkConfig {
            spacing_m: 0.0,
            ..cfg
        };
        assert!(along_walk(&scans, |_| None, &bad, &mut rep).is_err());
    }

    #[test]
    fn spatial_weights_and_heard_share() {
        let sources = [
            print(0.0, 0.0, &[(0, -50.0), (1, -90.0)]),
            print(2.0, 0.0, &[(0, -60.0)]),
        ];
        let cfg = SpatialConfig {
            cell_m: 1.0,
            radius_m: 1.5,
            kernel: Kernel::InverseDistance { power: 1.0 },
            min_sources: 2,
            min_heard_share: 0.5,
            ..Default::default()
        };
        let (made, rep) = spatial(&sources, &cfg).unwrap();
        // Lattice points with both sources within 1.5 m: (1, 0) and (1, +-1).
        let mid = made
            .iter()
            .find(|p| p.position == Point2::new(1.0, 0.0))
            .unwrap();
        // Equal weights: AP 0 is the mean; AP 1 has exactly half the weight: heard.
        assert!((mid.rss[0].1 + 55.0).abs() < 1e-4);
        assert!((mid.rss[0].2 - 5.0).abs() < 1e-4);
        assert_eq!(mid.rss[1], (1, -90.0, 0.0));
        assert_eq!(rep.spatial_points, made.len());
        assert_eq!(
            rep.lattice_candidates,
            rep.spatial_points
                + rep.lattice_too_few_sources
                + rep.lattice_too_close
                + rep.lattice_nothing_heard
        );
        // A stricter share drops AP 1.
        let strict = SpatialConfig {
            min_heard_share: 0.6,
            ..cfg
        };
        let (made, _) = spatial(&sources, &strict).unwrap();
        let mid = made
            .iter()
            .find(|p| p.position == Point2::new(1.0, 0.0))
            .unwrap();
        assert_eq!(mid.rss.len(), 1);
        // min_gap_m keeps points off the sources.
        let gap = SpatialConfig {
            min_gap_m: 0.9,
            min_sources: 1,
            ..cfg
        };
        let (made, rep) = spatial(&sources, &gap).unwrap();
        assert!(rep.lattice_too_close >= 2);
        for p in &made {
            for s in &sources {
                assert!((p.position - s.position).norm() >= 0.9);
            }
        }
    }

    #[test]
    fn spatial_rejects_bad_configs_and_guards_memory() {
        let sources = [print(0.0, 0.0, &[(0, -50.0)])];
        for bad in [
            SpatialConfig {
                cell_m: 0.0,
                ..Default::default()
            },
            SpatialConfig {
                radius_m: f64::NAN,
                ..Default::default()
            },
            SpatialConfig {
                min_heard_share: 0.0,
                ..Default::default()
            },
            SpatialConfig {
                min_sources: 0,
                ..Default::default()
            },
            SpatialConfig {
                kernel: Kernel::Gaussian { sigma_m: -1.0 },
                ..Default::default()
            },
            SpatialConfig {
                kernel: Kernel::InverseDistance {
                    power: f64::INFINITY,
                },
                ..Default::default()
            },
            SpatialConfig {
                cell_m: 0.001,
                radius_m: 10.0,
                ..Default::default()
            },
        ] {
            assert!(
                matches!(
                    spatial(&sources, &bad),
                    Err(FingerprintError::InvalidConfig(_))
                ),
                "{bad:?}"
            );
        }
        let nan = [print(f64::NAN, 0.0, &[(0, -50.0)])];
        assert!(spatial(&nan, &SpatialConfig::default()).is_err());
        assert!(
            spatial(&[], &SpatialConfig::default())
                .unwrap()
                .0
                .is_empty()
        );
    }

    #[test]
    fn idw_is_finite_on_a_source() {
        let k = Kernel::InverseDistance { power: 2.0 };
        assert!(k.weight(0.0).is_finite());
        assert_eq!(k.weight(0.0), k.weight(IDW_MIN_DISTANCE_M));
        assert!((Kernel::Gaussian { sigma_m: 1.0 }.weight(0.0) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn densify_marks_points_as_interpolated_and_keeps_sources_measured() {
        let mut map = RadioMap::new(
            ApVocabulary::from_names(["a".to_string(), "b".to_string()]),
            RadioMapConfig::default(),
        );
        for (x, r) in [(0.0, -50.0), (4.0, -70.0)] {
            let p = ReferencePoint {
                position: Point2::new(x, 0.0),
                z: Some(1.0),
                floor: Some(2),
                building: None,
                scans: 3,
            };
            map.push_point(p, &[Some(r), None], Some((&[3, 0], &[1.0, 0.0])))
                .unwrap();
        }
        let cfg = SpatialConfig {
            cell_m: 2.0,
            radius_m: 2.5,
            ..Default::default()
        };
        let rep = densify_spatially(&mut map, &cfg).unwrap();
        assert_eq!(rep.spatial_points, 1);
        assert_eq!(map.len(), 3);
        let p = map.points()[2];
        assert_eq!(p.scans, 0);
        assert_eq!(p.floor, Some(2));
        assert_eq!(p.position, Point2::new(2.0, 0.0));
        assert!((map.rss(2, 0).unwrap() + 60.0).abs() < 1e-4);
        assert_eq!(map.count(2, 0), 1);
        assert!((map.spread(2, 0) - 10.0).abs() < 1e-4);
        assert_eq!(map.rss(2, 1), None);
        // A second pass uses only the measured points: same lattice point again.
        let (sources, rows) = measured_prints(&map);
        assert_eq!(rows, vec![0, 1]);
        assert_eq!(sources.len(), 2);
    }

    fn arb_sources() -> impl Strategy<Value = Vec<SparsePrint>> {
        prop::collection::vec(
            (
                -30.0f64..30.0,
                -30.0f64..30.0,
                prop::collection::btree_map(0usize..6, -100.0f32..-30.0, 1..5),
            ),
            0..25,
        )
        .prop_map(|v| {
            v.into_iter()
                .map(|(x, y, rss)| SparsePrint {
                    position: Point2::new(x, y),
                    rss: rss.into_iter().collect(),
                })
                .collect()
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]

        /// Issue 8: interpolation never creates a fingerprint farther than its radius from a
        /// measured one; created RSS stays within the sources' range.
        #[test]
        fn spatial_points_lie_within_radius(
            sources in arb_sources(),
            cell in 0.5f64..4.0,
            radius in 0.5f64..8.0,
            min_sources in 1usize..4,
            gaussian in any::<bool>(),
            share in 0.05f64..1.0,
        ) {
            let kernel = if gaussian {
                Kernel::Gaussian { sigma_m: radius / 2.0 }
            } else {
                Kernel::InverseDistance { power: 2.0 }
            };
            let cfg = SpatialConfig {
                cell_m: cell,
                radius_m: radius,
                kernel,
                min_sources,
                min_heard_share: share,
                ..Default::default()
            };
            let (made, rep) = spatial(&sources, &cfg).unwrap();
            prop_assert_eq!(rep.spatial_points, made.len());
            for p in &made {
                let nearest = sources
                    .iter()
                    .map(|s| (s.position - p.position).norm())
                    .fold(f64::INFINITY, f64::min);
                prop_assert!(nearest <= radius + 1e-9, "{} > {}", nearest, radius);
                let within = sources
                    .iter()
                    .filter(|s| (s.position - p.position).norm() <= radius)
                    .count();
                prop_assert!(within >= min_sources);
                prop_assert!(!p.rss.is_empty());
                for &(j, v, s) in &p.rss {
                    let heard: Vec<f32> = sources
                        .iter()
                        .filter(|s| (s.position - p.position).norm() <= radius)
                        .flat_map(|s| s.rss.iter().filter(|e| e.0 == j).map(|e| e.1))
                        .collect();
                    let lo = heard.iter().copied().fold(f32::INFINITY, f32::min);
                    let hi = heard.iter().copied().fold(f32::NEG_INFINITY, f32::max);
                    prop_assert!(v >= lo - 1e-3 && v <= hi + 1e-3);
                    prop_assert!(s.is_finite() && s >= 0.0 && s <= hi - lo + 1e-3);
                }
            }
        }

        /// Along the walk, every created point lies within max_gap_m / 2 of one of its scans.
        #[test]
        fn along_walk_points_lie_near_their_scans(
            steps in prop::collection::vec((0.0f64..8.0, -3.0f64..3.0, 500i64..6_000), 1..15),
            wobble in 0.0f64..6.0,
            max_gap in 1.0f64..10.0,
        ) {
            let mut scans = vec![scan(0, 0.0, &[(0, -50.0), (1, -60.0)])];
            for (k, &(dx, dy, dt)) in steps.iter().enumerate() {
                let last = scans.last().unwrap().clone();
                scans.push(WalkScan {
                    t: last.t + dt,
                    print: print(last.print.position.x + dx, last.print.position.y + dy,
                        &[(0, -50.0 - k as f32), (1, -60.0)]),
                });
            }
            let cfg = AlongWalkConfig { max_gap_m: max_gap, min_shared_aps: 1, ..Default::default() };
            let mut rep = InterpolationReport::default();
            let made = along_walk(&scans, |t| Some(Point2::new(t as f64 / 1000.0, wobble)), &cfg, &mut rep).unwrap();
            for p in &made {
                let nearest = scans
                    .iter()
                    .map(|s| (s.print.position - p.position).norm())
                    .fold(f64::INFINITY, f64::min);
                prop_assert!(nearest <= max_gap / 2.0 + 1e-9);
                prop_assert!(p.rss.iter().all(|e| is_valid_rssi(f64::from(e.1)) && e.2 >= 0.0));
            }
        }
    }
}

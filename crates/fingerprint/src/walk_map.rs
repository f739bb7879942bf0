//! Radio maps from recorded walks (`docs/evaluation.md`): each scan becomes a fingerprint at
//! the position interpolated between the walk's waypoints at the scan time
//! ([`wipdr_core::walk::interpolate_waypoints`]); optionally fingerprints are averaged into
//! grid cells.
//!
//! The real scans are stale (median entry age 3-4 s, 60 % over 2 s): how old an entry may be
//! relative to its scan is [`WalkMapConfig::max_entry_age_ms`] (docs/experiments.md: 5-10 s
//! beats 2 s; default 5 s). Labels are taken at the scan time by default (docs/experiments.md:
//! labelling at the entries' last-seen time is worse). Everything dropped is counted in
//! [`WalkMapReport`].
//!
//! [`WalkMapConfig::interpolation`] (off by default) densifies the map (paper 004 §5.3, see
//! [`crate::interpolate`]): fingerprints between consecutive scans of each training walk, at
//! the walk's waypoint-interpolated position, and kernel interpolation onto a lattice near the
//! measured points. Interpolated reference points have `scans = 0` and come after the measured
//! ones. With [`WalkMapConfig::grid_cell_m`] the lattice interpolates the cell means, and the
//! along-walk points are added as points of their own (never averaged into cells).

use crate::FingerprintError;
use crate::interpolate::{
    InterpolationConfig, InterpolationReport, WalkScan, along_walk, densify_spatially,
    push_interpolated,
};
use crate::radio_map::{
    ApVocabulary, RadioMap, RadioMapConfig, ReferencePoint, TableBudget, is_valid_rssi,
};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet};
use wipdr_core::walk::{floor_of_waypoints, interpolate_waypoints};
use wipdr_core::{Bssid, Point2, TimestampMs, Walk};

/// When a scan's fingerprint is labelled.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum LabelTime {
    /// At the scan time (default; docs/experiments.md).
    #[default]
    ScanTime,
    /// At the mean last-seen time of the entries kept.
    MeanLastSeen,
}

/// Settings of the walk-to-map builder.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WalkMapConfig {
    /// Drop entries older than this relative to their scan (ms); `None` keeps all.
    /// In TOML, `"off"` stands for `None` ([`wipdr_core::off`]).
    #[serde(with = "wipdr_core::off")]
    pub max_entry_age_ms: Option<i64>,
    /// Drop scans whose label time is farther than this from the nearest waypoint (ms);
    /// `None` only requires the label time to lie within the waypoints' span.
    pub max_waypoint_gap_ms: Option<i64>,
    /// When labels are taken.
    pub label_time: LabelTime,
    /// Minimum number of entries a scan must keep to become a fingerprint.
    pub min_aps: usize,
    /// Average fingerprints into square cells of this size (metres); `None` keeps one
    /// reference point per scan.
    pub grid_cell_m: Option<f64>,
    /// Floor written on the reference points whose walk's waypoints carry no floor (a
    /// waypoint's floor, where known, labels the scans after it; grid cells never mix
    /// floors).
    pub floor: Option<i32>,
    /// The map's settings ("not heard" value).
    pub radio: RadioMapConfig,
    /// Radio-map interpolation (paper 004 §5.3); `None` (default) = the measured points only.
    /// In TOML: `[radio_map.interpolation.along_walk]` and/or
    /// `[radio_map.interpolation.spatial]`.
    /// In TOML, `"off"` stands for `None` ([`wipdr_core::off`]).
    #[serde(with = "wipdr_core::off")]
    pub interpolation: Option<InterpolationConfig>,
    /// The most distinct APs the map may have (its vocabulary, the dense table's columns):
    /// more is [`FingerprintError::LimitExceeded`] naming `radio_map.max_aps`, checked before
    /// the table is allocated. Default [`DEFAULT_MAX_APS`], at most [`MAX_APS_CEILING`].
    #[serde(skip_serializing_if = "is_default_max_aps")]
    pub max_aps: usize,
    /// The most memory the map's dense table may take, MiB (measured and interpolated
    /// points x APs x [`crate::radio_map::BYTES_PER_CELL`]): crossing it is
    /// [`FingerprintError::LimitExceeded`] naming `radio_map.max_table_mib`, before the
    /// memory is allocated. Default [`DEFAULT_MAX_TABLE_MIB`], at most
    /// [`MAX_TABLE_MIB_CEILING`].
    #[serde(skip_serializing_if = "is_default_max_table_mib")]
    pub max_table_mib: usize,
}

/// Default of [`WalkMapConfig::max_aps`]: far above the real data (hundreds to a few
/// thousand APs per floor).
pub const DEFAULT_MAX_APS: usize = 100_000;
/// Hard ceiling of [`WalkMapConfig::max_aps`].
pub const MAX_APS_CEILING: usize = 1_000_000;
/// Default of [`WalkMapConfig::max_table_mib`] (8 GiB).
pub const DEFAULT_MAX_TABLE_MIB: usize = 8 * 1024;
/// Hard ceiling of [`WalkMapConfig::max_table_mib`] (16 GiB, two thirds of the 24 GiB
/// machines the project runs on).
pub const MAX_TABLE_MIB_CEILING: usize = 16 * 1024;

fn is_default_max_aps(v: &usize) -> bool {
    *v == DEFAULT_MAX_APS
}

fn is_default_max_table_mib(v: &usize) -> bool {
    *v == DEFAULT_MAX_TABLE_MIB
}

impl Default for WalkMapConfig {
    fn default() -> Self {
        Self {
            max_entry_age_ms: Some(5_000),
            max_waypoint_gap_ms: None,
            label_time: LabelTime::ScanTime,
            min_aps: 1,
            grid_cell_m: None,
            floor: None,
            radio: RadioMapConfig::default(),
            interpolation: None,
            max_aps: DEFAULT_MAX_APS,
            max_table_mib: DEFAULT_MAX_TABLE_MIB,
        }
    }
}

impl WalkMapConfig {
    /// Checks the values; the error is the field's name (relative to `radio_map`) and what
    /// is wrong.
    pub fn validate_fields(&self) -> Result<(), wipdr_core::ConfigError> {
        if let Some(age) = self.max_entry_age_ms
            && age < 0
        {
            return Err(wipdr_core::ConfigError::new(
                "max_entry_age_ms",
                format!(
                    "must be >= 0 ms (or \"off\" to keep every entry), got {age}: a negative age drops every entry"
                ),
            ));
        }
        if let Some(gap) = self.max_waypoint_gap_ms
            && gap < 0
        {
            return Err(wipdr_core::ConfigError::new(
                "max_waypoint_gap_ms",
                format!("must be >= 0 ms, got {gap}"),
            ));
        }
        if let Some(c) = self.grid_cell_m
            && !(c.is_finite() && c > 0.0)
        {
            return Err(wipdr_core::ConfigError::new(
                "grid_cell_m",
                format!("must be positive, got {c}"),
            ));
        }
        if !(1..=MAX_APS_CEILING).contains(&self.max_aps) {
            return Err(wipdr_core::ConfigError::new(
                "max_aps",
                format!("must be in 1..={MAX_APS_CEILING}, got {}", self.max_aps),
            ));
        }
        if !(1..=MAX_TABLE_MIB_CEILING).contains(&self.max_table_mib) {
            return Err(wipdr_core::ConfigError::new(
                "max_table_mib",
                format!(
                    "must be in 1..={MAX_TABLE_MIB_CEILING} MiB, got {}",
                    self.max_table_mib
                ),
            ));
        }
        Ok(())
    }

    /// Checks the values ([`WalkMapConfig::validate_fields`]), the interpolation's too.
    pub fn validate(&self) -> Result<(), FingerprintError> {
        self.validate_fields().map_err(|e| e.under("radio_map"))?;
        if let Some(i) = &self.interpolation {
            i.validate()?;
        }
        Ok(())
    }

    /// The budget of the dense table ([`WalkMapConfig::max_table_mib`]).
    pub fn table_budget(&self) -> TableBudget {
        TableBudget {
            max_bytes: self.max_table_mib.saturating_mul(1 << 20),
            limit: "radio_map.max_table_mib",
            hint: "raise it with `[radio_map] max_table_mib = N` (at most 16384), or build the \
                   map from fewer walks, on a coarser grid (`grid_cell_m`) or with less \
                   interpolation",
        }
    }
}

/// What the builder kept and dropped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub struct WalkMapReport {
    /// Walks read.
    pub walks: usize,
    /// Scans seen.
    pub scans: usize,
    /// Scans that became (or went into) reference points.
    pub scans_used: usize,
    /// Scans outside the waypoints' span or too far from a waypoint.
    pub scans_unlabelled: usize,
    /// Scans with fewer than `min_aps` entries left.
    pub scans_too_few_aps: usize,
    /// Entries dropped for staleness.
    pub entries_stale: usize,
    /// Entries dropped for NaN / out-of-range RSSI.
    pub entries_invalid: usize,
    /// Duplicate entries of one BSSID in a scan (the most recent kept).
    pub entries_duplicate: usize,
    /// Reference points in the map (measured and interpolated).
    pub reference_points: usize,
    /// What interpolation made and skipped (all zero when it is off).
    pub interpolation: InterpolationReport,
}

struct Fingerprint {
    walk: usize,
    t: TimestampMs,
    position: Point2,
    floor: Option<i32>,
    entries: Vec<(Bssid, f32)>,
}

/// Builds a radio map from walks with waypoints.
pub fn build_from_walks<'a, I>(
    walks: I,
    config: &WalkMapConfig,
) -> Result<(RadioMap, WalkMapReport), FingerprintError>
where
    I: IntoIterator<Item = &'a Walk>,
{
    config.validate()?;
    let mut report = WalkMapReport::default();
    let mut prints: Vec<Fingerprint> = Vec::new();
    let walks: Vec<&Walk> = walks.into_iter().collect();
    for (walk_index, walk) in walks.iter().enumerate() {
        report.walks += 1;
        for scan in &walk.wifi {
            report.scans += 1;
            let mut s = scan.clone();
            report.entries_duplicate += s.dedup_keep_most_recent();
            let mut entries = Vec::with_capacity(s.entries.len());
            let mut seen_sum = 0f64;
            for e in &s.entries {
                if !is_valid_rssi(e.rssi_dbm) {
                    report.entries_invalid += 1;
                    continue;
                }
                if let Some(max) = config.max_entry_age_ms
                    && e.age_ms(s.t) > max
                {
                    report.entries_stale += 1;
                    continue;
                }
                seen_sum += e.last_seen_ms as f64;
                entries.push((e.bssid, e.rssi_dbm as f32));
            }
            if entries.is_empty() || entries.len() < config.min_aps {
                report.scans_too_few_aps += 1;
                continue;
            }
            let t: TimestampMs = match config.label_time {
                LabelTime::ScanTime => s.t,
                LabelTime::MeanLastSeen => (seen_sum / entries.len() as f64).round() as i64,
            };
            let near_enough = config
                .max_waypoint_gap_ms
                .is_none_or(|gap| walk.waypoints.iter().any(|w| (w.t - t).abs() <= gap));
            let position = match interpolate_waypoints(&walk.waypoints, t) {
                Some(p) if near_enough => p,
                _ => {
                    report.scans_unlabelled += 1;
                    continue;
                }
            };
            report.scans_used += 1;
            prints.push(Fingerprint {
                walk: walk_index,
                t,
                position,
                floor: floor_of_waypoints(&walk.waypoints, t).or(config.floor),
                entries,
            });
        }
    }
    let bssids: BTreeSet<Bssid> = prints
        .iter()
        .flat_map(|f| f.entries.iter().map(|e| e.0))
        .collect();
    // Bounded before anything the size of the vocabulary (or of the table) is allocated.
    if bssids.len() > config.max_aps {
        return Err(FingerprintError::limit_exceeded(
            format!(
                "the training walks' {} distinct APs (the radio map's columns)",
                bssids.len()
            ),
            "radio_map.max_aps",
            config.max_aps.to_string(),
            format!(
                "raise it with `[radio_map] max_aps = N` (at most {MAX_APS_CEILING}), or leave \
                 out the walks whose scans carry that many BSSIDs"
            ),
        ));
    }
    let budget = config.table_budget();
    if config.grid_cell_m.is_none() {
        budget.check(prints.len(), bssids.len())?;
    }
    let vocabulary = ApVocabulary::from_bssids(bssids);
    let m = vocabulary.len();
    let mut map = RadioMap::new(vocabulary, config.radio);
    map.set_table_budget(Some(budget))?;
    let column = |b: Bssid, map: &RadioMap| map.vocabulary().column_of_bssid(b).unwrap_or(0);
    match config.grid_cell_m {
        None => {
            let mut row = vec![None; m];
            for f in &prints {
                row.fill(None);
                for &(b, r) in &f.entries {
                    row[column(b, &map)] = Some(r);
                }
                map.push_point(point(f.position, 1, f.floor), &row, None)?;
            }
        }
        Some(cell) => {
            // Cells never mix floors: the key leads with the fingerprint's floor.
            let mut cells: BTreeMap<(Option<i32>, i64, i64), Vec<usize>> = BTreeMap::new();
            for (i, f) in prints.iter().enumerate() {
                // Checked: a position so far out (or non-finite) that its bin does not fit
                // an i64 would otherwise saturate into one bin with every other such point.
                let bin = |v: f64| wipdr_core::grid::checked_i64((v / cell).floor());
                let (Some(bx), Some(by)) = (bin(f.position.x), bin(f.position.y)) else {
                    tracing::warn!(position = ?f.position, "fingerprint off any grid bin; skipped");
                    continue;
                };
                cells.entry((f.floor, bx, by)).or_default().push(i);
            }
            budget.check(cells.len(), m)?;
            let mut sum = vec![0f64; m];
            let mut sum_sq = vec![0f64; m];
            let mut count = vec![0u32; m];
            for (&(floor, _, _), members) in &cells {
                sum.fill(0.0);
                sum_sq.fill(0.0);
                count.fill(0);
                let mut centre = Point2::origin();
                for &i in members {
                    centre.x += prints[i].position.x;
                    centre.y += prints[i].position.y;
                    for &(b, r) in &prints[i].entries {
                        let j = column(b, &map);
                        sum[j] += f64::from(r);
                        sum_sq[j] += f64::from(r) * f64::from(r);
                        count[j] += 1;
                    }
                }
                let n = members.len() as f64;
                centre.x /= n;
                centre.y /= n;
                let mean: Vec<Option<f32>> = (0..m)
                    .map(|j| (count[j] > 0).then(|| (sum[j] / f64::from(count[j])) as f32))
                    .collect();
                let counts: Vec<u16> = count
                    .iter()
                    .map(|&c| c.min(u32::from(u16::MAX)) as u16)
                    .collect();
                let spread: Vec<f32> = (0..m)
                    .map(|j| {
                        if count[j] < 2 {
                            return 0.0;
                        }
                        let c = f64::from(count[j]);
                        let mu = sum[j] / c;
                        ((sum_sq[j] / c - mu * mu).max(0.0)).sqrt() as f32
                    })
                    .collect();
                map.push_point(
                    point(centre, members.len() as u32, floor),
                    &mean,
                    Some((&counts, &spread)),
                )?;
            }
        }
    }
    if let Some(interp) = &config.interpolation {
        // Spatial first: its sources are the measured points only.
        if let Some(sp) = &interp.spatial {
            // Per floor: a lattice point never averages fingerprints of two floors.
            let reports = crate::radio_map::per_floor(&mut map, |m| densify_spatially(m, sp))?;
            report.interpolation = reports
                .into_iter()
                .fold(InterpolationReport::default(), |a, b| a.add(&b));
        }
        if let Some(aw) = &interp.along_walk {
            let mut by_walk: Vec<Vec<usize>> = vec![Vec::new(); walks.len()];
            for (i, f) in prints.iter().enumerate() {
                by_walk[f.walk].push(i);
            }
            for (w, members) in by_walk.iter_mut().enumerate() {
                members.sort_by_key(|&i| prints[i].t);
                let scans: Vec<WalkScan> = members
                    .iter()
                    .map(|&i| WalkScan {
                        t: prints[i].t,
                        print: sparse_print(&prints[i], &map),
                    })
                    .collect();
                let waypoints = &walks[w].waypoints;
                let made = along_walk(
                    &scans,
                    |t| interpolate_waypoints(waypoints, t),
                    aw,
                    &mut report.interpolation,
                )?;
                // An along-walk point is on the floor of its nearest scan.
                push_interpolated(&mut map, &made, |k| {
                    let floor = made
                        .get(k)
                        .and_then(|p| members.get(p.nearest_source))
                        .and_then(|&i| prints[i].floor);
                    point(Point2::origin(), 0, floor)
                })?;
            }
        }
    }
    report.reference_points = map.len();
    tracing::info!(?report, "radio map built from walks");
    Ok((map, report))
}

/// A scan's fingerprint over the map's columns, sorted by column.
fn sparse_print(f: &Fingerprint, map: &RadioMap) -> crate::interpolate::SparsePrint {
    let mut rss: Vec<(usize, f32)> = f
        .entries
        .iter()
        .filter_map(|&(b, r)| map.vocabulary().column_of_bssid(b).map(|j| (j, r)))
        .collect();
    rss.sort_unstable_by_key(|e| e.0);
    rss.dedup_by_key(|e| e.0);
    crate::interpolate::SparsePrint {
        position: f.position,
        rss,
    }
}

fn point(position: Point2, scans: u32, floor: Option<i32>) -> ReferencePoint {
    ReferencePoint {
        position,
        z: None,
        floor,
        building: None,
        scans,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use wipdr_core::{Waypoint, WifiEntry, WifiScan};

    fn entry(b: u64, rssi: f64, seen: i64) -> WifiEntry {
        WifiEntry {
            bssid: Bssid(b),
            ssid: String::new(),
            rssi_dbm: rssi,
            frequency_mhz: 2412,
            last_seen_ms: seen,
        }
    }

    fn walk() -> Walk {
        Walk {
            waypoints: vec![
                Waypoint::new(0, Point2::new(0.0, 0.0)),
                Waypoint::new(10_000, Point2::new(10.0, 0.0)),
            ],
            wifi: vec![
                WifiScan {
                    t: 2_000,
                    entries: vec![entry(1, -50.0, 2_000), entry(2, -70.0, -5_000)],
                },
                WifiScan {
                    t: 2_500,
                    entries: vec![entry(1, -54.0, 2_500), entry(2, f64::NAN, 2_500)],
                },
                WifiScan {
                    t: 20_000,
                    entries: vec![entry(1, -50.0, 20_000)],
                },
            ],
            ..Default::default()
        }
    }

    #[test]
    fn per_scan_map_with_staleness() {
        let w = walk();
        let (map, rep) = build_from_walks([&w], &WalkMapConfig::default()).unwrap();
        assert_eq!(map.len(), 2);
        assert_eq!(rep.entries_stale, 1);
        assert_eq!(rep.entries_invalid, 1);
        assert_eq!(rep.scans_unlabelled, 1);
        assert!((map.point(0).position.x - 2.0).abs() < 1e-9);
        assert!((map.point(1).position.x - 2.5).abs() < 1e-9);
        // AP 2 was only heard stale: still in the vocabulary? No: only kept entries count.
        assert_eq!(map.n_aps(), 1);
        let cfg = WalkMapConfig {
            max_entry_age_ms: None,
            ..Default::default()
        };
        let (map, _) = build_from_walks([&w], &cfg).unwrap();
        assert_eq!(map.n_aps(), 2);
    }

    #[test]
    fn gridding_averages() {
        let w = walk();
        let cfg = WalkMapConfig {
            grid_cell_m: Some(5.0),
            ..Default::default()
        };
        let (map, _) = build_from_walks([&w], &cfg).unwrap();
        assert_eq!(map.len(), 1);
        assert_eq!(map.rss(0, 0), Some(-52.0));
        assert_eq!(map.count(0, 0), 2);
        assert!((map.spread(0, 0) - 2.0).abs() < 1e-6);
        assert_eq!(map.point(0).scans, 2);
        let bad = WalkMapConfig {
            grid_cell_m: Some(0.0),
            ..Default::default()
        };
        assert!(build_from_walks([&w], &bad).is_err());
    }

    #[test]
    fn interpolation_adds_marked_points() {
        use crate::interpolate::{AlongWalkConfig, SpatialConfig};
        let mut w = walk();
        w.wifi = vec![
            WifiScan {
                t: 2_000,
                entries: vec![entry(1, -50.0, 2_000), entry(2, -80.0, 2_000)],
            },
            WifiScan {
                t: 6_000,
                entries: vec![entry(1, -70.0, 6_000), entry(3, -60.0, 6_000)],
            },
        ];
        let along = WalkMapConfig {
            interpolation: Some(InterpolationConfig {
                along_walk: Some(AlongWalkConfig {
                    min_shared_aps: 1,
                    ..Default::default()
                }),
                spatial: None,
            }),
            floor: Some(4),
            ..Default::default()
        };
        let (map, rep) = build_from_walks([&w], &along).unwrap();
        // Scans at x = 2 and x = 6: points at x = 3, 4, 5 with AP 1 only.
        assert_eq!(map.len(), 5);
        assert_eq!(rep.reference_points, 5);
        assert_eq!(rep.interpolation.along_walk_points, 3);
        let col = map.vocabulary().column_of_bssid(Bssid(1)).unwrap();
        for (i, x) in [(2, 3.0), (3, 4.0), (4, 5.0)] {
            let p = map.points()[i];
            assert_eq!(p.scans, 0);
            assert_eq!(p.floor, Some(4));
            assert!((p.position.x - x).abs() < 1e-9);
            let want = -50.0 - 20.0 * (x as f32 - 2.0) / 4.0;
            assert!((map.rss(i, col).unwrap() - want).abs() < 1e-4);
            assert_eq!(map.heard(i).count(), 1);
        }
        assert!(map.points()[..2].iter().all(|p| p.scans == 1));

        let spatial = WalkMapConfig {
            interpolation: Some(InterpolationConfig {
                along_walk: None,
                spatial: Some(SpatialConfig {
                    cell_m: 1.0,
                    radius_m: 2.5,
                    min_sources: 2,
                    ..Default::default()
                }),
            }),
            ..Default::default()
        };
        let (map, rep) = build_from_walks([&w], &spatial).unwrap();
        assert_eq!(rep.interpolation.spatial_points, map.len() - 2);
        assert!(map.len() > 2);
        for p in &map.points()[2..] {
            assert_eq!(p.scans, 0);
            let near = [2.0, 6.0]
                .iter()
                .map(|&x| (p.position - Point2::new(x, 0.0)).norm())
                .fold(f64::INFINITY, f64::min);
            assert!(near <= 2.5);
        }
        let bad = WalkMapConfig {
            interpolation: Some(InterpolationConfig {
                along_walk: Some(AlongWalkConfig {
                    max_gap_m: -1.0,
                    ..Default::default()
                }),
                spatial: None,
            }),
            ..Default::default()
        };
        assert!(build_from_walks([&w], &bad).is_err());
    }

    #[test]
    fn interpolation_is_off_by_default_and_written_as_off() {
        let cfg: WalkMapConfig = serde_json::from_str("{}").unwrap();
        assert_eq!(cfg.interpolation, None);
        let json = serde_json::to_string(&WalkMapConfig::default()).unwrap();
        assert!(json.contains(r#""interpolation":"off""#), "{json}");
        let back: WalkMapConfig = serde_json::from_str(&json).unwrap();
        assert_eq!(back.interpolation, None);
        let on: WalkMapConfig = serde_json::from_str(
            r#"{"interpolation": {"spatial": {"radius_m": 3.0, "kernel": {"kind": "inverse_distance", "power": 2.0}}}}"#,
        )
        .unwrap();
        let sp = on.interpolation.unwrap().spatial.unwrap();
        assert_eq!(sp.radius_m, 3.0);
        assert_eq!(sp.cell_m, 2.0);
        assert!(
            serde_json::from_str::<WalkMapConfig>(r#"{"interpolation": {"spatail": {}}}"#).is_err()
        );
    }
}

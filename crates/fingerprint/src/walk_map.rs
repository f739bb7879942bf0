//! Radio maps from recorded walks (`docs/evaluation.md`): each scan becomes a fingerprint at
//! the position interpolated between the walk's waypoints at the scan time
//! ([`wipdr_core::walk::interpolate_waypoints`]); optionally fingerprints are averaged into
//! grid cells.
//!
//! The real scans are stale (median entry age 3-4 s, 60 % over 2 s): how old an entry may be
//! relative to its scan is [`WalkMapConfig::max_entry_age_ms`] (findings.md: 5-10 s beats
//! 2 s; default 5 s). Labels are taken at the scan time by default (findings.md: labelling at
//! the entries' last-seen time is worse). Everything dropped is counted in [`WalkMapReport`].

use crate::FingerprintError;
use crate::radio_map::{ApVocabulary, RadioMap, RadioMapConfig, ReferencePoint, is_valid_rssi};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet};
use wipdr_core::walk::interpolate_waypoints;
use wipdr_core::{Bssid, Point2, TimestampMs, Walk};

/// When a scan's fingerprint is labelled.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum LabelTime {
    /// At the scan time (default; findings.md).
    #[default]
    ScanTime,
    /// At the mean last-seen time of the entries kept.
    MeanLastSeen,
}

/// Settings of the walk-to-map builder.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct WalkMapConfig {
    /// Drop entries older than this relative to their scan (ms); `None` keeps all.
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
    /// Floor index written on every reference point, where known.
    pub floor: Option<i32>,
    /// The map's settings ("not heard" value).
    pub radio: RadioMapConfig,
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
    /// Reference points in the map.
    pub reference_points: usize,
}

struct Fingerprint {
    position: Point2,
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
    if let Some(c) = config.grid_cell_m
        && !(c.is_finite() && c > 0.0)
    {
        return Err(FingerprintError::InvalidConfig(format!(
            "grid_cell_m must be positive, got {c}"
        )));
    }
    let mut report = WalkMapReport::default();
    let mut prints: Vec<Fingerprint> = Vec::new();
    for walk in walks {
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
            prints.push(Fingerprint { position, entries });
        }
    }
    let bssids: BTreeSet<Bssid> = prints
        .iter()
        .flat_map(|f| f.entries.iter().map(|e| e.0))
        .collect();
    let vocabulary = ApVocabulary::from_bssids(bssids);
    let m = vocabulary.len();
    let mut map = RadioMap::new(vocabulary, config.radio);
    let column = |b: Bssid, map: &RadioMap| map.vocabulary.column_of_bssid(b).unwrap_or(0);
    match config.grid_cell_m {
        None => {
            let mut row = vec![None; m];
            for f in &prints {
                row.fill(None);
                for &(b, r) in &f.entries {
                    row[column(b, &map)] = Some(r);
                }
                map.push_point(point(f.position, 1, config.floor), &row, None)?;
            }
        }
        Some(cell) => {
            let mut cells: BTreeMap<(i64, i64), Vec<usize>> = BTreeMap::new();
            for (i, f) in prints.iter().enumerate() {
                let key = (
                    (f.position.x / cell).floor() as i64,
                    (f.position.y / cell).floor() as i64,
                );
                cells.entry(key).or_default().push(i);
            }
            let mut sum = vec![0f64; m];
            let mut sum_sq = vec![0f64; m];
            let mut count = vec![0u32; m];
            for members in cells.values() {
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
                    point(centre, members.len() as u32, config.floor),
                    &mean,
                    Some((&counts, &spread)),
                )?;
            }
        }
    }
    report.reference_points = map.len();
    tracing::info!(?report, "radio map built from walks");
    Ok((map, report))
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
                Waypoint {
                    t: 0,
                    position: Point2::new(0.0, 0.0),
                },
                Waypoint {
                    t: 10_000,
                    position: Point2::new(10.0, 0.0),
                },
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
        assert!((map.points[0].position.x - 2.0).abs() < 1e-9);
        assert!((map.points[1].position.x - 2.5).abs() < 1e-9);
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
        assert_eq!(map.points[0].scans, 2);
        let bad = WalkMapConfig {
            grid_cell_m: Some(0.0),
            ..Default::default()
        };
        assert!(build_from_walks([&w], &bad).is_err());
    }
}

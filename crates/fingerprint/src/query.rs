//! Online queries: what a matcher takes in. A real [`WifiScan`] (BSSIDs) and a benchmark row
//! (a column vector) both become a [`Query`] over the map's AP columns.
//!
//! Online filtering (paper 002 §3.2.1): entries weaker than an RSSI threshold are dropped,
//! entries of APs the map does not know are ignored; both are counted in [`QueryStats`].
//! Entries with NaN or out-of-range RSSI (outside `[-120, 0]` dBm) are dropped and counted,
//! or rejected with [`FingerprintError::InvalidRssi`] when [`QueryFilter::strict`] is set.
//! A scan with no entry left is an error ([`FingerprintError::EmptyScan`] /
//! [`FingerprintError::NoUsableAps`]), never a silent fix.

use crate::radio_map::is_valid_rssi;
use crate::{FingerprintError, RadioMap};
use serde::{Deserialize, Serialize};
use wipdr_core::FingerprintTable;
use wipdr_core::{TimestampMs, WifiScan};

/// Online-side filtering of a scan.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
#[serde(default, deny_unknown_fields)]
pub struct QueryFilter {
    /// Drop readings weaker than this (dBm); paper 002 §3.2.1 uses -85 dBm stationary,
    /// -75 dBm moving. `None` keeps all.
    pub min_rssi_dbm: Option<f64>,
    /// Drop scan entries older than this relative to the scan time (ms); `None` keeps all.
    /// In TOML, `"off"` stands for `None` ([`wipdr_core::off`]).
    #[serde(with = "wipdr_core::off")]
    pub max_age_ms: Option<i64>,
    /// Reject (instead of dropping and counting) invalid RSSI values.
    pub strict: bool,
}

impl QueryFilter {
    /// Checks the values; the error is the field's name and what is wrong.
    pub fn validate_fields(&self) -> Result<(), wipdr_core::ConfigError> {
        if let Some(v) = self.min_rssi_dbm
            && !v.is_finite()
        {
            return Err(wipdr_core::ConfigError::new(
                "min_rssi_dbm",
                format!("must be finite, got {v}"),
            ));
        }
        if let Some(age) = self.max_age_ms
            && age < 0
        {
            return Err(wipdr_core::ConfigError::new(
                "max_age_ms",
                format!(
                    "must be >= 0 ms (or \"off\" to keep every entry), got {age}: a negative age drops every entry"
                ),
            ));
        }
        Ok(())
    }
}

/// What the filtering did to one query.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub struct QueryStats {
    /// Entries of APs the map does not know (ignored).
    pub unknown_aps: usize,
    /// Entries dropped by the RSSI threshold.
    pub below_threshold: usize,
    /// Entries dropped for NaN / out-of-range RSSI.
    pub invalid_rssi: usize,
    /// Entries dropped for staleness.
    pub stale: usize,
    /// Duplicate entries of one AP merged (the most recent, then strongest, kept).
    pub duplicates: usize,
}

/// A query over a map's AP columns: the heard APs as `(column, RSSI dBm)`, sorted by column,
/// one entry per column. Independent of the order of entries in the scan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Query {
    /// Scan time (Unix ms); 0 for benchmark rows.
    pub t: TimestampMs,
    /// Heard APs, `(column, dBm)`, strictly increasing columns.
    pub heard: Vec<(u32, f32)>,
    /// What filtering did.
    pub stats: QueryStats,
}

impl Query {
    /// The query as a dense vector of `n_aps` values with `fill` where not heard.
    pub fn dense(&self, n_aps: usize, fill: f32) -> Vec<f32> {
        let mut v = vec![fill; n_aps];
        for &(j, r) in &self.heard {
            v[j as usize] = r;
        }
        v
    }

    /// Builds a query from a scan against a map.
    pub fn from_scan(
        scan: &WifiScan,
        map: &RadioMap,
        filter: &QueryFilter,
    ) -> Result<Self, FingerprintError> {
        if scan.entries.is_empty() {
            return Err(FingerprintError::EmptyScan);
        }
        let mut stats = QueryStats::default();
        // (column, rssi, last_seen)
        let mut kept: Vec<(u32, f32, TimestampMs)> = Vec::with_capacity(scan.entries.len());
        for e in &scan.entries {
            if !is_valid_rssi(e.rssi_dbm) {
                if filter.strict {
                    return Err(FingerprintError::InvalidRssi {
                        ap: e.bssid.to_string(),
                        value: e.rssi_dbm,
                    });
                }
                stats.invalid_rssi += 1;
                continue;
            }
            if let Some(max_age) = filter.max_age_ms
                && e.age_ms(scan.t) > max_age
            {
                stats.stale += 1;
                continue;
            }
            if let Some(th) = filter.min_rssi_dbm
                && e.rssi_dbm < th
            {
                stats.below_threshold += 1;
                continue;
            }
            match map.vocabulary().column_of_bssid(e.bssid) {
                Some(j) => kept.push((j as u32, e.rssi_dbm as f32, e.last_seen_ms)),
                None => stats.unknown_aps += 1,
            }
        }
        // Sort by column, then most recent and strongest first, so duplicates resolve the
        // same way whatever the entry order.
        kept.sort_by(|a, b| a.0.cmp(&b.0).then(b.2.cmp(&a.2)).then(b.1.total_cmp(&a.1)));
        let before = kept.len();
        kept.dedup_by_key(|e| e.0);
        stats.duplicates = before - kept.len();
        Self::finish(
            scan.t,
            kept.into_iter().map(|(j, r, _)| (j, r)).collect(),
            stats,
        )
    }

    /// Builds a query from a benchmark row over the map's columns (100 = not detected).
    pub fn from_row(
        row: &[f32],
        map: &RadioMap,
        filter: &QueryFilter,
    ) -> Result<Self, FingerprintError> {
        if row.len() != map.n_aps() {
            return Err(FingerprintError::DimensionMismatch {
                expected: map.n_aps(),
                found: row.len(),
            });
        }
        let mut stats = QueryStats::default();
        let mut heard = Vec::new();
        let mut any = false;
        for (j, &v) in row.iter().enumerate() {
            if FingerprintTable::is_not_heard(v) {
                continue;
            }
            any = true;
            let vf = f64::from(v);
            if !is_valid_rssi(vf) {
                if filter.strict {
                    return Err(FingerprintError::InvalidRssi {
                        ap: map.vocabulary().name(j).to_string(),
                        value: vf,
                    });
                }
                stats.invalid_rssi += 1;
                continue;
            }
            if let Some(th) = filter.min_rssi_dbm
                && vf < th
            {
                stats.below_threshold += 1;
                continue;
            }
            heard.push((j as u32, v));
        }
        if !any {
            return Err(FingerprintError::EmptyScan);
        }
        Self::finish(0, heard, stats)
    }

    fn finish(
        t: TimestampMs,
        heard: Vec<(u32, f32)>,
        stats: QueryStats,
    ) -> Result<Self, FingerprintError> {
        let dropped = stats.unknown_aps + stats.below_threshold + stats.invalid_rssi;
        if dropped > 0 {
            tracing::debug!(
                t,
                unknown = stats.unknown_aps,
                weak = stats.below_threshold,
                invalid = stats.invalid_rssi,
                "query entries dropped"
            );
        }
        if heard.is_empty() {
            return Err(FingerprintError::NoUsableAps {
                unknown: stats.unknown_aps,
                below_threshold: stats.below_threshold + stats.stale,
                invalid_rssi: stats.invalid_rssi,
            });
        }
        Ok(Self { t, heard, stats })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::radio_map::{ApVocabulary, RadioMapConfig, ReferencePoint};
    use wipdr_core::{Bssid, Point2, WifiEntry};

    fn map() -> RadioMap {
        let mut m = RadioMap::new(
            ApVocabulary::from_bssids([Bssid(1), Bssid(2)]),
            RadioMapConfig::default(),
        );
        let p = ReferencePoint {
            position: Point2::new(0.0, 0.0),
            z: None,
            floor: None,
            building: None,
            scans: 1,
        };
        m.push_point(p, &[Some(-50.0), Some(-60.0)], None).unwrap();
        m
    }

    fn entry(b: u64, rssi: f64, seen: i64) -> WifiEntry {
        WifiEntry {
            bssid: Bssid(b),
            ssid: String::new(),
            rssi_dbm: rssi,
            frequency_mhz: 2412,
            last_seen_ms: seen,
        }
    }

    fn scan(entries: Vec<WifiEntry>) -> WifiScan {
        WifiScan { t: 1000, entries }
    }

    #[test]
    fn empty_and_unknown_only() {
        let m = map();
        let f = QueryFilter::default();
        assert_eq!(
            Query::from_scan(&scan(vec![]), &m, &f),
            Err(FingerprintError::EmptyScan)
        );
        let e = Query::from_scan(&scan(vec![entry(9, -50.0, 1000)]), &m, &f).unwrap_err();
        assert_eq!(
            e,
            FingerprintError::NoUsableAps {
                unknown: 1,
                below_threshold: 0,
                invalid_rssi: 0
            }
        );
    }

    #[test]
    fn invalid_rssi_counted_or_rejected() {
        let m = map();
        let s = scan(vec![
            entry(1, f64::NAN, 1000),
            entry(2, 5.0, 1000),
            entry(2, -130.0, 1000),
            entry(1, -40.0, 1000),
            entry(7, -40.0, 1000),
        ]);
        let q = Query::from_scan(&s, &m, &QueryFilter::default()).unwrap();
        assert_eq!(q.heard, vec![(0, -40.0)]);
        assert_eq!(q.stats.invalid_rssi, 3);
        assert_eq!(q.stats.unknown_aps, 1);
        let strict = QueryFilter {
            strict: true,
            ..Default::default()
        };
        assert!(matches!(
            Query::from_scan(&s, &m, &strict),
            Err(FingerprintError::InvalidRssi { .. })
        ));
    }

    #[test]
    fn threshold_staleness_duplicates() {
        let m = map();
        let s = scan(vec![
            entry(1, -80.0, 1000),
            entry(2, -60.0, 500),
            entry(2, -65.0, 900),
        ]);
        let f = QueryFilter {
            min_rssi_dbm: Some(-75.0),
            ..Default::default()
        };
        let q = Query::from_scan(&s, &m, &f).unwrap();
        assert_eq!(q.heard, vec![(1, -65.0)]);
        assert_eq!(q.stats.below_threshold, 1);
        assert_eq!(q.stats.duplicates, 1);
        let f = QueryFilter {
            max_age_ms: Some(200),
            ..Default::default()
        };
        let q = Query::from_scan(&s, &m, &f).unwrap();
        assert_eq!(q.heard, vec![(0, -80.0), (1, -65.0)]);
        assert_eq!(q.stats.stale, 1);
    }

    #[test]
    fn rows() {
        let m = map();
        let f = QueryFilter::default();
        assert_eq!(
            Query::from_row(&[100.0, 100.0], &m, &f),
            Err(FingerprintError::EmptyScan)
        );
        assert!(matches!(
            Query::from_row(&[100.0], &m, &f),
            Err(FingerprintError::DimensionMismatch { .. })
        ));
        let q = Query::from_row(&[-70.0, f32::NAN], &m, &f).unwrap();
        assert_eq!(q.heard, vec![(0, -70.0)]);
        assert_eq!(q.stats.invalid_rssi, 1);
        assert_eq!(q.dense(2, -110.0), vec![-70.0, -110.0]);
    }
}

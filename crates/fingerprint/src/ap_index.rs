//! AP-matching index `apindex` (paper 002 §3.2, eq. 6) with the motion-dependent RSSI
//! threshold of §3.2.1.
//!
//! Offline, every reference point is indexed under its two strongest APs. Online, readings
//! weaker than the threshold are dropped (-85 dBm when the walker is stationary, -75 dBm when
//! moving; the motion state comes from the caller), and the candidates are the reference points
//! whose top-2 holds the scan's strongest AP (eq. 6: `AP_max,online ∈ {AP_top2,offline}`).
//! WKNN runs over the candidates. Fallbacks: when the threshold leaves no reading, the
//! strongest reading is kept; when no reference point matches, the whole map is searched.
//! `visited` is the number of candidates whose distance was computed.
//!
//! ```
//! use wipdr_fingerprint::ap_index::{ApIndexConfig, ApIndexMatcher};
//! use wipdr_fingerprint::{Matcher, Query, QueryFilter, RadioMap, RadioMapConfig};
//! use wipdr_io::fingerprint_csv::read_fingerprint_csv_from;
//! let csv = "ap_000,ap_001,ap_002,x,y,z,floor,building\n\
//!            -40,-60,-80,0,0,0,0,0\n-60,-40,-80,5,0,0,0,0\n-80,-60,-40,10,0,0,0,0\n";
//! let table = read_fingerprint_csv_from(csv.as_bytes(), "inline").unwrap();
//! let map = RadioMap::from_table(&table, RadioMapConfig::default()).unwrap();
//! let idx = ApIndexMatcher::new(map, ApIndexConfig::default()).unwrap();
//! let q = Query::from_row(&[-42.0, -62.0, -79.0], idx.map(), &QueryFilter::default()).unwrap();
//! let obs = idx.locate(&q).unwrap();
//! // AP 0 is in the top two of points 0 and 1 only.
//! assert_eq!(obs.visited, 2);
//! ```

use crate::cluster_search::{shifted_norms, wknn_over};
use crate::matcher::Weighting;
use crate::{FingerprintError, Matcher, Query, RadioMap};
use serde::{Deserialize, Serialize};
use std::sync::Arc;
use wipdr_core::{MotionState, WifiObservation};

/// Settings of the AP-matching index (paper 002 defaults).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ApIndexConfig {
    /// Strongest offline APs a reference point is indexed under (paper: 2).
    pub top_offline: usize,
    /// Online RSSI threshold when stationary, dBm (paper 002 §3.2.1: -85).
    pub stationary_threshold_dbm: f32,
    /// Online RSSI threshold when moving, dBm (paper 002 §3.2.1: -75).
    pub moving_threshold_dbm: f32,
    /// Whether [`Matcher::locate`] (which has no motion input) assumes a moving walker.
    pub assume_moving: bool,
    /// Apply the threshold at all (off: every reading is used).
    pub apply_threshold: bool,
    /// WKNN neighbours.
    pub k: usize,
    /// WKNN weighting.
    pub weighting: Weighting,
}

impl Default for ApIndexConfig {
    fn default() -> Self {
        Self {
            top_offline: 2,
            stationary_threshold_dbm: -85.0,
            moving_threshold_dbm: -75.0,
            assume_moving: false,
            apply_threshold: true,
            k: 5,
            weighting: Weighting::InverseDistance { power: 1.0 },
        }
    }
}

/// The `apindex` matcher.
#[derive(Debug, Clone)]
pub struct ApIndexMatcher {
    map: Arc<RadioMap>,
    config: ApIndexConfig,
    /// For each AP column, the reference points with that AP among their top APs.
    index: Vec<Vec<u32>>,
    norms: Vec<f64>,
}

impl ApIndexMatcher {
    /// Builds the index.
    pub fn new(
        map: impl Into<Arc<RadioMap>>,
        config: ApIndexConfig,
    ) -> Result<Self, FingerprintError> {
        let map: Arc<RadioMap> = map.into();
        if map.is_empty() {
            return Err(FingerprintError::EmptyMap);
        }
        if config.top_offline == 0 || config.k == 0 {
            return Err(FingerprintError::InvalidConfig(
                "apindex: top_offline and k must be at least 1".into(),
            ));
        }
        let mut index = vec![Vec::new(); map.n_aps()];
        for i in 0..map.len() {
            let mut heard: Vec<(usize, f32)> = map.heard(i).collect();
            heard.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
            for &(j, _) in heard.iter().take(config.top_offline) {
                index[j].push(i as u32);
            }
        }
        Ok(Self {
            norms: shifted_norms(&map),
            map,
            config,
            index,
        })
    }

    /// Reference points indexed under AP column `j`.
    pub fn indexed_under(&self, j: usize) -> &[u32] {
        self.index.get(j).map_or(&[], |v| v.as_slice())
    }

    /// Locates a query with the walker's motion state (stationary -> the -85 dBm threshold,
    /// moving -> -75 dBm).
    pub fn locate_with_motion(
        &self,
        query: &Query,
        motion: &MotionState,
    ) -> Result<WifiObservation, FingerprintError> {
        self.locate_moving(query, !motion.stationary)
    }

    /// Locates a query, `moving` choosing the threshold.
    pub fn locate_moving(
        &self,
        query: &Query,
        moving: bool,
    ) -> Result<WifiObservation, FingerprintError> {
        if query.heard.is_empty() {
            return Err(FingerprintError::EmptyScan);
        }
        let threshold = if moving {
            self.config.moving_threshold_dbm
        } else {
            self.config.stationary_threshold_dbm
        };
        let mut kept = query.clone();
        if self.config.apply_threshold {
            kept.heard.retain(|&(_, r)| r >= threshold);
            if kept.heard.is_empty() {
                // Keep the strongest reading rather than fail.
                if let Some(&best) = query
                    .heard
                    .iter()
                    .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)))
                {
                    kept.heard.push(best);
                }
            }
            kept.stats.below_threshold += query.heard.len() - kept.heard.len();
        }
        let strongest = kept
            .heard
            .iter()
            .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)))
            .map(|&(j, _)| j as usize)
            .ok_or(FingerprintError::EmptyScan)?;
        let matched = self.indexed_under(strongest);
        let candidates: Vec<usize> = if matched.is_empty() {
            (0..self.map.len()).collect()
        } else {
            matched.iter().map(|&i| i as usize).collect()
        };
        let visited = candidates.len();
        wknn_over(
            &self.map,
            &self.norms,
            &kept,
            &candidates,
            self.config.k,
            self.config.weighting,
            visited,
        )
    }
}

impl Matcher for ApIndexMatcher {
    fn name(&self) -> String {
        let c = &self.config;
        format!(
            "apindex(top={},threshold={},moving={},k={})",
            c.top_offline,
            if c.apply_threshold { "on" } else { "off" },
            c.assume_moving,
            c.k
        )
    }

    fn map(&self) -> &RadioMap {
        &self.map
    }

    fn locate(&self, query: &Query) -> Result<WifiObservation, FingerprintError> {
        self.locate_moving(query, self.config.assume_moving)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::RadioMapConfig;
    use wipdr_io::fingerprint_csv::read_fingerprint_csv_from;

    fn map() -> RadioMap {
        let csv = "ap_000,ap_001,ap_002,x,y,z,floor,building\n\
                   -40,-60,-80,0,0,0,0,0\n-60,-40,-80,5,0,0,0,0\n-80,-60,-40,10,0,0,0,0\n";
        let t = read_fingerprint_csv_from(csv.as_bytes(), "t").unwrap();
        RadioMap::from_table(&t, RadioMapConfig::default()).unwrap()
    }

    fn q(heard: Vec<(u32, f32)>) -> Query {
        Query {
            t: 0,
            heard,
            stats: Default::default(),
        }
    }

    #[test]
    fn index_holds_each_point_under_its_two_strongest_aps() {
        let m = ApIndexMatcher::new(map(), ApIndexConfig::default()).unwrap();
        assert_eq!(m.indexed_under(0), &[0, 1]);
        assert_eq!(m.indexed_under(1), &[0, 1, 2]);
        assert_eq!(m.indexed_under(2), &[2]);
    }

    #[test]
    fn moving_threshold_drops_weaker_readings_than_stationary() {
        let m = ApIndexMatcher::new(map(), ApIndexConfig::default()).unwrap();
        // Strongest reading -80 (AP 2): kept when stationary (-85), dropped when moving (-75)
        // except as the last resort.
        let query = q(vec![(0, -78.0), (2, -80.0)]);
        let still = m.locate_moving(&query, false).unwrap();
        assert_eq!(still.visited, 2); // strongest AP 0 -> points 0, 1
        let moving = m.locate_moving(&query, true).unwrap();
        // Both readings below -75: the strongest (AP 0) is kept.
        assert_eq!(moving.visited, 2);
        let only_weak = q(vec![(2, -80.0)]);
        let obs = m.locate_moving(&only_weak, true).unwrap();
        assert_eq!(obs.visited, 1);
        assert_eq!(obs.candidates[0].index, 2);
    }

    #[test]
    fn unmatched_strongest_ap_falls_back_to_the_whole_map() {
        let csv = "ap_000,ap_001,ap_002,ap_003,x,y,z,floor,building\n\
                   -40,-60,-80,-90,0,0,0,0,0\n-60,-40,-80,-90,5,0,0,0,0\n";
        let t = read_fingerprint_csv_from(csv.as_bytes(), "t").unwrap();
        let map = RadioMap::from_table(&t, RadioMapConfig::default()).unwrap();
        let m = ApIndexMatcher::new(map, ApIndexConfig::default()).unwrap();
        let obs = m.locate(&q(vec![(3, -50.0)])).unwrap();
        assert_eq!(obs.visited, 2);
    }
}

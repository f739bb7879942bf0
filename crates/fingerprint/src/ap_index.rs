//! AP-matching index `apindex` (paper 002 §3.2, eq. 6) with the motion-dependent RSSI
//! threshold of §3.2.1.
//!
//! Offline, every reference point is indexed under its two strongest APs. Online, readings
//! weaker than the threshold are dropped (-85 dBm when the walker is stationary, -75 dBm when
//! moving; the motion state comes from the caller), and the candidates are the reference points
//! whose top-2 holds the scan's strongest AP (eq. 6: `AP_max,online ∈ {AP_top2,offline}`).
//! WKNN runs over the candidates, with the brute-force engine's compact layout restricted to
//! the candidate rows ([`KnnMatcher::locate_among`]; distance and representation configurable,
//! Euclidean on raw dBm by default). Fallbacks: when the threshold leaves no reading, the
//! strongest reading is kept; when no reference point matches, the whole map is searched.
//! `visited` is the number of candidates whose distance was computed.
//!
//! Callers that know the walker's steps (the evaluation pipeline) derive the motion state with
//! [`motion_at`]: moving when a step was detected within
//! [`ApIndexConfig::stationary_after_ms`] before the scan.
//!
//! ```
//! use wipdr_fingerprint::ap_index::{ApIndexConfig, ApIndexMatcher};
//! use wipdr_fingerprint::{Matcher, Query, QueryFilter, RadioMap, RadioMapConfig};
//! use wipdr_core::{FingerprintLabel, FingerprintTable};
//! let mut table = FingerprintTable::new(vec!["ap_000".into(), "ap_001".into(), "ap_002".into()]);
//! for (rss, x) in [([-40.0, -60.0, -80.0], 0.0), ([-60.0, -40.0, -80.0], 5.0), ([-80.0, -60.0, -40.0], 10.0)] {
//!     table.push_row(&rss, FingerprintLabel::at(x, 0.0, 0)).unwrap();
//! }
//! let map = RadioMap::from_table(&table, RadioMapConfig::default()).unwrap();
//! let idx = ApIndexMatcher::new(map, ApIndexConfig::default()).unwrap();
//! let q = Query::from_row(&[-42.0, -62.0, -79.0], idx.map(), &QueryFilter::default()).unwrap();
//! let obs = idx.locate(&q).unwrap();
//! // AP 0 is in the top two of points 0 and 1 only.
//! assert_eq!(obs.visited, 2);
//! ```

use crate::distance::{Metric, Representation};
use crate::matcher::Weighting;
use crate::{FingerprintError, KnnConfig, KnnMatcher, Matcher, Query, RadioMap};
use serde::{Deserialize, Serialize};
use std::sync::Arc;
use wipdr_core::{MotionState, StepEvent, TimestampMs, WifiObservation};

/// Settings of the AP-matching index (paper 002 defaults).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
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
    /// Signal distance of the WKNN over the candidates (paper 002 eq. 1: Euclidean).
    pub metric: Metric,
    /// Data representation of the WKNN (raw dBm, as the paper).
    pub representation: Representation,
    /// For callers deriving motion from PDR steps ([`motion_at`]): the walker counts as
    /// stationary when no step was detected within this many ms before the scan (2,000 ms:
    /// about four step periods; not from the paper, which takes the state from its PDR).
    pub stationary_after_ms: i64,
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
            metric: Metric::Euclidean,
            representation: Representation::Raw,
            stationary_after_ms: 2_000,
        }
    }
}

impl ApIndexConfig {
    /// The WKNN run over the candidates.
    pub fn inner(&self) -> KnnConfig {
        KnnConfig {
            k: self.k,
            weighting: self.weighting,
            metric: self.metric,
            representation: self.representation,
        }
    }
}

/// The walker's motion state at time `t` from the PDR steps detected so far (`steps` in time
/// order; only steps at or before `t` are used, so it is causal): the last step's state, with
/// `stationary` set when that step is more than `stationary_after_ms` before `t` or there is
/// none.
pub fn motion_at(steps: &[StepEvent], t: TimestampMs, stationary_after_ms: i64) -> MotionState {
    let last = steps.partition_point(|s| s.t <= t);
    match last.checked_sub(1).map(|i| &steps[i]) {
        Some(step) => MotionState {
            stationary: t - step.t > stationary_after_ms,
            ..step.motion
        },
        None => MotionState {
            stationary: true,
            ..MotionState::default()
        },
    }
}

/// The `apindex` matcher.
#[derive(Debug)]
pub struct ApIndexMatcher {
    config: ApIndexConfig,
    /// For each AP column, the reference points with that AP among their top APs, ascending.
    index: Vec<Vec<u32>>,
    /// The WKNN over candidate rows (brute-force engine and layout).
    inner: KnnMatcher,
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
                wipdr_core::ConfigError::new("apindex", "top_offline and k must be at least 1"),
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
            inner: KnnMatcher::new(map, config.inner())?,
            config,
            index,
        })
    }

    /// Reference points indexed under AP column `j`.
    pub fn indexed_under(&self, j: usize) -> &[u32] {
        self.index.get(j).map_or(&[], |v| v.as_slice())
    }

    /// The configuration.
    pub fn config(&self) -> &ApIndexConfig {
        &self.config
    }

    /// Locates a query with the walker's motion state (stationary -> the -85 dBm threshold,
    /// moving -> -75 dBm); the same as [`Matcher::locate_with_motion`].
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
        if matched.is_empty() {
            return self.inner.locate(&kept);
        }
        self.inner.locate_among(&kept, matched, matched.len())
    }
}

impl Matcher for ApIndexMatcher {
    fn name(&self) -> String {
        let c = &self.config;
        format!(
            "apindex(top={},threshold={},still={},moving={},assume_moving={},{})",
            c.top_offline,
            if c.apply_threshold { "on" } else { "off" },
            c.stationary_threshold_dbm,
            c.moving_threshold_dbm,
            c.assume_moving,
            c.inner().describe()
        )
    }

    fn map(&self) -> &RadioMap {
        self.inner.map()
    }

    fn locate(&self, query: &Query) -> Result<WifiObservation, FingerprintError> {
        self.locate_moving(query, self.config.assume_moving)
    }

    fn locate_with_motion(
        &self,
        query: &Query,
        motion: &MotionState,
    ) -> Result<WifiObservation, FingerprintError> {
        self.locate_moving(query, !motion.stationary)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::RadioMapConfig;

    fn map() -> RadioMap {
        let t = crate::test_table(
            3,
            &[
                (&[-40.0, -60.0, -80.0], 0.0),
                (&[-60.0, -40.0, -80.0], 5.0),
                (&[-80.0, -60.0, -40.0], 10.0),
            ],
        );
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
    fn motion_comes_from_the_last_step_before_the_scan() {
        let step = |t, stationary| StepEvent {
            t,
            length: 0.7,
            heading: 0.0,
            heading_change: 0.0,
            period_s: 0.5,
            motion: MotionState {
                stationary,
                ..MotionState::default()
            },
            covariance: None,
        };
        let steps = [step(1_000, true), step(1_500, false), step(9_000, false)];
        assert!(motion_at(&steps, 500, 2_000).stationary); // no step yet
        assert!(!motion_at(&steps, 1_200, 2_000).stationary); // step 200 ms ago
        assert!(!motion_at(&steps, 3_500, 2_000).stationary); // 2,000 ms: still moving
        assert!(motion_at(&steps, 3_501, 2_000).stationary); // longer: stationary
        // A later step is not used (causal).
        assert!(motion_at(&steps, 8_999, 2_000).stationary);
        let m = ApIndexMatcher::new(map(), ApIndexConfig::default()).unwrap();
        let query = q(vec![(0, -78.0), (2, -80.0)]);
        let dynamic: &dyn Matcher = &m;
        assert_eq!(
            dynamic
                .locate_with_motion(&query, &motion_at(&steps, 1_200, 2_000))
                .unwrap(),
            m.locate_moving(&query, true).unwrap()
        );
    }

    #[test]
    fn candidate_search_equals_brute_force_over_the_candidates() {
        // Every point hears AP 0 among its top two: the index search is the brute force.
        let t = crate::test_table(
            3,
            &[
                (&[-40.0, -60.0, -80.0], 0.0),
                (&[-45.0, -40.0, -80.0], 5.0),
                (&[-41.0, -70.0, -60.0], 10.0),
            ],
        );
        let map = Arc::new(RadioMap::from_table(&t, RadioMapConfig::default()).unwrap());
        for metric in ["euclidean", "manhattan", "sorensen", "shared_ap"] {
            let cfg = ApIndexConfig {
                k: 2,
                metric: Metric::parse(metric).unwrap(),
                ..ApIndexConfig::default()
            };
            let idx = ApIndexMatcher::new(map.clone(), cfg).unwrap();
            let brute = KnnMatcher::new(map.clone(), cfg.inner()).unwrap();
            let query = q(vec![(0, -42.0), (1, -55.0), (2, -70.0)]);
            let a = idx.locate(&query).unwrap();
            let b = brute.locate(&query).unwrap();
            assert_eq!(a.candidates, b.candidates, "{metric}");
            assert_eq!(a.visited, 3);
        }
    }

    #[test]
    fn unmatched_strongest_ap_falls_back_to_the_whole_map() {
        let t = crate::test_table(
            4,
            &[
                (&[-40.0, -60.0, -80.0, -90.0], 0.0),
                (&[-60.0, -40.0, -80.0, -90.0], 5.0),
            ],
        );
        let map = RadioMap::from_table(&t, RadioMapConfig::default()).unwrap();
        let m = ApIndexMatcher::new(map, ApIndexConfig::default()).unwrap();
        let obs = m.locate(&q(vec![(3, -50.0)])).unwrap();
        assert_eq!(obs.visited, 2);
    }
}

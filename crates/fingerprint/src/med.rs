//! Multi-scan Euclidean distance matcher `med` (paper 004 eq. 11, Table 3).
//!
//! The printed eq. 11 sums signed differences without square or root; `docs/algorithms.md`
//! fixes it to the Euclidean form the name says:
//! `d(c) = sqrt( sum_{i=k-w+1..k} sum_j (RSS(i,j) - RSS_db(i,j))^2 )` over the last `w` scans
//! (default 2, paper 004 Table 3).
//!
//! The database side implemented here is **the map shifted by PDR displacement** (it works with
//! any radio map; the paper's consecutive survey fingerprints need a map recorded by walking):
//! for a candidate reference point `c` at position `p_c`, the fingerprint compared with past
//! scan `i` is that of the reference point nearest to `p_c - D_i` (same building and floor),
//! where `D_i` is the walker's displacement since scan `i`, supplied by the caller (PDR). The
//! current scan is compared with `c` itself. WKNN (`1/d`) over the `k` smallest `d(c)`.
//!
//! **Shared-AP form (wipdr's extension, not paper 004).** With
//! [`MedConfig::metric`] = [`MedMetric::SharedAp`] each scan is compared with the same
//! database point as above, but by the shared-AP distance of [`crate::distance::SharedAp`]
//! (mean `|dRSSI|` over the APs both heard plus `lambda * non-shared / union`, the default
//! single-scan distance on recorded walks, docs/experiments.md), evaluated by the sparse engine of
//! [`KnnMatcher`] exactly as single-scan shared-AP WKNN evaluates it. The per-scan distances
//! `d_i` combine as their root mean square over the scans in the window,
//! `d(c) = sqrt( sum_i d_i^2 / n )` (`n` = scans held, at most `w`): the root of a sum of
//! squares across scans is what eq. 11 does with the per-scan terms, and dividing by `n` keeps
//! `d(c)` in dB on the scale of one scan's shared-AP distance (so `w = 1` is exactly
//! single-scan shared-AP WKNN). Squares rather than a plain mean make a candidate that fits one
//! scan badly rank worse than one that fits every scan moderately. Each scan's distances to
//! every reference point are computed once, when the scan arrives, and kept while it is in
//! the window. The default [`MedMetric::Euclidean`] is the paper's form above.
//!
//! The matcher is stateful: [`MedMatcher::locate_next`] takes the displacement since the
//! previous scan, updates every stored displacement and keeps the last `w - 1` scans;
//! [`MedMatcher::reset`] forgets them (start of a walk). [`Matcher::locate`] is the
//! stateless single-scan form (`w = 1`).
//!
//! ```
//! use wipdr_fingerprint::med::{MedConfig, MedMatcher};
//! use wipdr_fingerprint::{Query, QueryFilter, RadioMap, RadioMapConfig};
//! use wipdr_core::{FingerprintLabel, FingerprintTable, Vector2};
//! let mut t = FingerprintTable::new(vec!["ap_000".into(), "ap_001".into()]);
//! for (i, rss) in [[-40.0, -80.0], [-50.0, -70.0], [-60.0, -60.0], [-70.0, -50.0]].iter().enumerate() {
//!     t.push_row(rss, FingerprintLabel::at(i as f64, 0.0, 0)).unwrap();
//! }
//! let map = RadioMap::from_table(&t, RadioMapConfig::default()).unwrap();
//! let mut med = MedMatcher::new(map, MedConfig { k: 1, ..MedConfig::default() }).unwrap();
//! let f = QueryFilter::default();
//! let q1 = Query::from_row(&[-50.0, -70.0], med.map_ref(), &f).unwrap();
//! med.locate_next(&q1, Vector2::zeros()).unwrap();
//! let q2 = Query::from_row(&[-60.0, -60.0], med.map_ref(), &f).unwrap();
//! let obs = med.locate_next(&q2, Vector2::new(1.0, 0.0)).unwrap();
//! assert_eq!(obs.candidates[0].index, 2);
//! ```

use crate::cluster_search::dense_query;
use crate::distance::{Metric, Representation, SharedAp};
use crate::matcher::{Weighting, observation_from_neighbours};
use crate::mixdis::squared_euclidean;
use crate::{FingerprintError, KnnConfig, KnnMatcher, Matcher, Query, RadioMap};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;
use std::sync::Arc;
use wipdr_core::{Point2, Vector2, WifiObservation};

/// Settings of the MED matcher (paper 004 defaults).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MedConfig {
    /// Scans in the window, the current one included (paper 004 Table 3: 2 best).
    pub window: usize,
    /// WKNN neighbours.
    pub k: usize,
    /// WKNN weighting.
    pub weighting: Weighting,
    /// Per-scan signal distance (default: the paper's Euclidean form; absent from a config
    /// file = Euclidean). In TOML: `[med.metric]` with `kind = "euclidean"` or
    /// `kind = "shared_ap"` and `lambda = 60.0`.
    pub metric: MedMetric,
}

impl Default for MedConfig {
    fn default() -> Self {
        Self {
            window: 2,
            k: 5,
            weighting: Weighting::InverseDistance { power: 1.0 },
            metric: MedMetric::Euclidean,
        }
    }
}

/// The per-scan signal distance of MED and how the window combines it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum MedMetric {
    /// Paper 004 eq. 11 in its Euclidean form: squared differences of the dense fingerprints
    /// ("not heard" = the map's fill value) summed over APs and scans, then the root.
    #[default]
    Euclidean,
    /// wipdr's extension: the shared-AP distance per scan ([`SharedAp`], as single-scan
    /// shared-AP WKNN computes it), combined as the root mean square over the window's scans.
    SharedAp(SharedAp),
}

impl MedMetric {
    /// Short name (`euclidean`, `shared_ap`).
    pub fn name(&self) -> &'static str {
        match self {
            MedMetric::Euclidean => "euclidean",
            MedMetric::SharedAp(_) => "shared_ap",
        }
    }
}

/// What a past scan keeps for later comparisons.
#[derive(Debug, Clone)]
enum ScanSignal {
    /// Euclidean form: the dense fingerprint.
    Dense(Vec<f32>),
    /// Shared-AP form: the scan's shared-AP distance to every reference point, map order.
    Distances(Vec<f32>),
}

/// A past scan: its signal and the displacement from where it was taken to now.
#[derive(Debug, Clone)]
struct PastScan {
    signal: ScanSignal,
    since: Vector2,
}

/// The `med` matcher.
#[derive(Debug, Clone)]
pub struct MedMatcher {
    map: Arc<RadioMap>,
    config: MedConfig,
    /// The shared-AP engine over the same map (`Some` for [`MedMetric::SharedAp`]).
    shared_ap: Option<Arc<KnnMatcher>>,
    history: VecDeque<PastScan>,
}

impl MedMatcher {
    /// A matcher with an empty history. Errors on an empty map, `window` or `k` of 0, or a
    /// shared-AP `lambda` that is not finite and >= 0.
    pub fn new(map: impl Into<Arc<RadioMap>>, config: MedConfig) -> Result<Self, FingerprintError> {
        let map: Arc<RadioMap> = map.into();
        if map.is_empty() {
            return Err(FingerprintError::EmptyMap);
        }
        if config.window == 0 || config.k == 0 {
            return Err(FingerprintError::InvalidConfig(
                wipdr_core::ConfigError::new("med", "window and k must be at least 1"),
            ));
        }
        let shared_ap = match config.metric {
            MedMetric::Euclidean => None,
            MedMetric::SharedAp(d) => {
                if !(d.lambda.is_finite() && d.lambda >= 0.0) {
                    return Err(FingerprintError::InvalidConfig(
                        wipdr_core::ConfigError::new(
                            "med.distance",
                            format!("shared_ap lambda must be finite and >= 0, got {}", d.lambda),
                        ),
                    ));
                }
                // Raw representation: "not heard" is 0, so the sparse engine is used.
                let knn = KnnMatcher::new(
                    Arc::clone(&map),
                    KnnConfig {
                        k: config.k,
                        weighting: config.weighting,
                        metric: Metric::SharedAp(d),
                        representation: Representation::Raw,
                    },
                )?;
                Some(Arc::new(knn))
            }
        };
        Ok(Self {
            map,
            config,
            shared_ap,
            history: VecDeque::new(),
        })
    }

    /// The configuration.
    pub fn config(&self) -> &MedConfig {
        &self.config
    }

    /// The radio map.
    pub fn map_ref(&self) -> &RadioMap {
        &self.map
    }

    /// Forgets the scan history.
    pub fn reset(&mut self) {
        self.history.clear();
    }

    /// Past scans held (at most `window - 1`).
    pub fn history_len(&self) -> usize {
        self.history.len()
    }

    /// Index of the reference point nearest to `p` on the same building/floor as `like`.
    fn nearest_point(&self, p: Point2, like: usize) -> usize {
        let (b, f) = (self.map.point(like).building, self.map.point(like).floor);
        let mut best = like;
        let mut best_d = f64::INFINITY;
        for (i, rp) in self.map.points().iter().enumerate() {
            if rp.building == b && rp.floor == f {
                let d = (rp.position - p).norm_squared();
                if d < best_d {
                    best_d = d;
                    best = i;
                }
            }
        }
        best
    }

    /// The current scan's signal: the dense fingerprint (Euclidean) or its shared-AP
    /// distance to every reference point.
    fn signal_of(&self, query: &Query) -> Result<ScanSignal, FingerprintError> {
        match &self.shared_ap {
            None => Ok(ScanSignal::Dense(dense_query(&self.map, query)?)),
            Some(knn) => Ok(ScanSignal::Distances(knn.distances(query)?)),
        }
    }

    /// MED over the current scan and the stored history, for every reference point.
    fn distances(&self, current: &ScanSignal) -> Vec<f64> {
        let scans = (self.history.len() + 1) as f64;
        (0..self.map.len())
            .into_par_iter()
            .map(|c| {
                let pc = self.map.point(c).position;
                let mut sum = Self::squared_term(current, &self.map, c);
                for past in &self.history {
                    let j = self.nearest_point(pc - past.since, c);
                    sum += Self::squared_term(&past.signal, &self.map, j);
                }
                match current {
                    ScanSignal::Dense(_) => sum.sqrt(),
                    ScanSignal::Distances(_) => (sum / scans).sqrt(),
                }
            })
            .collect()
    }

    /// One scan's squared term against reference point `j`: the squared Euclidean distance
    /// of the dense fingerprints, or the square of the shared-AP distance.
    fn squared_term(signal: &ScanSignal, map: &RadioMap, j: usize) -> f64 {
        match signal {
            ScanSignal::Dense(q) => f64::from(squared_euclidean(q, map.filled_row(j))),
            ScanSignal::Distances(d) => {
                let d = f64::from(d[j]);
                d * d
            }
        }
    }

    /// Locates the next scan of a walk. `displacement` is the PDR displacement (metres, map
    /// frame) from the previous scan to this one (ignored for the first scan).
    pub fn locate_next(
        &mut self,
        query: &Query,
        displacement: Vector2,
    ) -> Result<WifiObservation, FingerprintError> {
        if query.heard.is_empty() {
            return Err(FingerprintError::EmptyScan);
        }
        if !(displacement.x.is_finite() && displacement.y.is_finite()) {
            return Err(FingerprintError::InvalidInput(
                "med: non-finite displacement".into(),
            ));
        }
        let signal = self.signal_of(query)?;
        for past in &mut self.history {
            past.since += displacement;
        }
        let obs = self.locate_signal(query, &signal)?;
        self.history.push_back(PastScan {
            signal,
            since: Vector2::zeros(),
        });
        while self.history.len() + 1 > self.config.window {
            self.history.pop_front();
        }
        Ok(obs)
    }

    fn locate_signal(
        &self,
        query: &Query,
        signal: &ScanSignal,
    ) -> Result<WifiObservation, FingerprintError> {
        let d = self.distances(signal);
        let neighbours = crate::knn::top_k(
            &d.iter().map(|&v| v as f32).collect::<Vec<_>>(),
            self.config.k,
        );
        let neighbours: Vec<(usize, f64)> =
            neighbours.into_iter().map(|(i, _)| (i, d[i])).collect();
        observation_from_neighbours(
            &self.map,
            query,
            &neighbours,
            self.config.weighting,
            self.map.len(),
        )
    }
}

impl Matcher for MedMatcher {
    fn name(&self) -> String {
        match self.config.metric {
            MedMetric::Euclidean => {
                format!("med(window={},k={})", self.config.window, self.config.k)
            }
            MedMetric::SharedAp(d) => format!(
                "med(window={},k={},shared_ap,lambda={})",
                self.config.window, self.config.k, d.lambda
            ),
        }
    }

    fn map(&self) -> &RadioMap {
        &self.map
    }

    /// Single-scan form (no history): plain Euclidean WKNN, or shared-AP WKNN with
    /// [`MedMetric::SharedAp`].
    fn locate(&self, query: &Query) -> Result<WifiObservation, FingerprintError> {
        if query.heard.is_empty() {
            return Err(FingerprintError::EmptyScan);
        }
        let signal = self.signal_of(query)?;
        let single = Self {
            map: Arc::clone(&self.map),
            config: self.config,
            shared_ap: self.shared_ap.clone(),
            history: VecDeque::new(),
        };
        single.locate_signal(query, &signal)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{QueryFilter, RadioMapConfig};

    /// Two places with the same fingerprint (x = 1 and x = 6) that only the past scan tells
    /// apart.
    fn ambiguous() -> RadioMap {
        let t = crate::test_table(
            2,
            &[
                (&[-40.0, -80.0], 0.0),
                (&[-60.0, -60.0], 1.0),
                (&[-45.0, -45.0], 5.0),
                (&[-60.0, -60.0], 6.0),
            ],
        );
        RadioMap::from_table(&t, RadioMapConfig::default()).unwrap()
    }

    #[test]
    fn history_disambiguates_identical_fingerprints() {
        let map = ambiguous();
        let f = QueryFilter::default();
        let cfg = MedConfig {
            k: 1,
            ..MedConfig::default()
        };
        for (first, expect) in [([-45.0, -45.0], 3usize), ([-40.0, -80.0], 1)] {
            let mut med = MedMatcher::new(map.clone(), cfg).unwrap();
            let q1 = Query::from_row(&first, &map, &f).unwrap();
            med.locate_next(&q1, Vector2::zeros()).unwrap();
            let q2 = Query::from_row(&[-60.0, -60.0], &map, &f).unwrap();
            let obs = med.locate_next(&q2, Vector2::new(1.0, 0.0)).unwrap();
            assert_eq!(obs.candidates[0].index, expect);
            assert_eq!(med.history_len(), 1);
        }
    }

    #[test]
    fn window_one_equals_single_scan_and_distance_is_euclidean() {
        let map = ambiguous();
        let f = QueryFilter::default();
        let mut med = MedMatcher::new(
            map.clone(),
            MedConfig {
                window: 1,
                k: 1,
                ..Default::default()
            },
        )
        .unwrap();
        let q = Query::from_row(&[-57.0, -64.0], &map, &f).unwrap();
        let a = med.locate_next(&q, Vector2::zeros()).unwrap();
        let b = med.locate(&q).unwrap();
        assert_eq!(a.candidates[0].index, b.candidates[0].index);
        assert!((a.candidates[0].distance - 5.0).abs() < 1e-9);
        assert_eq!(med.history_len(), 0);
    }

    /// Three APs, some not heard (100 in the CSV), on a line x = 0, 1, 2.
    fn partial() -> RadioMap {
        let t = crate::test_table(
            3,
            &[
                (&[-40.0, -80.0, 100.0], 0.0),
                (&[-60.0, -60.0, -70.0], 1.0),
                (&[100.0, -50.0, -70.0], 2.0),
            ],
        );
        RadioMap::from_table(&t, RadioMapConfig::default()).unwrap()
    }

    fn shared_ap(lambda: f32, window: usize, k: usize) -> MedConfig {
        MedConfig {
            window,
            k,
            metric: MedMetric::SharedAp(SharedAp {
                lambda,
                ..SharedAp::default()
            }),
            ..MedConfig::default()
        }
    }

    /// `(index, distance)` of every candidate, best first.
    fn ranked(obs: &WifiObservation) -> Vec<(usize, f64)> {
        obs.candidates
            .iter()
            .map(|c| (c.index, c.distance))
            .collect()
    }

    fn assert_ranked(got: &[(usize, f64)], want: &[(usize, f64)]) {
        assert_eq!(got.len(), want.len(), "{got:?} vs {want:?}");
        for (g, w) in got.iter().zip(want) {
            assert_eq!(g.0, w.0, "{got:?} vs {want:?}");
            assert!((g.1 - w.1).abs() < 1e-4, "{got:?} vs {want:?}");
        }
    }

    #[test]
    fn default_metric_is_the_euclidean_form_by_hand() {
        assert_eq!(MedConfig::default().metric, MedMetric::Euclidean);
        let map = ambiguous();
        let f = QueryFilter::default();
        let mut med = MedMatcher::new(
            map.clone(),
            MedConfig {
                k: 4,
                ..MedConfig::default()
            },
        )
        .unwrap();
        assert_eq!(med.name(), "med(window=2,k=4)");
        let q1 = Query::from_row(&[-45.0, -45.0], &map, &f).unwrap();
        med.locate_next(&q1, Vector2::zeros()).unwrap();
        let q2 = Query::from_row(&[-60.0, -60.0], &map, &f).unwrap();
        let obs = med.locate_next(&q2, Vector2::new(1.0, 0.0)).unwrap();
        // d(c) = sqrt(|q2 - x_c|^2 + |q1 - x_nearest(p_c - 1)|^2):
        // c = 3 (x 6): 0 + |q1 - x_2|^2 = 0; c = 2 (x 5, past at x 4 -> point 2): 450 + 0;
        // c = 1 (x 1, past at x 0 -> point 0): 0 + 25 + 1225; c = 0: 800 + 1250.
        assert_ranked(
            &ranked(&obs),
            &[
                (3, 0.0),
                (2, 450f64.sqrt()),
                (1, 1250f64.sqrt()),
                (0, 2050f64.sqrt()),
            ],
        );
    }

    #[test]
    fn shared_ap_window_two_by_hand() {
        let map = partial();
        let f = QueryFilter::default();
        let mut med = MedMatcher::new(map.clone(), shared_ap(10.0, 2, 3)).unwrap();
        assert_eq!(med.name(), "med(window=2,k=3,shared_ap,lambda=10)");
        // Scan 1 (heard by all three APs) against points 0, 1, 2:
        // 0: shared {0,1} mean 20, 1 of 3 not shared -> 20 + 10/3; 1: exact -> 0;
        // 2: shared {1,2} mean 5, 1 of 3 not shared -> 5 + 10/3.
        let q1 = Query::from_row(&[-60.0, -60.0, -70.0], &map, &f).unwrap();
        let first = med.locate_next(&q1, Vector2::zeros()).unwrap();
        assert_ranked(
            &ranked(&first),
            &[(1, 0.0), (2, 5.0 + 10.0 / 3.0), (0, 20.0 + 10.0 / 3.0)],
        );
        // Scan 2 (AP 0 not heard), one metre on:
        // 0: shared {1} mean 28, 2 of 3 not shared -> 28 + 20/3; 1: shared {1,2} mean 4,
        // 1 of 3 -> 4 + 10/3; 2: shared {1,2} mean 1, union {1,2} -> 1.
        let q2 = Query::from_row(&[100.0, -52.0, -70.0], &map, &f).unwrap();
        let obs = med.locate_next(&q2, Vector2::new(1.0, 0.0)).unwrap();
        // Past scan against the point nearest p_c - 1: c 0 -> 0, c 1 -> 0, c 2 -> 1.
        let rms = |a: f64, b: f64| ((a * a + b * b) / 2.0).sqrt();
        let s1 = [20.0 + 10.0 / 3.0, 0.0, 5.0 + 10.0 / 3.0];
        let s2 = [28.0 + 20.0 / 3.0, 4.0 + 10.0 / 3.0, 1.0];
        assert_ranked(
            &ranked(&obs),
            &[
                (2, rms(s2[2], s1[1])),
                (1, rms(s2[1], s1[0])),
                (0, rms(s2[0], s1[0])),
            ],
        );
        assert_eq!(med.history_len(), 1);
    }

    #[test]
    fn shared_ap_history_disambiguates_identical_fingerprints() {
        let map = ambiguous();
        let f = QueryFilter::default();
        let q2 = Query::from_row(&[-60.0, -60.0], &map, &f).unwrap();
        // One scan alone ties points 1 and 3 (same fingerprint): the lower index wins.
        let single = MedMatcher::new(map.clone(), shared_ap(60.0, 2, 1)).unwrap();
        assert_eq!(single.locate(&q2).unwrap().candidates[0].index, 1);
        for (first, expect) in [([-45.0, -45.0], 3usize), ([-40.0, -80.0], 1)] {
            let mut med = MedMatcher::new(map.clone(), shared_ap(60.0, 2, 1)).unwrap();
            let q1 = Query::from_row(&first, &map, &f).unwrap();
            med.locate_next(&q1, Vector2::zeros()).unwrap();
            let obs = med.locate_next(&q2, Vector2::new(1.0, 0.0)).unwrap();
            assert_eq!(obs.candidates[0].index, expect);
            assert_eq!(obs.candidates[0].distance, 0.0);
        }
    }

    #[test]
    fn shared_ap_window_one_equals_single_scan_shared_ap_wknn() {
        let map = partial();
        let f = QueryFilter::default();
        let knn = KnnMatcher::new(
            map.clone(),
            KnnConfig {
                k: 2,
                metric: Metric::SharedAp(SharedAp {
                    lambda: 60.0,
                    ..SharedAp::default()
                }),
                ..KnnConfig::default()
            },
        )
        .unwrap();
        let mut med = MedMatcher::new(map.clone(), shared_ap(60.0, 1, 2)).unwrap();
        for row in [
            [-50.0, -70.0, 100.0],
            [-61.0, -58.0, -75.0],
            [100.0, -49.0, 100.0],
        ] {
            let q = Query::from_row(&row, &map, &f).unwrap();
            let a = med.locate_next(&q, Vector2::new(1.0, 0.0)).unwrap();
            let b = knn.locate(&q).unwrap();
            assert_eq!(ranked(&a), ranked(&b));
            assert_eq!(a.estimate, b.estimate);
            assert_eq!(med.history_len(), 0);
        }
    }

    #[test]
    fn config_parsing_keeps_old_files_and_names_unknown_metrics() {
        // Old configs without `metric` keep the Euclidean form (same serde derive as TOML).
        let old: MedConfig = serde_json::from_str(r#"{"window": 3}"#).unwrap();
        assert_eq!(
            old,
            MedConfig {
                window: 3,
                ..MedConfig::default()
            }
        );
        let new: MedConfig =
            serde_json::from_str(r#"{"metric": {"kind": "shared_ap", "lambda": 60.0}}"#).unwrap();
        assert_eq!(
            new.metric,
            MedMetric::SharedAp(SharedAp {
                lambda: 60.0,
                ..SharedAp::default()
            })
        );
        assert_eq!(new.metric.name(), "shared_ap");
        let back: MedConfig = serde_json::from_str(&serde_json::to_string(&new).unwrap()).unwrap();
        assert_eq!(back, new);
        let err = serde_json::from_str::<MedConfig>(r#"{"metric": {"kind": "cosine"}}"#)
            .unwrap_err()
            .to_string();
        assert!(err.contains("cosine"), "{err}");
    }

    #[test]
    fn bad_shared_ap_lambda_rejected() {
        for lambda in [f32::NAN, -1.0, f32::INFINITY] {
            assert!(MedMatcher::new(ambiguous(), shared_ap(lambda, 2, 1)).is_err());
        }
    }
}

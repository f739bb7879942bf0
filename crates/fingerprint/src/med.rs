//! Multi-scan Euclidean distance matcher `med` (paper 004 eq. 11, Table 3).
//!
//! The printed eq. 11 sums signed differences without square or root; algorithms.md fixes it
//! to the Euclidean form the name says:
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
//! The matcher is stateful: [`MedMatcher::locate_next`] takes the displacement since the
//! previous scan, updates every stored displacement and keeps the last `w - 1` scans;
//! [`MedMatcher::reset`] forgets them (start of a walk). [`Matcher::locate`] is the
//! stateless single-scan form (`w = 1`).
//!
//! ```
//! use wipdr_fingerprint::med::{MedConfig, MedMatcher};
//! use wipdr_fingerprint::{Query, QueryFilter, RadioMap, RadioMapConfig};
//! use wipdr_io::fingerprint_csv::read_fingerprint_csv_from;
//! use wipdr_core::Vector2;
//! let csv = "ap_000,ap_001,x,y,z,floor,building\n\
//!            -40,-80,0,0,0,0,0\n-50,-70,1,0,0,0,0\n-60,-60,2,0,0,0,0\n-70,-50,3,0,0,0,0\n";
//! let t = read_fingerprint_csv_from(csv.as_bytes(), "inline").unwrap();
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
use crate::matcher::{Weighting, observation_from_neighbours};
use crate::mixdis::squared_euclidean;
use crate::{FingerprintError, Matcher, Query, RadioMap};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;
use std::sync::Arc;
use wipdr_core::{Point2, Vector2, WifiObservation};

/// Settings of the MED matcher (paper 004 defaults).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct MedConfig {
    /// Scans in the window, the current one included (paper 004 Table 3: 2 best).
    pub window: usize,
    /// WKNN neighbours.
    pub k: usize,
    /// WKNN weighting.
    pub weighting: Weighting,
}

impl Default for MedConfig {
    fn default() -> Self {
        Self {
            window: 2,
            k: 5,
            weighting: Weighting::InverseDistance { power: 1.0 },
        }
    }
}

/// A past scan: its dense fingerprint and the displacement from where it was taken to now.
#[derive(Debug, Clone)]
struct PastScan {
    dense: Vec<f32>,
    since: Vector2,
}

/// The `med` matcher.
#[derive(Debug, Clone)]
pub struct MedMatcher {
    map: Arc<RadioMap>,
    config: MedConfig,
    history: VecDeque<PastScan>,
}

impl MedMatcher {
    /// A matcher with an empty history.
    pub fn new(map: impl Into<Arc<RadioMap>>, config: MedConfig) -> Result<Self, FingerprintError> {
        let map: Arc<RadioMap> = map.into();
        if map.is_empty() {
            return Err(FingerprintError::EmptyMap);
        }
        if config.window == 0 || config.k == 0 {
            return Err(FingerprintError::InvalidConfig(
                "med: window and k must be at least 1".into(),
            ));
        }
        Ok(Self {
            map,
            config,
            history: VecDeque::new(),
        })
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
        let (b, f) = (self.map.points[like].building, self.map.points[like].floor);
        let mut best = like;
        let mut best_d = f64::INFINITY;
        for (i, rp) in self.map.points.iter().enumerate() {
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

    /// MED over the current scan `q` and the stored history, for every reference point.
    fn distances(&self, q: &[f32]) -> Vec<f64> {
        (0..self.map.len())
            .into_par_iter()
            .map(|c| {
                let mut sum = f64::from(squared_euclidean(q, self.map.filled_row(c)));
                let pc = self.map.points[c].position;
                for past in &self.history {
                    let j = self.nearest_point(pc - past.since, c);
                    sum += f64::from(squared_euclidean(&past.dense, self.map.filled_row(j)));
                }
                sum.sqrt()
            })
            .collect()
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
            return Err(FingerprintError::InvalidConfig(
                "med: non-finite displacement".into(),
            ));
        }
        for past in &mut self.history {
            past.since += displacement;
        }
        let q = dense_query(&self.map, query)?;
        let obs = self.locate_dense(query, &q)?;
        self.history.push_back(PastScan {
            dense: q,
            since: Vector2::zeros(),
        });
        while self.history.len() + 1 > self.config.window {
            self.history.pop_front();
        }
        Ok(obs)
    }

    fn locate_dense(&self, query: &Query, q: &[f32]) -> Result<WifiObservation, FingerprintError> {
        let d = self.distances(q);
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
        format!("med(window={},k={})", self.config.window, self.config.k)
    }

    fn map(&self) -> &RadioMap {
        &self.map
    }

    /// Single-scan form (no history): plain Euclidean WKNN.
    fn locate(&self, query: &Query) -> Result<WifiObservation, FingerprintError> {
        if query.heard.is_empty() {
            return Err(FingerprintError::EmptyScan);
        }
        let q = dense_query(&self.map, query)?;
        let single = Self {
            map: Arc::clone(&self.map),
            config: self.config,
            history: VecDeque::new(),
        };
        single.locate_dense(query, &q)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{QueryFilter, RadioMapConfig};
    use wipdr_io::fingerprint_csv::read_fingerprint_csv_from;

    /// Two places with the same fingerprint (x = 1 and x = 6) that only the past scan tells
    /// apart.
    fn ambiguous() -> RadioMap {
        let csv = "ap_000,ap_001,x,y,z,floor,building\n\
                   -40,-80,0,0,0,0,0\n-60,-60,1,0,0,0,0\n-45,-45,5,0,0,0,0\n-60,-60,6,0,0,0,0\n";
        let t = read_fingerprint_csv_from(csv.as_bytes(), "t").unwrap();
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
}

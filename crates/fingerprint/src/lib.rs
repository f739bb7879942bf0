//! # wipdr-fingerprint — Wi-Fi fingerprinting: radio maps and matchers
//!
//! Turns a Wi-Fi scan into a position by comparing it with a radio map of reference
//! fingerprints. Implements the radio map of paper 000 §2.1 (eq. 2) and paper 001 §4.1, the
//! NN / KNN / WKNN estimators of paper 000 eq. 3-4, paper 001 eq. 7 and paper 002 eq. 1-3 with
//! online filtering (paper 002 §3.2.1), and the deterministic k-NN variants of the literature
//! (Torres-Sospedra et al. 2015: data representations and distances), by fast exact brute
//! force.
//!
//! ## The pieces
//!
//! - [`RadioMap`]: reference points ([`ReferencePoint`]: position, optional floor/building)
//!   with mean RSS, sample count and spread per AP, an AP vocabulary ([`ApVocabulary`], BSSID
//!   or column name <-> column) and a "not heard" fill value (default -110 dBm). Built from
//!   fingerprint tables ([`RadioMap::from_table`], e.g. the benchmark CSVs read by
//!   `wipdr_io::fingerprint_csv`) or recorded walks ([`walk_map`]); serde and
//!   bincode.
//! - [`Query`]: what every matcher takes: the heard APs as sorted `(column, dBm)` pairs. A real
//!   [`wipdr_core::WifiScan`] ([`Query::from_scan`]) and a benchmark row ([`Query::from_row`])
//!   both become one, through the same [`QueryFilter`] (RSSI threshold, staleness; unknown APs
//!   ignored and counted in [`QueryStats`]).
//! - [`Matcher`]: **the one matcher trait**. `locate(&Query) -> WifiObservation`: estimate, K
//!   candidates (position, signal distance, weight, map index) ordered by distance, the number
//!   of reference points visited, floor/building by majority. See the trait for the full
//!   contract; [`observation_from_neighbours`] is the shared last step (weights, estimate,
//!   majority) for any matcher that ends in a k-NN.
//! - [`KnnMatcher`] with [`KnnConfig`]: NN, KNN, WKNN (`1/d^w`), over the distances of
//!   [`distance`] (Manhattan, Euclidean, squared Euclidean, Sørensen, Neyman, PLGD, shared-AP)
//!   and representations (raw, positive, exponential, powed).
//!
//! ```
//! use wipdr_fingerprint::{KnnConfig, KnnMatcher, Matcher, Query, QueryFilter, RadioMap, RadioMapConfig};
//! use wipdr_core::{FingerprintLabel, FingerprintTable};
//!
//! let nh = FingerprintTable::NOT_HEARD;
//! let mut table = FingerprintTable::new(vec!["ap_000".into(), "ap_001".into(), "ap_002".into()]);
//! table.push_row(&[-40.0, -70.0, nh], FingerprintLabel::at(0.0, 0.0, 0)).unwrap();
//! table.push_row(&[-70.0, -40.0, -80.0], FingerprintLabel::at(10.0, 0.0, 0)).unwrap();
//! table.push_row(&[nh, -70.0, -40.0], FingerprintLabel::at(20.0, 0.0, 1)).unwrap();
//! let map = RadioMap::from_table(&table, RadioMapConfig::default()).unwrap();
//! let wknn = KnnMatcher::new(map, KnnConfig::wknn(2, 1.0)).unwrap();
//! let query = Query::from_row(&[-45.0, -68.0, nh], wknn.map(), &QueryFilter::default()).unwrap();
//! let obs = wknn.locate(&query).unwrap();
//! assert_eq!(obs.candidates[0].index, 0);
//! assert!(obs.estimate.x > 0.0 && obs.estimate.x < 10.0);
//! assert_eq!(obs.floor, Some(0));
//! ```

pub mod distance;
pub mod error;
pub mod interpolate;
pub mod knn;
pub mod likelihood;
pub mod matcher;
pub mod online;
pub mod query;
pub mod radio_map;
mod records;
pub mod walk_map;

pub use distance::{Distance, Metric, Representation};
pub use error::{FingerprintError, LimitError};
pub use knn::{FloorFirstMatcher, KnnConfig, KnnMatcher};
pub use matcher::{Matcher, Weighting, majority, observation_from_neighbours, weights_of};
pub use online::{MatcherConfig, MatcherModel, OnlineMatcher, ScanContext};
pub use query::{Query, QueryFilter, QueryStats};
pub use radio_map::{ApVocabulary, RadioMap, RadioMapConfig, ReferencePoint};

pub mod affinity;
pub mod ap_index;
pub mod cluster_search;
pub mod kmeans;
pub mod med;
pub mod mixdis;
pub mod propagation;

/// Tables built in code for the unit tests: one row per `(rss, x)`, at `y = 0` on floor 0.
#[cfg(test)]
pub(crate) fn test_table(n_aps: usize, rows: &[(&[f32], f64)]) -> wipdr_core::FingerprintTable {
    let names = (0..n_aps).map(|j| format!("ap_{j:03}")).collect();
    let mut t = wipdr_core::FingerprintTable::new(names);
    for &(rss, x) in rows {
        t.push_row(rss, wipdr_core::FingerprintLabel::at(x, 0.0, 0))
            .expect("test row length");
    }
    t
}

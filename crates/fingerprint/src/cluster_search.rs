//! Cluster-search matcher `apc` (paper 001 §2.3) over an affinity-propagation clustering of
//! the radio map (paper 001 §2.1-2.2).
//!
//! Offline: the reference points are grouped by (building, floor) (the paper's map is one
//! floor; GeoDis across floors means nothing), and each group is clustered with
//! [`affinity_propagation`](crate::affinity::affinity_propagation) on `-MixDis` (or the
//! signal similarity). Each cluster keeps its exemplar, its members, its *AP set* (the APs
//! heard at the exemplar) and its centre vector (the exemplar's fingerprint, or the members'
//! mean).
//!
//! Online, for a query:
//! 1. take the `n_strongest` (3-5, default 3) strongest heard APs of the query and keep the
//!    clusters whose AP set contains all of them;
//! 2. among those, pick the cluster whose centre is nearest in signal space (Euclidean over the
//!    filled vectors);
//! 3. WKNN (paper 001 eq. 7) inside it, with the brute-force engine's compact layout
//!    restricted to the members ([`KnnMatcher::locate_among`]; Euclidean on raw dBm by
//!    default, distance and representation configurable).
//!
//! Fallback when no cluster matches (configurable): drop the weakest of the `N` APs and try
//! again down to 1 AP, then compare with every cluster centre. `visited` counts the centres
//! compared plus the members searched.
//!
//! ```
//! use wipdr_fingerprint::cluster_search::{ClusterSearchConfig, ClusterSearchMatcher};
//! use wipdr_fingerprint::{Matcher, Query, QueryFilter, RadioMap, RadioMapConfig};
//! use wipdr_core::{FingerprintLabel, FingerprintTable};
//! let mut table = FingerprintTable::new(vec!["ap_000".into(), "ap_001".into(), "ap_002".into()]);
//! for i in 0..10 {
//!     let (a, b) = if i < 5 { (-40 - i, -80) } else { (-80, -40 - i) };
//!     let label = FingerprintLabel::at(f64::from(i), 0.0, 0);
//!     table.push_row(&[a as f32, b as f32, -70.0], label).unwrap();
//! }
//! let map = RadioMap::from_table(&table, RadioMapConfig::default()).unwrap();
//! let apc = ClusterSearchMatcher::build(map, &ClusterSearchConfig::default()).unwrap();
//! let q = Query::from_row(&[-42.0, -80.0, -70.0], apc.map(), &QueryFilter::default()).unwrap();
//! let obs = apc.locate(&q).unwrap();
//! assert!(obs.estimate.x < 5.0);
//! assert!(obs.visited < 10);
//! ```

use crate::affinity::{AffinityConfig, AffinityError, affinity_propagation_owned};
use crate::distance::{Metric, Representation};
use crate::kmeans::{KMeansConfig, kmeans};
use crate::matcher::Weighting;
use crate::mixdis::{
    MixDisConfig, OwnedFingerprints, SimilarityKind, similarity, squared_euclidean,
};
use crate::{FingerprintError, KnnConfig, KnnMatcher, Matcher, Query, RadioMap};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::sync::Arc;
use wipdr_core::WifiObservation;

/// What a cluster's centre vector is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum ClusterCentre {
    /// The exemplar's fingerprint (affinity propagation's centre).
    #[default]
    Exemplar,
    /// The mean of the members' filled fingerprints.
    Mean,
}

/// What to do when no cluster's AP set holds the query's `N` strongest APs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum ClusterFallback {
    /// Drop the weakest of the `N` APs and retry down to 1, then use every cluster.
    #[default]
    ReduceThenAll,
    /// Use every cluster at once.
    AllClusters,
}

/// How the map is clustered.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum ClusterMethod {
    /// Affinity propagation (paper 001 §2.2).
    #[default]
    AffinityPropagation,
    /// K-means baseline ([`crate::kmeans`]) with `ceil(points / mean_size)` clusters per
    /// (building, floor) group; the exemplar is the member nearest to the centroid.
    KMeans {
        /// Target mean cluster size.
        mean_size: usize,
    },
}

/// Settings of the cluster-search matcher (paper 001 defaults).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ClusterSearchConfig {
    /// Strongest online APs a cluster's AP set must contain (paper: 3-5).
    pub n_strongest: usize,
    /// Neighbours of the WKNN inside the cluster (paper 001 eq. 7).
    pub k: usize,
    /// WKNN weighting (paper 001 eq. 7: `1/d`).
    pub weighting: Weighting,
    /// Signal distance of the WKNN inside the clusters (paper 001: Euclidean). The nearest
    /// centre is always Euclidean over the filled vectors (step 2).
    pub metric: Metric,
    /// Data representation of the WKNN inside the clusters (raw dBm, as the paper).
    pub representation: Representation,
    /// Clustering similarity (paper: MixDis).
    pub similarity: SimilarityKind,
    /// MixDis settings.
    pub mixdis: MixDisConfig,
    /// Affinity-propagation settings (paper: row-median preference, damping 0.9).
    pub affinity: AffinityConfig,
    /// Cluster centre vector.
    pub centre: ClusterCentre,
    /// Fallback.
    pub fallback: ClusterFallback,
    /// Also search the members of clusters whose centre is within this factor of the nearest
    /// centre distance (1.0 = only the nearest cluster, the paper's rule).
    pub centre_slack: f64,
    /// Search the members of this many nearest clusters (1 = the paper's rule); combined with
    /// `centre_slack`, the larger set wins.
    pub clusters_searched: usize,
    /// Clustering method (paper: affinity propagation).
    pub method: ClusterMethod,
}

impl Default for ClusterSearchConfig {
    fn default() -> Self {
        Self {
            n_strongest: 3,
            k: 5,
            weighting: Weighting::InverseDistance { power: 1.0 },
            metric: Metric::Euclidean,
            representation: Representation::Raw,
            similarity: SimilarityKind::MixDis,
            mixdis: MixDisConfig::default(),
            affinity: AffinityConfig::default(),
            centre: ClusterCentre::Exemplar,
            fallback: ClusterFallback::ReduceThenAll,
            centre_slack: 1.0,
            clusters_searched: 1,
            method: ClusterMethod::AffinityPropagation,
        }
    }
}

/// One cluster of the map.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MapCluster {
    /// Map index of the exemplar.
    pub exemplar: usize,
    /// Map indices of the members (exemplar included).
    pub members: Vec<usize>,
    /// AP columns heard at the exemplar, ascending.
    pub ap_set: Vec<u32>,
    /// Centre vector (filled, one value per AP column).
    pub centre: Vec<f32>,
}

impl ClusterSearchConfig {
    /// The WKNN run inside the chosen clusters.
    pub fn inner(&self) -> KnnConfig {
        KnnConfig {
            k: self.k,
            weighting: self.weighting,
            metric: self.metric,
            representation: self.representation,
        }
    }
}

/// Clustering statistics of a build.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ClusterBuildReport {
    /// (building, floor) groups clustered.
    pub groups: usize,
    /// Groups where affinity propagation did not converge (exemplars of the last iteration
    /// used).
    pub not_converged: usize,
    /// Total clusters.
    pub clusters: usize,
    /// Total iterations over all groups.
    pub iterations: usize,
}

/// The `apc` matcher.
#[derive(Debug)]
pub struct ClusterSearchMatcher {
    map: Arc<RadioMap>,
    config: ClusterSearchConfig,
    clusters: Vec<MapCluster>,
    report: ClusterBuildReport,
    norms: Vec<f64>,
    /// The WKNN over the chosen clusters' members.
    inner: KnnMatcher,
}

/// Exemplars (group-local indices) and members of one group's clusters.
struct GroupClusters {
    exemplars: Vec<usize>,
    members: Vec<Vec<usize>>,
}

/// Converts an affinity error into the crate's error.
fn ap_error(e: AffinityError) -> FingerprintError {
    FingerprintError::InvalidConfig(wipdr_core::ConfigError::new("affinity", e.to_string()))
}

/// The query as a dense filled vector over the map's columns.
pub(crate) fn dense_query(map: &RadioMap, query: &Query) -> Result<Vec<f32>, FingerprintError> {
    let m = map.n_aps();
    let mut v = vec![map.not_heard_dbm(); m];
    for &(j, r) in &query.heard {
        let j = j as usize;
        if j >= m {
            return Err(FingerprintError::DimensionMismatch {
                expected: m,
                found: j + 1,
            });
        }
        v[j] = r;
    }
    Ok(v)
}

/// `||r_i - fill||^2` for every reference point: with it the Euclidean distance of a query to
/// a point costs O(heard APs of the query) instead of O(all APs):
/// `||q - r||^2 = ||q - f||^2 + ||r - f||^2 - 2 (q - f).(r - f)`, the dot product running
/// over the query's heard columns only (`q - f` is zero elsewhere).
pub(crate) fn shifted_norms(map: &RadioMap) -> Vec<f64> {
    let f = f64::from(map.not_heard_dbm());
    (0..map.len())
        .map(|i| {
            map.filled_row(i)
                .iter()
                .map(|&v| (f64::from(v) - f) * (f64::from(v) - f))
                .sum()
        })
        .collect()
}

/// Euclidean distance from a query to reference point `i` by the sparse identity of
/// [`shifted_norms`] (clamped at 0 against rounding).
#[inline]
pub(crate) fn sparse_distance(
    map: &RadioMap,
    norms: &[f64],
    query: &Query,
    q_norm: f64,
    i: usize,
) -> f64 {
    let f = f64::from(map.not_heard_dbm());
    let row = map.filled_row(i);
    let dot: f64 = query
        .heard
        .iter()
        .map(|&(j, r)| (f64::from(r) - f) * (f64::from(row[j as usize]) - f))
        .sum();
    (q_norm + norms[i] - 2.0 * dot).max(0.0).sqrt()
}

/// `||q - f||^2` of a query.
pub(crate) fn query_norm(map: &RadioMap, query: &Query) -> f64 {
    let f = f64::from(map.not_heard_dbm());
    query
        .heard
        .iter()
        .map(|&(_, r)| (f64::from(r) - f) * (f64::from(r) - f))
        .sum()
}

/// The `n` strongest heard columns of a query, strongest first (ties: lower column).
pub(crate) fn strongest(query: &Query, n: usize) -> Vec<u32> {
    let mut h = query.heard.clone();
    h.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    h.into_iter().take(n).map(|(j, _)| j).collect()
}

impl ClusterSearchMatcher {
    /// Clusters the map and builds the matcher.
    pub fn build(
        map: impl Into<Arc<RadioMap>>,
        config: &ClusterSearchConfig,
    ) -> Result<Self, FingerprintError> {
        let map: Arc<RadioMap> = map.into();
        if map.is_empty() {
            return Err(FingerprintError::EmptyMap);
        }
        if config.n_strongest == 0 || config.k == 0 {
            return Err(FingerprintError::InvalidConfig(
                wipdr_core::ConfigError::new(
                    "cluster_search",
                    "n_strongest and k must be at least 1",
                ),
            ));
        }
        let mut groups: BTreeMap<(Option<i32>, Option<i32>), Vec<usize>> = BTreeMap::new();
        for (i, p) in map.points().iter().enumerate() {
            groups.entry((p.building, p.floor)).or_default().push(i);
        }
        let mut clusters = Vec::new();
        let mut report = ClusterBuildReport {
            groups: groups.len(),
            ..Default::default()
        };
        for members in groups.values() {
            let fp = OwnedFingerprints::from_map(&map, members);
            let (exemplars, labels) = match config.method {
                ClusterMethod::AffinityPropagation => {
                    let s = similarity(&fp.view(), config.similarity, &config.mixdis);
                    let c = affinity_propagation_owned(s, &config.affinity).map_err(ap_error)?;
                    report.iterations += c.iterations;
                    if !c.converged() {
                        report.not_converged += 1;
                        tracing::warn!(
                            points = members.len(),
                            iterations = c.iterations,
                            "affinity propagation did not converge on a floor group; using the last exemplars"
                        );
                    }
                    (c.exemplars, c.labels)
                }
                ClusterMethod::KMeans { mean_size } => {
                    let k = members.len().div_ceil(mean_size.max(1));
                    let km = kmeans(
                        &fp.rss,
                        fp.n_aps,
                        &KMeansConfig {
                            k,
                            ..KMeansConfig::default()
                        },
                    )?;
                    report.iterations += km.iterations;
                    if !km.converged {
                        report.not_converged += 1;
                    }
                    // Exemplar: the member nearest to its centroid; empty clusters dropped.
                    let dim = fp.n_aps;
                    let mut best: Vec<Option<(f32, usize)>> = vec![None; km.k];
                    for (i, &l) in km.labels.iter().enumerate() {
                        let d = squared_euclidean(
                            &fp.rss[i * dim..(i + 1) * dim],
                            &km.centres[l * dim..(l + 1) * dim],
                        );
                        if best[l].is_none_or(|(bd, _)| d < bd) {
                            best[l] = Some((d, i));
                        }
                    }
                    let mut renumber = vec![usize::MAX; km.k];
                    let mut exemplars = Vec::new();
                    for (l, b) in best.iter().enumerate() {
                        if let Some((_, i)) = b {
                            renumber[l] = exemplars.len();
                            exemplars.push(*i);
                        }
                    }
                    let labels = km.labels.iter().map(|&l| renumber[l]).collect();
                    (exemplars, labels)
                }
            };
            let mut grouped = vec![Vec::new(); exemplars.len()];
            for (i, &l) in labels.iter().enumerate() {
                grouped[l].push(i);
            }
            let c = GroupClusters {
                exemplars,
                members: grouped,
            };
            for (k, local) in c.members.into_iter().enumerate() {
                let exemplar = members[c.exemplars[k]];
                let global: Vec<usize> = local.iter().map(|&l| members[l]).collect();
                let ap_set: Vec<u32> = map.heard(exemplar).map(|(j, _)| j as u32).collect();
                let centre = match config.centre {
                    ClusterCentre::Exemplar => map.filled_row(exemplar).to_vec(),
                    ClusterCentre::Mean => {
                        let mut acc = vec![0f64; map.n_aps()];
                        for &i in &global {
                            for (a, &v) in acc.iter_mut().zip(map.filled_row(i)) {
                                *a += f64::from(v);
                            }
                        }
                        acc.iter()
                            .map(|a| (a / global.len() as f64) as f32)
                            .collect()
                    }
                };
                clusters.push(MapCluster {
                    exemplar,
                    members: global,
                    ap_set,
                    centre,
                });
            }
        }
        report.clusters = clusters.len();
        Ok(Self {
            norms: shifted_norms(&map),
            inner: KnnMatcher::new(map.clone(), config.inner())?,
            map,
            config: config.clone(),
            clusters,
            report,
        })
    }

    /// The clusters.
    pub fn clusters(&self) -> &[MapCluster] {
        &self.clusters
    }

    /// What the build did.
    pub fn report(&self) -> &ClusterBuildReport {
        &self.report
    }

    /// Indices of the clusters whose AP set holds every column of `aps`.
    fn matching(&self, aps: &[u32]) -> Vec<usize> {
        (0..self.clusters.len())
            .filter(|&c| {
                aps.iter()
                    .all(|a| self.clusters[c].ap_set.binary_search(a).is_ok())
            })
            .collect()
    }
}

impl Matcher for ClusterSearchMatcher {
    fn name(&self) -> String {
        let c = &self.config;
        format!(
            "apc(n={},clusters={},slack={},sim={:?},centre={:?},k={},damping={},method={:?})",
            c.n_strongest,
            c.clusters_searched,
            c.centre_slack,
            c.similarity,
            c.centre,
            c.k,
            c.affinity.damping,
            c.method
        )
        .to_lowercase()
    }

    fn map(&self) -> &RadioMap {
        &self.map
    }

    fn locate(&self, query: &Query) -> Result<WifiObservation, FingerprintError> {
        if query.heard.is_empty() {
            return Err(FingerprintError::EmptyScan);
        }
        let q = dense_query(&self.map, query)?;
        // (1) clusters whose AP set holds the N strongest online APs.
        let mut top = strongest(query, self.config.n_strongest);
        let mut candidates = self.matching(&top);
        while candidates.is_empty() && self.config.fallback == ClusterFallback::ReduceThenAll {
            if top.len() <= 1 {
                break;
            }
            top.pop();
            candidates = self.matching(&top);
        }
        if candidates.is_empty() {
            candidates = (0..self.clusters.len()).collect();
        }
        // (2) nearest centre in signal space.
        let q_norm = query_norm(&self.map, query);
        let dist: Vec<(f64, usize)> = candidates
            .iter()
            .map(|&c| {
                let d = match self.config.centre {
                    ClusterCentre::Exemplar => sparse_distance(
                        &self.map,
                        &self.norms,
                        query,
                        q_norm,
                        self.clusters[c].exemplar,
                    ),
                    ClusterCentre::Mean => {
                        f64::from(squared_euclidean(&q, &self.clusters[c].centre)).sqrt()
                    }
                };
                (d, c)
            })
            .collect();
        let mut dist = dist;
        dist.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let Some(&(nearest, _)) = dist.first() else {
            return Err(FingerprintError::EmptyMap);
        };
        let bound = nearest * self.config.centre_slack.max(1.0);
        let chosen: Vec<usize> = dist
            .iter()
            .enumerate()
            .take_while(|&(rank, &(d, _))| {
                rank < self.config.clusters_searched.max(1) || d <= bound
            })
            .map(|(_, &(_, c))| c)
            .collect();
        let mut members: Vec<u32> = chosen
            .iter()
            .flat_map(|&c| self.clusters[c].members.iter().map(|&i| i as u32))
            .collect();
        // Ascending, so that ties resolve by map index as in the brute force.
        members.sort_unstable();
        // (3) WKNN inside.
        let visited = candidates.len() + members.len();
        self.inner.locate_among(query, &members, visited)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{QueryFilter, RadioMapConfig};

    fn corridor() -> RadioMap {
        // 30 points along a corridor, three APs fading in and out.
        let rows: Vec<([f32; 4], f64)> = (0..30)
            .map(|i| {
                let x = i as f64;
                let a = |c: f64| {
                    let v = -35.0 - 2.5 * (x - c).abs();
                    if v < -95.0 { 100.0 } else { v.round() as f32 }
                };
                ([a(0.0), a(10.0), a(20.0), a(29.0)], x)
            })
            .collect();
        let rows: Vec<(&[f32], f64)> = rows.iter().map(|(r, x)| (&r[..], *x)).collect();
        let t = crate::test_table(4, &rows);
        RadioMap::from_table(&t, RadioMapConfig::default()).unwrap()
    }

    #[test]
    fn clusters_partition_the_map_and_search_visits_fewer_points() {
        let map = corridor();
        let apc = ClusterSearchMatcher::build(map, &ClusterSearchConfig::default()).unwrap();
        let mut all: Vec<usize> = apc
            .clusters()
            .iter()
            .flat_map(|c| c.members.clone())
            .collect();
        all.sort_unstable();
        assert_eq!(all, (0..30).collect::<Vec<_>>());
        assert!(apc.clusters().len() >= 2);
        let row: Vec<f32> = apc.map().filled_row(12).to_vec();
        let raw: Vec<f32> = row
            .iter()
            .map(|&v| if v == -110.0 { 100.0 } else { v })
            .collect();
        let q = Query::from_row(&raw, apc.map(), &QueryFilter::default()).unwrap();
        let obs = apc.locate(&q).unwrap();
        assert!(obs.visited < 30);
        assert!((obs.estimate.x - 12.0).abs() < 3.0, "{}", obs.estimate.x);
        let wsum: f64 = obs.candidates.iter().map(|c| c.weight).sum();
        assert!((wsum - 1.0).abs() < 1e-9);
    }

    #[test]
    fn configs_set_thresholds_and_the_inner_search() {
        use crate::MatcherConfig;
        let c: MatcherConfig = toml::from_str(
            "kind = \"apindex\"\nmoving_threshold_dbm = -80.0\nstationary_threshold_dbm = -90.0\n\
             stationary_after_ms = 3000\nmetric = { kind = \"sorensen\" }",
        )
        .unwrap();
        let MatcherConfig::Apindex(a) = c else {
            panic!("{c:?}")
        };
        assert_eq!(a.moving_threshold_dbm, -80.0);
        assert_eq!(a.stationary_threshold_dbm, -90.0);
        assert_eq!(a.stationary_after_ms, 3000);
        assert!(!a.assume_moving);
        assert_eq!(a.metric, Metric::Sorensen);
        let c: MatcherConfig = toml::from_str(
            "kind = \"apc\"\nmetric = { kind = \"manhattan\" }\nrepresentation = { kind = \"positive\" }",
        )
        .unwrap();
        let MatcherConfig::Apc(apc) = c else {
            panic!("{c:?}")
        };
        assert_eq!(apc.inner().metric, Metric::Manhattan);
        assert!(
            toml::from_str::<MatcherConfig>("kind = \"apindex\"\nmoving_threshold_dbm = \"loud\"")
                .is_err()
        );
        assert!(
            toml::from_str::<MatcherConfig>("kind = \"apc\"\nmetric = { kind = \"cosine\" }")
                .is_err()
        );
    }

    #[test]
    fn unknown_strongest_aps_fall_back_instead_of_failing() {
        let map = corridor();
        let apc = ClusterSearchMatcher::build(map, &ClusterSearchConfig::default()).unwrap();
        // Only an AP no exemplar hears strongly enough: still a fix.
        let q = Query {
            t: 0,
            heard: vec![(3, -90.0)],
            stats: Default::default(),
        };
        let obs = apc.locate(&q).unwrap();
        assert!(obs.estimate.x.is_finite());
    }
}

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
    FingerprintError::InvalidConfig(format!("affinity propagation: {e}"))
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
                "cluster search: n_strongest and k must be at least 1".into(),
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

/// Settings of the matchers `apc`, `apindex` and `med`, by name (for the tools).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(default, deny_unknown_fields)]
pub struct ClusteringMatchersConfig {
    /// `apc`.
    pub apc: ClusterSearchConfig,
    /// `apindex`.
    pub apindex: crate::ap_index::ApIndexConfig,
    /// `med`.
    pub med: crate::med::MedConfig,
}

/// Names [`build_matcher`] knows.
pub const MATCHER_NAMES: [&str; 3] = ["apc", "apindex", "med"];

/// Whether `spec` (`NAME` or `NAME:key=value,...`) names one of [`MATCHER_NAMES`].
pub fn is_clustering_matcher(spec: &str) -> bool {
    MATCHER_NAMES.contains(&spec.split(':').next().unwrap_or(""))
}

fn parse_settings(spec: &str) -> Result<Vec<(String, String)>, FingerprintError> {
    let Some((_, rest)) = spec.split_once(':') else {
        return Ok(Vec::new());
    };
    rest.split(',')
        .filter(|s| !s.is_empty())
        .map(|kv| {
            kv.split_once('=')
                .map(|(k, v)| (k.trim().to_string(), v.trim().to_string()))
                .ok_or_else(|| {
                    FingerprintError::InvalidConfig(format!(
                        "{spec}: expected key=value, got {kv:?}"
                    ))
                })
        })
        .collect()
}

fn parse_num<T: std::str::FromStr>(spec: &str, key: &str, v: &str) -> Result<T, FingerprintError> {
    v.parse()
        .map_err(|_| FingerprintError::InvalidConfig(format!("{spec}: bad value {v:?} for {key}")))
}

fn parse_metric(spec: &str, v: &str) -> Result<Metric, FingerprintError> {
    Metric::parse(v)
        .ok_or_else(|| FingerprintError::InvalidConfig(format!("{spec}: unknown metric {v:?}")))
}

fn parse_representation(spec: &str, v: &str) -> Result<Representation, FingerprintError> {
    Representation::parse(v).ok_or_else(|| {
        FingerprintError::InvalidConfig(format!("{spec}: unknown representation {v:?}"))
    })
}

/// Applies `NAME:key=value,...` settings to `config`. Keys: `apc`: `n` (strongest APs),
/// `k`, `clusters` (nearest clusters searched), `slack`, `centre` (exemplar|mean), `sim`
/// (mixdis|signal), `damping`, `kmeans` (K-means baseline with this mean cluster size),
/// `metric` and `rep` (the inner WKNN, names of [`Metric::parse`] /
/// [`Representation::parse`]); `apindex`: `k`, `top` (offline APs indexed), `moving` (`0` or
/// `1`: assume a moving walker when no motion is given; any other number: the moving
/// threshold in dBm, e.g. `moving=-80`), `still` (the stationary threshold, dBm),
/// `still_after` (ms without a step before the walker counts as stationary), `threshold`
/// (0|1), `metric`, `rep`; `med`: `k`, `window`.
pub fn apply_spec(
    spec: &str,
    config: &mut ClusteringMatchersConfig,
) -> Result<(), FingerprintError> {
    let name = spec.split(':').next().unwrap_or("");
    for (k, v) in parse_settings(spec)? {
        let bad = || FingerprintError::InvalidConfig(format!("{spec}: unknown key {k:?}"));
        match (name, k.as_str()) {
            ("apc", "n") => config.apc.n_strongest = parse_num(spec, &k, &v)?,
            ("apc", "k") => config.apc.k = parse_num(spec, &k, &v)?,
            ("apc", "clusters") => config.apc.clusters_searched = parse_num(spec, &k, &v)?,
            ("apc", "slack") => config.apc.centre_slack = parse_num(spec, &k, &v)?,
            ("apc", "damping") => config.apc.affinity.damping = parse_num(spec, &k, &v)?,
            ("apc", "kmeans") => {
                config.apc.method = ClusterMethod::KMeans {
                    mean_size: parse_num(spec, &k, &v)?,
                }
            }
            ("apc", "centre") => {
                config.apc.centre = match v.as_str() {
                    "exemplar" => ClusterCentre::Exemplar,
                    "mean" => ClusterCentre::Mean,
                    _ => return Err(bad()),
                }
            }
            ("apc", "sim") => {
                config.apc.similarity = match v.as_str() {
                    "mixdis" => SimilarityKind::MixDis,
                    "signal" => SimilarityKind::Signal,
                    _ => return Err(bad()),
                }
            }
            ("apc", "metric") => config.apc.metric = parse_metric(spec, &v)?,
            ("apc", "rep") => config.apc.representation = parse_representation(spec, &v)?,
            ("apindex", "k") => config.apindex.k = parse_num(spec, &k, &v)?,
            ("apindex", "top") => config.apindex.top_offline = parse_num(spec, &k, &v)?,
            ("apindex", "moving") => match v.as_str() {
                "0" | "1" => config.apindex.assume_moving = v == "1",
                _ => config.apindex.moving_threshold_dbm = parse_num(spec, &k, &v)?,
            },
            ("apindex", "still") => {
                config.apindex.stationary_threshold_dbm = parse_num(spec, &k, &v)?
            }
            ("apindex", "still_after") => {
                config.apindex.stationary_after_ms = parse_num(spec, &k, &v)?
            }
            ("apindex", "metric") => config.apindex.metric = parse_metric(spec, &v)?,
            ("apindex", "rep") => config.apindex.representation = parse_representation(spec, &v)?,
            ("apindex", "threshold") => config.apindex.apply_threshold = v == "1",
            ("med", "k") => config.med.k = parse_num(spec, &k, &v)?,
            ("med", "window") => config.med.window = parse_num(spec, &k, &v)?,
            _ => return Err(bad()),
        }
    }
    Ok(())
}

/// Builds the matcher `spec` (`apc`, `apindex`, `med`, optionally `NAME:key=value,...`, see
/// [`apply_spec`]) over `map`; `Ok(None)` for another name. `med` built here is its stateless
/// single-scan form; walks use [`crate::med::MedMatcher::locate_next`].
pub fn build_matcher(
    spec: &str,
    map: impl Into<Arc<RadioMap>>,
    config: &ClusteringMatchersConfig,
) -> Result<Option<Box<dyn Matcher>>, FingerprintError> {
    if !is_clustering_matcher(spec) {
        return Ok(None);
    }
    let mut config = config.clone();
    apply_spec(spec, &mut config)?;
    let config = &config;
    Ok(match spec.split(':').next().unwrap_or("") {
        "apc" => Some(Box::new(ClusterSearchMatcher::build(map, &config.apc)?)),
        "apindex" => Some(Box::new(crate::ap_index::ApIndexMatcher::new(
            map,
            config.apindex,
        )?)),
        "med" => Some(Box::new(crate::med::MedMatcher::new(map, config.med)?)),
        _ => None,
    })
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
    fn specs_set_thresholds_and_the_inner_search() {
        let mut cfg = ClusteringMatchersConfig::default();
        apply_spec("apindex:moving=-80,still=-90,still_after=3000", &mut cfg).unwrap();
        assert_eq!(cfg.apindex.moving_threshold_dbm, -80.0);
        assert_eq!(cfg.apindex.stationary_threshold_dbm, -90.0);
        assert_eq!(cfg.apindex.stationary_after_ms, 3000);
        assert!(!cfg.apindex.assume_moving);
        apply_spec("apindex:moving=1,metric=sorensen,rep=powed", &mut cfg).unwrap();
        assert!(cfg.apindex.assume_moving);
        assert_eq!(cfg.apindex.moving_threshold_dbm, -80.0);
        assert_eq!(cfg.apindex.metric, Metric::Sorensen);
        apply_spec("apc:metric=manhattan,rep=positive", &mut cfg).unwrap();
        assert_eq!(cfg.apc.inner().metric, Metric::Manhattan);
        assert!(apply_spec("apindex:moving=loud", &mut cfg).is_err());
        assert!(apply_spec("apc:metric=cosine", &mut cfg).is_err());
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

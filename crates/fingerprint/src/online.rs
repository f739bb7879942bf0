//! The online matcher seam: matching scans as they arrive in a stream.
//!
//! A stream matcher sees one [`WifiScan`] at a time, with what the PDR knows at that instant
//! ([`ScanContext`]: the latest step's motion state, the displacement walked since the
//! previous scan). Stateful matchers keep their history here: MED (paper 004 eq. 11) holds
//! its window of past scans. Stateless matchers (WKNN, cluster search, the AP index) are
//! streamed by [`Stateless`] for free.
//!
//! Every matcher is named by one serde enum, [`MatcherConfig`] (`kind = "wknn" | "apc" |
//! "apindex" | "med"`, each with its own fields); [`MatcherConfig::build`] turns it into a
//! [`MatcherModel`] (the expensive, shareable part: clusters, indexes) and
//! [`MatcherModel::stream`] into one stream's [`OnlineMatcher`]. A name that is not a
//! matcher, or a field that is not the kind's, is a deserialisation error: no setting is ever
//! dropped silently.
//!
//! ```
//! use std::sync::Arc;
//! use wipdr_core::{Bssid, Point2, WifiEntry, WifiScan};
//! use wipdr_fingerprint::online::{MatcherConfig, ScanContext};
//! use wipdr_fingerprint::{QueryFilter, RadioMap, RadioMapConfig};
//!
//! // A radio map from sparse records: two reference points, two APs.
//! let map = RadioMap::from_records(
//!     [
//!         (Point2::new(0.0, 0.0), vec![(Bssid(1), -40.0), (Bssid(2), -80.0)]),
//!         (Point2::new(10.0, 0.0), vec![(Bssid(1), -80.0), (Bssid(2), -40.0)]),
//!     ],
//!     RadioMapConfig::default(),
//! )
//! .unwrap();
//! let config: MatcherConfig = toml::from_str("kind = \"med\"\nwindow = 2\nk = 1").unwrap();
//! let model = config.build(Arc::new(map)).unwrap();
//! let mut matcher = model.stream(QueryFilter::default());
//! let scan = |t| WifiScan {
//!     t,
//!     entries: vec![WifiEntry::new(Bssid(1), -42.0), WifiEntry::new(Bssid(2), -79.0)],
//! };
//! let fix = matcher.locate_online(&scan(0), &ScanContext::default()).unwrap();
//! assert_eq!(fix.estimate, Point2::new(0.0, 0.0));
//! assert!(toml::from_str::<MatcherConfig>("kind = \"med\"\nwindw = 2").is_err());
//! ```

use crate::ap_index::{ApIndexConfig, ApIndexMatcher};
use crate::cluster_search::{ClusterSearchConfig, ClusterSearchMatcher};
use crate::distance::{Metric, SharedAp};
use crate::med::{MedConfig, MedMatcher};
use crate::{FingerprintError, KnnConfig, KnnMatcher, Matcher, Query, QueryFilter, RadioMap};
use serde::{Deserialize, Serialize};
use std::sync::Arc;
use wipdr_core::{MotionState, TimestampMs, Vector2, WifiObservation, WifiScan};

/// What the stream knows at a scan's instant besides the scan (causal: inputs up to the
/// scan's time, steps of the same millisecond included).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ScanContext {
    /// Time and motion state of the latest PDR step at or before the scan; `None` before the
    /// first step.
    pub last_step: Option<(TimestampMs, MotionState)>,
    /// PDR displacement (map frame, metres) since the previous scan of the stream.
    pub displacement: Vector2,
}

impl ScanContext {
    /// The walker's motion at `t`: the latest step's state, stationary when no step came
    /// within `stationary_after_ms` before `t` (or none at all). The streaming form of
    /// [`crate::ap_index::motion_at`].
    pub fn motion_at(&self, t: TimestampMs, stationary_after_ms: i64) -> MotionState {
        match self.last_step {
            Some((step_t, motion)) => MotionState {
                stationary: t.saturating_sub(step_t) > stationary_after_ms,
                ..motion
            },
            None => MotionState {
                stationary: true,
                ..MotionState::default()
            },
        }
    }
}

/// A matcher in a stream: one scan in, one observation out, history kept inside.
///
/// The contract of [`Matcher`] holds for every observation. Scans must come in time order;
/// [`OnlineMatcher::reset`] forgets the history (a new walk).
pub trait OnlineMatcher: Send {
    /// Short name with its settings.
    fn name(&self) -> String;

    /// The radio map candidates index into.
    fn map(&self) -> &RadioMap;

    /// Locates the stream's next scan.
    fn locate_online(
        &mut self,
        scan: &WifiScan,
        context: &ScanContext,
    ) -> Result<WifiObservation, FingerprintError>;

    /// Forgets the stream's history.
    fn reset(&mut self);
}

/// Any stateless [`Matcher`] streamed: the scan is filtered with the stream's
/// [`QueryFilter`] and located with the motion state of [`ScanContext::motion_at`] (which
/// only motion-aware matchers, the AP index, read).
#[derive(Clone)]
pub struct Stateless {
    matcher: Arc<dyn Matcher>,
    filter: QueryFilter,
    stationary_after_ms: i64,
}

impl std::fmt::Debug for Stateless {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Stateless")
            .field("matcher", &self.matcher.name())
            .field("filter", &self.filter)
            .finish()
    }
}

/// The stationary window of [`Stateless`] for matchers that have none of their own, ms
/// (the AP index's default; other stateless matchers ignore the motion state).
pub const DEFAULT_STATIONARY_AFTER_MS: i64 = 2_000;

impl Stateless {
    /// Streams `matcher` with `filter`; the walker counts as stationary when no step came
    /// within `stationary_after_ms` before a scan.
    pub fn new(matcher: Arc<dyn Matcher>, filter: QueryFilter, stationary_after_ms: i64) -> Self {
        Self {
            matcher,
            filter,
            stationary_after_ms,
        }
    }
}

impl OnlineMatcher for Stateless {
    fn name(&self) -> String {
        self.matcher.name()
    }

    fn map(&self) -> &RadioMap {
        self.matcher.map()
    }

    fn locate_online(
        &mut self,
        scan: &WifiScan,
        context: &ScanContext,
    ) -> Result<WifiObservation, FingerprintError> {
        let motion = context.motion_at(scan.t, self.stationary_after_ms);
        self.matcher
            .locate_scan_with_motion(scan, &self.filter, &motion)
    }

    fn reset(&mut self) {}
}

/// MED streamed: its window of past scans, each placed by the PDR displacement since.
#[derive(Debug, Clone)]
pub struct MedStream {
    med: MedMatcher,
    filter: QueryFilter,
}

impl MedStream {
    /// Streams `med` (its history cleared) with `filter`.
    pub fn new(mut med: MedMatcher, filter: QueryFilter) -> Self {
        med.reset();
        Self { med, filter }
    }
}

impl OnlineMatcher for MedStream {
    fn name(&self) -> String {
        Matcher::name(&self.med)
    }

    fn map(&self) -> &RadioMap {
        self.med.map_ref()
    }

    fn locate_online(
        &mut self,
        scan: &WifiScan,
        context: &ScanContext,
    ) -> Result<WifiObservation, FingerprintError> {
        let query = Query::from_scan(scan, self.med.map_ref(), &self.filter)?;
        self.med.locate_next(&query, context.displacement)
    }

    fn reset(&mut self) {
        self.med.reset();
    }
}

/// Every matcher by name, with its own settings (TOML: `[matcher]` with `kind = ...`).
///
/// Fields a section leaves out take [`MatcherConfig::defaults_for`] of its kind, i.e. the
/// measured defaults for recorded walks (the shared-AP distance); [`MatcherConfig::paper`]
/// gives each kind's paper settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum MatcherConfig {
    /// Brute-force (W)KNN over the whole map (paper 001 eq. 7).
    Wknn(KnnConfig),
    /// Affinity-propagation clusters and cluster search (paper 001 §2.3).
    Apc(ClusterSearchConfig),
    /// The AP-matching index with dynamic RSSI thresholds (paper 002 §3.2).
    Apindex(ApIndexConfig),
    /// Multi-scan MED over the scan history, placed by PDR (paper 004 eq. 11).
    Med(MedConfig),
}

/// The kinds of [`MatcherConfig`], as written in configs.
pub const MATCHER_KINDS: [&str; 4] = ["wknn", "apc", "apindex", "med"];

impl Default for MatcherConfig {
    /// Shared-AP WKNN (k = 5, 1/d weights): the measured best single-scan matcher on the
    /// recorded walks (docs/results/fusion-real.md).
    fn default() -> Self {
        Self::defaults_for("wknn").unwrap_or(Self::Wknn(KnnConfig::default()))
    }
}

impl MatcherConfig {
    /// The kind's name (`wknn`, `apc`, `apindex`, `med`).
    pub fn kind(&self) -> &'static str {
        match self {
            Self::Wknn(_) => "wknn",
            Self::Apc(_) => "apc",
            Self::Apindex(_) => "apindex",
            Self::Med(_) => "med",
        }
    }

    /// The kind's settings as the papers give them (Euclidean distances, paper thresholds).
    pub fn paper(kind: &str) -> Result<Self, FingerprintError> {
        Ok(match kind {
            "wknn" => Self::Wknn(KnnConfig::default()),
            "apc" => Self::Apc(ClusterSearchConfig::default()),
            "apindex" => Self::Apindex(ApIndexConfig::default()),
            "med" => Self::Med(MedConfig::default()),
            other => return Err(unknown_kind(other)),
        })
    }

    /// The kind's defaults for recorded walks: the paper settings with the shared-AP
    /// distance (docs/experiments.md; MED keeps its Euclidean form, whose shared-AP variant is
    /// wipdr's extension and opt-in).
    pub fn defaults_for(kind: &str) -> Result<Self, FingerprintError> {
        let shared = Metric::SharedAp(SharedAp::default());
        Ok(match Self::paper(kind)? {
            Self::Wknn(c) => Self::Wknn(KnnConfig {
                metric: shared,
                ..c
            }),
            Self::Apc(c) => Self::Apc(ClusterSearchConfig {
                metric: shared,
                ..c
            }),
            Self::Apindex(c) => Self::Apindex(ApIndexConfig {
                metric: shared,
                ..c
            }),
            Self::Med(c) => Self::Med(c),
        })
    }

    /// Neighbours K of the kind's WKNN.
    pub fn k(&self) -> usize {
        match self {
            Self::Wknn(c) => c.k,
            Self::Apc(c) => c.k,
            Self::Apindex(c) => c.k,
            Self::Med(c) => c.k,
        }
    }

    /// Checks the settings without building: errors name the field (`matcher.k`).
    pub fn validate(&self) -> Result<(), FingerprintError> {
        let bad = |field: &str, reason: String| {
            FingerprintError::InvalidConfig(wipdr_core::ConfigError::new(
                format!("matcher.{field}"),
                reason,
            ))
        };
        if self.k() == 0 {
            return Err(bad("k", "must be at least 1, got 0".into()));
        }
        match self {
            Self::Wknn(_) => {}
            Self::Apc(c) => {
                if c.n_strongest == 0 {
                    return Err(bad("n_strongest", "must be at least 1, got 0".into()));
                }
                if !(c.centre_slack.is_finite() && c.centre_slack >= 1.0) {
                    return Err(bad(
                        "centre_slack",
                        format!("must be finite and >= 1, got {}", c.centre_slack),
                    ));
                }
            }
            Self::Apindex(c) => {
                if c.top_offline == 0 {
                    return Err(bad("top_offline", "must be at least 1, got 0".into()));
                }
                for (field, v) in [
                    ("stationary_threshold_dbm", c.stationary_threshold_dbm),
                    ("moving_threshold_dbm", c.moving_threshold_dbm),
                ] {
                    if !v.is_finite() {
                        return Err(bad(field, format!("must be finite, got {v}")));
                    }
                }
                if c.stationary_after_ms < 0 {
                    return Err(bad(
                        "stationary_after_ms",
                        format!("must be >= 0, got {}", c.stationary_after_ms),
                    ));
                }
            }
            Self::Med(c) => {
                if c.window == 0 {
                    return Err(bad("window", "must be at least 1, got 0".into()));
                }
            }
        }
        Ok(())
    }

    /// Builds the matcher over `map` (clusters and indexes are built here, once).
    pub fn build(&self, map: Arc<RadioMap>) -> Result<MatcherModel, FingerprintError> {
        self.validate()?;
        // An empty map is its own error, not a `k` too large (the cause is upstream: every
        // scan dropped, e.g. by the staleness limit).
        if map.is_empty() {
            return Err(FingerprintError::EmptyMap);
        }
        if self.k() > map.len() {
            return Err(FingerprintError::InvalidConfig(
                wipdr_core::ConfigError::new(
                    "matcher.k",
                    format!(
                        "{} neighbours asked of a radio map of {} reference points (lower k)",
                        self.k(),
                        map.len()
                    ),
                ),
            ));
        }
        let inner = match self {
            Self::Wknn(c) => Model::Stateless(
                Arc::new(KnnMatcher::new(map, *c)?),
                DEFAULT_STATIONARY_AFTER_MS,
            ),
            Self::Apc(c) => Model::Stateless(
                Arc::new(ClusterSearchMatcher::build(map, c)?),
                DEFAULT_STATIONARY_AFTER_MS,
            ),
            Self::Apindex(c) => Model::Stateless(
                Arc::new(ApIndexMatcher::new(map, *c)?),
                c.stationary_after_ms,
            ),
            Self::Med(c) => Model::Med(MedMatcher::new(map, *c)?),
        };
        Ok(MatcherModel {
            inner,
            config: self.clone(),
        })
    }
}

impl MatcherConfig {
    /// Builds the kind's stateless matcher over `map`, for matching queries one at a time
    /// without a stream (the fingerprint benchmarks of `wipdr fingerprint-eval`): MED is then
    /// its single-scan form (a window of one scan), the others are as streamed.
    pub fn build_stateless(
        &self,
        map: Arc<RadioMap>,
    ) -> Result<Box<dyn Matcher>, FingerprintError> {
        self.validate()?;
        Ok(match self {
            Self::Wknn(c) => Box::new(KnnMatcher::new(map, *c)?),
            Self::Apc(c) => Box::new(ClusterSearchMatcher::build(map, c)?),
            Self::Apindex(c) => Box::new(ApIndexMatcher::new(map, *c)?),
            Self::Med(c) => Box::new(MedMatcher::new(map, *c)?),
        })
    }
}

fn unknown_kind(kind: &str) -> FingerprintError {
    FingerprintError::InvalidConfig(wipdr_core::ConfigError::new(
        "matcher.kind",
        format!(
            "unknown matcher {kind:?} (known: {})",
            MATCHER_KINDS.join(", ")
        ),
    ))
}

#[derive(Clone)]
enum Model {
    Stateless(Arc<dyn Matcher>, i64),
    Med(MedMatcher),
}

/// A built matcher, shareable between streams (and threads): [`MatcherModel::stream`] starts
/// one stream's [`OnlineMatcher`] with its own history.
#[derive(Clone)]
pub struct MatcherModel {
    inner: Model,
    config: MatcherConfig,
}

impl std::fmt::Debug for MatcherModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MatcherModel")
            .field("name", &self.name())
            .finish()
    }
}

impl MatcherModel {
    /// Short name with settings.
    pub fn name(&self) -> String {
        match &self.inner {
            Model::Stateless(m, _) => m.name(),
            Model::Med(m) => Matcher::name(m),
        }
    }

    /// The config it was built from ([`MatcherConfig::build`]).
    pub fn config(&self) -> &MatcherConfig {
        &self.config
    }

    /// The radio map.
    pub fn map(&self) -> &RadioMap {
        match &self.inner {
            Model::Stateless(m, _) => m.map(),
            Model::Med(m) => m.map_ref(),
        }
    }

    /// A new stream (empty history) filtering its scans with `filter`.
    pub fn stream(&self, filter: QueryFilter) -> Box<dyn OnlineMatcher> {
        match &self.inner {
            Model::Stateless(m, still_after) => {
                Box::new(Stateless::new(m.clone(), filter, *still_after))
            }
            Model::Med(m) => Box::new(MedStream::new(m.clone(), filter)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn configs_name_their_kind_and_reject_strangers() {
        let c: MatcherConfig = toml::from_str("kind = \"apindex\"\ntop_offline = 4").unwrap();
        match c {
            MatcherConfig::Apindex(a) => assert_eq!(a.top_offline, 4),
            other => panic!("{other:?}"),
        }
        assert!(toml::from_str::<MatcherConfig>("kind = \"wknn\"\nkk = 3").is_err());
        assert!(toml::from_str::<MatcherConfig>("kind = \"medd\"").is_err());
        assert!(MatcherConfig::paper("nope").is_err());
        for kind in MATCHER_KINDS {
            let d = MatcherConfig::defaults_for(kind).unwrap();
            assert_eq!(d.kind(), kind);
            let text = toml::to_string(&d).unwrap();
            assert_eq!(toml::from_str::<MatcherConfig>(&text).unwrap(), d);
        }
    }

    #[test]
    fn validation_names_the_field() {
        let mut c = MatcherConfig::defaults_for("med").unwrap();
        if let MatcherConfig::Med(m) = &mut c {
            m.window = 0;
        }
        let e = c.validate().unwrap_err().to_string();
        assert!(e.contains("matcher.window"), "{e}");
        let mut c = MatcherConfig::default();
        if let MatcherConfig::Wknn(k) = &mut c {
            k.k = 0;
        }
        assert!(c.validate().unwrap_err().to_string().contains("matcher.k"));
    }

    #[test]
    fn k_larger_than_the_map_is_an_error_not_a_clamp() {
        let map = Arc::new(
            RadioMap::from_records(
                [(
                    wipdr_core::Point2::new(0.0, 0.0),
                    vec![(wipdr_core::Bssid(1), -50.0)],
                )],
                crate::RadioMapConfig::default(),
            )
            .unwrap(),
        );
        for kind in MATCHER_KINDS {
            let e = MatcherConfig::defaults_for(kind)
                .unwrap()
                .build(map.clone())
                .unwrap_err()
                .to_string();
            assert!(
                e.contains("matcher.k") && e.contains("1 reference points"),
                "{kind}: {e}"
            );
        }
    }

    #[test]
    fn motion_from_the_last_step() {
        let ctx = ScanContext {
            last_step: Some((1000, MotionState::default())),
            displacement: Vector2::zeros(),
        };
        assert!(!ctx.motion_at(2500, 2000).stationary);
        assert!(ctx.motion_at(3001, 2000).stationary);
        assert!(ScanContext::default().motion_at(0, 2000).stationary);
        // No overflow at the extremes.
        assert!(ctx.motion_at(i64::MAX, 2000).stationary);
    }
}

//! The one serde config of a [`crate::Positioner`].

use crate::PositioningError;
use serde::{Deserialize, Serialize};
use wipdr_core::ConfigError;
use wipdr_fingerprint::likelihood::LikelihoodConfig;
use wipdr_fingerprint::{MatcherConfig, QueryFilter};
use wipdr_fusion::SchemeConfig;
use wipdr_fusion::static_start::StaticStartConfig;
use wipdr_pdr::PdrConfig;

/// Everything a [`crate::Positioner`] is built from (TOML or JSON; unknown fields are
/// errors). Defaults: shared-AP WKNN, the default PDR, the `ekf` scheme.
///
/// ```
/// let cfg: wipdr_positioning::PositionerConfig = toml::from_str(r#"
///     [matcher]
///     kind = "apindex"
///     top_offline = 4
///     [scheme]
///     scheme = "pmf"
/// "#).unwrap();
/// assert_eq!(cfg.scheme.name(), "pmf");
/// assert!(toml::from_str::<wipdr_positioning::PositionerConfig>("mapmatching = true").is_err());
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PositionerConfig {
    /// The matcher ([`MatcherConfig`], `[matcher]` with `kind = ...`).
    pub matcher: MatcherConfig,
    /// Online filtering of each scan before matching ([`QueryFilter`], `[query]`).
    pub query: QueryFilter,
    /// The PDR pipeline ([`PdrConfig`], `[pdr]`).
    pub pdr: PdrConfig,
    /// The fusion scheme ([`SchemeConfig`], `[scheme]` with `scheme = "ekf"`, ...).
    pub scheme: SchemeConfig,
    /// Project every estimate onto the floor plan's walkable space
    /// ([`wipdr_fusion::MapMatched`], paper 004 §4); needs a plan with an outline.
    pub map_matching: bool,
    /// Start from the robust average of the fixes taken before the first step
    /// ([`StaticStartConfig`], paper 001 §3.2); `None`: off.
    pub static_start: Option<StaticStartConfig>,
    /// The floor estimate from Wi-Fi and the barometer ([`crate::FloorConfig`], `[floor]`),
    /// used when the radio map has floors.
    pub floor: crate::FloorConfig,
    /// Seed of the random schemes (particle filters).
    pub seed: u64,
    /// The motion source between Wi-Fi fixes ([`Odometry`], `odometry = "steps"` or
    /// `"learned"`); default `steps`, the better of the two under leave-one-floor-out
    /// (`docs/results/odometry.md`).
    pub odometry: Odometry,
    /// The scan likelihood over the floor ([`LikelihoodConfig`], `[likelihood]`): fit from
    /// the radio map when the site model is loaded, evaluated for each scan when the scheme
    /// weighs positions by it (`pmf` with `wifi_likelihood`).
    pub likelihood: LikelihoodConfig,
}

/// What moves the walker between Wi-Fi fixes: the motion events the front end hands to the
/// fuser (`odometry = "steps" | "learned"` in TOML; any other value is refused).
///
/// ```
/// use wipdr_positioning::{PositionerConfig, config::Odometry};
/// let cfg = PositionerConfig::from_toml("odometry = \"learned\"").unwrap();
/// assert_eq!(cfg.odometry, Odometry::Learned);
/// assert_eq!(PositionerConfig::default().odometry, Odometry::Steps);
/// assert!(PositionerConfig::from_toml("odometry = \"ronin\"").is_err());
/// ```
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Odometry {
    /// The PDR's detected steps (length x heading), each scheme with its own step noise.
    /// The default: between consecutive waypoints of the five ILC floors it errs 1.428 m a
    /// segment against the learned source's 1.710 m under leave-one-floor-out
    /// (`odometry-train lofo`, `docs/results/odometry.md`).
    #[default]
    Steps,
    /// The learned inertial odometry ([`wipdr_pdr::odometry`], the shipped weights): one
    /// displacement a second with its covariance, turned into the map frame by the PDR's
    /// heading offset (`pdr.heading.map_offset_rad`). The PDR still runs for the matchers'
    /// motion state; its steps do not move the fuser.
    Learned,
}

impl Odometry {
    /// The name used in configs and reports (`steps`, `learned`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Steps => "steps",
            Self::Learned => "learned",
        }
    }
}

impl Default for PositionerConfig {
    /// The best measured configuration (`docs/results/accuracy.md`): the AP-matching index
    /// over each scan's 4 strongest APs without an RSSI threshold around the shared-AP WKNN,
    /// map matching on, and the PDR's handling gate at 3 rad/s. [`PositionerConfig::paper`] has
    /// the papers' settings.
    fn default() -> Self {
        Self {
            matcher: recommended_matcher(),
            map_matching: true,
            pdr: PdrConfig::default(),
            scheme: SchemeConfig::Ekf(wipdr_fusion::EkfConfig::default()),
            ..Self::paper()
        }
    }
}

/// The default matcher: the AP-matching index (paper 002 §3.2) with the top 4 offline APs and
/// no online RSSI threshold (paper: top 2, -85 / -75 dBm), WKNN over the shared APs with
/// `lambda = 80` and the detection weighting at `detection_mid_db = 20` (-90 dBm with not
/// heard = -110; [`wipdr_fingerprint::distance::SharedAp`]: chosen on both buildings,
/// `docs/experiments.md`, detection weighting; before: `lambda = 60`, no weighting).
pub fn recommended_matcher() -> MatcherConfig {
    match MatcherConfig::defaults_for("apindex") {
        Ok(MatcherConfig::Apindex(c)) => {
            MatcherConfig::Apindex(wipdr_fingerprint::ap_index::ApIndexConfig {
                top_offline: 4,
                apply_threshold: false,
                metric: wipdr_fingerprint::distance::Metric::SharedAp(
                    wipdr_fingerprint::distance::SharedAp {
                        lambda: 80.0,
                        detection_mid_db: 20.0,
                        ..Default::default()
                    },
                ),
                ..c
            })
        }
        _ => MatcherConfig::default(),
    }
}

impl PositionerConfig {
    /// The papers' settings: WKNN (k = 5, shared-AP distance), no map matching, no handling
    /// gate ([`wipdr_pdr::handling::HandlingConfig::off`]), `ekf` with the papers' values
    /// ([`wipdr_fusion::EkfConfig::paper`]).
    pub fn paper() -> Self {
        Self {
            matcher: MatcherConfig::default(),
            query: default_query(),
            pdr: PdrConfig {
                handling: wipdr_pdr::handling::HandlingConfig::off(),
                ..PdrConfig::default()
            },
            scheme: SchemeConfig::Ekf(wipdr_fusion::EkfConfig::paper()),
            map_matching: false,
            static_start: None,
            floor: crate::FloorConfig::default(),
            seed: 1,
            odometry: Odometry::Steps,
            likelihood: LikelihoodConfig::default(),
        }
    }
}

/// Scans entries older than this relative to their scan are dropped by default, ms (the
/// radio map's staleness limit for recorded walks).
pub const DEFAULT_MAX_ENTRY_AGE_MS: i64 = 5_000;

/// The default online filter: entries older than [`DEFAULT_MAX_ENTRY_AGE_MS`] dropped.
pub fn default_query() -> QueryFilter {
    QueryFilter {
        max_age_ms: Some(DEFAULT_MAX_ENTRY_AGE_MS),
        ..QueryFilter::default()
    }
}

impl PositionerConfig {
    /// Reads a TOML config: a partial section merges onto the defaults of its context
    /// ([`crate::merge::from_toml_onto`]), unknown fields are errors naming their path.
    pub fn from_toml(text: &str) -> Result<Self, PositioningError> {
        let user = crate::merge::toml_to_json(text).map_err(PositioningError::Parse)?;
        // A field the chosen scheme would not read is refused, not ignored.
        if let Some(serde_json::Value::Object(t)) = user.get("scheme")
            && let Some(kind) = t.get("scheme").and_then(serde_json::Value::as_str)
        {
            crate::merge::check_scheme_table(kind, t).map_err(|e| e.under("scheme"))?;
        }
        let cfg: Self = crate::merge::from_value_onto(user, &Self::default())?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// Checks values (errors name the field path).
    pub fn validate(&self) -> Result<(), PositioningError> {
        // Each part's check names its field; the paths below are where the part sits.
        self.matcher
            .validate()
            .map_err(wipdr_fingerprint::FingerprintError::into_config_error)?;
        self.pdr.validate().map_err(|e| e.under("pdr"))?;
        self.scheme
            .validate()
            .map_err(|e| e.into_config_error().under("scheme"))?;
        self.likelihood
            .check()
            .map_err(wipdr_fingerprint::FingerprintError::into_config_error)?;
        self.floor.validate()?;
        if let Some(age) = self.query.max_age_ms
            && age < 0
        {
            return Err(PositioningError::InvalidConfig(ConfigError::new(
                "query.max_age_ms",
                format!("must be >= 0, got {age}"),
            )));
        }
        if let Some(v) = self.query.min_rssi_dbm
            && !v.is_finite()
        {
            return Err(PositioningError::InvalidConfig(ConfigError::new(
                "query.min_rssi_dbm",
                format!("must be finite, got {v}"),
            )));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A config written to TOML reads back as itself: the paper preset's gate is off
    /// (`None`), written `"off"`, not dropped to come back as the default's 3 rad/s.
    #[test]
    fn presets_survive_a_trip_through_toml() {
        for cfg in [PositionerConfig::default(), PositionerConfig::paper()] {
            let text = toml::to_string_pretty(&cfg).unwrap();
            assert_eq!(PositionerConfig::from_toml(&text).unwrap(), cfg, "{text}");
        }
        assert_eq!(
            PositionerConfig::paper().pdr.handling.max_rotation_rad_s,
            None
        );
    }

    /// The motion source is an enum of two names: anything else is refused naming the field.
    #[test]
    fn an_unknown_odometry_is_refused_naming_the_field() {
        let e = PositionerConfig::from_toml("odometry = \"ronin\"").unwrap_err();
        let text = e.to_string();
        assert!(text.contains("odometry"), "{text}");
        assert!(text.contains("ronin"), "{text}");
        let cfg = PositionerConfig::from_toml("odometry = \"learned\"").unwrap();
        assert_eq!(cfg.odometry, Odometry::Learned);
        let text = toml::to_string_pretty(&cfg).unwrap();
        assert!(text.contains("odometry = \"learned\""), "{text}");
        assert_eq!(PositionerConfig::paper().odometry, Odometry::Steps);
    }

    /// A field the chosen scheme does not read is refused, naming the scheme and the field;
    /// the schemes that read it take it.
    #[test]
    fn a_field_the_scheme_ignores_is_refused() {
        let e = PositionerConfig::from_toml(
            "[scheme]\nscheme = \"ekf\"\n[scheme.robust]\nalpha = 0.05",
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("scheme.robust") && e.contains("`ekf`") && e.contains("rkf"),
            "{e}"
        );
        let cfg = PositionerConfig::from_toml(
            "[scheme]\nscheme = \"rkf\"\n[scheme.robust]\nalpha = 0.05",
        )
        .unwrap();
        assert_eq!(cfg.scheme.name(), "rkf");
        assert!(
            PositionerConfig::from_toml("[scheme]\nscheme = \"akf\"\nq_heading_deg = 3.0").is_err()
        );
    }

    /// TOML's `nan` would reach serde as null and turn an optional threshold off: refused,
    /// naming the field.
    #[test]
    fn a_nan_is_refused_naming_the_field() {
        let e = PositionerConfig::from_toml("[query]\nmin_rssi_dbm = nan").unwrap_err();
        assert!(
            e.to_string()
                .contains("query.min_rssi_dbm: NaN is not a finite number"),
            "{e}"
        );
    }
}

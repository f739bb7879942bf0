//! The evaluation config (`wipdr eval --config FILE.toml`): the [`PositionerConfig`] of every
//! scheme run, plus how each fold's radio map and PDR calibration are made and how runs are
//! scored.

use crate::error::EvalError;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use wipdr_fingerprint::propagation::PropagationConfig;
use wipdr_fingerprint::walk_map::WalkMapConfig;
use wipdr_fingerprint::{MatcherConfig, QueryFilter};
use wipdr_fusion::SchemeConfig;
use wipdr_fusion::static_start::StaticStartConfig;
use wipdr_pdr::PdrConfig;
use wipdr_pdr::calibrate::CalibrationConfig;
use wipdr_positioning::site_model::{SiteConfig, SiteFitConfig};
use wipdr_positioning::{FloorConfig, PositionerConfig};

/// Everything an evaluation can be told; every field has a default. Read it with
/// [`EvalConfig::from_toml`]: a partial section merges onto these defaults (not onto its
/// type's own), unknown fields are errors naming their path. The sweep tool addresses its
/// fields by dotted path (`radio_map.max_entry_age_ms`, `matcher.k`, `schemes.ekf.r_wifi`).
///
/// The positioner's settings live in one [`PositionerConfig`] and the site model's fit
/// settings in one [`SiteFitConfig`]; the evaluation adds only the protocol's own (the scheme
/// table, scoring, offline mode). In TOML (and JSON) the layout is flat, as it always was:
/// the positioner's and the fit's sections and keys are top-level (`[matcher]`, `[pdr]`,
/// `seed`, `[radio_map]`, `propagation`, ...; the file layout is `EvalConfigFile`, converted
/// field by field, so that a field added to either config must be given a key there).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(from = "EvalConfigFile", into = "EvalConfigFile")]
pub struct EvalConfig {
    /// The positioner every run uses: matcher, query filter, the PDR before calibration, map
    /// matching, static start, floor estimate, seed (mixed with each walk's id,
    /// [`wipdr_positioning::stream_seed`]). Its `scheme` is not read: each run names its
    /// scheme, configured in [`EvalConfig::schemes`].
    pub positioner: PositionerConfig,
    /// How each fold's site model is learned: radio map, path-loss extension, PDR
    /// calibration.
    pub fit: SiteFitConfig,
    /// Scheme configs by name ([`SchemeConfig`]); a scheme not listed runs with its
    /// defaults.
    pub schemes: BTreeMap<String, SchemeConfig>,
    /// Score only waypoints after the walk's first Wi-Fi scan, for every scheme (as the
    /// reference pipeline does); earlier ones are counted as skipped.
    pub score_from_first_scan: bool,
    /// Score only waypoints within this many metres of path from the walk's first waypoint;
    /// `None`: the whole walk.
    pub score_first_m: Option<f64>,
    /// Offline mode (`wipdr eval --offline`): every scheme but the `pdr` baseline is scored
    /// on its whole-walk smoothed track ([`wipdr_positioning::smooth::smooth_fusion`]: the
    /// scheme run forward and on the reversed walk, combined), which uses inputs after each
    /// estimate's time. Default `false`: causal estimates, what a live user gets.
    pub offline: bool,
}

/// The scheme of [`EvalConfig::positioner`], which no run reads (each names its own): one
/// fixed value, so that a config read back from its TOML equals itself.
fn unread_scheme() -> SchemeConfig {
    SchemeConfig::Ekf(wipdr_fusion::EkfConfig::default())
}

/// The file layout of [`EvalConfig`] (TOML and JSON): the positioner's and the fit's fields
/// as top-level keys, as before they were grouped.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
struct EvalConfigFile {
    /// How training walks become a radio map ([`WalkMapConfig`]).
    radio_map: WalkMapConfig,
    /// The matcher ([`MatcherConfig`]: `kind = "wknn" | "apc" | "apindex" | "med"`, each
    /// with its own fields).
    matcher: MatcherConfig,
    /// Online filtering of test scans ([`QueryFilter`]).
    query: QueryFilter,
    /// The PDR pipeline before calibration ([`PdrConfig`]).
    pdr: PdrConfig,
    /// Whether step length (and heading offset) are fitted on each fold's training walks.
    calibrate_pdr: bool,
    /// How the calibration fits ([`CalibrationConfig`]).
    calibration: CalibrationConfig,
    /// [`EvalConfig::score_from_first_scan`].
    score_from_first_scan: bool,
    /// Seed of the random schemes.
    seed: u64,
    /// [`EvalConfig::schemes`].
    schemes: BTreeMap<String, SchemeConfig>,
    /// Map-match every scheme's estimates onto the floor plan's walkable space (paper 004
    /// §4; [`wipdr_fusion::MapMatched`]).
    map_matching: bool,
    /// The static start ([`StaticStartConfig`]); `None`: off.
    static_start: Option<StaticStartConfig>,
    /// [`EvalConfig::score_first_m`].
    score_first_m: Option<f64>,
    /// The path-loss extension ([`PropagationConfig`]); `None`: off. In TOML, `"off"`
    /// stands for `None` ([`wipdr_core::off`]).
    #[serde(with = "wipdr_core::off")]
    propagation: Option<PropagationConfig>,
    /// Count the synthesised points of `propagation` as coverage.
    propagation_is_coverage: bool,
    /// The floor estimate ([`FloorConfig`]).
    floor: FloorConfig,
    /// [`EvalConfig::offline`].
    offline: bool,
    /// The motion source between fixes ([`wipdr_positioning::config::Odometry`],
    /// `odometry = "steps" | "learned"`); `pdr` and every fused scheme run it.
    odometry: wipdr_positioning::config::Odometry,
    /// The scan likelihood over the floor
    /// ([`wipdr_fingerprint::likelihood::LikelihoodConfig`], `[likelihood]`).
    likelihood: wipdr_fingerprint::likelihood::LikelihoodConfig,
}

impl Default for EvalConfigFile {
    fn default() -> Self {
        EvalConfig::default().into()
    }
}

impl From<EvalConfigFile> for EvalConfig {
    fn from(f: EvalConfigFile) -> Self {
        let EvalConfigFile {
            radio_map,
            matcher,
            query,
            pdr,
            calibrate_pdr,
            calibration,
            score_from_first_scan,
            seed,
            schemes,
            map_matching,
            static_start,
            score_first_m,
            propagation,
            propagation_is_coverage,
            floor,
            offline,
            odometry,
            likelihood,
        } = f;
        Self {
            positioner: PositionerConfig {
                matcher,
                query,
                pdr,
                scheme: unread_scheme(),
                map_matching,
                static_start,
                floor,
                seed,
                odometry,
                likelihood,
            },
            fit: SiteFitConfig {
                radio_map,
                propagation,
                propagation_is_coverage,
                calibrate_pdr,
                calibration,
            },
            schemes,
            score_from_first_scan,
            score_first_m,
            offline,
        }
    }
}

impl From<EvalConfig> for EvalConfigFile {
    fn from(c: EvalConfig) -> Self {
        let EvalConfig {
            positioner:
                PositionerConfig {
                    matcher,
                    query,
                    pdr,
                    scheme: _,
                    map_matching,
                    static_start,
                    floor,
                    seed,
                    odometry,
                    likelihood,
                },
            fit:
                SiteFitConfig {
                    radio_map,
                    propagation,
                    propagation_is_coverage,
                    calibrate_pdr,
                    calibration,
                },
            schemes,
            score_from_first_scan,
            score_first_m,
            offline,
        } = c;
        Self {
            radio_map,
            matcher,
            query,
            pdr,
            calibrate_pdr,
            calibration,
            score_from_first_scan,
            seed,
            schemes,
            map_matching,
            static_start,
            score_first_m,
            propagation,
            propagation_is_coverage,
            floor,
            offline,
            odometry,
            likelihood,
        }
    }
}

impl Default for EvalConfig {
    /// The best measured configuration (was `docs/configs/best.toml`; figures in
    /// `docs/results/accuracy.md`): [`PositionerConfig::default`] (AP-matching index top 4,
    /// map matching) with heading snapping on, and [`SiteFitConfig::default`] (the radio map
    /// interpolated along the training walks (1 m) and onto a 3 m lattice, the path-loss
    /// extension into coverage gaps down to -85 dBm). [`EvalConfig::paper`] has the papers'
    /// settings; `preset = "paper"` in a config file merges onto them instead.
    fn default() -> Self {
        let positioner = PositionerConfig::default();
        Self {
            positioner: PositionerConfig {
                // the handling gate on (the papers' preset has none), heading snapping on
                // (its grid orientation learned from the training legs by `calibrate_pdr`)
                pdr: wipdr_pdr::PdrConfig {
                    heading: wipdr_pdr::pipeline::HeadingConfig {
                        snap: wipdr_pdr::snap::HeadingSnapConfig {
                            enabled: true,
                            ..Default::default()
                        },
                        ..positioner.pdr.heading
                    },
                    ..positioner.pdr
                },
                scheme: unread_scheme(),
                ..positioner
            },
            // How a site is learned: the one default of `SiteFitConfig` (the interpolated
            // map, the path-loss extension).
            fit: SiteFitConfig::default(),
            // Every scheme at its shipped defaults (`SchemeConfig::default_for`), not the
            // papers' presets that `paper()` lists.
            schemes: BTreeMap::new(),
            ..Self::paper()
        }
    }
}

impl EvalConfig {
    /// The papers' settings: [`PositionerConfig::paper`] (WKNN k = 5, no map matching),
    /// [`SiteFitConfig::paper`] (the radio map of the measured fingerprints alone, no
    /// path-loss extension, PDR calibrated), every scheme at its paper preset
    /// ([`SchemeConfig::paper_for`]).
    pub fn paper() -> Self {
        Self {
            positioner: PositionerConfig {
                scheme: unread_scheme(),
                ..PositionerConfig::paper()
            },
            fit: SiteFitConfig::paper(),
            schemes: wipdr_fusion::scheme_names()
                .iter()
                .filter_map(|n| SchemeConfig::paper_for(n).ok().map(|c| (n.to_string(), c)))
                .collect(),
            score_from_first_scan: true,
            score_first_m: None,
            offline: false,
        }
    }
}

/// Reads TOML text into the JSON value the config readers merge and deserialise, refusing
/// what JSON cannot hold: a non-finite float (`nan`, `inf`) is an error naming its dotted
/// path. (serde_json turns a NaN into `null`, which an optional field would read as "not
/// set" and a required one report as "invalid type: null".)
///
/// ```
/// let v = wipdr_eval::config::toml_to_json("[query]\nmin_rssi_dbm = -80.0").unwrap();
/// assert_eq!(v["query"]["min_rssi_dbm"], -80.0);
/// let e = wipdr_eval::config::toml_to_json("[query]\nmin_rssi_dbm = nan").unwrap_err();
/// assert!(e.starts_with("query.min_rssi_dbm: NaN is not a finite number"), "{e}");
/// ```
pub fn toml_to_json(text: &str) -> Result<serde_json::Value, String> {
    wipdr_positioning::merge::toml_to_json(text)
}

/// Keys of earlier config versions, with what replaced them.
const REMOVED_KEYS: [(&str, &str); 3] = [
    (
        "matcher_spec",
        "`matcher_spec = \"apindex:top=4\"` is now `[matcher]` with `kind = \"apindex\"` and `top_offline = 4` (kinds: wknn, apc, apindex, med)",
    ),
    (
        "med",
        "`[med]` is now `[matcher]` with `kind = \"med\"` and the same fields",
    ),
    (
        "clustering",
        "`[clustering.apc]` / `[clustering.apindex]` are now fields of `[matcher]` with `kind = \"apc\"` / `\"apindex\"`",
    ),
];

impl EvalConfig {
    /// Reads a TOML config: merged onto [`EvalConfig::default`] section by section
    /// ([`wipdr_positioning::merge`]), unknown fields rejected with their path, values
    /// validated ([`EvalConfig::validate`]). `source` names the file in errors.
    pub fn from_toml(text: &str, source: &str) -> Result<Self, EvalError> {
        let bad = |reason: String| EvalError::Config {
            origin: source.to_string(),
            reason,
        };
        let mut user: serde_json::Value = toml_to_json(text).map_err(bad)?;
        let mut base = Self::default();
        if let Some(fields) = user.as_object_mut() {
            for (key, instead) in REMOVED_KEYS {
                if fields.contains_key(key) {
                    return Err(bad(format!("{key}: no longer a config key: {instead}")));
                }
            }
            // A scheme table may leave out `scheme` when its name is a scheme's.
            if let Some(serde_json::Value::Object(schemes)) = fields.get_mut("schemes") {
                for (name, table) in schemes.iter_mut() {
                    let serde_json::Value::Object(t) = table else {
                        continue;
                    };
                    if let Some(kind) = t.get("scheme").and_then(serde_json::Value::as_str) {
                        wipdr_positioning::merge::check_scheme_table(kind, t)
                            .map_err(|e| bad(e.under(&format!("schemes.{name}")).to_string()))?;
                        continue;
                    }
                    if wipdr_fusion::scheme_names().contains(&name.as_str()) {
                        wipdr_positioning::merge::check_scheme_table(name, t)
                            .map_err(|e| bad(e.under(&format!("schemes.{name}")).to_string()))?;
                        t.insert("scheme".into(), serde_json::Value::String(name.clone()));
                    } else {
                        return Err(bad(format!(
                            "schemes.{name}: no `scheme` field, and {name:?} is not a scheme's \
                             name: say which scheme the table configures, e.g. \
                             `scheme = \"ekf\"` (schemes: {})",
                            wipdr_fusion::scheme_names().join(", ")
                        )));
                    }
                }
            }
            match fields.remove("preset") {
                None => {}
                Some(serde_json::Value::String(p)) if p == "paper" => base = Self::paper(),
                Some(serde_json::Value::String(p)) if p == "recommended" => {}
                Some(other) => {
                    return Err(bad(format!(
                        "preset: expected \"paper\" or \"recommended\", got {other}"
                    )));
                }
            }
        }
        let cfg: Self = wipdr_positioning::merge::from_value_onto(user, &base)
            .map_err(|e| bad(e.to_string()))?;
        cfg.validate().map_err(|e| bad(e.to_string()))?;
        Ok(cfg)
    }

    /// Checks values that serde cannot (errors name the field path).
    pub fn validate(&self) -> Result<(), EvalError> {
        use wipdr_core::ConfigError;
        use wipdr_fingerprint::FingerprintError;
        let invalid = |path: &str, reason: String| EvalError::from(ConfigError::new(path, reason));
        self.positioner.validate().map_err(|e| match e {
            wipdr_positioning::PositioningError::InvalidConfig(e) => EvalError::from(e),
            other => invalid("", other.to_string()),
        })?;
        let fit = &self.fit;
        fit.calibration
            .validate()
            .map_err(|e| e.under("calibration"))?;
        self.positioner
            .query
            .validate_fields()
            .map_err(|e| e.under("query"))?;
        fit.radio_map
            .validate_fields()
            .map_err(|e| e.under("radio_map"))?;
        if let Some(i) = &fit.radio_map.interpolation {
            i.validate()
                .map_err(|e| e.into_config_error().under("radio_map.interpolation"))?;
        }
        if let Some(p) = &fit.propagation {
            p.validate().map_err(FingerprintError::into_config_error)?;
        }
        for (name, scheme) in &self.schemes {
            scheme
                .validate()
                .map_err(|e| e.into_config_error().under(&format!("schemes.{name}")))?;
        }
        let not_heard = fit.radio_map.radio.not_heard_dbm;
        if !(not_heard.is_finite() && (-200.0..=-30.0).contains(&not_heard)) {
            return Err(invalid(
                "radio_map.radio.not_heard_dbm",
                format!(
                    "must be a finite dBm value in [-200, -30] (below every heard RSSI), got {not_heard}"
                ),
            ));
        }
        if let Some(m) = self.score_first_m
            && !(m.is_finite() && m >= 0.0)
        {
            return Err(invalid(
                "score_first_m",
                format!("must be finite and >= 0, got {m}"),
            ));
        }
        if let Some(ss) = &self.positioner.static_start {
            ss.validate().map_err(|e| e.into_config_error())?;
        }
        Ok(())
    }

    /// The config of scheme `name`: the one given, else its defaults.
    pub fn scheme(&self, name: &str) -> Result<SchemeConfig, EvalError> {
        match self.schemes.get(name) {
            Some(c) => Ok(c.clone()),
            None => SchemeConfig::default_for(name).map_err(|source| EvalError::Scheme {
                scheme: name.to_string(),
                source,
            }),
        }
    }

    /// The [`PositionerConfig`] a run of `scheme` uses, with the (calibrated) `pdr`.
    pub fn positioner_for(&self, scheme: SchemeConfig, pdr: PdrConfig) -> PositionerConfig {
        PositionerConfig {
            pdr,
            scheme,
            ..self.positioner.clone()
        }
    }

    /// How a site model is fit and run under this config ([`SiteModel::fit`]): the fit
    /// settings, the positioner (its scheme `ekf`'s settings; a stream names its own), and
    /// the scheme table.
    ///
    /// [`SiteModel::fit`]: wipdr_positioning::SiteModel::fit
    pub fn site_config(&self) -> SiteConfig {
        let default_scheme = self
            .scheme("ekf")
            .unwrap_or_else(|_| SchemeConfig::Ekf(Default::default()));
        SiteConfig {
            fit: self.fit.clone(),
            positioner: self.positioner_for(default_scheme, self.positioner.pdr),
            schemes: self.schemes.clone(),
        }
    }

    /// A key of the settings [`crate::pipeline::prepare`] depends on (equal keys, equal
    /// prepared inputs): the whole config without the fields that only the scheme runs and
    /// the scoring read. Built by exclusion, so that a field added later counts as a
    /// preparation input (safe: at worst a sweep prepares more often than it needs to).
    pub fn preparation_key(&self) -> String {
        const RUN_ONLY: [&str; 7] = [
            "schemes",
            "offline",
            "seed",
            "map_matching",
            "static_start",
            "score_first_m",
            "score_from_first_scan",
        ];
        match serde_json::to_value(self) {
            Ok(serde_json::Value::Object(mut fields)) => {
                for f in RUN_ONLY {
                    fields.remove(f);
                }
                serde_json::Value::Object(fields).to_string()
            }
            // Not reached: the config always serialises to an object.
            Ok(other) => other.to_string(),
            Err(e) => format!("unserialisable config: {e}"),
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use wipdr_fingerprint::Metric;

    #[test]
    fn the_defaults_are_the_recommended_settings_and_paper_is_a_preset_away() {
        let d = EvalConfig::default();
        assert_eq!(d.positioner.matcher.kind(), "apindex");
        assert!(
            d.positioner.map_matching
                && d.fit.propagation.is_some()
                && d.fit.radio_map.interpolation.is_some()
        );
        let p = EvalConfig::paper();
        assert_eq!(p.positioner.matcher.kind(), "wknn");
        assert!(
            !p.positioner.map_matching
                && p.fit.propagation.is_none()
                && p.fit.radio_map.interpolation.is_none()
        );
        let cfg = EvalConfig::from_toml("preset = \"paper\"\nmap_matching = true\n", "t").unwrap();
        assert!(cfg.positioner.map_matching && cfg.fit.propagation.is_none());
        assert_eq!(
            EvalConfig::from_toml("preset = \"recommended\"\n", "t").unwrap(),
            d
        );
        // Every scheme: its shipped defaults here, its paper preset there, and a partial
        // scheme section merges onto the preset's values.
        for name in wipdr_fusion::scheme_names() {
            assert_eq!(
                d.scheme(name).unwrap(),
                SchemeConfig::default_for(name).unwrap()
            );
            assert_eq!(
                p.scheme(name).unwrap(),
                SchemeConfig::paper_for(name).unwrap()
            );
        }
        let text = "preset = \"paper\"\n[schemes.ekf]\nscheme = \"ekf\"\nq_heading_deg = 3.0\n";
        let Ok(SchemeConfig::Ekf(ekf)) = EvalConfig::from_toml(text, "t").unwrap().scheme("ekf")
        else {
            panic!("ekf section");
        };
        assert_eq!(
            ekf,
            wipdr_fusion::EkfConfig {
                q_heading_deg: 3.0,
                ..wipdr_fusion::EkfConfig::paper()
            }
        );
        let err = EvalConfig::from_toml("preset = \"best\"\n", "t")
            .unwrap_err()
            .to_string();
        assert!(err.contains("preset"), "{err}");
    }

    #[test]
    fn preparation_key_follows_what_prepare_reads() {
        let base = EvalConfig::default();
        let key = base.preparation_key();
        let mut run_only = base.clone();
        run_only.positioner.seed = 7;
        run_only.positioner.map_matching = true;
        run_only.score_first_m = Some(20.0);
        run_only
            .schemes
            .insert("pmf".into(), SchemeConfig::default_for("pmf").unwrap());
        assert_eq!(run_only.preparation_key(), key);
        let mut propagation = base.clone();
        propagation.fit.propagation = Some(PropagationConfig::default());
        assert_ne!(propagation.preparation_key(), key);
        let mut map = base.clone();
        map.fit.radio_map.max_entry_age_ms = Some(12_345);
        assert_ne!(map.preparation_key(), key);
        let mut coverage = propagation.clone();
        coverage.fit.propagation_is_coverage = true;
        assert_ne!(coverage.preparation_key(), propagation.preparation_key());
    }

    #[test]
    fn a_partial_section_keeps_the_evaluation_defaults() {
        // Seen on the old main: `[matcher] k = 5` switched the metric to Euclidean and a
        // `[query]` section dropped the 5 s staleness limit.
        let cfg =
            EvalConfig::from_toml("[matcher]\nk = 5\n[query]\nstrict = true", "t.toml").unwrap();
        match &cfg.positioner.matcher {
            MatcherConfig::Apindex(c) => {
                assert!(matches!(c.metric, Metric::SharedAp(_)));
                assert_eq!((c.k, c.top_offline, c.apply_threshold), (5, 4, false));
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(
            cfg.positioner.query.max_age_ms,
            EvalConfig::default().positioner.query.max_age_ms
        );
        assert!(cfg.positioner.query.strict);
    }

    #[test]
    fn misspelt_keys_are_errors_naming_the_path() {
        for (text, path) in [
            (
                "[schemes.ekf]\nscheme = \"ekf\"\nr_wifii = 3.0",
                "schemes.ekf",
            ),
            ("[matcher]\nkk = 3", "matcher"),
            ("[pdr]\nstep_lenght = 1", "pdr"),
            ("[radio_map]\nmax_entry_age = 1", "radio_map"),
            ("[matcher]\nkind = \"med\"\nwindw = 3", "matcher"),
            ("map_matchin = true", "map_matchin"),
        ] {
            let e = EvalConfig::from_toml(text, "t.toml")
                .unwrap_err()
                .to_string();
            assert!(e.contains(path) && e.contains("t.toml"), "{text}: {e}");
        }
    }

    /// A scheme table setting a field its scheme does not read is refused, naming the table
    /// path, the scheme and the field (with or without `scheme = ...`).
    #[test]
    fn a_scheme_table_with_a_field_its_scheme_ignores_is_refused() {
        for (text, needle) in [
            (
                "[schemes.ekf]\n[schemes.ekf.speed]\nnormal_q_step_m2 = 2.0",
                "schemes.ekf.speed",
            ),
            (
                "[schemes.my]\nscheme = \"aekf\"\nq_heading_deg = 3.0",
                "schemes.my.q_heading_deg",
            ),
        ] {
            let e = EvalConfig::from_toml(text, "t.toml")
                .unwrap_err()
                .to_string();
            assert!(
                e.contains(needle) && e.contains("does not read"),
                "{text}: {e}"
            );
        }
        assert!(
            EvalConfig::from_toml("[schemes.akf.speed]\nnormal_q_step_m2 = 2.0", "t.toml").is_ok()
        );
    }

    #[test]
    fn removed_keys_say_what_replaced_them() {
        let e = EvalConfig::from_toml("matcher_spec = \"med\"", "t.toml")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("kind = \\\"apindex\\\"") || e.contains("[matcher]"),
            "{e}"
        );
        let e = EvalConfig::from_toml("[med]\nwindow = 2", "t.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains("kind = \"med\""), "{e}");
    }

    #[test]
    fn bad_values_name_their_field() {
        for (text, path) in [
            (
                "[schemes.ekf]\nscheme = \"ekf\"\nr_wifi_m2 = -3.0",
                "schemes.ekf.r_wifi_m2",
            ),
            (
                "[pdr]\nmin_step_length = 1.0\nmax_step_length = 0.5",
                "pdr.max_step_length",
            ),
            (
                "[radio_map.radio]\nnot_heard_dbm = 50.0",
                "radio_map.radio.not_heard_dbm",
            ),
            (
                "[radio_map.radio]\nnot_heard_dbm = nan",
                "radio_map.radio.not_heard_dbm",
            ),
            ("[matcher]\nkind = \"med\"\nwindow = 0", "matcher.window"),
            (
                "[schemes.pf]\nscheme = \"pf\"\nn_particles = 1000000000",
                "schemes.pf.n_particles",
            ),
            ("score_first_m = -1.0", "score_first_m"),
        ] {
            let e = EvalConfig::from_toml(text, "t.toml")
                .unwrap_err()
                .to_string();
            assert!(e.contains(path), "{text}: {e}");
        }
    }

    /// Seen on the old main: TOML `nan` became JSON `null`, read by an optional field as
    /// "not set" (the threshold silently off), and by a required one as "invalid type: null,
    /// expected f64"; `max_entry_age_ms = -1` was accepted and emptied the radio map.
    #[test]
    fn non_finite_and_negative_values_are_refused_naming_the_field() {
        for (text, path) in [
            ("score_first_m = nan", "score_first_m"),
            ("score_first_m = inf", "score_first_m"),
            ("[query]\nmin_rssi_dbm = nan", "query.min_rssi_dbm"),
            ("[radio_map]\ngrid_cell_m = nan", "radio_map.grid_cell_m"),
            (
                "[radio_map.radio]\nnot_heard_dbm = nan",
                "radio_map.radio.not_heard_dbm",
            ),
            ("[schemes.ekf]\nr_wifi_m2 = -inf", "schemes.ekf.r_wifi_m2"),
            (
                "[radio_map]\nmax_entry_age_ms = -1",
                "radio_map.max_entry_age_ms",
            ),
            (
                "[radio_map]\nmax_waypoint_gap_ms = -5",
                "radio_map.max_waypoint_gap_ms",
            ),
            ("[query]\nmax_age_ms = -1", "query.max_age_ms"),
            ("[radio_map]\nmax_aps = 2000000", "radio_map.max_aps"),
            (
                "[radio_map]\nmax_table_mib = 100000",
                "radio_map.max_table_mib",
            ),
            (
                "[radio_map.interpolation.spatial]\ncell_m = 0.001\nmax_points = 1000000000",
                "spatial.max_points",
            ),
            (
                "[propagation]\nmax_points = 1000000000",
                "propagation.max_points",
            ),
        ] {
            let e = EvalConfig::from_toml(text, "t.toml")
                .unwrap_err()
                .to_string();
            assert!(e.contains(path) && e.contains("t.toml"), "{text}: {e}");
            assert!(!e.contains("invalid type: null"), "{text}: {e}");
        }
        let cfg = EvalConfig::from_toml("[radio_map]\nmax_entry_age_ms = 0", "t").unwrap();
        assert_eq!(cfg.fit.radio_map.max_entry_age_ms, Some(0));
    }

    /// Seen on the old main: `[schemes.ekf]` without `scheme = "ekf"` said only "missing
    /// field `scheme`".
    #[test]
    fn a_scheme_table_takes_its_kind_from_its_name() {
        let cfg = EvalConfig::from_toml("[schemes.ekf]\nq_heading_deg = 3.0\n", "t").unwrap();
        let Ok(SchemeConfig::Ekf(ekf)) = cfg.scheme("ekf") else {
            panic!("ekf section");
        };
        assert_eq!(ekf.q_heading_deg, 3.0);
        let e = EvalConfig::from_toml("[schemes.fast]\nq_heading_deg = 3.0\n", "t.toml")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("schemes.fast") && e.contains("scheme = \"ekf\"") && e.contains("t.toml"),
            "{e}"
        );
        // An explicit kind under another name still works.
        let cfg = EvalConfig::from_toml(
            "[schemes.fast]\nscheme = \"ekf\"\nq_heading_deg = 2.0\n",
            "t",
        )
        .unwrap();
        assert!(matches!(cfg.scheme("fast"), Ok(SchemeConfig::Ekf(_))));
    }

    /// The `.toml` files of `docs/<folder>` with their text (shipped configs and sweeps).
    pub(crate) fn shipped_toml_files(folder: &str) -> Vec<(std::path::PathBuf, String)> {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../docs")
            .join(folder);
        let mut files: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "toml"))
            .map(|p| {
                let text = std::fs::read_to_string(&p).unwrap();
                (p, text)
            })
            .collect();
        files.sort();
        files
    }

    /// A config written to TOML (a sweep's best config, a saved preset) reads back as
    /// itself: a `None` field whose default is `Some` is written `"off"`, not dropped.
    #[test]
    fn presets_survive_a_trip_through_toml() {
        let mut off = EvalConfig::default();
        off.positioner.pdr.handling.tumbling_rad_s = None;
        off.fit.radio_map.max_entry_age_ms = None;
        off.positioner.query.max_age_ms = None;
        for (name, cfg) in [
            ("default", EvalConfig::default()),
            ("paper", EvalConfig::paper()),
            ("off", off),
        ] {
            let text = toml::to_string_pretty(&cfg).unwrap();
            let back = EvalConfig::from_toml(&text, name).unwrap();
            assert_eq!(back, cfg, "{name}:\n{text}");
        }
        let text = "[pdr.handling]\ntumbling_rad_s = \"off\"\n";
        let cfg = EvalConfig::from_toml(text, "t").unwrap();
        assert_eq!(cfg.positioner.pdr.handling.tumbling_rad_s, None);
        assert!(
            EvalConfig::default()
                .positioner
                .pdr
                .handling
                .tumbling_rad_s
                .is_some()
        );
        let text = "propagation = \"off\"\n[radio_map]\ninterpolation = \"off\"\n";
        let cfg = EvalConfig::from_toml(text, "t").unwrap();
        assert!(cfg.fit.propagation.is_none() && cfg.fit.radio_map.interpolation.is_none());
        // A table onto an "off" base (the paper preset) turns the setting on again.
        let text = "preset = \"paper\"\n[propagation]\nmin_predicted_dbm = -85.0\n";
        let cfg = EvalConfig::from_toml(text, "t").unwrap();
        assert_eq!(
            cfg.fit.propagation.map(|p| p.min_predicted_dbm),
            Some(-85.0)
        );
        let err = EvalConfig::from_toml("[pdr.handling]\ntumbling_rad_s = \"of\"\n", "t")
            .unwrap_err()
            .to_string();
        assert!(err.contains("tumbling_rad_s"), "{err}");
    }

    /// Every TOML example of the user guide reads as what it says it is: a sweep file (it
    /// has a `[grid]` or `[random]` table) or a config, strict as `--config` reads it.
    #[test]
    fn every_toml_example_of_the_guide_reads() {
        let guide = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/guide.md");
        let text = std::fs::read_to_string(&guide).unwrap();
        let mut blocks: Vec<String> = Vec::new();
        let mut current: Option<String> = None;
        for line in text.lines() {
            match (&mut current, line.trim_start()) {
                (None, "```toml") => current = Some(String::new()),
                (Some(block), "```") => {
                    blocks.push(std::mem::take(block));
                    current = None;
                }
                (Some(block), _) => {
                    block.push_str(line);
                    block.push('\n');
                }
                (None, _) => {}
            }
        }
        let (mut sweeps, mut configs) = (0, 0);
        for block in &blocks {
            if block.contains("[grid]") || block.contains("[random]") {
                crate::sweep::SweepSpec::from_toml(block)
                    .unwrap_or_else(|e| panic!("the guide's sweep example: {e}\n{block}"));
                sweeps += 1;
            } else {
                EvalConfig::from_toml(block, "docs/guide.md")
                    .unwrap_or_else(|e| panic!("the guide's config example: {e}\n{block}"));
                configs += 1;
            }
        }
        assert!(
            sweeps >= 1 && configs >= 2,
            "{sweeps} sweeps, {configs} configs"
        );
    }

    #[test]
    fn every_shipped_config_reads() {
        let files = shipped_toml_files("configs");
        for (path, text) in &files {
            EvalConfig::from_toml(text, &path.display().to_string()).unwrap();
        }
        assert!(files.len() >= 5, "{} configs", files.len());
    }
}

//! # wipdr-fusion — Wi-Fi / PDR fusion behind one [`Fuser`] trait
//!
//! A fuser consumes PDR [`StepEvent`]s and Wi-Fi [`WifiObservation`]s in time order and
//! answers the current position estimate. Every scheme of the four papers is one type behind
//! the trait, built by name from a serde [`SchemeConfig`] (TOML or JSON) so that the
//! evaluation and sweep tools can run any of them:
//!
//! | name | scheme | paper |
//! | --- | --- | --- |
//! | `wifi` | Wi-Fi only, held between scans | — |
//! | `pdr` | PDR only from a given start (or the first fix) | — |
//! | `ekf` | 4-state error EKF with closed-loop correction between fixes | 001 eq. 10-16, 19-20; 000 eq. 7-17 |
//! | `aekf` | `ekf` + adaptive Q by straight / turn / pseudo-turn | 001 §3.2 |
//! | `akf` | adaptive Q by path, scenario (corridor / open) and speed | 000 §4.1 |
//! | `rkf` | robust R by the Mahalanobis F-test | 000 §4.2, eq. 18-21 |
//! | `arkf` | `akf` + `rkf` (scheme 3) | 000 §4 |
//! | `aws` | adaptive weighted smoothing with the displacement constraint | 001 §3.1, eq. 8-9 |
//! | `tcpf` | Trust Chain Positioning Fusion | 002 §4.3, eq. 15-19 |
//! | `pf` | particle filter, DR state, Wi-Fi-minus-DR observation | 004 eq. 12-17 |
//! | `apf` | `pf` + floor-plan walls + adaptive weight | 004 eq. 18-20, §4.3.3 |
//! | `rof` | robust offset: PDR placed by the geometric median of recent Wi-Fi offsets | wipdr's own baseline, not from the papers |
//! | `pmf` | point-mass filter over the PDR track's placement with walkable space and coverage-aware Wi-Fi | wipdr's own, not from the papers |
//!
//! Any scheme's output can be map-matched onto walkable space ([`MapMatched`], paper 004 §4),
//! and any scheme can start from the robust average of the fixes taken while the walker
//! stood still ([`static_start::StaticStart`], paper 001 §3.2). `pmf` can also weigh its
//! hypotheses by where training walks went ([`trails`], wipdr's own; measured without gain on
//! the ILC floors, off by default) and run one lattice per constant PDR heading bias, weighed by
//! evidence ([`point_mass::PointMassMixture`], off by default). Every scheme's config has a
//! `paper()` preset ([`SchemeConfig::paper_for`]) beside its tuned default.
//!
//! Every scheme's estimate carries a horizontal covariance (its 95 % radius): the Kalman
//! family's own, and for the others the propagation and the learned Wi-Fi error of
//! [`fix_error`] (wipdr's own: the fixes' variance from their residuals, and the share of it
//! a walk's correlated Wi-Fi bias keeps in any average).
//!
//! The Kalman machinery lives in [`kalman`] (Joseph form, innovation with Mahalanobis
//! distance, symmetric positive-definite enforcement); resampling in [`resample`] (free
//! functions returning indexes); the wall R-tree in [`walls`]; a small deterministic
//! synthetic-walk generator for tests, examples and benches in [`synthetic`].
//!
//! Where a formula as printed contradicts its own paper's text, the rustdoc of the scheme says
//! what is implemented (see `docs/algorithms.md`).
//!
//! ```
//! use wipdr_core::{Candidate, MotionState, Point2, StepEvent, WifiObservation};
//! use wipdr_fusion::{BuildContext, Fuser, SchemeConfig};
//!
//! let config: SchemeConfig = toml::from_str("scheme = \"arkf\"").unwrap();
//! let mut fuser = config.build(&BuildContext::default()).unwrap();
//! let fix = |t, x: f64, y: f64| WifiObservation {
//!     t, estimate: Point2::new(x, y),
//!     candidates: vec![Candidate { position: Point2::new(x, y), distance: 1.0, weight: 1.0, index: 0, floor: None }],
//!     visited: 1, floor: None, building: None,
//!     likelihood: None,
//! };
//! fuser.on_wifi(&fix(0, 0.0, 0.0));                 // initialises at the first fix
//! for k in 1..=4 {                                  // four steps due north (heading 0)
//!     fuser.on_step(&StepEvent { t: 500 * k, length: 0.7, heading: 0.0, heading_change: 0.0,
//!         period_s: 0.5, motion: MotionState::default(), covariance: None });
//! }
//! fuser.on_wifi(&fix(2000, 0.0, 3.0));
//! let estimate = fuser.estimate().unwrap();
//! assert!((estimate.position.y - 2.8).abs() < 0.5);
//! ```
//!
//! (The example needs `toml`, a dev-dependency; any serde format works.)

pub mod aws;
pub mod baseline;
pub mod ekf;
pub mod fix_error;
pub mod kalman;
pub mod offline;
pub mod particle;
pub mod point_mass;
pub mod replay;
pub mod resample;
pub mod robust_offset;
pub mod static_start;
pub mod synthetic;
pub mod tcpf;
pub mod trails;
pub mod walkable;
pub mod walls;

use std::sync::Arc;

use nalgebra::Matrix2;
use serde::{Deserialize, Serialize};
use wipdr_core::{FloorPlan, Point2, StepEvent, TimestampMs, WifiObservation};

pub use aws::{AwsConfig, AwsFuser};
pub use baseline::{PdrOnly, PdrOnlyConfig, WifiOnly, WifiOnlyConfig};
pub use ekf::{Adaptation, EkfConfig, ErrorStateEkf, RobustConfig, RobustMode, Scenario};
pub use kalman::Innovation;
pub use particle::{ParticleFilter, PfConfig, WeightedPoint};
pub use point_mass::{PointMassConfig, PointMassFilter};
pub use robust_offset::{RobustOffset, RobustOffsetConfig};
pub use tcpf::{Tcpf, TcpfConfig, TrustState};
pub use trails::TrailRaster;
pub use walkable::{MapMatched, WalkableGrid};
pub use walls::WallIndex;

/// Errors of the fusion crate.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FusionError {
    /// A configuration field is out of range (its path relative to the scheme's section).
    #[error(transparent)]
    InvalidConfig(#[from] wipdr_core::ConfigError),
    /// The innovation covariance is not positive definite.
    #[error("innovation covariance is not positive definite")]
    SingularInnovation,
    /// An update would make the state non-finite.
    #[error("update would make the state non-finite")]
    NonFiniteState,
    /// Unknown scheme name.
    #[error("unknown fusion scheme `{0}` (known: {known})", known = scheme_names().join(", "))]
    UnknownScheme(String),
}

impl FusionError {
    /// The error as a config error: its [`wipdr_core::ConfigError`] when it is one, else
    /// the message under an empty path (a check that failed for another reason).
    pub fn into_config_error(self) -> wipdr_core::ConfigError {
        match self {
            Self::InvalidConfig(e) => e,
            other => wipdr_core::ConfigError::new("", other.to_string()),
        }
    }
}

/// What a scheme exposes for plots and diagnosis besides its position.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Diagnostics {
    /// TCPF trust state after the latest Wi-Fi epoch (002 §4.3.3).
    pub trust_state: Option<TrustState>,
    /// TCPF's TC parameter `lambda` (002 eq. 17-18), current value.
    pub tc_lambda: Option<f64>,
    /// Robust test statistic `lambda = M^2 / m` of the latest Wi-Fi fix (000 eq. 18).
    pub test_statistic: Option<f64>,
    /// Robust factor `beta` applied to R for the latest fix (000 eq. 21; 1 when accepted).
    pub robust_factor: Option<f64>,
    /// Whether the latest Wi-Fi fix was flagged as a gross error / untrusted / inconsistent.
    pub wifi_flagged: Option<bool>,
    /// How many times the scheme re-initialised (persistent rejections, re-seeding).
    pub reinitialisations: u32,
    /// Particle count (particle filters).
    pub particle_count: Option<usize>,
    /// Effective sample size `1 / sum w^2` before the latest resampling decision.
    pub effective_sample_size: Option<f64>,
    /// Steps on which walls killed every particle (recovered by keeping the previous set).
    pub wall_recoveries: u32,
    /// Inputs skipped because they were non-finite or out of time order.
    pub skipped_inputs: u32,
}

/// The current estimate of a fuser.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Estimate {
    /// Time of the latest input that changed the estimate (Unix ms).
    pub t: TimestampMs,
    /// Position, metres.
    pub position: Point2,
    /// Position covariance (m²), where the scheme has one.
    pub covariance: Option<Matrix2<f64>>,
    /// Internal state for plots.
    pub diagnostics: Diagnostics,
}

impl Estimate {
    /// An estimate without a covariance (schemes that do not carry one).
    pub fn point(t: TimestampMs, position: Point2, diagnostics: Diagnostics) -> Self {
        Self {
            t,
            position,
            covariance: None,
            diagnostics,
        }
    }
}

/// A fusion scheme: steps and Wi-Fi observations in, in time order; the current estimate out.
///
/// Inputs that are non-finite or older than the latest input are skipped, logged with
/// `tracing` and counted in [`Diagnostics::skipped_inputs`]; nothing panics on input data.
pub trait Fuser {
    /// The scheme's name (one of [`scheme_names`]).
    fn name(&self) -> &'static str;
    /// Feed one PDR step.
    fn on_step(&mut self, step: &StepEvent);
    /// Feed one Wi-Fi observation.
    fn on_wifi(&mut self, obs: &WifiObservation);
    /// The current estimate; `None` until initialised (first Wi-Fi fix or a given start).
    fn estimate(&self) -> Option<Estimate>;
    /// The particle cloud (position, normalised weight) for plots; `None` for non-particle
    /// schemes. Separate from [`Fuser::estimate`] so that querying an estimate stays cheap.
    fn particle_cloud(&self) -> Option<Vec<WeightedPoint>> {
        None
    }
}

/// What a scheme may need to be built.
#[derive(Debug, Clone, Default)]
pub struct BuildContext {
    /// Wall index of the floor plan (for `apf`); build once per floor with
    /// [`BuildContext::with_floor_plan`] or [`WallIndex::new`] and share.
    pub walls: Option<Arc<WallIndex>>,
    /// Seed of the scheme's random generator (particle filters).
    pub seed: u64,
    /// Start position for baselines (`pdr`) or a known start; otherwise the first Wi-Fi fix.
    pub start: Option<Point2>,
    /// Walkable space of the floor plan (for `pmf`); build once per floor and share.
    pub walkable: Option<Arc<WalkableGrid>>,
    /// Positions of the radio map's reference points (training data), for coverage-aware
    /// schemes (`pmf`).
    pub coverage: Option<Arc<Vec<Point2>>>,
    /// Where training walks went ([`trails::TrailRaster`]), for `pmf`'s trail prior.
    pub trails: Option<Arc<trails::TrailRaster>>,
}

impl BuildContext {
    /// Context with the walls of `plan` indexed.
    pub fn with_floor_plan(plan: &FloorPlan) -> Self {
        Self {
            walls: Some(Arc::new(WallIndex::new(&plan.walls))),
            ..Self::default()
        }
    }
}

/// Every scheme's config, tagged by name (`scheme = "arkf"` in TOML). Every field has the
/// papers' default, so a bare tag is a complete config.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "scheme", rename_all = "lowercase")]
pub enum SchemeConfig {
    /// Wi-Fi only.
    Wifi(WifiOnlyConfig),
    /// PDR only.
    Pdr(PdrOnlyConfig),
    /// Error-state EKF (001 eq. 10-16, 19-20).
    Ekf(EkfConfig),
    /// EKF with Q adapted by turn state (001 §3.2).
    Aekf(EkfConfig),
    /// EKF with Q adapted by path, scenario and speed (000 §4.1).
    Akf(EkfConfig),
    /// EKF with robust R (000 §4.2).
    Rkf(EkfConfig),
    /// Adaptive and robust EKF (000 scheme 3).
    Arkf(EkfConfig),
    /// Adaptive weighted smoothing (001 §3.1).
    Aws(AwsConfig),
    /// Trust Chain Positioning Fusion (002 §4.3).
    Tcpf(TcpfConfig),
    /// Particle filter (004 eq. 12-17).
    Pf(PfConfig),
    /// Adaptive particle filter with walls (004 eq. 18-20).
    Apf(PfConfig),
    /// Robust offset fusion: wipdr's own baseline, not from the papers
    /// ([`robust_offset`]).
    Rof(RobustOffsetConfig),
    /// Point-mass filter with walkable space: wipdr's own, not from the papers
    /// ([`point_mass`]).
    Pmf(PointMassConfig),
}

const SCHEME_NAMES: [&str; 13] = [
    "wifi", "pdr", "ekf", "aekf", "akf", "rkf", "arkf", "aws", "tcpf", "pf", "apf", "rof", "pmf",
];

/// Names of every scheme, in the order of the issue table.
pub fn scheme_names() -> &'static [&'static str] {
    &SCHEME_NAMES
}

impl SchemeConfig {
    /// The default config of scheme `name`.
    pub fn default_for(name: &str) -> Result<Self, FusionError> {
        Self::preset_for(name, false)
    }

    /// The papers' config of scheme `name` (each config's `paper()`): the values the papers
    /// print where they print them ([`EkfConfig::paper`], [`AwsConfig::paper`],
    /// [`TcpfConfig::paper`]); the particle filters' paper gives no numbers and `wifi`,
    /// `pdr`, `rof` and `pmf` have none to give, so their presets say what they hold.
    ///
    /// ```
    /// use wipdr_fusion::{SchemeConfig, scheme_names};
    /// for name in scheme_names() {
    ///     assert_eq!(SchemeConfig::paper_for(name).unwrap().name(), *name);
    /// }
    /// assert_ne!(SchemeConfig::paper_for("ekf").unwrap(), SchemeConfig::default_for("ekf").unwrap());
    /// ```
    pub fn paper_for(name: &str) -> Result<Self, FusionError> {
        Self::preset_for(name, true)
    }

    /// Scheme `name` at its papers' preset (`paper`) or its default.
    fn preset_for(name: &str, paper: bool) -> Result<Self, FusionError> {
        fn pick<T: Default>(paper: bool, preset: fn() -> T) -> T {
            if paper { preset() } else { T::default() }
        }
        Ok(match name {
            "wifi" => Self::Wifi(WifiOnlyConfig::default()),
            "pdr" => Self::Pdr(pick(paper, PdrOnlyConfig::paper)),
            "ekf" => Self::Ekf(pick(paper, EkfConfig::paper)),
            "aekf" => Self::Aekf(pick(paper, EkfConfig::paper)),
            "akf" => Self::Akf(pick(paper, EkfConfig::paper)),
            "rkf" => Self::Rkf(pick(paper, EkfConfig::paper)),
            "arkf" => Self::Arkf(pick(paper, EkfConfig::paper)),
            "aws" => Self::Aws(pick(paper, AwsConfig::paper)),
            "tcpf" => Self::Tcpf(pick(paper, TcpfConfig::paper)),
            "pf" => Self::Pf(pick(paper, PfConfig::paper)),
            "apf" => Self::Apf(pick(paper, PfConfig::paper)),
            "rof" => Self::Rof(pick(paper, RobustOffsetConfig::paper)),
            "pmf" => Self::Pmf(pick(paper, PointMassConfig::paper)),
            other => return Err(FusionError::UnknownScheme(other.to_string())),
        })
    }

    /// Whether the scheme weighs positions by a scan's likelihood over the floor
    /// ([`wipdr_core::WifiObservation::likelihood`]), so that the front end should compute
    /// it: `pmf`, `pf` and `apf` with `wifi_likelihood`.
    pub fn uses_wifi_likelihood(&self) -> bool {
        match self {
            Self::Pmf(c) => c.wifi_likelihood,
            Self::Pf(c) | Self::Apf(c) => c.wifi_likelihood,
            _ => false,
        }
    }

    /// The fields (and sections) of scheme `name`'s config type that the scheme does not
    /// read: the EKF family shares one config type ([`EkfConfig`]) whose parts each variant
    /// reads or not. A config that sets one of them is refused
    /// ([`SchemeConfig::check_unread`]) instead of silently ignored. Empty for the other
    /// schemes and unknown names.
    ///
    /// ```
    /// use wipdr_fusion::SchemeConfig;
    /// assert!(SchemeConfig::unread_fields("ekf").contains(&"robust"));
    /// assert!(!SchemeConfig::unread_fields("rkf").contains(&"robust"));
    /// assert!(SchemeConfig::unread_fields("akf").contains(&"q_heading_deg"));
    /// ```
    pub fn unread_fields(name: &str) -> &'static [&'static str] {
        match name {
            // `Adaptation::None`, no robust test.
            "ekf" => &["turn", "scenario", "speed", "robust"],
            // Heading by turn state (not `q_heading_deg`), no robust test.
            "aekf" => &["q_heading_deg", "scenario", "speed", "robust"],
            // Position by scenario, step by speed, heading by turn state.
            "akf" => &["q_position_m2", "q_step_m2", "q_heading_deg", "robust"],
            "rkf" => &["turn", "scenario", "speed"],
            "arkf" => &["q_position_m2", "q_step_m2", "q_heading_deg"],
            _ => &[],
        }
    }

    /// Refuses `keys` (the fields a config file sets in a table for scheme `name`) that the
    /// scheme does not read ([`SchemeConfig::unread_fields`]); the error's path is the field
    /// (relative to the table), its reason names the scheme and the schemes that do read it.
    pub fn check_unread<'a>(
        name: &str,
        keys: impl IntoIterator<Item = &'a str>,
    ) -> Result<(), wipdr_core::ConfigError> {
        let unread = Self::unread_fields(name);
        for key in keys {
            if unread.contains(&key) {
                let readers: Vec<&str> = ["ekf", "aekf", "akf", "rkf", "arkf"]
                    .into_iter()
                    .filter(|s| !Self::unread_fields(s).contains(&key))
                    .collect();
                return Err(wipdr_core::ConfigError::new(
                    key,
                    format!(
                        "scheme `{name}` does not read it (only {} do); remove it or choose \
                         one of those schemes",
                        readers.join(", ")
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The scheme's name.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Wifi(_) => "wifi",
            Self::Pdr(_) => "pdr",
            Self::Ekf(_) => "ekf",
            Self::Aekf(_) => "aekf",
            Self::Akf(_) => "akf",
            Self::Rkf(_) => "rkf",
            Self::Arkf(_) => "arkf",
            Self::Aws(_) => "aws",
            Self::Tcpf(_) => "tcpf",
            Self::Pf(_) => "pf",
            Self::Apf(_) => "apf",
            Self::Rof(_) => "rof",
            Self::Pmf(_) => "pmf",
        }
    }

    /// Checks the scheme's fields without building it; the error names the field
    /// (`FusionError::InvalidConfig { field, .. }`, relative to the scheme's section).
    pub fn validate(&self) -> Result<(), FusionError> {
        match self {
            Self::Wifi(_) | Self::Pdr(_) => Ok(()),
            Self::Ekf(c) | Self::Aekf(c) | Self::Akf(c) | Self::Rkf(c) | Self::Arkf(c) => {
                c.validate()
            }
            Self::Aws(c) => AwsFuser::new(c.clone(), None).map(|_| ()),
            Self::Tcpf(c) => c.validate(),
            Self::Pf(c) | Self::Apf(c) => c.validate(),
            Self::Rof(c) => c.validate(),
            Self::Pmf(c) => c.validate(),
        }
    }

    /// Validates the config and builds the scheme.
    pub fn build(&self, ctx: &BuildContext) -> Result<Box<dyn Fuser + Send>, FusionError> {
        Ok(match self {
            Self::Wifi(c) => Box::new(WifiOnly::new(c.clone())),
            Self::Pdr(c) => Box::new(PdrOnly::new(c.clone(), ctx.start)),
            Self::Ekf(c) => Box::new(ErrorStateEkf::new(
                "ekf",
                c.clone(),
                Adaptation::None,
                false,
                ctx.start,
            )?),
            Self::Aekf(c) => Box::new(ErrorStateEkf::new(
                "aekf",
                c.clone(),
                Adaptation::TurnState,
                false,
                ctx.start,
            )?),
            Self::Akf(c) => Box::new(ErrorStateEkf::new(
                "akf",
                c.clone(),
                Adaptation::PathScenarioSpeed,
                false,
                ctx.start,
            )?),
            Self::Rkf(c) => Box::new(ErrorStateEkf::new(
                "rkf",
                c.clone(),
                Adaptation::None,
                true,
                ctx.start,
            )?),
            Self::Arkf(c) => Box::new(ErrorStateEkf::new(
                "arkf",
                c.clone(),
                Adaptation::PathScenarioSpeed,
                true,
                ctx.start,
            )?),
            Self::Aws(c) => Box::new(AwsFuser::new(c.clone(), ctx.start)?),
            Self::Tcpf(c) => Box::new(Tcpf::new(c.clone(), ctx.start)?),
            Self::Pf(c) => Box::new(ParticleFilter::new(
                "pf",
                c.clone(),
                false,
                None,
                ctx.seed,
                ctx.start,
            )?),
            Self::Apf(c) => {
                if ctx.walls.is_none() {
                    // Said once per site, where the site is built (`Site::from_plan`), not per stream.
                    tracing::debug!("apf built without a floor plan: no wall constraint");
                }
                Box::new(ParticleFilter::new(
                    "apf",
                    c.clone(),
                    true,
                    ctx.walls.clone(),
                    ctx.seed,
                    ctx.start,
                )?)
            }
            Self::Rof(c) => {
                c.validate()?;
                Box::new(RobustOffset::new(c.clone()))
            }
            Self::Pmf(c) => Box::new(point_mass::PointMassMixture::from_context(c, ctx)?),
        })
    }
}

/// Input guard shared by the schemes: rejects non-finite inputs and inputs older than the
/// latest accepted one (logging and counting them).
#[derive(Debug, Clone, Default)]
pub(crate) struct InputGuard {
    last_t: Option<TimestampMs>,
    pub(crate) skipped: u32,
}

impl InputGuard {
    /// Diagnostics carrying the count of skipped inputs (the rest default).
    pub(crate) fn diagnostics(&self) -> Diagnostics {
        Diagnostics {
            skipped_inputs: self.skipped,
            ..Diagnostics::default()
        }
    }

    pub(crate) fn accept_step(&mut self, step: &StepEvent) -> bool {
        let ok = step.length.is_finite() && step.length >= 0.0 && step.heading.is_finite();
        if !ok {
            self.skipped += 1;
            tracing::warn!(
                t = step.t,
                "skipping a step with a non-finite or negative field"
            );
            return false;
        }
        self.accept_time(step.t)
    }

    pub(crate) fn accept_wifi(&mut self, obs: &WifiObservation) -> bool {
        let ok = obs.estimate.x.is_finite() && obs.estimate.y.is_finite();
        if !ok {
            self.skipped += 1;
            tracing::warn!(
                t = obs.t,
                "skipping a Wi-Fi observation with a non-finite estimate"
            );
            return false;
        }
        self.accept_time(obs.t)
    }

    fn accept_time(&mut self, t: TimestampMs) -> bool {
        if let Some(last) = self.last_t
            && t < last
        {
            self.skipped += 1;
            tracing::warn!(t, last, "skipping an input out of time order");
            return false;
        }
        self.last_t = Some(t);
        true
    }
}

/// Finite candidates of an observation (position and weight), or the estimate alone when the
/// observation has none; weights renormalised (uniform when they do not sum to a positive
/// number).
pub(crate) fn usable_candidates(obs: &WifiObservation) -> Vec<(Point2, f64)> {
    let mut c: Vec<(Point2, f64)> = obs
        .candidates
        .iter()
        .filter(|c| c.position.x.is_finite() && c.position.y.is_finite())
        .map(|c| {
            (
                c.position,
                if c.weight.is_finite() && c.weight > 0.0 {
                    c.weight
                } else {
                    0.0
                },
            )
        })
        .collect();
    if c.is_empty() {
        return vec![(obs.estimate, 1.0)];
    }
    let sum: f64 = c.iter().map(|(_, w)| w).sum();
    let n = c.len() as f64;
    for (_, w) in &mut c {
        *w = if sum > 0.0 { *w / sum } else { 1.0 / n };
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_name_round_trips_through_toml() {
        for name in scheme_names() {
            let cfg: SchemeConfig = toml::from_str(&format!("scheme = \"{name}\"")).unwrap();
            assert_eq!(cfg.name(), *name);
            assert_eq!(cfg, SchemeConfig::default_for(name).unwrap());
            let text = toml::to_string(&cfg).unwrap();
            let back: SchemeConfig = toml::from_str(&text).unwrap();
            assert_eq!(back, cfg);
            let fuser = cfg.build(&BuildContext::default()).unwrap();
            assert_eq!(fuser.name(), *name);
        }
        assert!(matches!(
            SchemeConfig::default_for("kalman"),
            Err(FusionError::UnknownScheme(_))
        ));
    }

    #[test]
    fn a_partial_toml_overrides_one_field() {
        let cfg: SchemeConfig =
            toml::from_str("scheme = \"rkf\"\nr_wifi_m2 = 25.0\n[robust]\nalpha = 0.05\n").unwrap();
        match cfg {
            SchemeConfig::Rkf(c) => {
                assert_eq!(c.r_wifi_m2, 25.0);
                assert_eq!(c.robust.alpha, 0.05);
                assert_eq!(c.q_position_m2, EkfConfig::default().q_position_m2);
            }
            other => panic!("wrong variant {other:?}"),
        }
    }
}

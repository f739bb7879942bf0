//! A site model: everything a [`crate::Positioner`] needs that is learned from a site's data,
//! fit once ([`SiteModel::fit`]), saved ([`SiteModel::save`]), loaded anywhere
//! ([`SiteModel::load`]) and used by any number of streams ([`SiteModel::positioner`]).
//!
//! What it holds: the radio map with floors (after interpolation and path-loss extension),
//! the measured reference points (coverage), the PDR calibrated on the training walks, the
//! barometric references, where the training walks went (trails), the floor plan and the
//! WGS84 frame where the data has them, the building's floors, the [`PositionerConfig`] it was
//! fit with and the scheme settings by name, and its [`Provenance`]. What it derives on load
//! (never saved): the built matcher and the plan's indexes (walls, walkable raster).
//!
//! Learning and using are split as in scikit-learn's and linfa's `fit` / `predict`: the
//! evaluation (`wipdr-eval`) fits one model per protocol fold with the same
//! [`SiteModel::fit`] a user calls once for their building.
//!
//! ```
//! use wipdr_core::{Bssid, FloorPlan, Point2, Walk, WifiEntry, WifiScan, Waypoint};
//! use wipdr_positioning::site_model::{SiteConfig, SiteModel, TrainingData};
//!
//! // A training walk along a corridor: a scan and a waypoint every second.
//! let mut walk = Walk::default();
//! walk.meta.id = "survey".into();
//! for i in 0..20 {
//!     let (t, x) = (1000 * i, f64::from(i as i32));
//!     walk.waypoints.push(Waypoint::new(t, Point2::new(x, 0.0)));
//!     walk.wifi.push(WifiScan { t, entries: vec![
//!         WifiEntry::new(Bssid(1), -40.0 - 2.0 * x).seen_at(t),
//!         WifiEntry::new(Bssid(2), -80.0 + 2.0 * x).seen_at(t),
//!     ]});
//! }
//! let data = TrainingData { name: "corridor", walks: &[&walk], ..Default::default() };
//! let model = SiteModel::fit(&data, &SiteConfig::default())?;
//! assert!(model.radio_map().len() > 0);
//!
//! // Saved and loaded, it positions a stream exactly as before.
//! let dir = std::env::temp_dir().join(format!("wipdr-doc-{}", std::process::id()));
//! std::fs::create_dir_all(&dir)?;
//! let path = dir.join("corridor.wipdr");
//! model.save(&path)?;
//! let loaded = SiteModel::load(&path)?;
//! assert_eq!(loaded.data(), model.data());
//! let mut positioner = wipdr_positioning::Positioner::new(&loaded, "ekf")?;
//! positioner.push_scan(WifiScan { t: 0, entries: vec![WifiEntry::new(Bssid(1), -50.0)] });
//! assert!(positioner.estimate().is_some());
//! # std::fs::remove_dir_all(&dir)?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod coverage;
mod file;
mod fit;
mod pressure;
mod provenance;
mod survey;

pub use coverage::{MeasuredPoint, coverage_distance, measured_points};
pub use file::{
    FORMAT_VERSION, HEADER_BYTES, MAGIC, MAX_MAP_CELLS, MAX_MODEL_BYTES, SiteModelFileError,
};
pub use fit::{SiteConfig, SiteFitConfig, TrainingData, calibrate_pdr};
pub use pressure::{
    HEIGHT_PAIR_MAX_MS, REFERENCE_MAX_RANGE_HPA, REFERENCE_STRETCH_MS, building_floors,
    floor_heights, pressure_references,
};
pub use provenance::{Provenance, SourceFile};
pub use survey::{
    DEFAULT_LEAVE_OUT_GROUPS, FloorSurvey, LeaveOneOut, LeaveOutPoint, MAX_LEAVE_OUT_POINTS,
    SurveySettings, floor_survey, leave_one_walk_out, survey_floors,
};

use crate::{
    Positioner, PositionerConfig, PositioningError, PressureReference, Site, StreamIdentity,
    stream_seed,
};
use std::collections::BTreeMap;
use std::sync::Arc;
use thiserror::Error;
use wipdr_core::ConfigError;
use wipdr_core::{FloorPlan, GeoFrame, Point2, Segment};
use wipdr_fingerprint::likelihood::ScanLikelihood;
use wipdr_fingerprint::{MatcherModel, RadioMap};
use wipdr_fusion::SchemeConfig;
use wipdr_fusion::trails::TrailRaster;

/// Raster cell of a site model's trail raster, metres.
pub const TRAIL_CELL_M: f64 = 0.5;
/// Distance cap of a site model's trail raster, metres.
pub const TRAIL_MAX_DISTANCE_M: f64 = 15.0;

/// Why a site model could not be fit, built or used.
#[derive(Debug, Error)]
pub enum SiteModelError {
    /// The radio map or matcher could not be built (no reference point, no heard AP, a
    /// setting out of range).
    #[error("radio map: {0}")]
    Fingerprint(#[from] wipdr_fingerprint::FingerprintError),
    /// A positioner setting is invalid, or a stream's positioner could not be built.
    #[error(transparent)]
    Positioning(#[from] PositioningError),
    /// Both walks and a survey table were given.
    #[error(
        "training data: give walks or a survey table, not both (fit one site model from each and compare them)"
    )]
    WalksAndSurvey,
    /// A scheme name no scheme has.
    #[error("scheme {name:?}: {source}")]
    Scheme {
        /// The name asked for.
        name: String,
        /// Cause (lists the known names).
        source: wipdr_fusion::FusionError,
    },
    /// A model file could not be read or written.
    #[error(transparent)]
    File(#[from] SiteModelFileError),
    /// The survey guidance could not be made (a bad setting, a raster over its limit) or its
    /// saved leave-one-out errors are invalid.
    #[error("survey guidance: {0}")]
    Survey(String),
}

/// What a site model saves: the learned data and its settings. [`SiteModel`] adds what is
/// derived from it on load. The large parts are shared (`Arc`) with the matcher and the
/// streams, never copied.
#[derive(Debug, Clone, PartialEq)]
pub struct SiteModelData {
    /// The site's display name.
    pub name: String,
    /// The positioner every stream runs: its `pdr` calibrated on the training walks, its
    /// `floor.fixes_across_floors` resolved for this site.
    pub config: PositionerConfig,
    /// Scheme settings by name; a scheme not listed runs with its defaults.
    pub schemes: BTreeMap<String, SchemeConfig>,
    /// The radio map (after interpolation and path-loss extension).
    pub radio_map: Arc<RadioMap>,
    /// The measured reference points (before any path-loss extension).
    pub measured: Arc<Vec<MeasuredPoint>>,
    /// Whether the extension's synthesised points count as coverage for coverage-aware
    /// schemes (`pmf`).
    pub coverage_includes_extension: bool,
    /// Where the training walks went: the segments between their consecutive waypoints.
    pub trail_segments: Vec<Segment>,
    /// The training walks' barometer on known floors.
    pub pressure_references: Arc<Vec<PressureReference>>,
    /// The floor plan, where the data has one.
    pub plan: Option<FloorPlan>,
    /// The WGS84 frame of the metre coordinates, where known.
    pub geo_frame: Option<GeoFrame>,
    /// The building's floors, sorted: every floor number from the lowest to the highest the
    /// radio map and the waypoints name ([`building_floors`]; those without fingerprints
    /// are reached by the barometer alone); empty for a single floor without floor numbers.
    pub floors: Vec<i32>,
    /// The height of each of [`SiteModelData::floors`], metres above the lowest
    /// ([`floor_heights`]: from the training walks' pressure where they change floor, else
    /// [`crate::FloorConfig::hpa_per_floor`] apart); empty: that default for every floor.
    pub floor_heights_m: Vec<f64>,
    /// Where the model came from.
    pub provenance: Provenance,
    /// The Wi-Fi errors of the training scans with their walk left out of the radio map
    /// ([`leave_one_walk_out`]), for survey guidance (`wipdr inspect --plot`); `None`: not
    /// measured (a model fit in code or by the evaluation, `wipdr fit --no-leave-one-out`).
    /// Never read by the positioner.
    pub leave_one_out: Option<LeaveOneOut>,
}

/// A fitted site; see the [module docs](self).
#[derive(Debug, Clone)]
pub struct SiteModel {
    data: SiteModelData,
    matcher: MatcherModel,
    site: Site,
}

/// What a stream tells its [`Positioner`] when it is built from a [`SiteModel`].
#[derive(Debug, Clone, Default)]
pub struct StreamSpec {
    /// The stream's id, mixed into the seed ([`stream_seed`]) so every stream has its own
    /// random sequence; `None`: the config's seed as it is.
    pub id: Option<String>,
    /// Phone model and start time, for the barometric references; `None`: none used.
    pub identity: Option<StreamIdentity>,
    /// A known start position (the `pdr` baseline's true first waypoint).
    pub start: Option<Point2>,
}

impl SiteModel {
    /// A model from its saved data: checks it ([`RadioMap::check_consistent`], the config's
    /// validation) and builds the matcher and the plan's indexes (`plan_site`, when given,
    /// is used instead of indexing `data.plan` again).
    pub fn from_data(data: SiteModelData, plan_site: Option<Site>) -> Result<Self, SiteModelError> {
        data.radio_map.check_consistent()?;
        data.config.validate()?;
        if let Some(loo) = &data.leave_one_out {
            loo.validate()
                .map_err(|e| SiteModelError::Survey(format!("leave-one-out errors: {e}")))?;
        }
        for (name, scheme) in &data.schemes {
            scheme.validate().map_err(|e| {
                PositioningError::InvalidConfig(ConfigError::new(
                    format!("schemes.{name}"),
                    e.to_string(),
                ))
            })?;
        }
        let map = data.radio_map.clone();
        let matcher = data.config.matcher.build(map.clone())?;
        let mut site = plan_site.unwrap_or_else(|| Site::from_plan(data.plan.as_ref()));
        site.coverage = Some(Arc::new(if data.coverage_includes_extension {
            map.points().iter().map(|p| p.position).collect()
        } else {
            data.measured.iter().map(|p| p.position).collect()
        }));
        site.trails = if data.trail_segments.is_empty() {
            None
        } else {
            match TrailRaster::new(&data.trail_segments, TRAIL_CELL_M, TRAIL_MAX_DISTANCE_M) {
                Ok(r) => Some(Arc::new(r)),
                Err(e) => {
                    tracing::warn!(site = %data.name, error = %e, "no trail raster");
                    None
                }
            }
        };
        // Data-dependent failures (a raster over its limit because a reference point lies
        // far off the floor) leave the model without the likelihood, logged, as the trail
        // raster does: its fixes are then points only (`pmf` weighs them by the Gaussian).
        site.likelihood = match ScanLikelihood::fit(&map, &data.config.likelihood) {
            Ok(l) => Some(Arc::new(l)),
            Err(e) => {
                tracing::warn!(site = %data.name, error = %e, "no scan likelihood: fixes are points only");
                None
            }
        };
        Ok(Self {
            matcher,
            site,
            data,
        })
    }

    /// The saved part of the model.
    pub fn data(&self) -> &SiteModelData {
        &self.data
    }

    /// The provenance, for the caller that read the input files to name them
    /// ([`Provenance::sources`]) and date the fit: the only part of a model that can change
    /// after fitting.
    pub fn provenance_mut(&mut self) -> &mut Provenance {
        &mut self.data.provenance
    }

    /// Sets the leave-one-walk-out Wi-Fi errors ([`leave_one_walk_out`] on the data the
    /// model was fit on); they change no estimate. Errors when they are invalid
    /// ([`LeaveOneOut::validate`]).
    pub fn set_leave_one_out(&mut self, loo: Option<LeaveOneOut>) -> Result<(), SiteModelError> {
        if let Some(l) = &loo {
            l.validate()
                .map_err(|e| SiteModelError::Survey(format!("leave-one-out errors: {e}")))?;
        }
        self.data.leave_one_out = loo;
        Ok(())
    }

    /// The site's display name.
    pub fn name(&self) -> &str {
        &self.data.name
    }

    /// The positioner config streams run (PDR calibrated, floor settings resolved).
    pub fn config(&self) -> &PositionerConfig {
        &self.data.config
    }

    /// The radio map.
    pub fn radio_map(&self) -> &RadioMap {
        self.matcher.map()
    }

    /// The built matcher (shared by every stream).
    pub fn matcher(&self) -> &MatcherModel {
        &self.matcher
    }

    /// The site's plan indexes, coverage and trails.
    pub fn site(&self) -> &Site {
        &self.site
    }

    /// The measured reference points.
    pub fn measured(&self) -> &Arc<Vec<MeasuredPoint>> {
        &self.data.measured
    }

    /// The barometric references.
    pub fn pressure_references(&self) -> &Arc<Vec<PressureReference>> {
        &self.data.pressure_references
    }

    /// Where the training walks went (`None` when they had fewer than two waypoints each).
    pub fn trails(&self) -> Option<&Arc<TrailRaster>> {
        self.site.trails.as_ref()
    }

    /// The positions of the reference points coverage-aware schemes count as coverage.
    pub fn coverage(&self) -> Arc<Vec<Point2>> {
        self.site.coverage.clone().unwrap_or_default()
    }

    /// The config of scheme `name`: the model's settings for it, else its defaults.
    pub fn scheme(&self, name: &str) -> Result<SchemeConfig, SiteModelError> {
        match self.data.schemes.get(name) {
            Some(c) => Ok(c.clone()),
            None => SchemeConfig::default_for(name).map_err(|source| SiteModelError::Scheme {
                name: name.to_string(),
                source,
            }),
        }
    }

    /// The positioner config of scheme `name` for a stream with seed `seed`.
    pub fn positioner_config(
        &self,
        scheme: &str,
        seed: u64,
    ) -> Result<PositionerConfig, SiteModelError> {
        Ok(PositionerConfig {
            scheme: self.scheme(scheme)?,
            seed,
            ..self.data.config.clone()
        })
    }

    /// A [`Positioner`] for one stream running scheme `name` on this model.
    pub fn positioner(
        &self,
        scheme: &str,
        stream: &StreamSpec,
    ) -> Result<Positioner, SiteModelError> {
        let seed = match &stream.id {
            Some(id) => stream_seed(self.data.config.seed, id),
            None => self.data.config.seed,
        };
        let config = self.positioner_config(scheme, seed)?;
        let mut positioner =
            Positioner::from_parts(&self.matcher, &self.site, &config, stream.start)?;
        if !self.data.floors.is_empty() {
            positioner.set_building_floors(&self.data.floors, &self.data.floor_heights_m);
        }
        if let Some(id) = &stream.identity {
            positioner.set_pressure_references(self.data.pressure_references.clone(), id.clone());
        }
        Ok(positioner)
    }
}

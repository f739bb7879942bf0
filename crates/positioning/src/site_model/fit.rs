//! Learning a site: the radio map (with its interpolation and path-loss extension), the
//! calibrated PDR, the barometric references and where the training walks went, from a
//! site's training data in the core vocabulary.

use super::coverage::{MeasuredPoint, measured_points};
use super::pressure::{building_floors, floor_heights, pressure_references};
use super::{Provenance, SiteModel, SiteModelData, SiteModelError};
use crate::PositionerConfig;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::sync::Arc;
use wipdr_core::{FingerprintTable, FloorPlan, GeoFrame, Segment, Walk};
use wipdr_fingerprint::RadioMap;
use wipdr_fingerprint::interpolate::{AlongWalkConfig, InterpolationConfig, Kernel, SpatialConfig};
use wipdr_fingerprint::propagation::{PropagationConfig, extend_radio_map, fit_ap_models};
use wipdr_fingerprint::radio_map::per_floor;
use wipdr_fingerprint::walk_map::{WalkMapConfig, build_from_walks};
use wipdr_fusion::SchemeConfig;
use wipdr_fusion::trails::trails_of;
use wipdr_pdr::calibrate::{CalibrationConfig, WalkSteps, calibrate_config};
use wipdr_pdr::{CheckedPdrConfig, Pdr, PdrConfig};

/// How a site is learned from its training data (the `[radio_map]`, `propagation`,
/// `calibrate_pdr` and `[calibration]` settings of an evaluation config).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SiteFitConfig {
    /// How training walks become a radio map ([`WalkMapConfig`]).
    pub radio_map: WalkMapConfig,
    /// Extend the radio map into its coverage gaps with per-AP path-loss models fitted on the
    /// training fingerprints (synthesised points only where the floor plan is walkable);
    /// `None`: off. In TOML, `"off"` stands for `None` ([`wipdr_core::off`]).
    #[serde(with = "wipdr_core::off")]
    pub propagation: Option<PropagationConfig>,
    /// Count the synthesised points of `propagation` as coverage.
    pub propagation_is_coverage: bool,
    /// Fit step length, heading offset and the heading grid on the training walks.
    pub calibrate_pdr: bool,
    /// How the calibration fits ([`CalibrationConfig`]).
    pub calibration: CalibrationConfig,
}

impl Default for SiteFitConfig {
    /// The best measured setting (`docs/results/accuracy.md`): the radio map interpolated
    /// along the training walks (1 m) and onto a 3 m lattice (Gaussian kernel, sigma 3 m,
    /// radius 6 m), the path-loss extension into coverage gaps down to -85 dBm, PDR calibrated.
    fn default() -> Self {
        Self {
            radio_map: WalkMapConfig {
                interpolation: Some(InterpolationConfig {
                    along_walk: Some(AlongWalkConfig::default()),
                    spatial: Some(SpatialConfig {
                        cell_m: 3.0,
                        radius_m: 6.0,
                        kernel: Kernel::Gaussian { sigma_m: 3.0 },
                        ..SpatialConfig::default()
                    }),
                }),
                ..WalkMapConfig::default()
            },
            propagation: Some(PropagationConfig {
                min_predicted_dbm: -85.0,
                ..PropagationConfig::default()
            }),
            ..Self::paper()
        }
    }
}

impl SiteFitConfig {
    /// The papers' setting: the radio map of the measured fingerprints alone (no
    /// interpolation, no extension), PDR calibrated on the training walks.
    pub fn paper() -> Self {
        Self {
            radio_map: WalkMapConfig::default(),
            propagation: None,
            propagation_is_coverage: false,
            calibrate_pdr: true,
            calibration: CalibrationConfig::default(),
        }
    }
}

/// Everything a site is fit with: how it is learned, the positioner every stream runs, and
/// the named scheme settings that override a scheme's defaults.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SiteConfig {
    /// How the site is learned.
    pub fit: SiteFitConfig,
    /// The positioner (its `pdr` before calibration; its `scheme` is the model's default).
    pub positioner: PositionerConfig,
    /// Scheme settings by name (`[schemes.pmf]`); a scheme not listed runs with its defaults.
    pub schemes: BTreeMap<String, SchemeConfig>,
}

/// A site's training data in the core vocabulary.
#[derive(Debug, Clone, Copy, Default)]
pub struct TrainingData<'a> {
    /// The site's display name (`site1`, `ipin2023`).
    pub name: &'a str,
    /// Walks with waypoints (the radio map, the PDR calibration, the barometric references
    /// and the trails come from them).
    pub walks: &'a [&'a Walk],
    /// Survey fingerprints (a benchmark table: one reference point per row), for a site
    /// surveyed point by point instead of walked. A site is fit from walks or from a survey
    /// table, not both.
    pub survey: Option<&'a FingerprintTable>,
    /// The floor plan in the data's metre frame (walls, walkable space); `None`: no plan.
    pub plan: Option<&'a FloorPlan>,
    /// Where the metre frame lies in WGS84, where known (estimates can then be written in
    /// latitude and longitude).
    pub geo_frame: Option<GeoFrame>,
}

/// The radio map's measured fingerprints and the extended map: what [`fit_radio_map`] learns.
pub(super) struct LearnedMap {
    pub(super) map: RadioMap,
    measured: Vec<MeasuredPoint>,
    extended: bool,
}

/// The radio map of `data` under `fit`: from the walks or the survey table, interpolated,
/// extended by path-loss models.
pub(super) fn fit_radio_map(
    data: &TrainingData<'_>,
    fit: &SiteFitConfig,
) -> Result<LearnedMap, SiteModelError> {
    let mut map = match (data.survey, data.walks.is_empty()) {
        (Some(_), false) => return Err(SiteModelError::WalksAndSurvey),
        (Some(table), true) => RadioMap::from_table(table, fit.radio_map.radio)?,
        (None, _) => {
            let (map, report) = build_from_walks(data.walks.iter().copied(), &fit.radio_map)?;
            tracing::debug!(
                site = data.name,
                points = map.len(),
                aps = map.n_aps(),
                ?report,
                "radio map"
            );
            map
        }
    };
    let measured = measured_points(&map);
    let mut extended = false;
    if let Some(prop) = &fit.propagation {
        // Per floor: an AP's path-loss model is fitted on (and extends) one floor.
        // Data-dependent failures (a lattice over the limit because a training waypoint lies
        // far off the floor) skip the extension, logged, as the trail raster does; the config
        // itself was validated before.
        let mut extended_map = map.clone();
        let plan = data.plan;
        match per_floor(&mut extended_map, |m| {
            let models = fit_ap_models(m, prop)?;
            extend_radio_map(m, &models, prop, |p| {
                plan.is_none_or(|plan| plan.outline.is_empty() || plan.is_walkable(p))
            })
        }) {
            Ok(report) => {
                tracing::info!(
                    site = data.name,
                    ?report,
                    "radio map extended by path-loss models"
                );
                map = extended_map;
                extended = true;
            }
            Err(e) => tracing::warn!(
                site = data.name,
                "radio map not extended by path-loss models (skipped): {e}"
            ),
        }
    }
    Ok(LearnedMap {
        map,
        measured,
        extended,
    })
}

/// Runs PDR under `base` on the `training` walks (their waypoints are training data) and
/// calibrates it there ([`calibrate_config`]: step length, heading offset, the grid
/// orientation of heading snapping). Returns `base` unchanged when there is nothing to fit on.
pub fn calibrate_pdr(
    base: &CheckedPdrConfig,
    cal: &CalibrationConfig,
    training: &[&Walk],
) -> PdrConfig {
    let detailed: Vec<_> = training
        .par_iter()
        .map(|w| Pdr::run_detailed(*base, w).0)
        .collect();
    let walks: Vec<WalkSteps<'_>> = detailed
        .iter()
        .zip(training)
        .map(|(steps, w)| WalkSteps {
            steps,
            waypoints: &w.waypoints,
        })
        .collect();
    calibrate_config(base, cal, &walks).0
}

/// The floors the training data names: the radio map's and the waypoints', sorted.
fn floors_of(data: &TrainingData<'_>, map: &RadioMap) -> Vec<i32> {
    let mut floors: Vec<i32> = map
        .points()
        .iter()
        .filter_map(|p| p.floor)
        .chain(
            data.walks
                .iter()
                .flat_map(|w| w.waypoints.iter().filter_map(|p| p.floor)),
        )
        .collect();
    floors.sort_unstable();
    floors.dedup();
    floors
}

impl SiteModel {
    /// Learns a site from its training data under `config`: the radio map (walks or survey
    /// table, interpolated and extended as `config.fit` says), the PDR calibrated on the
    /// walks, the barometric references, the trails, and the plan's indexes. Errors when the
    /// data gives no radio map (no heard AP, no reference point) or a setting is invalid.
    pub fn fit(data: &TrainingData<'_>, config: &SiteConfig) -> Result<Self, SiteModelError> {
        Self::fit_sharing_plan(data, config, None)
    }

    /// [`SiteModel::fit`] with the plan's indexes already built (`plan_site`: walls and
    /// walkable raster of `data.plan`, [`crate::Site::from_plan`]), as the evaluation shares
    /// them between the folds of a floor.
    pub fn fit_sharing_plan(
        data: &TrainingData<'_>,
        config: &SiteConfig,
        plan_site: Option<crate::Site>,
    ) -> Result<Self, SiteModelError> {
        config.positioner.validate()?;
        let learned = fit_radio_map(data, &config.fit)?;
        let mut positioner = config.positioner.clone();
        if config.fit.calibrate_pdr && !data.walks.is_empty() {
            let base = (positioner.pdr.check())
                .map_err(|e| crate::PositioningError::from(e.under("pdr")))?;
            positioner.pdr = calibrate_pdr(&base, &config.fit.calibration, data.walks);
        }
        // Fixes keep their candidates on every floor where the floors share one WGS84 frame
        // (they lie over each other), unless the config says.
        positioner.floor.fixes_across_floors = Some(
            positioner
                .floor
                .fixes_across_floors
                .unwrap_or(data.geo_frame.is_some()),
        );
        let trail_segments: Vec<Segment> =
            trails_of(data.walks.iter().map(|w| w.waypoints.as_slice()));
        let provenance = Provenance::of(data, &learned.map);
        let floors = building_floors(&floors_of(data, &learned.map));
        let floor_heights_m = floor_heights(data.walks, &floors, positioner.floor.hpa_per_floor);
        let model_data = SiteModelData {
            name: data.name.to_string(),
            config: positioner,
            schemes: config.schemes.clone(),
            coverage_includes_extension: learned.extended && config.fit.propagation_is_coverage,
            radio_map: Arc::new(learned.map),
            measured: Arc::new(learned.measured),
            trail_segments,
            pressure_references: Arc::new(pressure_references(data.walks)),
            plan: data.plan.cloned(),
            geo_frame: data.geo_frame,
            floors,
            floor_heights_m,
            provenance,
            leave_one_out: None,
        };
        SiteModel::from_data(model_data, plan_site)
    }
}

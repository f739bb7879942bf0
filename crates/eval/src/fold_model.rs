//! One protocol fold of one floor: the site model fit on the fold's training walks
//! ([`SiteModel::fit`], the same code a user fits their building with) and the test walks it
//! positions.

use crate::config::EvalConfig;
use crate::coverage::coverage_distance;
use crate::error::EvalError;
use crate::fold_rules::folds_of_walks;
use crate::input::FloorInput;
use crate::streams::MissingStream;
use std::sync::Arc;
use wipdr_core::{Point2, StepEvent, TimestampMs, Walk, Waypoint, WifiObservation};
use wipdr_fusion::trails::TrailRaster;
use wipdr_positioning::site_model::{SiteModel, SiteModelError, StreamSpec, TrainingData};
use wipdr_positioning::{Frontend, Positioner, Site, StreamIdentity, samples_of};

/// Who recorded a walk and when (phone model and start time), where its metadata says.
pub fn identity_of(walk: &Walk) -> Option<StreamIdentity> {
    Some(StreamIdentity {
        model: walk.meta.model.clone()?,
        start_unix_ms: walk.meta.start_time?,
    })
}

/// One test walk turned into scheme inputs.
#[derive(Debug, Clone)]
pub struct PreparedWalk {
    /// Floor label.
    pub floor: String,
    /// Index of the floor in the input list.
    pub floor_index: usize,
    /// Walk id.
    pub walk: String,
    /// Protocol fold.
    pub fold: usize,
    /// PDR steps (calibrated on the fold's training walks).
    pub steps: Vec<StepEvent>,
    /// Wi-Fi observations (radio map of the fold's training walks).
    pub observations: Vec<WifiObservation>,
    /// Scans the matcher could not use (no known AP left after filtering, …).
    pub unmatched_scans: usize,
    /// Time of the walk's first Wi-Fi scan.
    pub first_scan_t: Option<TimestampMs>,
    /// Ground truth, for scoring only.
    pub waypoints: Vec<Waypoint>,
    /// Each waypoint's distance to the fold's nearest measured reference point on its floor
    /// (aligned with `waypoints`; [`crate::coverage`]), for the error-by-coverage table.
    pub waypoint_coverage_m: Vec<Option<f64>>,
    /// The stream's floor estimate (`(time, floor)` at each change; empty when the radio
    /// map has no floors): scheme-independent, made by the front end from Wi-Fi and the
    /// barometer.
    pub floors: Vec<(TimestampMs, i32)>,
    /// Fixes dropped because none of their candidates was on the stream's floor.
    pub off_floor_fixes: usize,
    /// Positions of the fold's radio-map reference points (training data: where the map
    /// has fingerprints), shared by the fold's walks; coverage-aware schemes use it.
    pub coverage: Arc<Vec<Point2>>,
    /// Where the fold's training walks went (segments between their consecutive waypoints),
    /// shared by the fold's walks; `pmf`'s trail prior uses it. `None` when the training
    /// walks have fewer than two waypoints each.
    pub trails: Option<Arc<TrailRaster>>,
    /// The input streams the walk lacks ([`crate::streams::missing_streams`]): a scheme
    /// that needs one of them is not run on it but counted as a skipped run.
    pub missing_streams: Vec<MissingStream>,
}

impl PreparedWalk {
    /// The true first waypoint: the start of the PDR-only baseline (and only of it).
    pub fn true_start(&self) -> Option<Waypoint> {
        self.waypoints.first().copied()
    }
}

/// What one fold learned from its training walks: the site model, and the walks it tests.
#[derive(Debug, Clone)]
pub struct FoldModel {
    /// The fold.
    pub fold: usize,
    /// The site model fit on the fold's training walks.
    pub model: SiteModel,
    /// Indices (into the floor's walks) of the fold's test walks.
    pub test_walks: Vec<usize>,
}

/// The protocol fold of every walk of a floor ([`folds_of_walks`]: by route where walks
/// have routes, else walk `i` of the name order in fold `i mod 5`).
pub fn folds_of(floor: &FloorInput) -> Vec<usize> {
    folds_of_walks(&floor.data.walks).0
}

/// The number of protocol folds of a floor.
pub fn fold_count(floor: &FloorInput) -> usize {
    folds_of_walks(&floor.data.walks).1
}

impl FoldModel {
    /// Learns fold `fold` of `floor` from its training walks under `cfg`.
    pub fn build(floor: &FloorInput, fold: usize, cfg: &EvalConfig) -> Result<Self, EvalError> {
        Self::build_sharing_plan(floor, fold, cfg, None)
    }

    /// [`FoldModel::build`] with the floor plan's indexes already built (`plan_site`,
    /// [`Site::from_plan`] of the floor's plan), shared between a floor's folds.
    pub fn build_sharing_plan(
        floor: &FloorInput,
        fold: usize,
        cfg: &EvalConfig,
        plan_site: Option<Site>,
    ) -> Result<Self, EvalError> {
        let folds = folds_of(floor);
        let (test, training): (Vec<usize>, Vec<usize>) =
            (0..folds.len()).partition(|&i| folds[i] == fold);
        Self::build_on(floor, fold, &training, test, cfg, plan_site)
    }

    /// Learns from every walk of `floor` but walk `index` (a walk located with all the
    /// others as training data, as `wipdr locate` does for a logfile); the model's `fold` is
    /// [`usize::MAX`] (no protocol fold).
    pub fn build_all_but(
        floor: &FloorInput,
        index: usize,
        cfg: &EvalConfig,
    ) -> Result<Self, EvalError> {
        let training: Vec<usize> = (0..floor.data.walks.len())
            .filter(|&i| i != index)
            .collect();
        Self::build_on(floor, usize::MAX, &training, vec![index], cfg, None)
    }

    /// Learns from the walks `training` (indices into the floor's walks), for the test walks
    /// `test_walks`, labelled `fold`: [`SiteModel::fit`] on those walks with the floor's plan
    /// and WGS84 frame.
    pub fn build_on(
        floor: &FloorInput,
        fold: usize,
        training: &[usize],
        test_walks: Vec<usize>,
        cfg: &EvalConfig,
        plan_site: Option<Site>,
    ) -> Result<Self, EvalError> {
        let walks = &floor.data.walks;
        let training: Vec<&Walk> = training.iter().filter_map(|&i| walks.get(i)).collect();
        let model = fit_site(floor, fold, &training, cfg, plan_site)?;
        Ok(Self {
            fold,
            model,
            test_walks,
        })
    }

    /// A whole [`Positioner`] for one stream on this model, as `wipdr locate` builds it:
    /// scheme `scheme` with the config's settings for it, the seed mixed with `stream_id`,
    /// and, with an `identity`, the model's barometric references. `start` is a known start
    /// position (the `pdr` baseline's true first waypoint).
    pub fn positioner(
        &self,
        floor: &FloorInput,
        scheme: &str,
        stream_id: &str,
        identity: Option<StreamIdentity>,
        start: Option<Point2>,
    ) -> Result<Positioner, EvalError> {
        self.model
            .positioner(
                scheme,
                &StreamSpec {
                    id: Some(stream_id.to_string()),
                    identity,
                    start,
                },
            )
            .map_err(|e| site_error(floor, self.fold, e))
    }

    /// Streams a test walk's raw samples through the front end of the
    /// [`Positioner`] (PDR + stream matcher,
    /// [`Frontend::record`]), recording its motion (step or learned odometry, as the config's
    /// `odometry` says) and fix events: the scheme-independent half of every run, done once
    /// per walk.
    pub fn prepare_walk(
        &self,
        floor: &FloorInput,
        floor_index: usize,
        walk: &Walk,
        cfg: &EvalConfig,
    ) -> Result<PreparedWalk, EvalError> {
        let config = self.model.config();
        let mut frontend = Frontend::with_floor_config(
            config
                .pdr
                .check()
                .map_err(|e| EvalError::from(e.under("pdr")))?,
            self.model.matcher().stream(cfg.positioner.query),
            config.floor,
        )
        .with_odometry_model(
            config.odometry,
            floor.odometry.clone(),
            config.pdr.heading.map_offset_rad,
        )
        .map_err(|source| EvalError::Positioning {
            floor: floor.label.clone(),
            source,
        })?
        // Every fix carries its scan's likelihood: the schemes that do not read it ignore it.
        .with_likelihood(self.model.site().likelihood.clone());
        let data = self.model.data();
        if !data.floors.is_empty() {
            frontend.set_building_floors(&data.floors, &data.floor_heights_m);
        }
        if let Some(id) = identity_of(walk) {
            frontend.set_pressure_references(self.model.pressure_references().clone(), id);
        }
        let recorded = frontend.record(samples_of(walk));
        let counts = frontend.counts();
        Ok(PreparedWalk {
            floor: floor.label.clone(),
            floor_index,
            walk: walk.meta.id.clone(),
            fold: self.fold,
            steps: recorded.steps,
            observations: recorded.fixes,
            unmatched_scans: usize::try_from(counts.unmatched_scans).unwrap_or(usize::MAX),
            first_scan_t: walk.wifi.first().map(|s| s.t),
            waypoint_coverage_m: walk
                .waypoints
                .iter()
                .map(|w| coverage_distance(w.position, w.floor, self.model.measured()))
                .collect(),
            waypoints: walk.waypoints.clone(),
            floors: recorded.floors,
            off_floor_fixes: usize::try_from(counts.off_floor_fixes).unwrap_or(usize::MAX),
            coverage: self.model.coverage(),
            trails: self.model.trails().cloned(),
            missing_streams: crate::streams::missing_streams(walk),
        })
    }
}

/// Fits the site model of one fold (see [`FoldModel::build_on`]).
pub fn fit_site(
    floor: &FloorInput,
    fold: usize,
    training: &[&Walk],
    cfg: &EvalConfig,
    plan_site: Option<Site>,
) -> Result<SiteModel, EvalError> {
    let data = TrainingData {
        name: &floor.label,
        walks: training,
        survey: None,
        plan: Some(&floor.data.plan),
        geo_frame: floor.data.geo_frame,
    };
    SiteModel::fit_sharing_plan(&data, &cfg.site_config(), plan_site)
        .map_err(|e| site_error(floor, fold, e))
}

/// A site model error of one fold as an evaluation error naming the floor and fold.
fn site_error(floor: &FloorInput, fold: usize, e: SiteModelError) -> EvalError {
    match e {
        SiteModelError::Fingerprint(source) => EvalError::Fingerprint {
            floor: floor.label.clone(),
            fold,
            source,
        },
        SiteModelError::Positioning(source) => EvalError::Positioning {
            floor: floor.label.clone(),
            source,
        },
        SiteModelError::Scheme { name, source } => EvalError::Scheme {
            scheme: name,
            source,
        },
        other => EvalError::Site {
            floor: floor.label.clone(),
            reason: other.to_string(),
        },
    }
}

//! One protocol fold of one floor: what is learned from the training walks (radio map and
//! its extension, the built matcher, the calibrated PDR, coverage and trails), and the
//! [`Positioner`](wipdr_positioning::Positioner) parts a test walk runs through.

use crate::folds::folds_of_walks;
use crate::pipeline::{EvalConfig, calibrate_pdr};
use crate::pipeline::{EvalError, FloorInput, PreparedWalk, TRAIL_CELL_M, TRAIL_MAX_DISTANCE_M};
use std::sync::Arc;
use wipdr_core::{Point2, TimestampMs, Walk};
use wipdr_fingerprint::MatcherModel;
use wipdr_fingerprint::propagation::{extend_radio_map, fit_ap_models};
use wipdr_fingerprint::radio_map::per_floor;
use wipdr_fingerprint::walk_map::build_from_walks;
use wipdr_fusion::trails::{TrailRaster, trails_of};
use wipdr_pdr::PdrConfig;
use wipdr_positioning::{Event, Frontend, Site, samples_of};

/// What one fold learned from its training walks.
#[derive(Debug, Clone)]
pub struct FoldModel {
    /// The fold.
    pub fold: usize,
    /// The matcher built on the fold's radio map.
    pub matcher: MatcherModel,
    /// The PDR config, calibrated on the training walks when the config asks.
    pub pdr: PdrConfig,
    /// Positions of the radio map's measured reference points (coverage for `pmf`).
    pub coverage: Arc<Vec<Point2>>,
    /// Where the training walks went; `None` when they have fewer than two waypoints each.
    pub trails: Option<Arc<TrailRaster>>,
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
        let folds = folds_of(floor);
        let (test, training): (Vec<usize>, Vec<usize>) =
            (0..folds.len()).partition(|&i| folds[i] == fold);
        Self::build_on(floor, fold, &training, test, cfg)
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
        Self::build_on(floor, usize::MAX, &training, vec![index], cfg)
    }

    /// Learns from the walks `training` (indices into the floor's walks), for the test walks
    /// `test_walks`, labelled `fold`.
    pub fn build_on(
        floor: &FloorInput,
        fold: usize,
        training: &[usize],
        test_walks: Vec<usize>,
        cfg: &EvalConfig,
    ) -> Result<Self, EvalError> {
        let walks = &floor.data.walks;
        let training: Vec<&Walk> = training.iter().filter_map(|&i| walks.get(i)).collect();
        let fp_err = |source| EvalError::Fingerprint {
            floor: floor.label.clone(),
            fold,
            source,
        };
        let (mut map, report) =
            build_from_walks(training.iter().copied(), &cfg.radio_map).map_err(fp_err)?;
        tracing::debug!(floor = %floor.label, fold, points = map.len(), aps = map.n_aps(), ?report, "radio map");
        let mut coverage: Arc<Vec<Point2>> =
            Arc::new(map.points().iter().map(|p| p.position).collect());
        if let Some(prop) = &cfg.propagation {
            let plan = &floor.data.plan;
            // Per floor: an AP's path-loss model is fitted on (and extends) one floor.
            let extended = per_floor(&mut map, |m| {
                let models = fit_ap_models(m, prop)?;
                extend_radio_map(m, &models, prop, |p| {
                    plan.outline.is_empty() || plan.is_walkable(p)
                })
            })
            .map_err(fp_err)?;
            tracing::info!(floor = %floor.label, fold, ?extended, "radio map extended by path-loss models");
            if cfg.propagation_is_coverage {
                coverage = Arc::new(map.points().iter().map(|p| p.position).collect());
            }
        }
        let segments = trails_of(training.iter().map(|w| w.waypoints.as_slice()));
        let trails = if segments.is_empty() {
            None
        } else {
            match TrailRaster::new(&segments, TRAIL_CELL_M, TRAIL_MAX_DISTANCE_M) {
                Ok(r) => Some(Arc::new(r)),
                Err(e) => {
                    tracing::warn!(floor = %floor.label, fold, error = %e, "no trail raster");
                    None
                }
            }
        };
        let matcher = cfg.matcher.build(Arc::new(map)).map_err(fp_err)?;
        let pdr = if cfg.calibrate_pdr {
            calibrate_pdr(&cfg.pdr, &cfg.calibration, &training)
        } else {
            cfg.pdr
        };
        Ok(Self {
            fold,
            matcher,
            pdr,
            coverage,
            trails,
            test_walks,
        })
    }

    /// The site of a test walk: the floor's plan indexes (`plan_site`, shared per floor)
    /// with this fold's coverage and trails.
    pub fn site(&self, plan_site: &Site) -> Site {
        Site {
            coverage: Some(self.coverage.clone()),
            trails: self.trails.clone(),
            ..plan_site.clone()
        }
    }

    /// Streams a test walk's raw samples through the front end of the
    /// [`Positioner`](wipdr_positioning::Positioner) (PDR + stream matcher), recording its
    /// step and fix events: the scheme-independent half of every run, done once per walk.
    pub fn prepare_walk(
        &self,
        floor: &FloorInput,
        floor_index: usize,
        walk: &Walk,
        cfg: &EvalConfig,
    ) -> PreparedWalk {
        let mut frontend =
            Frontend::with_floor_config(self.pdr, self.matcher.stream(cfg.query), cfg.floor);
        let mut steps = Vec::new();
        let mut observations = Vec::with_capacity(walk.wifi.len());
        let mut floors: Vec<(TimestampMs, i32)> = Vec::new();
        for sample in samples_of(walk) {
            let t = sample.t();
            match frontend.push(&sample) {
                Some(Event::Step(s)) => steps.push(s),
                Some(Event::Fix(o)) => observations.push(o),
                None => {}
            }
            if let Some(f) = frontend.floor()
                && floors.last().is_none_or(|&(_, last)| last != f)
            {
                floors.push((t, f));
            }
        }
        let counts = frontend.counts();
        PreparedWalk {
            floor: floor.label.clone(),
            floor_index,
            walk: walk.meta.id.clone(),
            fold: self.fold,
            steps,
            observations,
            unmatched_scans: usize::try_from(counts.unmatched_scans).unwrap_or(usize::MAX),
            first_scan_t: walk.wifi.first().map(|s| s.t),
            waypoints: walk.waypoints.clone(),
            floors,
            off_floor_fixes: usize::try_from(counts.off_floor_fixes).unwrap_or(usize::MAX),
            coverage: self.coverage.clone(),
            trails: self.trails.clone(),
        }
    }
}

//! One protocol fold of one floor: what is learned from the training walks (radio map and
//! its extension, the built matcher, the calibrated PDR, coverage and trails), and the
//! [`Positioner`](wipdr_positioning::Positioner) parts a test walk runs through.

use crate::coverage::{MeasuredPoint, coverage_distance, measured_points};
use crate::folds::folds_of_walks;
use crate::pipeline::FloorEnv;
use crate::pipeline::{EvalConfig, calibrate_pdr};
use crate::pipeline::{EvalError, FloorInput, PreparedWalk, TRAIL_CELL_M, TRAIL_MAX_DISTANCE_M};
use std::sync::Arc;
use wipdr_core::walk::floor_of_waypoints;
use wipdr_core::{Point2, TimestampMs, Walk};
use wipdr_fingerprint::MatcherModel;
use wipdr_fingerprint::propagation::{extend_radio_map, fit_ap_models};
use wipdr_fingerprint::radio_map::per_floor;
use wipdr_fingerprint::walk_map::build_from_walks;
use wipdr_fusion::SchemeConfig;
use wipdr_fusion::trails::{TrailRaster, trails_of};
use wipdr_pdr::PdrConfig;
use wipdr_positioning::{
    Event, Frontend, Positioner, PressureReference, Site, StreamIdentity, samples_of, stream_seed,
};

/// The floor config of a floor's runs: `fixes_across_floors` resolved where it is auto
/// (across floors where the floors share one WGS84 frame).
pub fn floor_config(floor: &FloorInput, cfg: &EvalConfig) -> wipdr_positioning::FloorConfig {
    let mut c = cfg.floor;
    c.fixes_across_floors = Some(
        c.fixes_across_floors
            .unwrap_or(floor.data.geo_frame.is_some()),
    );
    c
}

/// Who recorded a walk and when (phone model and start time), where its metadata says.
pub fn identity_of(walk: &Walk) -> Option<StreamIdentity> {
    Some(StreamIdentity {
        model: walk.meta.model.clone()?,
        start_unix_ms: walk.meta.start_time?,
    })
}

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
    /// The radio map's measured reference points with their floors (before any path-loss
    /// extension): what [`crate::coverage`] measures a waypoint's distance to.
    pub measured: Arc<Vec<MeasuredPoint>>,
    /// Where the training walks went; `None` when they have fewer than two waypoints each.
    pub trails: Option<Arc<TrailRaster>>,
    /// Indices (into the floor's walks) of the fold's test walks.
    pub test_walks: Vec<usize>,
    /// The training walks' barometer on known floors (for the floor estimate's references).
    pub pressure_references: Arc<Vec<PressureReference>>,
}

/// Length of the stretches a training walk's pressure is averaged over, ms.
pub const REFERENCE_STRETCH_MS: i64 = 30_000;
/// Largest pressure range within a stretch for it to be a reference (a stretch on the
/// stairs is not), hPa.
pub const REFERENCE_MAX_RANGE_HPA: f64 = 0.1;

/// Barometric references from walks with a phone model, a start time (Unix ms) and
/// floors on their waypoints: the mean pressure of each stretch of [`REFERENCE_STRETCH_MS`]
/// within the waypoints' span on one floor, steady within [`REFERENCE_MAX_RANGE_HPA`].
pub fn pressure_references(walks: &[&Walk]) -> Vec<PressureReference> {
    let mut out = Vec::new();
    for w in walks {
        let (Some(model), Some(start)) = (&w.meta.model, w.meta.start_time) else {
            continue;
        };
        let mut stretch: Vec<(TimestampMs, f64)> = Vec::new();
        let mut stretch_floor: Option<i32> = None;
        let mut flush = |stretch: &mut Vec<(TimestampMs, f64)>, floor: Option<i32>| {
            if let (Some(floor), Some(first), Some(last)) = (floor, stretch.first(), stretch.last())
                && stretch.len() >= 5
            {
                let (lo, hi) = stretch
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                        (lo.min(p.1), hi.max(p.1))
                    });
                if hi - lo <= REFERENCE_MAX_RANGE_HPA {
                    let mean = stretch.iter().map(|p| p.1).sum::<f64>() / stretch.len() as f64;
                    out.push(PressureReference {
                        model: model.clone(),
                        t_unix_ms: start.saturating_add((first.0 + last.0) / 2),
                        hpa: mean,
                        floor,
                    });
                }
            }
            stretch.clear();
        };
        for p in &w.pressure {
            let floor = floor_of_waypoints(&w.waypoints, p.t);
            let too_long = stretch
                .first()
                .is_some_and(|f| p.t - f.0 >= REFERENCE_STRETCH_MS);
            if floor != stretch_floor || too_long {
                flush(&mut stretch, stretch_floor);
                stretch_floor = floor;
            }
            if floor.is_some() && p.hpa.is_finite() {
                stretch.push((p.t, p.hpa));
            }
        }
        flush(&mut stretch, stretch_floor);
    }
    out
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
        let measured: Arc<Vec<MeasuredPoint>> = Arc::new(measured_points(&map));
        if let Some(prop) = &cfg.propagation {
            let plan = &floor.data.plan;
            // Per floor: an AP's path-loss model is fitted on (and extends) one floor.
            // Data-dependent failures (a lattice over the limit because a training waypoint
            // lies far off the floor) skip the extension of this fold, logged, as the trail
            // raster does; the config itself was validated before.
            let mut extended_map = map.clone();
            match per_floor(&mut extended_map, |m| {
                let models = fit_ap_models(m, prop)?;
                extend_radio_map(m, &models, prop, |p| {
                    plan.outline.is_empty() || plan.is_walkable(p)
                })
            }) {
                Ok(extended) => {
                    tracing::info!(floor = %floor.label, fold, ?extended, "radio map extended by path-loss models");
                    map = extended_map;
                    if cfg.propagation_is_coverage {
                        coverage = Arc::new(map.points().iter().map(|p| p.position).collect());
                    }
                }
                Err(e) => tracing::warn!(
                    floor = %floor.label,
                    fold,
                    "radio map not extended by path-loss models (skipped for this fold): {e}"
                ),
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
        let pressure_references = Arc::new(pressure_references(&training));
        Ok(Self {
            pressure_references,
            fold,
            matcher,
            pdr,
            coverage,
            measured,
            trails,
            test_walks,
        })
    }

    /// A whole [`Positioner`] for one stream on this model, as `wipdr locate` builds it: the
    /// model's calibrated PDR, `scheme`, the config's wrappers, the seed mixed with
    /// `stream_id` ([`stream_seed`]), the floor config of `floor` ([`floor_config`]), the
    /// site of `floor`'s plan with the model's coverage and trails, and, with an `identity`,
    /// the model's barometric references. `start` is a known start position (the `pdr`
    /// baseline's true first waypoint).
    pub fn positioner(
        &self,
        floor: &FloorInput,
        scheme: SchemeConfig,
        cfg: &EvalConfig,
        stream_id: &str,
        identity: Option<StreamIdentity>,
        start: Option<Point2>,
    ) -> Result<Positioner, EvalError> {
        let mut positioner_cfg = cfg.positioner(scheme, self.pdr);
        positioner_cfg.seed = stream_seed(cfg.seed, stream_id);
        positioner_cfg.floor = floor_config(floor, cfg);
        let site = self.site(&FloorEnv::new(floor).site);
        let mut positioner = Positioner::new(&self.matcher, &site, &positioner_cfg, start)
            .map_err(|source| EvalError::Positioning {
                floor: floor.label.clone(),
                source,
            })?;
        if let Some(id) = identity {
            positioner.set_pressure_references(self.pressure_references.clone(), id);
        }
        Ok(positioner)
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
        let mut frontend = Frontend::with_floor_config(
            self.pdr,
            self.matcher.stream(cfg.query),
            floor_config(floor, cfg),
        );
        if let Some(id) = identity_of(walk) {
            frontend.set_pressure_references(self.pressure_references.clone(), id);
        }
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
            waypoint_coverage_m: walk
                .waypoints
                .iter()
                .map(|w| coverage_distance(w.position, w.floor, &self.measured))
                .collect(),
            waypoints: walk.waypoints.clone(),
            floors,
            off_floor_fixes: usize::try_from(counts.off_floor_fixes).unwrap_or(usize::MAX),
            coverage: self.coverage.clone(),
            trails: self.trails.clone(),
        }
    }
}

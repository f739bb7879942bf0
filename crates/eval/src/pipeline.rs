//! The protocol of `docs/evaluation.md`, end to end: folds per floor, radio map and PDR
//! calibration from the training walks of each fold, causal runs of every scheme over each
//! test walk, scoring at the waypoints.
//!
//! The work is split in two so that sweeps can reuse the expensive part:
//! [`prepare`] turns every test walk into scheme inputs (PDR steps and Wi-Fi observations,
//! which depend on the radio-map, matcher and PDR settings only), and [`run_prepared`] runs
//! fusion schemes over those inputs and scores them. A test walk's waypoints never reach a
//! scheme: they are kept apart in [`PreparedWalk::waypoints`] for scoring; the only exception
//! is the PDR-only baseline, which by the protocol starts at the true first waypoint and is
//! labelled so.

use crate::folds::{FOLDS, folds_by_name};
use crate::report::{EvalReport, WalkResult};
use crate::scoring::{Track, score_track};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::sync::Arc;
use thiserror::Error;
use wipdr_core::{Point2, StepEvent, TimestampMs, Walk, Waypoint, WifiObservation};
use wipdr_fingerprint::distance::{Metric, SharedAp};
use wipdr_fingerprint::med::{MedConfig, MedMatcher};
use wipdr_fingerprint::propagation::{PropagationConfig, extend_radio_map, fit_ap_models};
use wipdr_fingerprint::walk_map::{WalkMapConfig, build_from_walks};
use wipdr_fingerprint::{KnnConfig, KnnMatcher, Matcher, Query, QueryFilter};
use wipdr_fusion::static_start::{StaticStart, StaticStartConfig};
use wipdr_fusion::trails::{TrailRaster, trails_of};
use wipdr_fusion::{BuildContext, MapMatched, SchemeConfig, WalkableGrid, WallIndex};
use wipdr_io::floor::FloorData;
use wipdr_pdr::calibrate::{CalibrationConfig, WalkSteps, fit_heading_offset, fit_step_length};
use wipdr_pdr::{Pdr, PdrConfig};

/// Errors of an evaluation.
#[derive(Debug, Error)]
pub enum EvalError {
    /// A floor has fewer walks than folds.
    #[error("floor {floor}: {walks} walks, need at least {folds} for the protocol folds")]
    TooFewWalks {
        /// Floor label.
        floor: String,
        /// Walks found.
        walks: usize,
        /// Folds required.
        folds: usize,
    },
    /// Building a radio map or matcher failed.
    #[error("floor {floor}, fold {fold}: {source}")]
    Fingerprint {
        /// Floor label.
        floor: String,
        /// Fold.
        fold: usize,
        /// Cause.
        source: wipdr_fingerprint::FingerprintError,
    },
    /// A sweep could not be set up or recorded.
    #[error("sweep: {0}")]
    Sweep(String),
    /// A scheme could not be built from its config.
    #[error("scheme {scheme}: {source}")]
    Scheme {
        /// Scheme name.
        scheme: String,
        /// Cause.
        source: wipdr_fusion::FusionError,
    },
}

/// Everything an evaluation can be told; every field has a default. Deserialises from TOML
/// (`wipdr eval --config FILE.toml`); the sweep tool addresses its fields by dotted path
/// (`radio_map.max_entry_age_ms`, `matcher.k`, `schemes.ekf.r_wifi`, …).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EvalConfig {
    /// How training walks become a radio map.
    pub radio_map: WalkMapConfig,
    /// The matcher.
    pub matcher: KnnConfig,
    /// Online filtering of test scans.
    pub query: QueryFilter,
    /// Use the multi-scan MED matcher (paper 004 eq. 11, Euclidean form) on the same radio
    /// map instead of `matcher`, fed with the PDR displacement between scans. `None`
    /// (default): single-scan `matcher`.
    pub med: Option<MedConfig>,
    /// Use an indexed matcher instead of searching `matcher` by brute force: `apc` (cluster
    /// search, paper 001 §2.3) or `apindex` (AP index, paper 002 §3.2), optionally with
    /// settings `NAME:key=value,...` (`wipdr_fingerprint::cluster_search::apply_spec`, e.g.
    /// `"apc:sim=signal,clusters=3"`, `"apindex:moving=-80"`). Built per fold on the fold's
    /// radio map; its inner WKNN takes `matcher`'s k, weighting, distance and representation
    /// (the spec's `k`, `metric`, `rep` override them). `apindex` is given the walker's motion
    /// from the PDR steps (`wipdr_fingerprint::ap_index::motion_at`: moving when a step came
    /// within `stationary_after_ms`, default 2 s, before the scan). `med` takes precedence.
    /// `None` (default): brute force.
    pub matcher_spec: Option<String>,
    /// Further settings of the indexed matchers (`[clustering.apindex]`, `[clustering.apc]`:
    /// thresholds, clustering), under `matcher_spec`'s keys.
    pub clustering: wipdr_fingerprint::cluster_search::ClusteringMatchersConfig,
    /// The PDR pipeline (before calibration).
    pub pdr: PdrConfig,
    /// Whether step length (and heading offset) are fitted on each fold's training walks.
    pub calibrate_pdr: bool,
    /// How the calibration fits.
    pub calibration: CalibrationConfig,
    /// Score only waypoints after the walk's first Wi-Fi scan, for every scheme (as the
    /// reference pipeline does); earlier ones are counted as skipped.
    pub score_from_first_scan: bool,
    /// Seed of the random schemes (mixed with each walk's id).
    pub seed: u64,
    /// Scheme configs by name; a scheme not listed runs with its defaults.
    pub schemes: BTreeMap<String, SchemeConfig>,
    /// Map-match every scheme's estimates onto the floor plan's walkable space (paper 004
    /// §4; [`MapMatched`]): causal, from the plan alone.
    pub map_matching: bool,
    /// Start every scheme from the robust average of the fixes taken before the first step
    /// (paper 001 §3.2; [`StaticStart`]); `None`: off.
    pub static_start: Option<StaticStartConfig>,
    /// Score only waypoints within this many metres of path from the walk's first waypoint
    /// (the "first 20 m" of issue 8's static start); `None`: the whole walk.
    pub score_first_m: Option<f64>,
    /// Extend each fold's radio map into its coverage gaps with per-AP path-loss models
    /// fitted on the training fingerprints ([`wipdr_fingerprint::propagation`]; synthesised
    /// points only where the floor plan is walkable); `None` (default): off. The synthesised
    /// points do not count as coverage for `pmf`'s gap awareness unless
    /// `propagation_is_coverage`.
    pub propagation: Option<PropagationConfig>,
    /// Count the synthesised points of `propagation` as coverage (see [`PreparedWalk::coverage`]).
    pub propagation_is_coverage: bool,
}

impl Default for EvalConfig {
    fn default() -> Self {
        Self {
            radio_map: WalkMapConfig::default(),
            // The shared-AP distance (findings.md) is the tuned default for recorded walks;
            // `docs/configs/reference.toml` restores the reference's Euclidean WKNN.
            matcher: KnnConfig {
                metric: Metric::SharedAp(SharedAp::default()),
                ..KnnConfig::default()
            },
            query: QueryFilter {
                max_age_ms: WalkMapConfig::default().max_entry_age_ms,
                ..QueryFilter::default()
            },
            med: None,
            matcher_spec: None,
            clustering: Default::default(),
            pdr: PdrConfig::default(),
            calibrate_pdr: true,
            calibration: CalibrationConfig::default(),
            score_from_first_scan: true,
            seed: 1,
            schemes: BTreeMap::new(),
            map_matching: false,
            static_start: None,
            score_first_m: None,
            propagation: None,
            propagation_is_coverage: false,
        }
    }
}

impl EvalConfig {
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

    /// A key of the settings [`prepare`] depends on (equal keys, equal prepared inputs): the
    /// whole config without the fields that only the scheme runs and the scoring read. Built
    /// by exclusion, so that a field added later counts as a preparation input (safe: at
    /// worst a sweep prepares more often than it needs to).
    pub fn preparation_key(&self) -> String {
        const RUN_ONLY: [&str; 6] = [
            "schemes",
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

/// A floor under evaluation: its label (as given on the command line) and data.
#[derive(Debug, Clone)]
pub struct FloorInput {
    /// Label used in reports.
    pub label: String,
    /// The parsed floor.
    pub data: Arc<FloorData>,
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
    /// Positions of the fold's radio-map reference points (training data: where the map
    /// has fingerprints), shared by the fold's walks; coverage-aware schemes use it.
    pub coverage: Arc<Vec<Point2>>,
    /// Where the fold's training walks went (segments between their consecutive waypoints),
    /// shared by the fold's walks; `pmf`'s trail prior uses it. `None` when the training
    /// walks have fewer than two waypoints each.
    pub trails: Option<Arc<TrailRaster>>,
}

/// Raster cell of [`PreparedWalk::trails`], metres.
pub const TRAIL_CELL_M: f64 = 0.5;
/// Distance cap of [`PreparedWalk::trails`], metres.
pub const TRAIL_MAX_DISTANCE_M: f64 = 15.0;

impl PreparedWalk {
    /// The true first waypoint: the start of the PDR-only baseline (and only of it).
    pub fn true_start(&self) -> Option<Waypoint> {
        self.waypoints.first().copied()
    }
}

/// Steps of `walk` under `cfg`.
pub fn steps_of(cfg: &PdrConfig, walk: &Walk) -> Vec<StepEvent> {
    Pdr::run(*cfg, walk)
}

/// Fits step length and heading offset on `training` walks (their waypoints are training
/// data). Returns `base` unchanged when there is nothing to fit on.
pub fn calibrate_pdr(base: &PdrConfig, cal: &CalibrationConfig, training: &[&Walk]) -> PdrConfig {
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
    let mut out = *base;
    out.step_length = fit_step_length(base.step_length, &walks, cal);
    if cal.fit_heading_offset
        && let Some(off) = fit_heading_offset(&out.step_length, base.heading.source, &walks, cal)
    {
        out.heading.map_offset_rad = base.heading.map_offset_rad + off;
    }
    out
}

/// Turns every walk of `floors` into scheme inputs under the protocol folds.
pub fn prepare(floors: &[FloorInput], cfg: &EvalConfig) -> Result<Vec<PreparedWalk>, EvalError> {
    let mut jobs = Vec::new();
    for (fi, f) in floors.iter().enumerate() {
        let n = f.data.walks.len();
        if n < FOLDS {
            return Err(EvalError::TooFewWalks {
                floor: f.label.clone(),
                walks: n,
                folds: FOLDS,
            });
        }
        for fold in 0..FOLDS {
            jobs.push((fi, fold));
        }
    }
    let per_fold: Vec<Result<Vec<PreparedWalk>, EvalError>> = jobs
        .par_iter()
        .map(|&(fi, fold)| prepare_fold(&floors[fi], fi, fold, cfg))
        .collect();
    let mut out = Vec::new();
    for r in per_fold {
        out.extend(r?);
    }
    out.sort_by(|a, b| (a.floor_index, &a.walk).cmp(&(b.floor_index, &b.walk)));
    Ok(out)
}

fn prepare_fold(
    floor: &FloorInput,
    floor_index: usize,
    fold: usize,
    cfg: &EvalConfig,
) -> Result<Vec<PreparedWalk>, EvalError> {
    let walks = &floor.data.walks;
    let ids: Vec<&str> = walks.iter().map(|w| w.walk.meta.id.as_str()).collect();
    let folds = folds_by_name(&ids);
    let training: Vec<&Walk> = walks
        .iter()
        .zip(&folds)
        .filter(|(_, f)| **f != fold)
        .map(|(w, _)| &w.walk)
        .collect();
    let fp_err = |source| EvalError::Fingerprint {
        floor: floor.label.clone(),
        fold,
        source,
    };
    let (mut map, report) =
        build_from_walks(training.iter().copied(), &cfg.radio_map).map_err(fp_err)?;
    tracing::debug!(floor = %floor.label, fold, points = map.len(), aps = map.n_aps(), ?report, "radio map");
    let mut coverage: Arc<Vec<Point2>> = Arc::new(map.points.iter().map(|p| p.position).collect());
    if let Some(prop) = &cfg.propagation {
        let models = fit_ap_models(&map, prop).map_err(fp_err)?;
        let plan = &floor.data.plan;
        let extended = extend_radio_map(&mut map, &models, prop, |p| {
            plan.outline.is_empty() || plan.is_walkable(p)
        })
        .map_err(fp_err)?;
        tracing::info!(floor = %floor.label, fold, ?extended, "radio map extended by path-loss models");
        if cfg.propagation_is_coverage {
            coverage = Arc::new(map.points.iter().map(|p| p.position).collect());
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
    let matcher = KnnMatcher::new(map, cfg.matcher).map_err(fp_err)?;
    // The indexed matcher of `matcher_spec`, and its stationary window (ms).
    let indexed: Option<(Box<dyn Matcher>, i64)> = match &cfg.matcher_spec {
        None => None,
        Some(spec) => {
            use wipdr_fingerprint::cluster_search::{apply_spec, build_matcher};
            let mut c = cfg.clustering.clone();
            let m = &cfg.matcher;
            (c.apc.k, c.apc.weighting, c.apc.metric, c.apc.representation) =
                (m.k, m.weighting, m.metric, m.representation);
            (c.apindex.k, c.apindex.weighting, c.apindex.metric) = (m.k, m.weighting, m.metric);
            c.apindex.representation = m.representation;
            apply_spec(spec, &mut c).map_err(fp_err)?;
            let built = build_matcher(spec, matcher.shared_map().clone(), &c)
                .map_err(fp_err)?
                .ok_or_else(|| {
                    fp_err(wipdr_fingerprint::FingerprintError::InvalidConfig(format!(
                        "matcher_spec {spec:?}: expected apc, apindex or med"
                    )))
                })?;
            Some((built, c.apindex.stationary_after_ms))
        }
    };
    let med = cfg
        .med
        .map(|m| MedMatcher::new(matcher.shared_map().clone(), m))
        .transpose()
        .map_err(fp_err)?;
    let pdr_cfg = if cfg.calibrate_pdr {
        calibrate_pdr(&cfg.pdr, &cfg.calibration, &training)
    } else {
        cfg.pdr
    };
    let tests: Vec<(usize, &Walk)> = walks
        .iter()
        .zip(&folds)
        .enumerate()
        .filter(|(_, (_, f))| **f == fold)
        .map(|(i, (w, _))| (i, &w.walk))
        .collect();
    let timed: Vec<(PreparedWalk, std::time::Duration)> = tests
        .par_iter()
        .map(|&(_, walk)| {
            let steps = steps_of(&pdr_cfg, walk);
            let mut observations = Vec::with_capacity(walk.wifi.len());
            let mut unmatched = 0;
            let mut locate_time = std::time::Duration::ZERO;
            let mut med = med.clone();
            if let Some(m) = med.as_mut() {
                m.reset();
            }
            let mut prev_t = TimestampMs::MIN;
            for scan in &walk.wifi {
                let started = std::time::Instant::now();
                let located = match med.as_mut() {
                    None => match &indexed {
                        None => matcher.locate_scan(scan, &cfg.query),
                        Some((m, still_after)) => {
                            // Causal: only steps detected up to the scan.
                            let motion = wipdr_fingerprint::ap_index::motion_at(
                                &steps,
                                scan.t,
                                *still_after,
                            );
                            m.locate_scan_with_motion(scan, &cfg.query, &motion)
                        }
                    },
                    Some(m) => {
                        // PDR displacement since the previous scan (causal: steps up to now).
                        let moved = steps
                            .iter()
                            .filter(|s| s.t > prev_t && s.t <= scan.t)
                            .map(|s| wipdr_core::angle::step_displacement(s.length, s.heading))
                            .fold(wipdr_core::Vector2::zeros(), |a, b| a + b);
                        Query::from_scan(scan, m.map_ref(), &cfg.query)
                            .and_then(|q| m.locate_next(&q, moved))
                    }
                };
                prev_t = scan.t;
                locate_time += started.elapsed();
                match located {
                    Ok(o) => observations.push(o),
                    Err(e) => {
                        unmatched += 1;
                        tracing::trace!(walk = %walk.meta.id, t = scan.t, error = %e, "scan not matched");
                    }
                }
            }
            let prepared = PreparedWalk {
                floor: floor.label.clone(),
                floor_index,
                walk: walk.meta.id.clone(),
                fold,
                steps,
                observations,
                unmatched_scans: unmatched,
                first_scan_t: walk.wifi.first().map(|s| s.t),
                waypoints: walk.waypoints.clone(),
                coverage: coverage.clone(),
                trails: trails.clone(),
            };
            (prepared, locate_time)
        })
        .collect();
    // Matcher cost of the fold (for `-v` runs: visited fraction and queries per second of
    // matcher time, summed over the fold's walks).
    let scans: usize = timed.iter().map(|(p, _)| p.observations.len()).sum();
    let visited: usize = timed
        .iter()
        .flat_map(|(p, _)| p.observations.iter().map(|o| o.visited))
        .sum();
    let locate_s: f64 = timed.iter().map(|(_, d)| d.as_secs_f64()).sum();
    tracing::info!(
        floor = %floor.label,
        fold,
        map_points = matcher.map().len(),
        scans,
        visited,
        visited_fraction = visited as f64 / (scans.max(1) * matcher.map().len().max(1)) as f64,
        locate_s,
        "fold matcher"
    );
    Ok(timed.into_iter().map(|(p, _)| p).collect())
}

/// Mixes the evaluation seed with a walk id (FNV-1a), so every walk has its own stream.
fn walk_seed(seed: u64, walk: &str) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325 ^ seed;
    for b in walk.bytes() {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// What the schemes may use of a floor plan, built once per floor and shared.
#[derive(Debug, Clone)]
pub struct FloorEnv {
    /// Wall index (wall-aware particle filters).
    pub walls: Arc<WallIndex>,
    /// Walkable-space raster (`pmf`, map matching); `None` when the plan has no outline.
    pub walkable: Option<Arc<WalkableGrid>>,
}

/// Options wrapped around every scheme by [`run_scheme`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RunOptions {
    /// Map-match the estimates ([`MapMatched`]).
    pub map_matching: bool,
    /// Static start ([`StaticStart`]); not applied to the `pdr` baseline, which starts at
    /// the true first waypoint.
    pub static_start: Option<StaticStartConfig>,
}

impl RunOptions {
    /// The options of an evaluation config.
    pub fn of(cfg: &EvalConfig) -> Self {
        Self {
            map_matching: cfg.map_matching,
            static_start: cfg.static_start.clone(),
        }
    }
}

/// Raster cell of [`FloorEnv::walkable`], metres.
pub const WALKABLE_CELL_M: f64 = 0.5;

impl FloorEnv {
    /// Indexes the plan of `floor`.
    pub fn new(floor: &FloorInput) -> Self {
        let plan = &floor.data.plan;
        let walkable = if plan.outline.is_empty() {
            None
        } else {
            match WalkableGrid::new(plan, WALKABLE_CELL_M) {
                Ok(g) => Some(Arc::new(g)),
                Err(e) => {
                    tracing::warn!(floor = %floor.label, error = %e, "no walkable raster");
                    None
                }
            }
        };
        Self {
            walls: Arc::new(WallIndex::new(&plan.walls)),
            walkable,
        }
    }
}

/// Runs one scheme causally over one prepared walk: steps and observations merged in time
/// order (a step before a Wi-Fi fix of the same millisecond), the estimate recorded after
/// every input. `env` is the floor's plan (for wall-aware schemes and map matching); with
/// `map_matching` every estimate is projected onto walkable space ([`MapMatched`]).
pub fn run_scheme(
    scheme: &SchemeConfig,
    walk: &PreparedWalk,
    env: Option<&FloorEnv>,
    options: &RunOptions,
    seed: u64,
) -> Result<Track, EvalError> {
    let is_pdr_baseline = scheme.name() == "pdr";
    let start = if is_pdr_baseline {
        walk.true_start()
    } else {
        None
    };
    let walkable = env.and_then(|e| e.walkable.clone());
    let ctx = BuildContext {
        walls: env.map(|e| e.walls.clone()),
        seed: walk_seed(seed, &walk.walk),
        start: start.map(|w| w.position),
        walkable: walkable.clone(),
        coverage: Some(walk.coverage.clone()),
        trails: walk.trails.clone(),
    };
    let mut fuser = scheme.build(&ctx).map_err(|source| EvalError::Scheme {
        scheme: scheme.name().to_string(),
        source,
    })?;
    if let Some(ss) = options.static_start.as_ref().filter(|_| !is_pdr_baseline) {
        fuser = Box::new(StaticStart::new(fuser, ss.clone()));
    }
    if options.map_matching
        && let Some(grid) = walkable
    {
        fuser = Box::new(MapMatched::new(fuser, grid));
    }
    let mut track: Track = Vec::with_capacity(walk.steps.len() + walk.observations.len() + 1);
    if let (Some(w), Some(e)) = (start, fuser.estimate()) {
        track.push((w.t, e.position));
    }
    let (mut i, mut j) = (0, 0);
    let (steps, obs) = (&walk.steps, &walk.observations);
    while i < steps.len() || j < obs.len() {
        let take_step = j >= obs.len() || (i < steps.len() && steps[i].t <= obs[j].t);
        let t = if take_step {
            fuser.on_step(&steps[i]);
            i += 1;
            steps[i - 1].t
        } else {
            fuser.on_wifi(&obs[j]);
            j += 1;
            obs[j - 1].t
        };
        if let Some(e) = fuser.estimate() {
            track.push((t, e.position));
        }
    }
    Ok(track)
}

/// Runs `schemes` over prepared walks and scores them.
pub fn run_prepared(
    floors: &[FloorInput],
    prepared: &[PreparedWalk],
    cfg: &EvalConfig,
    schemes: &[String],
    on_done: &(dyn Fn() + Sync),
) -> Result<EvalReport, EvalError> {
    let configs: Vec<SchemeConfig> = schemes
        .iter()
        .map(|s| cfg.scheme(s))
        .collect::<Result<_, _>>()?;
    let envs: Vec<FloorEnv> = floors.par_iter().map(FloorEnv::new).collect();
    let options = RunOptions::of(cfg);
    let jobs: Vec<(usize, usize)> = (0..prepared.len())
        .flat_map(|w| (0..configs.len()).map(move |s| (w, s)))
        .collect();
    let results: Vec<Result<WalkResult, EvalError>> = jobs
        .par_iter()
        .map(|&(w, s)| {
            let pw = &prepared[w];
            let track = run_scheme(
                &configs[s],
                pw,
                Some(&envs[pw.floor_index]),
                &options,
                cfg.seed,
            )?;
            let from = if cfg.score_from_first_scan {
                pw.first_scan_t
            } else {
                None
            };
            let score = match cfg.score_first_m {
                None => score_track(&pw.waypoints, &track, from),
                Some(m) => score_track(&first_metres(&pw.waypoints, m), &track, from),
            };
            on_done();
            Ok(WalkResult {
                floor: pw.floor.clone(),
                walk: pw.walk.clone(),
                fold: pw.fold,
                scheme: schemes[s].clone(),
                first_scan_t: pw.first_scan_t,
                score,
            })
        })
        .collect();
    let walks = results.into_iter().collect::<Result<Vec<_>, _>>()?;
    Ok(EvalReport::from_walks(
        schemes.to_vec(),
        floors.iter().map(|f| f.label.clone()).collect(),
        walks,
    ))
}

/// The waypoints within `metres` of path (along the waypoints) from the first one.
pub fn first_metres(waypoints: &[Waypoint], metres: f64) -> Vec<Waypoint> {
    let mut out = Vec::new();
    let mut walked = 0.0;
    for (i, w) in waypoints.iter().enumerate() {
        if i > 0 {
            walked += (w.position - waypoints[i - 1].position).norm();
        }
        if walked > metres {
            break;
        }
        out.push(*w);
    }
    out
}

/// [`prepare`] then [`run_prepared`].
pub fn evaluate(
    floors: &[FloorInput],
    cfg: &EvalConfig,
    schemes: &[String],
    on_done: &(dyn Fn() + Sync),
) -> Result<EvalReport, EvalError> {
    let prepared = prepare(floors, cfg)?;
    run_prepared(floors, &prepared, cfg, schemes, on_done)
}

/// The track of every scheme on one prepared walk (for plots).
pub fn tracks_of(
    floor: &FloorInput,
    walk: &PreparedWalk,
    cfg: &EvalConfig,
    schemes: &[String],
) -> Result<Vec<(String, Track)>, EvalError> {
    let env = FloorEnv::new(floor);
    schemes
        .iter()
        .map(|s| {
            Ok((
                s.clone(),
                run_scheme(
                    &cfg.scheme(s)?,
                    walk,
                    Some(&env),
                    &RunOptions::of(cfg),
                    cfg.seed,
                )?,
            ))
        })
        .collect()
}

/// The true position of a prepared walk at `t` (for plots), from its waypoints.
pub fn truth_at(walk: &PreparedWalk, t: TimestampMs) -> Option<Point2> {
    wipdr_core::walk::interpolate_waypoints(&walk.waypoints, t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn preparation_key_follows_what_prepare_reads() {
        let base = EvalConfig::default();
        let key = base.preparation_key();
        // Run-only settings share the prepared inputs.
        let mut run_only = base.clone();
        run_only.seed = 7;
        run_only.map_matching = true;
        run_only.score_first_m = Some(20.0);
        run_only
            .schemes
            .insert("pmf".into(), SchemeConfig::default_for("pmf").unwrap());
        assert_eq!(run_only.preparation_key(), key);
        // Anything else changes them, including fields added after the key was written.
        let mut propagation = base.clone();
        propagation.propagation = Some(PropagationConfig::default());
        assert_ne!(propagation.preparation_key(), key);
        let mut map = base.clone();
        map.radio_map.max_entry_age_ms = Some(12_345);
        assert_ne!(map.preparation_key(), key);
        let mut coverage = propagation.clone();
        coverage.propagation_is_coverage = true;
        assert_ne!(coverage.preparation_key(), propagation.preparation_key());
    }
}

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

use crate::coverage::attach_coverage;
use crate::fold_model::FoldModel;
use crate::fold_rules::FOLDS;
use crate::report::{EvalReport, SkippedRun, WalkMotion, WalkResult, WalkScanLikelihood};
use crate::scoring::{Track, TrackPoint, score_track_with_floors};
use rayon::prelude::*;
use wipdr_core::walk::interpolate_waypoints;
use wipdr_core::{Point2, StepEvent, TimestampMs, Walk, Waypoint};
use wipdr_fusion::SchemeConfig;
use wipdr_pdr::{CheckedPdrConfig, Pdr, odometry};
use wipdr_positioning::replay::replay_scheme;
use wipdr_positioning::site_model::{SiteModel, SiteModelError, StreamSpec};
use wipdr_positioning::smooth::smooth_fusion;
use wipdr_positioning::{PositionEstimate, Site, samples_of, stream_seed, track_of};

#[doc(no_inline)]
pub use crate::config::EvalConfig;
#[doc(no_inline)]
pub use crate::error::EvalError;
#[doc(no_inline)]
pub use crate::fold_model::PreparedWalk;
#[doc(no_inline)]
pub use crate::input::FloorInput;

pub use wipdr_positioning::site_model::{TRAIL_CELL_M, TRAIL_MAX_DISTANCE_M};

/// Steps of `walk` under `cfg`.
pub fn steps_of(cfg: &CheckedPdrConfig, walk: &Walk) -> Vec<StepEvent> {
    Pdr::run(*cfg, walk)
}

pub use wipdr_positioning::site_model::calibrate_pdr;

/// A floor needs a walk per fold (route folds: at least two routes).
fn check_enough_walks(f: &FloorInput) -> Result<(), EvalError> {
    let n = f.data.walks.len();
    let by_route = f.data.walks.iter().all(|w| w.meta.route.is_some()) && n > 0;
    if by_route {
        let routes = crate::fold_model::fold_count(f);
        if routes < 2 {
            return Err(EvalError::TooFewRoutes {
                floor: f.label.clone(),
                routes,
            });
        }
    } else if n < FOLDS {
        return Err(EvalError::TooFewWalks {
            floor: f.label.clone(),
            walks: n,
            folds: FOLDS,
        });
    }
    Ok(())
}

/// Turns every walk of `floors` into scheme inputs under the protocol folds.
pub fn prepare(floors: &[FloorInput], cfg: &EvalConfig) -> Result<Vec<PreparedWalk>, EvalError> {
    prepare_items(floors, cfg, &work_items(floors)?)
}

/// The work items of an evaluation: `(floor index, fold)` for every fold of every floor,
/// floor by floor, folds in order (checking each floor has enough walks for its folds).
/// A work item is one fold's model (radio map and calibration from the floor's other folds)
/// and its test walks; [`crate::shard`] spreads them over machines.
pub fn work_items(floors: &[FloorInput]) -> Result<Vec<(usize, usize)>, EvalError> {
    let mut items = Vec::new();
    for (fi, f) in floors.iter().enumerate() {
        check_enough_walks(f)?;
        items.extend((0..crate::fold_model::fold_count(f)).map(|fold| (fi, fold)));
    }
    Ok(items)
}

/// [`prepare`] of the work items `jobs` only (from [`work_items`]): each fold still learns
/// from all of its floor's other folds, so the result is the matching part of [`prepare`]'s,
/// in the same order.
pub fn prepare_items(
    floors: &[FloorInput],
    cfg: &EvalConfig,
    jobs: &[(usize, usize)],
) -> Result<Vec<PreparedWalk>, EvalError> {
    // The plan's indexes (walls, walkable raster) are built once per floor and shared by
    // its folds' site models.
    let mut needed: Vec<usize> = jobs.iter().map(|&(fi, _)| fi).collect();
    needed.sort_unstable();
    needed.dedup();
    let plan_sites: std::collections::BTreeMap<usize, Site> = needed
        .par_iter()
        .map(|&fi| (fi, FloorEnv::new(&floors[fi]).site))
        .collect();
    let per_fold: Vec<Result<Vec<PreparedWalk>, EvalError>> = jobs
        .par_iter()
        .map(|&(fi, fold)| prepare_fold(&floors[fi], fi, fold, cfg, plan_sites.get(&fi).cloned()))
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
    plan_site: Option<Site>,
) -> Result<Vec<PreparedWalk>, EvalError> {
    let model = FoldModel::build_sharing_plan(floor, fold, cfg, plan_site)?;
    let prepared: Vec<PreparedWalk> = model
        .test_walks
        .par_iter()
        .map(|&i| model.prepare_walk(floor, floor_index, &floor.data.walks[i], cfg))
        .collect::<Result<_, _>>()?;
    // Matcher cost of the fold (for `-v` runs: visited fraction, summed over the fold's walks).
    let scans: usize = prepared.iter().map(|p| p.observations.len()).sum();
    let visited: usize = prepared
        .iter()
        .flat_map(|p| p.observations.iter().map(|o| o.visited))
        .sum();
    let map_points = model.model.radio_map().len();
    tracing::info!(
        floor = %floor.label,
        fold,
        map_points,
        scans,
        visited,
        visited_fraction = visited as f64 / (scans.max(1) * map_points.max(1)) as f64,
        "fold matcher"
    );
    Ok(prepared)
}

/// What the schemes may use of a floor plan, built once per floor and shared: the
/// positioning [`Site`] without a fold's coverage.
#[derive(Debug, Clone)]
pub struct FloorEnv {
    /// Walls and walkable raster of the floor's plan.
    pub site: Site,
}

impl FloorEnv {
    /// Indexes the plan of `floor`.
    pub fn new(floor: &FloorInput) -> Self {
        Self {
            site: Site::from_plan(Some(&floor.data.plan)),
        }
    }
}

/// Runs one scheme causally over one prepared walk: its recorded steps and fixes replayed
/// through the scheme's fusion ([`replay_scheme`], what a
/// [`Positioner`](wipdr_positioning::Positioner) with the scheme gives; merged by the one
/// replay driver [`wipdr_fusion::replay`]: a step before a fix of the same millisecond), the
/// estimate recorded after every input. `env` is the floor's plan (walls, walkable space);
/// `cfg` gives the wrappers (map matching, static start) and the seed (mixed with the walk's
/// id). The `pdr` baseline starts at the true first waypoint (the protocol's one use of
/// truth, labelled so) and its track begins there: steps and fixes before that time are not
/// fed (IPIN logfiles hold a minute of handling before the walk).
pub fn run_scheme(
    scheme: &SchemeConfig,
    walk: &PreparedWalk,
    env: Option<&FloorEnv>,
    cfg: &EvalConfig,
) -> Result<Track, EvalError> {
    let start = if scheme.name() == "pdr" {
        walk.true_start()
    } else {
        None
    };
    let mut site = env.map(|e| e.site.clone()).unwrap_or_default();
    site.coverage = Some(walk.coverage.clone());
    site.trails = walk.trails.clone();
    let positioner = cfg.positioner_for(scheme.clone(), cfg.positioner.pdr);
    if cfg.offline && start.is_none() {
        let smoothed = smooth_fusion(
            &site,
            scheme,
            &positioner,
            stream_seed(cfg.positioner.seed, &walk.walk),
            &walk.steps,
            &walk.observations,
        )
        .map_err(|source| EvalError::Positioning {
            floor: walk.floor.clone(),
            source,
        })?;
        return Ok(smoothed.iter().map(TrackPoint::from).collect());
    }
    let track = replay_scheme(
        &site,
        scheme,
        &positioner,
        stream_seed(cfg.positioner.seed, &walk.walk),
        start.map(|w| (w.t, w.position)),
        &walk.steps,
        &walk.observations,
    )
    .map_err(|source| EvalError::Positioning {
        floor: walk.floor.clone(),
        source,
    })?;
    Ok(track.iter().map(TrackPoint::from).collect())
}

/// The track `wipdr locate` writes for walk `walk_id` of `floor`: the walk's raw samples
/// streamed one by one through a full [`Positioner`](wipdr_positioning::Positioner) built from the walk's fold (radio map
/// and calibration from the other folds' walks, as the protocol does). One row per estimate
/// (after each step or fix; for `pdr`, first the true start). Its score at the waypoints
/// equals what [`evaluate`] reports for that walk and scheme. With `cfg.offline` the
/// track is [`Positioner::smooth`](wipdr_positioning::Positioner::smooth) after the whole walk (what `eval --offline` scores).
pub fn locate(
    floor: &FloorInput,
    walk_id: &str,
    scheme: &str,
    cfg: &EvalConfig,
) -> Result<Vec<PositionEstimate>, EvalError> {
    locate_with(floor, walk_id, scheme, cfg, Training::ProtocolFold)
}

/// Which walks give a located walk its radio map and calibration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Training {
    /// The other folds' walks (the evaluation protocol: [`locate`] equals [`evaluate`]).
    ProtocolFold,
    /// Every other walk of the floor (a logfile located with all others, as a competitor
    /// would).
    AllOthers,
}

/// [`locate`] with a choice of training walks.
pub fn locate_with(
    floor: &FloorInput,
    walk_id: &str,
    scheme: &str,
    cfg: &EvalConfig,
    training: Training,
) -> Result<Vec<PositionEstimate>, EvalError> {
    let walks = &floor.data.walks;
    let index = walks
        .iter()
        .position(|w| w.meta.id == walk_id)
        .ok_or_else(|| EvalError::UnknownWalk {
            floor: floor.label.clone(),
            walk: walk_id.to_string(),
        })?;
    let model = match training {
        Training::ProtocolFold => {
            check_enough_walks(floor)?;
            FoldModel::build(floor, crate::fold_model::folds_of(floor)[index], cfg)?
        }
        Training::AllOthers => FoldModel::build_all_but(floor, index, cfg)?,
    };
    locate_on_model(floor, &model, index, scheme, cfg)
}

/// The track of walk `index` of `floor` streamed through a whole [`Positioner`](wipdr_positioning::Positioner) built on
/// `model` (what [`locate_with`] does once it has learned the model; the Python package's
/// `wipdr.locate` learns its model from the walks it is given). For `pdr`, the track starts
/// at the walk's true first waypoint.
pub fn locate_on_model(
    floor: &FloorInput,
    model: &FoldModel,
    index: usize,
    scheme: &str,
    cfg: &EvalConfig,
) -> Result<Vec<PositionEstimate>, EvalError> {
    let walk = floor
        .data
        .walks
        .get(index)
        .ok_or_else(|| EvalError::UnknownWalk {
            floor: floor.label.clone(),
            walk: format!("#{index}"),
        })?;
    locate_walk(&model.model, walk, scheme, cfg.offline).map_err(|e| EvalError::Site {
        floor: floor.label.clone(),
        reason: e.to_string(),
    })
}

/// The track of `walk` streamed sample by sample through a [`Positioner`](wipdr_positioning::Positioner) on a site
/// model, as `wipdr locate --model` writes it: one estimate after each step or fix, the
/// stream seeded by the walk's id and using the model's barometric references where the walk
/// names its phone model and start time. For `pdr` (dead reckoning alone, which needs a known
/// start) the track starts at the walk's true first waypoint, the protocol's one use of truth;
/// a walk without waypoints cannot run `pdr`. With `offline`, the whole stream re-estimated
/// after its end ([`Positioner::smooth`](wipdr_positioning::Positioner::smooth); `pdr` stays causal).
pub fn locate_walk(
    model: &SiteModel,
    walk: &Walk,
    scheme: &str,
    offline: bool,
) -> Result<Vec<PositionEstimate>, SiteModelError> {
    let scheme_cfg = model.scheme(scheme)?;
    let start = if scheme_cfg.name() == "pdr" {
        let Some(w) = walk.waypoints.first() else {
            return Err(SiteModelError::Positioning(
                wipdr_positioning::PositioningError::InvalidConfig(wipdr_core::ConfigError::new(
                    "scheme",
                    format!(
                        "{scheme} is dead reckoning from a known start (the walk's first waypoint), and walk {} has no waypoints",
                        walk.meta.id
                    ),
                )),
            ));
        };
        Some((w.t, w.position))
    } else {
        None
    };
    let mut positioner = model.positioner(
        scheme,
        &StreamSpec {
            id: Some(walk.meta.id.clone()),
            identity: crate::fold_model::identity_of(walk),
            start: start.map(|(_, p)| p),
        },
    )?;
    let track = track_of(&mut positioner, samples_of(walk), start);
    if !offline || start.is_some() {
        return Ok(track);
    }
    // Offline: the whole stream re-estimated (the `pdr` baseline from the truth stays causal).
    Ok(positioner.smooth()?)
}

/// Runs `schemes` over prepared walks and scores them.
pub fn run_prepared(
    floors: &[FloorInput],
    prepared: &[PreparedWalk],
    cfg: &EvalConfig,
    schemes: &[String],
    on_done: &(dyn Fn() + Sync),
) -> Result<EvalReport, EvalError> {
    run_prepared_observed(floors, prepared, cfg, schemes, on_done, &|_, _, _| {})
}

/// [`run_prepared`], handing each track to `on_track(index into prepared, index into
/// schemes, track)` as it is made (the report page keeps a downsampled copy to draw).
pub fn run_prepared_observed(
    floors: &[FloorInput],
    prepared: &[PreparedWalk],
    cfg: &EvalConfig,
    schemes: &[String],
    on_done: &(dyn Fn() + Sync),
    on_track: &(dyn Fn(usize, usize, &Track) + Sync),
) -> Result<EvalReport, EvalError> {
    let configs: Vec<SchemeConfig> = schemes
        .iter()
        .map(|s| cfg.scheme(s))
        .collect::<Result<_, _>>()?;
    let envs: Vec<FloorEnv> = floors.par_iter().map(FloorEnv::new).collect();
    // A walk lacking a stream a scheme needs is not run for it, but counted.
    let mut skipped_runs = Vec::new();
    let mut jobs: Vec<(usize, usize)> = Vec::with_capacity(prepared.len() * configs.len());
    for (w, pw) in prepared.iter().enumerate() {
        for (s, scheme) in configs.iter().enumerate() {
            match crate::streams::blocking_stream(scheme, &pw.missing_streams) {
                None => jobs.push((w, s)),
                Some(missing) => {
                    tracing::warn!(floor = %pw.floor, walk = %pw.walk, scheme = %schemes[s], missing = missing.label(), "walk not run for the scheme");
                    on_done();
                    skipped_runs.push(SkippedRun {
                        floor: pw.floor.clone(),
                        walk: pw.walk.clone(),
                        fold: pw.fold,
                        scheme: schemes[s].clone(),
                        missing,
                    });
                }
            }
        }
    }
    let results: Vec<Result<WalkResult, EvalError>> = jobs
        .par_iter()
        .map(|&(w, s)| {
            let pw = &prepared[w];
            let track = run_scheme(&configs[s], pw, Some(&envs[pw.floor_index]), cfg)?;
            on_track(w, s, &track);
            let from = if cfg.score_from_first_scan {
                pw.first_scan_t
            } else {
                None
            };
            let mut score = match cfg.score_first_m {
                None => score_track_with_floors(&pw.waypoints, &track, &pw.floors, from),
                Some(m) => score_track_with_floors(
                    &first_metres(&pw.waypoints, m),
                    &track,
                    &pw.floors,
                    from,
                ),
            };
            // `first_metres` keeps a prefix of the waypoints, so the alignment holds.
            attach_coverage(&mut score, &pw.waypoints, &pw.waypoint_coverage_m);
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
    let input_skips = floors
        .iter()
        .map(|f| (f.label.clone(), f.input_skips.clone()))
        .collect();
    let motion = prepared
        .iter()
        .map(|pw| {
            let segments = segment_errors(
                &pw.steps,
                &pw.waypoints,
                pw.first_scan_t.filter(|_| cfg.score_from_first_scan),
            );
            WalkMotion {
                floor: pw.floor.clone(),
                walk: pw.walk.clone(),
                fold: pw.fold,
                segments: segments.iter().map(|s| (s.length_m, s.error_m)).collect(),
                inside_95: segments.iter().map(|s| s.inside_95).collect(),
            }
        })
        .collect();
    Ok(EvalReport::from_walks(
        schemes.to_vec(),
        floors.iter().map(|f| f.label.clone()).collect(),
        walks,
    )
    .with_skips(skipped_runs, input_skips)
    .with_motion(motion)
    .with_scan_likelihood(scan_likelihood(prepared, cfg)))
}

/// Where the truth falls in each scored scan's likelihood, per prepared walk whose fixes
/// carry one: the scans from the scoring start on, the truth the waypoints interpolated at
/// the scan's time (scans outside the waypoints' span are left out).
fn scan_likelihood(prepared: &[PreparedWalk], cfg: &EvalConfig) -> Vec<WalkScanLikelihood> {
    prepared
        .iter()
        .filter_map(|pw| {
            let from = pw.first_scan_t.filter(|_| cfg.score_from_first_scan);
            let scans: Vec<(usize, bool)> = pw
                .observations
                .iter()
                .filter(|o| from.is_none_or(|t| o.t >= t))
                .filter_map(|o| {
                    let l = o.likelihood.as_ref()?;
                    let truth = interpolate_waypoints(&pw.waypoints, o.t)?;
                    Some(l.rank_and_region(truth, 0.95))
                })
                .collect();
            (!scans.is_empty()).then(|| WalkScanLikelihood {
                floor: pw.floor.clone(),
                walk: pw.walk.clone(),
                fold: pw.fold,
                scans,
            })
        })
        .collect()
}

/// One segment between consecutive waypoints, as [`segment_errors`] scores it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SegmentError {
    /// The true displacement's length, m.
    pub length_m: f64,
    /// The length of the motion events' summed displacement minus the true one, m.
    pub error_m: f64,
    /// Whether the true displacement lies inside the 95 % ellipse of the events' summed
    /// covariance (independent events: their covariances add); `None` when an event of the
    /// segment has no covariance (detected steps) or the sum is not positive definite. A
    /// segment without events has a zero sum: `None`.
    pub inside_95: Option<bool>,
}

/// The motion source's error between consecutive waypoints: for each pair `(a, b)` with
/// `a` at or after `from` (the scoring start), the motion events with `t_a < t <= t_b`
/// summed (length x heading each: steps or learned displacements, the same sum for both)
/// against `p_b - p_a`, and their summed covariance's 95 % ellipse tested where every event
/// has one. Pairs on different floors are left out.
pub fn segment_errors(
    events: &[StepEvent],
    waypoints: &[Waypoint],
    from: Option<TimestampMs>,
) -> Vec<SegmentError> {
    let mut out = Vec::with_capacity(waypoints.len().saturating_sub(1));
    let mut k = 0usize;
    for pair in waypoints.windows(2) {
        let (a, b) = (&pair[0], &pair[1]);
        while k < events.len() && events[k].t <= a.t {
            k += 1;
        }
        if from.is_some_and(|f| a.t < f) || a.floor != b.floor || b.t < a.t {
            continue;
        }
        let mut d = wipdr_core::Vector2::zeros();
        // The events' covariances `(xx, xy, yy)` summed; `None` once one has none.
        let mut covariance = Some([0.0f64; 3]);
        let mut j = k;
        while j < events.len() && events[j].t <= b.t {
            d += wipdr_core::angle::step_displacement(events[j].length, events[j].heading);
            covariance = covariance
                .zip(events[j].displacement_covariance())
                .map(|(s, c)| [s[0] + c[(0, 0)], s[1] + c[(0, 1)], s[2] + c[(1, 1)]]);
            j += 1;
        }
        let truth = b.position - a.position;
        let residual = d - truth;
        let inside_95 = covariance
            .filter(|_| j > k)
            .and_then(|c| odometry::mahalanobis2([residual.x, residual.y], c))
            .filter(|m2| m2.is_finite())
            .map(|m2| m2 <= odometry::CHI2_2_95);
        out.push(SegmentError {
            length_m: truth.norm(),
            error_m: residual.norm(),
            inside_95,
        });
    }
    out
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
                run_scheme(&cfg.scheme(s)?, walk, Some(&env), cfg)?,
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

    use wipdr_fusion::synthetic::step as event;

    fn waypoint(t: TimestampMs, x: f64, y: f64) -> Waypoint {
        Waypoint {
            t,
            position: Point2::new(x, y),
            floor: None,
        }
    }

    /// Each segment sums the events in `(t_a, t_b]`; segments before the scoring start are
    /// left out.
    #[test]
    fn segment_errors_sum_the_events_inside_each_segment() {
        let north = 0.0;
        let east = std::f64::consts::FRAC_PI_2;
        let events = [
            event(1000, 1.0, north), // at the first waypoint: not in (1000, 3000]
            event(2000, 2.0, north),
            event(3000, 1.0, north), // at the second waypoint: in the first segment
            event(4000, 3.0, east),
        ];
        let waypoints = [
            waypoint(1000, 0.0, 0.0),
            waypoint(3000, 0.0, 3.0),
            waypoint(5000, 4.0, 3.0),
        ];
        let got = segment_errors(&events, &waypoints, None);
        assert_eq!(got.len(), 2);
        assert!(
            (got[0].length_m - 3.0).abs() < 1e-12 && got[0].error_m.abs() < 1e-12,
            "{got:?}"
        );
        assert!((got[1].length_m - 4.0).abs() < 1e-12 && (got[1].error_m - 1.0).abs() < 1e-12);
        // Detected steps carry no covariance: no ellipse test.
        assert!(got.iter().all(|s| s.inside_95.is_none()));
        let later = segment_errors(&events, &waypoints, Some(2000));
        assert_eq!(later.len(), 1);
        assert_eq!(later[0], got[1]);
        let pairs: Vec<(f64, f64)> = got.iter().map(|s| (s.length_m, s.error_m)).collect();
        let summary = crate::report::MotionSummary::of(&pairs);
        assert_eq!(summary.segments, 2);
        assert!(
            (summary.mean_m - 0.5).abs() < 1e-12 && (summary.mean_length_m - 3.5).abs() < 1e-12
        );
        assert_eq!(summary.inside_95, None);
    }

    /// Events with a covariance (learned odometry): the segment's covariances add, and the
    /// truth is inside the 95 % ellipse when its Mahalanobis distance is at most
    /// sqrt(5.99) = 2.45 standard deviations.
    #[test]
    fn segments_of_events_with_a_covariance_test_the_95_ellipse() {
        let north = 0.0;
        let with = |t, length, var: f64| StepEvent {
            covariance: Some([var, 0.0, var]),
            ..event(t, length, north)
        };
        // Two events of variance 0.5 m² each: a sum of 1 m², sd 1 m a axis.
        let events = [
            with(2000, 1.0, 0.5),
            with(3000, 1.0, 0.5),
            with(4000, 1.0, 0.5),
        ];
        let waypoints = [
            waypoint(1000, 0.0, 0.0),
            waypoint(3000, 0.0, 4.0), // summed 2 m north: 2 sd off, inside
            waypoint(5000, 0.0, 8.0), // summed 1 m north: 3 sd off, outside
        ];
        let got = segment_errors(&events, &waypoints, None);
        assert_eq!(
            got.iter().map(|s| s.inside_95).collect::<Vec<_>>(),
            [Some(true), Some(false)]
        );
        let pairs: Vec<(f64, f64)> = got.iter().map(|s| (s.length_m, s.error_m)).collect();
        let summary = crate::report::MotionSummary::with_ellipses(
            pairs.iter().zip(got.iter().map(|s| s.inside_95)),
        );
        assert_eq!(summary.inside_95, Some(0.5));
        // One event without a covariance in the segment: no test for it.
        let mixed = [with(2000, 1.0, 0.5), event(3000, 1.0, north)];
        let got = segment_errors(&mixed, &waypoints[..2], None);
        assert_eq!(got[0].inside_95, None);
    }
}

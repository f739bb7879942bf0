//! # wipdr-sim — synthetic floors and walks with known truth
//!
//! The real walks (`ilc20/` under the data root, `wipdr_io::data_root()`) have waypoints
//! only every several metres and no truth for steps, turns or Wi-Fi gross errors. This crate builds a synthetic mall floor and
//! walks on it whose every step, turn, stop and injected Wi-Fi gross error is known, from a
//! seed, reproducibly: for the PDR acceptance (step count, step length, turn detection of
//! papers 000 §2.2, 001 §3.2 eq. 17-18, 002 §4.2, 004 §4.1), for the robust-fusion acceptance
//! (gross errors at known times, paper 000 §4.2), for tests of every crate, and for the demo
//! fixtures (`fixtures/sim`).
//!
//! ## The models
//!
//! - **Floor** ([`floor`]): a 120 x 80 m mall: rows of shops (units with walls), a 3 x 3 grid of
//!   5 m corridors and an open hall; walks follow a corridor graph, with rounded corners.
//! - **Radio** ([`radio`]): access points in corridors and shops (2.4 GHz, some also 5 GHz);
//!   log-distance path loss `P0 - 10 n log10(d/d0)`, a loss per crossed wall, spatially
//!   consistent log-normal shadowing, fading and multipath outliers, whole-dBm readings.
//! - **Scans** ([`scan`]): a scan every ~2 s (jittered) reporting the OS cache: entries carry
//!   last-seen times seconds old (median 3-4 s as in the real data), weak access points are
//!   missed below a -95 dBm floor, optional gross-error scans generated far away.
//! - **Walker** ([`walker`]): cadence 1.6-2.0 Hz, step length 0.6-0.8 m (`scale (a + b f)`),
//!   slow and fast legs, a standing start half of the time (paper 001 §3.2), stops at
//!   junctions; an inverted-pendulum bounce per step (paper 004 eq. 6).
//! - **IMU** ([`imu`]): 50 Hz with timestamp jitter and dropped samples; a phone held flat in
//!   front: accelerometer with step-synchronous vertical acceleration and gravity on the
//!   phone's axes, gyroscope with turn rates, bias and noise, magnetometer with local
//!   disturbances near walls, rotation vector (phone to East-North-Up) with drifting yaw.
//! - **Truth** ([`truth`]): every step (time, length, heading), turn (start, end, angle), stop,
//!   the trajectory, and the injected gross errors.
//! - **Survey** ([`survey`]): a radio map on a grid along the corridors and in the hall, and
//!   held-out queries, in the fingerprint-benchmark CSV layout.
//!
//! Heading convention: clockwise from `+y` (`docs/algorithms.md`). Every parameter is
//! a field of [`SimConfig`] (serde, `Default`). Random draws come from ChaCha8 streams of one
//! seed: the access points, the magnetic disturbances, the survey and each walk's motion, IMU,
//! Wi-Fi and waypoints have their own stream, so walk `i` is the same whatever the number of
//! walks, and changing one model (say the IMU noise) leaves the other streams' output alone.
//! [`write`](mod@write) writes a floor folder in the ILC layout that the real readers read, byte-identical
//! for the same seed and configuration (`wipdr simulate`; the committed set is
//! `fixtures/sim/F1`, see `fixtures/README.md`). Tests of other crates can skip the files:
//! [`generate`] returns everything in memory, and [`SimWorld::walk`] makes one walk at a time.
//!
//! ```
//! use wipdr_sim::{SimConfig, generate};
//! let mut cfg = SimConfig::default();
//! cfg.walks = 1;
//! cfg.duration_s = 30.0;
//! cfg.duration_jitter_s = 0.0;
//! cfg.survey.test_points = 5;
//! let sim = generate(&cfg, 42).unwrap();
//! let (walk, truth) = (&sim.walks[0].walk, &sim.walks[0].truth);
//! assert!(walk.imu.accelerometer.len() > 1400); // ~50 Hz for 30 s
//! assert!(!walk.wifi.is_empty());
//! // The truth's steps explain the distance walked.
//! let walked: f64 = truth.steps.iter().map(|s| s.arc_length).sum();
//! assert!((walked - truth.distance_m).abs() < 1e-6);
//! // The same seed gives the same walk.
//! assert_eq!(generate(&cfg, 42).unwrap().walks[0].walk, *walk);
//! ```

pub mod config;
pub mod floor;
pub mod imu;
pub mod radio;
mod rng;
pub mod scan;
pub mod survey;
pub mod truth;
pub mod walker;
pub mod write;

pub use config::SimConfig;
pub use floor::SimFloorPlan;
pub use survey::{SurveyMap, SurveyPoint};
pub use truth::WalkTruth;

use imu::{ImuScene, MagDisturbance, PhonePose};
use radio::RadioModel;
use rng::Draw;
use scan::Scanner;
use std::path::PathBuf;
use thiserror::Error;
use truth::{GrossErrorTruth, StepTruth, StopTruth, TrajectorySample, TurnTruth, round_to};
use walker::{Motion, Timeline, WalkPath, WalkerParams};
use wipdr_core::{CoreError, Point2, TimestampMs, Walk, WalkMeta, Waypoint, angle};

/// Errors of the simulator.
#[derive(Debug, Error)]
pub enum SimError {
    /// A configuration value is out of range (the dotted path of the field and why).
    #[error("simulator config {0}")]
    InvalidConfig(#[from] wipdr_core::ConfigError),
    /// Building a core value failed.
    #[error(transparent)]
    Core(#[from] CoreError),
    /// Writing output failed.
    #[error("writing {path}: {source}")]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A wipdr-io writer failed.
    #[error(transparent)]
    Writer(#[from] wipdr_io::IoError),
    /// The fingerprint CSV writer failed.
    #[error(transparent)]
    Csv(#[from] wipdr_io::fingerprint_csv::FingerprintCsvError),
    /// A truth file could not be parsed.
    #[error("parsing {path}: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// The cause.
        message: String,
    },
    /// Serialising output failed.
    #[error("serialising {path}: {message}")]
    Serialise {
        /// The file.
        path: PathBuf,
        /// The cause.
        message: String,
    },
}

/// One synthetic walk and its truth.
#[derive(Debug, Clone, PartialEq)]
pub struct SimWalk {
    /// The walk, as a reader would return it (streams time-sorted).
    pub walk: Walk,
    /// What really happened.
    pub truth: WalkTruth,
}

/// The floor and its radio environment: everything walks are generated on.
#[derive(Debug, Clone, PartialEq)]
pub struct SimWorld {
    /// The configuration.
    pub config: SimConfig,
    /// The seed.
    pub seed: u64,
    /// The floor plan and corridor graph.
    pub floor: SimFloorPlan,
    /// Access points and propagation model.
    pub radio: RadioModel,
    /// Local magnetic disturbances.
    pub disturbances: Vec<MagDisturbance>,
}

/// A generated floor: world, walks and survey radio map.
#[derive(Debug, Clone, PartialEq)]
pub struct SimFloor {
    /// The world the walks were generated on.
    pub world: SimWorld,
    /// The walks, in id order.
    pub walks: Vec<SimWalk>,
    /// The survey radio map.
    pub survey: SurveyMap,
}

/// Generates a whole floor: the world, `cfg.walks` walks and the survey radio map.
pub fn generate(cfg: &SimConfig, seed: u64) -> Result<SimFloor, SimError> {
    let world = SimWorld::build(cfg, seed)?;
    let walks = (0..cfg.walks).map(|i| world.walk(i)).collect();
    let survey = world.survey();
    Ok(SimFloor {
        world,
        walks,
        survey,
    })
}

impl SimWorld {
    /// Builds the floor, access points and magnetic disturbances.
    pub fn build(cfg: &SimConfig, seed: u64) -> Result<Self, SimError> {
        cfg.validate()?;
        let floor = SimFloorPlan::build(&cfg.floor)?;
        let mut rng = rng::stream(seed, rng::STREAM_WORLD);
        let radio = RadioModel::build(&cfg.radio, &floor, &mut rng);
        let mut rng = rng::stream(seed, rng::STREAM_MAGNETIC);
        let disturbances = imu::mag_disturbances(&cfg.imu, &floor, &mut rng);
        Ok(Self {
            config: cfg.clone(),
            seed,
            floor,
            radio,
            disturbances,
        })
    }

    /// The id of walk `index` (sorting ids sorts walks by index).
    pub fn walk_id(&self, index: usize) -> String {
        format!("sim_{}_w{index:04}", self.config.floor_name)
    }

    /// The survey radio map (its own random stream).
    pub fn survey(&self) -> SurveyMap {
        let mut rng = rng::stream(self.seed, rng::STREAM_SURVEY);
        SurveyMap::survey(
            &self.config.survey,
            &self.config.scan,
            &self.radio,
            &self.floor,
            &mut rng,
        )
    }

    /// Generates walk `index` (its own random stream: independent of the other walks).
    pub fn walk(&self, index: usize) -> SimWalk {
        let cfg = &self.config;
        let mut rng = rng::walk_stream(self.seed, index, rng::WALK_MOTION);
        let duration_s =
            cfg.duration_s + rng.uniform(-cfg.duration_jitter_s, cfg.duration_jitter_s);
        let w = &cfg.walker;
        let params = WalkerParams {
            step_frequency_hz: rng.uniform(w.step_frequency_min_hz, w.step_frequency_max_hz),
            step_length_scale: rng.uniform(w.step_length_scale[0], w.step_length_scale[1]),
            leg_length_m: rng.uniform(w.leg_length_min_m, w.leg_length_max_m),
        };
        let route = walker::random_route(
            &self.floor,
            &cfg.floor,
            w,
            duration_s * 2.5 + 20.0,
            &mut rng,
        );
        let path = WalkPath::through(&route, cfg.floor.corner_cut_m);
        let timeline = Timeline::generate(&path, w, &params, duration_s, &mut rng);
        let pose = PhonePose::draw(&cfg.imu, &mut rng);
        let start_ms =
            cfg.start_time_ms + (index as f64 * cfg.walk_spacing_s * 1000.0).round() as TimestampMs;
        let to_ms = |t: f64| start_ms + (t * 1000.0).round() as TimestampMs;
        let end_ms = to_ms(duration_s);

        let scene = ImuScene {
            cfg: &cfg.imu,
            path: &path,
            timeline: &timeline,
            pose,
            disturbances: &self.disturbances,
            start_ms,
        };
        let imu = scene.synthesise(&mut rng::walk_stream(self.seed, index, rng::WALK_IMU));

        let position = |t: f64| path.at(timeline.at(t).s).0;
        let scanner = Scanner {
            cfg: &cfg.scan,
            radio: &self.radio,
            floor: &self.floor,
            start_ms,
            duration_s,
            gross_error_rate: cfg.gross_error_rate,
        };
        let (wifi, injected) = scanner.run(
            &position,
            &mut rng::walk_stream(self.seed, index, rng::WALK_WIFI),
        );

        // Truth: steps, turns, stops, trajectory.
        let steps: Vec<StepTruth> = timeline
            .steps()
            .filter_map(|m| match *m {
                Motion::Step { t0, t1, s0, s1, .. } => {
                    let d = path.at(s1).0 - path.at(s0).0;
                    Some(StepTruth {
                        t: to_ms(t1),
                        length: round_to(d.norm(), 1e6),
                        heading: round_to(angle::heading_of(d), 1e6),
                        arc_length: s1 - s0,
                        period_s: round_to(t1 - t0, 1e6),
                    })
                }
                Motion::Stand { .. } => None,
            })
            .collect();
        let s_end = timeline.at(duration_s).s;
        let min_turn = w.min_turn_deg.to_radians();
        let turns: Vec<TurnTruth> = path
            .corners
            .iter()
            .filter(|c| c.angle.abs() >= min_turn && c.s_end <= s_end)
            .map(|c| TurnTruth {
                t_start: to_ms(timeline.time_at_arc(c.s_start)),
                t_end: to_ms(timeline.time_at_arc(c.s_end)),
                angle: round_to(c.angle, 1e6),
            })
            .collect();
        let stops: Vec<StopTruth> = timeline
            .motions
            .iter()
            .filter_map(|m| match *m {
                Motion::Stand { t0, t1, .. } => Some(StopTruth {
                    t_start: to_ms(t0),
                    t_end: to_ms(t1),
                }),
                Motion::Step { .. } => None,
            })
            .collect();
        let n_traj = (duration_s * cfg.trajectory_rate_hz).floor() as usize;
        let trajectory: Vec<TrajectorySample> = (0..=n_traj)
            .map(|k| (k as f64 / cfg.trajectory_rate_hz).min(duration_s))
            .chain(std::iter::once(duration_s))
            .map(|t| {
                let (p, psi) = path.at(timeline.at(t).s);
                TrajectorySample {
                    t: to_ms(t),
                    x: round_to(p.x, 1e4),
                    y: round_to(p.y, 1e4),
                    heading: round_to(angle::wrap_pi(psi), 1e4),
                }
            })
            .fold(Vec::new(), |mut v: Vec<TrajectorySample>, s| {
                if v.last().is_none_or(|l| l.t < s.t) {
                    v.push(s);
                }
                v
            });
        let gross_errors = injected
            .iter()
            .map(|g| {
                let tp = position((g.t - start_ms) as f64 / 1000.0);
                GrossErrorTruth {
                    t: g.t,
                    true_position: Point2::new(round_to(tp.x, 1e4), round_to(tp.y, 1e4)),
                    scan_position: Point2::new(
                        round_to(g.position.x, 1e4),
                        round_to(g.position.y, 1e4),
                    ),
                }
            })
            .collect();

        let mut rng = rng::walk_stream(self.seed, index, rng::WALK_WAYPOINTS);
        // Waypoints: start, about every `waypoint_spacing_m`, the middle of every recorded
        // turn, and the end.
        let mut marks: Vec<f64> = Vec::new();
        let mut s = w.waypoint_spacing_m * rng.uniform(0.7, 1.3);
        while s < s_end - 0.5 {
            marks.push(s);
            s += w.waypoint_spacing_m * rng.uniform(0.7, 1.3);
        }
        marks.extend(
            path.corners
                .iter()
                .filter(|c| c.angle.abs() >= min_turn && c.s_end <= s_end)
                .map(|c| (c.s_start + c.s_end) / 2.0),
        );
        let mut times: Vec<f64> = marks.into_iter().map(|s| timeline.time_at_arc(s)).collect();
        times.push(0.0);
        times.push(duration_s);
        times.sort_by(f64::total_cmp);
        let mut waypoints: Vec<Waypoint> = Vec::new();
        for t in times {
            let t_ms = to_ms(t);
            if waypoints.last().is_some_and(|l| l.t >= t_ms) {
                continue;
            }
            let p = position(t);
            let (nx, ny) = (rng.normal(), rng.normal());
            let noise = w.waypoint_noise_m;
            waypoints.push(Waypoint::new(
                t_ms,
                Point2::new(
                    round_to(p.x + noise * nx, 1e4),
                    round_to(p.y + noise * ny, 1e4),
                ),
            ));
        }

        let walk_id = self.walk_id(index);
        let walk = Walk {
            meta: WalkMeta {
                id: walk_id.clone(),
                site_id: Some("wipdr-sim".into()),
                site_name: Some(cfg.site_name.clone()),
                floor_id: Some(format!("wipdr-sim-{}", cfg.floor_name)),
                floor_name: Some(cfg.floor_name.clone()),
                brand: Some("wipdr".into()),
                model: Some("sim".into()),
                android: Some("sim".into()),
                start_time: Some(start_ms),
                end_time: Some(end_ms),
                route: None,
            },
            waypoints,
            wifi,
            beacons: Vec::new(),
            imu,
            pressure: Vec::new(),
        };
        let distance_m = steps.iter().map(|s| s.arc_length).sum();
        let truth = WalkTruth {
            walk_id,
            seed: self.seed,
            index,
            start_ms,
            end_ms,
            walker: params,
            phone: pose,
            map_to_magnetic: cfg.imu.map_to_magnetic_deg.to_radians(),
            steps,
            turns,
            stops,
            trajectory,
            gross_errors,
            distance_m,
        };
        SimWalk { walk, truth }
    }
}

//! The online pipeline: [`Frontend`] (PDR + stream matcher: samples in, step and fix events
//! out), the fusion stage (a fuser and its wrappers: events in, estimates out; crate-internal,
//! replayed over a recorded stream by [`crate::replay::replay_scheme`]) and the
//! [`Positioner`] that chains them for one stream.

use crate::config::Odometry;
use crate::sample::{PressureSample, Sample};
use crate::{
    FloorConfig, FloorTracker, PositionEstimate, PositionerConfig, PositioningError, Site,
};
use std::sync::Arc;
use wipdr_core::ConfigError;
use wipdr_core::MotionState;
use wipdr_core::{
    Point2, RotationVectorSample, StepEvent, TimestampMs, Vec3Sample, Vector2, WifiObservation,
    WifiScan, angle,
};
use wipdr_fingerprint::likelihood::{RssOffsetEstimate, ScanLikelihood};
use wipdr_fingerprint::{MatcherModel, OnlineMatcher, ScanContext};
use wipdr_fusion::replay::{FusionInput, merged};
use wipdr_fusion::static_start::StaticStart;
use wipdr_fusion::{Fuser, MapMatched, SchemeConfig};
use wipdr_pdr::odometry::{self, LearnedOdometry, OdometryStream};
use wipdr_pdr::{CheckedPdrConfig, Pdr};

/// The largest device RSS offset the likelihood's online estimate may reach, dB (phones
/// differ from one another by up to about 10-15 dB).
const MAX_RSS_OFFSET_DB: f64 = 20.0;

/// What the front end made of one sample.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Event {
    /// A motion event ended at this sample: a PDR step, or with `odometry = "learned"` the
    /// learned displacement since the previous one with its covariance
    /// ([`StepEvent::covariance`]).
    Step(StepEvent),
    /// A Wi-Fi scan was matched.
    Fix(WifiObservation),
}

/// Counts of what a stream's front end received and made.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct StreamCounts {
    /// Samples received.
    pub samples: u64,
    /// Samples older than the latest one (out of order), ignored.
    pub out_of_order: u64,
    /// Steps detected.
    pub steps: u64,
    /// Learned odometry outputs (one a second of IMU; 0 with `odometry = "steps"`).
    pub odometry_outputs: u64,
    /// Scans received.
    pub scans: u64,
    /// Scans the matcher could not use (no known AP left after filtering, ...).
    pub unmatched_scans: u64,
    /// Pressure samples received (the floor estimate's barometer input).
    pub pressure: u64,
    /// Fixes none of whose candidates lie on the stream's current floor, dropped.
    pub off_floor_fixes: u64,
}

/// The scheme-independent half of a [`Positioner`]: PDR and the stream matcher (and the floor
/// estimate where the map has floors), raw samples in, motion events and Wi-Fi fixes out.
/// Computes what the matchers need from the PDR (the latest step's motion for the AP index,
/// the displacement since the previous scan for MED).
///
/// A positioner runs one inside; on its own, [`Frontend::record`] streams a recording once
/// and keeps its events, which [`crate::replay::replay_scheme`] then runs through any number
/// of schemes, each giving what a positioner with that scheme would (the evaluation's use:
/// thirteen schemes over each test walk). See [`crate::replay`] for an example.
pub struct Frontend {
    pdr: Pdr,
    matcher: Box<dyn OnlineMatcher>,
    last_step: Option<(TimestampMs, wipdr_core::MotionState)>,
    moved: Vector2,
    last_t: Option<TimestampMs>,
    last_pressure: Option<PressureSample>,
    floors: Option<FloorTracker>,
    fixes_across_floors: bool,
    counts: StreamCounts,
    /// The learned odometry (`odometry = "learned"`); `None`: steps move the fuser.
    learned: Option<Box<LearnedMotion>>,
    /// The scan likelihood each fix carries ([`Frontend::with_likelihood`]); `None`: fixes
    /// are points only.
    likelihood: Option<Arc<ScanLikelihood>>,
    /// The stream's device RSS offset for the likelihood (`likelihood.estimate_offset`).
    rss_offset: RssOffsetEstimate,
    /// The offset the latest fix's likelihood was made with, dB.
    rss_offset_db: f64,
}

/// The learned motion source of a stream: the streaming network and what turns its outputs
/// into motion events in the map frame.
#[derive(Debug)]
struct LearnedMotion {
    stream: OdometryStream,
    /// `pdr.heading.map_offset_rad`: the map frame's heading offset from East-North-Up.
    map_offset_rad: f64,
    /// Heading and time of the previous motion event.
    previous: Option<(f64, TimestampMs)>,
}

impl LearnedMotion {
    /// The outputs the stream completed, summed (a gap in the IMU can complete several) into
    /// one motion event stamped `t` (the sample that completed them, as a step is stamped
    /// when its detection completes); `None` when there is none.
    fn take(&mut self, t: TimestampMs, motion: MotionState) -> Option<(StepEvent, u64)> {
        let mut d = [0.0; 2];
        let mut c = [0.0; 3];
        let mut n = 0u64;
        while let Some(o) = self.stream.pop() {
            d[0] += o.displacement[0];
            d[1] += o.displacement[1];
            for (ci, oc) in c.iter_mut().zip(o.covariance) {
                *ci += oc;
            }
            n += 1;
        }
        if n == 0 {
            return None;
        }
        let d = odometry::rotate_heading(d, self.map_offset_rad);
        let c = odometry::rotate_covariance(c, self.map_offset_rad);
        let heading = angle::wrap_two_pi(angle::heading_of(Vector2::new(d[0], d[1])));
        let (heading_change, period_s) = match self.previous {
            Some((h, t0)) => (angle::wrap_pi(heading - h), (t - t0) as f64 / 1000.0),
            None => (0.0, n as f64 * odometry::INTERVAL_MS as f64 / 1000.0),
        };
        self.previous = Some((heading, t));
        Some((
            StepEvent {
                t,
                length: d[0].hypot(d[1]),
                heading,
                heading_change,
                period_s,
                motion,
                covariance: Some(c),
            },
            n,
        ))
    }
}

impl std::fmt::Debug for Frontend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Frontend")
            .field("matcher", &self.matcher.name())
            .field("counts", &self.counts)
            .finish()
    }
}

impl Frontend {
    /// A front end over a built matcher, with the default [`FloorConfig`].
    pub fn new(pdr: CheckedPdrConfig, matcher: Box<dyn OnlineMatcher>) -> Self {
        Self::with_floor_config(pdr, matcher, FloorConfig::default())
    }

    /// A front end over a built matcher. When the matcher's radio map has floors, a
    /// [`FloorTracker`] over them estimates the stream's floor from the fixes and the
    /// barometer, and each fix is restricted to its candidates on that floor
    /// ([`WifiObservation::on_floor`]; a fix with none there is dropped and counted) unless
    /// [`FloorConfig::fixes_across_floors`].
    pub fn with_floor_config(
        pdr: CheckedPdrConfig,
        matcher: Box<dyn OnlineMatcher>,
        floor: FloorConfig,
    ) -> Self {
        let levels: Vec<i32> = matcher
            .map()
            .points()
            .iter()
            .filter_map(|p| p.floor)
            .collect();
        let floors = (!levels.is_empty()).then(|| FloorTracker::new(levels, floor));
        Self {
            pdr: Pdr::new(pdr),
            matcher,
            last_step: None,
            moved: Vector2::zeros(),
            last_t: None,
            last_pressure: None,
            floors,
            fixes_across_floors: floor.fixes_across_floors.unwrap_or(false),
            counts: StreamCounts::default(),
            learned: None,
            likelihood: None,
            rss_offset: RssOffsetEstimate::new(1.0, 20.0),
            rss_offset_db: 0.0,
        }
    }

    /// The front end with each fix carrying its scan's likelihood over the fix's floor
    /// ([`WifiObservation::likelihood`], from `likelihood`'s fields; `None`: points only).
    /// What `pmf` with `wifi_likelihood` weighs cells by; its cost, a pass over the floor's
    /// raster and the scan's APs' fields, is paid only when a scheme asks for it.
    pub fn with_likelihood(mut self, likelihood: Option<Arc<ScanLikelihood>>) -> Self {
        if let Some(model) = &likelihood {
            self.rss_offset =
                RssOffsetEstimate::new(model.config().offset_prior_scans, MAX_RSS_OFFSET_DB);
        }
        self.likelihood = likelihood;
        self
    }

    /// The front end with motion source `odometry`: with [`Odometry::Learned`], the shipped
    /// network ([`LearnedOdometry::shipped_shared`]) makes the motion events, turned into
    /// the map frame by `map_offset_rad` (the PDR's `heading.map_offset_rad`); the PDR still
    /// runs for the matchers' motion state. Errors when the shipped weights cannot be read.
    pub fn with_odometry(
        self,
        odometry: Odometry,
        map_offset_rad: f64,
    ) -> Result<Self, PositioningError> {
        self.with_odometry_model(odometry, None, map_offset_rad)
    }

    /// [`Frontend::with_odometry`] with the network `model` instead of the shipped one
    /// (`None`: the shipped one): how an evaluation runs each floor on a network that never
    /// trained on it (`wipdr eval --odometry-holdout`). `model` is not read under
    /// [`Odometry::Steps`].
    pub fn with_odometry_model(
        mut self,
        odometry: Odometry,
        model: Option<Arc<LearnedOdometry>>,
        map_offset_rad: f64,
    ) -> Result<Self, PositioningError> {
        self.learned = match odometry {
            Odometry::Steps => None,
            Odometry::Learned => {
                let model = match model {
                    Some(m) => m,
                    None => LearnedOdometry::shipped_shared().map_err(|e| {
                        PositioningError::InvalidConfig(ConfigError::new("odometry", e.to_string()))
                    })?,
                };
                Some(Box::new(LearnedMotion {
                    stream: OdometryStream::new(model),
                    map_offset_rad,
                    previous: None,
                }))
            }
        };
        Ok(self)
    }

    /// The motion source of this front end.
    pub fn odometry(&self) -> Odometry {
        if self.learned.is_some() {
            Odometry::Learned
        } else {
            Odometry::Steps
        }
    }

    /// Gives the floor estimate barometric references for this stream
    /// ([`FloorTracker::with_references`]); no effect when the map has no floors.
    pub fn set_pressure_references(
        &mut self,
        references: std::sync::Arc<Vec<crate::PressureReference>>,
        identity: crate::StreamIdentity,
    ) {
        if let Some(t) = self.floors.take() {
            self.floors = Some(t.with_references(references, identity));
        }
    }

    /// Gives the floor estimate the building's floors and their heights, metres
    /// ([`FloorTracker::with_building`]: floors without fingerprints are reached by the
    /// barometer); no effect when the map has no floors. Call before the first sample.
    pub fn set_building_floors(&mut self, floors: &[i32], heights_m: &[f64]) {
        if let Some(t) = self.floors.take() {
            self.floors = Some(t.with_building(floors, heights_m));
        }
    }

    /// The stream's current floor (`None` when the map has no floors, or before a fix).
    pub fn floor(&self) -> Option<i32> {
        self.floors.as_ref().and_then(FloorTracker::floor)
    }

    /// What the stream received so far.
    pub fn counts(&self) -> StreamCounts {
        self.counts
    }

    /// The latest barometer reading.
    pub fn last_pressure(&self) -> Option<PressureSample> {
        self.last_pressure
    }

    /// Feeds one sample; samples must come in time order (an older one is counted and
    /// ignored). Returns the event it completed, if any.
    pub(crate) fn push(&mut self, sample: &Sample) -> Option<Event> {
        self.counts.samples += 1;
        let t = sample.t();
        if self.last_t.is_some_and(|last| t < last) {
            self.counts.out_of_order += 1;
            tracing::debug!(t, "sample older than the stream: ignored");
            return None;
        }
        self.last_t = Some(t);
        if self.learned.is_some() {
            return self.push_learned(sample);
        }
        match sample {
            Sample::RotationVector(s) => self.pdr.push_rotation_vector(s),
            Sample::Gyroscope(s) => self.pdr.push_gyroscope(s),
            Sample::Magnetometer(s) => self.pdr.push_magnetometer(s),
            Sample::Accelerometer(s) => return self.accelerometer(s).map(Event::Step),
            Sample::Pressure(_) | Sample::Wifi(_) => return self.push_other(sample),
        }
        None
    }

    /// [`Frontend::push`] with the learned motion source: the IMU feeds both the PDR (whose
    /// steps give the matchers' motion state) and the network, whose outputs are the motion
    /// events.
    fn push_learned(&mut self, sample: &Sample) -> Option<Event> {
        let learned = self.learned.as_mut()?;
        match sample {
            Sample::RotationVector(s) => {
                self.pdr.push_rotation_vector(s);
                learned.stream.push_rotation_vector(s.t, s.v);
            }
            Sample::Gyroscope(s) => {
                self.pdr.push_gyroscope(s);
                learned.stream.push_gyroscope(s.t, s.v);
            }
            Sample::Accelerometer(s) => {
                learned.stream.push_accelerometer(s.t, s.v);
                if let Some(step) = self.pdr.push_accelerometer(s) {
                    self.counts.steps += 1;
                    self.last_step = Some((step.t, step.motion));
                }
            }
            Sample::Magnetometer(s) => {
                self.pdr.push_magnetometer(s);
                return None;
            }
            Sample::Pressure(_) | Sample::Wifi(_) => return self.push_other(sample),
        }
        let motion = self.last_step.map(|(_, m)| m).unwrap_or_default();
        let learned = self.learned.as_mut()?;
        let (event, outputs) = learned.take(sample.t(), motion)?;
        self.counts.odometry_outputs += outputs;
        self.moved += angle::step_displacement(event.length, event.heading);
        Some(Event::Step(event))
    }

    /// Pressure and Wi-Fi samples (the same for both motion sources).
    fn push_other(&mut self, sample: &Sample) -> Option<Event> {
        match sample {
            Sample::Pressure(p) => {
                if p.hpa.is_finite() {
                    self.counts.pressure += 1;
                    self.last_pressure = Some(*p);
                    if let Some(floors) = &mut self.floors {
                        floors.push_pressure(p);
                    }
                }
                None
            }
            Sample::Wifi(scan) => self.scan(scan).map(Event::Fix),
            _ => None,
        }
    }

    fn accelerometer(&mut self, s: &Vec3Sample) -> Option<StepEvent> {
        let step = self.pdr.push_accelerometer(s)?;
        self.counts.steps += 1;
        self.last_step = Some((step.t, step.motion));
        self.moved += angle::step_displacement(step.length, step.heading);
        Some(step)
    }

    fn scan(&mut self, scan: &WifiScan) -> Option<WifiObservation> {
        self.counts.scans += 1;
        let context = ScanContext {
            last_step: self.last_step,
            displacement: self.moved,
        };
        self.moved = Vector2::zeros();
        let obs = match self.matcher.locate_online(scan, &context) {
            Ok(obs) => obs,
            Err(e) => {
                self.counts.unmatched_scans += 1;
                tracing::trace!(t = scan.t, error = %e, "scan not matched");
                return None;
            }
        };
        let obs = self.fix_on_floor(scan, obs)?;
        let Some(model) = &self.likelihood else {
            return Some(obs);
        };
        let offset_db = if model.config().estimate_offset {
            if let Some(r) = model.rss_residual(obs.floor, obs.estimate, scan) {
                self.rss_offset.observe(r);
            }
            self.rss_offset.offset_db()
        } else {
            0.0
        };
        self.rss_offset_db = offset_db;
        Some(WifiObservation {
            likelihood: model.relative(obs.floor, scan, offset_db).map(Arc::new),
            ..obs
        })
    }

    /// The fix on the stream's floor: its floor set to the tracker's, restricted to its
    /// candidates there (`None`, counted, when it has none) unless fixes may cross floors.
    fn fix_on_floor(&mut self, scan: &WifiScan, obs: WifiObservation) -> Option<WifiObservation> {
        let Some(floors) = &mut self.floors else {
            return Some(obs);
        };
        floors.push_fix(obs.t, obs.floor);
        let Some(floor) = floors.floor() else {
            return Some(obs);
        };
        if self.fixes_across_floors {
            return Some(WifiObservation {
                floor: Some(floor),
                ..obs
            });
        }
        let on_floor = obs.on_floor(floor);
        if on_floor.is_none() {
            self.counts.off_floor_fixes += 1;
            tracing::trace!(t = scan.t, floor, fix_floor = ?obs.floor, "fix off the current floor dropped");
        }
        on_floor
    }
}

/// One stream's fusion: the scheme's fuser wrapped in the configured static start and map
/// matching, fed events in time order ([`wipdr_fusion::replay`]'s tie rule).
pub(crate) struct FusionStage {
    fuser: Box<dyn Fuser + Send>,
    floor: Option<i32>,
    /// The fuser's estimate after its latest input (its floor set on reading). The fuser's
    /// estimate is a function of its state, which only its inputs change, so it is computed
    /// once an input instead of once a sample: the Positioner answers every sample (200 a
    /// second) while steps and fixes come a few a second. Computing `pmf`'s estimate (a
    /// weighted mean and median over the cells about the mode) for every sample cost a tenth
    /// of its instructions (callgrind, `benches/profile_positioner.sh`: 33,799 -> 30,472 a
    /// sample).
    current: Option<PositionEstimate>,
}

impl std::fmt::Debug for FusionStage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FusionStage")
            .field("scheme", &self.fuser.name())
            .finish()
    }
}

impl FusionStage {
    /// Builds `config.scheme` for one stream. `start` is a known start position (the `pdr`
    /// baseline of the evaluation protocol starts at the true first waypoint; a user may know
    /// theirs); with a start the static start is not applied. `seed` seeds random schemes.
    pub fn new(
        site: &Site,
        config: &PositionerConfig,
        seed: u64,
        start: Option<Point2>,
    ) -> Result<Self, PositioningError> {
        Self::with_scheme(site, &config.scheme, config, seed, start)
    }

    /// [`FusionStage::new`] with another scheme than `config.scheme` (the evaluation runs
    /// many schemes with one config).
    pub fn with_scheme(
        site: &Site,
        scheme: &SchemeConfig,
        config: &PositionerConfig,
        seed: u64,
        start: Option<Point2>,
    ) -> Result<Self, PositioningError> {
        let ctx = site.build_context(seed, start);
        let mut fuser = scheme
            .build(&ctx)
            .map_err(|source| PositioningError::Scheme {
                scheme: scheme.name().to_string(),
                source,
            })?;
        if let Some(ss) = config.static_start.as_ref().filter(|_| start.is_none()) {
            ss.validate().map_err(|e| e.into_config_error())?;
            fuser = Box::new(StaticStart::new(fuser, ss.clone()));
        }
        if config.map_matching {
            match &site.walkable {
                Some(grid) => fuser = Box::new(MapMatched::new(fuser, grid.clone())),
                // Said once per site (`Site::from_plan`), not per stream.
                None => tracing::debug!("map_matching needs a floor plan with an outline: off"),
            }
        }
        let current = Self::estimate_of(fuser.as_ref());
        Ok(Self {
            fuser,
            floor: None,
            current,
        })
    }

    /// The fuser's estimate, without a floor.
    fn estimate_of(fuser: &(dyn Fuser + Send)) -> Option<PositionEstimate> {
        fuser.estimate().map(|e| PositionEstimate {
            t: e.t,
            position: e.position,
            floor: None,
            covariance: e.covariance,
        })
    }

    /// Feeds a step; returns the estimate after it.
    pub fn push_step(&mut self, step: &StepEvent) -> Option<PositionEstimate> {
        self.fuser.on_step(step);
        self.current = Self::estimate_of(self.fuser.as_ref());
        self.estimate()
    }

    /// Feeds a Wi-Fi fix; returns the estimate after it.
    pub fn push_fix(&mut self, fix: &WifiObservation) -> Option<PositionEstimate> {
        self.fuser.on_wifi(fix);
        if fix.floor.is_some() {
            self.floor = fix.floor;
        }
        self.current = Self::estimate_of(self.fuser.as_ref());
        self.estimate()
    }

    /// Feeds a recorded stream's steps and fixes (each time-sorted) in time order, skipping
    /// the inputs before `from` (a known start holds from its time); the estimate after every
    /// input that gave one, stamped with that input's time. What the evaluation and
    /// [`crate::smooth`] run.
    pub fn replay(
        &mut self,
        steps: &[StepEvent],
        fixes: &[WifiObservation],
        from: Option<TimestampMs>,
    ) -> Vec<PositionEstimate> {
        let mut out = Vec::with_capacity(steps.len() + fixes.len());
        for input in merged(steps, fixes) {
            let t = match input {
                FusionInput::Step(i) => steps[i].t,
                FusionInput::Wifi(j) => fixes[j].t,
            };
            if from.is_some_and(|from| t < from) {
                continue;
            }
            let estimate = match input {
                FusionInput::Step(i) => self.push_step(&steps[i]),
                FusionInput::Wifi(j) => self.push_fix(&fixes[j]),
            };
            if let Some(e) = estimate {
                out.push(PositionEstimate { t, ..e });
            }
        }
        out
    }

    /// Feeds an event.
    pub fn push(&mut self, event: &Event) -> Option<PositionEstimate> {
        match event {
            Event::Step(s) => self.push_step(s),
            Event::Fix(f) => self.push_fix(f),
        }
    }

    /// The current estimate (`None` until the scheme has one).
    pub fn estimate(&self) -> Option<PositionEstimate> {
        self.current.clone().map(|e| PositionEstimate {
            floor: self.floor,
            ..e
        })
    }
}

/// The online positioning pipeline of one stream: raw samples in, one at a time in time
/// order; the current estimate out. Owns the PDR, the stream matcher and the fuser.
///
/// See the [crate docs](crate) for an example.
#[derive(Debug)]
pub struct Positioner {
    frontend: Frontend,
    fusion: FusionStage,
    /// What [`Positioner::smooth`] needs: the site, the config and the events so far.
    smoothing: Option<Smoothing>,
}

/// The inputs of [`Positioner::smooth`]: how the fusion stage was built and every event.
#[derive(Debug)]
struct Smoothing {
    site: Site,
    config: PositionerConfig,
    steps: Vec<StepEvent>,
    /// The fixes, without their likelihood rasters (tens of kB each: a live stream keeps
    /// its scan instead, and the raster is made again when smoothing).
    fixes: Vec<WifiObservation>,
    /// Per fix: the scan and the RSS offset its likelihood was made with, when it had one.
    fix_scans: Vec<Option<(WifiScan, f64)>>,
    /// The front end's floor after each event: `(time, floor)`.
    floors: Vec<(TimestampMs, Option<i32>)>,
}

impl Positioner {
    /// A positioner for one stream running scheme `scheme` on a fitted site model
    /// ([`crate::SiteModel`]): its radio map, calibrated PDR, plan, coverage and trails, the
    /// model's config with the model's settings for `scheme`, the config's seed. For a seed
    /// per stream, barometric references or a known start, use
    /// [`crate::SiteModel::positioner`].
    pub fn new(model: &crate::SiteModel, scheme: &str) -> Result<Self, crate::SiteModelError> {
        model.positioner(scheme, &crate::StreamSpec::default())
    }

    /// A positioner for one stream over a built matcher and a site, all settings given
    /// (`seed` as given: mix a stream id in with [`crate::stream_seed`] for many streams);
    /// what [`Positioner::new`] does once it has the site model's parts. The matcher must
    /// be the one `config.matcher` names (built by its [`MatcherConfig::build`]): another
    /// is an error, so that a positioner always runs the matcher its config says.
    ///
    /// [`MatcherConfig::build`]: wipdr_fingerprint::MatcherConfig::build
    pub fn from_parts(
        matcher: &MatcherModel,
        site: &Site,
        config: &PositionerConfig,
        start: Option<Point2>,
    ) -> Result<Self, PositioningError> {
        config.validate()?;
        if matcher.config() != &config.matcher {
            return Err(PositioningError::InvalidConfig(ConfigError::new(
                "matcher",
                format!(
                    "the config names the matcher {:?} but the one given was built from {:?}: build it with `config.matcher.build(map)`",
                    config.matcher.kind(),
                    matcher.config().kind()
                ),
            )));
        }
        Ok(Self {
            frontend: Frontend::with_floor_config(
                config.pdr.check().map_err(|e| e.under("pdr"))?,
                matcher.stream(config.query),
                config.floor,
            )
            .with_odometry(config.odometry, config.pdr.heading.map_offset_rad)?
            .with_likelihood(
                site.likelihood
                    .clone()
                    .filter(|_| config.scheme.uses_wifi_likelihood()),
            ),
            fusion: FusionStage::new(site, config, config.seed, start)?,
            // A known start is a causal prior the backward run cannot use: no smoothing.
            smoothing: start.is_none().then(|| Smoothing {
                site: site.clone(),
                config: config.clone(),
                steps: Vec::new(),
                fixes: Vec::new(),
                fix_scans: Vec::new(),
                floors: Vec::new(),
            }),
        })
    }

    /// Feeds one sample. Returns the new estimate when the sample completed a step or a fix
    /// (and the scheme has an estimate); `None` otherwise (see [`Positioner::estimate`]).
    pub fn push(&mut self, sample: &Sample) -> Option<PositionEstimate> {
        let event = self.frontend.push(sample)?;
        if let Some(sm) = self.smoothing.as_mut() {
            let t = match &event {
                Event::Step(s) => {
                    sm.steps.push(*s);
                    s.t
                }
                Event::Fix(f) => {
                    let mut stored = f.clone();
                    let scan = match (stored.likelihood.take(), sample) {
                        (Some(_), Sample::Wifi(scan)) => {
                            Some((scan.clone(), self.frontend.rss_offset_db))
                        }
                        _ => None,
                    };
                    sm.fixes.push(stored);
                    sm.fix_scans.push(scan);
                    f.t
                }
            };
            if self.frontend.floors.is_some() {
                sm.floors.push((t, self.frontend.floor()));
            }
        }
        self.fusion.push(&event)?;
        self.estimate()
    }

    /// The whole stream so far re-estimated offline: the scheme run forward and on the
    /// time-reversed stream over every step and fix received, combined at each input time
    /// ([`crate::smooth::smooth_fusion`]); each estimate uses the inputs after it too (what
    /// `wipdr eval --offline` scores). The live estimate is not changed. Errors for a
    /// positioner built with a known start.
    pub fn smooth(&self) -> Result<Vec<PositionEstimate>, PositioningError> {
        let sm = self.smoothing.as_ref().ok_or_else(|| {
            PositioningError::InvalidConfig(ConfigError::new(
                "smooth",
                "this positioner was built with a known start; build it without a start to \
                 smooth",
            ))
        })?;
        // The fixes' likelihoods made again from their scans, as the live stream made them.
        let fixes: Vec<WifiObservation> = match &sm.site.likelihood {
            Some(model) if sm.fix_scans.iter().any(Option::is_some) => sm
                .fixes
                .iter()
                .zip(&sm.fix_scans)
                .map(|(f, scan)| WifiObservation {
                    likelihood: scan.as_ref().and_then(|(scan, offset)| {
                        model.relative(f.floor, scan, *offset).map(Arc::new)
                    }),
                    ..f.clone()
                })
                .collect(),
            _ => sm.fixes.clone(),
        };
        let mut track = crate::smooth::smooth_fusion(
            &sm.site,
            &sm.config.scheme,
            &sm.config,
            sm.config.seed,
            &sm.steps,
            &fixes,
        )?;
        if !sm.floors.is_empty() {
            // The front end's floor (Wi-Fi and barometer), as the live estimate reports it.
            let mut j = 0usize;
            let mut floor = None;
            for e in &mut track {
                while j < sm.floors.len() && sm.floors[j].0 <= e.t {
                    floor = sm.floors[j].1;
                    j += 1;
                }
                e.floor = floor;
            }
        }
        Ok(track)
    }

    /// Gives the floor estimate barometric references for this stream
    /// ([`Frontend::set_pressure_references`]).
    pub fn set_pressure_references(
        &mut self,
        references: std::sync::Arc<Vec<crate::PressureReference>>,
        identity: crate::StreamIdentity,
    ) {
        self.frontend.set_pressure_references(references, identity);
    }

    /// Gives the floor estimate the building's floors and their heights
    /// ([`Frontend::set_building_floors`]). Call before the first sample.
    pub fn set_building_floors(&mut self, floors: &[i32], heights_m: &[f64]) {
        self.frontend.set_building_floors(floors, heights_m);
    }

    /// Feeds one sample to the front end only (PDR attitude and filters, matcher state, floor
    /// estimate), not to the fuser: the samples before a known start time, which must not
    /// move the start.
    pub fn warm_up(&mut self, sample: &Sample) {
        let _ = self.frontend.push(sample);
    }

    /// Feeds an accelerometer sample (m/s², device frame).
    pub fn push_accelerometer(&mut self, t: TimestampMs, v: [f64; 3]) -> Option<PositionEstimate> {
        self.push(&Sample::Accelerometer(Vec3Sample { t, v, accuracy: 3 }))
    }

    /// Feeds a gyroscope sample (rad/s, device frame).
    pub fn push_gyroscope(&mut self, t: TimestampMs, v: [f64; 3]) -> Option<PositionEstimate> {
        self.push(&Sample::Gyroscope(Vec3Sample { t, v, accuracy: 3 }))
    }

    /// Feeds a magnetometer sample (µT, device frame).
    pub fn push_magnetometer(&mut self, t: TimestampMs, v: [f64; 3]) -> Option<PositionEstimate> {
        self.push(&Sample::Magnetometer(Vec3Sample { t, v, accuracy: 3 }))
    }

    /// Feeds a rotation-vector sample (`x, y, z` of Android's attitude quaternion).
    pub fn push_rotation_vector(
        &mut self,
        t: TimestampMs,
        v: [f64; 3],
    ) -> Option<PositionEstimate> {
        self.push(&Sample::RotationVector(RotationVectorSample {
            t,
            v,
            accuracy: 3,
        }))
    }

    /// Feeds a barometer sample (hPa).
    pub fn push_pressure(&mut self, t: TimestampMs, hpa: f64) -> Option<PositionEstimate> {
        self.push(&Sample::Pressure(PressureSample { t, hpa }))
    }

    /// Feeds a Wi-Fi scan.
    pub fn push_scan(&mut self, scan: WifiScan) -> Option<PositionEstimate> {
        self.push(&Sample::Wifi(scan))
    }

    /// The current estimate (`None` until the scheme has one), on the front end's floor
    /// when the map has floors.
    pub fn estimate(&self) -> Option<PositionEstimate> {
        let mut e = self.fusion.estimate()?;
        if self.frontend.floors.is_some() {
            e.floor = self.frontend.floor();
        }
        Some(e)
    }

    /// What the stream received so far.
    pub fn counts(&self) -> StreamCounts {
        self.frontend.counts()
    }
}

/// A whole recorded stream through a [`Positioner`]: the track of estimates, one after each
/// step or fix (and one at `start`'s time first when a start is given), as `wipdr locate`
/// writes it and the evaluation scores it. With a start, the samples before its time only
/// warm the front end up ([`Positioner::warm_up`]): a step taken before the start does not
/// move it; the start's row is taken once they are in, so it carries the floor the front end
/// estimated from them.
pub fn track_of(
    positioner: &mut Positioner,
    samples: impl IntoIterator<Item = Sample>,
    start: Option<(TimestampMs, Point2)>,
) -> Vec<PositionEstimate> {
    let mut track = Vec::new();
    let mut start_row = start.map(|(t, _)| t);
    let mut emit_start = |positioner: &Positioner, track: &mut Vec<PositionEstimate>| {
        if let (Some(t), Some(mut e)) = (start_row.take(), positioner.estimate()) {
            e.t = t;
            track.push(e);
        }
    };
    for s in samples {
        let t = s.t();
        if start.is_some_and(|(t0, _)| t < t0) {
            positioner.warm_up(&s);
            continue;
        }
        emit_start(positioner, &mut track);
        if let Some(mut e) = positioner.push(&s) {
            e.t = t;
            track.push(e);
        }
    }
    emit_start(positioner, &mut track);
    track
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;
    use wipdr_core::Bssid;
    use wipdr_fingerprint::{KnnConfig, MatcherConfig, RadioMap};

    /// `from_parts` runs the matcher its config names: a matcher built from another config
    /// (even of the same kind with other settings) is refused, naming the field.
    #[test]
    fn a_matcher_built_from_another_config_is_refused() {
        let map = Arc::new(
            RadioMap::from_records(
                (0..10).map(|i| {
                    let x = f64::from(i);
                    (
                        Point2::new(x, 0.0),
                        vec![(Bssid(1), -40.0 - 4.0 * x), (Bssid(2), -76.0 + 4.0 * x)],
                    )
                }),
                Default::default(),
            )
            .unwrap(),
        );
        let site = Site::new(None, &map);
        let config = PositionerConfig::default();
        let own = config.matcher.build(map.clone()).unwrap();
        assert!(Positioner::from_parts(&own, &site, &config, None).is_ok());
        for other in [
            MatcherConfig::Wknn(KnnConfig::default()),
            MatcherConfig::Wknn(KnnConfig {
                k: 3,
                ..KnnConfig::default()
            }),
        ] {
            let matcher = other.build(map.clone()).unwrap();
            let paper = PositionerConfig::paper();
            let e = Positioner::from_parts(&matcher, &site, &config, None).unwrap_err();
            assert!(e.to_string().contains("matcher"), "{e}");
            // The paper preset names the default WKNN: it runs it, and refuses k = 3.
            let ran = Positioner::from_parts(&matcher, &site, &paper, None);
            assert_eq!(ran.is_ok(), other == paper.matcher, "{other:?}");
        }
    }

    /// The fusion stage hands out the estimate its fuser gave after the latest input: the
    /// same as asking the fuser, after every step and fix, with the latest fix's floor.
    #[test]
    fn the_stage_estimate_is_the_fusers_after_every_input() {
        use wipdr_core::MotionState;
        let map = Arc::new(
            RadioMap::from_records(
                (0..10).map(|i| {
                    let x = f64::from(i);
                    (Point2::new(x, 0.0), vec![(Bssid(1), -40.0 - 4.0 * x)])
                }),
                Default::default(),
            )
            .unwrap(),
        );
        let site = Site::new(None, &map);
        let config = PositionerConfig::default();
        for name in ["ekf", "pmf", "pf"] {
            let scheme = SchemeConfig::default_for(name).unwrap();
            let mut stage = FusionStage::with_scheme(&site, &scheme, &config, 7, None).unwrap();
            assert_eq!(stage.estimate(), None, "{name}: no estimate before a fix");
            for k in 0..40i64 {
                let t = 1_000 + 500 * k;
                let out = if k % 7 == 0 {
                    stage.push_fix(&WifiObservation {
                        t,
                        estimate: Point2::new(0.3 * k as f64, 0.5),
                        candidates: vec![],
                        visited: 0,
                        floor: Some(i32::from(k >= 21)),
                        building: None,
                        likelihood: None,
                    })
                } else {
                    stage.push_step(&StepEvent {
                        t,
                        length: 0.7,
                        heading: 0.0,
                        heading_change: 0.0,
                        period_s: 0.5,
                        motion: MotionState::default(),
                        covariance: None,
                    })
                };
                let direct =
                    FusionStage::estimate_of(stage.fuser.as_ref()).map(|e| PositionEstimate {
                        floor: stage.floor,
                        ..e
                    });
                assert_eq!(out, direct, "{name}, input {k}");
                assert_eq!(stage.estimate(), direct, "{name}, input {k}");
            }
            assert_eq!(stage.estimate().and_then(|e| e.floor), Some(1), "{name}");
        }
    }
}

//! The streaming PDR pipeline: IMU samples in, [`StepEvent`]s out.

use crate::attitude::{
    GyroAttitude, GyroAttitudeConfig, HeadingKf, HeadingKfConfig, compass_orientation,
    gravity_orientation, heading_of, heading_rate, rotation_vector_quaternion,
};
use crate::detector::{StepCandidate, StepDetector, StepDetectorConfig};
use crate::length::{StepFeatures, StepLengthConfig};
use crate::motion::{MotionConfig, StationaryDetector, classify_speed, classify_turn};
use crate::vertical::{VerticalConfig, VerticalZupt};
use nalgebra::{UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use wipdr_core::angle::{diff, wrap_pi};
use wipdr_core::{MotionState, RotationVectorSample, StepEvent, TimestampMs, Vec3Sample, Walk};

/// Where a step's heading comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HeadingSource {
    /// The phone's rotation vector (Android's own gyro + accelerometer + magnetometer fusion).
    #[default]
    RotationVector,
    /// Quaternion integration of the gyroscope (paper 004 eq. 1-5), started from the first
    /// absolute orientation (rotation vector, else compass, else gravity with heading 0).
    Gyro,
    /// Gyro + compass Kalman filter (paper 002 eq. 9-12).
    GyroCompassKf,
    /// Tilt-compensated compass (accelerometer + magnetometer) alone.
    Compass,
}

impl HeadingSource {
    /// All sources, in the fallback order used when the chosen one has no value.
    pub const ALL: [HeadingSource; 4] = [
        HeadingSource::RotationVector,
        HeadingSource::GyroCompassKf,
        HeadingSource::Gyro,
        HeadingSource::Compass,
    ];

    /// A short name.
    pub fn name(self) -> &'static str {
        match self {
            HeadingSource::RotationVector => "rotation_vector",
            HeadingSource::Gyro => "gyro",
            HeadingSource::GyroCompassKf => "gyro_compass_kf",
            HeadingSource::Compass => "compass",
        }
    }
}

/// Which heading sample represents a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HeadingAt {
    /// The latest heading at the step's time (the sample code). The default: on the real
    /// walks it beats the step mean (pooled 3.41 vs 3.52 m, `docs/results/pdr.md`).
    #[default]
    StepTime,
    /// The circular mean of the headings since the previous step (averages out the sway of
    /// the phone within a stride, but lags half a step in turns).
    StepMean,
}

/// Heading settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HeadingConfig {
    /// The source of the emitted heading.
    pub source: HeadingSource,
    /// Which sample represents a step.
    pub at: HeadingAt,
    /// Offset added to every heading to go from magnetic azimuth to the map frame, rad
    /// (learned per floor from training walks by [`crate::calibrate`]).
    pub map_offset_rad: f64,
    /// Gyroscope attitude settings.
    pub gyro: GyroAttitudeConfig,
    /// Heading Kalman filter settings.
    pub kf: HeadingKfConfig,
    /// Snapping to the building's dominant directions (off by default).
    pub snap: crate::snap::HeadingSnapConfig,
}

impl Default for HeadingConfig {
    fn default() -> Self {
        Self {
            source: HeadingSource::default(),
            at: HeadingAt::default(),
            map_offset_rad: 0.0,
            gyro: GyroAttitudeConfig::default(),
            kf: HeadingKfConfig::default(),
            snap: crate::snap::HeadingSnapConfig::default(),
        }
    }
}

/// The whole PDR configuration.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PdrConfig {
    /// Step detection.
    pub detector: StepDetectorConfig,
    /// Step-length model and coefficients.
    pub step_length: StepLengthConfig,
    /// Heading.
    pub heading: HeadingConfig,
    /// Vertical ZUPT filter (inverted-pendulum model).
    pub vertical: VerticalConfig,
    /// Motion state.
    pub motion: MotionConfig,
    /// Handling gate: no steps while the phone is turned over in the hand.
    pub handling: crate::handling::HandlingConfig,
    /// Step lengths are clamped to at least this, m.
    pub min_step_length: f64,
    /// ... and at most this, m.
    pub max_step_length: f64,
    /// Period assumed for the first step after a start or reset, s.
    pub default_period_s: f64,
}

impl Default for PdrConfig {
    fn default() -> Self {
        Self {
            detector: StepDetectorConfig::default(),
            step_length: StepLengthConfig::default(),
            heading: HeadingConfig::default(),
            vertical: VerticalConfig::default(),
            motion: MotionConfig::default(),
            handling: crate::handling::HandlingConfig::default(),
            min_step_length: 0.2,
            max_step_length: 1.5,
            default_period_s: 0.55,
        }
    }
}

/// A [`PdrConfig`] whose values passed [`PdrConfig::validate`]: the only form [`Pdr`] is
/// built from, so a config read from a file reaches the pipeline checked or not at all (the
/// checked/unchecked split of linfa's `ParamGuard`). Read it through `Deref`; make it with
/// [`PdrConfig::check`], or take the defaults (valid: a unit test holds them).
///
/// ```
/// use wipdr_pdr::{CheckedPdrConfig, PdrConfig};
/// let bad = PdrConfig { min_step_length: f64::NAN, ..PdrConfig::default() };
/// assert_eq!(bad.check().unwrap_err().path, "min_step_length");
/// let good: CheckedPdrConfig = PdrConfig::default().check().unwrap();
/// assert_eq!(good.max_step_length, PdrConfig::default().max_step_length);
/// assert_eq!(good, CheckedPdrConfig::default());
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CheckedPdrConfig(PdrConfig);

impl CheckedPdrConfig {
    /// The config inside.
    pub fn into_inner(self) -> PdrConfig {
        self.0
    }
}

impl Default for CheckedPdrConfig {
    /// [`PdrConfig::default`], which validates.
    fn default() -> Self {
        Self(PdrConfig::default())
    }
}

impl std::ops::Deref for CheckedPdrConfig {
    type Target = PdrConfig;
    fn deref(&self) -> &PdrConfig {
        &self.0
    }
}

impl TryFrom<PdrConfig> for CheckedPdrConfig {
    type Error = wipdr_core::ConfigError;
    fn try_from(cfg: PdrConfig) -> Result<Self, Self::Error> {
        cfg.check()
    }
}

impl PdrConfig {
    /// The config as [`Pdr`] takes it, once [`PdrConfig::validate`] passes.
    pub fn check(self) -> Result<CheckedPdrConfig, wipdr_core::ConfigError> {
        self.validate()?;
        Ok(CheckedPdrConfig(self))
    }

    /// Checks the values a config file could get wrong (NaN, negative, inverted limits).
    /// Errors name the field's path under the PDR config (`detector.window_s`).
    pub fn validate(&self) -> Result<(), wipdr_core::ConfigError> {
        let bad = |field: &str, reason: String| Err(wipdr_core::ConfigError::new(field, reason));
        let (lo, hi) = (self.min_step_length, self.max_step_length);
        if !(lo.is_finite() && lo >= 0.0) {
            return bad(
                "min_step_length",
                format!("must be finite and >= 0, got {lo}"),
            );
        }
        if !(hi.is_finite() && hi >= lo) {
            return bad(
                "max_step_length",
                format!("must be finite and >= min_step_length ({lo}), got {hi}"),
            );
        }
        self.handling.validate()?;
        let d = &self.detector;
        for (field, v) in [
            ("detector.window_s", d.window_s),
            ("detector.max_gap_s", d.max_gap_s),
            ("default_period_s", self.default_period_s),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(field, format!("must be finite and > 0, got {v}"));
            }
        }
        for (field, v) in [
            ("detector.min_threshold", d.min_threshold),
            ("detector.std_factor", d.std_factor),
            ("detector.min_step_interval_s", d.min_step_interval_s),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(field, format!("must be finite and >= 0, got {v}"));
            }
        }
        if !self.heading.map_offset_rad.is_finite() {
            return bad(
                "heading.map_offset_rad",
                format!("must be finite, got {}", self.heading.map_offset_rad),
            );
        }
        self.heading.snap.validate()?;
        Ok(())
    }

    /// The competition sample code's PDR: its detector, its stride model, the rotation
    /// vector's heading at the step time, no map offset, no clamping (bounds 0 and 10 m).
    pub fn sample_code() -> Self {
        Self {
            step_length: StepLengthConfig::SampleCode(crate::length::SampleCode::default()),
            heading: HeadingConfig {
                source: HeadingSource::RotationVector,
                at: HeadingAt::StepTime,
                ..HeadingConfig::default()
            },
            min_step_length: 0.0,
            max_step_length: 10.0,
            ..Self::default()
        }
    }
}

/// Headings of one step from every source, in the map frame (offset applied), rad.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct SourceHeadings {
    /// Rotation vector.
    pub rotation_vector: Option<f64>,
    /// Gyroscope integration.
    pub gyro: Option<f64>,
    /// Gyro + compass Kalman filter.
    pub gyro_compass_kf: Option<f64>,
    /// Compass.
    pub compass: Option<f64>,
}

impl SourceHeadings {
    /// The heading of one source.
    pub fn get(&self, s: HeadingSource) -> Option<f64> {
        match s {
            HeadingSource::RotationVector => self.rotation_vector,
            HeadingSource::Gyro => self.gyro,
            HeadingSource::GyroCompassKf => self.gyro_compass_kf,
            HeadingSource::Compass => self.compass,
        }
    }
}

/// A step event with everything that was known about it: for calibration and evaluation,
/// which re-derive lengths and headings under other models without re-running the pipeline.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StepDetail {
    /// The emitted event.
    pub event: StepEvent,
    /// Features for the step-length models.
    pub features: StepFeatures,
    /// Heading of every source.
    pub headings: SourceHeadings,
    /// Accumulated heading rate over the step, `SGyr_k` (rad, clockwise positive).
    pub sgyr: f64,
}

/// Counters of input problems met so far (each is also logged at `debug`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct PdrDiagnostics {
    /// Samples with a NaN or infinite value, skipped.
    pub non_finite: usize,
    /// Samples whose time is not after the previous sample of the same stream, skipped.
    pub out_of_order: usize,
    /// Gaps in the accelerometer stream that reset the step detector.
    pub gaps: usize,
    /// Steps for which no heading source had a value (heading 0 was emitted).
    pub steps_without_heading: usize,
    /// Steps whose heading came from a fallback source instead of the configured one.
    pub steps_with_fallback_heading: usize,
    /// Compass observations rejected by the heading filter's gate.
    pub compass_rejected: usize,
    /// Steps rejected because the phone was being handled ([`crate::handling`]).
    pub steps_rejected_handling: usize,
}

#[derive(Debug, Clone, Copy, Default)]
struct HeadingTrack {
    latest: Option<f64>,
    sin: f64,
    cos: f64,
    n: u32,
}

impl HeadingTrack {
    #[inline]
    fn update(&mut self, h: f64) {
        if h.is_finite() {
            self.latest = Some(h);
            let (s, c) = h.sin_cos();
            self.sin += s;
            self.cos += c;
            self.n += 1;
        }
    }

    fn take(&mut self, at: HeadingAt) -> Option<f64> {
        let mean = (self.n > 0 && (self.sin.abs() > 1e-12 || self.cos.abs() > 1e-12))
            .then(|| self.sin.atan2(self.cos));
        self.sin = 0.0;
        self.cos = 0.0;
        self.n = 0;
        match at {
            HeadingAt::StepTime => self.latest,
            HeadingAt::StepMean => mean.or(self.latest),
        }
    }
}

/// Streaming pedestrian dead reckoning. Feed samples of each stream in time order (streams
/// may interleave arbitrarily); a step comes out of [`Pdr::push_accelerometer`].
///
/// Bad input, documented behaviour (never a panic):
/// - a sample with a NaN / infinite component: skipped, counted in `non_finite`;
/// - a sample not later than the previous one of its stream (repeated or backwards time):
///   skipped, counted in `out_of_order`;
/// - a gap longer than `detector.max_gap_s` in the accelerometer: the detector restarts
///   (no step spans the gap; the next step has no period and counts as after a stop);
///   a gyro gap longer than `heading.gyro.max_dt_s` is not integrated, and the gyro
///   attitude restarts from the next absolute orientation;
/// - no gyroscope: `Gyro` and `GyroCompassKf` headings are unavailable (the KF runs on the
///   compass alone with zero input), `SGyr` is the step's change of the emitted heading;
/// - no magnetometer: `Compass` is unavailable, the KF starts from the gyro attitude's
///   heading and runs on the gyro alone;
/// - no rotation vector: the gyro attitude starts from the compass, else from gravity with
///   heading 0;
/// - the configured source has no value at a step: the first source of
///   [`HeadingSource::ALL`] that has one is used (`steps_with_fallback_heading`); if none
///   has, heading 0 (`steps_without_heading`).
#[derive(Debug, Clone)]
pub struct Pdr {
    cfg: PdrConfig,
    detector: StepDetector,
    gyro_att: GyroAttitude,
    kf: HeadingKf,
    vertical: VerticalZupt,
    stationary: StationaryDetector,
    rv: Option<UnitQuaternion<f64>>,
    acc: Option<[f64; 3]>,
    mag: Option<[f64; 3]>,
    last_acc_t: Option<TimestampMs>,
    last_gyro_t: Option<TimestampMs>,
    last_mag_t: Option<TimestampMs>,
    last_rv_t: Option<TimestampMs>,
    last_rate: Option<f64>,
    tracks: [HeadingTrack; 4],
    sgyr: f64,
    sgyr_prev: f64,
    emitted_heading_at_last_step: Option<f64>,
    prev_heading: Option<f64>,
    prev_variance: Option<f64>,
    prev_period: Option<f64>,
    handling: crate::handling::HandlingGate,
    snap: crate::snap::HeadingSnap,
    diag: PdrDiagnostics,
}

fn finite3(v: &[f64; 3]) -> bool {
    v.iter().all(|c| c.is_finite())
}

impl Pdr {
    /// A pipeline at rest, on a checked config ([`PdrConfig::check`]).
    pub fn new(cfg: CheckedPdrConfig) -> Self {
        let cfg = cfg.into_inner();
        Self {
            detector: StepDetector::new(cfg.detector),
            gyro_att: GyroAttitude::new(cfg.heading.gyro),
            kf: HeadingKf::new(cfg.heading.kf),
            vertical: VerticalZupt::new(cfg.vertical),
            stationary: StationaryDetector::new(cfg.motion),
            cfg,
            rv: None,
            acc: None,
            mag: None,
            last_acc_t: None,
            last_gyro_t: None,
            last_mag_t: None,
            last_rv_t: None,
            last_rate: None,
            tracks: [HeadingTrack::default(); 4],
            sgyr: 0.0,
            sgyr_prev: 0.0,
            emitted_heading_at_last_step: None,
            prev_heading: None,
            prev_variance: None,
            prev_period: None,
            handling: crate::handling::HandlingGate::default(),
            snap: crate::snap::HeadingSnap::default(),
            diag: PdrDiagnostics::default(),
        }
    }

    /// The configuration.
    pub fn config(&self) -> &PdrConfig {
        &self.cfg
    }

    /// Input problems met so far.
    pub fn diagnostics(&self) -> PdrDiagnostics {
        PdrDiagnostics {
            gaps: self.detector.resets(),
            compass_rejected: self.kf.rejected(),
            ..self.diag
        }
    }

    /// Whether the walker is standing still now (paper 002 §3.2.1).
    pub fn is_stationary(&self) -> bool {
        self.stationary.is_stationary()
    }

    /// Checks a sample's time against the stream's last; counts and rejects bad ones.
    fn accept(
        diag: &mut PdrDiagnostics,
        last: &mut Option<TimestampMs>,
        t: TimestampMs,
        ok: bool,
    ) -> bool {
        if !ok {
            diag.non_finite += 1;
            tracing::debug!(t, "non-finite IMU sample skipped");
            return false;
        }
        if last.is_some_and(|l| t <= l) {
            diag.out_of_order += 1;
            tracing::debug!(t, "repeated or backwards IMU timestamp skipped");
            return false;
        }
        *last = Some(t);
        true
    }

    fn offset(&self, h: f64) -> f64 {
        wrap_pi(h + self.cfg.heading.map_offset_rad)
    }

    /// The orientation used for the vertical acceleration and the heading rate: the
    /// rotation vector when there is one, else the gyro attitude.
    fn reference_orientation(&self) -> Option<UnitQuaternion<f64>> {
        self.rv.or_else(|| self.gyro_att.orientation().copied())
    }

    /// Feeds a rotation-vector sample.
    pub fn push_rotation_vector(&mut self, s: &RotationVectorSample) {
        if !Self::accept(&mut self.diag, &mut self.last_rv_t, s.t, finite3(&s.v)) {
            return;
        }
        if let Some(q) = rotation_vector_quaternion(s.v) {
            self.rv = Some(q);
            self.tracks[0].update(heading_of(&q));
        }
    }

    /// Feeds a magnetometer sample (µT).
    pub fn push_magnetometer(&mut self, s: &Vec3Sample) {
        if !Self::accept(&mut self.diag, &mut self.last_mag_t, s.t, finite3(&s.v)) {
            return;
        }
        self.mag = Some(s.v);
        let Some(acc) = self.acc else { return };
        let Some(q) = compass_orientation(acc, s.v) else {
            return;
        };
        let h = heading_of(&q);
        self.tracks[3].update(h);
        if self.kf.is_initialised() {
            self.kf.update(h);
        } else {
            self.kf.initialise(h, self.last_rate.unwrap_or(0.0));
        }
        if self.kf.is_initialised() {
            let a = self.kf.angle().unwrap_or(h);
            self.tracks[2].update(a);
        }
    }

    /// Feeds a gyroscope sample (rad/s).
    pub fn push_gyroscope(&mut self, s: &Vec3Sample) {
        let last = self.last_gyro_t;
        if !Self::accept(&mut self.diag, &mut self.last_gyro_t, s.t, finite3(&s.v)) {
            return;
        }
        if !self.gyro_att.is_initialised() {
            let init = self
                .rv
                .or_else(|| {
                    self.acc
                        .zip(self.mag)
                        .and_then(|(a, m)| compass_orientation(a, m))
                })
                .or_else(|| self.acc.and_then(gravity_orientation));
            if let Some(q) = init {
                self.gyro_att.initialise(q);
            }
        }
        self.handling.push_vector(s.t, s.v, &self.cfg.handling);
        self.gyro_att.integrate(s.t, s.v, self.acc);
        if let Some(q) = self.gyro_att.orientation() {
            self.tracks[1].update(heading_of(q));
        }
        let Some(reference) = self.reference_orientation() else {
            return;
        };
        let rate = heading_rate(&reference, s.v);
        let dt = last.map(|l| (s.t - l) as f64 / 1000.0);
        match dt {
            Some(dt) if dt > 0.0 && dt <= self.cfg.heading.gyro.max_dt_s => {
                self.sgyr += rate * dt;
                if !self.kf.is_initialised()
                    && self.mag.is_none()
                    && let Some(q) = self.gyro_att.orientation()
                {
                    self.kf.initialise(heading_of(q), rate);
                }
                let u = self.last_rate.map_or(0.0, |r| (rate - r) / dt);
                self.kf.predict(dt, u);
                if let Some(a) = self.kf.angle() {
                    self.tracks[2].update(a);
                }
            }
            _ => {}
        }
        self.last_rate = Some(rate);
    }

    /// Feeds an accelerometer sample (m/s²); returns a step when one is detected here.
    pub fn push_accelerometer(&mut self, s: &Vec3Sample) -> Option<StepEvent> {
        self.push_accelerometer_detailed(s).map(|d| d.event)
    }

    /// As [`Pdr::push_accelerometer`], with the step's features and every source's heading.
    pub fn push_accelerometer_detailed(&mut self, s: &Vec3Sample) -> Option<StepDetail> {
        if !Self::accept(&mut self.diag, &mut self.last_acc_t, s.t, finite3(&s.v)) {
            return None;
        }
        self.acc = Some(s.v);
        let magnitude = s.norm();
        self.stationary.push(s.t, magnitude);
        if let Some(q) = self.reference_orientation() {
            let up = (q * Vector3::from(s.v)).z;
            self.vertical.push(s.t, up);
        }
        let resets_before = self.detector.resets();
        let candidate = self.detector.push(s.t, magnitude);
        if self.detector.resets() != resets_before {
            self.stationary.reset();
            self.prev_period = None;
        }
        let candidate = candidate?;
        if self.handling.handling(&self.cfg.handling) {
            self.diag.steps_rejected_handling += 1;
            return None;
        }
        Some(self.make_step(candidate))
    }

    fn make_step(&mut self, c: StepCandidate) -> StepDetail {
        let cfg = self.cfg;
        let period = c.period_s.unwrap_or(cfg.default_period_s);
        let mean_period = match (c.period_s, self.prev_period) {
            (Some(p), Some(q)) => 0.5 * (p + q),
            (Some(p), None) => p,
            _ => cfg.default_period_s,
        };
        let features = StepFeatures {
            period_s: period,
            mean_period_s: mean_period,
            acc_max: c.acc_max,
            acc_min: c.acc_min,
            peak_detrended: c.peak_detrended,
            acc_variance: c.acc_variance,
            prev_acc_variance: self.prev_variance.unwrap_or(c.acc_variance),
            first: c.period_s.is_none(),
            vertical_excursion: self.vertical.zupt(),
        };
        self.prev_variance = Some(c.acc_variance);
        self.prev_period = c.period_s;
        let raw = cfg.step_length.model().length(&features);
        let length = if raw.is_finite() {
            raw.max(cfg.min_step_length).min(cfg.max_step_length)
        } else {
            cfg.min_step_length
        };

        let at = cfg.heading.at;
        let mut raw_headings = [None; 4];
        for (slot, track) in raw_headings.iter_mut().zip(self.tracks.iter_mut()) {
            *slot = track.take(at);
        }
        let map = |h: Option<f64>| h.map(|h| self.offset(h));
        let headings = SourceHeadings {
            rotation_vector: map(raw_headings[0]),
            gyro: map(raw_headings[1]),
            gyro_compass_kf: map(raw_headings[2]),
            compass: map(raw_headings[3]),
        };
        let heading = match headings.get(cfg.heading.source) {
            Some(h) => h,
            None => match HeadingSource::ALL.iter().find_map(|s| headings.get(*s)) {
                Some(h) => {
                    self.diag.steps_with_fallback_heading += 1;
                    h
                }
                None => {
                    self.diag.steps_without_heading += 1;
                    tracing::debug!(t = c.t, "step without any heading: 0 emitted");
                    0.0
                }
            },
        };
        let heading = self.snap.apply(heading, &cfg.heading.snap);
        let heading_change = self.prev_heading.map_or(0.0, |p| diff(heading, p));
        // SGyr_k: the gyro's accumulated heading rate; without a gyro the heading change.
        let sgyr = if self.last_gyro_t.is_some() {
            std::mem::take(&mut self.sgyr)
        } else {
            self.emitted_heading_at_last_step
                .map_or(0.0, |p| diff(heading, p))
        };
        let turn = classify_turn(sgyr, self.sgyr_prev, &cfg.motion);
        self.sgyr_prev = sgyr;
        self.prev_heading = Some(heading);
        self.emitted_heading_at_last_step = Some(heading);
        let stopped = self.stationary.take_stop_since_last_step()
            || c.period_s.is_none_or(|p| p > cfg.motion.stop_gap_s);
        let event = StepEvent {
            t: c.t,
            length,
            heading,
            heading_change,
            period_s: period,
            motion: MotionState {
                turn,
                speed: classify_speed(period, &cfg.motion),
                stationary: stopped,
            },
            covariance: None,
        };
        StepDetail {
            event,
            features,
            headings,
            sgyr,
        }
    }

    /// Runs the pipeline over a whole walk (streams merged in time order; at equal times the
    /// rotation vector, gyroscope and magnetometer come before the accelerometer, so a step
    /// sees the orientation of its own instant). Returns every step with its details.
    pub fn run_detailed(cfg: CheckedPdrConfig, walk: &Walk) -> (Vec<StepDetail>, PdrDiagnostics) {
        let mut pdr = Pdr::new(cfg);
        let imu = &walk.imu;
        let (acc, gyr, mag, rv) = (
            &imu.accelerometer,
            &imu.gyroscope,
            &imu.magnetometer,
            &imu.rotation_vector,
        );
        let (mut ia, mut ig, mut im, mut ir) = (0usize, 0usize, 0usize, 0usize);
        let mut out = Vec::with_capacity(acc.len() / 20 + 1);
        loop {
            let ta = acc.get(ia).map_or(i64::MAX, |s| s.t);
            let tg = gyr.get(ig).map_or(i64::MAX, |s| s.t);
            let tm = mag.get(im).map_or(i64::MAX, |s| s.t);
            let tr = rv.get(ir).map_or(i64::MAX, |s| s.t);
            let t = ta.min(tg).min(tm).min(tr);
            if t == i64::MAX {
                break;
            }
            if tr == t {
                pdr.push_rotation_vector(&rv[ir]);
                ir += 1;
            } else if tg == t {
                pdr.push_gyroscope(&gyr[ig]);
                ig += 1;
            } else if tm == t {
                pdr.push_magnetometer(&mag[im]);
                im += 1;
            } else {
                if let Some(d) = pdr.push_accelerometer_detailed(&acc[ia]) {
                    out.push(d);
                }
                ia += 1;
            }
        }
        (out, pdr.diagnostics())
    }

    /// Runs the pipeline over a whole walk and returns its step events.
    ///
    /// ```
    /// use wipdr_pdr::{CheckedPdrConfig, Pdr};
    /// let walk = wipdr_core::Walk::default();
    /// assert!(Pdr::run(CheckedPdrConfig::default(), &walk).is_empty());
    /// ```
    pub fn run(cfg: CheckedPdrConfig, walk: &Walk) -> Vec<StepEvent> {
        Self::run_detailed(cfg, walk)
            .0
            .into_iter()
            .map(|d| d.event)
            .collect()
    }
}

#[cfg(test)]
mod config_tests {
    use super::*;

    #[test]
    fn bad_limits_are_named() {
        assert!(PdrConfig::default().validate().is_ok());
        assert!(PdrConfig::sample_code().validate().is_ok());
        let mut c = PdrConfig {
            min_step_length: 1.0,
            max_step_length: 0.5,
            ..PdrConfig::default()
        };
        assert_eq!(c.validate().unwrap_err().path, "max_step_length");
        c.max_step_length = f64::NAN;
        assert_eq!(c.validate().unwrap_err().path, "max_step_length");
        c.min_step_length = f64::NAN;
        assert_eq!(c.validate().unwrap_err().path, "min_step_length");
    }

    #[test]
    fn a_release_rate_above_the_gate_is_named() {
        let mut c = PdrConfig::default();
        c.handling.release_rad_s = Some(3.5);
        let e = c.validate().unwrap_err();
        assert_eq!(e.path, "handling.release_rad_s");
        assert!(e.reason.contains("3.5"), "{}", e.reason);
        c.handling.release_rad_s = Some(1.5);
        assert!(c.validate().is_ok());
        c.handling.release_rad_s = Some(f64::NAN);
        assert_eq!(c.validate().unwrap_err().path, "handling.release_rad_s");
        c.handling.release_rad_s = Some(-1.0);
        assert_eq!(c.validate().unwrap_err().path, "handling.release_rad_s");
        c.handling.release_rad_s = None;
        c.handling.release_hold_s = f64::INFINITY;
        assert_eq!(c.validate().unwrap_err().path, "handling.release_hold_s");
        c.handling.release_hold_s = 4.0;
        c.handling.max_axis_share = 0.0;
        assert_eq!(c.validate().unwrap_err().path, "handling.max_axis_share");
        c.handling.max_axis_share = 0.85;
        c.handling.tumbling_rad_s = Some(f64::NAN);
        assert_eq!(c.validate().unwrap_err().path, "handling.tumbling_rad_s");
        c.handling.tumbling_rad_s = Some(1.5);
        c.handling.axis_window_s = 0.0;
        assert_eq!(c.validate().unwrap_err().path, "handling.axis_window_s");
        // Gate off: a release is accepted (it is not used).
        c.handling = crate::handling::HandlingConfig::off();
        c.handling.release_rad_s = Some(2.0);
        assert!(c.validate().is_ok());
    }
}

//! Every parameter of the simulator, as serde structs whose `Default` is the documented model.
//!
//! All structs carry `#[serde(default)]`, so a TOML file may set only the fields it changes
//! (`wipdr simulate --config FILE.toml`).

use crate::SimError;
use serde::{Deserialize, Serialize};
use wipdr_core::ConfigError;

/// The whole simulator configuration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SimConfig {
    /// Floor name (the output folder name and the `FloorName` header).
    pub floor_name: String,
    /// Site name (the `SiteName` header).
    pub site_name: String,
    /// Number of walks.
    pub walks: usize,
    /// Duration of each walk, seconds (the walk length varies by `duration_jitter_s`).
    pub duration_s: f64,
    /// Uniform jitter of each walk's duration, seconds (`duration_s ± duration_jitter_s`).
    pub duration_jitter_s: f64,
    /// Probability that a Wi-Fi scan is replaced by a gross-error scan generated far away.
    pub gross_error_rate: f64,
    /// Unix time (ms) of the first walk's start; walk `i` starts `walk_spacing_s * i` later.
    pub start_time_ms: i64,
    /// Seconds between the starts of consecutive walks.
    pub walk_spacing_s: f64,
    /// Sampling rate of the true trajectory in the truth files, Hz.
    pub trajectory_rate_hz: f64,
    /// The floor layout.
    pub floor: FloorConfig,
    /// Access points and the radio propagation model.
    pub radio: RadioConfig,
    /// The phone's Wi-Fi scanning behaviour.
    pub scan: ScanConfig,
    /// The walker (gait, route, stops).
    pub walker: WalkerConfig,
    /// The IMU (sensor rate, phone pose, noise).
    pub imu: ImuConfig,
    /// The survey radio map (`train.csv`, `test.csv`).
    pub survey: SurveyConfig,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            floor_name: "F1".into(),
            site_name: "wipdr-sim mall".into(),
            walks: 10,
            duration_s: 90.0,
            duration_jitter_s: 30.0,
            gross_error_rate: 0.0,
            start_time_ms: 1_600_000_000_000,
            walk_spacing_s: 600.0,
            trajectory_rate_hz: 5.0,
            floor: FloorConfig::default(),
            radio: RadioConfig::default(),
            scan: ScanConfig::default(),
            walker: WalkerConfig::default(),
            imu: ImuConfig::default(),
            survey: SurveyConfig::default(),
        }
    }
}

impl SimConfig {
    /// Checks the values a generator divides by or samples from.
    pub fn validate(&self) -> Result<(), SimError> {
        let bad = |field: &'static str, why: &'static str| {
            Err(SimError::InvalidConfig(ConfigError::new(field, why)))
        };
        let positive = [
            ("duration_s", self.duration_s),
            ("trajectory_rate_hz", self.trajectory_rate_hz),
            ("walker.waypoint_spacing_m", self.walker.waypoint_spacing_m),
            ("floor.width_m", self.floor.width_m),
            ("floor.height_m", self.floor.height_m),
            ("floor.corridor_width_m", self.floor.corridor_width_m),
            ("floor.shop_width_m", self.floor.shop_width_m),
            ("radio.path_loss_exponent", self.radio.path_loss_exponent),
            (
                "radio.reference_distance_m",
                self.radio.reference_distance_m,
            ),
            (
                "radio.shadowing_correlation_m",
                self.radio.shadowing_correlation_m,
            ),
            ("scan.interval_s", self.scan.interval_s),
            ("scan.detection_slope_db", self.scan.detection_slope_db),
            (
                "walker.step_frequency_min_hz",
                self.walker.step_frequency_min_hz,
            ),
            ("walker.leg_length_min_m", self.walker.leg_length_min_m),
            ("imu.rate_hz", self.imu.rate_hz),
            ("survey.spacing_m", self.survey.spacing_m),
        ];
        for (field, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return bad(field, "must be finite and > 0");
            }
        }
        let probabilities = [
            ("gross_error_rate", self.gross_error_rate),
            (
                "radio.dual_band_probability",
                self.radio.dual_band_probability,
            ),
            (
                "radio.multipath_probability",
                self.radio.multipath_probability,
            ),
            ("radio.shop_ap_fraction", self.radio.shop_ap_fraction),
            (
                "scan.max_detection_probability",
                self.scan.max_detection_probability,
            ),
            (
                "walker.static_start_probability",
                self.walker.static_start_probability,
            ),
            ("walker.stop_probability", self.walker.stop_probability),
            ("imu.drop_probability", self.imu.drop_probability),
        ];
        for (field, p) in probabilities {
            if !(0.0..=1.0).contains(&p) {
                return bad(field, "must be a probability in [0, 1]");
            }
        }
        if !(self.duration_jitter_s >= 0.0 && self.duration_jitter_s < self.duration_s) {
            return bad("duration_jitter_s", "must be in [0, duration_s)");
        }
        if self.walker.step_frequency_max_hz < self.walker.step_frequency_min_hz {
            return bad(
                "walker.step_frequency_max_hz",
                "must be >= step_frequency_min_hz",
            );
        }
        if self.walker.leg_length_max_m < self.walker.leg_length_min_m {
            return bad("walker.leg_length_max_m", "must be >= leg_length_min_m");
        }
        if self.imu.timestamp_jitter_ms * 2.0 >= 1000.0 / self.imu.rate_hz {
            return bad(
                "imu.timestamp_jitter_ms",
                "must be under half the sample period",
            );
        }
        if self.radio.access_points == 0 {
            return bad("radio.access_points", "must be > 0");
        }
        if self.walks > 10_000 {
            return bad("walks", "at most 10000");
        }
        if self.duration_s > 7200.0 {
            return bad("duration_s", "at most 7200 s per walk");
        }
        Ok(())
    }
}

/// A mall-like floor: outer shop rows, corridors on a 3 x 3 grid and an open hall in the middle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FloorConfig {
    /// Floor width (x), metres.
    pub width_m: f64,
    /// Floor height (y), metres.
    pub height_m: f64,
    /// Corridor width, metres.
    pub corridor_width_m: f64,
    /// Target width of a shop along its row, metres (rows are split into equal shops).
    pub shop_width_m: f64,
    /// Hall extent in x as fractions of the width `[from, to]`.
    pub hall_x_fraction: [f64; 2],
    /// Corner rounding of the walked path at a junction: largest cut from the vertex, metres.
    pub corner_cut_m: f64,
    /// Largest random offset of the walked path from a corridor centre line, metres
    /// (must stay below half the corridor width).
    pub lane_offset_m: f64,
}

impl Default for FloorConfig {
    fn default() -> Self {
        Self {
            width_m: 120.0,
            height_m: 80.0,
            corridor_width_m: 5.0,
            shop_width_m: 15.0,
            hall_x_fraction: [0.355, 0.645],
            corner_cut_m: 1.5,
            lane_offset_m: 0.8,
        }
    }
}

/// Access points and the log-distance path-loss model
/// `RSS = P0 - 10 n log10(d / d0) - W * walls + S(p) + e`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RadioConfig {
    /// Number of access-point sites (each has a 2.4 GHz radio, some also 5 GHz).
    pub access_points: usize,
    /// Fraction of sites placed inside shops (the rest in corridors and the hall).
    pub shop_ap_fraction: f64,
    /// Probability that a site also has a 5 GHz BSSID.
    pub dual_band_probability: f64,
    /// Mean received power at the reference distance, 2.4 GHz, dBm (`P0`).
    pub p0_dbm: f64,
    /// Standard deviation of `P0` between access points, dB.
    pub p0_spread_db: f64,
    /// Extra loss of a 5 GHz radio against 2.4 GHz at the same distance, dB.
    pub band_5ghz_extra_loss_db: f64,
    /// Path-loss exponent `n`.
    pub path_loss_exponent: f64,
    /// Reference distance `d0`, metres.
    pub reference_distance_m: f64,
    /// Attenuation per crossed wall `W`, dB.
    pub wall_attenuation_db: f64,
    /// Largest total wall attenuation, dB (many walls saturate: signals go around).
    pub max_wall_attenuation_db: f64,
    /// Standard deviation of the spatially consistent log-normal shadowing `S(p)`, dB.
    pub shadowing_std_db: f64,
    /// Correlation length of the shadowing field, metres.
    pub shadowing_correlation_m: f64,
    /// Number of random Fourier features per access point that build the shadowing field.
    pub shadowing_features: usize,
    /// Standard deviation of the per-measurement fast fading `e`, dB.
    pub measurement_noise_db: f64,
    /// Probability that a measurement is a multipath outlier.
    pub multipath_probability: f64,
    /// Magnitude range of a multipath outlier `[min, max]`, dB (the sign is random).
    pub multipath_db: [f64; 2],
}

impl Default for RadioConfig {
    fn default() -> Self {
        Self {
            access_points: 48,
            shop_ap_fraction: 0.5,
            dual_band_probability: 0.6,
            p0_dbm: -38.0,
            p0_spread_db: 3.0,
            band_5ghz_extra_loss_db: 6.0,
            path_loss_exponent: 2.3,
            reference_distance_m: 1.0,
            wall_attenuation_db: 5.0,
            max_wall_attenuation_db: 25.0,
            shadowing_std_db: 4.0,
            shadowing_correlation_m: 5.0,
            shadowing_features: 16,
            measurement_noise_db: 2.5,
            multipath_probability: 0.02,
            multipath_db: [8.0, 20.0],
        }
    }
}

/// The phone's scanning: a scan every `interval_s`, results cached by the OS, so entries carry
/// a last-seen time seconds before the scan time (median age 3-4 s in the real data).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ScanConfig {
    /// Mean time between scans, seconds.
    pub interval_s: f64,
    /// Uniform jitter of the interval, seconds (`interval_s ± interval_jitter_s`).
    pub interval_jitter_s: f64,
    /// Time from the end of a channel sweep to the delivery of the results, seconds.
    pub report_latency_s: f64,
    /// Duration of one channel sweep, seconds: a channel is heard somewhere in it.
    pub sweep_duration_s: f64,
    /// Receiver sensitivity floor, dBm: weaker signals are never reported.
    pub sensitivity_dbm: f64,
    /// Highest per-sweep detection probability of an access point well above the floor.
    pub max_detection_probability: f64,
    /// Width of the logistic detection curve above the floor, dB.
    pub detection_slope_db: f64,
    /// Distance above the floor where detection reaches half its maximum, dB.
    pub detection_midpoint_db: f64,
    /// Cached entries older than this are no longer reported, seconds.
    pub cache_ttl_s: f64,
    /// Sweeps made before the walk starts (the phone was already scanning), at the start point.
    pub warmup_sweeps: usize,
    /// Scans at the start of a walk that are never replaced by gross errors.
    pub gross_error_grace_scans: usize,
    /// Smallest distance of a gross-error scan's position from the true position, metres.
    pub gross_error_min_distance_m: f64,
}

impl Default for ScanConfig {
    fn default() -> Self {
        Self {
            interval_s: 2.0,
            interval_jitter_s: 0.4,
            report_latency_s: 0.8,
            sweep_duration_s: 2.5,
            sensitivity_dbm: -95.0,
            max_detection_probability: 0.8,
            detection_slope_db: 2.0,
            detection_midpoint_db: 4.0,
            cache_ttl_s: 30.0,
            warmup_sweeps: 3,
            gross_error_grace_scans: 2,
            gross_error_min_distance_m: 40.0,
        }
    }
}

/// The walker: gait (step frequency and length), route choice and stops.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WalkerConfig {
    /// Lowest per-walker cadence, steps per second.
    pub step_frequency_min_hz: f64,
    /// Highest per-walker cadence, steps per second.
    pub step_frequency_max_hz: f64,
    /// Step length model `l = scale * (a + b f)` with cadence `f`: intercept `a`, metres.
    pub step_length_intercept_m: f64,
    /// Step length model slope `b`, metres per Hz.
    pub step_length_slope_m_per_hz: f64,
    /// Per-walker step-length scale range `[min, max]`.
    pub step_length_scale: [f64; 2],
    /// Relative per-step standard deviation of the step period.
    pub step_period_jitter: f64,
    /// Relative per-step standard deviation of the step length.
    pub step_length_jitter: f64,
    /// Relative per-step standard deviation of the vertical acceleration amplitude (the
    /// vigour of a step, independent of its length).
    pub bounce_amplitude_jitter: f64,
    /// Cadence factor of a slow leg.
    pub slow_factor: f64,
    /// Cadence factor of a fast leg.
    pub fast_factor: f64,
    /// Probability that a leg (between two junctions) is walked slowly; the same for fast.
    pub slow_fast_probability: f64,
    /// Leg length range of the inverted pendulum `[min, max]`, metres (paper 004 eq. 6): sets
    /// the vertical bounce `h = L - sqrt(L² - (l/2)²)` of a step of length `l`.
    pub leg_length_min_m: f64,
    /// See `leg_length_min_m`.
    pub leg_length_max_m: f64,
    /// Probability that a walk starts with the walker standing still (paper 001 §3.2).
    pub static_start_probability: f64,
    /// Range of a standing period, seconds `[min, max]`.
    pub stop_duration_s: [f64; 2],
    /// Probability of a stop when passing a junction.
    pub stop_probability: f64,
    /// Turns at least this large (degrees) are recorded as turn events in the truth.
    pub min_turn_deg: f64,
    /// Largest turn the route takes at a junction, degrees (no U-turns).
    pub max_turn_deg: f64,
    /// Turns in this band `[lo, hi]` (degrees) are avoided when the junction offers another
    /// way: they are neither clearly straight nor clearly a turn, which would make the
    /// turn-detection truth ambiguous.
    pub avoid_turn_deg: [f64; 2],
    /// A waypoint is labelled about every this many metres, and at every turn.
    pub waypoint_spacing_m: f64,
    /// Standard deviation of the surveyor's labelling error of a waypoint, metres.
    pub waypoint_noise_m: f64,
}

impl Default for WalkerConfig {
    fn default() -> Self {
        Self {
            step_frequency_min_hz: 1.6,
            step_frequency_max_hz: 2.0,
            step_length_intercept_m: 0.3,
            step_length_slope_m_per_hz: 0.22,
            step_length_scale: [0.9, 1.1],
            step_period_jitter: 0.03,
            step_length_jitter: 0.03,
            bounce_amplitude_jitter: 0.12,
            slow_factor: 0.85,
            fast_factor: 1.12,
            slow_fast_probability: 0.15,
            leg_length_min_m: 0.85,
            leg_length_max_m: 0.95,
            static_start_probability: 0.5,
            stop_duration_s: [2.0, 5.0],
            stop_probability: 0.12,
            min_turn_deg: 30.0,
            max_turn_deg: 135.0,
            avoid_turn_deg: [10.0, 50.0],
            waypoint_spacing_m: 8.0,
            waypoint_noise_m: 0.0,
        }
    }
}

/// The IMU: a phone held flat in front, screen up, top pointing forward.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ImuConfig {
    /// Nominal sampling rate of every stream, Hz.
    pub rate_hz: f64,
    /// Uniform timestamp jitter, milliseconds (`± timestamp_jitter_ms`).
    pub timestamp_jitter_ms: f64,
    /// Probability that a sample is dropped.
    pub drop_probability: f64,
    /// Gravity, m/s².
    pub gravity: f64,
    /// Range of the phone's pitch (top raised), degrees `[min, max]`, per walk.
    pub pitch_deg: [f64; 2],
    /// Standard deviation of the phone's roll, degrees, per walk.
    pub roll_std_deg: f64,
    /// Standard deviation of the phone's yaw misalignment against the walking direction,
    /// degrees, per walk.
    pub yaw_misalignment_std_deg: f64,
    /// Amplitude of the body's yaw sway at stride frequency (half the step frequency), degrees.
    pub yaw_sway_deg: f64,
    /// Amplitude of the phone's pitch bounce at step frequency, degrees.
    pub pitch_bounce_deg: f64,
    /// Amplitude of the lateral sway acceleration at stride frequency, m/s².
    pub lateral_sway_accel: f64,
    /// Range of the per-walk gain between the body's bounce and the phone's vertical
    /// acceleration `[min, max]` (the arm damps or amplifies it): step length is not read off
    /// the acceleration amplitude exactly, and needs calibration per walker.
    pub bounce_gain: [f64; 2],
    /// Forward acceleration amplitude as a fraction of the vertical one.
    pub forward_accel_ratio: f64,
    /// Weight of the second harmonic (heel strike) in the vertical displacement.
    pub vertical_second_harmonic: f64,
    /// Accelerometer white noise, m/s².
    pub accel_noise: f64,
    /// Standard deviation of the hand's jitter acceleration (a first-order Gauss-Markov
    /// process on each phone axis), m/s².
    pub hand_jitter_accel: f64,
    /// Correlation time of the hand's jitter, seconds.
    pub hand_jitter_time_s: f64,
    /// Gyroscope white noise, rad/s.
    pub gyro_noise: f64,
    /// Standard deviation of the per-walk gyroscope bias on each axis, rad/s.
    pub gyro_bias_std: f64,
    /// Magnetometer white noise, µT.
    pub mag_noise: f64,
    /// Earth field in the magnetic East-North-Up frame, µT.
    pub earth_field_ut: [f64; 3],
    /// Number of local magnetic disturbances (steel near walls).
    pub mag_disturbances: usize,
    /// Largest disturbance amplitude, µT.
    pub mag_disturbance_ut: f64,
    /// Radius (standard deviation of the Gaussian fall-off) of a disturbance, metres.
    pub mag_disturbance_radius_m: f64,
    /// The compass azimuth equals the map heading plus this offset, degrees (map frame
    /// against magnetic north).
    pub map_to_magnetic_deg: f64,
    /// Rotation vector: standard deviation of its slowly drifting yaw error, degrees.
    pub rotation_vector_drift_deg: f64,
    /// Rotation vector: correlation time of the yaw error, seconds.
    pub rotation_vector_drift_time_s: f64,
    /// Rotation vector: fraction of the local magnetic disturbance's heading error that its
    /// fusion passes on (indoor anomalies pull the phone's heading).
    pub rotation_vector_mag_coupling: f64,
    /// Rotation vector: white noise on each component's angle, degrees.
    pub rotation_vector_noise_deg: f64,
    /// Also write the uncalibrated streams (larger files).
    pub uncalibrated: bool,
    /// Quantum of written accelerometer values (sensor resolution), m/s².
    pub accel_quantum: f64,
    /// Quantum of written gyroscope values, rad/s.
    pub gyro_quantum: f64,
    /// Quantum of written magnetometer values, µT.
    pub mag_quantum: f64,
    /// Quantum of written rotation-vector components.
    pub rotation_vector_quantum: f64,
}

impl Default for ImuConfig {
    fn default() -> Self {
        Self {
            rate_hz: 50.0,
            timestamp_jitter_ms: 3.0,
            drop_probability: 0.002,
            gravity: 9.80665,
            pitch_deg: [5.0, 25.0],
            roll_std_deg: 3.0,
            yaw_misalignment_std_deg: 2.0,
            yaw_sway_deg: 2.0,
            pitch_bounce_deg: 1.0,
            lateral_sway_accel: 0.5,
            bounce_gain: [0.75, 1.25],
            forward_accel_ratio: 0.35,
            vertical_second_harmonic: 0.05,
            accel_noise: 0.12,
            hand_jitter_accel: 0.3,
            hand_jitter_time_s: 0.08,
            gyro_noise: 0.01,
            gyro_bias_std: 0.003,
            mag_noise: 0.6,
            earth_field_ut: [0.0, 30.0, -35.0],
            mag_disturbances: 14,
            mag_disturbance_ut: 15.0,
            mag_disturbance_radius_m: 3.0,
            map_to_magnetic_deg: 0.0,
            rotation_vector_drift_deg: 3.0,
            rotation_vector_drift_time_s: 20.0,
            rotation_vector_mag_coupling: 0.15,
            rotation_vector_noise_deg: 0.3,
            uncalibrated: false,
            accel_quantum: 0.001,
            gyro_quantum: 0.0001,
            mag_quantum: 0.01,
            rotation_vector_quantum: 0.000001,
        }
    }
}

/// The survey radio map: fingerprints on a grid along the corridors and in the hall.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SurveyConfig {
    /// Spacing of survey points along corridor centre lines and in the hall, metres.
    pub spacing_m: f64,
    /// Scans averaged per survey point.
    pub samples_per_point: usize,
    /// Number of held-out test points (single scans at random walkable positions).
    pub test_points: usize,
}

impl Default for SurveyConfig {
    fn default() -> Self {
        Self {
            spacing_m: 2.0,
            samples_per_point: 4,
            test_points: 120,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_is_valid_and_toml_roundtrips() {
        let c = SimConfig::default();
        c.validate().unwrap();
        let partial: SimConfig =
            toml::from_str("walks = 3\n[radio]\nwall_attenuation_db = 7.0\n").unwrap();
        assert_eq!(partial.walks, 3);
        assert_eq!(partial.radio.wall_attenuation_db, 7.0);
        assert_eq!(partial.radio.p0_dbm, c.radio.p0_dbm);
    }

    #[test]
    fn invalid_values_are_named() {
        let mut c = SimConfig::default();
        c.scan.interval_s = 0.0;
        assert!(matches!(
            c.validate(),
            Err(SimError::InvalidConfig(e)) if e.path == "scan.interval_s"
        ));
        let c = SimConfig {
            gross_error_rate: 1.5,
            ..SimConfig::default()
        };
        assert!(matches!(
            c.validate(),
            Err(SimError::InvalidConfig(e)) if e.path == "gross_error_rate"
        ));
        let mut c = SimConfig::default();
        c.imu.timestamp_jitter_ms = 15.0;
        assert!(c.validate().is_err());
    }
}

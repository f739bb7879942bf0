//! # wipdr-core — the vocabulary every wipdr crate shares
//!
//! Plain data, no I/O: 2D points in metres ([`Point2`]), Unix time in milliseconds
//! ([`TimestampMs`]), IMU samples as Android's `SensorEvent.values` ([`imu`]), Wi-Fi scans
//! ([`wifi`]), surveyed waypoints, whole recorded [`Walk`]s with time-sorted streams and a
//! merged time-ordered replay, floor plans with walls ([`floor`]), and the two seams of the
//! system: PDR [`StepEvent`]s and Wi-Fi [`WifiObservation`]s (papers 000 §2-3, 001 §2-3,
//! 002 §3-4, 004 §4: the inputs every fusion scheme consumes), and the IPIN competition's
//! scoring records ([`evaal`]).
//!
//! ## Conventions
//!
//! - Frame: `x` east (map right), `y` north (map up), metres.
//! - Heading `psi` is measured clockwise from `+y`; a step of length `l` moves
//!   `(l sin psi, l cos psi)` (see [`angle::step_displacement`]).
//! - Angles in radians; differences wrap to `(-pi, pi]` ([`angle::wrap_pi`]).
//!
//! ```
//! use wipdr_core::{angle, Point2};
//! let d = angle::step_displacement(0.75, std::f64::consts::FRAC_PI_2); // a step due east
//! let p = Point2::new(1.0, 2.0) + d;
//! assert!((p.x - 1.75).abs() < 1e-12 && (p.y - 2.0).abs() < 1e-12);
//! ```

pub mod angle;
pub mod error;
pub mod evaal;
pub mod fingerprint_table;
pub mod fit;
pub mod floor;
pub mod geo;
pub mod grid;
pub mod imu;
pub mod likelihood_grid;
pub mod observation;
pub mod off;
pub mod stats;
pub mod step;
pub mod survey;
pub mod walk;
pub mod wifi;

pub use error::{ConfigError, CoreError};
pub use evaal::{EvaalEstimate, EvaalTruthPoint};
pub use fingerprint_table::{FingerprintLabel, FingerprintTable};
pub use floor::{FloorPlan, Polygon, Segment, Unit};
pub use geo::GeoFrame;
pub use grid::{GridError, GridSpec};
pub use imu::{ImuStreams, RotationVectorSample, UncalibratedSample, Vec3Sample};
pub use likelihood_grid::WifiLikelihood;
pub use observation::{Candidate, WifiObservation};
pub use step::{MotionState, SpeedClass, StepEvent, TurnState};
pub use survey::Floor;
pub use walk::{BeaconSample, PressureSample, Record, Walk, WalkMeta, Waypoint};
pub use wifi::{Bssid, WifiEntry, WifiScan};

/// A point in the floor's metric frame (`x` east / map right, `y` north / map up), metres.
pub type Point2 = nalgebra::Point2<f64>;
/// A displacement in the floor's metric frame, metres.
pub type Vector2 = nalgebra::Vector2<f64>;
/// Unix time in milliseconds, as in the ILC 2.0 traces.
pub type TimestampMs = i64;

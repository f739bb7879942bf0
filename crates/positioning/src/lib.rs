//! # wipdr-positioning — the online pipeline users run
//!
//! A [`Positioner`] takes a phone's raw samples one at a time, in time order
//! (accelerometer, gyroscope, magnetometer, rotation vector, pressure, Wi-Fi scans) and
//! answers the current [`PositionEstimate`] (time, position, floor when known, covariance
//! where the scheme has one). It owns the three seams of the system, built from one serde
//! [`PositionerConfig`]:
//!
//! - the PDR (`wipdr-pdr`: step detection, step length, heading, motion state; papers 000-004),
//! - a stream matcher (`wipdr-fingerprint`'s [`wipdr_fingerprint::OnlineMatcher`]: WKNN,
//!   cluster search, the AP index with dynamic thresholds, MED over the scan history; papers
//!   001 §2.3, 002 §3.2, 004 eq. 11), fed what it needs from the PDR (motion state,
//!   displacement since the previous scan),
//! - a fuser (`wipdr-fusion`: every scheme behind the `Fuser` trait), wrapped in the static
//!   start and map matching where configured;
//! - where the radio map has floors, a [`FloorTracker`] (Wi-Fi majority floor of each fix and
//!   the barometer's pressure changes, a Bayes filter over the map's floors): estimates carry
//!   its floor and each fix is restricted to its candidates on that floor
//!   ([`wipdr_core::WifiObservation::on_floor`]).
//!
//! The evaluation (`wipdr-eval`), `wipdr locate` and the Python package all run this
//! pipeline, so a figure in a results table is what a user's own stream gets. To compare
//! schemes over one recording, [`replay`] runs the scheme-independent [`Frontend`] once and
//! replays what it recorded through each scheme (the same estimates as a `Positioner` per
//! scheme; the evaluation runs its thirteen schemes so). Recorded walks
//! are streamed by [`samples_of`] in the one documented order (time, then
//! [`Sample::tie_rank`]).
//!
//! ```
//! use std::sync::Arc;
//! use wipdr_core::{Bssid, Point2, WifiEntry, WifiScan};
//! use wipdr_positioning::{Positioner, PositionerConfig, Site};
//!
//! // A radio map from a user's own survey: ten points along a corridor, two APs.
//! let map = Arc::new(wipdr_fingerprint::RadioMap::from_records((0..10).map(|i| {
//!     let x = f64::from(i);
//!     (Point2::new(x, 0.0), vec![(Bssid(1), -40.0 - 4.0 * x), (Bssid(2), -76.0 + 4.0 * x)])
//! }), Default::default())?);
//! let config = PositionerConfig::default(); // shared-AP WKNN, default PDR, `ekf`
//! let matcher = config.matcher.build(map.clone())?;
//! let mut positioner = Positioner::from_parts(&matcher, &Site::new(None, &map), &config, None)?;
//! for k in 0..200 { // ten seconds at 20 Hz
//!     let t = 50 * k;
//!     positioner.push_rotation_vector(t, [0.0, 0.0, 0.0]);
//!     positioner.push_accelerometer(t, [0.0, 0.0, 9.81 + 3.0 * (t as f64 * 0.0126).sin()]);
//!     if k % 40 == 0 {
//!         let heard = vec![WifiEntry::new(Bssid(1), -48.0), WifiEntry::new(Bssid(2), -68.0)];
//!         positioner.push_scan(WifiScan { t, entries: heard });
//!     }
//! }
//! let estimate = positioner.estimate().expect("a fix was matched");
//! assert_eq!(positioner.counts().scans, 5);
//! assert!(estimate.position.x.is_finite() && estimate.sd_m().is_some());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod config;
pub mod error;
pub mod estimate;
pub mod floor_tracker;
pub mod merge;
pub mod positioner;
pub mod replay;
pub mod sample;
pub mod site;
pub mod site_model;
pub mod smooth;
pub mod track_format;

pub use config::PositionerConfig;
pub use error::PositioningError;
pub use estimate::PositionEstimate;
pub use floor_tracker::{
    FloorConfig, FloorTracker, HPA_PER_METRE, PressureReference, StreamIdentity,
};
pub use positioner::{Frontend, Positioner, StreamCounts, track_of};
pub use sample::{PressureSample, Sample, samples_of};
pub use site::{Site, WALKABLE_CELL_M, stream_seed};
pub use site_model::{SiteConfig, SiteModel, SiteModelError, StreamSpec, TrainingData};

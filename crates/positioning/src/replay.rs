//! One recorded stream, many schemes: the front end's half of the pipeline run once
//! ([`Frontend::record`]: raw samples in, motion events, Wi-Fi fixes and the floor estimate
//! out), then each scheme's fusion replayed over what it recorded ([`replay_scheme`]).
//!
//! The front end (PDR, stream matcher, floor estimate) does not depend on the fusion scheme,
//! and it is most of a stream's cost; a user comparing schemes over one recording, as the
//! evaluation does for every test walk, records once and replays per scheme. A replay gives
//! the same estimates, bit for bit, as a [`Positioner`](crate::Positioner) with that scheme
//! streamed the same samples ([`track_of`](crate::track_of)): the same events reach the same
//! fuser in the same order (a step before a fix of the same millisecond,
//! [`wipdr_fusion::replay`]).
//!
//! ```
//! use std::sync::Arc;
//! use wipdr_core::{Bssid, WifiEntry, WifiScan};
//! use wipdr_fusion::SchemeConfig;
//! use wipdr_positioning::replay::replay_scheme;
//! use wipdr_positioning::{Frontend, Positioner, PositionerConfig, Sample, Site, track_of};
//!
//! let map = Arc::new(wipdr_fingerprint::RadioMap::from_records((0..10).map(|i| {
//!     let x = f64::from(i);
//!     (wipdr_core::Point2::new(x, 0.0),
//!      vec![(Bssid(1), -40.0 - 4.0 * x), (Bssid(2), -76.0 + 4.0 * x)])
//! }), Default::default())?);
//! let config = PositionerConfig::default();
//! let matcher = config.matcher.build(map.clone())?;
//! let site = Site::new(None, &map);
//! // Ten seconds of a phone at 20 Hz, a scan every two seconds.
//! let mut samples = Vec::new();
//! for k in 0..200 {
//!     let t = 50 * k;
//!     samples.push(Sample::RotationVector(wipdr_core::RotationVectorSample { t, v: [0.0; 3], accuracy: 3 }));
//!     let z = 9.81 + 3.0 * (t as f64 * 0.0126).sin();
//!     samples.push(Sample::Accelerometer(wipdr_core::Vec3Sample { t, v: [0.0, 0.0, z], accuracy: 3 }));
//!     if k % 40 == 0 {
//!         let heard = vec![WifiEntry::new(Bssid(1), -48.0), WifiEntry::new(Bssid(2), -68.0)];
//!         samples.push(Sample::Wifi(WifiScan { t, entries: heard }));
//!     }
//! }
//! // The front end once ...
//! let mut frontend = Frontend::new(config.pdr.check()?, matcher.stream(config.query));
//! let recorded = frontend.record(samples.iter().cloned());
//! assert_eq!(recorded.fixes.len(), 5);
//! // ... then every scheme over what it recorded: what a Positioner with that scheme gives.
//! for name in ["ekf", "rof", "pf"] {
//!     let scheme = SchemeConfig::default_for(name)?;
//!     let track = replay_scheme(&site, &scheme, &config, config.seed, None, &recorded.steps,
//!                        &recorded.fixes)?;
//!     let own = PositionerConfig { scheme: scheme.clone(), ..config.clone() };
//!     let mut positioner = Positioner::from_parts(&matcher, &site, &own, None)?;
//!     assert_eq!(track, track_of(&mut positioner, samples.iter().cloned(), None), "{name}");
//! }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use crate::positioner::{Event, FusionStage};
use crate::{Frontend, PositionEstimate, PositionerConfig, PositioningError, Sample, Site};
use wipdr_core::{Point2, StepEvent, TimestampMs, WifiObservation};
use wipdr_fusion::SchemeConfig;

/// What a [`Frontend`] made of a stream ([`Frontend::record`]): the fusion inputs of every
/// scheme, and the floor estimate, which is the front end's and scheme-independent.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Recorded {
    /// Motion events in time order: PDR steps, or with `odometry = "learned"` the learned
    /// displacements ([`StepEvent::covariance`]).
    pub steps: Vec<StepEvent>,
    /// Matched Wi-Fi scans in time order (restricted to the stream's floor where the map has
    /// floors; fixes with no candidate there are dropped and counted,
    /// [`StreamCounts::off_floor_fixes`](crate::StreamCounts::off_floor_fixes)).
    pub fixes: Vec<WifiObservation>,
    /// The stream's floor estimate, `(time of the sample, floor)` at each change (empty when
    /// the radio map has no floors).
    pub floors: Vec<(TimestampMs, i32)>,
}

impl Frontend {
    /// Streams `samples` (in time order, as [`samples_of`](crate::samples_of) gives a recorded
    /// walk's) through the front end and keeps what it made: the scheme-independent half of a
    /// [`Positioner`](crate::Positioner), to be replayed through any number of schemes
    /// ([`replay_scheme`]). [`Frontend::counts`] tells what it received and dropped.
    pub fn record(&mut self, samples: impl IntoIterator<Item = Sample>) -> Recorded {
        let mut out = Recorded::default();
        for sample in samples {
            let t = sample.t();
            match self.push(&sample) {
                Some(Event::Step(s)) => out.steps.push(s),
                Some(Event::Fix(o)) => out.fixes.push(o),
                None => {}
            }
            if let Some(f) = self.floor()
                && out.floors.last().is_none_or(|&(_, last)| last != f)
            {
                out.floors.push((t, f));
            }
        }
        out
    }
}

/// The track of `scheme` over a recorded stream's motion events and fixes (each sorted by
/// time, as [`Frontend::record`] gives them): the estimate after every input that gave one,
/// stamped with that input's time, as [`track_of`](crate::track_of) gives it for a
/// [`Positioner`](crate::Positioner) built with `scheme` on `site` under `config` (its static
/// start and map matching) and seeded with `seed`.
///
/// With a known `start` `(time, position)` (e.g. dead reckoning from a surveyed point), the
/// scheme starts there, the static start is not applied, the track opens with the start's
/// estimate at its time and the inputs before that time are not fed.
pub fn replay_scheme(
    site: &Site,
    scheme: &SchemeConfig,
    config: &PositionerConfig,
    seed: u64,
    start: Option<(TimestampMs, Point2)>,
    steps: &[StepEvent],
    fixes: &[WifiObservation],
) -> Result<Vec<PositionEstimate>, PositioningError> {
    let mut stage = FusionStage::with_scheme(site, scheme, config, seed, start.map(|s| s.1))?;
    let mut track = Vec::with_capacity(steps.len() + fixes.len() + 1);
    if let (Some((t, _)), Some(e)) = (start, stage.estimate()) {
        track.push(PositionEstimate { t, ..e });
    }
    track.extend(stage.replay(steps, fixes, start.map(|s| s.0)));
    Ok(track)
}

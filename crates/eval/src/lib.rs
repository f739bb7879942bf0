//! # wipdr-eval — the one accuracy protocol of wipdr
//!
//! Implements `docs/evaluation.md` (shared with the papers' comparisons): 5-fold by walk per
//! floor, radio map and PDR calibration learned from the training folds only, every scheme run
//! causally over each test walk, errors scored at waypoints ([`scoring`]), summarised per walk,
//! per floor and pooled ([`report`]). Fusion schemes are started from the first Wi-Fi fix; the
//! PDR-only baseline from the true first waypoint (labelled so).
//!
//! The IPIN competition's protocol runs through the same code ([`fold_rules::folds_of_walks`]):
//! where every walk has a route (IPIN logfiles, `TrialNN`), folds are leave-one-route-out;
//! where waypoints carry floors, each scored point has a floor error and the reports give the
//! floor hit rate and the EvAAL metric (75th percentile of 2D error + 15 m per floor of error;
//! [`scoring::evaal_errors`], [`evaal_score::evaal_metric`]).
//!
//! [`evaal_score`] reproduces the competition's official scorer on its own files (ground
//! truth and the EvAAL API's estimates log): `wipdr score`.
//!
//! Every run goes through `wipdr-positioning`'s pipeline: a test walk's raw samples are
//! streamed through the [`Positioner`](wipdr_positioning::Positioner)'s front end (PDR +
//! stream matcher) once ([`fold_model::FoldModel::prepare_walk`],
//! [`Frontend::record`](wipdr_positioning::Frontend::record)), and each scheme replays the
//! recorded events ([`pipeline::run_scheme`],
//! [`replay_scheme`](wipdr_positioning::replay::replay_scheme)); [`pipeline::locate`] streams
//! a walk through a whole `Positioner` and gives the same track.
//!
//! The modules depend one way (no import loop): [`error`], [`input`], [`config`],
//! [`scoring`] and [`evaal_score`], [`report`] and [`coverage`] below [`fold_model`] (a fold's
//! site model and the [`PreparedWalk`]s it makes), below [`pipeline`], below [`sweep`] and
//! [`shard`].
//!
//! ```
//! use wipdr_core::{Point2, Waypoint};
//! use wipdr_eval::report::{EvalReport, WalkResult};
//! use wipdr_eval::scoring::{TrackPoint, score_track};
//!
//! let truth = [Waypoint::new(1_000, Point2::new(0.0, 0.0))];
//! let track = vec![TrackPoint::new(500, Point2::new(3.0, 4.0))];
//! let score = score_track(&truth, &track, None);
//! let walks = vec![WalkResult { floor: "F1".into(), walk: "w".into(), fold: 0,
//!                               scheme: "wifi".into(), first_scan_t: None, score }];
//! let report = EvalReport::from_walks(vec!["wifi".into()], vec!["F1".into()], walks);
//! assert_eq!(report.pooled["wifi"].mean, 5.0);
//! ```

pub mod config;
pub mod coverage;
pub mod drawing;
pub mod error;
pub mod evaal_score;
pub mod fingerprint_benchmark;
pub mod fold_model;
pub mod fold_rules;
pub mod input;
pub mod pdr_protocol;
pub mod pipeline;
pub mod report;
pub mod scoring;
pub mod shard;
pub mod streams;
pub mod sweep;

pub use config::EvalConfig;
pub use error::EvalError;
pub use fold_model::PreparedWalk;
pub use input::FloorInput;

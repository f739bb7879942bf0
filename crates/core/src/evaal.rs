//! The records of the IPIN competition's scoring (the EvAAL framework): ground-truth points
//! and the estimates a competitor posted through the EvAAL API, in degrees and seconds as the
//! organisers' files hold them. `wipdr_io::evaal` reads the files; `wipdr_eval::evaal_score`
//! scores estimates against ground truth.

use serde::{Deserialize, Serialize};

/// One ground-truth point of a scoring trial (a line of `GT_*.csv`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EvaalTruthPoint {
    /// Trial time, seconds (the clock of the estimates' `pts`).
    pub t_s: f64,
    /// WGS84 longitude, degrees.
    pub lon_deg: f64,
    /// WGS84 latitude, degrees.
    pub lat_deg: f64,
    /// Floor number.
    pub floor: i32,
    /// The point's number in the trial (1-based in the organisers' files).
    pub number: u32,
}

/// One estimate posted through the EvAAL API (a line of a `.est` file: `pts, c, h, s`, then
/// the position `longitude, latitude, floor`).
///
/// The two coordinates are kept as written: a competitor who swapped them is detected and
/// corrected by the scorer, not by the reader.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EvaalEstimate {
    /// Trial time of the estimate (`pts`), seconds.
    pub pts_s: f64,
    /// Wall clock at estimation (`c`), seconds.
    pub wall_clock_s: f64,
    /// Horizon requested with the estimate (`h`), seconds.
    pub horizon_s: f64,
    /// Slack time left at estimation (`s`), seconds.
    pub slack_s: f64,
    /// The position's first coordinate: longitude, degrees.
    pub lon_deg: f64,
    /// The position's second coordinate: latitude, degrees.
    pub lat_deg: f64,
    /// Estimated floor (a real number in the files, e.g. `-1.000000000000`).
    pub floor: f64,
}

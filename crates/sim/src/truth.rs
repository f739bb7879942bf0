//! The known truth of a synthetic walk, written as JSON next to it (`truth/<walk>.json`).
//!
//! Times are Unix milliseconds like the walk's records; positions in the floor's metre frame;
//! headings in radians clockwise from `+y` in the map frame, wrapped to `(-pi, pi]`.

use crate::SimError;
use crate::imu::PhonePose;
use crate::walker::WalkerParams;
use serde::{Deserialize, Serialize};
use std::path::Path;
use wipdr_core::{Point2, TimestampMs};

/// One true step: the heel strike that ends it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StepTruth {
    /// Time of the heel strike, Unix ms.
    pub t: TimestampMs,
    /// Straight-line length of the step (start to end position), metres.
    pub length: f64,
    /// Heading of the step's displacement (map frame), radians.
    pub heading: f64,
    /// Length along the (curved) path, metres.
    pub arc_length: f64,
    /// Duration of the step, seconds.
    pub period_s: f64,
}

/// One turn at a junction (`|angle| >= min_turn_deg`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TurnTruth {
    /// When the turn starts, Unix ms.
    pub t_start: TimestampMs,
    /// When the turn ends, Unix ms.
    pub t_end: TimestampMs,
    /// Signed turn angle (positive clockwise, to the right), radians.
    pub angle: f64,
}

/// A period of standing still.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StopTruth {
    /// Start, Unix ms.
    pub t_start: TimestampMs,
    /// End, Unix ms.
    pub t_end: TimestampMs,
}

/// A sample of the true trajectory.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TrajectorySample {
    /// Time, Unix ms.
    pub t: TimestampMs,
    /// Position, metres.
    pub x: f64,
    /// Position, metres.
    pub y: f64,
    /// Walking direction (path tangent, map frame), radians.
    pub heading: f64,
}

/// A Wi-Fi scan replaced by one generated far away.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GrossErrorTruth {
    /// Scan time, Unix ms.
    pub t: TimestampMs,
    /// True position at the scan time.
    pub true_position: Point2,
    /// Position the scan was generated at.
    pub scan_position: Point2,
}

/// The whole truth of one walk.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WalkTruth {
    /// Walk id (the trace file's name without extensions).
    pub walk_id: String,
    /// Seed of the generation run.
    pub seed: u64,
    /// Index of the walk in the run.
    pub index: usize,
    /// Walk start, Unix ms.
    pub start_ms: TimestampMs,
    /// Walk end, Unix ms.
    pub end_ms: TimestampMs,
    /// Walker parameters.
    pub walker: WalkerParams,
    /// Phone pose and gyroscope bias.
    pub phone: PhonePose,
    /// The compass azimuth equals the map heading plus this offset, radians.
    pub map_to_magnetic: f64,
    /// Every true step, in time order.
    pub steps: Vec<StepTruth>,
    /// Turns at junctions, in time order.
    pub turns: Vec<TurnTruth>,
    /// Standing periods (a static start is the one beginning at `start_ms`).
    pub stops: Vec<StopTruth>,
    /// The trajectory sampled at `trajectory_rate_hz`, and at the end.
    pub trajectory: Vec<TrajectorySample>,
    /// Injected gross-error scans.
    pub gross_errors: Vec<GrossErrorTruth>,
    /// Total distance walked, metres.
    pub distance_m: f64,
}

impl WalkTruth {
    /// True position at `t` (linear between trajectory samples; clamped at the ends).
    pub fn position_at(&self, t: TimestampMs) -> Option<Point2> {
        let tr = &self.trajectory;
        let first = tr.first()?;
        let i = tr.partition_point(|s| s.t <= t);
        if i == 0 {
            return Some(Point2::new(first.x, first.y));
        }
        let a = &tr[i - 1];
        let Some(b) = tr.get(i) else {
            return Some(Point2::new(a.x, a.y));
        };
        let f = if b.t > a.t {
            (t - a.t) as f64 / (b.t - a.t) as f64
        } else {
            0.0
        };
        Some(Point2::new(a.x + (b.x - a.x) * f, a.y + (b.y - a.y) * f))
    }

    /// Whether the scan at time `t` was an injected gross error.
    pub fn is_gross_error(&self, t: TimestampMs) -> bool {
        self.gross_errors.iter().any(|g| g.t == t)
    }
}

/// Reads one truth file (`truth/<walk id>.json`).
pub fn read_walk_truth(path: impl AsRef<Path>) -> Result<WalkTruth, SimError> {
    let path = path.as_ref();
    let text = std::fs::read_to_string(path).map_err(|source| SimError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    serde_json::from_str(&text).map_err(|e| SimError::Parse {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

/// Reads the truth of every walk of a written floor folder (`<floor>/truth/*.json` except
/// `world.json`), sorted by walk id (the order of the walk files).
pub fn read_floor_truths(floor_dir: impl AsRef<Path>) -> Result<Vec<WalkTruth>, SimError> {
    let dir = floor_dir.as_ref().join("truth");
    let io = |source| SimError::Io {
        path: dir.clone(),
        source,
    };
    let mut paths = Vec::new();
    for entry in std::fs::read_dir(&dir).map_err(io)? {
        let p = entry.map_err(io)?.path();
        let is_walk = p.extension().is_some_and(|e| e == "json")
            && p.file_name().is_some_and(|n| n != "world.json");
        if is_walk {
            paths.push(p);
        }
    }
    paths.sort();
    let mut truths: Vec<WalkTruth> = paths
        .iter()
        .map(read_walk_truth)
        .collect::<Result<_, _>>()?;
    truths.sort_by(|a, b| a.walk_id.cmp(&b.walk_id));
    Ok(truths)
}

/// Rounds to `1/scale` (scale an integer power of ten) so that JSON stays short and exact.
pub(crate) fn round_to(v: f64, scale: f64) -> f64 {
    let r = (v * scale).round() / scale;
    if r == 0.0 { 0.0 } else { r }
}

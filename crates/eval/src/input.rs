//! What an evaluation takes in: labelled floors (plan + walks), wherever they were read from.

use crate::report::InputSkips;
use std::sync::Arc;
use wipdr_core::Floor;
use wipdr_pdr::odometry::LearnedOdometry;

/// A floor under evaluation: its label (as given on the command line) and the floor in the
/// core vocabulary (plan + walks), wherever it came from (ILC or IPIN files, the Python
/// package, walks built in code).
#[derive(Debug, Clone)]
pub struct FloorInput {
    /// Label used in reports.
    pub label: String,
    /// The floor.
    pub data: Arc<Floor>,
    /// The folder it was read from, where it was (plots look for the floor image there).
    pub dir: Option<std::path::PathBuf>,
    /// What the readers skipped in it, by kind (records out of range, unreadable walk
    /// files, unusable plan features, ...), for the report's skip counts.
    pub input_skips: InputSkips,
    /// The learned odometry network this floor's walks run when the config says
    /// `odometry = "learned"` (not read under `steps`); `None`: the shipped weights. A
    /// leave-one-floor-out evaluation gives each floor the network that did not train on it
    /// (`wipdr eval --odometry-holdout`).
    pub odometry: Option<Arc<LearnedOdometry>>,
}

impl FloorInput {
    /// A labelled floor.
    pub fn new(label: impl Into<String>, floor: Floor) -> Self {
        Self {
            label: label.into(),
            data: Arc::new(floor),
            dir: None,
            input_skips: InputSkips::new(),
            odometry: None,
        }
    }

    /// The floor with what its readers skipped, by kind.
    pub fn with_input_skips(mut self, skips: InputSkips) -> Self {
        self.input_skips = skips;
        self
    }

    /// The floor with its own learned odometry network ([`FloorInput::odometry`]).
    pub fn with_odometry(mut self, model: Arc<LearnedOdometry>) -> Self {
        self.odometry = Some(model);
        self
    }

    /// The floor with the folder it was read from.
    pub fn with_dir(mut self, dir: impl Into<std::path::PathBuf>) -> Self {
        self.dir = Some(dir.into());
        self
    }
}

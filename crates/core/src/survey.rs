//! A floor under evaluation: its plan and its recorded walks, whatever they were read from
//! (ILC traces, IPIN logfiles, the Python package, walks built in code).

use crate::{FloorPlan, GeoFrame, Walk};
use serde::{Deserialize, Serialize};

/// A floor = plan + walks. The evaluation protocol (`wipdr-eval`) takes these, so walks that
/// did not come from files enter the same protocol.
///
/// ```
/// use wipdr_core::{Floor, FloorPlan, Walk};
/// let plan = FloorPlan::new(10.0, 10.0, vec![], vec![])?;
/// let floor = Floor::new("my/F1", plan, vec![Walk::default()]);
/// assert_eq!(floor.walks.len(), 1);
/// # Ok::<(), wipdr_core::CoreError>(())
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Floor {
    /// Display name (`site1/F1`).
    pub name: String,
    /// The plan in the walks' metre frame.
    pub plan: FloorPlan,
    /// The walks, sorted by id (the protocol's folds are by sorted id).
    pub walks: Vec<Walk>,
    /// The WGS84 frame of the metre coordinates, where known (IPIN logfiles): estimates can
    /// then be written in latitude/longitude.
    #[serde(default)]
    pub geo_frame: Option<GeoFrame>,
}

impl Floor {
    /// A floor; the walks are sorted by id.
    pub fn new(name: impl Into<String>, plan: FloorPlan, mut walks: Vec<Walk>) -> Self {
        walks.sort_by(|a, b| a.meta.id.cmp(&b.meta.id));
        Self {
            name: name.into(),
            plan,
            walks,
            geo_frame: None,
        }
    }

    /// The floor with its metre frame placed in WGS84.
    pub fn with_geo_frame(mut self, frame: GeoFrame) -> Self {
        self.geo_frame = Some(frame);
        self
    }

    /// The walk with id `id`.
    pub fn walk(&self, id: &str) -> Option<&Walk> {
        self.walks.iter().find(|w| w.meta.id == id)
    }
}
